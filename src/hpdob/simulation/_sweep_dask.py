"""The dask path of :func:`hpdob.sweep`, what a cluster that fails part-way leaves, and how a
later run resumes from it."""

from __future__ import annotations

import contextlib
import math

from .._interrupts import Interrupted, checkpoint
from .._validation import ParameterTypeError, ParameterValueError

__all__ = ["SweepIncomplete", "SweepInterrupted", "resumed_rows"]


class SweepIncomplete(RuntimeError):
    """A dask sweep whose cluster failed part-way (scheduler lost, workers killed repeatedly).

    ``rows`` is the DataFrame of the scenarios that finished (as :func:`sweep` returns, fewer
    rows), ``missing`` the numbers of the others, ``cause`` the cluster's error. The CLI
    writes ``rows`` to a partial file and names what is missing instead of losing the
    finished work; ``sweep(..., resume=rows)`` runs only the missing scenarios.
    """

    def __init__(self, rows, missing, cause: BaseException):
        self.rows, self.missing, self.cause = rows, list(missing), cause
        done = len(rows)
        super().__init__(
            f"the dask cluster failed after {done} of {done + len(self.missing)} scenarios "
            f"({type(cause).__name__}: {' '.join(str(cause).split())[:200]})"
        )


class SweepInterrupted(Interrupted):
    """A sweep interrupted by Ctrl-C (or SIGTERM, SIGHUP under ``hpdob``), local or on dask.

    A ``KeyboardInterrupt``: code that catches those still does. ``rows`` is the DataFrame of
    the scenarios that finished before the interrupt (those of ``resume`` included),
    ``missing`` the numbers of the others and ``signum`` the signal; as for
    :class:`SweepIncomplete`, ``sweep(..., resume=rows)`` runs only the missing scenarios.
    """

    def __init__(self, rows, missing, signum: int):
        super().__init__(signum)
        self.rows, self.missing = rows, list(missing)


class _Incomplete(Exception):
    """Internal: the rows finished before a dask cluster failed (cause: ``__cause__``)."""

    def __init__(self, rows, cause):
        super().__init__(str(cause))
        self.rows = rows


def _run_dask(base, scenarios, scheduler, update, rows, *, run_chunk, chunks_of) -> list:
    """Run ``scenarios`` in chunks (``chunks_of(scenarios, workers)``) of ``run_chunk`` on dask,
    appending the finished rows to ``rows`` (the caller keeps them if an interrupt ends it)."""
    try:
        from dask.distributed import Client
        from dask.distributed import as_completed as dask_completed
    except ImportError as err:  # pragma: no cover - depends on the environment
        raise ImportError(
            "a scheduler address or Client needs dask.distributed: pip install 'hpdob[dask]'"
        ) from err
    own = isinstance(scheduler, str)
    client = Client(scheduler) if own else scheduler
    try:
        chunks = chunks_of(scenarios, len(client.scheduler_info().get("workers", {})))
        # Each task carries the (small) base itself rather than a scattered copy: tasks then
        # have no data dependencies, so a task whose worker dies is simply run again elsewhere
        # (scattered data lost with a worker cancels its dependants: "lost dependencies").
        # pure=False: never reuse results across sweeps; retries also covers transient failures.
        futures = [client.submit(run_chunk, base, chunk, pure=False, retries=3) for chunk in chunks]
        try:
            for future in dask_completed(futures):
                try:
                    chunk_rows = future.result()
                except Exception as err:  # the cluster failed (run_chunk records row errors)
                    with contextlib.suppress(Exception):
                        client.cancel(futures)
                    raise _Incomplete(rows, err) from err
                rows.extend(chunk_rows)
                update(len(chunk_rows))
                checkpoint("sweep-chunk")
        except _Incomplete:
            raise
        except BaseException:  # an interrupt or a failure: nothing more may run for us
            with contextlib.suppress(Exception):
                client.cancel(futures)
            raise
        return rows
    finally:
        if own:
            client.close()


def resumed_rows(resume, scenarios: list, columns: list) -> list[dict]:
    """The rows of ``resume`` (an earlier, incomplete run's DataFrame) as :func:`sweep`'s row
    dicts, after checking that they belong to this sweep: the same columns, scenario numbers
    within ``range(len(scenarios))`` and each once, and every row's parameters equal to its
    scenario's (a partial file of another spec or seed is refused, not merged)."""
    if type(resume).__name__ != "DataFrame":
        raise ParameterTypeError(
            f"resume must be the pandas DataFrame of an incomplete run of this sweep, got "
            f"{type(resume).__name__}"
        )
    if list(resume.columns) != columns:
        raise ParameterValueError(
            f"resume must have this sweep's columns {columns}, got {list(resume.columns)}: "
            "it is not a result of this sweep"
        )
    rows = resume.to_dict("records")
    seen = set()
    for row in rows:
        index = row["scenario"]
        if isinstance(index, float) and index.is_integer():
            index = int(index)
        if not isinstance(index, int) or isinstance(index, bool) or not 0 <= index < len(scenarios):
            raise ParameterValueError(
                f"resume's scenario must be a whole number from 0 to {len(scenarios) - 1} (this "
                f"sweep has {len(scenarios)} scenarios), got {row['scenario']!r}"
            )
        if index in seen:
            raise ParameterValueError(f"resume holds scenario {index} twice")
        seen.add(index)
        row["scenario"] = index
        for path, value in scenarios[index].items():
            given = row[path]
            same = given == value or (
                isinstance(given, float) and isinstance(value, float)
                and math.isnan(given) and math.isnan(value)
            )  # fmt: skip
            if not same:
                raise ParameterValueError(
                    f"resume's scenario {index} has {path} = {given!r}, but this sweep's has "
                    f"{value!r}: the rows come from another spec or seed"
                )
            row[path] = value  # the sweep's own value and type (a file read back may differ)
        if not isinstance(row["error"], str):  # an empty cell read back from a CSV
            row["error"] = (
                "" if row["error"] is None or row["error"] != row["error"] else str(row["error"])
            )
    return rows
