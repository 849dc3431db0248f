"""``hpdob sweep`` on a dask cluster that fails part-way (issue 27, item 2): a real scheduler
and real workers in subprocesses, the scheduler or a worker killed mid-sweep. The finished rows
go to ``<out>.partial.csv`` (``--out`` is never a partial table), the message is one line that
says what is missing and how to resume, and ``--resume`` completes the sweep: the file equals a
run from scratch, byte for byte.

The tests synchronise on checkpoints (``HPDOB_TEST_PAUSE``, hpdob._interrupts): the command
waits after its first finished chunk, a worker inside its first scenario, and the test acts
while they wait. Nothing depends on a sleep.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import pytest

from hpdob.cli import main

distributed = pytest.importorskip("dask.distributed")
pytestmark = [
    pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals"),
    pytest.mark.timeout(180),
]

SPEC = """\
label = "s"
Ts = 1e-3
duration = 0.5
[plant]
J = 3.06e-4
[nominal]
J = 2.8e-4
[controller]
kp = 50.0
kd = 5.0
[reference]
type = "step"
time = 0.0
amplitude = 1.0
[observer]
order = 1
bandwidth = 100.0
[sweep]
n = 3
seed = 7
[sweep.grid]
"observer.bandwidth" = [40.0, 80.0, 120.0, 160.0]
"observer.order" = [0, 1]
[sweep.vary]
"plant.J" = ["loguniform", 2e-4, 5e-4]
"""
TOTAL = 24


def environment(**extra) -> dict:
    """The test's environment (its PYTHONPATH, as the other subprocess tests) and ``extra``."""
    return {**os.environ, "PYTHONUNBUFFERED": "1", **extra}


def wait_for(path: Path, *processes) -> None:
    """Wait until ``path`` exists; fail if one of ``processes`` ends first."""
    while not path.exists():
        for process in processes:
            if process.poll() is not None:
                raise AssertionError(f"exited before {path.name}: {process.communicate()}")
        time.sleep(0.02)


@contextlib.contextmanager
def cluster(tmp_path: Path, workers: list[dict], **scheduler_env):
    """A dask scheduler and one single-threaded worker per entry of ``workers`` (its extra
    environment), each a subprocess without a nanny; yields ``(address, worker processes)``
    once every worker has joined."""
    started = []
    file = tmp_path / "scheduler.json"
    try:
        scheduler = subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
             "--port", "0", "--no-dashboard", "--scheduler-file", str(file)],
            env=environment(**scheduler_env), stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )  # fmt: skip
        started.append(scheduler)
        wait_for(file, scheduler)
        procs = []
        for extra in workers:
            procs.append(
                subprocess.Popen(
                    [
                        sys.executable,
                        "-m",
                        "distributed.cli.dask_worker",
                        "--scheduler-file",
                        str(file),
                        "--nthreads",
                        "1",
                        "--no-nanny",
                        "--no-dashboard",
                    ],
                    env=environment(**extra),
                    stdout=subprocess.DEVNULL,
                    stderr=subprocess.DEVNULL,
                )
            )
            started.append(procs[-1])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            address = json.loads(file.read_text())["address"]
            with distributed.Client(address, timeout=60) as client:
                client.wait_for_workers(len(workers), timeout=120)
        yield scheduler, address, procs
    finally:
        for process in started:
            if process.poll() is None:
                process.kill()
            process.wait()


def sweep_paused(tmp_path: Path, spec: Path, out: Path, address: str):
    """``hpdob sweep`` on ``address``, paused after its first finished chunk; returns the
    process and the checkpoint's file (remove it to let the command go on)."""
    flag = tmp_path / "chunk.reached"
    process = subprocess.Popen(
        [sys.executable, "-m", "hpdob", "sweep", str(spec), "--out", str(out), "--scheduler",
         address, "--no-progress"],
        env=environment(HPDOB_TEST_PAUSE=f"sweep-chunk:{flag}"), stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    return process, flag


def from_scratch(tmp_path: Path, spec: Path, capsys) -> bytes:
    out = tmp_path / "scratch.csv"
    assert main(["sweep", str(spec), "--out", str(out), "--workers", "2", "--no-progress"]) == 0
    capsys.readouterr()
    return out.read_bytes()


def check_incomplete(process, out: Path, cause: str):
    """The command's one-line report of a failed cluster; returns the partial file's rows."""
    import pandas as pd

    stdout, stderr = process.communicate(timeout=120)
    assert process.returncode == 1, stderr  # was "internal error" and every row lost
    assert stdout == "" and stderr.count("\n") == 1, stderr  # no traceback from distributed
    assert stderr.startswith("hpdob sweep: error: the dask cluster failed after "), stderr
    assert "internal error" not in stderr and cause in stderr, stderr
    partial = out.with_name("rows.partial.csv")
    assert "wrote the " in stderr and str(partial) in stderr and "was not written" in stderr
    assert "missing: scenarios " in stderr and f"--out {out} --resume" in stderr, stderr
    assert not out.exists()  # --out holds complete results only
    rows = pd.read_csv(partial)
    assert 0 < len(rows) < TOTAL
    return rows


def test_a_lost_scheduler_keeps_the_finished_rows_and_resume_completes(tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text(SPEC)
    out = tmp_path / "rows.csv"
    with cluster(tmp_path, [{}]) as (scheduler, address, _):
        process, flag = sweep_paused(tmp_path, spec, out, address)
        wait_for(flag, process)  # one chunk is back
        scheduler.send_signal(signal.SIGKILL)
        scheduler.wait()
        flag.unlink()  # go on: the next result cannot come
        rows = check_incomplete(process, out, "scheduler-connection-lost")
    # resume on local threads: only the missing scenarios run
    code = main(["sweep", str(spec), "--out", str(out), "--resume", "--workers", "2",
                 "--no-progress"])  # fmt: skip
    report, err = capsys.readouterr()
    assert code == 0 and f"{len(rows)} of them from" in report, err
    assert not out.with_name("rows.partial.csv").exists()
    assert out.read_bytes() == from_scratch(tmp_path, spec, capsys)


def test_a_repeatedly_killed_worker_keeps_the_finished_rows_and_resume_completes(tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text(SPEC)
    out = tmp_path / "rows.csv"
    in_task = tmp_path / "scenario.reached"
    # allowed-failures 0: the first death of a worker running a task is that task's last
    # (KilledWorker), as the default 3 is after four deaths
    with cluster(
        tmp_path,
        [{"HPDOB_TEST_PAUSE": f"sweep-scenario:{in_task}"}, {}],
        DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES="0",
    ) as (_, address, workers):
        process, flag = sweep_paused(tmp_path, spec, out, address)
        wait_for(in_task, process, workers[0])  # the first worker is inside a task
        wait_for(flag, process)  # and a chunk from the second is back
        pid = int(in_task.read_text().split()[0])
        assert pid == workers[0].pid
        os.kill(pid, signal.SIGKILL)
        workers[0].wait()
        flag.unlink()
        rows = check_incomplete(process, out, "KilledWorker")
        # resume on the same cluster (the second worker)
        resumed = subprocess.run(
            [sys.executable, "-m", "hpdob", "sweep", str(spec), "--out", str(out), "--resume",
             "--scheduler", address, "--no-progress"],
            env=environment(), capture_output=True, text=True, timeout=120,
        )  # fmt: skip
    assert resumed.returncode == 0 and resumed.stderr == "", resumed.stderr
    assert f"{len(rows)} of them from" in resumed.stdout
    assert out.read_bytes() == from_scratch(tmp_path, spec, capsys)
