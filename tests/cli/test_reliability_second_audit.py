"""Issue 27: the second reliability audit (items 1-13; docs/reliability.md).

Each test reproduces one finding; the ones that need a subprocess synchronise on a checkpoint
the command reaches (``HPDOB_TEST_PAUSE``, see hpdob._interrupts), never on a sleep.
"""

from __future__ import annotations

import errno
import json
import os
import signal
import subprocess
import sys
import tempfile
import weakref
from pathlib import Path

import numpy as np
import pytest
from test_interrupts import start_paused

from hpdob import paper
from hpdob.cli import main

POSIX = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")


def run_cli(capsys, *argv):
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exit_:  # argparse's errors
        code = exit_.code
    out, err = capsys.readouterr()
    return code, out, err


def files_below(directory: Path) -> list[str]:
    return sorted(str(p.relative_to(directory)) for p in directory.rglob("*") if p.is_file())


def must_not_run(*args, **kwargs):
    raise AssertionError("the work started before the output location was checked")


SCENARIO = """\
label = "{label}"
Ts = 1e-3
duration = 0.05
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
"""


# -- item 1: output locations checked before the work ---------------------------------------
@pytest.mark.parametrize(
    ("argv", "module", "name"),
    [
        (["sweep", "{spec}", "--out", "{file}/r.csv"], "hpdob.simulation._sweep", "sweep"),
        (["compare", "--out", "{file}"], "hpdob.analysis", "compare_observers"),
        (["tune", "--out", "{file}"], "hpdob.tuning", "tune"),
        (["tune", "--export-c", "{file}/c"], "hpdob.tuning", "tune"),
        (["reproduce", "--out", "{file}"], "hpdob.paper._reproduce", "run"),
        (["simulate", "{spec}", "--out", "{file}/d"], "hpdob.simulation._simulate", "simulate"),
        (["analyze", "stability", "--out", "{file}"], "hpdob.analysis", "robust_stability_map"),
        (["export-c", "--out", "{file}"], "hpdob.export._c", "export_c"),
        (["identify", "--emps", "--out", "{file}"], "hpdob.identification._log", "identify"),
    ],
)
def test_output_location_is_checked_before_the_work(capsys, tmp_path, monkeypatch, argv,
                                                    module, name):  # fmt: skip
    import importlib

    monkeypatch.setattr(importlib.import_module(module), name, must_not_run, raising=False)
    file = tmp_path / "a_file"
    file.write_text("not a directory\n")
    spec = tmp_path / "s.toml"
    spec.write_text(SCENARIO.format(label="s") + "[sweep]\nn = 2\n")
    argv = [a.format(file=file, spec=spec) for a in argv]
    code, _, err = run_cli(capsys, *argv)
    assert code == 2 and err.count("\n") == 1, err
    assert "cannot be written" in err and str(file) in err, err
    assert file.read_text() == "not a directory\n"


def test_read_only_output_names_the_target_not_the_temporary(tmp_path, monkeypatch):
    from hpdob._files import OutputLocationError, check_output, write_text_atomic

    def read_only(*args, dir=None, **kwargs):
        raise OSError(errno.EROFS, "Read-only file system", f"{dir}/.r.csv.n54_hnfe.csv")

    monkeypatch.setattr(tempfile, "mkstemp", read_only)
    with pytest.raises(OutputLocationError) as info:
        check_output(tmp_path / "ro" / "r.csv", kind="file")
    assert str(info.value) == (
        f"--out {str(tmp_path / 'ro' / 'r.csv')!r} cannot be written: Read-only file system "
        f"(in {str(tmp_path)!r})"
    )
    with pytest.raises(OSError, match="Read-only") as info:  # the writer itself, too
        write_text_atomic(tmp_path / "r.csv", "x\n")
    assert info.value.filename == str(tmp_path / "r.csv") and ".n54" not in str(info.value)


