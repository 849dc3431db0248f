"""Tests of hpdob.sweep: rows equal single simulations, seeds, flags, local vs dask."""

from __future__ import annotations

import dataclasses
import os
import signal
import threading
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from hpdob import (
    DisturbanceObserver,
    ServoLoop,
    ServoModel,
    SimulationDivergedWarning,
    design_observer,
    paper,
    simulate,
    sweep,
)

METRICS = [
    "rms_estimation_error",
    "rms_position_error_regulation",
    "rms_position_error_tracking",
    "max_abs_position_error",
]


def base(duration=2.0):
    return {
        **paper.scenario(),
        "duration": duration,
        "observer": {"order": 1, "bandwidth": 100.0},
    }


def test_rows_equal_single_simulations():
    grid = {"observer.order": [0, 1], "plant.J": [2.5e-4, 3.5e-4], "disturbance_scale": [0.5, 1]}
    rows = sweep(base(5.0), grid=grid, progress=False)
    assert len(rows) == 8
    assert list(rows["scenario"]) == list(range(8))
    for _, row in rows.iloc[[0, 5, 7]].iterrows():
        kwargs = base(5.0)
        kwargs["plant"] = kwargs["plant"].replace(J=row["plant.J"])
        kwargs["disturbance"] = row["disturbance_scale"] * kwargs["disturbance"]
        obs = DisturbanceObserver(
            kwargs["nominal"].discretize(1e-3), order=int(row["observer.order"]), bandwidth=100.0
        )
        kwargs["observer"] = obs.design
        result = simulate(**kwargs)
        for name, value in result.metrics().items():
            assert row[name] == value, name  # the same engine: bit for bit
        assert row["max_abs_position_error"] == result.max_abs_position_error()
        assert row["stable"]
        assert row["error"] == ""


def test_monte_carlo_is_reproducible_and_seeded():
    vary = {"plant.J": ("uniform", 2.5e-4, 3.5e-4), "controller.kp": ("normal", 50, 5)}
    a = sweep(base(1.0), vary=vary, n=6, seed=11, progress=False)
    b = sweep(base(1.0), vary=vary, n=6, seed=11, scheduler=1, progress=False)
    c = sweep(base(1.0), vary=vary, n=6, seed=12, progress=False)
    pd.testing.assert_frame_equal(a, b)
    assert not a["plant.J"].equals(c["plant.J"])
    assert list(a.columns[:3]) == ["scenario", "controller.kp", "plant.J"]


def test_diverging_and_invalid_scenarios_are_flagged_not_raised():
    grid = {"nominal.J": [3e-4, 3e-3], "observer.bandwidth": [900.0, -1.0]}
    b = {**base(3.0), "plant": ServoModel(3e-5)}  # 1/10 or 1/100 of nominal: unstable
    with warnings.catch_warnings():
        warnings.simplefilter("error", SimulationDivergedWarning)  # sweep must not warn
        rows = sweep(b, grid=grid, progress=False)
    assert not rows["stable"].any()
    diverged = rows[rows["observer.bandwidth"] == 900.0]
    assert diverged["error"].str.contains("diverged").all()
    assert np.isfinite(diverged["rms_estimation_error"]).all()
    invalid = rows[rows["observer.bandwidth"] == -1.0]
    assert invalid["error"].str.startswith("bandwidth must be a positive").all()
    assert invalid["rms_estimation_error"].isna().all()


def test_sampling_period_and_observer_poles_base():
    b = base(1.0)
    b["observer"] = {"order": 1, "poles": [0.9, 0.85]}
    rows = sweep(b, grid={"Ts": [1e-3, 5e-4]}, progress=False)
    assert rows["stable"].all()
    assert rows.loc[0, "rms_estimation_error"] != rows.loc[1, "rms_estimation_error"]


def test_observer_object_in_base_and_progress_callback():
    b = base(1.0)
    b["observer"] = DisturbanceObserver(b["nominal"].discretize(1e-3), order=0, bandwidth=80.0)
    seen = []
    rows = sweep(
        b,
        grid={"controller.kd": [4.0, 5.0, 6.0]},
        progress=lambda done, total: seen.append((done, total)),
    )
    assert len(rows) == 3
    assert seen[-1] == (3, 3)


