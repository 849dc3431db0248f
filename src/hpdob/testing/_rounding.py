r"""Rounding-error bound of an exported observer (C build) against the Python reference.

The derivation is in ``docs/deployment.md``; in short, with unit roundoff ``u`` (``2^-24``
for float, ``2^-53`` for double) and :math:`\gamma_n = n u / (1 - n u)`:

* row ``i`` of the update sums the ``n_i`` terms of the observer's program (for the order-m
  family ``n_i <= 5`` for the history rows and ``m + 5`` for the last row). With the
  constants and the inputs rounded to the C type as well, the computed row is the exact one
  plus :math:`\delta_{k,i}` with :math:`|\delta_{k,i}| \le \gamma_{n_i+2} \sum_j |c_{ij}|\,
  |v_{k,j}|` (Higham, *Accuracy and Stability of Numerical Algorithms*, eq. 3.4), the sum
  running over the terms as the code evaluates them and ``v`` the operands (C state,
  measurement, u);
* the state error :math:`e_k = s^C_k - s_k` then obeys :math:`e_{k+1} = F e_k + \delta_k`, so
  :math:`|H_1 e_k| \le \sum_{j<k} |H_1 F^{k-1-j}|\,|\delta_j| + |H_1 F^k|\,|e_0|`;
* the estimate adds its own :math:`\gamma_{n_o+2} \sum |c|\,|v|` over its terms.

The reference's own rounding (binary64) is covered by using ``u_C + 2^-53`` as the unit
roundoff. Terms of second order in ``u`` are neglected (they are ``~1e-7`` relative for float).
"""

from __future__ import annotations

import numpy as np

from .._validation import check_choice
from ..observers import as_system

__all__ = ["UNIT_ROUNDOFF", "error_amplification", "export_error_bound", "impulse_rows"]

#: Unit roundoff of the C types (round to nearest).
UNIT_ROUNDOFF = {"double": 2.0**-53, "float": 2.0**-24}


def _gamma(n: int, u: float) -> float:
    return n * u / (1.0 - n * u)


def impulse_rows(observer, *, rtol: float = 1e-20, output: int = 0) -> np.ndarray:
    r"""Rows :math:`|H_1 F^j|`, ``j = 0, 1, ...``, until they fall below ``rtol`` of their
    peak: how a unit error in each state entry reaches the estimate ``j`` samples later.
    Shape ``(J, n_states)``."""
    system = as_system(observer)
    F = np.asarray(system.F)
    row = np.array(system.H[output], dtype=float)
    rows, peak = [], 0.0
    while True:
        size = float(np.abs(row).sum())
        peak = max(peak, size)
        rows.append(np.abs(row))
        if size < rtol * peak and len(rows) > 10 * F.shape[0]:
            return np.array(rows)
        row = row @ F


def error_amplification(observer) -> float:
    r"""The error amplification :math:`A = \sum_j \|H_1 F^j\|_1` of an observer.

    The largest factor by which per-sample rounding errors (bounded by the same number in
    every row) can add up in the estimate: the l1 norm of the error impulse response, summed
    until it has decayed by 1e-20 (``docs/deployment.md``).

    Parameters
    ----------
    observer : LinearObserver, design or runtime observer

    Returns
    -------
    float
        ``A`` (>= 1 for the order-m family; grows quickly with the order and with poles
        closer to 1).

    Raises
    ------
    ParameterTypeError
        If ``observer`` is not an observer.

    Examples
    --------
    >>> from hpdob import ServoModel, design_observer
    >>> from hpdob.testing import error_amplification
    >>> dob = design_observer(ServoModel(J=2.8e-4).discretize(1e-3), order=0, poles=[0.9])
    >>> round(error_amplification(dob), 9)   # sum_j 0.9^j = 1 / (1 - 0.9)
    10.0
    """
    return float(impulse_rows(observer).sum())


