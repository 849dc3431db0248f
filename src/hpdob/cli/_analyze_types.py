"""The argparse types of ``hpdob analyze``: grids, orders, families and tolerances."""

from __future__ import annotations

import argparse
import math

import numpy as np

from ._options import finite

__all__ = ["grid", "measurements", "orders", "pole_tolerance", "positive_real"]


def grid(text: str) -> list[float]:
    """``LO:HI:N`` (N log-spaced values) or a non-empty comma-separated list of numbers."""
    try:
        if ":" in text:
            lo, hi, n = text.split(":")
            lo, hi, count = float(lo), float(hi), int(n)
            if not (lo > 0 and hi > 0 and count >= 1):
                raise ValueError
            return np.geomspace(lo, hi, count).tolist()
        values = [float(item) for item in text.split(",") if item.strip()]
        if not values:
            raise ValueError
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
    try:
        return [int(item) for item in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated integer orders, got {text!r}"
        ) from None


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
