"""The linear sampled-data closed loop as a python-control system, and its poles."""

from __future__ import annotations

import functools

import numpy as np

from .._interrupts import interruptible
from ..simulation import ServoLoop, accepts_loop
from ._linear_loop import (
    INPUTS,
    OUTPUTS,
    delay_state,
    delayed_state_matrix,
    loop_matrices,
    loop_spec,
    state_names,
)

__all__ = ["closed_loop", "closed_loop_poles", "spectral_radii"]


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


def spectral_radii(loop: ServoLoop, plants, delay_samples) -> np.ndarray:
    """Closed-loop spectral radii of ``loop`` over true plants and actuator delays.

    ``out[i, j]`` is ``max(abs(closed_loop_poles(loop.replace(plant=plants[j],
    actuator=Actuator(delay_samples=delay_samples[i])))))``, bit for bit, without building and
    validating a loop per case: the loop is checked once and only the plant's ZOH model
    (computed once per plant) and the delay change (``tune`` scans thousands of these). A
    reaction-torque observer whose friction model follows the plant
    (:attr:`~hpdob.observers.ReactionObserverDesign.follows_plant`) is that of each plant's
    loop, as ``loop.replace`` makes it.

    Parameters
    ----------
    loop : ServoLoop
        The loop; its actuator's ``torque_limit`` must be None (only the delay is replaced).
    plants : sequence of ServoModel or TwoMassServo
        True plants (their linear models; Coulomb friction is ignored).
    delay_samples : sequence of int
        Actuator delays [samples], each in ``0..MAX_DELAY_SAMPLES`` (1000).

    Returns
    -------
    ndarray of float, shape (len(delay_samples), len(plants))
        The spectral radii (below 1: asymptotically stable).

    Raises
    ------
    TypeError, ValueError
        As for :func:`closed_loop`, or for a delay that is not an integer in range (named).

    Examples
    --------
    >>> from hpdob import PD, ServoLoop, ServoModel, design_observer
    >>> from hpdob.analysis import spectral_radii
    >>> nominal = ServoModel(2.8e-4)
    >>> obs = design_observer(nominal.discretize(1e-3), order=1, bandwidth=200.0)
    >>> loop = ServoLoop(plant=nominal, nominal=nominal, Ts=1e-3, controller=PD(50, 5),
    ...                  observer=obs)
    >>> radii = spectral_radii(loop, [ServoModel(2.0e-4), ServoModel(3.6e-4)], [0, 1])
    >>> radii.shape, bool((radii < 1).all())
    ((2, 2), True)
    """
    delays = _checked_delays(delay_samples)
    return RadiiScan(loop, plants).radii(delays)


def _checked_delays(delay_samples) -> list[int]:
    from .._validation import ParameterValueError
    from ._linear_loop import MAX_DELAY_SAMPLES

    delays = []
    for d in delay_samples:
        if (
            isinstance(d, bool)
            or not isinstance(d, (int, np.integer))
            or not (0 <= d <= MAX_DELAY_SAMPLES)
        ):
            raise ParameterValueError(
                f"delay_samples must be integers in 0..{MAX_DELAY_SAMPLES} [samples], got {d!r}"
            )
        delays.append(int(d))
    return delays


class RadiiScan:
    """:func:`spectral_radii` of one loop over fixed plants, for delays asked batch by batch.

    The loop is checked and the plants' one-sample state matrices are built once, not per
    call: ``tune`` asks for the radii with its delays and then scans up to 20 more delays one
    by one (its delay margin). ``RadiiScan(loop, plants).radii(delays)`` is
    ``spectral_radii(loop, plants, delays)``, bit for bit (internal).
    """

    def __init__(self, loop: ServoLoop, plants):
        import dataclasses

        spec = loop_spec(loop)
        models = [_linear_model(plant, loop.Ts) for plant in plants]
        if getattr(loop.design, "follows_plant", False):
            # an RTOB whose friction model is the plant's (friction = "plant"): its observer is
            # that of loop.replace(plant=...), one per plant
            specs = [loop_spec(loop.replace(plant=plant)) for plant in plants]
        else:
            specs = [spec] * len(models)
        self._ones = [dataclasses.replace(s, plant=model, delay=1)
                      for s, model in zip(specs, models, strict=True)]  # fmt: skip
        self._templates = None  # the one-sample state matrices, built on first use
        self._stack = None  # the same as one array, where they share their shape and layout

    def _one_sample(self):
        if self._templates is None:
            self._templates = [loop_matrices(one)[0] for one in self._ones]
            shapes = {t.shape for t in self._templates}
            places = {delay_state(one) for one in self._ones}
            if len(shapes) == 1 and len(places) == 1:
                self._stack = (np.stack(self._templates), places.pop())
        return self._templates

    def radii(self, delay_samples) -> np.ndarray:
        """``out[i, j]``: the spectral radius with ``delay_samples[i]`` and plant ``j``."""
        import dataclasses

        delays = _checked_delays(delay_samples)
        out = np.empty((len(delays), len(self._ones)))
        for i, d in enumerate(delays):
            if d == 0:
                A = [loop_matrices(dataclasses.replace(one, delay=0))[0] for one in self._ones]
            else:  # bit for bit loop_matrices(...)[0] with d samples, without the assembly
                templates = self._one_sample()
                if self._stack is not None:  # the stacked matrices built as one array
                    A = delayed_state_matrix(self._stack[0], None, d, state=self._stack[1])
                else:
                    A = [delayed_state_matrix(t, one, d)
                         for t, one in zip(templates, self._ones, strict=True)]  # fmt: skip
            sizes = {A.shape[1:]} if isinstance(A, np.ndarray) else {a.shape for a in A}
            if len(sizes) == 1 and max(sizes)[0] < INTERRUPTIBLE_STATES:
                # one stacked call: LAPACK's geev on each matrix, as one call per matrix would
                stack = A if isinstance(A, np.ndarray) else np.stack(A)
                out[i] = np.abs(np.linalg.eigvals(stack)).max(axis=-1)
            else:
                out[i] = [np.abs(_eigenvalues(a)).max() for a in A]
        return out


def _linear_model(plant, Ts: float):
    """The plant's ZOH model; equal plants share one (frozen, so safe to share)."""
    from .._validation import ParameterTypeError

    if not callable(getattr(plant, "discretize", None)):
        raise ParameterTypeError(
            "plants must be linear plants (ServoModel or TwoMassServo, with discretize), got "
            f"{type(plant).__name__}"
        )
    try:
        return _discretized(plant, repr(plant), Ts)
    except TypeError:  # an unhashable plant: no sharing
        return plant.discretize(Ts)


@functools.lru_cache(maxsize=64)
def _discretized(plant, key: str, Ts: float):  # key: repr tells -0.0 from 0.0
    return plant.discretize(Ts)


#: States from which the eigenvalues are computed off the main thread, so that a signal is
#: handled while LAPACK works (a long actuator delay: 1000 states, seconds under load).
INTERRUPTIBLE_STATES = 200


def _eigenvalues(A) -> np.ndarray:
    if A.shape[0] >= INTERRUPTIBLE_STATES:
        return interruptible(np.linalg.eigvals, A)
    return np.linalg.eigvals(A)


def _poles(spec) -> np.ndarray:
    poles = _eigenvalues(loop_matrices(spec)[0])
    return poles[np.argsort(-np.abs(poles), kind="stable")]
