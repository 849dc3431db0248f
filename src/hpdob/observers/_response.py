"""The observer's own responses: its state-space model and its disturbance-estimation
response on its nominal plant (what ``to_statespace`` and the Kalman design's bandwidth use;
:mod:`hpdob.analysis` builds its views on them)."""

from __future__ import annotations

import numpy as np

from .._validation import ParameterValueError

# ``system`` is a LinearObserver throughout (not imported: _system imports this module).

__all__ = ["estimation_frequency_response", "nominal_loop", "observer_matrices", "statespace"]


def observer_matrices(system):
    """``(A, B, C, D)`` numpy arrays of the observer: ``(F, G, H, E)`` of its system."""
    return (np.array(m, dtype=float) for m in (system.F, system.G, system.H, system.E))


def statespace(system):
    """The observer as a discrete python-control ``StateSpace`` (``dt = Ts``)."""
    import control

    A, B, C, D = observer_matrices(system)
    state = "z" if system.truncation_order is not None else "s"
    return control.ss(
        A,
        B,
        C,
        D,
        system.Ts,
        inputs=list(system.input_names),
        outputs=list(system.outputs),
        states=[f"{state}{i + 1}" for i in range(system.n_states)],
    )


def _nominal_model(system):
    if system.model is None:
        raise ParameterValueError(
            "the estimation response of an observer is defined on its nominal plant: give the "
            "observer's LinearObserver a model (the DiscreteServoModel it was designed on)"
        )
    return system.model


def nominal_loop(system):
    r"""``(A, B, C, D)``: :math:`\tau_{dn} \to \hat\tau` with the observer on its nominal plant,
    ``u = 0``: state ``[x, s]``, :math:`x_{k+1} = A_n x_k - D_n \tau_k`."""
    model = _nominal_model(system)
    An, Dn = np.asarray(model.A), np.asarray(model.D)
    p = len(system.measures)
    Cm = np.eye(2)[:p]  # measured rows of x
    F, G, H, E = (np.asarray(a) for a in (system.F, system.G, system.H, system.E))
    n = system.n_states
    A = np.zeros((2 + n, 2 + n))
    A[:2, :2] = An
    A[2:, :2] = G[:, :p] @ Cm
    A[2:, 2:] = F
    B = np.zeros((2 + n, 1))
    B[:2, 0] = -Dn
    C = np.hstack([E[:1, :p] @ Cm, H[:1]])
    return A, B, C, np.zeros((1, 1))


def estimation_frequency_response(system, z: np.ndarray, error: bool):
    """``Q`` (or ``1 - Q``) at the points ``z`` of the unit circle (checked by the callers)."""
    dynamics = system.error_dynamics
    if dynamics is not None:
        # Factored forms: (z - 1)^(m+1) / prod(z - p_i). Expanded polynomials would cancel
        # catastrophically near z = 1, where 1 - Q is tiny.
        ratio = (z - 1.0) ** (dynamics.order + 1)
        for pole in dynamics.poles:
            ratio = ratio / (z - pole)
        for zero in dynamics.zeros:
            ratio = ratio * (z - zero)
        return ratio if error else 1.0 - ratio
    A, B, C, _ = nominal_loop(system)
    eye = np.eye(A.shape[0])
    # One stacked solve (LAPACK's gesv per frequency, as one call each would do).
    X = np.linalg.solve(z[:, None, None] * eye - A, np.broadcast_to(B, (z.size, *B.shape)))
    Q = (C @ X)[:, 0, 0]
    return 1.0 - Q if error else Q
