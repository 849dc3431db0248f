r"""Structure of the order-m estimation error: companion matrix and characteristic polynomial.

With the disturbance model :math:`\Delta^{m+1}\tau = 0` the auxiliary-variable errors of the
order-m observer obey :math:`e_{k+1} = M e_k + [0, \dots, 0, \Delta^{m+1}\tau_{k+1}]^T` with
:math:`M = C - k\,e_{m+1}^T`, ``C`` the companion matrix of :math:`(z-1)^{m+1}` (eqs. 12, 22),
and :math:`\det(zI - M) = (z-1)^{m+1} + \sum_j k_j q_j(z)` is affine in the scalar gains
``k`` (``docs/theory.md``). This module holds that structure; :mod:`._synthesis` places the
poles with it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from .._validation import ParameterValueError, as_int, as_real_vector, readonly

__all__ = [
    "ErrorDynamics",
    "characteristic_polynomial",
    "error_matrix",
    "extrapolation_weights",
    "schur_cohn_stable",
    "schur_stable",
    "unit_root_polynomial",
]


def extrapolation_weights(order: int) -> np.ndarray:
    r"""Weights :math:`p_i` with :math:`\tau_{k+1} = \sum_i p_i \tau_{k-(m+1-i)}` when
    :math:`\Delta^{m+1}\tau_{k+1} = 0`.

    :math:`p_i = (-1)^{m+1-i}\binom{m+1}{i-1}` for ``i = 1..m+1`` (``order = m``): the
    degree-``m`` polynomial extrapolation of the last ``m+1`` samples.

    Parameters
    ----------
    order : int
        Truncation order ``m >= 0``.

    Returns
    -------
    ndarray, shape (m + 1,)
        :math:`p_1, \dots, p_{m+1}`, oldest sample first: ``[1]`` for the DOb, ``[-1, 2]``
        for the HPDOb.

    Raises
    ------
    ParameterTypeError, ParameterValueError
        If ``order`` is not a non-negative integer.

    References
    ----------
    The disturbance model of eqs. (10), (12) (``m = 0``: :math:`\tau_{k+1} = \tau_k`) and
    (17)-(19) (``m = 1``: :math:`\tau_{k+1} = 2\tau_k - \tau_{k-1}`), generalised to any
    order in ``docs/theory.md``.

    Examples
    --------
    >>> from hpdob import extrapolation_weights
    >>> extrapolation_weights(1)   # tau_(k+1) = -tau_(k-1) + 2 tau_k
    array([-1.,  2.])
    >>> extrapolation_weights(2)
    array([ 1., -3.,  3.])
    """
    m = as_int(order, "order", "a non-negative integer truncation order", minimum=0)
    return np.array([(-1.0) ** (m + 1 - i) * math.comb(m + 1, i - 1) for i in range(1, m + 2)])


def unit_root_polynomial(order: int) -> np.ndarray:
    r"""Coefficients of :math:`(z-1)^{m+1}` (``order = m``), **ascending** powers of ``z``:
    :math:`\binom{m+1}{j}(-1)^{m+1-j}` for ``j = 0..m+1``."""
    n = order + 1
    return np.array([math.comb(n, j) * (-1.0) ** (n - j) for j in range(n + 1)])


def companion(order: int) -> np.ndarray:
    n = order + 1
    C = np.zeros((n, n))
    C[np.arange(n - 1), np.arange(1, n)] = 1.0
    C[-1, :] += extrapolation_weights(order)
    return C


def error_matrix(k) -> np.ndarray:
    r"""Estimation-error matrix :math:`M = C - k\,e_{m+1}^T` for ``k_i = L_i^T D_Dn``.

    ``C`` is the companion matrix of :math:`(z-1)^{m+1}` (ones on the superdiagonal, the
    :func:`extrapolation_weights` in its last row); the errors of the auxiliary variables obey
    :math:`e_{k+1} = M e_k + [0, \dots, 0, \Delta^{m+1}\tau_{k+1}]^T`.

    Parameters
    ----------
    k : sequence of float
        The ``m + 1`` scalar gains :math:`k_i = L_i^T D_{Dn}` (``design.k``).

    Returns
    -------
    ndarray, shape (m + 1, m + 1)
        ``M``: ``[[1 - k1]]`` for one gain, ``[[0, 1 - k1], [-1, 2 - k2]]`` for two.

    Raises
    ------
    ParameterTypeError, ParameterValueError
        If ``k`` is empty or not a sequence of finite numbers.

    References
    ----------
    Eq. (12) (conventional DOb) and eq. (22) (HPDOb); any order in ``docs/theory.md``.

    Examples
    --------
    >>> from hpdob import error_matrix
    >>> error_matrix([0.19, 0.2])   # eq. (22) with k1 = 0.19, k2 = 0.2
    array([[ 0.  ,  0.81],
           [-1.  ,  1.8 ]])
    """
    k = as_real_vector(k, "k", "a sequence of scalar gains k_i = L_i^T D_Dn")
    if k.size == 0:
        raise ParameterValueError("k must have at least one entry, got an empty sequence")
    M = companion(k.size - 1)
    M[:, -1] -= k
    return M


def characteristic_basis(order: int) -> np.ndarray:
    r"""Matrix ``Q`` with ``charpoly(M) = (z-1)^{m+1} + Q @ k`` (ascending powers of z).

    Column ``j`` (1-based) holds the coefficients of
    :math:`q_j(z) = z^{m-j}\sum_{i\le j} p_i z^{i-1}` for ``j <= m`` and :math:`q_{m+1} = z^m`;
    derived in ``docs/theory.md``.
    """
    m = order
    p = extrapolation_weights(m)
    Q = np.zeros((m + 1, m + 1))
    for j in range(1, m + 1):
        for i in range(1, j + 1):
            Q[m - j + i - 1, j - 1] += p[i - 1]
    Q[m, m] = 1.0
    return Q


def characteristic_polynomial(k) -> np.ndarray:
    r"""Coefficients (highest power first) of :math:`\det(zI - M)` for gains ``k``.

    Computed from the affine formula :math:`(z-1)^{m+1} + \sum_j k_j q_j(z)`, not from
    eigenvalues, so it is exact to rounding for repeated roots too. Its roots are the poles
    of the estimation error (those of :func:`error_matrix`).

    Parameters
    ----------
    k : sequence of float
        The ``m + 1`` scalar gains :math:`k_i = L_i^T D_{Dn}`.

    Returns
    -------
    ndarray, shape (m + 2,)
        Monic coefficients, highest power of ``z`` first (as :func:`numpy.roots` takes them).

    Raises
    ------
    ParameterTypeError, ParameterValueError
        If ``k`` is empty or not a sequence of finite numbers.

    References
    ----------
    The characteristic polynomial of eq. (22), whose roots eq. (24) places:
    :math:`z^2 - (2 - k_2) z + (1 - k_1)`; any order in ``docs/theory.md``.

    Examples
    --------
    >>> from hpdob import characteristic_polynomial
    >>> characteristic_polynomial([0.19, 0.2])   # eq. (24) for poles 0.9, 0.9: (z - 0.9)^2
    array([ 1.  , -1.8 ,  0.81])
    """
    k = as_real_vector(k, "k", "a sequence of scalar gains k_i = L_i^T D_Dn")
    if k.size == 0:
        raise ParameterValueError("k must have at least one entry, got an empty sequence")
    m = k.size - 1
    ascending = np.zeros(m + 2)
    ascending[: m + 1] = characteristic_basis(m) @ k
    ascending += unit_root_polynomial(m)
    return ascending[::-1]


def schur_stable(k: np.ndarray) -> bool:
    r"""True if every eigenvalue of ``M = C - k e_{m+1}^T`` lies strictly inside the unit circle,
    decided exactly for the double-precision gains ``k``.

    Eigenvalues computed in floating point cannot decide this for near-defective ``M``
    (an ``(m+1)``-fold pole moves by ~``eps^(1/(m+1))``), so the characteristic polynomial
    :math:`(z-1)^{m+1} + \sum_j k_j q_j(z)` is built in exact rational arithmetic and tested by
    :func:`schur_cohn_stable`. Cross-checked against ``np.roots`` in
    ``tests/test_synthesis.py``.
    """
    if not np.all(np.isfinite(k)):
        return False
    m = k.size - 1
    Q = characteristic_basis(m)
    gains = [Fraction(float(v)) for v in k]
    c = [
        int(base) + sum((int(Q[i, j]) * gains[j] for j in range(m + 1)), Fraction(0))
        for i, base in enumerate(unit_root_polynomial(m)[: m + 1])
    ]
    c.append(Fraction(1))  # ascending coefficients of the monic degree-(m+1) polynomial
    return schur_cohn_stable(c)


def schur_cohn_stable(coefficients) -> bool:
    r"""True if every root of the polynomial lies strictly inside the unit circle (exact).

    ``coefficients`` are the polynomial's coefficients in **ascending** powers of ``z`` as
    exact rationals (:class:`fractions.Fraction` or ``int``), the last one non-zero. The
    Schur-Cohn recursion: with :math:`|c_0| < |c_n|`, :math:`p` is stable iff
    :math:`(c_n p(z) - c_0 z^n p(1/z)) / z` is (the Schur-Cohn reduction, as in Jury's
    stability test for discrete-time systems); every step is exact.
    """
    c = [Fraction(v) for v in coefficients]
    while len(c) > 1:
        n = len(c) - 1
        if abs(c[0]) >= abs(c[n]):
            return False
        reduced = [c[n] * c[i] - c[0] * c[n - i] for i in range(1, n + 1)]
        c = [v / reduced[-1] for v in reduced]  # monic again: keeps the numbers small
    return True


@dataclass(frozen=True, eq=False)
class ErrorDynamics:
    r"""Closed form of an observer's estimation error on its nominal plant.

    .. math:: 1 - Q(z) = \frac{\tau_{dn}(z) - \hat\tau(z)}{\tau_{dn}(z)}
              = \frac{(z-1)^{m+1} R(z)}{P(z)},\qquad P(z) = \prod_i (z - p_i),\quad
              R(z) = \prod_j (z - r_j),

    the structure of the order-m families (``docs/analysis.md``): the error is driven by
    :math:`\Delta^{m+1}\tau` only. For the observers that measure the state ``R = 1``; for the
    position-only ones ``R`` is the characteristic polynomial of their position/velocity part
    (two zeros).

    Attributes
    ----------
    order : int
        Truncation order ``m``.
    poles : ndarray
        The roots :math:`p_i` of ``P`` (the poles that were placed):
        ``order + 1 + len(zeros)`` of them.
    polynomial : ndarray
        ``P`` (highest power first) as the gains realise it.
    zeros : ndarray, optional
        The roots :math:`r_j` of ``R``; default none.
    """

    order: int
    poles: np.ndarray
    polynomial: np.ndarray
    zeros: np.ndarray = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "poles", readonly(np.array(np.atleast_1d(self.poles))))
        zeros = np.array(self.zeros, dtype=complex if np.iscomplexobj(self.zeros) else float)
        object.__setattr__(self, "zeros", readonly(zeros.reshape(-1)))
        polynomial = np.array(self.polynomial, dtype=float)
        n = self.order + 1 + self.zeros.size
        if polynomial.shape != (n + 1,) or self.poles.shape != (n,):
            raise ParameterValueError(
                f"error dynamics of order {self.order} with {self.zeros.size} zeros need {n} "
                f"poles and {n + 1} polynomial coefficients"
            )
        object.__setattr__(self, "polynomial", readonly(polynomial))
