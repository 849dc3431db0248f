"""Shared fixtures and reference values for the hpdob test suite."""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest

from hpdob import ServoModel

# simulate runs a loop built ahead of time from $HPDOB_AOT_DIR (default ~/.cache/hpdob/aot):
# the suite (and the processes it starts) looks in a folder of its own, so that neither a
# user's built loops nor the docs' example build changes which loop a test runs.
_AOT_FOLDER = tempfile.mkdtemp(prefix="hpdob-aot-tests-")
os.environ["HPDOB_AOT_DIR"] = _AOT_FOLDER
os.environ.pop("HPDOB_AOT", None)


def pytest_unconfigure(config):
    shutil.rmtree(_AOT_FOLDER, ignore_errors=True)


#: The suite's longest files (30-110 s of one worker each, ``--durations``, 2026-12-03), run
#: first: xdist's ``--dist loadfile`` hands files out in the order collected, and one of these
#: collected last (the site's build is in ``tests/test_docsite.py``) kept one worker busy
#: while the other had nothing left.
RUN_FIRST = (
    "cli/test_cli_memory_logs.py",
    "cli/test_cli_memory.py",
    "test_docsite.py",
    "analysis/test_contact_limit_cycle.py",
    "analysis/test_contact_deadband.py",
    "test_every_figure.py",
)
_TESTS = Path(__file__).resolve().parent


def pytest_collection_modifyitems(session, config, items):
    rank = {name: i for i, name in enumerate(RUN_FIRST)}

    def first(item):
        try:
            name = item.path.resolve().relative_to(_TESTS).as_posix()
        except ValueError:  # a test outside tests/ (a path given on the command line)
            return len(RUN_FIRST)
        return rank.get(name, len(RUN_FIRST))

    items.sort(key=first)  # stable: every file's tests, and the other files, keep their order


# The paper's set-up (section IV): Maxon EC 90 flat class motor, Ts = 1 ms.
PAPER_J = 3.06e-4  # kg m^2
PAPER_B = 5e-5  # N m s/rad
PAPER_TS = 1e-3  # s


@pytest.fixture
def rng():
    return np.random.default_rng(20261123)


@pytest.fixture
def paper_model():
    """Nominal discrete model of the paper's motor (J_n = 2.8e-4, b_n = 0, Ts = 1 ms)."""
    return ServoModel(J=2.8e-4).discretize(PAPER_TS)


@pytest.fixture(scope="module")
def dask_cluster():
    """Local dask clusters for a test module (the sweep's tests and the CLI's).

    ``dask_cluster(n_workers=2, *, processes=True, client=True)`` returns
    ``(cluster, client)``: a ``distributed.LocalCluster`` (one thread per worker, no
    dashboard; worker processes on 127.0.0.1, or with ``processes=False`` in this process, so
    that a monkeypatched function runs there) and a ``Client`` of it (None with
    ``client=False``: the code under test connects by the scheduler's address). Started at
    the first call with these arguments, closed after the module's last test; dask's warnings
    on starting and stopping (ports in use, workers lost at close) are silenced. Skips where
    dask.distributed is not installed.
    """
    distributed = pytest.importorskip("dask.distributed")
    started = {}
    with contextlib.ExitStack() as stack:

        def start(n_workers=2, *, processes=True, client=True):
            key = (n_workers, processes, client)
            if key not in started:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    # in-process workers talk over dask's inproc transport: no host to give
                    host = {"host": "127.0.0.1"} if processes else {}
                    cluster = distributed.LocalCluster(
                        n_workers=n_workers, threads_per_worker=1, processes=processes,
                        dashboard_address=None, **host,
                    )  # fmt: skip
                    stack.callback(_quietly, cluster.close)
                    connected = distributed.Client(cluster) if client else None
                    if connected is not None:
                        stack.callback(_quietly, connected.close)
                started[key] = (cluster, connected)
            return started[key]

        yield start


def _quietly(close) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        close()
