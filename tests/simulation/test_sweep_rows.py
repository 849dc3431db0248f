"""A sweep's rows without recorded traces (issue 25): bit for bit ``simulate(...).metrics``.

The sweep runs each scenario whose plant the compiled loop advances (and that has no
environment) through ``run_metrics``: a loop that records only ``tau_hat - tau_dn`` and
``theta - r``, reads the disturbance at the sub-step midpoints from one array per time grid,
and the metrics computed from those by the functions ``SimulationResult`` uses. Each row is
compared here with an independent full ``simulate`` of the same loop, for several loop
structures and every registered observer family.
"""

from __future__ import annotations

import math
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from hpdob import (
    PD,
    PID,
    Actuator,
    Encoder,
    ServoLoop,
    ServoModel,
    SimulationDivergedWarning,
    TwoMassServo,
    paper,
    simulate,
    sweep,
)
from hpdob.signals import Constant, Ramp, Sine, SmoothStep, Step
from hpdob.simulation import _kernel, _result, _simulate
from hpdob.simulation import _sweep as sweep_module

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "observers"))
from family_cases import design, family_specs, spec_id

METRICS = (
    "rms_estimation_error",
    "rms_position_error_regulation",
    "rms_position_error_tracking",
    "max_abs_position_error",
)


def _bits(value) -> bytes:
    return np.float64(value).tobytes()


def _direct(loop: ServoLoop, *, duration, reference, disturbance, windows=None) -> dict:
    """The row's metrics from a full run (every trace recorded) of ``loop``."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SimulationDivergedWarning)
        result = simulate(loop, duration=duration, reference=reference, disturbance=disturbance)
    metrics = result.metrics(**(windows or {}))
    metrics["max_abs_position_error"] = result.max_abs_position_error()
    return {**metrics, "stable": not result.diverged,
            "error": result.message if result.diverged else ""}  # fmt: skip


def _assert_row(row, expected: dict) -> None:
    for name in METRICS:
        assert _bits(row[name]) == _bits(expected[name]), name
    assert row["stable"] == expected["stable"]
    assert row["error"] == expected["error"]


def _canonical(**changes) -> dict:
    kw = paper.scenario()
    kw.update(duration=2.0, observer={"order": 1, "bandwidth": 100.0})
    kw.update(changes)
    return kw


def _loop(kw: dict, **changes) -> ServoLoop:
    parts = {k: kw.get(k) for k in ("plant", "nominal", "Ts", "controller", "observer",
                                    "sensor", "actuator")}  # fmt: skip
    parts.update(changes)
    return ServoLoop(**parts)


def _spy(monkeypatch) -> dict:
    """Counts of the fast and the full runs of the sweep's scenarios."""
    calls = {"fast": 0, "full": 0}
    fast, full = sweep_module.run_metrics, sweep_module.run_loop

    def counted_fast(*args, **kwargs):
        calls["fast"] += 1
        return fast(*args, **kwargs)

    def counted_full(*args, **kwargs):
        calls["full"] += 1
        return full(*args, **kwargs)

    monkeypatch.setattr(sweep_module, "run_metrics", counted_fast)
    monkeypatch.setattr(sweep_module, "run_loop", counted_full)
    return calls


MIXED = (
    Ramp(0.3, 0.02)
    + Constant(-0.01)
    + 2.0 * Step(0.7, 0.03)
    + Sine(0.01, 3.0, start=0.25, phase=0.4, offset=0.002)
)
STRUCTURES = {
    "canonical orders 0-2": ({}, {"observer.order": [0, 1, 2]}),
    "two-mass plant": (
        {"plant": TwoMassServo(J_motor=1.5e-4, J_load=1.5e-4, stiffness=10.0, damping=1e-3)},
        {"observer.order": [0, 1]},
    ),
    "encoder, limit and delay": (
        {"sensor": paper.VIRTUAL_SENSOR, "actuator": paper.VIRTUAL_ACTUATOR},
        {"observer.order": [0, 1]},
    ),
    "noisy encoder, exact velocity": (
        {"sensor": Encoder(4096, noise_std=2e-4, velocity="exact", seed=4)},
        {"observer.order": [1]},
    ),
    "position-only observer": (
        {"observer": {"order": 1, "bandwidth": 100.0, "measurement": "position"}},
        {"observer.bandwidth": [80.0, 160.0]},
    ),
    "no observer": ({"observer": None}, {"plant.J": [2.6e-4, 3.4e-4]}),
    "PID": ({"controller": PID(50.0, 100.0, 5.0)}, {"observer.order": [0, 1]}),
    "disturbance sampled in numpy (SmoothStep)": (
        {"disturbance": SmoothStep(0.05, 0.5, 0.4)},
        {"observer.order": [0, 1]},
    ),
    "no disturbance": ({"disturbance": None}, {"observer.order": [0, 1]}),
    "ramp, constant, step and sine": (
        {"disturbance": MIXED},
        {"observer.order": [1]},
    ),
}