def test_memory_is_per_scenario():
    """Rows only: the DataFrame holds a handful of numbers per scenario, never traces."""
    rows = sweep(base(1.0), grid={"controller.kp": [40.0, 50.0]}, progress=False)
    assert rows.memory_usage(deep=False).sum() < 2_000


@pytest.mark.parametrize(
    ("kwargs", "exc", "pattern"),
    [
        ({"grid": {"plant.mass": [1]}}, ValueError, r"valid paths: plant.J"),
        ({"scheduler": "localhost"}, ValueError, r"^scheduler must be 'threads'"),
        ({"scheduler": 0}, ValueError, r"^scheduler must be a positive number"),
        ({"scheduler": 2.5}, TypeError, r"^scheduler must be None"),
    ],
)
def test_bad_arguments(kwargs, exc, pattern):
    with pytest.raises(exc, match=pattern):
        sweep(base(1.0), progress=False, **kwargs)


@pytest.mark.parametrize(
    ("change", "exc", "pattern"),
    [
        ({"colour": 1}, ValueError, r"^unknown key base.colour = 1; valid keys of base: plant"),
        (
            {"observer": {"order": 1, "speed": 3}},
            ValueError,
            r"^unknown key observer.speed = 3; valid keys of observer: order",
        ),
        ({"observer": "hpdob"}, TypeError, r"^base\['observer'\] must be a dict"),
        (
            {"observer": {"bandwidth": 100.0}},
            ValueError,
            r"^base\['observer'\] must have the required key 'order' \(keys: order, poles, "
            r"bandwidth, measurement, velocity_bandwidth, gain_direction\), got "
            r"\{'bandwidth': 100.0\}",
        ),
        ({"controller": None}, TypeError, r"^controller must be a PD"),
        ({"reference": 3.0}, TypeError, r"^reference must be a Signal"),
        (
            {"Ts": -1e-3},
            ValueError,
            r"^Ts must be a positive finite sampling period \[s\], got -0.001",
        ),
        (
            {"duration": "1 s"},
            TypeError,
            r"^duration must be a positive finite duration \[s\], got '1 s'",
        ),
        ({"duration": 1.0005}, ValueError, r"^duration must be a positive multiple of Ts"),
        ({"substeps": 0}, ValueError, r"^substeps must be a positive integer .*got 0"),
        ({"substeps": 2.5}, TypeError, r"^substeps must be a positive integer .*got 2.5"),
        ({"x0": (0.0,)}, ValueError, r"^x0 must be an initial state .*shape \(2,\)"),
        ({"sensor": "encoder"}, TypeError, r"^sensor must be an Encoder or None, got str"),
        ({"actuator": 1.0}, TypeError, r"^actuator must be an Actuator or None, got float"),
    ],
)
def test_bad_base(change, exc, pattern):
    with pytest.raises(exc, match=pattern):
        sweep({**base(1.0), **change}, progress=False)


def test_missing_base_key():
    b = base(1.0)
    del b["plant"]
    with pytest.raises(ValueError, match=r"^base is missing the required key 'plant'"):
        sweep(b, progress=False)


def _loop_of(b):
    return ServoLoop(**{k: b[k] for k in ("plant", "nominal", "Ts", "controller", "observer")})


def test_a_servo_loop_base_gives_the_rows_of_its_dict_form():
    # Issue 20: sweep takes a ServoLoop, the run settings given as simulate() takes them.
    b = base(1.5)
    loop = _loop_of(b)
    run = {k: b[k] for k in ("duration", "reference", "disturbance")}
    grid = {"observer.order": [0, 1], "plant.J": [2.5e-4, 3.5e-4]}
    by_loop = sweep(loop, grid=grid, **run, substeps=2, progress=False)
    by_dict = sweep({"loop": loop, **run, "substeps": 2}, grid=grid, progress=False)
    pd.testing.assert_frame_equal(by_loop, by_dict)
    assert by_loop["stable"].all()
    assert not by_loop["rms_position_error_regulation"].isna().any()  # tracking starts at 4 s


