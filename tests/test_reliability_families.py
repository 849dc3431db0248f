"""Issue 16's last paragraph: the audit of the surfaces issues 12-15 added, each finding fixed.

``benchmarks/reliability_audit.py --part families`` found, on the commit before (64fe1cd),
13 escapes (tracebacks, warnings, internal errors) and 59 calls that were accepted although
an argument was silently ignored or the result was wrong (an unstable Kalman filter, an ESO
with its poles at 1, a sweep path that failed in every row). Each case below reproduces one;
the realised-pole findings are in tests/observers/test_realised.py, test_eso.py and
test_kalman.py (with this audit's ESO and Kalman cases), the output sets of
``hpdob estimate``/``compare``/``tune`` in tests/cli/test_atomic_outputs.py.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from hpdob import (
    PD,
    ParameterTypeError,
    ParameterValueError,
    ServoModel,
    TwoMassServo,
    compare_observers,
    paper,
    robust_stability_map,
    sweep,
    tune,
)
from hpdob.cli import main

MODEL = ServoModel(2.8e-4).discretize(1e-3)


def run_cli(capsys, *argv):
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exit_:  # argparse's errors
        code = exit_.code
    out, err = capsys.readouterr()
    return code, out, err


# -- the two-mass plant -------------------------------------------------------------------------
def test_two_mass_discretisation_that_overflows_says_so_without_a_warning():
    plant = TwoMassServo(1.4e-4, 1.4e-4, 20.0)  # pytest turns a RuntimeWarning into an error
    with pytest.raises(ParameterValueError, match=r"with Ts=1e\+308 s is not finite"):
        plant.discretize(1e308)


@pytest.mark.parametrize(
    ("plant", "observer", "grid", "pattern"),
    [
        ("two-mass", None, {"plant.J": [3e-4]}, r"a TwoMassServo has no parameter 'J'"),
        ("rigid", None, {"plant.stiffness": [10.0]}, r"a ServoModel has no parameter 'stiffness'"),
        ("rigid", None, {"plant.J_motor": [1e-4]}, r"has no parameter 'J_motor'"),
        ("rigid", {"type": "eso", "bandwidth": 100.0}, {"observer.order": [1]},
         r"type 'eso' has no design argument 'order'"),
        ("rigid", {"type": "kalman", "position_noise_std": 1e-4, "process_noise_std": 1e-3},
         {"observer.bandwidth": [100.0]}, r"type 'kalman' has no design argument 'bandwidth'"),
        ("rigid", {"order": 1, "bandwidth": 100.0}, {"observer.velocity_bandwidth": [100.0]},
         r"velocity_bandwidth applies with measurement='position' only"),
        ("rigid", "object", {"observer.order": [1]}, r"need base\['observer'\] as a dict"),
    ],
)  # fmt: skip
def test_sweep_paths_that_cannot_apply_are_refused_before_running(
    monkeypatch, plant, observer, grid, pattern
):
    import hpdob.simulation._sweep as module

    def never(*args, **kwargs):
        raise AssertionError("a scenario ran")

    monkeypatch.setattr(module, "run_scenario", never)  # every row used to fail with an error
    base = {**paper.scenario(), "duration": 0.05, "observer": {"order": 1, "bandwidth": 100.0}}
    if plant == "two-mass":
        base["plant"] = TwoMassServo(1.4e-4, 1.4e-4, 20.0)
    if observer == "object":
        from hpdob import design_observer

        base["observer"] = design_observer(MODEL, order=1, bandwidth=100.0).system
    elif observer is not None:
        base["observer"] = observer
    path = next(iter(grid))
    with pytest.raises(ParameterValueError, match=rf"^sweep path '{path}' does not apply.*"):
        sweep(base, grid=grid, scheduler=1, progress=False)
    # random draws too (an integer order only in a grid)
    varied = {"grid": {path: [0, 1]}} if path == "observer.order" else {
        "vary": {path: ("uniform", 1.0, 2.0)}, "n": 2}  # fmt: skip
    with pytest.raises(ParameterValueError, match=pattern):
        sweep(base, **varied, scheduler=1, progress=False)


def test_sweep_bad_values_of_a_valid_path_stay_per_row_errors():
    base = {**paper.scenario(), "duration": 0.05, "plant": TwoMassServo(1.4e-4, 1.4e-4, 20.0)}
    rows = sweep(base, grid={"plant.stiffness": [-1.0, 20.0]}, scheduler=1, progress=False)
    assert rows["error"][0].startswith("stiffness must be a positive") and rows["error"][1] == ""


# -- tune -------------------------------------------------------------------------------------
FAST = {"nominal": ServoModel(2.8e-4), "Ts": 1e-3, "families": ["state"],
        "scenario": {"reference": paper.REFERENCE, "duration": 0.5}}  # fmt: skip


class Searched(Exception):
    """Raised where the search starts: the arguments were all accepted."""


@pytest.fixture
def no_search(monkeypatch):
    import hpdob.tuning._tune as module

    def searched(*args, **kwargs):
        raise Searched

    monkeypatch.setattr(module, "_candidates", searched)


@pytest.mark.parametrize(
    ("changes", "error", "pattern"),
    [
        ({"Ts": 1e-320}, ParameterValueError, r"^duration/Ts = .* exceeds the limit"),
        ({"Ts": 0.3}, ParameterValueError, r"^Ts must be below 0.4 pi / 5 rad/s = 0.2513 s"),
        ({"disturbance_frequency": 600.0}, ParameterValueError,
         r"^disturbance_frequency must be below the Nyquist frequency 1/\(2 Ts\) = 500 Hz"),
        ({"disturbance_frequency": (1.0, 500.0)}, ParameterValueError, r"Nyquist"),
        ({"scenario": {**FAST["scenario"], "duration": 1e12}}, ParameterValueError,
         r"^duration/Ts = .* exceeds the limit"),
        ({"scenario": {**FAST["scenario"], "duration": 0.5005}}, ParameterValueError,
         r"^duration must be a positive multiple of Ts"),
        ({"scenario": {**FAST["scenario"], "duration": math.nan}}, ParameterValueError,
         r"^scenario duration must be a positive finite duration"),
        ({"scenario": {**FAST["scenario"], "reference": "step"}}, ParameterTypeError,
         r"reference"),
    ],
)  # fmt: skip
def test_tune_checks_everything_before_the_search(no_search, changes, error, pattern):
    with pytest.raises(error, match=pattern):  # Ts 1e-320 used to warn; the rest failed late
        tune(**{**FAST, **changes})


def test_tune_default_scenario_lasts_whole_samples(no_search):
    # Ts = 3e-4 does not divide the paper's 10 s: the default run is 33333 samples
    with pytest.raises(Searched):
        tune(nominal=ServoModel(2.8e-4), Ts=3e-4)


def test_tune_cli_refuses_a_negative_noise_std(capsys, tmp_path):
    # was silently dropped (no sensor) because only a positive value made an Encoder
    code, _, err = run_cli(capsys, "tune", "--noise-std", "-1", "--out", tmp_path / "t")
    assert code == 2 and "noise_std must be" in err and err.count("\n") == 1, err


# -- compare_observers ----------------------------------------------------------------------
@pytest.mark.parametrize(
    ("kwargs", "error", "pattern"),
    [
        ({"sensors": None}, ParameterTypeError, r"^sensors must be a sequence of 'ideal'"),
        ({"sensors": 1}, ParameterTypeError, r"^sensors must be a sequence"),
        ({"candidates": [{"order": 0}]}, ParameterTypeError, r"^candidates must be a non-empty"),
        ({"candidates": {1: {"order": 0}}}, ParameterTypeError,
         r"^candidates names must be non-empty str, got 1"),
        ({"candidates": {"x": {"order": 0, "bandwidth": 5.0}}}, ParameterValueError,
         r"^candidates\['x'\] must not give bandwidth: the comparison tunes the bandwidth"),
        ({"candidates": {"x": {"type": "kalman", "position_noise_std": 1.0}}},
         ParameterValueError, r"^candidates\['x'\] must not give position_noise_std"),
        ({"candidates": {"x": {"order": 0, "gain": 1.0}}}, ParameterValueError,
         r"candidates\['x'\]\.gain"),
        ({"candidates": {"x": {"order": -1}}}, ParameterValueError,
         r"^candidates\['x'\]: order must be a non-negative integer"),
        ({"duration": 1e12}, ParameterValueError, r"^duration/Ts = .* exceeds the limit"),
    ],
)  # fmt: skip
def test_compare_observers_bad_arguments(monkeypatch, kwargs, error, pattern):
    import hpdob.analysis._comparison as module

    def never(*args, **kwargs):
        raise AssertionError("simulated")

    monkeypatch.setattr("hpdob.simulation.simulate", never)  # all refused before simulating
    if "order" not in str(kwargs):
        monkeypatch.setattr(module, "_tune", never)  # and before tuning
    with pytest.raises(error, match=pattern):
        compare_observers(**{"candidates": {"DOb": {"order": 0}}, **kwargs})


def test_compare_observers_names_each_sensor_once():
    result = compare_observers(sensors=("ideal", "ideal"), candidates={"DOb": {"order": 0}},
                               duration=0.2)  # fmt: skip
    assert [r["sensor"] for r in result.rows] == ["ideal"]


# -- robust_stability_map(observer=...) -------------------------------------------------------
MAP = {"J_ratio": [0.5, 1.0], "bandwidth": [100.0], "nominal": ServoModel(2.8e-4), "Ts": 1e-3,
       "controller": PD(50.0, 5.0)}  # fmt: skip


@pytest.mark.parametrize(
    ("observer", "extra", "error", "pattern"),
    [  # int('a') was a ValueError, int(None)/int([1]) TypeErrors, the rest silently ignored
        ({"type": "eso", "extended_order": "a"}, {}, ParameterTypeError,
         r"^observer.extended_order must be a non-negative integer"),
        ({"type": "eso", "extended_order": None}, {}, ParameterTypeError,
         r"^observer.extended_order"),
        ({"order": "a"}, {}, ParameterTypeError, r"^observer.order must be"),
        ({"order": [1]}, {}, ParameterTypeError, r"^observer.order must be"),
        ({"order": 1, "bandwidth": 5.0}, {}, ParameterValueError,
         r"^observer must not give bandwidth: the map designs"),
        ({"order": 1, "poles": [0.9, 0.9]}, {}, ParameterValueError,
         r"^observer must not give poles"),
        ({"type": "kalman", "position_noise_std": 1e-4, "process_noise_std": 1.0}, {},
         ParameterValueError, r"^observer must not give process_noise_std"),
        ({"type": "eso"}, {"measurement": "position"}, ParameterValueError,
         r"^measurement and gain_direction apply with order"),
        ({"type": "eso"}, {"gain_direction": (0.0, 1.0)}, ParameterValueError,
         r"gain_direction=\(0.0, 1.0\)"),
        ({"type": "eso", "order": 1}, {}, ParameterValueError, r"observer\.order"),
    ],
)  # fmt: skip
def test_stability_map_observer_specs(observer, extra, error, pattern):
    with pytest.raises(error, match=pattern):
        robust_stability_map(**MAP, observer=observer, **extra)


def test_stability_map_of_a_spec_still_works():
    smap = robust_stability_map(**MAP, observer={"type": "eso", "extended_order": 1})
    assert smap.order == 1 and smap.observer == {"type": "eso", "extended_order": 1}


# -- hpdob design / export-c --type: options of another family are refused --------------------
@pytest.mark.parametrize("command", ["design", "export-c"])
@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--extended-order", "1"], "--extended-order applies to --type eso only, not --type dob"),
        (["--form", "predictive"], "--form applies to --type eso only, not --type dob"),
        (["--position-noise-std", "1e-4"],
         "--position-noise-std applies to --type kalman only, not --type dob"),
        (["--type", "eso", "--process-noise-std", "1"],
         "--process-noise-std applies to --type kalman only, not --type eso"),
        (["--type", "eso", "--order", "1"], "--type eso takes --extended-order, not --order"),
        (["--type", "kalman", "--position-noise-std", "1e-4", "--extended-order", "1",
          "--form", "current"], "--extended-order, --form apply to --type eso only"),
        (["--type", "kalman", "--position-noise-std", "1e-4", "--process-noise-std", "1e-3",
          "--bandwidth", "100"], "--type kalman takes --bandwidth"),
        (["--type", "kalman", "--position-noise-std", "1e-9", "--process-noise-std", "1e-4",
          "--order", "2"], "is not stable in double precision"),
    ],
)  # fmt: skip
def test_design_cli_refuses_options_of_another_family(capsys, tmp_path, command, argv, message):
    tail = ["--out", tmp_path] if command == "export-c" else []
    code, out, err = run_cli(capsys, command, *argv, *tail)
    assert code == 2 and message in err and err.count("\n") == 1 and out == "", err
    assert list(tmp_path.iterdir()) == []


def test_design_cli_of_each_family_still_works(capsys):
    for argv in (["--type", "eso", "--extended-order", "1", "--form", "predictive"],
                 ["--type", "kalman", "--position-noise-std", "1e-4", "--order", "1"],
                 ["--measurement", "position", "--velocity-bandwidth", "300"]):  # fmt: skip
        code, out, err = run_cli(capsys, "design", *argv)
        assert code == 0 and err == "" and "eigenvalues" in out


# -- hpdob estimate --from-identification with values of the wrong type ------------------------
@pytest.mark.parametrize(
    ("parameters", "needle"),
    [
        ('{"J": 1.0, "b": null}', "parameters.b of"),  # was an internal error (float(None))
        ('{"J": "big", "b": 0.0}', "parameters.J of"),
        ('{"J": -1.0, "b": 0.0}', "J must be a positive finite inertia"),
    ],
)
def test_estimate_identification_values_are_checked(capsys, tmp_path, parameters, needle):
    path = tmp_path / "identification.json"
    path.write_text(f'{{"parameters": {parameters}}}')
    code, _, err = run_cli(capsys, "estimate", "--emps", "--from-identification", path,
                           "--out", tmp_path / "o", "--no-plot")  # fmt: skip
    assert code == 2 and needle in err and err.count("\n") == 1, err
    assert not (tmp_path / "o").exists()


def test_the_audit_finds_no_escape():
    """The audit's cheapest surfaces (the designs, about 1 s): every outcome clean or accepted."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import reliability_audit
    import reliability_audit_families as families

    audit = reliability_audit.Audit(verbose=False)
    for part in (families.audit_position, families.audit_eso, families.audit_kalman):
        part(audit)
    assert audit.escapes == []
    assert np.sum([audit.counts[k] for k in audit.counts]) > 150