@pytest.mark.parametrize("name", list(STRUCTURES))
def test_rows_are_the_metrics_of_full_runs_bit_for_bit(name, monkeypatch):
    changes, grid = STRUCTURES[name]
    kw = _canonical(**changes)
    calls = _spy(monkeypatch)
    rows = sweep(kw, grid=grid, progress=False, scheduler=1)
    assert calls == {"fast": len(rows), "full": 0}  # no trace was recorded
    (path, values), = grid.items()  # fmt: skip
    for value, (_, row) in zip(values, rows.iterrows(), strict=True):
        loop = sweep_module.scenario_loop(sweep_module._resolve_base(kw), {path: value})
        expected = _direct(loop, duration=kw["duration"], reference=kw["reference"],
                           disturbance=kw["disturbance"])  # fmt: skip
        _assert_row(row, expected)


def test_scaled_disturbances_and_windows_bit_for_bit():
    """``disturbance_scale`` (signed zeros, negative, 1 and others) multiplies the grid's one
    midpoint array as the loop multiplies its table; a run's windows as slices."""
    kw = _canonical(duration=3.0)
    windows = {"regulation": (0.25, 1.7), "tracking": (2.9, 3.5)}
    scales = [1.0, 0.5, -0.0, 0.0, -2.0]
    rows = sweep(kw, grid={"disturbance_scale": scales}, metric_windows=windows, progress=False)
    for scale, (_, row) in zip(scales, rows.iterrows(), strict=True):
        expected = _direct(_loop(kw), duration=3.0, reference=kw["reference"],
                           disturbance=scale * kw["disturbance"], windows=windows)  # fmt: skip
        _assert_row(row, expected)


def test_a_diverging_scenario_has_the_full_runs_metrics_and_message():
    kw = _canonical()
    rows = sweep(kw, grid={"plant.J": [1e-6, 3.06e-4]}, progress=False, scheduler=1)
    assert list(rows["stable"]) == [False, True]
    for J, (_, row) in zip((1e-6, 3.06e-4), rows.iterrows(), strict=True):
        loop = _loop(kw, plant=kw["plant"].replace(J=J))
        _assert_row(row, _direct(loop, duration=2.0, reference=kw["reference"],
                                 disturbance=kw["disturbance"]))  # fmt: skip
    assert "diverged" in rows["error"].iloc[0]


@pytest.mark.parametrize("spec", family_specs(), ids=spec_id)
def test_every_registered_family_sweeps_to_the_metrics_of_its_full_runs(spec):
    """The invariant over the registered families (tests/observers/family_cases.py): for each
    family's variants, a sweep over the true inertia gives each run's metrics bit for bit."""
    kw = _canonical(duration=1.0)
    nominal, Ts = kw["nominal"], kw["Ts"]
    observer = design(nominal.discretize(Ts), spec)
    kw["observer"] = observer
    inertias = [2.6e-4, 3.4e-4]
    rows = sweep(kw, grid={"plant.J": inertias}, progress=False, scheduler=1)
    for J, (_, row) in zip(inertias, rows.iterrows(), strict=True):
        loop = _loop(kw, plant=kw["plant"].replace(J=J), observer=observer)
        _assert_row(row, _direct(loop, duration=1.0, reference=kw["reference"],
                                 disturbance=kw["disturbance"]))  # fmt: skip


def test_plants_with_an_environment_or_advanced_from_python_run_in_full(monkeypatch):
    """Their rows read the contact traces (or the plant is MuJoCo): the full run, as before."""
    from hpdob.simulation import load_scenario

    path = Path(__file__).resolve().parents[2] / "examples" / "force_step_stiff_wall.toml"
    calls = _spy(monkeypatch)
    rows = sweep(load_scenario(path), grid={"plant.environment.stiffness": [10.0]},
                 progress=False)  # fmt: skip
    assert calls == {"fast": 0, "full": 1}
    assert "contact_impact_peak" in rows.columns


