"""Issue 16, item 1: every file is written under a temporary name and renamed when complete.

A run that fails (a bad value found late, a full disk) or is interrupted leaves the previous
complete outputs, or files without their marker (``metrics.json``, the summary JSON): never a
truncated file, never a marker beside missing or stale files, never a temporary file.
"""

from __future__ import annotations

import errno
import json
import os
from pathlib import Path

import numpy as np
import pytest

from hpdob import (
    PD,
    ServoLoop,
    ServoModel,
    SimulationResult,
    design_observer,
    export_c,
    paper,
)
from hpdob.cli import main


def snapshot(directory: Path) -> dict:
    """``{relative path: bytes}`` of every file below ``directory``."""
    return {
        str(p.relative_to(directory)): p.read_bytes() for p in directory.rglob("*") if p.is_file()
    }


def no_temporaries(directory: Path) -> bool:
    return not [p for p in directory.rglob(".*") if p.is_file()]


def full_disk(*args, **kwargs):
    raise OSError(errno.ENOSPC, "No space left on device")


# -- the helpers ----------------------------------------------------------------------------
def stage(directory, files: dict, *, markers=(), error: BaseException | None = None) -> None:
    """Stage ``{name: text}`` in order, then raise ``error`` (if any) before the commit."""
    from hpdob._files import staged_outputs

    with staged_outputs(directory, markers=markers) as outputs:
        for name, text in files.items():
            outputs.write_text(name, text)
        if error is not None:
            raise error


def test_failed_run_leaves_previous_outputs(tmp_path):
    stage(tmp_path, {"a.csv": "old a\n", "metrics.json": "{}\n"}, markers=["metrics.json"])
    before = snapshot(tmp_path)
    with pytest.raises(RuntimeError, match="late failure"):
        stage(tmp_path, {"a.csv": "new a\n"}, error=RuntimeError("late failure"))
    assert snapshot(tmp_path) == before and no_temporaries(tmp_path)


def test_interrupted_run_leaves_previous_outputs(tmp_path):
    (tmp_path / "a.csv").write_text("old\n")
    with pytest.raises(KeyboardInterrupt):
        stage(tmp_path, {"a.csv": "new\n"}, error=KeyboardInterrupt())
    assert snapshot(tmp_path) == {"a.csv": b"old\n"} and no_temporaries(tmp_path)


def test_marker_is_renamed_last_and_removed_first(tmp_path, monkeypatch):
    (tmp_path / "a.csv").write_text("old a\n")
    (tmp_path / "b.csv").write_text("old b\n")
    (tmp_path / "metrics.json").write_text("old\n")
    renamed = []
    real_replace = os.replace

    def replace(src, dst):
        if len(renamed) == 1:  # the second rename fails (a full disk, a pulled USB stick)
            raise OSError(errno.EIO, "I/O error")
        renamed.append(Path(dst).name)
        real_replace(src, dst)

    monkeypatch.setattr(os, "replace", replace)
    new = {"metrics.json": "new\n", "a.csv": "new a\n", "b.csv": "new b\n"}  # marker first
    with pytest.raises(OSError, match="I/O error"):
        stage(tmp_path, new, markers=["metrics.json"])
    # a.csv is new, b.csv old: the set is mixed, and so there is no metrics.json
    assert renamed == ["a.csv"]
    assert snapshot(tmp_path) == {"a.csv": b"new a\n", "b.csv": b"old b\n"}
    assert no_temporaries(tmp_path)


def test_directory_targets_are_refused_before_writing(tmp_path):
    from hpdob._files import atomic_path

    (tmp_path / "a.csv").write_text("old\n")
    (tmp_path / "b.csv").mkdir()
    with pytest.raises(IsADirectoryError, match=r"b\.csv': it is an existing directory"):
        stage(tmp_path, {"a.csv": "new\n", "b.csv": "new\n"})
    assert (tmp_path / "a.csv").read_text() == "old\n" and no_temporaries(tmp_path)
    with pytest.raises(IsADirectoryError), atomic_path(tmp_path / "b.csv"):
        pass


# -- the writers ---------------------------------------------------------------------------
def short_result(label="run", end=1.0) -> SimulationResult:
    from hpdob.simulation._result import COLUMNS

    n = 50
    columns = {name: np.zeros(n) for name in COLUMNS}
    columns.update(t=np.arange(n) * 1e-3, theta=np.linspace(0.0, end, n))
    return SimulationResult(**columns, Ts=1e-3, label=label)


