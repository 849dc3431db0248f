"""Issue 16, item 2: Ctrl-C cancels pending work, prints one line and exits with 130.

Before the fix every command printed a KeyboardInterrupt traceback, and a local sweep ran to
completion after SIGINT (the thread pool waited for every submitted chunk).
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from hpdob import paper, sweep

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")


def test_interrupted_local_sweep_cancels_pending_chunks(monkeypatch):
    import hpdob.simulation._sweep as sweep_module

    ran = []
    real = sweep_module.run_scenario

    def counted(*args, **kwargs):
        ran.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(sweep_module, "run_scenario", counted)

    def progress(done, total):  # Ctrl-C as soon as the first chunk is back
        raise KeyboardInterrupt

    base = {**paper.scenario(), "duration": 0.5, "observer": {"order": 1, "bandwidth": 100.0}}
    vary = {"plant.J": ("loguniform", 1.5e-4, 6e-4)}
    total = 2000
    with pytest.raises(KeyboardInterrupt):
        sweep(base, vary=vary, n=total, scheduler=2, progress=progress)
    deadline = time.monotonic() + 30
    while any(t.name.startswith("ThreadPoolExecutor") for t in threading.enumerate()):
        assert time.monotonic() < deadline, "sweep threads still running after the interrupt"
        time.sleep(0.01)
    # chunks of 64 scenarios, at most 2 per worker in flight, each stopping between scenarios
    assert len(ran) <= 5 * 64 < total


def start_paused(argv, checkpoint: str, tmp_path: Path, *, cwd: Path):
    """Start ``python -m hpdob argv`` and return it once it waits at ``checkpoint``.

    The command creates a flag file when it reaches the checkpoint and waits there for a signal
    (``HPDOB_TEST_PAUSE``, see hpdob._interrupts): the test waits for that event, never for a
    time, so a loaded machine changes nothing (issue 20: a sleep-based version failed once).
    """
    flag = tmp_path / f"{checkpoint}.reached"
    env = {**os.environ, "HPDOB_TEST_PAUSE": f"{checkpoint}:{flag}", "PYTHONUNBUFFERED": "1"}
    process = subprocess.Popen(
        [sys.executable, "-m", "hpdob", *map(str, argv)],
        cwd=cwd,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    while not flag.exists():
        if process.poll() is not None:
            raise AssertionError(f"exited before {checkpoint}: {process.communicate()}")
        with contextlib.suppress(subprocess.TimeoutExpired):
            process.wait(0.02)
    return process


SWEEP = """\
Ts = 1e-3
duration = 10.0
[plant]
J = 3.06e-4
b = 5e-5
coulomb = 0.01
[nominal]
J = 2.8e-4
[controller]
kp = 50.0
kd = 5.0
[observer]
order = 1
bandwidth = 100.0
[[reference]]
type = "smooth_step"
start = 0.2
end = 1.2
amplitude = 1.0
[sweep]
n = 2000
seed = 0
[sweep.vary]
"plant.J" = ["loguniform", 1.5e-4, 6e-4]
"""


def test_ctrl_c_stops_a_local_sweep(tmp_path):
    # Interrupted once its first chunk (64 scenarios of 2000) is back: the sweep waits there
    # for the signal, and ends at once, keeping that chunk (issue 27, rel4 item 1).
    (tmp_path / "spec.toml").write_text(SWEEP)
    argv = ["sweep", "spec.toml", "--out", "rows.csv", "--workers", "2"]
    process = start_paused(argv, "sweep-chunk", tmp_path, cwd=tmp_path)
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=120)
    assert process.returncode == 130
    kept = check_kept_line(err, "", "rows.partial.csv", "rows.csv", 2000, tmp_path)
    assert len(kept) == 64
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "rows.partial.csv", "spec.toml", "sweep-chunk.reached"]  # fmt: skip


def check_kept_line(err: str, name: str, partial: str, out: str, total: int, cwd: Path) -> set:
    """Check the one line of a sweep interrupted by signal ``name`` ("" for SIGINT, else e.g.
    " (SIGTERM)") and return the scenarios of the partial file; with those the line says are
    missing, they are every scenario once. Which chunk finishes first is up to the threads."""
    import re

    import pandas as pd

    pattern = (
        rf"hpdob sweep: interrupted{re.escape(name)}; wrote the (\d+) finished rows to "
        rf"{re.escape(partial)} \({re.escape(out)} was not written\); missing: scenarios "
        rf"([-\d, ]+); to run only those and write {re.escape(out)}: hpdob sweep spec.toml "
        rf"--out {re.escape(out)} --resume\n"
    )
    match = re.fullmatch(pattern, err)
    assert match, err
    missing = set()
    for span in match[2].split(", "):
        first, _, last = span.partition("-")
        missing.update(range(int(first), int(last or first) + 1))
    path = cwd / partial
    rows = pd.read_parquet(path) if path.suffix == ".parquet" else pd.read_csv(path)
    kept = set(rows["scenario"])
    assert len(kept) == len(rows) == int(match[1]) and not kept & missing
    assert kept | missing == set(range(total))
    return kept


SMALL_SWEEP = SWEEP.replace("duration = 10.0", "duration = 0.5").replace("n = 2000", "n = 40")


@pytest.mark.parametrize(
    ("signum", "code", "name", "suffix"),
    [(signal.SIGINT, 130, "", ".csv"), (signal.SIGTERM, 143, " (SIGTERM)", ".parquet")],
)  # fmt: skip
def test_an_interrupted_local_sweep_resumes_to_the_same_bytes(tmp_path, signum, code, name,
                                                              suffix):  # fmt: skip
    # issue 27, rel4 item 1: a local sweep interrupted by a signal keeps its finished rows
    # (before: nothing), and --resume writes the file a run from scratch writes, byte for byte.
    from hpdob.cli import main

    (tmp_path / "spec.toml").write_text(SMALL_SWEEP)
    reference = tmp_path / "reference"
    reference.mkdir()
    spec, expected = tmp_path / "spec.toml", reference / f"rows{suffix}"
    assert main(["sweep", str(spec), "--out", str(expected), "--workers", "2"]) == 0
    argv = ["sweep", "spec.toml", "--out", f"rows{suffix}", "--workers", "2"]
    process = start_paused(argv, "sweep-chunk", tmp_path, cwd=tmp_path)
    process.send_signal(signum)
    _, err = process.communicate(timeout=120)
    assert process.returncode == code
    # 40 scenarios on 2 workers: chunks of 3; the first chunk is back at the checkpoint
    kept = check_kept_line(err, name, f"rows.partial{suffix}", f"rows{suffix}", 40, tmp_path)
    assert len(kept) == 3
    assert not (tmp_path / f"rows{suffix}").exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporaries
    resumed = subprocess.run(
        [sys.executable, "-m", "hpdob", "sweep", "spec.toml", "--out", f"rows{suffix}",
         "--resume", "--workers", "2"], cwd=tmp_path, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert (resumed.returncode, resumed.stderr) == (0, "")
    assert ", 3 of them from rows.partial" in resumed.stdout
    assert (tmp_path / f"rows{suffix}").read_bytes() == expected.read_bytes()
    assert not (tmp_path / f"rows.partial{suffix}").exists()


def test_ctrl_c_during_reproduce_leaves_the_previous_outputs(tmp_path):
    out = tmp_path / "results"
    (out / "traces").mkdir(parents=True)
    previous = {"metrics.json": "previous\n", "fig2.png": "previous\n"}
    previous.update({f"traces/{name}.csv": "previous\n" for name in paper.RUNS})
    for name, text in previous.items():
        (out / name).write_text(text)
    # Interrupted with every trace staged under its temporary name, before the commit.
    process = start_paused(["reproduce", "--out", out], "reproduce-staged", tmp_path, cwd=tmp_path)
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=120)
    assert (process.returncode, err) == (130, "hpdob reproduce: interrupted\n")
    files = {str(p.relative_to(out)): p for p in out.rglob("*") if p.is_file()}
    assert {name: p.read_text() for name, p in files.items()} == previous  # no temporaries


@pytest.mark.parametrize(
    ("command", "module", "name", "marker"),
    [
        ("compare", "hpdob.analysis", "compare_observers", "comparison.json"),
        ("tune", "hpdob.tuning", "tune", "tune.json"),
        ("estimate", "hpdob.identification", "estimate_log", "estimate.json"),
    ],
)
def test_ctrl_c_in_compare_tune_estimate(capsys, tmp_path, monkeypatch, command, module, name,
                                         marker):  # fmt: skip
    import importlib

    from hpdob.cli import main

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(importlib.import_module(module), name, interrupted)
    out = tmp_path / "out"
    out.mkdir()
    (out / marker).write_text("previous\n")
    argv = [command, "--out", str(out)]
    if command == "estimate":
        argv += ["--emps", "--J-n", "95"]
    assert main(argv) == 130
    assert capsys.readouterr().err == f"hpdob {command}: interrupted\n"
    assert [p.name for p in out.iterdir()] == [marker] and (out / marker).read_text() == (
        "previous\n"
    )


# -- issue 27, item 5: a signal at any moment of start-up ------------------------------------
def console_script() -> list[str]:
    """The program pip's wrapper for the ``hpdob`` console script runs (its template: ``re``
    and ``sys`` imported, then the entry point of pyproject.toml called)."""
    import tomllib

    pyproject = Path(__file__).resolve().parents[2] / "pyproject.toml"
    entry = tomllib.loads(pyproject.read_text())["project"]["scripts"]["hpdob"]
    module, _, function = entry.partition(":")
    code = (
        f"import re\nimport sys\nfrom {module} import {function}\nif __name__ == '__main__':\n"
        f"    sys.argv[0] = re.sub(r'(-script\\.pyw|\\.exe)?$', '', sys.argv[0])\n"
        f"    sys.exit({function}())\n"
    )
    return [sys.executable, "-c", code]


ENTRIES = {"python -m hpdob": [sys.executable, "-m", "hpdob"], "console script": console_script()}


def start_at(entry: str, argv, checkpoint: str, tmp_path: Path):
    """Start the ``hpdob`` command by ``entry`` and return it once it waits at ``checkpoint``
    (and the checkpoint's file: remove it to let the command go on)."""
    flag = tmp_path / f"{checkpoint}.reached"
    flag.unlink(missing_ok=True)
    env = {**os.environ, "HPDOB_TEST_PAUSE": f"{checkpoint}:{flag}", "PYTHONUNBUFFERED": "1"}
    process = subprocess.Popen(
        [*ENTRIES[entry], *map(str, argv)], cwd=tmp_path, env=env, stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    while not flag.exists():
        if process.poll() is not None:
            raise AssertionError(f"exited before {checkpoint}: {process.communicate()}")
        with contextlib.suppress(subprocess.TimeoutExpired):
            process.wait(0.02)
    return process, flag


@pytest.mark.parametrize("entry", ENTRIES)
@pytest.mark.parametrize(
    ("signum", "code", "line"),
    [(signal.SIGINT, 130, "hpdob: interrupted\n"),
     (signal.SIGTERM, 143, "hpdob: interrupted (SIGTERM)\n")],
)  # fmt: skip
def test_a_signal_before_the_imports_is_one_line(tmp_path, entry, signum, code, line):
    # The entry point's first statement installs the handler; the checkpoint is right after
    # it, before the command modules, argparse and numpy are imported (they used to import
    # first: a KeyboardInterrupt traceback, exit -2).
    process, _ = start_at(entry, ["design"], "entry", tmp_path)
    process.send_signal(signum)
    out, err = process.communicate(timeout=60)
    assert (process.returncode, out, err) == (code, "", line)


def test_what_runs_before_the_entry_handler_imports_nothing_heavy():
    # Issue 27 item 5: before the handler, Python's own Ctrl-C (a traceback) applies. What hpdob
    # runs there is hpdob/__init__ and hpdob._entry: no numpy, and not even `signal` (it
    # imports enum; _entry installs its handler through the C module _signal). -S: without
    # site, whose .pth files (coverage, setuptools) import modules of their own.
    code = (
        "import sys; before = set(sys.modules); import hpdob._entry; "
        "print(sorted(m for m in set(sys.modules) - before if not m.startswith('hpdob')))"
    )
    # Without site an editable install's .pth is not read either: put the package's own
    # directory on the path (the one this test imports).
    import hpdob

    env = {**os.environ, "PYTHONPATH": str(Path(hpdob.__file__).resolve().parent.parent)}
    done = subprocess.run([sys.executable, "-S", "-c", code], capture_output=True, text=True,
                          check=True, timeout=60, env=env)  # fmt: skip
    assert done.stdout.strip() == "[]", done.stdout


def test_ctrl_c_at_any_moment_after_the_entry_is_clean(tmp_path):
    # Every moment from the entry point on: imports, parsing, the design, printing, the exit.
    # The delays only spread the moments; whatever moment each signal hits, the outcome
    # must be clean: exit 130 (or -2: killed by SIGINT once Python's exit restored the
    # default action, which a shell reports as 130) with at most one line and no traceback,
    # or, if the command ended before the signal came, its normal output and exit 0.
    done = subprocess.run(
        [*ENTRIES["python -m hpdob"], "design"], cwd=tmp_path, capture_output=True, text=True,
        check=True, timeout=60,
    )  # fmt: skip
    lines = {"", "hpdob: interrupted\n", "hpdob design: interrupted\n"}
    outcomes = []
    for i, delay in enumerate([0, 0.002, 0.01, 0.03, 0.1, 0.3, 0.6, 1.0, 1.5, 2.5]):
        entry = list(ENTRIES)[i % 2]
        process, flag = start_at(entry, ["design"], "entry", tmp_path)
        flag.unlink()  # go on
        time.sleep(delay)  # spreads the moments; nothing below depends on it
        with contextlib.suppress(ProcessLookupError):
            process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=60)
        outcomes.append(process.returncode)
        if process.returncode == 0:
            assert (out, err) == (done.stdout, ""), (entry, delay)
        else:
            assert process.returncode in (130, -signal.SIGINT), (entry, delay, err)
            assert err in lines, (entry, delay, err)
    assert any(code != 0 for code in outcomes)  # the signals did arrive during the run


def test_an_interrupted_command_ends_without_the_interpreters_finalisation(tmp_path):
    # Issue 27 (third round): `hpdob reproduce` took 0.3-1.6 s from the signal to its exit,
    # nearly all of it Python's finalisation (numpy, numba, matplotlib torn down) after the
    # line. The entry point now runs the exit handlers (coverage saves its data there) and
    # ends the process; a finaliser of __main__ would run in the finalisation it skips.
    marker, flag = tmp_path / "atexit.ran", tmp_path / "startup.reached"
    script = tmp_path / "run.py"
    script.write_text(
        "import atexit, sys\n"
        f"atexit.register(lambda: open({str(marker)!r}, 'w').close())\n"
        "class Final:\n"
        "    def __del__(self):\n"
        "        sys.stderr.write('finalised\\n')\n"
        "keep = Final()\n"
        "sys.argv = ['hpdob', 'design']\n"
        "from hpdob._entry import main\n"
        "sys.exit(main())\n"
    )
    env = {**os.environ, "HPDOB_TEST_PAUSE": f"startup:{flag}", "PYTHONUNBUFFERED": "1"}
    process = subprocess.Popen(
        [sys.executable, str(script)], cwd=tmp_path, env=env, stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    while not flag.exists():
        assert process.poll() is None, process.communicate()
        time.sleep(0.01)
    process.send_signal(signal.SIGINT)
    out, err = process.communicate(timeout=60)
    assert (process.returncode, out, err) == (130, "", "hpdob: interrupted\n")
    assert marker.exists()  # the exit handlers ran


@pytest.mark.parametrize("moment", ["as its handler goes in", "as the handlers come out"])
def test_a_signal_while_the_handlers_change_is_one_line_and_restores_them(monkeypatch, capsys,
                                                                         moment):  # fmt: skip
    """A Ctrl-C right after SIGINT's handler is in place (before the command's try), or while
    the handlers are restored after it: exit 130 with the one line, not a traceback (it was
    exit 1 once in a few hundred signals 8 ms after the entry), and every handler restored."""
    from hpdob import _interrupts
    from hpdob.cli import main

    real, original = signal.signal, signal.getsignal(signal.SIGINT)
    fired = []

    def changing(signum, handler):
        ours = handler is _interrupts._handler
        if moment == "as the handlers come out" and not ours and not fired:
            fired.append(signum)
            raise _interrupts.Interrupted(signal.SIGINT)  # before this restore
        previous = real(signum, handler)
        if moment == "as its handler goes in" and ours and signum == signal.SIGINT and not fired:
            fired.append(signum)
            raise _interrupts.Interrupted(signal.SIGINT)  # right after it is in place
        return previous

    monkeypatch.setattr(signal, "signal", changing)
    escaped = False
    try:
        code = main(["design", "--order", "1"])
    except KeyboardInterrupt:  # what a regression does: a failure, not the end of the session
        escaped, code = True, None
    finally:
        monkeypatch.undo()
        restored = signal.getsignal(signal.SIGINT)
        real(signal.SIGINT, original)
    _, err = capsys.readouterr()
    assert not escaped, "the signal escaped main"
    assert restored is original
    assert fired and code == 130
    assert err in ("hpdob: interrupted\n", "hpdob design: interrupted\n")


def test_held_back_signals_restore_every_handler_when_one_comes_while_they_change(monkeypatch):
    """interrupts_deferred (a commit's renames) shares handling_signals' handler swap: a signal
    while the handlers are restored still leaves every one as it was, and is raised after."""
    from hpdob import _interrupts

    real = signal.signal
    before = {signum: signal.getsignal(signum) for signum in _interrupts.SIGNALS}
    fired = []

    def restoring(signum, handler):
        if handler is before[signum] and not fired:  # the first restore: a signal comes
            fired.append(signum)
            raise _interrupts.Interrupted(signal.SIGINT)
        return real(signum, handler)

    monkeypatch.setattr(signal, "signal", restoring)
    with pytest.raises(_interrupts.Interrupted), _interrupts.interrupts_deferred():
        pass
    monkeypatch.undo()
    assert fired
    assert {signum: signal.getsignal(signum) for signum in before} == before


def test_a_signal_while_an_error_is_reported_is_the_interrupt(monkeypatch, capsys):
    """A Ctrl-C while main reports a rejected argument: exit 130 with the one line (the
    handlers restored), not a traceback."""
    import hpdob.cli
    from hpdob import _interrupts

    def reporting(command, err):
        raise _interrupts.Interrupted(signal.SIGINT)

    original = signal.getsignal(signal.SIGINT)
    monkeypatch.setattr(hpdob.cli, "_failed", reporting)
    code = hpdob.cli.main(["design", "--order", "-1"])
    _, err = capsys.readouterr()
    assert code == 130 and err == "hpdob design: interrupted\n"
    assert signal.getsignal(signal.SIGINT) is original
