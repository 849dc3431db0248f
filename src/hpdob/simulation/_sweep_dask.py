"""The dask path of :func:`hpdob.sweep`, and what a cluster that fails part-way leaves."""

from __future__ import annotations

import contextlib

from .._interrupts import checkpoint

__all__ = ["SweepIncomplete"]


class SweepIncomplete(RuntimeError):
    """A dask sweep whose cluster failed part-way (scheduler lost, workers killed repeatedly).

    ``rows`` is the DataFrame of the scenarios that finished (as :func:`sweep` returns, fewer
    rows), ``missing`` the numbers of the others, ``cause`` the cluster's error. The CLI
    writes ``rows`` and names what is missing instead of losing the finished work.
    """

    def __init__(self, rows, missing, cause: BaseException):
        self.rows, self.missing, self.cause = rows, list(missing), cause
        done = len(rows)
        super().__init__(
            f"the dask cluster failed after {done} of {done + len(self.missing)} scenarios "
            f"({type(cause).__name__}: {' '.join(str(cause).split())[:200]})"
        )


class _Incomplete(Exception):
    """Internal: the rows finished before a dask cluster failed (cause: ``__cause__``)."""

    def __init__(self, rows, cause):
        super().__init__(str(cause))
        self.rows = rows


def _run_dask(base, scenarios, scheduler, update, *, run_chunk, chunks_of) -> list:
    """Run ``scenarios`` in chunks (``chunks_of(scenarios, workers)``) of ``run_chunk`` on dask."""
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
        rows = []
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
