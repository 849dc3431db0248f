"""A family defined only here, registered at run time, works in every layer that designs
observers by name -- with no edit under src/ (issue 20, section 1).

The family: the paper's order-m DOb followed by a first-order low-pass of its estimate,
``tau_f[k+1] = a tau_f[k] + (1 - a) tau_hat[k]`` with ``a = exp(-filter_bandwidth Ts)``,
built from the DOb's F, G, H, E, N by hand (as tests/observers/test_system.py does for one design).
The docs' table of families is the registry's (docs/architecture.md; moved here from
tests/observers/test_registry_docs.py).
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

import low_pass_family
from hpdob import (
    PD,
    Encoder,
    ServoModel,
    compare_observers,
    design_observer,
    estimation_response,
    robust_stability_map,
    simulate,
    sweep,
    tune,
)
from hpdob.cli import main
from hpdob.observers import (
    Family,
    Observer,
    Parameter,
    design_from_spec,
    families,
    get_family,
    register_family,
    spec_of,
)
from hpdob.simulation import load_scenario
from low_pass_family import FILTERED, FilteredDesign, design_filtered

TS = 1e-3
NOMINAL = ServoModel(2.8e-4)
MODEL = NOMINAL.discretize(TS)
registered = low_pass_family.registered  # the fixture registering FILTERED


def test_registration_is_undone_by_the_fixture():
    assert "dob_lp" not in [f.name for f in families()]


def test_spec_round_trip_and_runtime(registered):
    design = design_from_spec(
        MODEL, {"type": "dob_lp", "bandwidth": 150.0, "filter_bandwidth": 300.0}
    )
    spec = spec_of(design)
    assert spec == {"type": "dob_lp", "order": 0, "bandwidth": 150.0, "filter_bandwidth": 300.0}
    again = design_from_spec(MODEL, spec)
    np.testing.assert_array_equal(again.system.F, design.system.F)
    assert type(Observer.of(design)) is Observer
    # Q is the DOb's times the low-pass (an independent check of the construction)
    dob = design_observer(MODEL, order=0, bandwidth=150.0)
    f = np.array([1.0, 20.0])
    z = np.exp(1j * 2 * np.pi * f * TS)
    a = math.exp(-300.0 * TS)
    np.testing.assert_allclose(
        estimation_response(design, f), estimation_response(dob, f) * (1 - a) / (z - a), rtol=1e-9
    )


def test_register_refuses_a_taken_name_and_clashing_kinds(registered):
    with pytest.raises(ValueError, match="'dob_lp' is already registered"):
        register_family(FILTERED)
    clash = Family("clash", design_filtered, (Parameter("order", "float"), Parameter("bandwidth")))
    with pytest.raises(ValueError, match="parameter 'order' is a 'float'"):
        register_family(clash)
    assert get_family("dob_lp") is FILTERED


def test_hpdob_design_and_export_c_cli(registered, capsys, tmp_path):
    argv = [
        "design",
        "--type",
        "dob_lp",
        "--order",
        "1",
        "--bandwidth",
        "150",
        "--filter-bandwidth",
        "300",
        "--json",
    ]
    assert main(argv) == 0
    summary = json.loads(capsys.readouterr().out)
    expected = design_filtered(MODEL, order=1, bandwidth=150.0, filter_bandwidth=300.0)
    np.testing.assert_array_equal(np.array(summary["F"]), expected.system.F)
    options = ["--type", "dob_lp", "--bandwidth", "150", "--filter-bandwidth", "300"]
    assert main(["export-c", *options, "--out", str(tmp_path)]) == 0
    capsys.readouterr()
    assert sorted(p.suffix for p in tmp_path.iterdir()) == [".c", ".h"]
    # an option of another family is refused with the generic message
    assert (
        main(["design", "--type", "dob_lp", "--filter-bandwidth", "300", "--form", "current"]) == 2
    )
    assert "--form applies to --type eso only, not --type dob_lp" in capsys.readouterr().err
    # and its own option is refused for the built-in families
    assert main(["design", "--filter-bandwidth", "300"]) == 2
    assert "--filter-bandwidth applies to --type dob_lp only" in capsys.readouterr().err


def test_toml_scenario(registered, tmp_path):
    path = tmp_path / "filtered.toml"
    path.write_text(
        "Ts = 1e-3\nduration = 0.5\n[plant]\nJ = 3.06e-4\nb = 5e-5\n[nominal]\nJ = 2.8e-4\n"
        "[controller]\nkp = 50.0\nkd = 5.0\n"
        '[observer]\ntype = "dob_lp"\norder = 1\nbandwidth = 150.0\nfilter_bandwidth = 300.0\n'
        '[[reference]]\ntype = "step"\ntime = 0.1\namplitude = 1.0\n'
        '[[disturbance]]\ntype = "step"\ntime = 0.2\namplitude = 0.05\n'
    )
    scenario = load_scenario(path)
    assert scenario.loop.system.name == "DOb m=1 + LP"
    assert scenario.loop.observer_spec["filter_bandwidth"] == 300.0
    result = scenario.simulate()
    fixed = design_filtered(MODEL, order=1, bandwidth=150.0, filter_bandwidth=300.0)
    direct = simulate(scenario.loop.replace(observer=fixed), **scenario.run)
    np.testing.assert_array_equal(result.tau_hat, direct.tau_hat)
    assert abs(result.tau_hat[-1] - result.tau_dn[-1]) < 1e-3  # converged on the step
    bad = path.read_text().replace("filter_bandwidth = 300.0", "filter_width = 300.0")
    path.write_text(bad)
    with pytest.raises(ValueError, match=r"observer\.filter_width"):
        load_scenario(path)


def test_sweep_over_its_parameters(registered):
    from hpdob.signals import Step

    base = {
        "plant": ServoModel(3.06e-4, 5e-5),
        "nominal": NOMINAL,
        "Ts": TS,
        "controller": PD(50, 5),
        "duration": 0.5,
        "reference": Step(0.1, 1.0),
        "disturbance": Step(0.2, 0.05),
        "observer": {"type": "dob_lp", "bandwidth": 150.0, "filter_bandwidth": 300.0},
    }
    grid = {"observer.order": [0, 1], "observer.filter_bandwidth": [100.0, 1000.0]}
    table = sweep(base, grid=grid)
    assert len(table) == 4
    assert (table["error"] == "").all() and table["stable"].all()
    assert table["rms_estimation_error"].nunique() == 4  # each scenario designed its observer
    # the scenario order=1, filter_bandwidth=1000 is what the direct design gives
    direct = simulate(
        **{k: v for k, v in base.items() if k != "observer"},
        observer=design_filtered(MODEL, order=1, bandwidth=150.0, filter_bandwidth=1000.0),
    )
    row = table[(table["observer.order"] == 1) & (table["observer.filter_bandwidth"] == 1000.0)]
    assert row["rms_estimation_error"].item() == direct.metrics()["rms_estimation_error"]
    # a path of another family does not apply to this spec
    with pytest.raises(ValueError, match="type 'dob_lp' has no design argument 'form'"):
        sweep(base, grid={"observer.form": ["current"]})


def test_robust_map(registered):
    smap = robust_stability_map(
        J_ratio=[0.5, 1.0, 2.0],
        bandwidth=[50.0, 100.0],
        observer={"type": "dob_lp", "order": 0, "filter_bandwidth": 2000.0},
        nominal=NOMINAL,
        Ts=TS,
        controller=PD(50, 5),
    )
    assert smap.stable.all()
    assert smap._setting.name == "DOb m=0 + LP"
    with pytest.raises(ValueError, match="must not give bandwidth"):
        robust_stability_map(
            J_ratio=[0.5, 1.0],
            bandwidth=[50.0],
            observer={"type": "dob_lp", "bandwidth": 1.0, "filter_bandwidth": 2000.0},
            nominal=NOMINAL,
            Ts=TS,
            controller=PD(50, 5),
        )


def test_compare_observers_default_candidates(registered):
    table = compare_observers(sensors=("ideal",), duration=0.5)
    names = [row["observer"] for row in table.rows]
    assert names[-1] == "DOb + LP" and names[:2] == ["DOb", "HPDOb"]
    row = table.rows[-1]
    assert row["family"] == "dob_lp" and row["tuned"] == "bandwidth"
    assert row["tuning"] == "matched"
    assert math.isclose(row["noise_gain"], table.noise_gain, rel_tol=1e-3)


def test_tune_candidates(registered):
    from hpdob.signals import Step

    result = tune(
        nominal=NOMINAL,
        Ts=TS,
        sensor=Encoder(16384),
        families=["filtered"],
        J_range=(0.9, 1.1),
        scenario={"reference": Step(0.1, 1.0), "duration": 0.3},
    )
    families_seen = {row["family"] for row in result.rows}
    assert families_seen == {"filtered"}
    assert {row["order"] for row in result.rows} == {0, 1}
    assert isinstance(result.design, FilteredDesign)


def test_robust_map_and_comparison_of_a_loop_with_the_family(registered):
    """The family as a loop's observer spec: the map designs it at every bandwidth (its
    spec's other parameters kept), with any controller; the comparison runs it in the loop."""
    from hpdob import PID, ServoLoop, closed_loop_poles

    spec = {"type": "dob_lp", "order": 1, "bandwidth": 100.0, "filter_bandwidth": 2000.0}
    loop = ServoLoop(plant=NOMINAL, nominal=NOMINAL, Ts=TS, controller=PID(50.0, 100.0, 5.0),
                     observer=spec)  # fmt: skip
    smap = robust_stability_map(loop, J_ratio=[0.5, 1.0, 2.0], bandwidth=[50.0, 150.0])
    assert smap.observer == {"type": "dob_lp", "order": 1, "filter_bandwidth": 2000.0}
    for i, ratio in enumerate((0.5, 1.0, 2.0)):
        for j, g in enumerate((50.0, 150.0)):
            design = design_filtered(MODEL, order=1, bandwidth=g, filter_bandwidth=2000.0)
            moved = loop.replace(plant=ServoModel(ratio * NOMINAL.J), observer=design)
            assert smap.spectral_radius[i, j] == np.abs(closed_loop_poles(moved)).max()
    candidates = {"LP": {"type": "dob_lp", "order": 0, "filter_bandwidth": 2000.0}}
    table = compare_observers(loop.replace(plant=ServoModel(3.06e-4, 5e-5)), sensors=("ideal",),
                              duration=0.3, candidates=candidates)  # fmt: skip
    assert [r["family"] for r in table.rows] == ["dob_lp"] and table.rows[0]["tuning"] == "matched"