@pytest.mark.parametrize(
    ("call", "exc", "pattern"),
    [
        (
            lambda loop, b: sweep(loop, progress=False, reference=b["reference"]),
            ValueError,
            r"^duration is required with a ServoLoop base: sweep\(loop, grid=\.\.\., duration=",
        ),
        (
            lambda loop, b: sweep(loop, progress=False, duration=1.0),
            ValueError,
            r"^reference is required with a ServoLoop base",
        ),
        (
            lambda loop, b: sweep(b, progress=False, duration=1.0),
            ValueError,
            r"^duration is a keyword of sweep\(loop, \.\.\.\) with a ServoLoop base only, got "
            r"duration=1.0 with a dict base",
        ),
        (
            lambda loop, b: sweep(1.0, progress=False),
            TypeError,
            r"^base must be a ServoLoop, a Scenario or a dict of simulate\(\) arguments, got float",
        ),
    ],
)
def test_servo_loop_base_errors(call, exc, pattern):
    b = base(1.0)
    with pytest.raises(exc, match=pattern):
        call(_loop_of(b), b)


@pytest.mark.timeout(120)
def test_dask_gives_the_same_rows_bit_for_bit(dask_cluster):
    _, client = dask_cluster()
    grid = {"observer.order": [0, 1], "observer.bandwidth": [60.0, 120.0]}
    vary = {"plant.J": ("loguniform", 2e-4, 5e-4)}
    local = sweep(base(1.0), grid=grid, vary=vary, n=3, seed=5, progress=False)
    remote = sweep(base(1.0), grid=grid, vary=vary, n=3, seed=5, scheduler=client, progress=False)
    by_address = sweep(
        base(1.0),
        grid=grid,
        vary=vary,
        n=3,
        seed=5,
        scheduler=client.scheduler.address,
        progress=False,
    )
    pd.testing.assert_frame_equal(local, remote)
    pd.testing.assert_frame_equal(local, by_address)


@pytest.mark.timeout(120)
def test_a_killed_worker_does_not_lose_rows(dask_cluster):
    _, client = dask_cluster()
    grid = {"observer.bandwidth": list(np.linspace(40.0, 200.0, 40)), "observer.order": [0, 1]}
    expected = sweep(base(1.0), grid=grid, progress=False)
    pids = list(client.run(os.getpid).values())
    killed = threading.Event()

    def kill_one(done, total):
        if done >= 8 and not killed.is_set():
            killed.set()
            os.kill(pids[0], signal.SIGKILL)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # dask may warn about the lost worker
        rows = sweep(base(1.0), grid=grid, scheduler=client, progress=kill_one)
    assert killed.is_set()
    assert len(rows) == 80
    pd.testing.assert_frame_equal(rows, expected)


@pytest.mark.timeout(120)
def test_an_interrupted_dask_sweep_cancels_its_tasks(dask_cluster):
    # issue 16, item 2: Ctrl-C (here raised by the progress callback once the first chunk is
    # back) must not leave the remaining chunks running on the cluster
    _, client = dask_cluster()
    # 63 chunks of 64 scenarios of 10 s: about a minute of work on the two workers
    grid = {"observer.bandwidth": list(np.linspace(40.0, 200.0, 2000)), "observer.order": [0, 1]}

    def interrupt(done, total):
        raise KeyboardInterrupt

    def tasks(dask_scheduler):
        return len(dask_scheduler.tasks)

    from hpdob.simulation import SweepInterrupted

    with pytest.raises(SweepInterrupted) as caught:  # a KeyboardInterrupt
        sweep(base(10.0), grid=grid, scheduler=client, progress=interrupt)
    # issue 27 (rel4): the chunk back before the interrupt is kept, not lost
    assert len(caught.value.rows) == 64 and len(caught.value.missing) == 4000 - 64
    del caught  # the traceback keeps the futures referenced
    deadline = time.monotonic() + 20
    while client.run_on_scheduler(tasks):
        assert time.monotonic() < deadline, "chunks still on the scheduler after the interrupt"
        time.sleep(0.05)


