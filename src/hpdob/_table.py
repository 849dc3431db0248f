"""Column tables of analysis results: CSV without pandas, and ``pandas.DataFrame``."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ._files import atomic_path

__all__ = ["columns_to_csv", "columns_to_pandas"]


def _cell(value) -> str:
    if isinstance(value, (str, np.str_)):
        return str(value)
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    return repr(float(value))


def columns_to_csv(columns: dict, path) -> Path:
    """Write equal-length columns ``{name: values}`` to ``path`` (header row, full precision).

    Atomically: a reader never sees a truncated file (:func:`hpdob._files.atomic_path`).
    """
    path = Path(path)
    with atomic_path(path) as temporary, temporary.open("w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f)
        writer.writerow(list(columns))
        writer.writerows([_cell(v) for v in row] for row in zip(*columns.values(), strict=True))
    return path


def columns_to_pandas(columns: dict, *, caller: str = "to_pandas()"):
    """The columns as a ``pandas.DataFrame`` (needs pandas; ``caller`` names the method)."""
    try:
        import pandas as pd
    except ImportError as err:  # pragma: no cover - depends on the environment
        raise ImportError(
            f"{caller} needs pandas; install it with `pip install pandas` or "
            "`pip install hpdob[pandas]`"
        ) from err
    return pd.DataFrame(columns)