def test_export_c_of_a_design_of_the_family(registered, tmp_path):
    """``export_c`` (the library call) writes the family's program: the C estimate replayed on
    a trace is the functional core's."""
    from hpdob import export_c
    from hpdob.observers import estimate, initial_state, update
    from hpdob.testing import find_compiler

    design = design_from_spec(MODEL, {"type": "dob_lp", "order": 1, "bandwidth": 150.0,
                                      "filter_bandwidth": 300.0})  # fmt: skip
    header, source = export_c(design, tmp_path, prefix="lp")
    text = source.read_text()
    assert "lp_estimate" in header.read_text() and "lp_update" in text
    if find_compiler() is None:  # the C is checked where a compiler is (CI has one)
        return
    import ctypes

    from hpdob.testing import STRICT_FLAGS, compile_c

    library = ctypes.CDLL(
        str(compile_c([source], tmp_path / "lp.so", flags=STRICT_FLAGS, shared=True))
    )
    n = design.system.n_states
    state = (ctypes.c_double * n)()
    library.lp_init(state, ctypes.c_double(0.0), ctypes.c_double(0.0), ctypes.c_double(0.0))
    library.lp_estimate.restype = ctypes.c_double
    rng = np.random.default_rng(3)
    s = initial_state(design, (0.0, 0.0), 0.0)
    for _ in range(200):
        theta, omega, u = rng.normal(size=3) * (1e-2, 1e-1, 1e-3)
        args = [ctypes.c_double(theta), ctypes.c_double(omega)]
        assert library.lp_estimate(state, *args) == estimate(design, s, (theta, omega))
        library.lp_update(state, *args, ctypes.c_double(u))
        s = update(design, s, (theta, omega), u)


DOCS_TABLE = Path(__file__).parents[2] / "docs" / "architecture.md"


def test_the_architecture_table_lists_every_registered_family():
    rows = {}
    for line in DOCS_TABLE.read_text().splitlines():
        m = re.match(r"^\| `(\w+)` \| (.+?) \| (.+?) \| `(\w+|None)` \| `(\w+)` \|$", line)
        if m:
            rows[m.group(1)] = m.groups()[1:]
    assert set(rows) == {f.name for f in families()}
    for f in families():
        title, params, order, tuned = rows[f.name]
        assert title == f.title
        names = re.findall(r"`(\w+)`", params)
        assert names == list(f.keys)
        assert re.findall(r"\*\*`(\w+)`\*\*", params) == [k for k in f.keys if k in f.required]
        assert (order, tuned) == (str(f.order), f.tuned)