def test_cli_sweep_example(tmp_path, capsys):
    from hpdob.cli import main

    example = Path(__file__).resolve().parents[2] / "examples" / "sweep_bandwidth.toml"
    out = tmp_path / "rows.parquet"
    assert main(["sweep", str(example), "--out", str(out), "--workers", "2"]) == 0
    assert "240 scenarios (240 stable" in capsys.readouterr().out
    rows = pd.read_parquet(out)
    assert len(rows) == 3 * 4 * 20
    assert set(rows["observer.order"]) == {0, 1, 2}
    csv = tmp_path / "rows.csv"
    assert main(["sweep", str(example), "--out", str(csv)]) == 0
    pd.testing.assert_frame_equal(pd.read_csv(csv, keep_default_na=False), rows, check_dtype=False)


def test_cli_sweep_errors(tmp_path, capsys):
    from hpdob.cli import main

    example = Path(__file__).resolve().parents[2] / "examples" / "sweep_bandwidth.toml"
    assert main(["sweep", str(example), "--out", str(tmp_path / "rows.xlsx")]) == 2
    assert "--out must end in .parquet or .csv" in capsys.readouterr().err
    spec = tmp_path / "spec.toml"
    spec.write_text(
        example.read_text().replace('"plant.J" = ["loguniform"', '"plant.K" = ["loguniform"')
    )
    assert main(["sweep", str(spec), "--out", str(tmp_path / "r.csv")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "vary path 'plant.K' is not a sweep parameter; valid paths:" in err
    spec.write_text(example.read_text().replace("[sweep]\nn = 20", "[sweep]\nruns = 20"))
    assert main(["sweep", str(spec), "--out", str(tmp_path / "r.csv")]) == 2
    assert "unknown key sweep.runs = 20" in capsys.readouterr().err


def test_progress_is_silent_off_a_terminal(capsys):
    sweep(base(0.5), grid={"controller.kp": [40.0, 50.0]})  # progress=None, stderr captured
    assert capsys.readouterr().err == ""


def test_progress_bar_when_forced(capsys):
    sweep(base(0.5), grid={"controller.kp": [40.0, 50.0]}, progress=True)
    err = capsys.readouterr().err
    assert "hpdob sweep" in err
    assert "2/2" in err


def test_metric_windows():
    rows = sweep(
        base(2.0),
        grid={"observer.order": [1]},
        metric_windows={"tracking": (0.5, 1.0)},
        progress=False,
    )
    kwargs = {**base(2.0)}
    spec = kwargs.pop("observer")
    kwargs["observer"] = design_observer(kwargs["nominal"].discretize(kwargs["Ts"]), **spec)
    expected = simulate(**kwargs).metrics(tracking=(0.5, 1.0))
    assert rows.loc[0, "rms_position_error_tracking"] == expected["rms_position_error_tracking"]
    assert rows.loc[0, "rms_position_error_regulation"] == expected["rms_position_error_regulation"]
    with pytest.raises(ValueError, match=r"^unknown key metric_windows.settle = "):
        sweep(base(2.0), metric_windows={"settle": (0, 1)}, progress=False)
    with pytest.raises(ValueError, match=r"^metric_windows\['tracking'\] must have start < stop"):
        sweep(base(2.0), metric_windows={"tracking": (1, 0)}, progress=False)


def test_base_duration_is_checked_per_scenario_when_Ts_varies():
    # 0.5 s is no multiple of the base Ts = 0.3 ms, but every scenario has its own Ts.
    rows = sweep({**base(0.5), "Ts": 3e-4}, grid={"Ts": [1e-3, 5e-4]}, progress=False)
    assert rows["stable"].all() and (rows["error"] == "").all()
    with pytest.raises(ValueError, match=r"^duration must be a positive multiple of Ts"):
        sweep({**base(0.5), "Ts": 3e-4}, grid={"observer.order": [0]}, progress=False)


def test_wildly_diverging_scenarios_are_flagged_without_warnings():
    # kd = 1e300 overflows the traces within a few samples; squaring them must not warn
    # (pytest turns warnings into errors) and the row must still be flagged.
    rows = sweep(base(1.0), grid={"controller.kd": [1e12, 1e300]}, progress=False)
    assert not rows["stable"].any()


def test_scenarios_that_share_a_design_design_it_once(monkeypatch):
    import hpdob.simulation._sweep as sweep_module

    calls = []
    real = sweep_module.design_from_spec

    def counted(model, spec):
        calls.append(spec)
        return real(model, spec)

    monkeypatch.setattr(sweep_module, "design_from_spec", counted)
    grid = {"plant.J": list(np.linspace(2e-4, 4e-4, 100))}
    for workers in (1, 2):
        calls.clear()
        sweep_module.clear_kept_designs()  # else the first sweep's design is taken again
        rows = sweep(base(0.2), grid=grid, scheduler=workers, progress=False)
        assert rows["stable"].all()
        # one design for the whole sweep, the up-front check's (the designs are kept across
        # the sweep's chunks and threads, 8 or 16 chunks here, and across sweeps), never one
        # per scenario
        assert len(calls) == 1
    rows = sweep(base(0.2), grid=grid, progress=False)  # again: the kept design, bit for bit
    assert calls == [calls[0]]
    assert rows.equals(sweep(base(0.2), grid=grid, scheduler=1, progress=False))


def test_resume_runs_only_the_missing_scenarios_and_equals_a_run_from_scratch(monkeypatch):
    # issue 27, item 2: the rows a failed dask run kept are completed, not recomputed
    import hpdob.simulation._sweep as module

    grid = {"observer.order": [0, 1], "observer.bandwidth": [60.0, 120.0]}
    vary = {"plant.J": ("loguniform", 2e-4, 5e-4)}
    settings = {"grid": grid, "vary": vary, "n": 2, "seed": 3, "progress": False}
    full = sweep(base(0.5), **settings)
    ran = []
    real = module.run_scenario
    monkeypatch.setattr(module, "run_scenario", lambda b, p, c=None: ran.append(p) or real(b, p, c))
    kept = full.iloc[[0, 3, 4, 7]]
    resumed = sweep(base(0.5), **settings, resume=kept, scheduler=2)
    assert len(ran) == len(full) - len(kept)
    pd.testing.assert_frame_equal(resumed, full)
    ran.clear()
    pd.testing.assert_frame_equal(sweep(base(0.5), **settings, resume=full), full)
    assert ran == []


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"seed": 4}, r"^resume's scenario 0 has plant.J = .*, but this sweep's has .*another"),
        ({"grid": {"observer.order": [0, 1]}}, r"^resume must have this sweep's columns"),
    ],
)
def test_resume_refuses_rows_of_another_sweep(change, match):
    settings = {"grid": {"observer.order": [0, 1], "observer.bandwidth": [60.0, 120.0]},
                "vary": {"plant.J": ("loguniform", 2e-4, 5e-4)}, "n": 2, "seed": 3,
                "progress": False}  # fmt: skip
    rows = sweep(base(0.2), **settings).iloc[:3]
    with pytest.raises(ValueError, match=match):
        sweep(base(0.2), **{**settings, **change}, resume=rows)