def test_run_metrics_reuses_its_scratch_across_lengths_and_equals_run_loop():
    """A thread's scratch arrays are shared by its runs: a long run, a short one and a long
    one again give what separate full runs give (nothing of an earlier run leaks in)."""
    kw = _canonical()
    loop = _loop(kw)
    windows = dict(_result.CANONICAL_WINDOWS)
    for duration in (2.0, 0.5, 1.3, 2.0):
        n = round(duration / loop.Ts)
        signals = _simulate.sample_signals(kw["reference"], kw["disturbance"], Ts=loop.Ts, n=n,
                                           substeps=8)  # fmt: skip
        metrics, diverged, message = _simulate.run_metrics(loop, signals, np.zeros(2),
                                                           windows=windows)  # fmt: skip
        result = _simulate.run_loop(loop, signals, np.zeros(2))
        expected = {**result.metrics(**windows),
                    "max_abs_position_error": result.max_abs_position_error()}  # fmt: skip
        assert {k: _bits(v) for k, v in metrics.items()} == {
            k: _bits(v) for k, v in expected.items()
        }
        assert (diverged, message) == (False, "ok")


def test_long_runs_get_scratch_arrays_of_their_own(monkeypatch):
    """A thread keeps scratch arrays up to SCRATCH_SAMPLES samples; a longer run's are its own
    (a long-lived worker thread holds no more), and its metrics are still the full run's."""
    monkeypatch.setattr(_simulate, "SCRATCH_SAMPLES", 600)
    monkeypatch.setattr(_simulate, "_SCRATCH", type(_simulate._SCRATCH)())
    kw = _canonical()
    loop = _loop(kw)
    windows = {"regulation": (0.1, 0.4), "tracking": (0.4, math.inf)}
    for n in (500, 900, 500):
        signals = _simulate.sample_signals(kw["reference"], kw["disturbance"], Ts=loop.Ts, n=n,
                                           substeps=8)  # fmt: skip
        metrics, _, _ = _simulate.run_metrics(loop, signals, np.zeros(2), windows=windows)
        result = _simulate.run_loop(loop, signals, np.zeros(2))
        assert _bits(metrics["rms_estimation_error"]) == _bits(
            result.metrics(**windows)["rms_estimation_error"]
        )
        assert _simulate._SCRATCH.arrays.shape[1] == 500  # the long run's were not kept


def test_the_error_loop_records_only_the_two_errors():
    """The sweep's loop writes ``position_error`` and ``estimation_error`` (and the delay line
    ``u``), none of a full run's traces; a loop without delay applies ``uk`` itself."""
    kw = _canonical(duration=0.01)
    loop = _loop(kw)
    signals = _simulate.sample_signals(kw["reference"], kw["disturbance"], Ts=loop.Ts, n=10,
                                       substeps=8)  # fmt: skip
    r, _, _, midpoint = _simulate._run_inputs(loop, signals, np.zeros(2))
    full = _kernel.loop_structure(r["plant"], r["ctl"], r["sen"], r["obs"], r["sig"], 2,
                                  midpoint[0], False, False)  # fmt: skip
    errors = (*full[:-2], True, False)
    text = _kernel.loop_source(errors)
    for trace in ("theta", "omega", "theta_m", "omega_m", "tau_hat", "tau_dn", "states"):
        assert f"{trace}[k" not in text, trace
    assert "position_error[k] = th - r_in[k]" in text
    # Eq. (3) at t_k^+, inline: ground_truth's own expression (the Python plant path's), the
    # motor's acceleration for its argument
    import inspect

    body = inspect.getsource(_kernel.ground_truth).strip().splitlines()[-1].strip()
    assert body.startswith("return ")
    inline = body.removeprefix("return ").replace("accel", "(accel / J_motor)")
    assert inline == "uk - b_n * om - J_n * (accel / J_motor)"
    assert f"estimation_error[k] = est - ({inline})" in text
    assert f"tau_dn[k] = {inline}" in _kernel.loop_source(full)
    assert "applied = uk" in text and "u[k - delay]" not in text
    delayed = _kernel.loop_source((*full[:-1], True))
    assert "applied = u[k - delay] if k >= delay else 0.0" in delayed and "tau_dn[k] =" in delayed


