"""Column tables of analysis results: CSV without pandas, and ``pandas.DataFrame``."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ._files import atomic_path

__all__ = ["CsvTable", "columns_to_csv", "columns_to_pandas"]


def _cell(value) -> str:
    if isinstance(value, (str, np.str_)):
        return str(value)
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    return repr(float(value))


def _float_columns(columns: dict) -> list | None:
    """The columns as float64 vectors of one length if every one is a float array (the traces
    of a run or a log) of at least ``_COMPILED_ROWS`` rows; otherwise None."""
    values = list(columns.values())
    if not values or not all(
        isinstance(v, np.ndarray) and v.ndim == 1 and v.dtype.kind == "f" for v in values
    ):
        return None
    if len({v.size for v in values}) != 1 or values[0].size < _COMPILED_ROWS:
        return None
    return [np.ascontiguousarray(v, dtype=np.float64) for v in values]


#: Fewer rows are written by the csv module (no compilation or thread start-up for a table).
_COMPILED_ROWS = 2000


def columns_to_csv(columns: dict, path, progress=None) -> Path:
    """Write equal-length columns ``{name: values}`` to ``path`` (header row, full precision).

    Every number is written as ``repr`` writes it, rows by :mod:`csv`'s default dialect. Long
    float columns (traces, logs) are formatted column-wise in compiled code
    (:mod:`hpdob._csv_floats`), into the same bytes, ``progress(rows written, rows)`` called
    after each chunk of 32768 rows (a short table: once, at its end). Atomically: a reader
    never sees a truncated file (:func:`hpdob._files.atomic_path`).
    """
    if progress is not None and not callable(progress):
        from ._validation import ParameterTypeError

        raise ParameterTypeError(
            f"progress must be a callable progress(done, total) or None, got {progress!r} of "
            f"type {type(progress).__name__}"
        )
    path = Path(path)
    floats = _float_columns(columns)
    with atomic_path(path) as temporary, temporary.open("w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f)
        writer.writerow(list(columns))
        if floats is None:
            rows = [[_cell(v) for v in row] for row in zip(*columns.values(), strict=True)]
            writer.writerows(rows)
            if progress is not None:
                progress(len(rows), len(rows))
        else:
            from ._csv_floats import write_float_rows

            f.flush()
            write_float_rows(f.buffer, floats, progress)
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


class CsvTable:
    """What a result with a long-format table shares: :meth:`to_csv` of the columns its
    ``_columns()`` gives (``{name: equal-length column}``); its ``to_pandas``, which documents
    those columns, is the result's own."""

    __slots__ = ()

    def _columns(self) -> dict:  # pragma: no cover - every table defines its columns
        raise NotImplementedError

    def to_csv(self, path):
        """Write the long-format table of :meth:`to_pandas` as CSV (no pandas needed).

        Parameters
        ----------
        path : str or os.PathLike
            The file to write (atomically; replaced if it exists).

        Returns
        -------
        pathlib.Path
            ``path``.
        """
        return columns_to_csv(self._columns(), path)