def test_resume_refuses_bad_rows():
    settings = {"grid": {"observer.order": [0, 1]}, "progress": False}
    rows = sweep(base(0.2), **settings)
    with pytest.raises(ValueError, match=r"^resume holds scenario 1 twice$"):
        sweep(base(0.2), **settings, resume=pd.concat([rows, rows.iloc[[1]]]))
    with pytest.raises(ValueError, match=r"^resume's scenario must be a whole number from 0 to 1"):
        sweep(base(0.2), **settings, resume=rows.assign(scenario=[0, 5]))
    with pytest.raises(TypeError, match=r"^resume must be the pandas DataFrame .* got list$"):
        sweep(base(0.2), **settings, resume=[])


def test_an_interrupted_sweep_keeps_the_finished_rows_and_resume_completes_it():
    # issue 27 (rel4, item 1): Ctrl-C used to throw away every finished row of a local sweep
    from hpdob.simulation import SweepInterrupted

    settings = {"grid": {"observer.order": [0, 1], "observer.bandwidth": [60.0, 120.0]},
                "vary": {"plant.J": ("loguniform", 2e-4, 5e-4)}, "n": 6, "seed": 3}  # fmt: skip
    full = sweep(base(0.3), **settings, progress=False, scheduler=2)

    def progress(done, total):  # Ctrl-C once the first chunk is back
        raise KeyboardInterrupt

    with pytest.raises(SweepInterrupted) as caught:
        sweep(base(0.3), **settings, progress=progress, scheduler=2)
    interrupt = caught.value
    assert isinstance(interrupt, KeyboardInterrupt) and interrupt.signum == signal.SIGINT
    kept = interrupt.rows
    assert 0 < len(kept) < len(full)  # chunks of 2 scenarios (24 on 2 workers)
    assert sorted([*kept["scenario"], *interrupt.missing]) == list(range(len(full)))
    pd.testing.assert_frame_equal(kept, full[full["scenario"].isin(kept["scenario"])]
                                  .reset_index(drop=True))  # fmt: skip
    resumed = sweep(base(0.3), **settings, progress=False, scheduler=2, resume=kept)
    pd.testing.assert_frame_equal(resumed, full)


