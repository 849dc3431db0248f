"""The argparse types of ``hpdob analyze``: grids, orders, families and tolerances."""

from __future__ import annotations

import argparse
import math

import numpy as np

from ._options import finite

__all__ = ["grid", "measurements", "orders", "pole_tolerance", "positive_real"]


#: Most values of one analysis grid (``--bandwidths``, ``--values``): sized up front, before
#: numpy allocates (``10:2000:100000000`` ended in a MemoryError after 12 s).
MAX_GRID_VALUES = 10_000


def grid(text: str) -> list[float]:
    """``LO:HI:N`` (N log-spaced values) or a non-empty comma-separated list of finite numbers,
    of at most :data:`MAX_GRID_VALUES` values."""
    try:
        if ":" in text:
            lo, hi, n = text.split(":")
            lo, hi, count = float(lo), float(hi), int(n)
            if not (0 < lo < math.inf and 0 < hi < math.inf and count >= 1):
                raise ValueError
        else:
            values = [float(item) for item in text.split(",") if item.strip()]
            if not values or not all(math.isfinite(v) for v in values):
                raise ValueError
            count = len(values)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected LO:HI:N (N log-spaced positive finite values) or finite values as at "
            f"least one comma-separated number, got {text!r}"
        ) from None
    if count > MAX_GRID_VALUES:
        raise argparse.ArgumentTypeError(
            f"a grid has at most {MAX_GRID_VALUES} values, got {count} in {text!r}"
        )
    try:
        if ":" in text:
            return np.geomspace(lo, hi, count).tolist()
        return values
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected LO:HI:N (N log-spaced positive values) or at least one "
            f"comma-separated number, got {text!r}"
        ) from None


def positive_real(text: str) -> float:
    """A finite number > 0 (e.g. ``--bandwidth`` of ``stability``)."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive finite number, got {text!r}")
    return value


def orders(text: str) -> list[int]:
    """Comma-separated distinct integer orders (a repeated one is refused up front: the maps
    were computed before the error)."""
    try:
        values = [int(item) for item in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated integer orders, got {text!r}"
        ) from None
    repeated = sorted({v for v in values if values.count(v) > 1})
    if repeated:
        raise argparse.ArgumentTypeError(
            f"expected distinct orders, got {text!r} (order {repeated[0]} twice)"
        )
    return values


def measurements(text: str) -> list[str]:
    items = [item.strip() for item in text.split(",") if item.strip()]
    if not items or any(item not in ("state", "position") for item in items):
        raise argparse.ArgumentTypeError(
            f"expected comma-separated 'state' and/or 'position', got {text!r}"
        )
    return items


def pole_tolerance(text: str):
    """``none`` or a number (argparse type of ``--pole-tolerance``; the value is checked by
    the design)."""
    return None if text.strip().lower() == "none" else finite(text)
