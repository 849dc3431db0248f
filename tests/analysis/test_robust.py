"""Robust stability maps: verdicts against divergence of the nonlinear simulator on both sides
of the boundary (inertia error, friction error, one-sample delay), and the map's outputs."""

from __future__ import annotations

import math
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from hpdob import (
    ADRC,
    PD,
    PID,
    Actuator,
    FilteredPD,
    LinearController,
    ParameterTypeError,
    ParameterValueError,
    ServoLoop,
    ServoModel,
    SimulationDivergedWarning,
    StabilityMap,
    closed_loop_poles,
    design_observer,
    robust_stability_map,
    simulate,
)
from hpdob.signals import SmoothStep

TS = 1e-3
NOMINAL = ServoModel(2.8e-4)
PDC = PD(50.0, 5.0)
CANONICAL_B = 5e-5  # N m s/rad, the canonical motor's viscous friction

CASES = {
    # name: map arguments, factor "just inside", factor "just outside" the boundary
    "inertia-lower": (
        {"J_ratio": np.geomspace(0.05, 0.3, 6), "b": CANONICAL_B, "bandwidth": [100.0], "order": 1},
        1.03,
        0.97,
    ),
    "inertia-upper": (
        {"J_ratio": np.geomspace(2.0, 10.0, 6), "b": CANONICAL_B, "bandwidth": [25.0], "order": 1},
        0.9,
        1.2,
    ),
    "friction": (
        {"J_ratio": 3.06 / 2.8, "b": np.geomspace(0.05, 1.0, 6), "bandwidth": [100.0], "order": 1},
        0.8,
        1.5,
    ),
    "delay": (
        {
            "J_ratio": np.geomspace(0.3, 1.5, 6),
            "b": CANONICAL_B,
            "bandwidth": [400.0],
            "order": 1,
            "delay_samples": 1,
        },
        1.03,
        0.97,
    ),
    "inertia-lower-order3": (
        {"J_ratio": np.geomspace(0.05, 0.3, 6), "b": CANONICAL_B, "bandwidth": [100.0], "order": 3},
        1.03,
        0.97,
    ),
}


def run(smap: StabilityMap, value: float, bandwidth: float, samples: int):
    J_ratio, b = (value, smap.b) if smap.parameter == "J_ratio" else (smap.J_ratio, value)
    design = design_observer(NOMINAL.discretize(TS), order=smap.order, bandwidth=bandwidth)
    return simulate(
        plant=ServoModel(J_ratio * NOMINAL.J, b),  # Coulomb friction off
        nominal=NOMINAL,
        Ts=TS,
        duration=samples * TS,
        controller=PDC,
        observer=design,
        reference=SmoothStep(0.0, 0.2, 1.0),
        actuator=Actuator(delay_samples=smap.delay_samples),
        substeps=1,  # exact for a linear plant and a torque held over the sample
    )


@pytest.mark.parametrize("case", list(CASES))
def test_verdict_matches_divergence_of_the_simulation(case):
    kwargs, inside, outside = CASES[case]
    smap = robust_stability_map(nominal=NOMINAL, Ts=TS, controller=PDC, **kwargs)
    (edge,) = smap.boundary()  # one crossing on each of these grids
    g, critical = edge["bandwidth"], edge[smap.parameter]
    rho_in = smap.radius_at(critical * inside, g)
    rho_out = smap.radius_at(critical * outside, g)
    assert rho_in < 1.0 < rho_out
    growth = math.log(1e9) / math.log(rho_out)  # samples to grow 1e9-fold
    samples = int(1.6 * growth) + 500
    with pytest.warns(SimulationDivergedWarning, match="diverged"):
        bad = run(smap, critical * outside, g, samples)
    assert bad.diverged
    assert 0.5 * growth < bad.t.size < 1.6 * growth + 500  # grows at the predicted rate
    good = run(smap, critical * inside, g, samples)  # filterwarnings=error: no warning here
    assert not good.diverged
    err = np.abs(good.theta - 1.0)
    quarter = samples // 4
    assert err[-quarter:].max() < err[quarter : 2 * quarter].max()  # decaying, not growing


def test_grid_matches_closed_loop_poles_and_outputs(tmp_path):
    smap = robust_stability_map(
        J_ratio=[0.1, 1.0, 4.0],
        bandwidth=[50.0, 800.0],
        order=2,
        nominal=NOMINAL,
        Ts=TS,
        controller=PDC,
        b=CANONICAL_B,
    )
    for i, ratio in enumerate(smap.values):
        for j, g in enumerate(smap.bandwidths):
            poles = closed_loop_poles(
                plant=ServoModel(ratio * NOMINAL.J, CANONICAL_B),
                nominal=NOMINAL,
                Ts=TS,
                controller=PDC,
                observer=design_observer(NOMINAL.discretize(TS), order=2, bandwidth=g),
            )
            assert smap.spectral_radius[i, j] == np.abs(poles).max()
    assert smap.stable.tolist() == (smap.spectral_radius < 1).tolist()
    assert (smap.parameter, smap.b, smap.J_ratio, smap.delay_samples) == (
        "J_ratio",
        CANONICAL_B,
        None,
        0,
    )
    frame = smap.to_pandas()
    assert list(frame.columns) == [
        "J_ratio",
        "bandwidth_rad_s",
        "b",
        "order",
        "delay_samples",
        "spectral_radius",
        "stable",
    ]
    assert (
        len(frame) == 6
        and frame["spectral_radius"].tolist() == smap.spectral_radius.ravel().tolist()
    )
    lines = smap.to_csv(tmp_path / "map.csv").read_text().splitlines()
    assert len(lines) == 7 and lines[1].endswith(("true", "false"))