def test_sweep_of_a_force_scenario_keeps_its_reaction_observer():
    """A scenario with a [reaction_observer] (a fixed composition, read by the force
    controller's tau_reac input) sweeps over the wall's stiffness; each row is the run."""
    from hpdob.simulation import load_scenario

    path = Path(__file__).resolve().parents[2] / "examples" / "force_step_stiff_wall.toml"
    scenario = load_scenario(path)
    rows = sweep(scenario, grid={"plant.environment.stiffness": [1.0, 10.0]}, progress=False)
    assert rows["stable"].all()
    direct = scenario.simulate().metrics()["rms_estimation_error"]
    assert rows["rms_estimation_error"].iloc[1] == direct


def test_scenarios_with_the_same_plant_parameters_share_one_plant(monkeypatch):
    import hpdob.simulation._sweep as sweep_module

    made = []
    real = sweep_module.replaced_plant

    def counted(plant, changes):
        made.append(dict(changes))
        return real(plant, changes)

    monkeypatch.setattr(sweep_module, "replaced_plant", counted)
    grid = {"plant.J": [2.5e-4, 3.5e-4], "observer.bandwidth": [60.0, 90.0, 120.0]}
    rows = sweep(base(0.2), grid=grid, scheduler=2, progress=False)
    assert rows["stable"].all() and len(rows) == 6
    assert sorted(c["J"] for c in made) == [2.5e-4, 3.5e-4]  # once each, not per scenario
    # the rows are those of runs that make their plant themselves
    single = [
        sweep(base(0.2), grid={"plant.J": [J], "observer.bandwidth": [g]}, progress=False)
        for J in grid["plant.J"]
        for g in grid["observer.bandwidth"]
    ]
    for i, one in enumerate(single):
        for column in METRICS:  # bit for bit (NaN: a window past the run's end)
            assert np.array_equal(rows[column][i], one[column][0], equal_nan=True)
        assert np.isfinite(rows["rms_estimation_error"][i])


def test_cache_keys_tell_signed_zeros_apart():
    from hpdob.simulation._sweep import _frozen

    assert _frozen({"b": 0.0}) != _frozen({"b": -0.0})
    assert _frozen({"b": 1.0}) == _frozen({"b": 1.0}) and _frozen({"b": [1.0]}) is not None
    assert _frozen({"x": frozenset({1, 2})}) is not None and _frozen({"x": {1, 2}}) is None
    assert _frozen({"x": object.__new__(type("U", (), {"__hash__": None}))}) is None


FORCE_STEP = Path(__file__).resolve().parents[2] / "examples" / "force_step_stiff_wall.toml"