def test_an_io_error_while_staging_names_the_file(tmp_path):
    from hpdob._files import staged_outputs

    def fail_writing(files, name=None):
        path = files.path(name) if name else None
        raise OSError(errno.EIO, "Input/output error", *([str(path)] if path else []))

    with pytest.raises(OSError, match="Input/output") as info, staged_outputs(tmp_path) as files:
        fail_writing(files, "estimate.csv")
    assert info.value.filename == str(tmp_path / "estimate.csv")
    with pytest.raises(OSError, match="Input/output") as info, staged_outputs(tmp_path) as files:
        fail_writing(files)  # no file name at all: the directory is named
    assert info.value.filename == str(tmp_path) and os.listdir(tmp_path) == []


# -- item 3: stale temporaries, no temporary of a temporary ----------------------------------
def dead_pid() -> int:
    process = subprocess.Popen([sys.executable, "-c", "pass"])
    process.wait()
    return process.pid


def test_a_later_run_removes_stale_temporaries_of_its_own(tmp_path):
    from hpdob._files import write_text_atomic

    dead = dead_pid()
    stale = [
        f".estimate.csv.~hpdob{dead}-k3j2_x9q.csv",  # this version's, writer gone
        ".estimate.csv.n54_hnfe.csv",  # an older version's
        "..estimate.csv.n54_hnfe.csv.a1b2c3d4.csv",  # and its temporary of a temporary
    ]
    kept = [
        f".estimate.csv.~hpdob{os.getppid()}-livewrit.csv",  # a live writer's: kept
        ".estimate.csv.notes.csv",  # not a temporary name
        "estimate.csv.bak",
    ]
    for name in stale + kept:
        (tmp_path / name).write_text("partial\n")
    write_text_atomic(tmp_path / "estimate.csv", "t\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([*kept, "estimate.csv"])


def test_a_staged_temporary_is_not_written_through_another_temporary(tmp_path, monkeypatch):
    from hpdob._files import staged_outputs

    result = paper.run("PD", duration=0.01)
    seen = []
    real = os.replace
    monkeypatch.setattr(os, "replace", lambda a, b: (seen.append(Path(b).name), real(a, b)))
    with staged_outputs(tmp_path, markers=["m.json"]) as files:
        result.to_csv(files.path("run.csv"))  # to_csv is atomic on its own
        files.write_text("m.json", "{}\n")
    assert seen == ["run.csv", "m.json"]  # one rename each: no temporary of the temporary
    assert files_below(tmp_path) == ["m.json", "run.csv"]


# -- item 4: one consistent set per output directory -----------------------------------------
def test_simulate_no_plot_removes_the_previous_runs_files(capsys, tmp_path):
    a, b, out = tmp_path / "a.toml", tmp_path / "b.toml", tmp_path / "d"
    a.write_text(SCENARIO.format(label="a"))
    b.write_text(SCENARIO.format(label="b"))
    assert run_cli(capsys, "simulate", a, "--out", out)[0] == 0
    assert files_below(out) == ["a.csv", "a.png", "metrics.json"]
    (out / "notes.txt").write_text("mine\n")  # not hpdob's: kept
    assert run_cli(capsys, "simulate", b, "--out", out, "--no-plot")[0] == 0
    assert files_below(out) == ["b.csv", "metrics.json", "notes.txt"]
    assert list(json.loads((out / "metrics.json").read_text())) == ["b"]


def test_estimate_no_plot_removes_the_previous_figure(capsys, tmp_path):
    from test_atomic_outputs import ESTIMATE, write_log

    log, out = write_log(tmp_path / "log.csv"), tmp_path / "out"
    assert run_cli(capsys, "estimate", log, *ESTIMATE, "--out", out)[0] == 0
    assert files_below(out) == ["estimate.csv", "estimate.json", "estimate.png"]
    assert run_cli(capsys, "estimate", log, *ESTIMATE, "--out", out, "--no-plot")[0] == 0
    assert files_below(out) == ["estimate.csv", "estimate.json"]


# -- items 5, 6, 3: signals --------------------------------------------------------------------
@POSIX
def test_the_command_imports_nothing_heavy_before_its_signal_handlers():
    code = "import sys, hpdob.cli; print(sorted({'numpy', 'scipy', 'control'} & set(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout == "[]\n"


@POSIX
def test_ctrl_c_during_start_up_exits_130_with_one_line(tmp_path):
    process = start_paused(["design"], "startup", tmp_path, cwd=tmp_path)
    process.send_signal(signal.SIGINT)
    out, err = process.communicate(timeout=60)
    assert (process.returncode, out, err) == (130, "", "hpdob: interrupted\n")


@POSIX
@pytest.mark.parametrize(
    ("signum", "code", "line"),
    [
        (signal.SIGINT, 130, "hpdob reproduce: interrupted\n"),
        (signal.SIGTERM, 143, "hpdob reproduce: interrupted (SIGTERM)\n"),
        (signal.SIGHUP, 129, "hpdob reproduce: interrupted (SIGHUP)\n"),
    ],
)
def test_sigterm_and_sighup_are_handled_like_ctrl_c(tmp_path, signum, code, line):
    out = tmp_path / "results"
    (out / "traces").mkdir(parents=True)
    previous = {"metrics.json": "previous\n", "fig2.png": "previous\n"}
    previous.update({f"traces/{name}.csv": "previous\n" for name in paper.RUNS})
    for name, text in previous.items():
        (out / name).write_text(text)
    # Paused with every trace staged under its temporary name: the signal must remove them.
    process = start_paused(["reproduce", "--out", out], "reproduce-staged", tmp_path, cwd=tmp_path)
    assert any(p.name.startswith(".") for p in (out / "traces").iterdir())
    process.send_signal(signum)
    _, err = process.communicate(timeout=60)
    assert (process.returncode, err) == (code, line)
    assert {name: (out / name).read_text() for name in files_below(out)} == previous


class _Interrupting:
    """Sends SIGINT to the process from its weakref callback, where Python ignores exceptions
    (``Exception ignored in: <function WeakKeyDictionary...remove>``)."""

    def __init__(self):
        self._ref = weakref.ref(self, lambda ref: signal.raise_signal(signal.SIGINT))


@POSIX
@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
def test_an_interrupt_python_ignores_still_ends_the_command(capsys, tmp_path, monkeypatch):
    import hpdob.cli._reproduce as command

    out = tmp_path / "out"
    out.mkdir()
    (out / "metrics.json").write_text("previous\n")

    def run(args):
        from hpdob._files import staged_outputs

        with staged_outputs(args.out, markers=["metrics.json"]) as files:
            files.write_text("metrics.json", "new\n")
            obj = _Interrupting()
            del obj  # the callback's KeyboardInterrupt is printed and ignored by Python
        return 0

    monkeypatch.setattr(command, "_run", run)
    assert run_cli(capsys, "reproduce", "--out", out)[::2] == (
        130,
        "hpdob reproduce: interrupted\n",
    )
    assert files_below(out) == ["metrics.json"] and (out / "metrics.json").read_text() == (
        "previous\n"
    )


@POSIX
@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
def test_an_ignored_interrupt_after_the_outputs_still_exits_130(capsys, monkeypatch):
    import hpdob.cli._design as command

    def run(args):
        obj = _Interrupting()
        del obj
        return 0

    monkeypatch.setattr(command, "_run", run)
    assert run_cli(capsys, "design")[::2] == (130, "hpdob design: interrupted\n")
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # restored


# -- item 7: a long LAPACK call does not hold back the signal ---------------------------------
@POSIX
def test_a_signal_during_a_long_eigenvalue_call_is_handled_at_once(monkeypatch):
    import threading

    import hpdob.analysis._closed_loop as module
    from hpdob import PD, Actuator, ServoModel, closed_loop_poles, design_observer
    from hpdob._interrupts import Interrupted, handling_signals

    release = threading.Event()

    def never_returns(A):  # a LAPACK call that takes "forever": the signal comes meanwhile
        os.kill(os.getpid(), signal.SIGTERM)
        release.wait(60)
        return np.zeros(A.shape[0])

    monkeypatch.setattr(module.np.linalg, "eigvals", never_returns)
    nominal = ServoModel(2.8e-4)
    observer = design_observer(nominal.discretize(1e-3), order=1, bandwidth=100.0)
    loop = {"plant": nominal, "nominal": nominal, "Ts": 1e-3, "controller": PD(50, 5)}
    try:
        with handling_signals(), pytest.raises(Interrupted) as info:
            closed_loop_poles(**loop, observer=observer, actuator=Actuator(delay_samples=999))
    finally:
        release.set()
    assert info.value.name == "SIGTERM"


# -- item 8: inputs that overflow the state are refused, the state unchanged ------------------
def _observers():
    from hpdob import (
        ExtendedStateObserver,
        KalmanDisturbanceObserver,
        Observer,
        ServoModel,
        design_observer,
    )

    model = ServoModel(2.8e-4).discretize(1e-3)
    return [
        Observer.of(design_observer(model, order=1, bandwidth=100.0)),
        Observer.of(design_observer(model, order=1, bandwidth=100.0, measurement="position")),
        ExtendedStateObserver(model, bandwidth=100.0),
        KalmanDisturbanceObserver(model, position_noise_std=1e-4, process_noise_std=1.0),
    ]


@pytest.mark.parametrize("index", range(4), ids=["state", "position", "eso", "kalman"])
def test_runtime_observers_refuse_inputs_that_overflow_their_state(index):
    from hpdob import ParameterValueError
    from hpdob.observers import update

    observer = _observers()[index]
    system = observer._system
    big = (1e308, -1e308) if system.measurement == "state" else 1e308

    def feed(step, state):
        for _ in range(40):  # the case: [nan nan nan] after a few samples
            state = step(state)
        return state

    def runtime(state):
        observer.update(big, 1e308)
        return observer._state

    with pytest.raises(ParameterValueError, match=r"overflows the state .* unchanged"):
        feed(runtime, observer._state)
    last = observer._state
    assert all(np.isfinite(last))  # the last good state, kept
    with pytest.raises(ParameterValueError, match="overflows the state"):  # functional core
        feed(lambda state: update(system, state, big, 1e308), last)  # was (9.41e307, inf)


# -- item 9: frequencies at or above Nyquist refused by every view ----------------------------
@pytest.mark.parametrize("frequency", ["1000", "600", "500", "-1"])
def test_analyze_bode_refuses_frequencies_at_or_above_nyquist(capsys, tmp_path, frequency):
    code, _, err = run_cli(capsys, "analyze", "bode", "--frequency", frequency, "--out", tmp_path)
    assert code == 2 and err.count("\n") == 1, err
    assert "below the Nyquist frequency 1/(2 Ts) = 500 Hz" in err and frequency in err
    assert list(tmp_path.iterdir()) == []


# -- item 10: the verification fails a run that does not track --------------------------------
def test_tune_verification_fails_a_run_that_does_not_track(capsys, tmp_path):
    code, _, err = run_cli(
        capsys, "tune", "--families", "state", "--torque-limit", "1e-300", "--out", tmp_path,
        "--no-plot",
    )  # fmt: skip
    # was: "verified by nonlinear simulation ... bounded" with an RMS position error of 2.77e3
    assert code == 2 and "tracks its reference" in err and err.count("\n") == 1, err
    assert list(tmp_path.iterdir()) == []


# -- item 11: values that are not numbers ------------------------------------------------------
def _number_entry_points():
    from hpdob import PD, Encoder, ServoModel, design_observer, estimation_response, signals

    observer = design_observer(ServoModel(2.8e-4).discretize(1e-3), order=1, bandwidth=100.0)
    return {
        "ServoModel(b)": lambda v: ServoModel(2.8e-4, v),
        "PD(kp)": lambda v: PD(v, 5.0),
        "Encoder(noise_std)": lambda v: Encoder(4096, noise_std=v),
        "Step(time)": lambda v: signals.Step(v, 1.0),
        "estimation_response(frequency)": lambda v: estimation_response(observer, v),
        "estimation_response([f, v])": lambda v: estimation_response(observer, [1.0, v]),
    }


@pytest.mark.parametrize("entry", list(_number_entry_points()))
@pytest.mark.parametrize(
    "value",
    [np.ma.masked, np.datetime64("2020-01-01"), np.timedelta64(3, "s")],
    ids=["masked", "datetime64", "timedelta64"],
)
def test_masked_values_and_dates_are_not_numbers(entry, value):
    from hpdob import ParameterTypeError

    with pytest.raises(ParameterTypeError) as info:  # masked was read as 0.0
        _number_entry_points()[entry](value)
    assert "\n" not in str(info.value)


def test_a_csv_cell_with_an_underscore_is_not_a_number(tmp_path):
    from hpdob import ParameterValueError, read_log

    path = tmp_path / "log.csv"
    path.write_text("t,q,i\n0.0,0.0,0.1\n0.001,0_4,0.1\n0.002,0.0,0.1\n")
    with pytest.raises(ParameterValueError, match=r"not numeric: sample 1 \(line 3\) holds '0_4'"):
        read_log(path, time="t", position="q", input="i")  # float("0_4") is 4.0


def test_an_empty_scheduler_is_refused(capsys, tmp_path, monkeypatch):
    monkeypatch.setattr("hpdob.simulation._sweep.sweep", must_not_run)
    spec = tmp_path / "s.toml"
    spec.write_text(SCENARIO.format(label="s") + "[sweep]\nn = 2\n")
    code, _, err = run_cli(capsys, "sweep", spec, "--out", tmp_path / "r.csv", "--scheduler", "")
    assert code == 2 and "--scheduler must be a dask address" in err and err.count("\n") == 1


@pytest.mark.parametrize("label", ["x\u202egnp.exe", "a\u200bb", "a\u2028b"])
def test_labels_with_bidi_or_invisible_characters_are_refused(capsys, tmp_path, label):
    spec = tmp_path / "s.toml"
    spec.write_text(SCENARIO.format(label=label.encode("unicode_escape").decode()))
    code, _, err = run_cli(capsys, "simulate", spec, "--out", tmp_path / "out", "--no-plot")
    assert code == 2 and "cannot name an output file" in err and err.count("\n") == 1, err
    assert not (tmp_path / "out").exists()


# -- item 12: one-line messages that name the parameter ---------------------------------------
@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["analyze", "noise", "--bandwidths", "1:1e400:5"], "positive finite values"),
        (["analyze", "bode", "--dpi", "1e-300"], "resolution of 10 to 1200 dots per inch"),
        (["analyze", "stability", "--orders", "1,1"], "distinct orders, got '1,1'"),
        (["tune", "--Ts", "0.2"], "default disturbance band 0.1-10 Hz reaches the Nyquist"),
        (["export-c", "--J-n", "-5e-4"], "J must be a positive finite inertia [kg m^2], got -0.0005"),  # noqa: E501
        (["analyze", "stability", "--values", "1:2:1001", "--bandwidths", "1:2:1000"],
         "1001 x 1000 = 1001000 points; at most 1000000"),
    ],
)  # fmt: skip
def test_unclear_messages_are_one_line_and_name_the_parameter(capsys, tmp_path, argv, needle):
    code, _, err = run_cli(capsys, *argv, "--out", tmp_path)
    assert code == 2 and needle in err and err.count("\n") == 1, err
    assert list(tmp_path.iterdir()) == []


