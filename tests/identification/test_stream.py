"""``estimate_log``: the estimate of a long log run block by block (issue 25) gives
``estimate_disturbance``'s estimate bit for bit and its CSV byte for byte, for every family at
orders 0-2, from a Parquet file read a row group at a time or from a ``Log``; an
``EstimationResult``'s ``state`` continues a run on the next piece of a log exactly."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pytest

from hpdob import ServoModel, design_observer, estimate_disturbance
from hpdob.identification import Log, LogEstimate, estimate_log, open_log, read_log
from hpdob.observers import design_eso, design_kalman

pa = pytest.importorskip("pyarrow")
pq = pytest.importorskip("pyarrow.parquet")

MODEL = ServoModel(2.8e-4, 1e-5).discretize(1e-3)
DESIGNS = {"eso-predictive": design_eso(MODEL, bandwidth=100.0, extended_order=1,
                                        form="predictive")}  # fmt: skip
for m in range(3):
    DESIGNS[f"dob-{m}"] = design_observer(MODEL, order=m, bandwidth=100.0)
    DESIGNS[f"position-{m}"] = design_observer(MODEL, order=m, bandwidth=100.0,
                                               measurement="position")  # fmt: skip
    DESIGNS[f"eso-{m}"] = design_eso(MODEL, bandwidth=100.0, extended_order=m)
    DESIGNS[f"kalman-{m}"] = design_kalman(MODEL, order=m, position_noise_std=1e-4,
                                           process_noise_std=1.0)  # fmt: skip


@pytest.fixture(scope="module")
def log_path(tmp_path_factory):
    rng = np.random.default_rng(25)
    n = 9001  # several row groups and blocks, the last one partial
    path = tmp_path_factory.mktemp("log") / "log.parquet"
    pq.write_table(pa.table({"t": 0.5 + np.arange(n) * 1e-3,
                             "q": np.cumsum(rng.standard_normal(n)) * 1e-4,
                             "u": rng.standard_normal(n) * 0.01}), path,
                   row_group_size=2500)  # fmt: skip
    return path


@pytest.mark.parametrize("name", list(DESIGNS))
def test_bit_for_bit_the_whole_runs_estimate_and_csv(tmp_path, log_path, name):
    design = DESIGNS[name]
    whole = read_log(log_path, time="t", position="q", input="u", input_gain=3.0)
    expected = estimate_disturbance(design, theta=whole.theta, u=whole.u, t=whole.t)
    expected.to_csv(tmp_path / "whole.csv")
    log = open_log(log_path, time="t", position="q", input="u", input_gain=3.0)
    run = estimate_log(design, log, csv=tmp_path / "blocks.csv", settle=0.1)
    assert isinstance(run, LogEstimate) and len(run) == len(whole) and run.finite
    assert np.array_equal(run.tau_hat, expected.tau_hat)
    assert (tmp_path / "blocks.csv").read_bytes() == (tmp_path / "whole.csv").read_bytes()
    # the statistics of the last 90 %, as numpy computes them on the whole run's estimate
    t = expected.t
    tail = expected.tau_hat[np.searchsorted(t, t[0] + 0.1 * (t[-1] - t[0])) :]
    assert (run.mean, run.std) == (float(tail.mean()), float(tail.std()))
    lean = estimate_log(design, log, settle=0.1, keep=False)  # std in the estimate's memory
    assert lean.tau_hat is None and (lean.mean, lean.std) == (run.mean, run.std)


def test_a_log_in_memory_and_the_figure(tmp_path, log_path):
    design = DESIGNS["dob-1"]
    whole = read_log(log_path, time="t", position="q", input="u")
    expected = estimate_disturbance(design, theta=whole.theta, u=whole.u, t=whole.t)
    run = estimate_log(design, whole)
    assert np.array_equal(run.tau_hat, expected.tau_hat)
    assert (run.mean, run.std) == (float(expected.tau_hat.mean()), float(expected.tau_hat.std()))
    ours, theirs = run.plot(title="x", axis="rotary"), expected.plot(title="x", axis="rotary")
    try:
        for a, b in zip(ours.axes, theirs.axes, strict=True):
            assert a.get_xlim() == b.get_xlim() and a.get_ylabel() == b.get_ylabel()
            for la, lb in zip(a.lines, b.lines, strict=True):
                assert np.array_equal(la.get_xydata(), lb.get_xydata())
    finally:
        plt.close(ours)
        plt.close(theirs)


def test_long_trace_figure_is_the_envelope_of_the_whole_run(monkeypatch):
    """Past the envelope threshold the figure draws the same envelope (a smaller threshold
    here, so that the test stays small)."""
    import hpdob._plotting as plotting

    monkeypatch.setattr(plotting.Envelope.__init__, "__kwdefaults__", {"samples": 500})
    monkeypatch.setattr(plotting.envelope, "__kwdefaults__", {"samples": 500})
    rng = np.random.default_rng(3)
    n = 20_011
    log = Log(t=np.arange(n) * 1e-3, theta=np.cumsum(rng.standard_normal(n)),
              u=rng.standard_normal(n))  # fmt: skip
    design = DESIGNS["kalman-1"]
    expected = estimate_disturbance(design, theta=log.theta, u=log.u, t=log.t)
    run = estimate_log(design, log)
    ours, theirs = run.plot(), expected.plot()
    try:
        for a, b in zip(ours.axes, theirs.axes, strict=True):
            (la,), (lb,) = a.lines, b.lines
            assert len(la.get_xdata()) < 600
            assert np.array_equal(la.get_xydata(), lb.get_xydata())
    finally:
        plt.close(ours)
        plt.close(theirs)


@pytest.mark.parametrize("name", ["dob-2", "position-1", "kalman-0"])
def test_state_continues_a_run_on_the_next_piece(name):
    rng = np.random.default_rng(8)
    theta, u = np.cumsum(rng.standard_normal(3000)) * 1e-4, rng.standard_normal(3000) * 0.01
    design = DESIGNS[name]
    whole = estimate_disturbance(design, theta=theta, u=u, tau0=0.01)
    measured = whole.omega is not None  # the next piece gets its differenced velocity
    first = estimate_disturbance(design, theta=theta[:1234], u=u[:1234], tau0=0.01)
    second = estimate_disturbance(design, theta=theta[1234:], u=u[1234:], state=first.state,
                                  omega=whole.omega[1234:] if measured else None)  # fmt: skip
    assert np.array_equal(np.concatenate([first.tau_hat, second.tau_hat]), whole.tau_hat)
    assert np.array_equal(second.state, whole.state) and not whole.state.flags.writeable


def test_refusals(tmp_path, log_path):
    log = open_log(log_path, time="t", position="q", input="u")
    with pytest.raises(TypeError, match="log must be a LogFile"):
        estimate_log(DESIGNS["dob-1"], {"t": [0.0]})
    other = design_observer(ServoModel(2.8e-4).discretize(2e-3), order=1, bandwidth=100.0)
    with pytest.raises(ValueError, match=r"sampling period Ts = 0\.002 s, got a step of 0\.001"):
        estimate_log(other, log, csv=tmp_path / "x.csv")
    for settle in (-0.1, 1.0, float("nan")):
        with pytest.raises(ValueError, match="settle must be"):
            estimate_log(DESIGNS["dob-1"], log, settle=settle)
    assert not (tmp_path / "x.csv").exists() and list(tmp_path.iterdir()) == []
