"""One loop description (issue 20, section 3): a ServoLoop holds values only -- a spec that
designs itself on the nominal model, or a fixed design -- and the initial observer state is
an argument of the run."""

from __future__ import annotations

import numpy as np
import pytest

from hpdob import PD, DisturbanceObserver, ServoLoop, ServoModel, design_observer, simulate
from hpdob.observers import Observer, design_eso, initial_state
from hpdob.signals import SmoothStep, Step

TS = 1e-3
PLANT, NOMINAL = ServoModel(3.06e-4, 5e-5), ServoModel(2.8e-4)
RUN = {"duration": 1.0, "reference": SmoothStep(0.1, 0.5, 1.0), "disturbance": Step(0.6, 0.05)}


def loop(observer):
    return ServoLoop(plant=PLANT, nominal=NOMINAL, Ts=TS, controller=PD(50, 5),
                     observer=observer)  # fmt: skip


def test_a_spec_designs_itself_on_the_nominal_model_and_again_on_replace():
    spec = {"type": "eso", "bandwidth": 150.0, "extended_order": 1}
    servo = loop(spec)
    assert servo.observer == spec and servo.observer is not spec  # a copy
    expected = design_eso(NOMINAL.discretize(TS), bandwidth=150.0, extended_order=1)
    np.testing.assert_array_equal(servo.system.F, expected.system.F)
    assert servo.observer_spec == spec
    moved = servo.replace(nominal=ServoModel(3e-4, 1e-4), Ts=2e-3)
    assert (moved.design.model.J, moved.design.model.b, moved.design.Ts) == (3e-4, 1e-4, 2e-3)
    result = simulate(servo, **RUN)
    assert np.array_equal(result.tau_hat, simulate(loop(expected), **RUN).tau_hat)


def test_a_bad_spec_is_named():
    with pytest.raises(ValueError, match=r"observer\.bogus"):
        loop({"order": 1, "bandwidth": 100.0, "bogus": 1})
    with pytest.raises(ValueError, match=r"observer\.type must be one of"):
        loop({"type": "nope"})


@pytest.mark.parametrize("family", ["dob", "eso", "system"])
def test_a_runtime_observer_is_refused_with_the_call_to_use(family):
    model = NOMINAL.discretize(TS)
    design = design_eso(model, bandwidth=100.0) if family == "eso" else (
        design_observer(model, order=1, bandwidth=100.0))  # fmt: skip
    design = design.system if family == "system" else design
    runtime = Observer.of(design)
    runtime.reset(x0=(0.0, 0.0), tau0=0.02)
    part = "system" if family == "system" else "design"
    message = (
        rf"^observer must be a family spec, a design or a LinearObserver \(a loop holds values, "
        rf"not state\), got a runtime {type(runtime).__name__}; pass observer=obs\.{part} and "
        r"start the run from its state: simulate\(loop, \.\.\., observer_state=obs\.state\)$"
    )
    with pytest.raises(TypeError, match=message):
        loop(runtime)
    with pytest.raises(TypeError, match=message):  # and wherever a loop is built from it
        simulate(plant=PLANT, nominal=NOMINAL, Ts=TS, controller=PD(50, 5), observer=runtime, **RUN)
    servo = loop(None)
    with pytest.raises(TypeError, match=message):
        servo.replace(observer=runtime)
    assert servo.observer is None  # a refused replace leaves the loop as it was
    # the call the message shows runs the runtime observer's run
    by_state = simulate(loop(getattr(runtime, part)), **RUN, observer_state=runtime.state)
    assert by_state.tau_hat[0] == pytest.approx(0.02)


def test_the_initial_observer_state_is_an_argument_of_the_run():
    design = design_observer(NOMINAL.discretize(TS), order=1, bandwidth=100.0)
    state = initial_state(design, x0=(0.0, 0.0), tau0=0.02)
    runtime = DisturbanceObserver(NOMINAL.discretize(TS), order=1, bandwidth=100.0)
    runtime.reset(x0=(0.0, 0.0), tau0=0.02)
    by_argument = simulate(loop(design), **RUN, observer_state=state)
    by_object = simulate(loop(runtime.design), **RUN, observer_state=runtime.state)
    assert np.array_equal(by_argument.tau_hat, by_object.tau_hat)
    assert by_argument.tau_hat[0] == pytest.approx(0.02)
    assert simulate(loop(design), **RUN).tau_hat[0] == 0.0
    with pytest.raises(ValueError, match=r"observer_state must be 2 finite floats"):
        simulate(loop(design), **RUN, observer_state=(0.0, 1.0, 2.0))
    with pytest.raises(ValueError, match=r"observer_state needs a loop with an observer"):
        simulate(loop(None), **RUN, observer_state=state)


# -- the functions that take a loop ------------------------------------------------------------
def test_robust_map_of_a_loop_equals_the_keyword_form():
    from hpdob import robust_stability_map

    grid = {"J_ratio": [0.5, 1.0, 2.0], "bandwidth": [50.0, 200.0]}
    servo = loop({"order": 1, "bandwidth": 100.0})  # the map replaces the bandwidth
    by_loop = robust_stability_map(servo, **grid)
    by_keywords = robust_stability_map(**grid, order=1, nominal=NOMINAL, Ts=TS,
                                       controller=PD(50, 5))  # fmt: skip
    assert np.array_equal(by_loop.spectral_radius, by_keywords.spectral_radius)
    eso = robust_stability_map(loop({"type": "eso", "bandwidth": 80.0, "extended_order": 1}),
                               **grid)  # fmt: skip
    assert eso.observer == {"type": "eso", "extended_order": 1} and eso.order == 1
    with pytest.raises(TypeError, match=r"takes a ServoLoop or the loop's keyword arguments"):
        robust_stability_map(servo, **grid, nominal=NOMINAL)
    with pytest.raises(ValueError, match=r"needs order, observer .* or a loop whose observer"):
        robust_stability_map(loop(None), **grid)


