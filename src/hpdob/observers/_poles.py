"""Poles of a design: validation (finite, inside the unit circle, in conjugate pairs) and
their formatting in messages and design summaries (shared by the order-m families)."""

from __future__ import annotations

import numpy as np

from .._validation import ParameterValueError, numeric_array

__all__ = ["fmt_complex", "fmt_pole", "validate_poles"]

#: Relative tolerance for matching complex-conjugate partners.
_PAIR_RTOL = 1e-9


def validate_poles(poles, count: int, label: str, order: int) -> np.ndarray:
    """``poles`` checked: ``count`` finite numbers inside the unit circle, complex ones in
    conjugate pairs (``label`` names the count in messages, e.g. ``"order + 1 = 2"``)."""
    values = numeric_array(poles, "poles", f"a sequence of {count} numbers", dtype=complex)
    if values.ndim == 0:
        values = values.reshape(1)
    if values.ndim != 1 or values.size != count:
        raise ParameterValueError(
            f"poles must have {label} entries for order {order}, got {values.size} ({poles!r})"
        )
    if not np.all(np.isfinite(values)):
        raise ParameterValueError(f"poles must be finite, got {poles!r}")
    outside = values[np.abs(values) >= 1.0]
    if outside.size:
        raise ParameterValueError(
            f"poles must lie strictly inside the unit circle (|p| < 1), got "
            f"{fmt_pole(outside[0])} with |p| = {abs(outside[0]):.6g}"
        )
    # Complex poles must come in conjugate pairs (with equal multiplicity).
    unmatched = [p for p in values if p.imag != 0.0]
    while unmatched:
        p = unmatched.pop(0)
        scale = max(abs(p), 1e-300)
        partner = next((q for q in unmatched if abs(q - p.conjugate()) <= _PAIR_RTOL * scale), None)
        if partner is None:
            raise ParameterValueError(
                f"poles must come in complex-conjugate pairs so the gains are real: "
                f"{fmt_pole(p)} has no partner {fmt_pole(p.conjugate())} in "
                f"{poles!r}"
            )
        unmatched.remove(partner)
    if np.all(values.imag == 0.0):
        return values.real.copy()
    return values


def fmt_pole(p: complex) -> str:
    p = complex(p)
    return f"{p.real:.6g}" if p.imag == 0.0 else f"({p.real:.6g}{p.imag:+.6g}j)"


def fmt_complex(p) -> str:
    p = complex(p)
    return repr(p.real) if p.imag == 0.0 else f"{p.real!r}{p.imag:+}j"