def _row_bounds(rows, operands: np.ndarray, unit: float) -> np.ndarray:
    """``gamma_{n_i+2} sum |c| |v|`` for each program row, at every sample (operands (n, w))."""
    out = np.zeros((operands.shape[0], len(rows)))
    for i, terms in enumerate(rows):
        total = np.zeros(operands.shape[0])
        for t in terms:
            total += abs(t.coefficient) * operands[:, t.operand]
        out[:, i] = _gamma(len(terms) + 2, unit) * total
    return out


def export_error_bound(
    observer, dtype: str, theta, omega, u, z, *, init=(0.0, 0.0, 0.0), output: int = 0
):
    r"""Bound on ``|tau_hat_C - tau_hat_Python|`` at every sample of a trace [N m].

    Parameters
    ----------
    observer : LinearObserver or observer-like
        The exported observer.
    dtype : {"double", "float"}
        Scalar type of the C build.
    theta, omega, u : array_like, shape (n,)
        The inputs of both observers (as doubles; the C build rounds them to ``dtype``);
        ``omega`` is ignored for a position-only observer.
    z : array_like, shape (n, n_states)
        The C build's state at the start of every sample (the operands of its arithmetic).
    init : sequence of 3 floats
        ``theta0, omega0, tau0`` both observers were initialised with.
    output : int, optional
        Which output to bound: 0 (``tau_hat``, default) or 1 (``omega_hat`` of observers
        that estimate the velocity).

    Returns
    -------
    ndarray, shape (n,)
        The bound [N m] at each sample (first order in the unit roundoff).

    Raises
    ------
    ParameterTypeError, ParameterValueError
        If ``observer`` is not an observer or ``dtype`` is not ``"double"`` or ``"float"``.

    References
    ----------
    ``docs/deployment.md`` (the derivation); N. J. Higham, *Accuracy and Stability of
    Numerical Algorithms*, 2nd ed., SIAM, 2002, section 3.1 (the :math:`\gamma_n` bounds).

    Examples
    --------
    The bound of a ``float`` build along a trace of the Python observer's states (which a
    ``double`` build reproduces bit for bit):

    >>> import numpy as np
    >>> from hpdob import ServoModel, design_observer, initial_state, update
    >>> from hpdob.testing import export_error_bound
    >>> design = design_observer(ServoModel(J=2.8e-4).discretize(1e-3), order=1,
    ...                          bandwidth=100.0)
    >>> rng = np.random.default_rng(0)
    >>> theta, omega, u = rng.normal(0, 1, 200), rng.normal(0, 10, 200), rng.normal(0, 0.1, 200)
    >>> states = [initial_state(design)]
    >>> for k in range(199):
    ...     states.append(update(design, states[-1], (theta[k], omega[k]), u[k]))
    >>> bound = export_error_bound(design, "float", theta, omega, u, np.array(states))
    >>> bound.shape, bool(0 < bound.min() and bound.max() < 1e-3)
    ((200,), True)
    """
    system = as_system(observer)
    dtype = check_choice(dtype, "dtype", UNIT_ROUNDOFF)
    unit = UNIT_ROUNDOFF[dtype] + UNIT_ROUNDOFF["double"]
    theta, omega, u = (np.abs(np.asarray(a, dtype=float)) for a in (theta, omega, u))
    z = np.abs(np.asarray(z, dtype=float))
    measured = [theta, omega][: len(system.measures)]
    operands = np.column_stack([z, *measured, u])
    program = system.program
    delta = _row_bounds(program.update, operands, unit)
    start = np.abs(np.asarray(init, dtype=float))[None, :]
    e0 = _row_bounds(program.reset, start, unit)[0]
    h = impulse_rows(system, output=output)
    n = theta.size
    bound = np.zeros(n)
    for i in range(system.n_states):
        carried = np.convolve(delta[:, i], h[:, i])[: n - 1]  # sum_{j<=k} h_{k-j} delta_j
        bound[1:] += carried
        reach = np.zeros(n)
        reach[: min(n, h.shape[0])] = h[:n, i]
        bound += reach * e0[i]
    bound += _row_bounds(program.output[output : output + 1], operands, unit)[:, 0]
    return bound
