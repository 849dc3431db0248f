"""Estimators designed elsewhere in: a discrete python-control ``StateSpace`` as a
:class:`~hpdob.LinearObserver`, with its reset matrix ``N`` derived from the matrices."""

from __future__ import annotations

import numpy as np

from .._validation import ParameterTypeError, ParameterValueError, _show
from ._signals import MEASUREMENTS, OUTPUTS

__all__ = ["observer_from_statespace"]


def observer_from_statespace(cls, sys, *, measures, outputs, model, N, name):
    """:meth:`LinearObserver.from_statespace` (``cls`` is the class built)."""
    import control

    from ..models import as_discrete_model, is_lti

    if not is_lti(sys):
        raise ParameterTypeError(
            f"sys must be a python-control StateSpace, got {type(sys).__name__}"
        )
    if not sys.isdtime(strict=True):
        raise ParameterValueError(
            f"sys must be a discrete system with its sampling period (dt > 0), got dt = "
            f"{sys.dt}; an observer runs at the loop's Ts"
        )
    ss = control.ss(sys) if not isinstance(sys, control.StateSpace) else sys
    inputs, labels = tuple(ss.input_labels), tuple(ss.output_labels)
    if measures is None:
        measures = inputs[:-1]
        if inputs[-1:] != ("u",) or measures not in MEASUREMENTS.values():
            raise ParameterValueError(
                f"measures must be given (('theta', 'omega') or ('theta',)): sys's inputs "
                f"{list(inputs)} are not the measured signals followed by 'u'"
            )
    if outputs is None:
        outputs = labels if labels in OUTPUTS else ("tau_hat",) if len(labels) == 1 else None
        if outputs is None:
            raise ParameterValueError(
                f"outputs must be given (('tau_hat',) or ('tau_hat', 'omega_hat')) for sys's "
                f"{len(labels)} outputs {list(labels)}"
            )
    if model is not None:
        model = as_discrete_model(model, "model")
    F, G, H, E = (np.asarray(m, dtype=float) for m in (ss.A, ss.B, ss.C, ss.D))
    if N is None:
        N = _converged_reset(F, G, H, E, float(ss.dt), tuple(measures), tuple(outputs))
    return cls(F=F, G=G, H=H, E=E, N=N, Ts=float(ss.dt), measures=tuple(measures),
               outputs=tuple(outputs), model=model,
               name=ss.name if name is None else name)  # fmt: skip


def _converged_reset(F, G, H, E, Ts, measures, outputs) -> np.ndarray:
    r"""``N`` of an observer given by its matrices: its state once converged (see
    :meth:`LinearObserver.from_statespace`).

    On the ramp :math:`\theta_k = \theta_0 + k T_s \omega_0`, :math:`\omega_k = \omega_0`,
    :math:`u_k = u` the converged state is affine, :math:`s_k = a + k c`, with
    :math:`c = (I - F)^{-1} G_\theta T_s \omega_0` and :math:`a = (I - F)^{-1}(G v_0 - c)`.
    The columns for :math:`\theta_0` and :math:`\tau_0` (``u = \tau_0`` at rest) follow
    directly; the :math:`\omega_0` column adds the torque :math:`\beta\omega_0` that keeps
    the estimate at :math:`\tau_0` while turning.
    """
    n, p = F.shape[0], len(measures)
    if G.shape != (n, p + 1) or H.shape != (len(outputs), n) or E.shape != (len(outputs), p + 1):
        return np.zeros((n, 3))  # the constructor reports the shapes
    I_F = np.eye(n) - F
    if np.linalg.cond(I_F) > 1e12:
        raise ParameterValueError(
            "N cannot be derived: F has an eigenvalue at 1 (the observer has no unique "
            "converged state, e.g. it integrates the measurement); give N="
        )

    def converged(theta0, omega0, u):
        v = np.zeros(p + 1)
        v[0], v[-1] = theta0, u
        if p == 2:
            v[1] = omega0
        c = np.linalg.solve(I_F, G[:, 0] * Ts * omega0)
        a = np.linalg.solve(I_F, G @ v - c)
        drift = H @ c + E[:, 0] * Ts * omega0  # how the outputs change along the ramp
        return a, H @ a + E @ v, drift

    a_theta, y_theta, _ = converged(1.0, 0.0, 0.0)
    a_tau, y_tau, _ = converged(0.0, 0.0, 1.0)
    a_omega, y_omega, drift = converged(0.0, 1.0, 0.0)
    beta = -y_omega[0] / y_tau[0] if y_tau[0] != 0.0 else np.nan
    a_omega, y_omega = a_omega + beta * a_tau, y_omega + beta * y_tau
    expected = (np.array([0.0, 0.0]), np.array([1.0, 0.0]), np.array([0.0, 1.0]))
    got = (y_theta, y_tau, y_omega)
    for label, y, want in zip(("theta0", "tau0", "omega0"), got, expected, strict=True):
        if not (np.all(np.isfinite(y)) and np.allclose(y, want[: y.size], atol=1e-6)):
            raise ParameterValueError(
                "N cannot be derived: at a constant disturbance the observer's outputs "
                f"{list(outputs)} do not converge to it (for unit {label} they settle at "
                f"{_show(y)}, expected {_show(want[: y.size])}); give N="
            )
    if not np.allclose(drift, 0.0, atol=1e-6 * max(1.0, float(np.max(np.abs(a_omega))))):
        raise ParameterValueError(
            "N cannot be derived: the observer's outputs drift while the axis turns at a "
            f"constant velocity (by {_show(drift)} per sample); give N="
        )
    return np.column_stack([a_theta, a_omega, a_tau])