def test_to_csv_on_a_full_disk_keeps_the_previous_file(tmp_path, monkeypatch):
    import hpdob._table

    path = tmp_path / "trace.csv"
    short_result().to_csv(path)
    before = path.read_bytes()
    calls = []

    def cell(value):  # the disk fills up after 30 cells
        calls.append(value)
        if len(calls) > 30:
            full_disk()
        return repr(float(value))

    monkeypatch.setattr(hpdob._table, "_cell", cell)
    with pytest.raises(OSError, match="No space left"):
        short_result().to_csv(path)
    assert path.read_bytes() == before and no_temporaries(tmp_path)


def fake_runs(monkeypatch, *, fail_on_figure=None, end=1.0):
    """Make ``paper.reproduce`` fast: short results ending at ``end`` and small figures of
    them, optionally failing on one figure."""
    import matplotlib.pyplot as plt

    import hpdob.paper._figures
    import hpdob.paper._reproduce

    monkeypatch.setattr(hpdob.paper._reproduce, "run", lambda name: short_result(name, end))

    def figures(results):
        out = {}
        for name in ("fig2", "fig3", "fig4", "fig5"):
            if name == fail_on_figure:
                raise RuntimeError(f"{name} failed")
            fig, ax = plt.subplots(figsize=(2, 2))
            ax.plot([0, 1], [0, end])
            out[name] = fig
        return out

    monkeypatch.setattr(hpdob.paper._figures, "paper_figures", figures)


def test_reproduce_failing_late_keeps_the_previous_complete_set(tmp_path, monkeypatch):
    fake_runs(monkeypatch)
    paper.reproduce(tmp_path)
    before = snapshot(tmp_path)
    assert "metrics.json" in before and "traces/PD.csv" in before and "fig5.pdf" in before
    fake_runs(monkeypatch, fail_on_figure="fig4", end=2.0)  # new traces, fig2, fig3
    with pytest.raises(RuntimeError, match="fig4 failed"):
        paper.reproduce(tmp_path)
    assert snapshot(tmp_path) == before and no_temporaries(tmp_path)


def test_reproduce_on_a_full_disk_writes_nothing(tmp_path, monkeypatch):
    import matplotlib.figure

    fake_runs(monkeypatch)

    def savefig(self, fname, **kwargs):
        Path(fname).write_bytes(b"\x89PNG truncated")
        full_disk()

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", savefig)
    with pytest.raises(OSError, match="No space left"):
        paper.reproduce(tmp_path / "out")
    files = snapshot(tmp_path)
    assert "out/metrics.json" not in files and not any(k.endswith(".png") for k in files)
    assert no_temporaries(tmp_path)


def run_cli(capsys, *argv):
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exit_:  # argparse's errors
        code = exit_.code
    out, err = capsys.readouterr()
    return code, out, err


def test_analyze_bode_with_bad_frequency_writes_nothing(capsys, tmp_path):
    code, _, err = run_cli(capsys, "analyze", "bode", "--frequency", "nan", "--out", tmp_path)
    assert code == 2 and err.count("\n") == 1 and "--frequency" in err
    assert snapshot(tmp_path) == {}


def test_analyze_stability_failing_on_a_later_order_keeps_nothing(capsys, tmp_path):
    code, _, err = run_cli(
        capsys, "analyze", "stability", "--orders", "0,60", "--values", "0.5,1",
        "--bandwidths", "50,100", "--out", tmp_path,
    )  # fmt: skip
    assert code == 2 and "order must be at most 50" in err
    assert snapshot(tmp_path) == {}


def test_analyze_rejects_huge_dpi(capsys, tmp_path):
    code, _, err = run_cli(capsys, "analyze", "bode", "--dpi", "100000", "--out", tmp_path)
    assert code == 2 and "10 to 1200 dots per inch" in err and err.count("\n") == 1
    assert snapshot(tmp_path) == {}


def test_export_c_refuses_a_directory_target_and_keeps_the_header(tmp_path):
    design = design_observer(ServoModel(2.8e-4).discretize(1e-3), order=1, bandwidth=100.0)
    (tmp_path / "dob.h").write_text("/* the previous header */\n")
    (tmp_path / "dob.c").mkdir()
    with pytest.raises(ValueError, match=r"dob\.c': it is an existing directory"):
        export_c(design, tmp_path)
    assert (tmp_path / "dob.h").read_text() == "/* the previous header */\n"
    assert no_temporaries(tmp_path)