@pytest.mark.parametrize(
    "disturbance",
    [
        Step(1.5005, 0.05) + Sine(0.02, 2.0, start=2.5005),
        Ramp(0.1, -0.3) + 0.5 * Constant(0.2) + Sine(0.05, 7.0, phase=1.0, offset=-0.01),
        Step(0.25, -0.1),
    ],
    ids=["canonical", "ramp+constant+sine", "step"],
)
def test_the_midpoint_filler_gives_the_loops_own_values(disturbance):
    """The array one grid's scenarios read equals the disturbance sampled in numpy at the
    midpoints, and a run reading it equals the run evaluating the table inline, trace by
    trace: the same statements, so the same values."""
    kw = _canonical(duration=3.0, disturbance=disturbance)
    loop = _loop(kw)
    n, S = 3000, 8
    signals = _simulate.sample_signals(kw["reference"], disturbance, Ts=loop.Ts, n=n, substeps=S)
    assert signals.midpoint is not None
    filled = sweep_module._midpoints(signals, {}, ("midpoints", loop.Ts, n, S))
    np.testing.assert_array_equal(filled, signals.midpoints())
    inline = _simulate.run_loop(loop, signals, np.zeros(2))
    read = _simulate.run_loop(loop, signals._replace(midpoint=None, tau_mid=filled), np.zeros(2))
    for name in ("theta", "omega", "u", "tau_hat", "tau_dn"):
        np.testing.assert_array_equal(getattr(read, name), getattr(inline, name), err_msg=name)
    scaled = signals.scaled(-0.75)
    np.testing.assert_array_equal(
        sweep_module._midpoints(scaled, {}, ("midpoints", loop.Ts, n, S)), scaled.midpoints()
    )


def test_window_slices_select_what_the_masks_select():
    """``error_metrics(increasing=True)`` (a run's grid): each window a slice found by
    bisection, the same RMS as the mask, empty windows and windows past the run included."""
    rng = np.random.default_rng(7)
    t = np.arange(1000) * 1e-3
    e_est, e_pos = rng.standard_normal(1000), rng.standard_normal(1000) * 1e-3
    cases = [(0.0, 1.0), (0.1234, 0.5), (0.9995, math.inf), (-1.0, 0.0005), (2.0, 3.0),
             (0.5, 0.5000001), (0.001, 0.002)]  # fmt: skip
    for lo, hi in cases:
        for stop in (1000, 733, 1):
            args = (t[:stop], e_est[:stop], e_pos[:stop])
            masked = _result.error_metrics(*args, regulation=(lo, hi), tracking=(0.3, 0.6))
            sliced = _result.error_metrics(*args, regulation=(lo, hi), tracking=(0.3, 0.6),
                                           increasing=True)  # fmt: skip
            assert {k: _bits(v) for k, v in masked.items()} == {
                k: _bits(v) for k, v in sliced.items()
            }


def test_rms_is_numpys_mean_of_the_scaled_squares():
    """``_rms`` sums with ``np.add.reduce`` and divides by the count: what ``np.mean`` does,
    bit for bit, for arrays of every size class of numpy's pairwise sum and for views."""

    def by_mean(values):
        scale = float(np.max(np.abs(values)))
        scaled = values / scale
        np.square(scaled, out=scaled)
        return scale * float(np.sqrt(np.mean(scaled)))

    rng = np.random.default_rng(3)
    for n in [*range(1, 140), 255, 256, 257, 1000, 8191, 8192, 8193, 10000, 65537]:
        values = rng.standard_normal(n + 5) * 10.0 ** rng.integers(-200, 200)
        for x in (values[:n], values[3 : 3 + n]):
            assert _bits(_result._rms(x)) == _bits(by_mean(x)), n
    assert math.isnan(_result._rms(np.zeros(0)))
    assert _result._rms(np.zeros(4)) == 0.0


def test_a_plain_pd_loop_built_by_hand_sweeps_bit_for_bit():
    """A ServoLoop base (not the paper's dict): the rows equal runs of the loop itself."""
    nominal = ServoModel(2.8e-4)
    loop = ServoLoop(plant=ServoModel(3e-4, 4e-5, coulomb=0.004, coulomb_velocity=0.02),
                     nominal=nominal, Ts=1e-3, controller=PD(60.0, 6.0),
                     actuator=Actuator(torque_limit=0.3))  # fmt: skip
    reference, disturbance = SmoothStep(0.1, 0.2, 0.3), Step(0.6, 0.02)
    rows = sweep(loop, grid={"controller.kp": [40.0, 80.0]}, duration=1.0, reference=reference,
                 disturbance=disturbance, progress=False)  # fmt: skip
    for kp, (_, row) in zip((40.0, 80.0), rows.iterrows(), strict=True):
        scenario = loop.replace(controller=PD(kp, 6.0))
        _assert_row(row, _direct(scenario, duration=1.0, reference=reference,
                                 disturbance=disturbance))  # fmt: skip
