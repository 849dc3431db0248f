"""Outputs of the analysis commands: the ``--dpi`` option, checked figures and strict JSON.

Figures are limited in resolution and size up front (matplotlib's renderer otherwise runs out
of memory, ``std::bad_alloc``, instead of failing cleanly), and written into a staged set of
outputs (:func:`hpdob._files.staged_outputs`), like the JSON and CSV files.
"""

from __future__ import annotations

import argparse
import math

from ..simulation import json_ready
from ._errors import CLIError

__all__ = ["MAX_DPI", "MAX_PIXELS", "dpi_argument", "save_figure", "write_json"]

#: Highest --dpi, and most pixels along either side of a figure: beyond them matplotlib's
#: renderer runs out of memory (std::bad_alloc) instead of failing cleanly.
MAX_DPI = 1200
MAX_PIXELS = 16384
#: Lowest --dpi: below it the figures collapse to zero pixels (matplotlib warns, then fails).
MIN_DPI = 10


def dpi_argument(text: str) -> float:
    """A resolution [dots per inch]: a finite number in (0, MAX_DPI]."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and MIN_DPI <= value <= MAX_DPI):
        raise argparse.ArgumentTypeError(
            f"expected a resolution of {MIN_DPI} to {MAX_DPI} dots per inch, got {text!r}"
        )
    return value


def save_figure(fig, files, name: str, dpi: float) -> None:
    """Stage ``fig`` as ``name`` in ``files`` at ``dpi`` and close it; a CLIError if it would
    exceed :data:`MAX_PIXELS` per side or matplotlib cannot draw it."""
    import matplotlib.pyplot as plt

    try:
        width, height = fig.get_size_inches() * dpi
        if max(width, height) > MAX_PIXELS:
            raise CLIError(
                f"--dpi {dpi:g} makes {name} {width:.0f} x {height:.0f} pixels; at most "
                f"{MAX_PIXELS} pixels per side are supported"
            )
        try:
            files.save_figure(name, fig, dpi=dpi)
        except (OverflowError, ValueError) as err:  # e.g. log axes over ~300 decades
            raise CLIError(
                f"cannot draw {name} (the grids may span too many decades): "
                f"{type(err).__name__}: {err}"
            ) from None
    finally:
        plt.close(fig)


def write_json(files, name: str, data: dict) -> None:
    """Stage ``data`` as strict JSON (NaN as null) named ``name`` in ``files``."""
    files.write_json(name, json_ready(data))
