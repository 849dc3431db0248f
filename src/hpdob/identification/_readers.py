"""Readers of logged tables: CSV, Parquet and MATLAB ``.mat`` files, by column name.

Each reader returns ``{name: raw values}`` for the requested names and the sorted list of
names the file holds; :func:`hpdob.identification.read_log` validates the values.
"""

from __future__ import annotations

import array
import csv
from pathlib import Path

import numpy as np

from .._validation import ParameterValueError

__all__ = ["FORMATS", "parquet_blocks", "parquet_rows", "read_columns", "scalar"]

#: File name suffixes of each format.
FORMATS = {
    ".csv": "csv",
    ".txt": "csv",
    ".tsv": "csv",
    ".parquet": "parquet",
    ".pq": "parquet",
    ".mat": "mat",
}


def read_columns(path: Path, wanted: dict[str, str], progress=None) -> dict[str, np.ndarray]:
    """Read the columns ``{role: name}`` of ``path``; the result maps each role to its values.

    Raises
    ------
    ParameterValueError
        For an unknown format, an unreadable file, a missing column (the message lists the
        available ones) or a column that holds something other than numbers.
    """
    kind = FORMATS.get(path.suffix.lower())
    if kind is None:
        raise ParameterValueError(
            f"cannot tell the format of {path.name}: the name must end in one of "
            f"{', '.join(sorted(FORMATS))} (CSV, Parquet or MATLAB .mat)"
        )
    if not path.is_file():
        raise ParameterValueError(f"log file {path} does not exist or is not a file")
    if kind == "csv":
        return _read_csv(path, wanted, progress)
    total = path.stat().st_size
    if progress is not None:
        progress(0, total)
    data = {"parquet": _read_parquet, "mat": _read_mat}[kind](path, wanted)
    if progress is not None:
        progress(total, total)
    return data


def _missing(path: Path, wanted: dict[str, str], available) -> None:
    for role, name in wanted.items():
        if name not in available:
            listed = ", ".join(sorted(str(a) for a in available)) or "none"
            raise ParameterValueError(
                f"{role} column {name!r} is not in {path.name}; available: {listed}"
            )


def _one_line(err: Exception) -> str:
    """A library's error message on one line (pyarrow's end in a newline, some span several)."""
    return " ".join(str(err).split())


def _read_csv(path: Path, wanted: dict[str, str], progress=None) -> dict[str, np.ndarray]:
    try:
        return _parse_csv(path, wanted, progress)
    except UnicodeDecodeError as err:
        raise ParameterValueError(
            f"{path.name} is not UTF-8 text (byte {err.start} is "
            f"{err.object[err.start : err.start + 1]!r}): save the log as UTF-8 CSV"
        ) from None
    except csv.Error as err:  # e.g. a field over the csv module's limit (131072 characters)
        raise ParameterValueError(f"cannot read {path.name} as CSV: {_one_line(err)}") from None


#: Characters of a CSV log between two calls of ``progress``.
PROGRESS_STEP = 1 << 20


def _counted(handle, progress, total: int):
    """The lines of ``handle``, calling ``progress(done, total)`` every
    :data:`PROGRESS_STEP` characters (and at the start and the end)."""
    progress(0, total)
    done, report = 0, PROGRESS_STEP
    for text in handle:
        done += len(text)
        if done >= report:
            progress(min(done, total), total)
            report = done + PROGRESS_STEP
        yield text
    progress(total, total)


def _parse_csv(path: Path, wanted: dict[str, str], progress=None) -> dict[str, np.ndarray]:
    with path.open(newline="", encoding="utf-8-sig") as handle:
        first = handle.readline()
        delimiter = max(",;\t", key=first.count) if first.strip() else ","
        handle.seek(0)
        lines = handle if progress is None else _counted(handle, progress, path.stat().st_size)
        rows = csv.reader(lines, delimiter=delimiter)
        header = [cell.strip() for cell in next(rows, [])]
        _missing(path, wanted, header)
        index = {role: header.index(name) for role, name in wanted.items()}
        # 8 bytes a value (a list of floats holds 32: a pointer and a float object)
        values = {role: array.array("d") for role in wanted}
        for line, row in enumerate(rows, start=2):
            if not row or all(not cell.strip() for cell in row):
                continue  # blank line
            if len(row) != len(header):
                raise ParameterValueError(
                    f"{path.name} line {line} has {len(row)} fields, the header has {len(header)}"
                )
            for role, column in index.items():
                values[role].append(_number(row[column], role, wanted[role], line, path))
    out = {}
    for role in list(values):  # each column moved into numpy's memory and released in turn
        column = values.pop(role)
        out[role] = np.frombuffer(column, dtype=float).copy() if column else np.zeros(0)
        del column
        out[role].setflags(write=False)  # nobody else holds it: a Log takes it without a copy
    return out


def _number(cell: str, role: str, name: str, line: int, path: Path) -> float:
    try:
        if "_" in cell:  # Python's float() reads "0_4" as 4.0 (digit grouping): not a CSV number
            raise ValueError(cell)
        return float(cell)
    except ValueError:
        sample = line - 2
        raise ParameterValueError(
            f"{role} column {name!r} of {path.name} is not numeric: sample {sample} "
            f"(line {line}) holds {cell!r}"
        ) from None