def test_compare_observers_in_a_loop():
    from hpdob import compare_observers, paper

    candidates = {"HPDOb": {"order": 1}, "ESO": {"type": "eso"}}
    parts = {k: v for k, v in paper.scenario().items() if k in ("plant", "nominal", "controller")}
    paper_loop = ServoLoop(**parts, Ts=paper.TS)
    default = compare_observers(sensors=("ideal",), candidates=candidates, duration=0.5)
    same = compare_observers(paper_loop, sensors=("ideal",), candidates=candidates, duration=0.5)
    assert same.rows == default.rows
    heavy = ServoLoop(plant=ServoModel(3.06e-3, 5e-4, coulomb=0.1), nominal=ServoModel(2.8e-3),
                      Ts=TS, controller=PD(50, 5, feedforward=True))  # fmt: skip
    table = compare_observers(heavy, sensors=("ideal",), candidates=candidates, duration=0.5)
    assert all(r["tuning"] == "matched" and not r["diverged"] for r in table.rows)
    # the disturbance scales with J_n (the same acceleration, ten times the torque), and so
    # does the estimation error, roughly
    ratio = [b["rms_estimation_error"] / a["rms_estimation_error"]
             for a, b in zip(default.rows, table.rows, strict=True)]  # fmt: skip
    assert all(5 < r < 50 for r in ratio), ratio


def test_tune_of_a_loop_equals_the_keyword_form():
    from hpdob import Encoder, tune

    run = {"J_range": (0.9, 1.1), "families": ["state"], "coulomb": 0.0,
           "scenario": {"reference": Step(0.1, 1.0), "duration": 0.3}}  # fmt: skip
    servo = ServoLoop(plant=NOMINAL, nominal=NOMINAL, Ts=TS, controller=PD(50, 5),
                      sensor=Encoder(16384))  # fmt: skip
    by_loop = tune(servo, **run)
    by_keywords = tune(nominal=NOMINAL, Ts=TS, controller=PD(50, 5), sensor=Encoder(16384),
                       **run)  # fmt: skip
    keys = ("family", "order", "parameter", "value", "accuracy", "tau_noise")
    assert [by_loop.recommended[k] for k in keys] == [by_keywords.recommended[k] for k in keys]
    assert len(by_loop.rows) == len(by_keywords.rows)


def test_sweep_of_a_scenario_file(tmp_path):
    from pathlib import Path

    from hpdob import sweep
    from hpdob.simulation import load_scenario

    example = Path(__file__).parents[2] / "examples" / "canonical_hpdob.toml"
    path = tmp_path / "short.toml"
    path.write_text(example.read_text().replace("duration = 10.0", "duration = 1.0"))
    scenario = load_scenario(path)
    table = sweep(scenario, grid={"observer.bandwidth": [100.0, 150.0]}, progress=False)
    assert (table["error"] == "").all()
    direct = scenario.simulate()
    assert table["rms_estimation_error"][0] == direct.metrics()["rms_estimation_error"]


def test_hpdob_compare_for_another_motor(tmp_path, capsys):
    import json

    from hpdob.cli import main

    out = tmp_path / "cmp"
    code = main(["compare", "--J-n", "2.8e-3", "--sensor", "ideal", "--no-plot",
                 "--out", str(out)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    rows = json.loads((out / "comparison.json").read_text())["rows"]
    assert all(not r["diverged"] for r in rows)


def test_hpdob_simulate_starts_the_files_observer_at_its_x0(tmp_path):
    """``hpdob simulate`` passes the ``[observer]`` table's design (a value) to the loop, so a
    file's non-zero ``x0`` starts the observer converged there, as ``load_scenario`` does (a
    runtime observer built from the file started at rest at 0 and gave a transient)."""
    import json

    from hpdob.cli import main
    from hpdob.simulation import load_scenario

    path = tmp_path / "x0.toml"
    path.write_text(
        "Ts = 1e-3\nduration = 0.3\nx0 = [0.5, 2.0]\n[plant]\nJ = 3.06e-4\nb = 5e-5\n"
        "[nominal]\nJ = 2.8e-4\n[controller]\nkp = 50.0\nkd = 5.0\n"
        '[observer]\norder = 1\nbandwidth = 100.0\n[[reference]]\ntype = "step"\ntime = 0.0\n'
        "amplitude = 0.5\n"
    )
    assert main(["simulate", str(path), "--no-plot", "--out", str(tmp_path / "out")]) == 0
    got = json.loads((tmp_path / "out" / "metrics.json").read_text())["x0"]
    expected = load_scenario(path).simulate()
    assert got["rms_estimation_error"] == expected.metrics()["rms_estimation_error"]
    assert abs(expected.tau_hat[0]) < 1e-12  # converged at x0 on zero disturbance
