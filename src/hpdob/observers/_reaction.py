r"""The reaction-torque observer (RTOB): a disturbance observer minus a friction model."""

from __future__ import annotations

import numpy as np

from .._validation import ParameterValueError, nonnegative
from ._system import LinearObserver, as_system

__all__ = ["reaction_torque_observer"]


def reaction_torque_observer(dob, reaction=None, *, viscous: float = 0.0) -> LinearObserver:
    r"""The DOb and a reaction-torque observer as one :class:`LinearObserver`.

    .. math::

        \hat\tau_{reac,k} = \hat\tau^R_k - \hat f(\omega_k),\qquad
        \hat f(\omega) = \Delta b\,\omega,

    with :math:`\hat\tau^R` the disturbance estimate of ``reaction`` (an observer of any
    registered family and order on the same nominal model, with its own bandwidth) and
    :math:`\Delta b` the viscous friction beyond the nominal :math:`b_n` (:math:`b - b_n`).
    The state is the DOb's followed by the RTOB's, the outputs are the DOb's (``tau_hat``
    and, if it has one, ``omega_hat``) then ``tau_reac``: the loop compensates with
    ``tau_hat`` as before and a controller input named ``tau_reac`` reads the reaction-torque
    estimate, in :func:`hpdob.simulate`, :func:`hpdob.sweep` and the analysis views alike.

    Parameters
    ----------
    dob : observer
        The inner loop's disturbance observer (a design or a :class:`LinearObserver`).
    reaction : observer, optional
        The RTOB's observer, measuring what ``dob`` measures. Default None: ``dob`` itself
        (the DOb's bandwidth); :math:`\hat\tau^R = \hat\tau_{dn}` then, and no state is added.
    viscous : float, optional
        :math:`\Delta b` [N m s/rad], non-negative: the viscous friction the RTOB subtracts
        (``identify(...)``'s ``b`` minus the nominal ``b_n``). Default 0. The friction uses the
        measured velocity (``omega``) or, for a position-only ``reaction``, its ``omega_hat``.

    Returns
    -------
    LinearObserver
        Outputs ``("tau_hat", ["omega_hat",] "tau_reac")``.

    Raises
    ------
    ParameterValueError
        If the observers measure different signals, were designed at different ``Ts``, or
        ``viscous`` is negative; if no velocity is available for a non-zero ``viscous``.
    ParameterTypeError
        If an argument is not an observer.

    Notes
    -----
    The Coulomb part of :math:`\hat f` (``c tanh(omega/v)``) is not linear, so it is not part of
    this observer: the estimate keeps the Coulomb torque. In steady contact
    (:math:`\omega = 0`) the smoothed Coulomb torque of the plant is zero, so the steady-state
    force is unaffected; during motion it is not compensated.

    References
    ----------
    T. Murakami, F. Yu, K. Ohnishi, "Torque sensorless control in multidegree-of-freedom
    manipulator", IEEE Trans. Ind. Electron. 40(2), 1993.

    Examples
    --------
    >>> from hpdob import ServoModel, design_observer
    >>> from hpdob.observers import reaction_torque_observer
    >>> model = ServoModel(3.06e-4, 5e-5).discretize(1e-3)
    >>> dob = design_observer(model, order=1, bandwidth=100.0)
    >>> rtob = design_observer(model, order=0, bandwidth=200.0)
    >>> both = reaction_torque_observer(dob, rtob)
    >>> both.outputs, both.n_states
    (('tau_hat', 'tau_reac'), 3)
    """
    first = as_system(dob, "dob")
    second = first if reaction is None else as_system(reaction, "reaction")
    viscous = nonnegative(viscous, "viscous", "a non-negative finite viscous friction [N m s/rad]")
    if "tau_reac" in first.outputs:
        raise ParameterValueError("dob already has a tau_reac output (it is an RTOB composition)")
    if second.measures != first.measures:
        raise ParameterValueError(
            f"reaction must measure what dob measures {first.measures}, got {second.measures}"
        )
    if second.Ts != first.Ts:
        raise ParameterValueError(f"reaction.Ts = {second.Ts!r} must equal dob.Ts = {first.Ts!r}")
    n1 = first.n_states
    if reaction is None:  # one observer: tau_reac is tau_hat minus the friction
        F, G, N = first.F, first.G, first.N
        row_H, row_E = first.H[0].copy(), first.E[0].copy()
        velocity = None
        if "omega_hat" in first.outputs:
            velocity = (first.H[1], first.E[1])
    else:
        n2 = second.n_states
        F = np.block([[first.F, np.zeros((n1, n2))], [np.zeros((n2, n1)), second.F]])
        G, N = np.vstack([first.G, second.G]), np.vstack([first.N, second.N])
        row_H, row_E = np.concatenate([np.zeros(n1), second.H[0]]), second.E[0].copy()
        velocity = None
        if "omega_hat" in second.outputs:
            velocity = (np.concatenate([np.zeros(n1), second.H[1]]), second.E[1])
    if viscous:
        if "omega" in first.measures:  # the measured velocity: a feed-through
            row_E[first.measures.index("omega")] -= viscous
        elif velocity is not None:
            row_H, row_E = row_H - viscous * velocity[0], row_E - viscous * velocity[1]
        else:
            raise ParameterValueError(
                f"viscous = {viscous!r} needs a velocity: the observers measure "
                f"{first.measures} and the reaction observer has no omega_hat"
            )
    pad = F.shape[0] - n1
    H = np.vstack([np.hstack([first.H, np.zeros((len(first.outputs), pad))]), row_H])
    E = np.vstack([first.E, row_E])
    return LinearObserver(
        F=F,
        G=G,
        H=H,
        E=E,
        N=N,
        Ts=first.Ts,
        measures=first.measures,
        outputs=(*first.outputs, "tau_reac"),
        model=first.model,
        name=f"{first.name} + RTOB({second.name})",
        info=(
            *first.info,
            ("reaction observer", second.name),
            ("viscous friction subtracted", f"{viscous!r} N m s/rad"),
        ),
    )
