"""From tune to a run: ``TuningResult.loop()``, ``scenario.toml`` that ``hpdob simulate`` runs
as is, the report's velocity source, progress (stderr only), and ``scenario_toml`` read back
bit for bit."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from hpdob import (
    PD,
    Actuator,
    Encoder,
    ServoLoop,
    ServoModel,
    TwoMassServo,
    design_observer,
    paper,
    simulate,
    tune,
)
from hpdob.cli import main
from hpdob.controllers import PID, FilteredPD
from hpdob.observers import design_eso, design_kalman
from hpdob.signals import Sine, Step
from hpdob.simulation import load_scenario, scenario_toml

TS = 1e-3
RUN = {"reference": paper.REFERENCE, "duration": 2.0,
       "disturbance": Step(1.0005, 0.05) + 0.5 * Sine(0.02, 2.0, start=1.5)}  # fmt: skip


@pytest.fixture(scope="module")
def tuned():
    calls = []
    result = tune(nominal=ServoModel(2.8e-4), Ts=TS, sensor=Encoder(16384), J_range=(0.9, 1.1),
                  families=["position", "state"], disturbance_frequency=2.0, scenario=RUN,
                  progress=lambda *a: calls.append(a))  # fmt: skip
    return result, calls


def test_loop_repeats_the_run_that_ranked_the_recommendation(tuned):
    result, _ = tuned
    loop = result.loop()
    assert isinstance(loop, ServoLoop)
    assert loop.controller is result.controller and loop.observer is result.design
    assert loop.plant.coulomb == result.settings["coulomb"]
    again = simulate(loop, **result.scenario).metrics()
    assert again["rms_estimation_error"] == result.recommendation["simulated_estimation"]


def test_report_says_which_velocity_the_pd_uses(tuned):
    result, _ = tuned
    velocity = result.controller.velocity
    expected = "observer's velocity estimate" if velocity == "observer" else "measured velocity"
    assert f"the PD's derivative uses the {expected}" in result.report()


def test_progress_covers_every_stage_in_order(tuned):
    _, calls = tuned
    stages = [stage for stage, _, _ in calls]
    assert stages[0] == "analysis" and stages[-1] == "verification"
    assert list(dict.fromkeys(stages)) == ["analysis", "simulation", "verification"]
    for stage in ("analysis", "simulation", "verification"):
        done = [(d, t) for s, d, t in calls if s == stage]
        assert done[-1][0] == done[-1][1] and all(d <= t for d, t in done)
    with pytest.raises(TypeError, match="progress must be callable or None, got 3"):
        tune(nominal=ServoModel(2.8e-4), Ts=TS, progress=3)


def test_cli_tune_writes_a_scenario_that_simulate_runs(tmp_path, capsys):
    tuned_dir, run_dir = tmp_path / "t", tmp_path / "r"
    code = main(["tune", "--counts-per-rev", "16384", "--J-range", "0.9,1.1", "--frequency", "2",
                 "--families", "position", "--out", str(tuned_dir), "--no-plot",
                 "--progress"])  # fmt: skip
    out, err = capsys.readouterr()
    assert code == 0 and "scenario.toml" in out and "tune:" not in out
    assert "tune: verifying at the corners" in err  # progress on stderr, never in outputs
    recommendation = json.loads((tuned_dir / "tune.json").read_text())["recommendation"]
    assert main(["simulate", str(tuned_dir / "scenario.toml"), "--out", str(run_dir),
                 "--no-plot"]) == 0  # fmt: skip
    metrics = json.loads((run_dir / "metrics.json").read_text())["tuned"]
    assert math.isclose(metrics["rms_estimation_error"], recommendation["simulated_estimation"],
                        rel_tol=1e-12)  # fmt: skip
    capsys.readouterr()
    assert main(["tune", "--J-range", "0.9,1.1", "--families", "position", "--no-plot",
                 "--out", str(tmp_path / "quiet")]) == 0  # fmt: skip
    assert "tune:" not in capsys.readouterr().err  # not a terminal: silent by default


MOTOR = ServoModel(2.8e-4)
MODEL = MOTOR.discretize(TS)
LOOPS = {
    "hpdob": ServoLoop(plant=ServoModel(3.06e-4, 5e-5, coulomb=0.01), nominal=MOTOR, Ts=TS,
                       controller=PD(50.0, 5.0),
                       observer=design_observer(MODEL, order=2, poles=[0.9, 0.8 + 0.1j,
                                                                       0.8 - 0.1j])),
    "eso-encoder": ServoLoop(plant=MOTOR, nominal=MOTOR, Ts=TS, controller=PD(50.0, 5.0,
                             velocity="observer"), observer=design_eso(MODEL, bandwidth=150.0),
                             sensor=Encoder(4096, noise_std=1e-4, seed=3),
                             actuator=Actuator(torque_limit=0.2, delay_samples=1)),
    "kalman-two-mass": ServoLoop(plant=TwoMassServo(2e-4, 1e-4, 50.0, damping=1e-3),
                                 nominal=ServoModel(3e-4), Ts=TS, controller=PD(30.0, 4.0),
                                 observer=design_kalman(ServoModel(3e-4).discretize(TS),
                                                        position_noise_std=1e-4,
                                                        process_noise_std=1.0)),
    "pd-only": ServoLoop(plant=MOTOR, nominal=MOTOR, Ts=TS, controller=PD(50.0, 5.0)),
    "pid": ServoLoop(plant=MOTOR, nominal=MOTOR, Ts=TS, controller=PID(50.0, 100.0, 5.0),
                     observer={"type": "dob", "order": 1, "bandwidth": 100.0}),
    "filtered-pd": ServoLoop(plant=MOTOR, nominal=MOTOR, Ts=TS,
                             controller=FilteredPD(50.0, 5.0, time_constant=2e-3)),
}  # fmt: skip


@pytest.mark.parametrize("name", LOOPS)
def test_scenario_toml_reads_back_bit_for_bit(name, tmp_path):
    loop = LOOPS[name]
    run = {"reference": Step(0.1, 0.5) + 2.0 * Sine(0.1, 1.0), "duration": 0.5,
           "disturbance": 0.5 * Step(0.25, 0.02)}  # fmt: skip
    path = tmp_path / "s.toml"
    path.write_text(scenario_toml(loop, label=name, comment="a test\nof comments", **run))
    scenario = load_scenario(path)
    assert scenario.run["label"] == name
    mine = simulate(loop, **run)
    theirs = scenario.simulate()
    np.testing.assert_array_equal(theirs.theta, mine.theta)
    np.testing.assert_array_equal(theirs.tau_hat, mine.tau_hat)


def test_scenario_toml_refuses_what_has_no_file_form():
    from hpdob import LinearObserver

    system = design_observer(MODEL, order=1, bandwidth=100.0).system
    handmade = LinearObserver(F=system.F, G=system.G, H=system.H, E=system.E, N=system.N, Ts=TS,
                              model=MODEL)  # fmt: skip
    loop = ServoLoop(plant=MOTOR, nominal=MOTOR, Ts=TS, controller=PD(50, 5), observer=handmade)
    with pytest.raises(TypeError, match=r"loop\.observer must be of a known family"):
        scenario_toml(loop, reference=Step(0.1, 1.0), duration=1.0)
    with pytest.raises(TypeError, match="reference must be made of"):
        scenario_toml(LOOPS["pd-only"], reference=lambda t: (t, t, t), duration=1.0)


def test_tuning_result_shows_a_compact_table(tuned):
    result, _ = tuned
    text = result._repr_markdown_()
    assert text.startswith(f"**TuningResult: {result.recommendation['name']}**")
    assert f"| PD velocity | {result.controller.velocity} |" in text


def test_every_centre_run_is_that_candidates_own_simulate(tuned):
    """The centre runs start on two threads while the analysis of later candidates goes on:
    each qualified row's figures are still simulate() of that candidate alone, bit for bit."""
    result, _ = tuned
    s = result.settings
    nominal = ServoModel(s["nominal"]["J"], s["nominal"]["b"])
    plant = ServoModel(0.5 * sum(s["J_range"]) * nominal.J, 0.5 * sum(s["b_range"]),
                       coulomb=s["coulomb"])  # fmt: skip
    rows = [r for r in result.rows if r["robust"] and r["within_noise"]]
    assert len(rows) > 20
    for r in rows:
        metrics = simulate(plant=plant, nominal=nominal, Ts=s["Ts"], controller=r["_controller"],
                           observer=r["_design"], sensor=Encoder(16384),
                           **result.scenario).metrics()  # fmt: skip
        position = max(metrics["rms_position_error_regulation"],
                       metrics["rms_position_error_tracking"])  # fmt: skip
        assert r["simulated_estimation"] == metrics["rms_estimation_error"]
        assert r["simulated_position"] == position


