"""The comparison of observers (issue 13 section 4) and the equivalences docs/comparison.md
claims between the families."""

from __future__ import annotations

import json
import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from hpdob import (
    ADRC,
    PID,
    FilteredPD,
    ServoLoop,
    ServoModel,
    compare_observers,
    design_observer,
    estimate_disturbance,
    simulate,
)
from hpdob.analysis import observer_noise_gain
from hpdob.cli import main
from hpdob.observers import design_eso, design_kalman

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import interconnect

TS = 1e-3
NOMINAL = ServoModel(2.8e-4)


@pytest.fixture(scope="module")
def trace():
    rng = np.random.default_rng(7)
    return np.cumsum(rng.normal(scale=1e-3, size=1500)), rng.normal(scale=0.05, size=1500)


def estimates(design, trace):
    theta, u = trace
    return estimate_disturbance(design, theta=theta, u=u).tau_hat


def relative_difference(a, b) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def test_eso_of_order_0_is_the_position_only_dob_without_viscous_friction(trace):
    """Same model (theta'' = f + u/J_n with f held over the sample is eq. 8 with tau = -J_n f
    when b_n = 0), same measurement, same current form, same poles: the same observer."""
    model = ServoModel(2.8e-4).discretize(1e-3)
    eso = design_eso(model, bandwidth=150.0)
    dob = design_observer(model, order=0, bandwidth=150.0, measurement="position")
    assert relative_difference(estimates(eso, trace), estimates(dob, trace)) < 1e-10


def test_they_differ_with_viscous_friction_and_at_order_1(trace):
    """With b_n > 0 the ESO holds f = -(tau + b_n omega)/J_n constant over the sample where
    eq. 8 integrates b_n omega exactly; at m >= 1 the ESO's continuous f'' = 0 lets f ramp
    within the sample where Delta^2 tau = 0 holds tau over each sample."""
    friction = ServoModel(2.8e-4, 5e-5).discretize(1e-3)
    eso = design_eso(friction, bandwidth=150.0)
    dob = design_observer(friction, order=0, bandwidth=150.0, measurement="position")
    assert relative_difference(estimates(eso, trace), estimates(dob, trace)) > 1e-4
    model = ServoModel(2.8e-4).discretize(1e-3)
    geso = design_eso(model, bandwidth=150.0, extended_order=1)
    hpdob = design_observer(model, order=1, bandwidth=150.0, measurement="position")
    assert relative_difference(estimates(geso, trace), estimates(hpdob, trace)) > 1e-3


@pytest.mark.parametrize("m", [0, 1])
@pytest.mark.parametrize("b", [0.0, 5e-5])
def test_kalman_is_the_position_only_family_at_its_own_poles(trace, m, b):
    """The Kalman observer has the position-only family's model and filtered form; a
    single-output observer is fixed by its poles, so it is that family's observer placed at the
    poles the Riccati equation chose."""
    model = ServoModel(2.8e-4, b).discretize(1e-3)
    kalman = design_kalman(model, order=m, position_noise_std=1e-4,
                           process_noise_std=1e-3 if m == 0 else 3e-5)  # fmt: skip
    poles = np.linalg.eigvals(np.asarray(kalman.system.F))
    same = design_observer(model, order=m, poles=poles, measurement="position")
    assert relative_difference(estimates(kalman, trace), estimates(same, trace)) < 1e-10


@pytest.fixture(scope="module")
def comparison():
    return compare_observers(duration=4.0)


def test_every_observer_is_tuned_to_the_same_noise_gain(comparison):
    rows = comparison.rows
    assert {r["observer"] for r in rows} >= {"DOb", "HPDOb, position", "ESO, current",
                                             "Kalman m=1"}  # fmt: skip
    assert {r["sensor"] for r in rows} == {"ideal", "encoder"}
    for r in rows:
        assert r["tuning"] == "matched", r
        assert r["noise_gain"] == pytest.approx(comparison.noise_gain, rel=1e-5)
    # the noise in u follows: the same to within the PD's own share (about 20 %)
    u = [r["u_noise"] for r in rows]
    assert max(u) / min(u) < 1.3
    assert comparison.angle_noise == pytest.approx(2 * math.pi / 16384 / math.sqrt(12))


def test_the_finding_of_docs_comparison(comparison):
    """At equal noise every position-only observer estimates better than every observer of
    the paper (which must then run at a bandwidth of 8-25 rad/s), with both sensors."""
    for sensor in ("ideal", "encoder"):
        rows = {r["observer"]: r for r in comparison.rows if r["sensor"] == sensor}
        paper = max(rows[n]["rms_estimation_error"] for n in ("DOb", "HPDOb", "order 2"))
        best_paper = min(rows[n]["rms_estimation_error"] for n in ("DOb", "HPDOb", "order 2"))
        position = [rows[n]["rms_estimation_error"] for n in rows if "position" in n]
        assert max(position) < best_paper < paper
        assert rows["DOb"]["value"] < 30.0