def test_export_c_failing_second_file_keeps_both(tmp_path, monkeypatch):
    design = design_observer(ServoModel(2.8e-4).discretize(1e-3), order=1, bandwidth=100.0)
    export_c(design, tmp_path)
    before = snapshot(tmp_path)
    other = design_observer(ServoModel(2.8e-4).discretize(1e-3), order=0, bandwidth=50.0)
    real_write = Path.write_text

    def write_text(self, text, *args, **kwargs):
        if self.name.startswith(".dob.c"):
            real_write(self, text[:100], *args, **kwargs)
            full_disk()
        return real_write(self, text, *args, **kwargs)

    monkeypatch.setattr(Path, "write_text", write_text)
    with pytest.raises(OSError, match="No space left"):
        export_c(other, tmp_path)
    assert snapshot(tmp_path) == before and no_temporaries(tmp_path)


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


@pytest.mark.parametrize("label", ["../escaped", "a\\u0000b", "sub/dir", ".hidden"])
def test_simulate_label_cannot_escape_the_output_directory(capsys, tmp_path, label):
    spec = tmp_path / "spec" / "s.toml"
    spec.parent.mkdir()
    spec.write_text(SCENARIO.format(label=label))
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, "simulate", spec, "--out", out, "--no-plot")
    assert code == 2 and err.startswith("hpdob simulate: error: label ") and err.count("\n") == 1
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["s.toml", "spec"]


def test_simulate_writes_staged_outputs(capsys, tmp_path):
    spec = tmp_path / "s.toml"
    spec.write_text(SCENARIO.format(label="step run"))
    code, _, _ = run_cli(capsys, "simulate", spec, "--out", tmp_path / "out", "--no-plot")
    assert code == 0
    assert sorted(snapshot(tmp_path / "out")) == ["metrics.json", "step run.csv"]
    assert list(json.loads((tmp_path / "out" / "metrics.json").read_text())) == ["step run"]


@pytest.mark.parametrize(
    "argv",
    [
        ["reproduce", "--out", ""],
        ["simulate", "x.toml", "--out", ""],
        ["sweep", "x.toml", "--out", ""],
        ["analyze", "bode", "--out", " "],
        ["export-c", "--out", ""],
        ["identify", "--emps", "--out", ""],
        ["estimate", "--emps", "--J-n", "1", "--out", ""],
        ["compare", "--out", ""],
        ["tune", "--out", ""],
        ["tune", "--export-c", " "],
    ],
)
def test_empty_out_is_refused(capsys, tmp_path, monkeypatch, argv):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as info:
        main(argv)
    err = capsys.readouterr().err
    assert info.value.code == 2 and "expected a non-empty path" in err
    assert list(tmp_path.iterdir()) == []


def test_sweep_output_on_a_full_disk_keeps_the_previous_table(capsys, tmp_path, monkeypatch):
    import pandas as pd

    spec = tmp_path / "sweep.toml"
    spec.write_text(SCENARIO.format(label="x") + '[sweep]\ngrid = {"plant.J" = [3e-4, 4e-4]}\n')
    out = tmp_path / "rows.parquet"
    assert run_cli(capsys, "sweep", spec, "--out", out, "--workers", "1")[0] == 0
    before = out.read_bytes()

    def to_parquet(self, path, **kwargs):
        Path(path).write_bytes(before[:64])
        full_disk()

    monkeypatch.setattr(pd.DataFrame, "to_parquet", to_parquet)
    code, _, err = run_cli(capsys, "sweep", spec, "--out", out, "--workers", "1")
    assert code == 2 and "No space left" in err
    assert out.read_bytes() == before and no_temporaries(tmp_path)


# -- hpdob estimate, compare and tune: staged like the others, their JSON last ---------------
def write_log(path: Path, n: int = 400) -> Path:
    t = np.arange(n) * 1e-3
    rows = ["t,q,i"] + [f"{float(v)!r},{0.1 * float(np.sin(v))!r},0.02" for v in t]
    path.write_text("\n".join(rows) + "\n")
    return path


ESTIMATE = ["--time", "t", "--position", "q", "--input", "i", "--J-n", "2.8e-4"]


def previous_outputs(out: Path, names) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    for name in names:
        (out / name).write_text("previous\n")
    return snapshot(out)


def fail_to_draw(*args, **kwargs):
    raise OSError(errno.ENOSPC, "No space left on device")


def test_estimate_writes_a_staged_set_with_its_json_last(capsys, tmp_path, monkeypatch):
    log, out = write_log(tmp_path / "log.csv"), tmp_path / "out"
    assert run_cli(capsys, "estimate", log, *ESTIMATE, "--out", out)[0] == 0
    assert sorted(snapshot(out)) == ["estimate.csv", "estimate.json", "estimate.png"]
    before = previous_outputs(out, ["estimate.csv", "estimate.json", "estimate.png"])
    from hpdob.identification import LogEstimate

    monkeypatch.setattr(LogEstimate, "plot", fail_to_draw)  # fails after the CSV
    code, _, err = run_cli(capsys, "estimate", log, *ESTIMATE, "--out", out)
    assert code == 2 and "No space left" in err and err.count("\n") == 1
    assert snapshot(out) == before and no_temporaries(out)