def test_plot_draws_the_boundary():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    smap = robust_stability_map(
        J_ratio=np.geomspace(0.1, 10, 12),
        bandwidth=np.geomspace(20, 2000, 10),
        order=1,
        nominal=NOMINAL,
        Ts=TS,
        controller=PDC,
    )
    assert smap.stable.any() and not smap.stable.all()
    fig = smap.plot(mark=(100.0, 3.06 / 2.8))
    ax = fig.axes[0]
    assert "bandwidth" in ax.get_xlabel() and "[rad/s]" in ax.get_xlabel()
    assert "J/J_n" in ax.get_ylabel()
    assert ax.collections, "heat-map and boundary contour drawn"
    assert any(type(c).__name__ in ("QuadContourSet", "ContourSet") for c in ax.collections)
    plt.close(fig)


def test_friction_map_with_zero_friction_on_the_grid():
    smap = robust_stability_map(
        J_ratio=1.0,
        b=[0.0, 0.1, 1.0],
        bandwidth=[100.0],
        order=0,
        nominal=NOMINAL,
        Ts=TS,
        controller=PDC,
    )
    assert smap.parameter == "b" and smap.J_ratio == 1.0 and smap.b is None
    assert smap.stable.all()  # the DOb tolerates any viscous friction here (docs/analysis.md)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        plt.close(smap.plot())  # linear axis when 0 is on the grid


def test_unsorted_grids_are_rejected():
    # boundary() brackets crossings between neighbouring grid values and names their kind from
    # their order: a reversed grid used to turn the HPDOb's small-inertia limit at 100 rad/s
    # (stable above J/J_n = 0.09517, docs/analysis.md section 6, so "lower") into an "upper"
    # one. The map's axes must therefore increase strictly.
    kw = {"order": 1, "nominal": NOMINAL, "Ts": TS, "controller": PDC}
    grid = np.geomspace(0.05, 0.3, 6)
    (edge,) = robust_stability_map(J_ratio=grid, bandwidth=[100.0], **kw).boundary()
    assert edge["kind"] == "lower" and edge["J_ratio"] == pytest.approx(0.0952, rel=1e-3)
    for bad in (grid[::-1], [0.1, 0.3, 0.2], [0.1, 0.2, 0.2]):
        with pytest.raises(ParameterValueError, match=r"^J_ratio must be strictly increasing"):
            robust_stability_map(J_ratio=bad, bandwidth=[100.0], **kw)
    with pytest.raises(ParameterValueError, match=r"^b must be strictly increasing, got \[1\."):
        robust_stability_map(J_ratio=1.0, b=[1.0, 0.0], bandwidth=[100.0], **kw)
    with pytest.raises(ParameterValueError, match=r"^bandwidth must be strictly increasing"):
        robust_stability_map(J_ratio=grid, bandwidth=[400.0, 100.0], **kw)


def test_bad_arguments():
    kw = {"bandwidth": [100.0], "order": 1, "nominal": NOMINAL, "Ts": TS, "controller": PDC}
    with pytest.raises(ParameterValueError, match="J_ratio must hold at least one value"):
        robust_stability_map(J_ratio=[], **kw)
    with pytest.raises(ParameterValueError, match=r"J_ratio must be positive.*-0\.5"):
        robust_stability_map(J_ratio=[1.0, -0.5], **kw)
    with pytest.raises(ParameterValueError, match=r"J_ratio must be positive.*got 0\.0"):
        robust_stability_map(J_ratio=[0.0, 1.0], **kw)
    with pytest.raises(ParameterValueError, match="bandwidth must hold at least one value"):
        robust_stability_map(J_ratio=[1.0], **{**kw, "bandwidth": []})
    with pytest.raises(ParameterValueError, match=r"bandwidth must be positive.*-100\.0"):
        robust_stability_map(J_ratio=[1.0], **{**kw, "bandwidth": [-100.0]})
    with pytest.raises(ParameterValueError, match=r"b must be non-negative.*-0\.1"):
        robust_stability_map(J_ratio=1.0, b=[0.1, -0.1], **kw)
    with pytest.raises(ParameterValueError, match=r"exactly one of J_ratio and b.*got both"):
        robust_stability_map(J_ratio=[1.0], b=[0.1], **kw)
    with pytest.raises(ParameterValueError, match=r"exactly one of J_ratio and b.*got neither"):
        robust_stability_map(J_ratio=1.0, **kw)
    with pytest.raises(ParameterValueError, match=r"order must be a non-negative.*-1"):
        robust_stability_map(J_ratio=[1.0], **{**kw, "order": -1})
    with pytest.raises(ParameterValueError, match="delay_samples must be a non-negative"):
        robust_stability_map(J_ratio=[1.0], delay_samples=-1, **kw)
    with pytest.raises(ParameterTypeError, match="controller must be a PD"):
        robust_stability_map(J_ratio=[1.0], **{**kw, "controller": None})
    smap = robust_stability_map(J_ratio=[1.0], **kw)
    with pytest.raises(ParameterValueError, match=r"value must be a positive.*-2"):
        smap.radius_at(-2.0, 100.0)