def _force_rows(grid, duration=0.6, errors=False, fixed=False):
    """A sweep of the force-step example (its [reaction_observer]: the HPDOb shared as the
    RTOB, the friction model known; ``fixed``: the plant's numbers given as numbers, which a
    sweep may vary), and the loops each row should have run, built by hand."""
    from hpdob.observers import design_reaction_observer
    from hpdob.simulation import load_scenario

    scenario = load_scenario(FORCE_STEP)
    run = {**scenario.run, "duration": duration}
    run.pop("label")
    loop = scenario.loop
    if fixed:  # friction = "plant" read into numbers that stay: viscous = b - b_n, coulomb
        loop = loop.replace(observer=dataclasses.replace(loop.design, follows_plant=False))
    rows = sweep({"loop": loop, **run}, grid=grid, progress=False)
    assert errors or (rows["error"] == "").all(), rows["error"].tolist()

    def direct(nominal=paper.NOMINAL, dob=None, rtob=None, **friction):
        model = nominal.discretize(paper.TS)
        dob = design_observer(model, **{"order": 1, "bandwidth": 100.0, **(dob or {})})
        rtob = None if rtob is None else design_observer(model, **rtob)
        observer = design_reaction_observer(
            dob, rtob, **{"viscous": 5e-5, "coulomb": 0.01, "velocity_filter": 100.0, **friction}
        )
        loop = scenario.loop.replace(nominal=nominal, observer=observer)
        return simulate(loop, **run).metrics()["rms_estimation_error"]

    return rows, direct


def test_sweep_over_the_dob_of_a_force_scenario_redesigns_the_composition():
    """observer.bandwidth and observer.order of a scenario with a [reaction_observer]: each row
    is the run of the composition designed again (the RTOB, the DOb itself, follows it)."""
    rows, direct = _force_rows({"observer.order": [0, 1], "observer.bandwidth": [50.0, 150.0]})
    assert len(set(rows["rms_estimation_error"])) == 4  # every row ran another loop
    for _, row in rows.iterrows():
        expected = direct(dob={"order": int(row["observer.order"]),
                               "bandwidth": row["observer.bandwidth"]})  # fmt: skip
        assert row["rms_estimation_error"] == expected


def test_sweep_over_the_reaction_observer_of_a_force_scenario():
    """reaction_observer.bandwidth gives the RTOB its own design (the DOb's spec at that
    bandwidth; the DOb keeps 100 rad/s); reaction_observer.velocity_filter and .coulomb vary the
    friction model given as numbers (one that is the plant's follows plant.coulomb instead:
    tests/simulation/test_sweep_plant_friction.py)."""
    rows, direct = _force_rows({"reaction_observer.bandwidth": [50.0, 200.0]})
    for _, row in rows.iterrows():
        g = row["reaction_observer.bandwidth"]
        assert row["rms_estimation_error"] == direct(rtob={"order": 1, "bandwidth": g})
    rows, direct = _force_rows({"reaction_observer.velocity_filter": [30.0],
                                "reaction_observer.coulomb": [0.005, 0.02]},
                               fixed=True)  # fmt: skip
    for _, row in rows.iterrows():
        c = row["reaction_observer.coulomb"]
        assert row["rms_estimation_error"] == direct(coulomb=c, velocity_filter=30.0)
    # a bad value is that row's error: a velocity filter without a Coulomb term
    rows, _ = _force_rows({"reaction_observer.coulomb": [0.0, 0.01]}, errors=True, fixed=True)
    assert "velocity_filter = 100.0 filters the Coulomb term's velocity, but coulomb is 0" in (
        rows["error"].iloc[0])  # fmt: skip
    assert rows["error"].iloc[1] == "" and not rows["stable"].iloc[0]


def test_sweep_over_the_nominal_model_keeps_the_rtob_on_the_dobs():
    """nominal.J: DOb and RTOB are designed again on the scenario's nominal model (the rule
    "the RTOB's nominal model is the DOb's" holds in every row)."""
    rows, direct = _force_rows({"nominal.J": [2.5e-4, 3.06e-4]})
    for _, row in rows.iterrows():
        assert row["rms_estimation_error"] == direct(nominal=paper.NOMINAL.replace(
            J=row["nominal.J"]))  # fmt: skip