def test_a_tiny_nominal_inertia_designs_without_a_leaked_warning(capsys):
    code, out, err = run_cli(capsys, "design", "--J-n", "1e-300")  # was an overflow warning
    assert code == 0 and err == "" and "eigenvalues" in out  # and a false "orthogonal" error


def test_api_errors_for_2d_arrays_are_one_line():
    from hpdob import ParameterValueError, ServoModel, design_observer

    model = ServoModel(2.8e-4).discretize(1e-3)
    with pytest.raises(ParameterValueError) as info:
        design_observer(model, order=1, poles=np.full((2, 2), 0.9))
    assert "\n" not in str(info.value)


def test_read_log_of_a_number_and_a_truncated_trace(tmp_path):
    from hpdob import ParameterTypeError, ParameterValueError, SimulationResult, read_log

    with pytest.raises(ParameterTypeError, match="path must be a file path"):
        read_log(3, time="t", position="q", input="i")
    text = paper.run("PD", duration=0.05).to_csv(tmp_path / "run.csv").read_text()
    (tmp_path / "cut.csv").write_text(text[: len(text) // 2])  # cut off mid-row
    with pytest.raises(ParameterValueError, match=r"cut.csv line \d+ is not a row of"):
        SimulationResult.from_csv(tmp_path / "cut.csv")  # was numpy's "inhomogeneous shape"


# -- item 2: a dask cluster that fails mid-sweep keeps the finished rows ----------------------
@pytest.mark.timeout(120)
def test_a_failing_dask_cluster_keeps_the_finished_rows(capsys, tmp_path, monkeypatch,
                                                        dask_cluster):  # fmt: skip
    distributed = pytest.importorskip("dask.distributed")
    import pandas as pd

    import hpdob.simulation._sweep as module

    real = module.run_chunk

    def fails_late(base, chunk, *args):  # as when every worker running it died (KilledWorker)
        if chunk[0][0] >= 4:
            raise distributed.KilledWorker("run_chunk-late", "tcp://127.0.0.1:1 (4 workers)")
        return real(base, chunk, *args)

    monkeypatch.setattr(module, "run_chunk", fails_late)
    spec = tmp_path / "s.toml"
    spec.write_text(
        SCENARIO.format(label="s")
        + '[sweep]\n[sweep.grid]\n"observer.bandwidth" = [40.0, 60.0, 80.0, 100.0, 120.0, 140.0]'
        + '\n"observer.order" = [0, 1]\n[observer]\norder = 1\nbandwidth = 100.0\n'
    )
    out = tmp_path / "rows.csv"
    cluster, _ = dask_cluster(1, processes=False, client=False)  # in-process: run_chunk patched
    argv = ["sweep", spec, "--out", out, "--scheduler", cluster.scheduler_address]
    code, _, err = run_cli(capsys, *argv)
    assert code == 1 and err.count("\n") == 1, err  # was "internal error" and no rows
    assert err.startswith("hpdob sweep: error: the dask cluster failed after 4 of 12 scenarios")
    assert "KilledWorker" in err and "missing: scenarios 4-11" in err and "--resume" in err
    assert not out.exists()  # the finished rows go to the partial file, --out stays complete
    rows = pd.read_csv(tmp_path / "rows.partial.csv")
    assert rows["scenario"].tolist() == [0, 1, 2, 3] and rows["error"].isna().all()


# -- item 13: bounded work, checked up front --------------------------------------------------
def test_oversized_scenario_and_log_files_are_refused_before_reading(capsys, tmp_path):
    from hpdob import ParameterValueError, read_log

    spec = tmp_path / "big.toml"
    spec.write_text(SCENARIO.format(label="s") + "# padding\n" * 200_000)  # 2 MB
    code, _, err = run_cli(capsys, "simulate", spec, "--out", tmp_path / "out")
    assert code == 2 and err.count("\n") == 1
    assert f"has {spec.stat().st_size} bytes; at most 1048576 bytes" in err
    log = tmp_path / "log.csv"
    with open(log, "wb") as handle:  # sparse: 300 MB that take no disk
        handle.truncate(300 << 20)
    with pytest.raises(ParameterValueError, match=r"has 314572800 bytes; at most 268435456"):
        read_log(log, time="t", position="q", input="i")


def test_analysis_grids_are_bounded_before_numpy_allocates(capsys, tmp_path):
    argv = ["analyze", "noise", "--bandwidths", "10:2000:100000000", "--out", tmp_path]
    code, _, err = run_cli(capsys, *argv)  # was a MemoryError after 12 s
    assert code == 2 and "at most 10000 values, got 100000000" in err and err.count("\n") == 1