# -- any controller of the protocol, the loop as the first argument (issue 20, section 3) ----

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import interconnect  # noqa: E402  (tests/interconnect.py: the loop assembled by python-control)

K, KI, KV, TF = 0.1, 0.3, 0.004, 5e-3  # N m/rad, N m/(rad s), N m s/rad, s


def from_scratch() -> LinearController:
    """A PI on the angle with a dirty-derivative velocity, plus the estimate, written here
    from its equations only (no anti-windup: the map's loop is linear):
    ``u = K (r - theta) + KI c1 - KV (theta - c2)/TF + tau_hat``,
    ``c1+ = c1 + Ts (r - theta)``, ``c2+ = c2 + (Ts/TF)(theta - c2)``."""
    a = TS / TF
    return LinearController(
        F=[[1.0, 0.0], [0.0, 1 - a]], G=[[TS, -TS, 0.0, 0.0], [0.0, a, 0.0, 0.0]],
        H=[[KI, KV / TF]], E=[[K, -K - KV / TF, 1.0]], N=[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]],
        Ts=TS, inputs=("r", "theta", "tau_hat"), name="PI + dirty derivative",
    )  # fmt: skip


CONTROLLERS = {
    "PID": PID(50.0, 100.0, 5.0),
    "FilteredPD": FilteredPD(50.0, 5.0, time_constant=2e-3),
    "ADRC": ADRC(40.0),
    "from scratch": from_scratch(),
    "PD, observer's velocity": PD(50.0, 5.0, velocity="observer"),
}


@pytest.mark.parametrize("name", list(CONTROLLERS))
def test_map_of_any_controller_is_the_python_control_loop(name):
    controller = CONTROLLERS[name]
    measurement = "position" if "velocity" in name else "state"
    spec = {"type": "dob", "order": 1, "bandwidth": 100.0, "measurement": measurement}
    loop = ServoLoop(plant=NOMINAL, nominal=NOMINAL, Ts=TS, controller=controller,
                     observer=spec)  # fmt: skip
    ratios, bandwidths = [0.3, 1.0, 3.0], [40.0, 150.0]
    smap = robust_stability_map(loop, J_ratio=ratios, b=CANONICAL_B, bandwidth=bandwidths)
    assert smap.observer["measurement"] == measurement  # the loop's spec, its bandwidth set
    for i, ratio in enumerate(ratios):
        for j, g in enumerate(bandwidths):
            design = design_observer(NOMINAL.discretize(TS), order=1, bandwidth=g,
                                     measurement=measurement)  # fmt: skip
            expected = interconnect.radius(J=ratio * NOMINAL.J, b=CANONICAL_B, Ts=TS,
                                           controller=loop.controller_system,
                                           observer=design.system)  # fmt: skip
            assert smap.spectral_radius[i, j] == pytest.approx(expected, rel=1e-9, abs=1e-12)
    # the map's verdicts are not all alike: the grid crosses the boundary for some controllers
    assert smap.spectral_radius.min() < 1.0


def test_map_of_a_pd_loop_is_the_keyword_map_bit_for_bit():
    loop = ServoLoop(plant=NOMINAL, nominal=NOMINAL, Ts=TS, controller=PDC,
                     observer={"order": 1, "bandwidth": 100.0})  # fmt: skip
    ratios = np.geomspace(0.05, 2.0, 7)
    by_loop = robust_stability_map(loop, J_ratio=ratios, bandwidth=[50.0, 100.0])
    by_keywords = robust_stability_map(J_ratio=ratios, bandwidth=[50.0, 100.0], order=1,
                                       nominal=NOMINAL, Ts=TS, controller=PDC)  # fmt: skip
    np.testing.assert_array_equal(by_loop.spectral_radius, by_keywords.spectral_radius)


def test_map_refuses_a_controller_it_cannot_wire():
    # the observer's velocity estimate from a family that measures the state: named, before
    # any work (it used to fail inside the linear algebra with a KeyError)
    with pytest.raises(ParameterValueError, match=r"controller\.velocity = 'observer' needs"):
        robust_stability_map(J_ratio=[1.0, 2.0], bandwidth=[100.0], order=1, nominal=NOMINAL,
                             Ts=TS, controller=PD(50.0, 5.0, velocity="observer"))  # fmt: skip
