r"""The poles a design really places: eigenvalues of the error matrix with rounded gains.

The synthesis solves for the gains ``k`` exactly and rounds them to double precision. A
repeated pole of multiplicity ``n`` then splits into a ring of radius up to ``~eps^(1/n)``
(times the conditioning of the companion form): tiny for the DOb and the HPDOb, but for high
orders with poles near 1 the realised poles can lie far from the requested ones (order 10 at
100 rad/s, ``Ts = 1 ms``: requested 0.9048, realised up to 0.9548) while the Schur-Cohn test
still certifies stability. Eigenvalues of ``M`` or ``np.roots`` of the characteristic
polynomial cannot show this: their own rounding splits the cluster as much. So the
characteristic polynomial of the rounded gains is built exactly (integers: floats are dyadic
rationals), shifted exactly to each requested pole, and only then solved in floating point,
where the cluster's roots are well conditioned (checked against 80-digit ``mpmath`` roots in
``tests/observers/test_synthesis.py``).

The other families use the same check on their own exact polynomial: the position-only
family's affine formula (:func:`polynomial_from_fractions` of its ``realised_polynomial``), the
ESO's and the Kalman observer's state matrix (:func:`matrix_characteristic_polynomial`,
Berkowitz's division-free algorithm on the matrix's exact binary values;
``tests/observers/test_realised.py``).
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np

from .._validation import ParameterValueError, _show, nonnegative
from ._error_dynamics import characteristic_basis, unit_root_polynomial

__all__ = [
    "POLE_TOLERANCE",
    "check_realised",
    "exact_characteristic_polynomial",
    "finite_gains",
    "matrix_characteristic_polynomial",
    "polynomial_from_fractions",
    "realised_poles",
    "realised_roots",
]

#: Default ``pole_tolerance`` of :func:`hpdob.design_observer`: every realised pole lies within
#: this fraction of its requested pole's distance to the unit circle,
#: ``|realised - p| <= 0.05 (1 - |p|)`` (the realised bandwidth ``-ln|z|/Ts`` is then within
#: about 5% of the requested one).
POLE_TOLERANCE = 0.05


def _fmt(p: complex) -> str:
    p = complex(p)
    return f"{p.real:.6g}" if p.imag == 0.0 else f"({p.real:.6g}{p.imag:+.6g}j)"


def exact_characteristic_polynomial(k) -> tuple[list[int], int]:
    r"""Ascending coefficients of :math:`\det(zI - M)` for the double-precision gains ``k``,
    exactly: integers ``c`` and an exponent ``e`` with coefficient ``i`` equal to
    ``c[i] / 2**e``. :math:`(z-1)^{m+1} + \sum_j k_j q_j(z)` with every float taken at its
    exact binary value (floats are dyadic rationals); the last coefficient is 1."""
    m = k.size - 1
    Q = characteristic_basis(m)
    gains, e = _dyadic([float(v) for v in k])
    c = [
        (int(base) << e) + sum(int(Q[i, j]) * gains[j] for j in range(m + 1))
        for i, base in enumerate(unit_root_polynomial(m)[: m + 1])
    ]
    c.append(1 << e)
    return c, e


def _dyadic(values) -> tuple[list[int], int]:
    """Integers ``N_i`` and one exponent ``E >= 0`` with ``values[i] == N_i / 2**E`` exactly
    (finite floats are dyadic rationals)."""
    ratios = [float(v).as_integer_ratio() for v in values]
    exponent = max(den.bit_length() - 1 for _, den in ratios)
    return [num << (exponent - den.bit_length() + 1) for num, den in ratios], exponent


def _shifted(numbers: list[int], e: int, center: complex) -> np.ndarray:
    r"""Ascending coefficients of :math:`P(c + w)` in ``w``, computed exactly and then rounded.

    ``P`` has the ascending coefficients ``numbers[i] / 2**e``; it and the float ``center``
    are dyadic rationals, so the Taylor shift runs on (Gaussian) integers and each coefficient
    is rounded once to a double (Python's int division rounds correctly). Around a cluster of
    roots at ``c`` the low coefficients are tiny differences of large numbers, which this
    keeps to full relative precision.
    """
    (re, im), f = _dyadic([center.real, center.imag])
    degree = len(numbers) - 1
    # D(W) = 2^(e + f degree) P((A + W) / 2^f) = sum_i N_i 2^(f (degree - i)) (A + W)^i
    real = [numbers[i] << (f * (degree - i)) for i in range(degree, -1, -1)]  # descending
    imag = [0] * (degree + 1)
    for i in range(degree):  # Horner's Taylor shift by A = re + i im
        for j in range(1, degree + 1 - i):
            real[j], imag[j] = (
                real[j] + re * real[j - 1] - im * imag[j - 1],
                imag[j] + re * imag[j - 1] + im * real[j - 1],
            )
    out = np.empty(degree + 1, dtype=complex)
    for j in range(degree + 1):  # coefficient of W^j is at index degree - j; w = W / 2^f
        scale = 1 << (e + f * (degree - j))
        out[j] = complex(real[degree - j] / scale, imag[degree - j] / scale)
    return out


def realised_roots(k: np.ndarray, centers, multiplicities) -> list[np.ndarray]:
    r"""The roots of :math:`\det(zI - M)` near each of ``centers``, for the gains ``k``.

    For each center ``c`` with multiplicity ``n`` (the requested poles), the ``n`` roots of the
    exact rational characteristic polynomial closest to ``c``: the polynomial is shifted to
    ``c`` exactly (:func:`_shifted`), scaled so that the cluster's roots have modulus about 1,
    and solved in double precision. A cluster of ``n`` poles split by rounding (by up to
    ``~eps^(1/n)``) is then resolved to a few ulp of its spread, where the eigenvalues of ``M``
    or ``np.roots`` of the unshifted polynomial are off by as much as the splitting itself.
    Cross-checked against 80-digit ``mpmath.polyroots`` in ``tests/observers/test_synthesis.py``.
    """
    numbers, e = exact_characteristic_polynomial(np.asarray(k, dtype=float))
    return roots_near(numbers, e, centers, multiplicities)


def roots_near(numbers: list[int], e: int, centers, multiplicities) -> list[np.ndarray]:
    """:func:`realised_roots` for the polynomial with ascending coefficients
    ``numbers[i] / 2**e`` (exact)."""
    found = []
    for center, n in zip(centers, multiplicities, strict=True):
        s = _shifted(numbers, e, complex(center))
        found.append(complex(center) + _nearest_roots(s, n))
    return found


def _integer_characteristic_polynomial(N: list[list[int]]) -> list[int]:
    r"""Descending coefficients of :math:`\det(zI - N)` for an integer matrix ``N``, exactly.

    Berkowitz's division-free algorithm: with :math:`N_k` the leading ``k x k`` block,
    partitioned as ``[[N_(k-1), c], [r, a]]``, the polynomial of :math:`N_k` is the Toeplitz
    matrix with first column ``[1, -a, -r c, -r N_(k-1) c, ..., -r N_(k-1)^(k-2) c]`` times
    that of :math:`N_{k-1}`.
    """
    n = len(N)
    p = [1]
    for k in range(1, n + 1):
        col = [1, -N[k - 1][k - 1]]
        v = [N[i][k - 1] for i in range(k - 1)]
        for _ in range(k - 1):
            col.append(-sum(N[k - 1][j] * v[j] for j in range(k - 1)))
            v = [sum(N[i][j] * v[j] for j in range(k - 1)) for i in range(k - 1)]
        p = [sum(col[i - j] * p[j] for j in range(min(i, k - 1) + 1)) for i in range(k + 1)]
    return p


def matrix_characteristic_polynomial(F) -> tuple[list[int], int]:
    r""":math:`\det(zI - F)` of a double-precision matrix ``F``, exactly: ascending integer
    coefficients ``c`` and an exponent ``e`` with coefficient ``i`` equal to ``c[i] / 2**e``
    (like :func:`exact_characteristic_polynomial`; floats are dyadic rationals)."""
    F = np.asarray(F, dtype=float)
    n = F.shape[0]
    flat, E = _dyadic(F.ravel().tolist())
    N = [flat[i * n : (i + 1) * n] for i in range(n)]
    descending = _integer_characteristic_polynomial(N)  # of N = 2^E F
    # coefficient of z^j in det(zI - F) is c_(n-j)(N) / 2^(E (n-j)) = c_(n-j)(N) 2^(E j) / 2^(nE)
    return [descending[n - j] << (E * j) for j in range(n + 1)], n * E


def polynomial_from_fractions(coefficients) -> tuple[list[int], int]:
    """Dyadic rationals (ascending, e.g. :func:`~hpdob.observers._position.realised_polynomial`)
    as integers over one power of two: ``(c, e)`` with coefficient ``i`` ``c[i] / 2**e``."""
    fractions = [Fraction(c) for c in coefficients]
    if any(f.denominator & (f.denominator - 1) for f in fractions):
        raise ValueError("the coefficients must be dyadic rationals")
    e = max(f.denominator.bit_length() - 1 for f in fractions)
    return [f.numerator << (e - f.denominator.bit_length() + 1) for f in fractions], e


def _nearest_roots(s: np.ndarray, n: int) -> np.ndarray:
    """The ``n`` roots of ``sum_j s_j w^j`` (ascending) closest to 0."""
    coefficients = s.tolist()
    size = [abs(c) for c in coefficients]
    if not any(size[:n]):  # w^n divides the polynomial: an exact n-fold root at 0
        return np.zeros(n, dtype=complex)
    logs = [math.log(a) if a > 0 else -math.inf for a in size]
    # Newton-polygon estimate of the cluster radius (balances s_0 .. s_n), in logarithms so
    # that neither tiny nor huge coefficients overflow.
    if size[n] > 0:
        log_rho = max((logs[j] - logs[n]) / (n - j) for j in range(n) if size[j] > 0)
    else:
        log_rho = 0.0
    # w = rho v: coefficients s_j rho^j, normalised to a largest modulus of 1; terms below
    # 1e-200 only carry roots far from the cluster (|v| >> 1) and are dropped.
    exponents = [x + j * log_rho for j, x in enumerate(logs)]
    top = max(exponents)
    scaled = [
        c / a * math.exp(x - top) if a > 0 and x - top > -460.0 else 0.0  # e^-460 ~ 1e-200
        for c, a, x in zip(coefficients, size, exponents, strict=True)
    ]
    roots = math.exp(log_rho) * np.roots(scaled[::-1])
    return roots[np.argsort(np.abs(roots), kind="stable")[:n]]


def _clusters(placed: np.ndarray, tolerance: float) -> list[list[int]]:
    """Indices of the requested poles grouped into clusters: poles closer than the tolerance
    radius of either are solved together (their realised roots cannot be told apart)."""
    if np.all(placed == placed[0]):  # one repeated pole (every bandwidth design)
        return [list(range(placed.size))]
    radius = tolerance * (1.0 - np.abs(placed))
    groups: list[list[int]] = []
    for i, p in enumerate(placed):
        near = [g for g in groups if any(abs(p - placed[j]) <= max(radius[i], radius[j])
                                         for j in g)]  # fmt: skip
        merged = [i] + [j for g in near for j in g]
        groups = [g for g in groups if g not in near] + [sorted(merged)]
    return sorted(groups)


def finite_gains(k, unit, dD: float, model) -> np.ndarray:
    """The gains ``L_i = k_i d / (d^T D_Dn)`` (rows), refused if a tiny ``d^T D_Dn`` (a
    subnormal ``Ts/J_n``) makes them overflow."""
    with np.errstate(over="ignore", invalid="ignore"):  # checked below
        G = np.outer(k, unit / dD)
    if not np.all(np.isfinite(G)):
        raise ParameterValueError(
            f"the gains L_i = k_i d / (d^T D_Dn) overflow: D_Dn = {np.asarray(model.D).tolist()} "
            f"is too small (J_n={model.J!r} kg m^2, Ts={model.Ts!r} s); use SI units with J_n "
            f"and Ts of a realistic scale"
        )
    return G


def realised_poles(k, placed, pole_tolerance, bandwidth, poles) -> np.ndarray:
    r"""The poles the gains ``k`` of an order-m design measuring the state realise, paired with
    the requested ``placed`` entry by entry (float if all real, else complex).

    A ParameterValueError if one lies further than ``pole_tolerance (1 - |p|)`` from its
    requested pole ``p`` (None: no check). ``bandwidth`` or ``poles`` (the request) are named
    in the message. Examples (``Ts = 1 ms``): order 10 at 100 rad/s realises poles up to
    ``|z| = 0.9548`` for the requested 0.9048 and is refused; orders 0-3 at 50-200 rad/s stay
    within 0.23% of ``1 - |p|``.
    """
    asked = f"bandwidth={bandwidth!r} rad/s" if bandwidth is not None else f"poles={_show(poles)}"
    numbers, e = exact_characteristic_polynomial(np.asarray(k, dtype=float))
    return check_realised(
        numbers, e, placed, pole_tolerance, asked=asked, what=f"order {len(placed) - 1}"
    )


def check_realised(numbers, e, placed, pole_tolerance, *, asked: str, what: str) -> np.ndarray:
    r"""The roots of the exact polynomial ``numbers[i] / 2**e`` (the realised characteristic
    polynomial of a design), paired with the requested poles ``placed``.

    A ParameterValueError naming ``asked`` (the request, e.g. ``"bandwidth=100.0 rad/s"``) and
    ``what`` (the design, e.g. ``"order 2"``) if a realised pole lies further than
    ``pole_tolerance (1 - |p|)`` from its requested pole ``p``; ``pole_tolerance`` None skips
    the check (the caller then decides stability, e.g. by :func:`stable`).
    """
    placed = np.asarray(placed)
    if pole_tolerance is None:
        tolerance = None
    else:
        tolerance = nonnegative(pole_tolerance, "pole_tolerance", "a fraction >= 0 or None")
    groups = _clusters(placed, POLE_TOLERANCE if tolerance is None else tolerance)
    centers = [placed[g[0]] for g in groups]
    found = roots_near(numbers, e, centers, [len(g) for g in groups])
    realised = np.empty(placed.size, dtype=complex)
    for group, roots in zip(groups, found, strict=True):
        if np.all(placed[group] == placed[group[0]]):  # a repeated pole: any pairing is one
            realised[group] = roots
            continue
        import scipy.optimize

        cost = np.abs(np.subtract.outer(placed[group], roots))
        rows, cols = scipy.optimize.linear_sum_assignment(cost)
        realised[np.asarray(group)[rows]] = roots[cols]
    off = np.abs(realised - placed) / (1.0 - np.abs(placed))
    worst = int(np.argmax(off))
    if tolerance is not None and off[worst] > tolerance:
        raise ParameterValueError(
            f"{asked} cannot be realised for {what} in double precision: with the gains "
            f"rounded to doubles the pole {_fmt(placed[worst])} is realised at "
            f"{_fmt(realised[worst])} (|z| = {abs(realised[worst]):.6g}), off by "
            f"{off[worst]:.3g} of its distance to the unit circle, more than pole_tolerance="
            f"{tolerance!r}; high orders and repeated poles near 1 are ill-conditioned. Use a "
            f"lower order, a higher bandwidth or distinct poles (or a larger pole_tolerance)"
        )
    return realised.real.copy() if np.all(realised.imag == 0.0) else realised
