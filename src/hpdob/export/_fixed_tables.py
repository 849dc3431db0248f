"""Helpers of :func:`hpdob.export.fixed_point_design`: ranges, Q formats, l1 gains, the
count-difference frame and the quantisation of one row (``docs/deployment.md``)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._validation import ParameterValueError, as_int, positive
from ..observers import LinearObserver

__all__ = ["FixedPointRow"]

#: The series of the l1 norms are summed until ||F^J||_inf falls below this (tail bounded).
_TAIL = 1e-13


@dataclass(frozen=True)
class FixedPointRow:
    """One row of integer arithmetic: ``sat(round(sum_j C_j V_j 2^k_j / 2^shift), limit)``.

    Attributes
    ----------
    target : str
        What the row computes (``"q1"``, ``"tau_hat"``, ...).
    terms : tuple of (int, int, int)
        ``(C_j, j, k_j)``: the term ``C_j V_j 2^k_j`` with ``|C_j| <= 2^(W-1) - 1`` and operand
        ``j`` of the row's operand vector (``FixedPointDesign.operands`` or
        ``FixedPointDesign.reset_operands``).
    shift : int
        Right shift from the accumulator to the target's Q format (``0 <= shift <= 2W - 2``).
    limit : int
        Saturation limit: the result is clamped to ``[-limit, limit]``.
    frac_bits : int
        Fractional bits ``a`` of the accumulator: ``acc * 2^-a`` is the row's value [SI].
    """

    target: str
    terms: tuple
    shift: int
    limit: int
    frac_bits: int


def _check_ranges(counts_per_rev, omega_max, u_max, tau_max):
    cpr = as_int(counts_per_rev, "counts_per_rev", "a positive integer number of encoder "
                 "counts per revolution", minimum=1, maximum=2**53)  # fmt: skip
    omega_max = positive(omega_max, "omega_max", "a positive finite velocity range [rad/s]")
    u_max = positive(u_max, "u_max", "a positive finite torque command range [N m]")
    tau_max = positive(tau_max, "tau_max", "a positive finite estimate range [N m]")
    return cpr, omega_max, u_max, tau_max


def _frac_bits(bound: float, word: int, name: str, value_name: str) -> int:
    """Largest fractional bit count whose range ``(2^(W-1) - 1) 2^-f`` holds ``bound``."""
    top = 2 ** (word - 1) - 1
    f = math.floor(math.log2(top) - math.log2(bound))
    while top * 2.0**-f < bound:  # log2 rounding
        f -= 1
    if f < -(word - 1) or f > 4 * word:
        raise ParameterValueError(
            f"{name} cannot be scaled into a {word}-bit word: {value_name} = {bound!r} needs "
            f"2^{-f} per bit (the formats allow 2^{-4 * word} to 2^{word - 1})"
        )
    return f


def _powers(F: np.ndarray):
    """``F^j`` for ``j = 0 .. J-1`` with ``||F^J||_inf < _TAIL``, and ``||F^J||_inf``."""
    n = F.shape[0]
    out, X = [], np.eye(n)
    for _ in range(200_000):
        out.append(X)
        X = X @ F
        norm = float(np.abs(X).sum(axis=1).max())
        if norm < _TAIL:
            return np.array(out), norm
        if not np.isfinite(norm) or norm > 1e30:
            break
    raise ParameterValueError(
        "observer must be stable in fixed point: the quantised state matrix F has a pole on "
        "or outside the unit circle (the design's coefficients cannot be represented)"
    )


def _l1_gain(powers, tail, B, C=None):
    """Entry-wise ``sum_j |C F^j B|`` (C = I by default), with the tail bound added."""
    terms = np.abs(powers @ B) if C is None else np.abs(C @ powers @ B)
    total = terms.sum(axis=0)
    # sum_{j>=J} |C F^j B| <= (tail / (1 - tail)) * max over entries of the first J terms
    return total + tail / (1.0 - tail) * float(terms.sum(axis=0).max())


def _peak_gain(powers, tail):
    """Entry-wise ``sup_k |F^k|`` (for the free response of the initial state)."""
    return np.abs(powers).max(axis=0) + tail


def _frame(system: LinearObserver):
    """The observer in the count-difference frame (real coefficients per operand)."""
    F, G, H, E, N = (np.asarray(a, dtype=float) for a in (system.F, system.G, system.H,
                                                         system.E, system.N))  # fmt: skip
    n = F.shape[0]
    try:
        d = np.linalg.solve(np.eye(n) - F, G[:, 0])
    except np.linalg.LinAlgError:
        raise ParameterValueError(
            "observer must have no pole at z = 1 (I - F singular): its state does not settle "
            "at a constant angle, so it cannot be written in count differences"
        ) from None
    eps = np.finfo(float).eps
    scale = np.abs(H) @ np.abs(d) + np.abs(E[:, 0])
    # residuals of the frame change, plus a bound on their own evaluation in binary64
    residual = np.abs(H @ d + E[:, 0]) + 4 * n * eps * scale
    update_residual = np.abs((F - np.eye(n)) @ d + G[:, 0]) + 4 * n * eps * (
        (np.abs(F) + np.eye(n)) @ np.abs(d) + np.abs(G[:, 0])
    )
    if np.any(residual > 1e-6 * np.maximum(scale, 1e-300)):
        raise ParameterValueError(
            "observer's outputs must not depend on a constant angle offset (zero DC gain from "
            f"theta, |H d + E_theta| = {residual.max():.3g}); it cannot run on count "
            "differences"
        )
    # per rad of count difference; the count's LSB (2 pi / cpr) is applied with the others
    Gq = np.column_stack([G[:, 0] - d, G[:, 1:-1], G[:, -1]])
    Eq = E
    Nq = N[:, 1:]  # (omega0, tau0): N_theta theta0 = d theta0 up to reset_residual
    reset_residual = np.abs(N[:, 0] - d) + 4 * eps * (np.abs(N[:, 0]) + np.abs(d))
    return F, Gq, H, Eq, Nq, (residual, update_residual, reset_residual)


def _quantise_row(target, coeffs, scales, vmax, f_target, limit, word, what, reach=None):
    """Integer row for real ``coeffs`` on operands of LSB ``scales`` and bound ``vmax``
    (``reach``: the operands' proven bounds, for the test that no term that matters is lost).

    Every coefficient gets a full word (``|C_j| <= 2^(W-1) - 1``) at its own exponent
    ``a_j <= a``; its product is scaled to the accumulator by the exact factor ``2^(a - a_j)``.
    ``a`` is the finest accumulator whose worst-case sum fits ``2W - 2`` bits.
    """
    top = 2 ** (word - 1) - 1
    acc_top = 2 ** (2 * word - 2) - 1
    real = np.asarray(coeffs, dtype=float) * np.asarray(scales, dtype=float)
    nonzero = real != 0.0
    if not nonzero.any():
        return FixedPointRow(target, (), 0, limit, f_target), real

    def exponent(c, a):
        e = min(a, math.floor(math.log2(top / abs(c))))
        while abs(round(c * 2.0**e)) > top:
            e -= 1
        return e

    a = f_target + 2 * word - 2
    while True:
        terms = []
        for j, c in enumerate(real):
            if c != 0.0:
                e = exponent(c, a)
                terms.append((round(c * 2.0**e), j, a - e))
        shift = a - f_target
        half = 2 ** (shift - 1) if shift > 0 else 0
        total = sum(abs(C) * 2**k * vmax[j] for C, j, k in terms) + half
        if total <= acc_top or shift < 0:
            break
        a -= 1
    if shift < 0:
        raise ParameterValueError(
            f"{what}: the coefficients of {target} cannot be represented: they need an "
            f"accumulator coarser than {target}'s Q format (largest |c| = "
            f"{np.abs(real).max():.3g} per bit); widen the declared ranges or use dtype 'double'"
        )
    quantised = np.zeros_like(real)
    for C, j, k in terms:
        quantised[j] = C * 2.0 ** (k - a)
    lsb_target = 2.0**-f_target
    for c, C, v in zip(real, quantised, vmax if reach is None else reach, strict=True):
        if c != 0.0 and C == 0.0 and abs(c) * v > lsb_target:
            raise ParameterValueError(
                f"{what}: a coefficient of {target} ({c:.3g} per bit) rounds to zero in the "
                f"{2 * word}-bit accumulator although it can move {target} by "
                f"{abs(c) * v / lsb_target:.3g} bits; the design's coefficients cannot be "
                "represented (its gains span too many orders of magnitude)"
            )
    terms = tuple(t for t in terms if t[0] != 0)
    return FixedPointRow(target, terms, shift, limit, a), quantised
