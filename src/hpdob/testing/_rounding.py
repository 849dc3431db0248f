r"""Rounding-error bound of an exported observer (C build) against the Python reference.

The derivation is in ``docs/deployment.md``; in short, with unit roundoff ``u`` (``2^-24``
for float, ``2^-53`` for double) and :math:`\gamma_n = n u / (1 - n u)`:

* row ``i`` of the update sums ``n_i`` products (``n_i = 5`` for the history rows,
  ``m + 5`` for the last row). With the constants and the inputs rounded to the C type as
  well, the computed row is the exact one plus :math:`\delta_{k,i}` with
  :math:`|\delta_{k,i}| \le \gamma_{n_i+2} \sum_j |c_{ij}|\,|v_{k,j}|` (Higham, *Accuracy and
  Stability of Numerical Algorithms*, eq. 3.4), the sum running over the terms as the code
  evaluates them and ``v`` the operands (C state, theta, omega, u);
* the state error :math:`e_k = \hat z^C_k - \hat z_k` then obeys
  :math:`e_{k+1} = M e_k + \delta_k`, so
  :math:`|e_{m+1,k}| \le \sum_{j<k} |e_{m+1}^T M^{k-1-j}|\,|\delta_j| + |e_{m+1}^T M^k|\,|e_0|`;
* the estimate adds its own :math:`\gamma_5 (|\hat z_{m+1}| + |L_\theta \theta| + |L_\omega
  \omega|)`.

The reference's own rounding (binary64) is covered by using ``u_C + 2^-53`` as the unit
roundoff. Terms of second order in ``u`` are neglected (they are ``~1e-7`` relative for float).
"""

from __future__ import annotations

import numpy as np

from .._validation import check_choice
from ..observers._synthesis import ObserverDesign

__all__ = ["UNIT_ROUNDOFF", "error_amplification", "export_error_bound", "impulse_rows"]

#: Unit roundoff of the C types (round to nearest).
UNIT_ROUNDOFF = {"double": 2.0**-53, "float": 2.0**-24}


def _gamma(n: int, u: float) -> float:
    return n * u / (1.0 - n * u)


def impulse_rows(design: ObserverDesign, *, rtol: float = 1e-20) -> np.ndarray:
    r"""Rows :math:`|e_{m+1}^T M^j|`, ``j = 0, 1, ...``, until they fall below ``rtol`` of
    their peak: how a unit error in each state entry reaches the estimate ``j`` samples later.
    Shape ``(J, order + 1)``."""
    M = np.asarray(design.error_matrix)
    row = np.zeros(M.shape[0])
    row[-1] = 1.0
    rows, peak = [], 0.0
    while True:
        size = float(np.abs(row).sum())
        peak = max(peak, size)
        rows.append(np.abs(row))
        if size < rtol * peak and len(rows) > 10 * M.shape[0]:
            return np.array(rows)
        row = row @ M


def error_amplification(design: ObserverDesign) -> float:
    r""":math:`\sum_j \|e_{m+1}^T M^j\|_1`: the largest factor by which per-sample rounding
    errors (bounded by the same number in every row) can add up in the estimate."""
    return float(impulse_rows(design).sum())


def export_error_bound(
    design: ObserverDesign, dtype: str, theta, omega, u, z, *, init=(0.0, 0.0, 0.0)
) -> np.ndarray:
    r"""Bound on ``|tau_hat_C - tau_hat_Python|`` at every sample of a trace [N m].

    Parameters
    ----------
    design : ObserverDesign
        The exported design.
    dtype : {"double", "float"}
        Scalar type of the C build.
    theta, omega, u : array_like, shape (n,)
        The inputs of both observers (as doubles; the C build rounds them to ``dtype``).
    z : array_like, shape (n, order + 1)
        The C build's state at the start of every sample (the operands of its arithmetic).
    init : sequence of 3 floats
        ``theta0, omega0, tau0`` both observers were initialised with.

    Returns
    -------
    ndarray, shape (n,)
    """
    dtype = check_choice(dtype, "dtype", UNIT_ROUNDOFF)
    unit = UNIT_ROUNDOFF[dtype] + UNIT_ROUNDOFF["double"]
    theta, omega, u = (np.abs(np.asarray(a, dtype=float)) for a in (theta, omega, u))
    z = np.abs(np.asarray(z, dtype=float))
    m = design.order
    k = np.abs(np.asarray(design.k))
    Kx, Ku = np.abs(design.state_input), np.abs(design.control_input)
    p = np.abs(np.asarray(design._p))
    G = np.abs(design.gains)

    n = theta.size
    delta = np.empty((n, m + 1))
    inputs = Kx[:, :1].T * theta[:, None] + Kx[:, 1:].T * omega[:, None] + Ku * u[:, None]
    for i in range(m):  # z_{i+1} - k_i z_last + Kx_i0 theta + Kx_i1 omega + Ku_i u
        delta[:, i] = _gamma(5 + 2, unit) * (z[:, i + 1] + k[i] * z[:, m] + inputs[:, i])
    last = k[m] * z[:, m] + inputs[:, m] + z @ p  # -k z_last + ... + sum_j p_j z_j
    delta[:, m] = _gamma(m + 5 + 2, unit) * last

    tau0 = abs(float(init[2]))
    e0 = _gamma(5, unit) * (tau0 + G[:, 0] * abs(float(init[0])) + G[:, 1] * abs(float(init[1])))
    h = impulse_rows(design)
    bound = np.zeros(n)
    for i in range(m + 1):
        carried = np.convolve(delta[:, i], h[:, i])[: n - 1]  # sum_{j<=k} h_{k-j} delta_j
        bound[1:] += carried
        reach = np.zeros(n)
        reach[: min(n, h.shape[0])] = h[:n, i]
        bound += reach * e0[i]
    bound += _gamma(5, unit) * (z[:, m] + G[m, 0] * theta + G[m, 1] * omega)
    return bound