def test_estimate_that_diverges_writes_nothing(capsys, tmp_path):
    log = tmp_path / "log.csv"
    log.write_text("t,q,i\n" + "".join(f"{k / 1000},1e300,1e300\n" for k in range(50)))
    code, _, err = run_cli(capsys, "estimate", log, *ESTIMATE, "--out", tmp_path / "out")
    assert code == 2 and "the estimate of" in err and "not finite" in err, err
    assert not (tmp_path / "out").exists()


class FakeComparison:
    """What ``hpdob compare`` needs of a Comparison, instantly."""

    def __init__(self):
        self.rows = [{"observer": "DOb", "sensor": "ideal"}]

    def to_csv(self, path):
        Path(path).write_text("observer,sensor\nDOb,ideal\n")

    def to_markdown(self):
        return "| DOb |\n"

    def to_dict(self):
        return {"rows": self.rows}

    def plot(self):
        import matplotlib.pyplot as plt

        return plt.figure(figsize=(1, 1))


def test_compare_writes_a_staged_set_with_its_json_last(capsys, tmp_path, monkeypatch):
    import hpdob.analysis

    monkeypatch.setattr(hpdob.analysis, "compare_observers", lambda *a, **kw: FakeComparison())
    out = tmp_path / "out"
    assert run_cli(capsys, "compare", "--out", out)[0] == 0
    names = ["comparison.csv", "comparison.json", "comparison.md", "comparison.png"]
    assert sorted(snapshot(out)) == names
    before = previous_outputs(out, names)
    monkeypatch.setattr(FakeComparison, "plot", fail_to_draw)
    code, _, err = run_cli(capsys, "compare", "--out", out)
    assert code == 2 and "No space left" in err
    assert snapshot(out) == before and no_temporaries(out)


class FakeTuning:
    """What ``hpdob tune`` needs of a TuningResult, instantly."""

    def __init__(self):
        import pandas as pd

        self.table = pd.DataFrame({"family": ["state"], "order": [1]})
        self.design = design_observer(ServoModel(2.8e-4).discretize(1e-3), order=1,
                                      bandwidth=100.0)  # fmt: skip

        self.recommendation = {"name": "HPDOb", "parameter": "bandwidth", "value": 100.0}
        self.scenario = {"reference": paper.REFERENCE, "duration": 1.0}

    def loop(self):
        nominal = ServoModel(2.8e-4)
        return ServoLoop(plant=nominal, nominal=nominal, Ts=1e-3, controller=PD(50.0, 5.0),
                         observer=self.design)  # fmt: skip

    def plot(self):
        import matplotlib.pyplot as plt

        return plt.figure(figsize=(1, 1))

    def to_dict(self):
        return {"recommendation": "HPDOb"}

    def report(self):
        return "Recommended: HPDOb"


def test_tune_writes_a_staged_set_and_checks_the_c_options_first(capsys, tmp_path, monkeypatch):
    import hpdob.tuning

    calls = []
    monkeypatch.setattr(hpdob.tuning, "tune", lambda **kw: calls.append(kw) or FakeTuning())
    out, c = tmp_path / "out", tmp_path / "c"
    assert run_cli(capsys, "tune", "--out", out, "--export-c", c)[0] == 0
    assert sorted(snapshot(out)) == ["scenario.toml", "tune.csv", "tune.json", "tune.png"]
    assert sorted(snapshot(c)) == ["dob.c", "dob.h"]
    before = previous_outputs(out, ["scenario.toml", "tune.csv", "tune.json", "tune.png"])
    # a C export that fails (the directory is a file) leaves the previous tune.* as they were
    monkeypatch.setattr(hpdob.export, "export_c", fail_to_draw)
    code, _, err = run_cli(capsys, "tune", "--out", out, "--export-c", c)
    assert code == 2 and "No space left" in err
    assert snapshot(out) == before and no_temporaries(out)
    # bad C options are refused before the (long) search runs
    calls.clear()
    for argv, needle in [
        (["--export-c", c, "--prefix", "math"], "shadows the C standard header"),
        (["--export-c", c, "--dtype", "half"], "dtype must be one of"),
        (["--export-c", out / "tune.csv"], "must be a directory"),
        (["--prefix", "axis1"], "apply to --export-c only"),
    ]:
        code, _, err = run_cli(capsys, "tune", "--out", out, *argv)
        assert code == 2 and needle in err and err.count("\n") == 1, err
    assert calls == []