def test_an_error_during_the_analysis_leaves_no_simulation_thread():
    """A progress callback that raises halfway through the analysis (as an interrupt would):
    the error comes out of tune and the centre runs' threads are gone."""
    import threading

    class Stop(Exception):
        pass

    def progress(stage, done, total):
        if stage == "analysis" and done == total // 2:
            raise Stop

    before = threading.active_count()
    with pytest.raises(Stop):
        tune(nominal=ServoModel(2.8e-4), Ts=TS, sensor=Encoder(16384), J_range=(0.9, 1.1),
             families=["position", "state"], scenario=RUN, progress=progress)  # fmt: skip
    assert threading.active_count() == before


def test_one_centre_run_at_a_time_while_the_analysis_goes_on(monkeypatch):
    """While tune still analyses candidates, its centre runs take one core (one at a time);
    two at a time once it waits for them."""
    import threading
    import time

    from hpdob.tuning import _runs

    lock, active, most = threading.Lock(), [0], {"analysis": 0, "simulation": 0}
    stage = ["analysis"]
    run = _runs.VerificationRuns._quiet_run

    def counted(self, *args):
        with lock:
            active[0] += 1
            most[stage[0]] = max(most[stage[0]], active[0])
        time.sleep(0.003)  # widens the overlap a second run would have (no timing asserted)
        try:
            return run(self, *args)
        finally:
            with lock:
                active[0] -= 1

    def progress(name, done, total):
        if name != "analysis" or done == total:  # the analysis is over: tune waits next
            stage[0] = "simulation"

    monkeypatch.setattr(_runs.VerificationRuns, "_quiet_run", counted)
    tune(nominal=ServoModel(2.8e-4), Ts=TS, sensor=Encoder(16384), J_range=(0.9, 1.1),
         families=["position", "state"], scenario=RUN, progress=progress)  # fmt: skip
    assert most["analysis"] == 1