def _parquet_file(path: Path, wanted: dict[str, str]):
    """The ``pyarrow.parquet.ParquetFile`` of ``path``, its ``wanted`` columns checked to exist
    and hold numbers."""
    try:
        import pyarrow.parquet as pq
    except ImportError as err:  # pragma: no cover - pyarrow is in the [sweep] and [test] extras
        raise ImportError(
            "reading Parquet logs needs pyarrow: pip install pyarrow (or hpdob[sweep])"
        ) from err
    try:
        schema = pq.read_schema(path)
    except Exception as err:  # pyarrow raises its own exception types
        raise ParameterValueError(f"cannot read {path.name} as Parquet: {_one_line(err)}") from err
    _missing(path, wanted, schema.names)
    for role, name in wanted.items():
        kind = str(schema.field(name).type)
        if not (kind.startswith(("int", "uint", "float", "double", "halffloat", "decimal"))):
            raise ParameterValueError(
                f"{role} column {name!r} of {path.name} is not numeric: its type is {kind}"
            )
    try:
        return pq.ParquetFile(path, pre_buffer=False, buffer_size=1 << 20)  # pages as needed
    except Exception as err:  # pyarrow raises its own exception types
        raise ParameterValueError(f"cannot read {path.name} as Parquet: {_one_line(err)}") from err


def parquet_rows(path: Path, wanted: dict[str, str]) -> int:
    """The number of rows of the Parquet file ``path`` (its ``wanted`` columns checked)."""
    return _parquet_file(path, wanted).metadata.num_rows


#: Rows per block of :func:`parquet_blocks` (0.5 MB per column).
PARQUET_BLOCK = 1 << 16


def parquet_blocks(path: Path, wanted: dict[str, str]):
    """The ``wanted`` columns of the Parquet file ``path`` as float64 arrays ``{role: values}``,
    in blocks of at most :data:`PARQUET_BLOCK` rows (pyarrow reads the pages as they are needed
    and holds little more than a block)."""
    import pyarrow as pa

    file = _parquet_file(path, wanted)
    names = list(dict.fromkeys(wanted.values()))
    pool = pa.default_memory_pool()
    try:
        for group in range(file.num_row_groups):
            for batch in file.iter_batches(batch_size=PARQUET_BLOCK, row_groups=[group],
                                           columns=names, use_threads=False):  # fmt: skip
                columns = [c.to_numpy(zero_copy_only=False) for c in batch.columns]
                yield {role: np.asarray(columns[names.index(name)], dtype=float)
                       for role, name in wanted.items()}  # fmt: skip
            pool.release_unused()  # pyarrow's allocator would keep the row group's pages
    except ParameterValueError:  # pragma: no cover - raised above, not by pyarrow
        raise
    except Exception as err:  # pyarrow raises its own exception types
        raise ParameterValueError(f"cannot read {path.name} as Parquet: {_one_line(err)}") from err


def _read_parquet(path: Path, wanted: dict[str, str]) -> dict[str, np.ndarray]:
    # Row group by row group into arrays allocated once: a log of 1e7 samples is held once,
    # not also as pyarrow's decoded chunks and their concatenation.
    out = {role: np.empty(parquet_rows(path, wanted)) for role in wanted}
    start = 0
    for block in parquet_blocks(path, wanted):
        stop = start + next(iter(block.values())).size
        for role, values in block.items():
            out[role][start:stop] = values
        start = stop
    for column in out.values():
        column.setflags(write=False)  # nobody else holds it: a Log takes it without a copy
    return out


def _read_mat(path: Path, wanted: dict[str, str]) -> dict[str, np.ndarray]:
    import scipy.io

    try:
        # the variables asked for only (a log's other signals are not held); the names of
        # all of them only to say which are there when one is missing
        data = scipy.io.loadmat(path, variable_names=sorted(set(wanted.values())))
    except NotImplementedError as err:  # MATLAB v7.3 files are HDF5
        raise ParameterValueError(
            f"{path.name} is a MATLAB v7.3 (HDF5) file, which scipy cannot read; save it "
            "with save(..., '-v7') or export the signals to CSV or Parquet"
        ) from err
    except (ValueError, TypeError, OSError) as err:
        raise ParameterValueError(
            f"cannot read {path.name} as a MATLAB file: {_one_line(err)}"
        ) from err
    variables = {key: value for key, value in data.items() if not key.startswith("__")}
    if any(name not in variables for name in wanted.values()):
        _missing(path, wanted, [name for name, _, _ in scipy.io.whosmat(path)])
    out = {}
    for role, name in wanted.items():
        value = variables[name]
        if not isinstance(value, np.ndarray) or value.dtype.kind not in "iuf":
            kind = value.dtype if isinstance(value, np.ndarray) else type(value).__name__
            raise ParameterValueError(
                f"{role} variable {name!r} of {path.name} is not numeric (it holds {kind})"
            )
        if value.ndim > 2 or (value.ndim == 2 and 1 not in value.shape):
            raise ParameterValueError(
                f"{role} variable {name!r} of {path.name} must be a vector, got shape {value.shape}"
            )
        out[role] = _frozen(np.asarray(value, dtype=float).ravel())
    return out


def _frozen(array: np.ndarray) -> np.ndarray:
    """``array`` read-only down to the memory it views, which only the reader holds (scipy's
    arrays view the file's bytes): a Log then takes it without a copy."""
    view = array
    while isinstance(view, np.ndarray):
        view.setflags(write=False)
        view = view.base
    return array


def scalar(values: np.ndarray, role: str, name: str, path: Path) -> float:
    """The single value of a scalar variable (or of a column holding one value in every row)."""
    if values.size == 0 or np.any(values != values.flat[0]):
        raise ParameterValueError(
            f"{role} {name!r} of {path.name} must hold a single number, got {values.size} "
            "different samples"
        )
    return float(values.flat[0])