def test_outputs(comparison, tmp_path):
    frame = comparison.to_pandas()
    assert len(frame) == len(comparison.rows) and "delay_margin" in frame
    comparison.to_csv(tmp_path / "c.csv")
    data = json.loads(comparison.to_json(tmp_path / "c.json").read_text())
    assert data["noise_gain"] == 10.0 and len(data["rows"]) == len(comparison.rows)
    assert "| observer | tuned |" in comparison.to_markdown()
    fig = comparison.plot()
    assert fig.axes[0].get_ylabel() == "RMS estimation error [N m]"


def test_cli(tmp_path, capsys):
    code = main(["compare", "--sensor", "ideal", "--noise-gain", "20", "--out",
                 str(tmp_path), "--no-plot"])  # fmt: skip
    _, err = capsys.readouterr()
    assert code == 0 and err == ""
    assert {p.name for p in tmp_path.iterdir()} == {"comparison.csv", "comparison.json",
                                                   "comparison.md"}  # fmt: skip
    data = json.loads((tmp_path / "comparison.json").read_text())
    assert data["noise_gain"] == 20.0 and {r["sensor"] for r in data["rows"]} == {"ideal"}
    assert main(["compare", "--noise-gain", "-1", "--out", str(tmp_path)]) == 2
    assert "noise_gain must be a positive" in capsys.readouterr().err


def test_bad_arguments():
    with pytest.raises(ValueError, match="sensors must be one of 'ideal', 'encoder'"):
        compare_observers(sensors=("lab",))
    with pytest.raises(ValueError, match="noise_gain must be a positive"):
        compare_observers(noise_gain=0.0)
    with pytest.raises(TypeError, match=r"candidates\[.x.\] must be a family spec"):
        compare_observers(candidates={"x": 3})


def test_noise_gain_is_the_encoder_channels():
    model = ServoModel(2.8e-4).discretize(1e-3)
    design = design_observer(model, order=1, bandwidth=100.0, measurement="position")
    assert observer_noise_gain(design, noise="encoder") == observer_noise_gain(
        design, noise="position"
    )


# -- the comparison in a loop with any controller of the protocol (issue 20, section 3) -----

CANDIDATES = {
    "DOb": {"type": "dob", "order": 0},
    "position-only HPDOb": {"type": "dob", "order": 1, "measurement": "position"},
}


@pytest.mark.parametrize(
    ("controller", "expected"),
    [
        # a controller with a velocity source takes the candidate's velocity estimate where it
        # has one, the measured velocity otherwise
        (PID(50.0, 100.0, 5.0), lambda c, v: replace(c, velocity=v)),
        (FilteredPD(50.0, 5.0, time_constant=2e-3), lambda c, v: replace(c, velocity=v)),
        # ADRC has none: it runs as it is
        (ADRC(40.0), lambda c, v: c),
    ],
    ids=["PID", "FilteredPD", "ADRC"],
)
def test_a_loop_with_any_controller(controller, expected):
    from hpdob.observers import design_from_spec
    from hpdob.paper import DISTURBANCE, PLANT, REFERENCE

    loop = ServoLoop(plant=PLANT, nominal=NOMINAL, Ts=TS, controller=controller)
    table = compare_observers(loop, sensors=("ideal",), duration=0.5, candidates=CANDIDATES)
    for row in table.rows:
        assert row["tuning"] == "matched"
        spec = {**CANDIDATES[row["observer"]], "bandwidth": row["value"]}
        design = design_from_spec(NOMINAL.discretize(TS), spec)
        velocity = "observer" if design.system.has_velocity else "measured"
        run = loop.replace(controller=expected(controller, velocity), observer=design)
        direct = simulate(run, reference=REFERENCE, disturbance=DISTURBANCE, duration=0.5)
        result = table._results[(row["observer"], "ideal")]
        np.testing.assert_array_equal(result.u, direct.u)  # the run is this loop's
        # the stable inertia range is that of the python-control loop (at the range's ends)
        linear = {"b": PLANT.b, "Ts": TS, "controller": run.controller_system,
                  "observer": design.system}  # fmt: skip
        low, high = row["J_ratio_low"], row["J_ratio_high"]
        assert 1e-3 < low < 1.0 < high < 1e3  # both ends found for these loops
        for end, inside in ((low, 1.001), (high, 0.999)):
            assert interconnect.radius(J=end * inside * NOMINAL.J, **linear) < 1.0
            assert interconnect.radius(J=end / inside * NOMINAL.J, **linear) > 1.0


@pytest.mark.parametrize("Ts", [1e-320, 1e-9])
def test_a_too_small_Ts_is_refused_up_front_naming_the_limit(Ts, capsys):
    # Issue 27: round(10 s / 1e-320) raised OverflowError (an internal error in `hpdob compare`).
    from hpdob.paper import PLANT

    loop = ServoLoop(
        plant=PLANT, nominal=NOMINAL, Ts=Ts, controller=FilteredPD(50.0, 5.0, time_constant=2e-3)
    )
    with pytest.raises(ValueError, match=r"^Ts must be at least 10 s / 1e\+08 = 1e-07 s .*got "):
        compare_observers(loop)
    assert main(["compare", "--Ts", repr(Ts)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Ts must be at least" in err and "internal" not in err
