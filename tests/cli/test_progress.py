"""Issue 27 item 13: the long jobs within the documented limits show progress with the time
left, or state their size up front. The lines are checked with an injected clock, never the
speed (no wall-clock timing in tests)."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
import pytest

from hpdob import PD, ParameterTypeError, ServoModel, robust_stability_map
from hpdob.cli import _simulate as cli_simulate
from hpdob.cli import _tune as cli_tune
from hpdob.cli import main
from hpdob.cli._progress import ProgressLine, format_seconds
from hpdob.simulation._scenario import read_toml, scenario_from_dict

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


class Clock:
    """A clock the test advances by hand."""

    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def test_progress_line_states_done_total_and_time_left():
    stream, clock = io.StringIO(), Clock()
    line = ProgressLine("map", stream, clock=clock)
    line(0, 1000)
    clock.now += 30.0  # 250 of 1000 in 30 s: 750 more take about 90 s
    line(250, 1000)
    clock.now += 3600.0
    line(500, 1000)
    line(1000, 1000)
    frames = stream.getvalue().split("\r\x1b[K")[1:]
    assert frames == [
        "map 0/1000 (0%)",
        "map 250/1000 (25%), about 1 min 30 s left",
        "map 500/1000 (50%), about 1 h 00 min left",  # 3630 s for 500 (minutes floored)
        "map 1000/1000 (100%)\n",
    ]


@pytest.mark.parametrize(
    ("seconds", "text"), [(0.4, "0 s"), (59.4, "59 s"), (65, "1 min 05 s"), (7260, "2 h 01 min")]
)
def test_format_seconds(seconds, text):
    assert format_seconds(seconds) == text


def test_stability_map_reports_counts_per_row_and_result_unchanged():
    calls = []
    args = {
        "J_ratio": np.geomspace(0.1, 3.0, 4),
        "bandwidth": [50.0, 100.0, 200.0],
        "order": 1,
        "nominal": ServoModel(2.8e-4),
        "Ts": 1e-3,
        "controller": PD(50.0, 5.0),
    }
    smap = robust_stability_map(**args, progress=lambda d, t: calls.append((d, t)))
    assert calls == [(0, 12), (3, 12), (6, 12), (9, 12), (12, 12)]
    plain = robust_stability_map(**args)
    assert np.array_equal(smap.spectral_radius, plain.spectral_radius)
    with pytest.raises(ParameterTypeError, match=r"progress must be a callable .* got 'yes'"):
        robust_stability_map(**args, progress="yes")


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_analyze_stability_progress_on_stderr_only(capsys, tmp_path):
    common = ("analyze", "stability", "--orders", "0,1", "--values", "0.5,1,2",
              "--bandwidths", "50,100", "--dpi", "30")  # fmt: skip
    code, out, err = run(capsys, *common, "--out", str(tmp_path / "p"), "--progress")
    assert code == 0
    # one line for both maps: done/total (and the time left) count every requested order
    frames = err.split("\r\x1b[K")[1:]
    assert frames[0] == "analyze stability: order 0, 0/12 (0%)"
    assert "analyze stability: order 0, 6/12 (50%)" in frames[3]
    assert "analyze stability: order 1, 6/12 (50%)" in frames[4]
    assert frames[-1] == "analyze stability: order 1, 12/12 (100%)\n"
    assert err.count("\n") == 1 and all("left" in f for f in frames[1:-1] if "0/12" not in f)
    assert "analyze stability" not in out
    code, _, quiet = run(capsys, *common, "--out", str(tmp_path / "q"), "--no-progress")
    assert code == 0 and "analyze stability:" not in quiet
    # Not a terminal (pytest captures stderr) and no flag: silent; the outputs are the same.
    code, _, default = run(capsys, *common, "--out", str(tmp_path / "d"))
    assert code == 0 and "analyze stability:" not in default
    for name in ("stability.json", "stability_J_ratio_m1.csv"):
        assert (tmp_path / "p" / name).read_bytes() == (tmp_path / "q" / name).read_bytes()


def test_stability_time_left_covers_every_requested_order():
    # issue 27: the time left used to cover the current order's map only
    from hpdob.cli._analyze import _overall

    stream, clock = io.StringIO(), Clock()
    line = ProgressLine("analyze stability:", stream, clock=clock)
    first, second = _overall(line, 0, 2, 0), _overall(line, 1, 2, 1)
    first(0, 100)
    clock.now += 10.0
    first(50, 100)  # 50 of 200 points in 10 s: 150 more take 30 s (not 10 s: order 0's rest)
    first(100, 100)
    second(0, 100)
    clock.now += 10.0
    second(100, 100)
    assert stream.getvalue().split("\r\x1b[K")[1:] == [
        "analyze stability: order 0, 0/200 (0%)",
        "analyze stability: order 0, 50/200 (25%), about 30 s left",
        "analyze stability: order 0, 100/200 (50%), about 10 s left",
        "analyze stability: order 1, 100/200 (50%), about 10 s left",
        "analyze stability: order 1, 200/200 (100%)\n",
    ]


def test_tune_progress_has_time_left_per_stage():
    stream, clock = io.StringIO(), Clock()
    show = cli_tune._Progress(stream, clock=clock)
    show("analysis", 0, 4)
    clock.now += 10.0
    show("analysis", 1, 4)
    show("analysis", 4, 4)
    show("simulation", 0, 2)
    clock.now += 5.0
    show("simulation", 1, 2)
    show("verification", 0, 1)  # a stage left before its end still gets its own line
    show("verification", 1, 1)
    frames = stream.getvalue().split("\r\x1b[K")[1:]
    assert frames == [
        "tune: analysing candidates 0/4 (0%)",
        "tune: analysing candidates 1/4 (25%), about 30 s left",
        "tune: analysing candidates 4/4 (100%)\n",
        "tune: simulating the robust ones 0/2 (0%)",
        "tune: simulating the robust ones 1/2 (50%), about 5 s left\n",
        "tune: verifying at the corners 0/1 (0%)",
        "tune: verifying at the corners 1/1 (100%)\n",
    ]


def _canonical(duration):
    data = read_toml(EXAMPLES / "canonical_hpdob.toml")
    data["duration"] = duration
    return scenario_from_dict(data)


def test_simulate_states_a_long_run_before_it(capsys):
    # 2000 s at 1 ms with the canonical plant's 8 sub-steps: 1.6e7 plant steps, announced
    # (not run: the notice is computed from the arguments alone).
    cli_simulate._check_size(_canonical(2000.0))
    err = capsys.readouterr().err
    assert err == (
        "hpdob simulate: a long run of 2000000 samples x 8 substeps = 1.6e+07 plant steps "
        "(the limits per run are 2000000 samples and 1e+08 plant steps); --progress shows how "
        "far it is\n"
    )
    cli_simulate._check_size(_canonical(2000.0), showing=True)  # the progress says it all
    assert capsys.readouterr().err == ""
    cli_simulate._check_size(_canonical(10.0))  # 8e4 plant steps: nothing to say
    assert capsys.readouterr().err == ""


def test_simulate_refuses_a_run_beyond_its_sample_limit(capsys, tmp_path):
    # issue 27: a run up to 1e8 plant steps (1e8 samples: a 17 GB CSV, half an hour) showed
    # no progress; the command now stops at 2e6 samples, about a minute, before any work
    from hpdob.cli import CLIError

    with pytest.raises(
        CLIError,
        match=r"^a run of 2000001 samples \(duration 2000\.001 s at "
        r"Ts = 0\.001 s\) is beyond hpdob simulate's limit of 2000000 samples",
    ):
        cli_simulate._check_size(_canonical(2000.001))
    scenario = tmp_path / "long.toml"
    text = (EXAMPLES / "canonical_hpdob.toml").read_text()
    scenario.write_text(text.replace("duration = 10.0", "duration = 1e5"))
    assert "duration = 1e5" in scenario.read_text()
    code = main(["simulate", str(scenario), "--out", str(tmp_path / "o"), "--no-plot"])
    out, err = capsys.readouterr()
    assert code == 2 and out == "" and err.count("\n") == 1, err
    assert "a run of 100000000 samples" in err and "limit of 2000000 samples" in err
    assert not (tmp_path / "o").exists()


def test_simulate_notice_leaves_the_results_bit_for_bit(capsys, tmp_path, monkeypatch):
    scenario = str(EXAMPLES / "canonical_hpdob.toml")
    assert main(["simulate", scenario, "--out", str(tmp_path / "a"), "--no-plot"]) == 0
    assert "long run" not in capsys.readouterr().err
    monkeypatch.setattr(cli_simulate, "NOTICE_PLANT_STEPS", 1000)
    assert main(["simulate", scenario, "--out", str(tmp_path / "b"), "--no-plot"]) == 0
    out, err = capsys.readouterr()
    assert "plant steps" in err and "plant steps" not in out
    for name in ("metrics.json", "HPDOb-100.csv"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
    assert json.loads((tmp_path / "b" / "metrics.json").read_text())


def test_sweep_bar_covers_a_million_scenarios_with_time_left(monkeypatch):
    # The sweep's tqdm bar (issue 16) counts scenarios against the total and shows
    # elapsed<remaining; its line at a chosen elapsed time is formatted, not timed.
    from hpdob.simulation import _sweep

    stream = io.StringIO()
    monkeypatch.setattr(_sweep.sys, "stderr", stream)
    update, close = _sweep._progress_callback(True, 10**6)
    bar = update.__self__
    update(250_000)
    line = bar.format_meter(**{**bar.format_dict, "elapsed": 30.0})
    close()
    assert "250000/1000000" in line and "00:30<01:30" in line, line
    assert "hpdob sweep" in stream.getvalue()


def _small_sweep(tmp_path):
    text = (EXAMPLES / "sweep_bandwidth.toml").read_text()
    text = text.replace("duration = 10.0", "duration = 0.2").replace("n = 20", "n = 1")
    text = text.replace('"observer.order" = [0, 1, 2]', '"observer.order" = [1]')
    spec = tmp_path / "sweep.toml"
    spec.write_text(text)
    return spec


def test_cli_sweep_progress_flag(capsys, tmp_path):
    spec = _small_sweep(tmp_path)
    assert main(["sweep", str(spec), "--out", str(tmp_path / "a.csv"), "--workers", "1",
                 "--progress"]) == 0  # fmt: skip
    out, err = capsys.readouterr()
    assert "hpdob sweep" in err and "4/4" in err and "4/4" not in out
    assert main(["sweep", str(spec), "--out", str(tmp_path / "b.csv"), "--workers", "1",
                 "--no-progress"]) == 0  # fmt: skip
    assert "4/4" not in capsys.readouterr().err
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()


def test_a_line_left_open_is_ended_once():
    # tune --delay 999 that finds no stable candidate used to print its error after the
    # progress line, on the same line; the commands now end an open line first.
    stream = io.StringIO()
    line = ProgressLine("map", stream, clock=Clock())
    line(0, 10)
    line.end()
    line.end()
    assert stream.getvalue() == "\r\x1b[Kmap 0/10 (0%)\n"
    done = io.StringIO()
    line = ProgressLine("map", done, clock=Clock())
    line(10, 10)
    line.end()  # already ended by the last count
    assert done.getvalue() == "\r\x1b[Kmap 10/10 (100%)\n"
    stream = io.StringIO()
    show = cli_tune._Progress(stream, clock=Clock())
    show("analysis", 3, 72)
    show.end()
    assert stream.getvalue() == "\r\x1b[Ktune: analysing candidates 3/72 (4%), about 0 s left\n"


def test_read_log_reports_the_bytes_read(tmp_path, monkeypatch):
    # issue 27: `hpdob estimate` on a log under the 256 MiB cap read it with no progress
    import hpdob.identification._readers as readers
    from hpdob import read_log

    monkeypatch.setattr(readers, "PROGRESS_STEP", 1000)  # a report every 1000 characters
    path = tmp_path / "log.csv"
    rows = [
        f"{k * 1e-3!r},{float(np.sin(k * 1e-3))!r},{float(np.cos(k * 1e-3))!r}" for k in range(2000)
    ]
    path.write_text("t,q,u\n" + "\n".join(rows) + "\n")
    calls = []
    log = read_log(path, time="t", position="q", input="u", progress=lambda *c: calls.append(c))
    size = path.stat().st_size
    assert calls[0] == (0, size) and calls[-1] == (size, size)
    done = [d for d, _ in calls]
    assert done == sorted(done) and len(calls) >= size // 1000 and {t for _, t in calls} == {size}
    plain = read_log(path, time="t", position="q", input="u")
    assert np.array_equal(log.theta, plain.theta) and np.array_equal(log.u, plain.u)
    with pytest.raises(ParameterTypeError, match=r"^progress must be a callable"):
        read_log(path, time="t", position="q", input="u", progress="yes")


def test_estimate_progress_reading_and_estimating_on_stderr_only(capsys, tmp_path, monkeypatch):
    import hpdob.identification._readers as readers

    monkeypatch.setattr(readers, "PROGRESS_STEP", 4096)
    path = tmp_path / "log.csv"
    rows = [f"{k * 1e-3!r},{float(1e-3 * np.sin(k * 1e-2))!r},{float(0.01 * np.cos(k * 1e-2))!r}"
            for k in range(3000)]  # fmt: skip
    path.write_text("t,q,u\n" + "\n".join(rows) + "\n")
    common = ["estimate", str(path), "--time", "t", "--position", "q", "--input", "u",
              "--J-n", "2.8e-4", "--no-plot"]  # fmt: skip
    code, out, err = run(capsys, *common, "--out", str(tmp_path / "p"), "--progress")
    assert code == 0, err
    frames = err.split("\r\x1b[K")[1:]
    mib = path.stat().st_size / 2**20
    assert frames[0] == f"hpdob estimate: reading log.csv 0.0/{mib:.1f} MiB (0%)"
    assert frames[1].startswith("hpdob estimate: reading log.csv ") and "left" in frames[1]
    assert f"hpdob estimate: reading log.csv {mib:.1f}/{mib:.1f} MiB (100%)\n" in frames
    assert frames[-2:] == [  # one stage: the CSV is written as the estimate runs (issue 25)
        "hpdob estimate: estimating, writing estimate.csv 0/3000 rows (0%)",  # one chunk
        "hpdob estimate: estimating, writing estimate.csv 3000/3000 rows (100%)\n",
    ]
    assert "hpdob estimate:" not in out
    code, _, quiet = run(capsys, *common, "--out", str(tmp_path / "q"), "--no-progress")
    assert code == 0 and quiet == ""
    code, _, default = run(capsys, *common, "--out", str(tmp_path / "d"))  # not a terminal
    assert code == 0 and default == ""
    for name in ("estimate.csv", "estimate.json"):
        assert (tmp_path / "p" / name).read_bytes() == (tmp_path / "q" / name).read_bytes()


def test_simulate_progress_on_stderr_only_and_the_same_files(capsys, tmp_path, monkeypatch):
    # issue 27: `hpdob simulate` showed no progress; the kernel now runs in chunks (the same
    # bits, tests/simulation/test_simulate.py) and reports the samples done with the time left
    import hpdob.simulation._simulate as module

    monkeypatch.setattr(module, "PROGRESS_PLANT_STEPS", 8 * 2500)  # 2500 samples a chunk
    scenario = str(EXAMPLES / "canonical_hpdob.toml")
    code, out, err = run(capsys, "simulate", scenario, "--out", str(tmp_path / "p"),
                         "--no-plot", "--progress")  # fmt: skip
    assert code == 0, err
    frames = err.split("\r\x1b[K")[1:]
    assert frames[0] == "hpdob simulate: 0/10000 samples (0%)"
    assert frames[1].startswith("hpdob simulate: 2500/10000 samples (25%), about ")
    assert frames[4] == "hpdob simulate: 10000/10000 samples (100%)\n"
    assert frames[5:] == [
        "hpdob simulate: writing HPDOb-100.csv 0/10000 rows (0%)",
        "hpdob simulate: writing HPDOb-100.csv 10000/10000 rows (100%)\n",
    ]
    assert "hpdob simulate:" not in out
    code, _, quiet = run(capsys, "simulate", scenario, "--out", str(tmp_path / "q"), "--no-plot")
    assert code == 0 and quiet == ""  # not a terminal: no progress, one call of the kernel
    for name in ("metrics.json", "HPDOb-100.csv"):
        assert (tmp_path / "p" / name).read_bytes() == (tmp_path / "q" / name).read_bytes()


def test_identify_stage_lines_have_time_left_per_stage():
    # issue 27 (rel4, item 2): identify's stages, each timed by its own clock
    from hpdob.cli import _identify as cli_identify
    from hpdob.cli._progress import StagedProgress

    stream, clock = io.StringIO(), Clock()
    show = StagedProgress("hpdob identify:", cli_identify.STAGES, stream, clock)
    show("filtering", 0, 1)
    show("filtering", 1, 1)
    show("iterating", 0, 20)
    clock.now += 4.0  # 2 of at most 20 in 4 s: at most 36 s more
    show("iterating", 2, 20)
    show("iterating", 3, 3)  # converged after 3
    show("sensitivity", 0, 2)
    clock.now += 7.0
    show("sensitivity", 1, 2)
    show.end()  # interrupted: the open line is ended
    frames = stream.getvalue().split("\r\x1b[K")[1:]
    assert frames == [
        "hpdob identify: filtering the logs 0/1 (0%)",
        "hpdob identify: filtering the logs 1/1 (100%)\n",
        "hpdob identify: IDIM-IV iterations (at most) 0/20 (0%)",
        "hpdob identify: IDIM-IV iterations (at most) 2/20 (10%), about 36 s left",
        "hpdob identify: IDIM-IV iterations (at most) 3/3 (100%)\n",
        "hpdob identify: re-estimating with the filters x2, /2 0/2 (0%)",
        "hpdob identify: re-estimating with the filters x2, /2 1/2 (50%), about 7 s left\n",
    ]


def test_cli_identify_progress_on_stderr_only(capsys, tmp_path):
    # noise-free motion with J = 2, b = 3, c = 1.5, offset = -0.4 (as test_cli_identify's)
    t = np.arange(5000) * 1e-3
    w = 2 * np.pi
    q = 0.3 * np.sin(w * t) + 0.05 * np.sin(3 * w * t)
    qd = 0.3 * w * np.cos(w * t) + 0.15 * w * np.cos(3 * w * t)
    qdd = -0.3 * w**2 * np.sin(w * t) - 0.45 * w**2 * np.sin(3 * w * t)
    u = 2.0 * qdd + 3.0 * qd + 1.5 * np.sign(qd) - 0.4
    log = tmp_path / "run.csv"
    rows = zip(t.tolist(), q.tolist(), u.tolist(), strict=True)
    log.write_text("time,pos,cmd\n" + "".join(f"{a!r},{b!r},{c!r}\n" for a, b, c in rows))
    common = ["identify", str(log), "--time", "time", "--position", "pos", "--input", "cmd",
              "--no-plot"]  # fmt: skip
    assert main([*common, "--out", str(tmp_path / "a"), "--progress"]) == 0
    out, err = capsys.readouterr()
    frames = err.split("\r\x1b[K")[1:]
    assert frames[0].startswith("hpdob identify: reading run.csv 0.0/0.")
    assert [f for f in frames if f.endswith("\n")][1:] == [
        "hpdob identify: filtering the logs 1/1 (100%)\n",
        *[f for f in frames if f.startswith("hpdob identify: IDIM-IV") and f.endswith("\n")],
        "hpdob identify: re-estimating with the filters x2, /2 2/2 (100%)\n",
        "hpdob identify: simulating the fit 1/1 (100%)\n",
    ]
    assert "\r" not in out
    assert main([*common, "--out", str(tmp_path / "b"), "--no-progress"]) == 0
    quiet_out, quiet_err = capsys.readouterr()
    assert quiet_err == "" and quiet_out.replace(str(tmp_path / "b"), "") == out.replace(
        str(tmp_path / "a"), "")  # fmt: skip
    for name in ("identification.json", "identification.csv"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()


def test_simulate_writing_stage_counts_the_chunks(capsys, tmp_path, monkeypatch):
    # issue 27 (rel4, item 3): the CSV is formatted in chunks; the line counts their rows
    from hpdob import _csv_floats

    monkeypatch.setattr(_csv_floats, "CHUNK", 4000)  # 10000 rows: chunks of 4000, 4000, 2000
    scenario = str(EXAMPLES / "canonical_hpdob.toml")
    assert main(["simulate", scenario, "--out", str(tmp_path / "a"), "--no-plot",
                 "--progress"]) == 0  # fmt: skip
    frames = capsys.readouterr().err.split("\r\x1b[K")[1:]
    writing = [f for f in frames if "writing" in f]
    # (the time left of the middle lines is the real clock's: only their counts are checked)
    assert [f.split(", about")[0] for f in writing] == [
        "hpdob simulate: writing HPDOb-100.csv 0/10000 rows (0%)",
        "hpdob simulate: writing HPDOb-100.csv 4000/10000 rows (40%)",
        "hpdob simulate: writing HPDOb-100.csv 8000/10000 rows (80%)",
        "hpdob simulate: writing HPDOb-100.csv 10000/10000 rows (100%)\n",
    ]
    assert main(["simulate", scenario, "--out", str(tmp_path / "b"), "--no-plot"]) == 0
    capsys.readouterr()
    name = "HPDOb-100.csv"
    assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()


def test_noise_tradeoff_reports_counts_per_point_and_result_unchanged():
    from hpdob import noise_tradeoff

    calls = []
    kwargs = {"nominal": ServoModel(2.8e-4), "Ts": 1e-3, "frequency": 2.0,
              "bandwidths": [50.0, 100.0, 200.0], "orders": (0, 1)}  # fmt: skip
    quiet = noise_tradeoff(**kwargs)
    loud = noise_tradeoff(**kwargs, progress=lambda done, total: calls.append((done, total)))
    assert calls == [(k, 6) for k in range(7)]
    assert np.array_equal(quiet.error_gain, loud.error_gain)
    assert np.array_equal(quiet.noise_gain, loud.noise_gain)
    with pytest.raises(ParameterTypeError, match=r"^progress must be a callable"):
        noise_tradeoff(**kwargs, progress=3)


@pytest.mark.parametrize(
    ("view", "options", "total", "files"),
    [
        ("noise", ("--orders", "0,1", "--bandwidths", "50,100,200"), 6,
         ("noise.csv", "noise.json")),
        ("tradeoff", ("--orders", "0,1", "--bandwidths", "50,100,200"), 6,
         ("tradeoff.csv", "tradeoff.json")),
        ("bode", ("--orders", "0,1"), 4, ("bode.csv", "bode.json")),
    ],
)  # fmt: skip
def test_analyze_grid_views_progress_on_stderr_only(capsys, tmp_path, view, options, total,
                                                    files):  # fmt: skip
    # Issue 27 item 13: `analyze noise` over a 10 000-point grid ran for minutes with nothing
    # on stderr; noise, tradeoff and bode now show done/total and the time left, like stability.
    common = ("analyze", view, *options, "--dpi", "30")
    code, out, err = run(capsys, *common, "--out", str(tmp_path / "p"), "--progress")
    assert code == 0
    frames = err.split("\r\x1b[K")[1:]
    assert frames[0] == f"analyze {view}: 0/{total} (0%)"
    assert frames[-1] == f"analyze {view}: {total}/{total} (100%)\n"
    assert len(frames) == total + 1 and err.count("\n") == 1
    assert all(", about " in f and " left" in f for f in frames[1:-1])
    assert f"analyze {view}:" not in out
    code, _, quiet = run(capsys, *common, "--out", str(tmp_path / "q"), "--no-progress")
    assert code == 0 and quiet == ""
    code, _, default = run(capsys, *common, "--out", str(tmp_path / "d"))  # not a terminal
    assert code == 0 and default == ""
    for name in files:
        assert (tmp_path / "p" / name).read_bytes() == (tmp_path / "q" / name).read_bytes()