def test_reaction_observer_paths_that_cannot_apply_are_refused():
    from hpdob.observers import design_eso, design_reaction_observer
    from hpdob.simulation import load_scenario

    with pytest.raises(
        ValueError,
        match=r"^sweep path 'reaction_observer\.bandwidth' does not "
        r"apply to this base: the base has no reaction-torque",
    ):
        sweep(base(), grid={"reaction_observer.bandwidth": [50.0]}, progress=False)
    scenario = load_scenario(FORCE_STEP)
    run = {k: v for k, v in scenario.run.items() if k != "label"}
    model = paper.NOMINAL.discretize(paper.TS)
    dob = design_observer(model, order=1, bandwidth=100.0, measurement="position")
    eso = design_reaction_observer(dob, design_eso(model, bandwidth=200.0), viscous=5e-5)
    loop = scenario.loop.replace(observer=eso, sensor=paper.VIRTUAL_SENSOR)
    with pytest.raises(
        ValueError,
        match=r"'reaction_observer\.order' does not apply to this "
        r"base: an observer spec of type 'eso' has no design "
        r"argument 'order'",
    ):
        sweep({"loop": loop, **run}, grid={"reaction_observer.order": [1]}, progress=False)
    rows = sweep(
        {"loop": loop, **run, "duration": 0.3},
        grid={"reaction_observer.extended_order": [0, 1]},
        progress=False,
    )
    assert (rows["error"] == "").all() and rows["stable"].all()


def test_sweep_spec_of_a_force_scenario_varies_its_observers(tmp_path):
    """A sweep file (hpdob sweep's input) of the force-step example over the DOb's and the
    RTOB's bandwidths: the rows are those of the Python sweep of the loaded scenario."""
    from hpdob.simulation import load_scenario, load_sweep

    path = tmp_path / "spec.toml"
    path.write_text(FORCE_STEP.read_text().replace("duration = 1.0 ", "duration = 0.4 ") + (
        '\n[sweep]\ngrid = { "observer.bandwidth" = [50.0, 100.0], '
        '"reaction_observer.bandwidth" = [200.0] }\n'))  # fmt: skip
    spec, options = load_sweep(path)
    rows = sweep(spec, **options, progress=False)
    scenario = load_scenario(FORCE_STEP)
    run = {**scenario.run, "duration": 0.4}
    run.pop("label")
    again = sweep({"loop": scenario.loop, **run}, grid=options["grid"], progress=False)
    assert rows["error"].tolist() == ["", ""]
    np.testing.assert_array_equal(rows["rms_estimation_error"], again["rms_estimation_error"])


def test_a_composition_of_a_handmade_dob_sweeps_its_friction_only():
    """A composition whose DOb is of no registered family: its design paths are refused, its
    friction model sweeps, and another nominal model is that row's error (the loop refuses a
    DOb designed on another one)."""
    from hpdob import LinearObserver
    from hpdob.observers import design_reaction_observer
    from hpdob.simulation import load_scenario

    scenario = load_scenario(FORCE_STEP)
    run = {k: v for k, v in scenario.run.items() if k != "label"}
    run["duration"] = 0.3
    system = scenario.loop.design.dob.system
    handmade = LinearObserver(F=system.F, G=system.G, H=system.H, E=system.E, N=system.N,
                              Ts=system.Ts, model=system.model)  # fmt: skip
    loop = scenario.loop.replace(observer=design_reaction_observer(handmade, viscous=5e-5))
    with pytest.raises(ValueError, match="the composition's dob is not a design of a known"):
        sweep({"loop": loop, **run}, grid={"observer.bandwidth": [50.0]}, progress=False)
    rows = sweep({"loop": loop, **run}, grid={"reaction_observer.viscous": [0.0, 1e-4]},
                 progress=False)  # fmt: skip
    assert rows["error"].tolist() == ["", ""]
    rows = sweep({"loop": loop, **run}, grid={"nominal.J": [3e-4]}, progress=False)
    assert "must be designed on nominal.discretize(Ts)" in rows["error"].iloc[0]
