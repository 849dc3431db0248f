"""The linear sampled-data closed loop as a python-control system, and its poles."""

from __future__ import annotations

import numpy as np

from .._interrupts import interruptible
from ..simulation._loop import ServoLoop, accepts_loop
from ._linear_loop import INPUTS, OUTPUTS, loop_matrices, loop_spec, state_names

__all__ = ["closed_loop", "closed_loop_poles"]


@accepts_loop
def closed_loop(loop: ServoLoop):
    """The linear sampled-data closed loop as a discrete python-control ``StateSpace``.

    Parameters
    ----------
    loop : ServoLoop
        The loop (see :class:`~hpdob.ServoLoop`), or its parts as keyword arguments
        (the loop functions' one alias rule, :data:`hpdob.simulation.LOOP_KEYS`).
        The plant must have a linear model (a
        :class:`~hpdob.ServoModel` or a :class:`~hpdob.TwoMassServo`; Coulomb friction is
        ignored); of the sensor only its ``velocity`` method is used (default: the ideal
        state); of the actuator only ``delay_samples`` (``torque_limit`` must be None).

    Returns
    -------
    control.StateSpace
        ``dt = Ts``; inputs ``r, r_dot, r_ddot`` [rad, rad/s, rad/s^2], ``tau_ext`` [N m],
        ``n_theta`` [rad], ``n_omega`` [rad/s]; outputs ``theta`` [rad], ``omega`` [rad/s],
        ``u`` [N m], ``tau_hat`` [N m]; states ``theta, omega``, then ``theta_prev`` (previous
        measured angle, backward-difference sensor only), ``u_delay1..d`` (commands in the
        actuator's delay line) and the observer's (``z1..z{m+1}`` for the order-m family).
        A two-mass plant has the states ``theta, omega, theta_load, omega_load``; ``theta`` and
        ``omega`` are then the motor's.

    Raises
    ------
    TypeError, ValueError
        For arguments of the wrong type or value, with the parameter named.

    Notes
    -----
    The loop is the one :func:`hpdob.simulate` runs, made linear: the true plant's exact ZOH
    discretisation (``plant.J``, ``plant.b``; Coulomb friction left out), the sampled PD with
    its feed-forward, the observer (if any) designed on ``nominal.discretize(Ts)``, an optional
    actuator delay of whole samples and, with an ``Encoder(velocity="backward-difference")``,
    the velocity differenced from the measured position. Quantisation, sensor noise levels and
    torque limits are not linear and are not modelled (a torque limit is rejected); measurement
    noise enters through the inputs ``n_theta`` and ``n_omega`` instead. The external torque
    ``tau_ext`` is held over each sample (the simulator integrates it between samples: for a
    torque that changes within a sample the two differ by that intra-sample variation).

    References
    ----------
    Section IV of the paper (PD outer loop, DOb inner loop); eq. (8) for the sampled plant.

    Examples
    --------
    >>> import numpy as np
    >>> from hpdob import PD, ServoLoop, ServoModel, closed_loop, design_observer
    >>> nominal = ServoModel(2.8e-4)
    >>> obs = design_observer(nominal.discretize(1e-3), order=1, bandwidth=100.0)
    >>> loop = closed_loop(ServoLoop(plant=ServoModel(3.06e-4, 5e-5), nominal=nominal,
    ...                              Ts=1e-3, controller=PD(50, 5), observer=obs))
    >>> loop.input_labels
    ['r', 'r_dot', 'r_ddot', 'tau_ext', 'n_theta', 'n_omega']
    >>> round(float(loop.dcgain()[0, 0]), 9)   # theta / r at DC
    1.0
    """
    import control

    spec = loop_spec(loop)
    A, B, C, D, _, _ = loop_matrices(spec)
    n = len(OUTPUTS)
    return control.ss(
        A,
        B,
        C[:n],
        D[:n],
        loop.Ts,
        inputs=list(INPUTS),
        outputs=list(OUTPUTS),
        states=state_names(spec),
    )


@accepts_loop
def closed_loop_poles(loop: ServoLoop) -> np.ndarray:
    """Eigenvalues of the linear closed loop of :func:`closed_loop` (same arguments).

    The loop is asymptotically stable when every eigenvalue lies strictly inside the unit
    circle (spectral radius below 1, as mapped by :func:`robust_stability_map`).

    Parameters
    ----------
    loop : ServoLoop
        The loop (see :class:`~hpdob.ServoLoop`), or its parts as keyword arguments
        (the loop functions' one alias rule, :data:`hpdob.simulation.LOOP_KEYS`).

    Returns
    -------
    ndarray of complex
        Sorted by decreasing magnitude. Repeated eigenvalues (e.g. an observer's ``m + 1``
        poles at one place) are returned split by about ``eps**(1/multiplicity)``, the
        conditioning of a Jordan block.

    Raises
    ------
    TypeError, ValueError
        As for :func:`closed_loop`.

    Examples
    --------
    >>> from hpdob import PD, ServoModel, closed_loop_poles, design_observer
    >>> nominal = ServoModel(2.8e-4)
    >>> obs = design_observer(nominal.discretize(1e-3), order=0, poles=[0.9])
    >>> poles = closed_loop_poles(plant=nominal, nominal=nominal, Ts=1e-3,
    ...                           controller=PD(50, 5), observer=obs)
    >>> bool(min(abs(poles - 0.9)) < 1e-12)   # on the nominal plant the observer pole stays
    True
    """
    spec = loop_spec(loop)
    return _poles(spec)


#: States from which the eigenvalues are computed off the main thread, so that a signal is
#: handled while LAPACK works (a long actuator delay: 1000 states, seconds under load).
INTERRUPTIBLE_STATES = 200


def _poles(spec) -> np.ndarray:
    A = loop_matrices(spec)[0]
    if A.shape[0] >= INTERRUPTIBLE_STATES:
        poles = interruptible(np.linalg.eigvals, A)
    else:
        poles = np.linalg.eigvals(A)
    return poles[np.argsort(-np.abs(poles), kind="stable")]
