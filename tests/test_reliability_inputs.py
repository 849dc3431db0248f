"""Issue 16, items 3-6: inputs that used to escape validation, and work that was unbounded.

Every case here raised a bare OverflowError, UnicodeDecodeError, RecursionError, LinAlgError or
MemoryError, or was silently accepted, before the fix; now each is a ParameterValueError or
ParameterTypeError whose message names the parameter, and a rejected call changes no state.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import hpdob
from hpdob import (
    PD,
    Actuator,
    DisturbanceObserver,
    Encoder,
    ServoLoop,
    ServoModel,
    design_observer,
    estimate,
    initial_state,
    paper,
    robust_stability_map,
    simulate,
    sweep,
    update,
)
from hpdob.signals import Constant, Sine, SmoothStep, Step

HUGE = 10**400  # an int beyond the float range (float(HUGE) raises OverflowError)
PAPER = ServoModel(2.8e-4).discretize(1e-3)


def _loop(**changes):
    kwargs = {
        "plant": ServoModel(3.06e-4),
        "nominal": ServoModel(2.8e-4),
        "Ts": 1e-3,
        "controller": PD(50.0, 5.0),
    }
    kwargs.update(changes)
    return kwargs


# -- item 3: integers beyond the float range, at every entry point ------------------------
OVERFLOW_CASES = {
    "ServoModel J": (lambda: ServoModel(HUGE), r"^J must be a positive finite inertia"),
    "ServoModel b": (lambda: ServoModel(1e-4, HUGE), r"^b must be a non-negative"),
    "ServoModel coulomb": (lambda: ServoModel(1e-4, coulomb=HUGE), r"^coulomb must be"),
    "discretize Ts": (lambda: ServoModel(1e-4).discretize(HUGE), r"^Ts must be a positive"),
    "PD kp": (lambda: PD(HUGE, 1.0), r"^kp must be a non-negative finite gain"),
    "Actuator": (lambda: Actuator(torque_limit=HUGE), r"^torque_limit must be a positive"),
    "Encoder": (lambda: Encoder(HUGE), r"^counts_per_rev must be .* of at most 9007199254740992"),
    "Step": (lambda: Step(0.0, HUGE), r"^amplitude must be a real number"),
    "Constant": (lambda: Constant(HUGE), r"^value must be a real number"),
    "signal scaling": (lambda: Sine(1.0, 1.0) * HUGE, r"^factor must be a finite real factor"),
    "bandwidth": (
        lambda: design_observer(PAPER, order=0, bandwidth=HUGE),
        r"^bandwidth must be a positive finite observer bandwidth",
    ),
    "poles": (lambda: design_observer(PAPER, order=0, poles=[HUGE]), r"^poles must be"),
    "gain_direction": (
        lambda: design_observer(PAPER, order=0, bandwidth=10.0, gain_direction=[HUGE, 1]),
        r"^gain_direction must be",
    ),
    "ServoLoop Ts": (lambda: ServoLoop(**_loop(Ts=HUGE)), r"^Ts must be a positive"),
    "simulate duration": (
        lambda: simulate(**_loop(), duration=HUGE, reference=Step(0.0, 1.0)),
        r"^duration must be a positive finite duration",
    ),
    "simulate x0": (
        lambda: simulate(**_loop(), duration=0.01, reference=Step(0.0, 1.0), x0=(HUGE, 0)),
        r"^x0 must be an initial state",
    ),
    "initial_state tau0": (lambda: initial_state(PAPER_DESIGN, tau0=HUGE), r"^tau0 must be"),
    "estimate x": (
        lambda: estimate(PAPER_DESIGN, (0.0, 0.0), (HUGE, 0.0)),
        r"^x\[0\] \(theta\) must be a finite angle",
    ),
    "update u": (
        lambda: update(PAPER_DESIGN, (0.0, 0.0), (0.0, 0.0), HUGE),
        r"^u must be a finite control torque",
    ),
}
PAPER_DESIGN = design_observer(PAPER, order=1, bandwidth=100.0)


@pytest.mark.parametrize("case", sorted(OVERFLOW_CASES))
def test_integers_beyond_float_range_are_parameter_errors(case):
    call, pattern = OVERFLOW_CASES[case]
    with pytest.raises(ValueError, match=pattern) as info:
        call()
    assert "beyond the float range" in str(info.value) or "at most" in str(info.value)
    assert "\n" not in str(info.value)


def test_overflow_message_abbreviates_the_integer():
    with pytest.raises(ValueError, match=r"got an integer beyond the float range \(1\.000e400\)$"):
        ServoModel(HUGE)
    with pytest.raises(ValueError, match=r"\(about 2\*\*16610\)$"):  # too long to print
        ServoModel(10**5000)


def test_runtime_observer_rejects_overflow_without_changing_state():
    obs = DisturbanceObserver(PAPER, order=1, bandwidth=100.0)
    obs.update((0.1, 0.2), 0.01)
    before = obs.state.copy()
    with pytest.raises(ValueError, match="beyond the float range"):
        obs.update((0.0, 0.0), HUGE)
    np.testing.assert_array_equal(obs.state, before)


def test_huge_integers_in_toml(tmp_path):
    from hpdob.simulation import load_scenario

    text = (
        "Ts = 1e-3\nduration = 0.1\n[plant]\nJ = 1" + "0" * 400 + "\n[nominal]\nJ = 2.8e-4\n"
        '[controller]\nkp = 50.0\nkd = 5.0\n[reference]\ntype = "step"\ntime = 0.0\n'
        "amplitude = 1.0\n"
    )
    path = tmp_path / "big.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=r"^plant\.J must be .*beyond the float range"):
        load_scenario(path)


# -- item 3: signals -------------------------------------------------------------------------
def test_sine_derivative_overflow_is_a_clear_error():
    t = np.array([0.0, 0.25])
    with pytest.raises(ValueError, match=r"^derivative n=2 of Sine\(.*exceeds the float range"):
        Sine(1.0, 1e300).derivative(t, 2)
    with pytest.raises(ValueError, match=r"^derivative n=1000000 of Sine"):
        Sine(1.0, 1.0).derivative(t, 10**6)
    # d^n/dt^n sin(w t) = w^n sin(w t + n pi/2), also for n >= 4 (here n = 5: w^5 cos(w t))
    w = 2 * math.pi * 0.5
    np.testing.assert_allclose(Sine(1.0, 0.5).derivative(t, 5), w**5 * np.cos(w * t), rtol=1e-12)


def test_signal_times_must_be_numbers():
    with pytest.raises(TypeError, match=r"^t must be times \[s\]"):
        Sine(1.0, 1.0)("abc")


# -- item 3: analyze stability --b 0 --values 1e-310,1 ------------------------------------
def test_stability_map_names_the_grid_entry_that_cannot_be_discretised():
    with pytest.raises(ValueError, match=r"^J_ratio entry 1e-310 gives a true plant"):
        robust_stability_map(
            J_ratio=[1e-310, 1.0],
            b=0.0,
            bandwidth=[100.0],
            order=1,
            nominal=ServoModel(2.8e-4),
            Ts=1e-3,
            controller=PD(50.0, 5.0),
        )


# -- item 4: bounded work ---------------------------------------------------------------
def test_sweep_size_is_checked_up_front():
    base = {**paper.scenario(), "duration": 0.1, "observer": {"order": 1, "bandwidth": 100.0}}
    vary = {"plant.J": ("uniform", 2e-4, 4e-4)}
    with pytest.raises(ValueError, match=r"n=10{12} = 10{12} scenarios; at most 1000000"):
        sweep(base, vary=vary, n=10**12, progress=False)
    grid = {"plant.J": np.linspace(2e-4, 4e-4, 10**4), "nominal.J": np.linspace(2e-4, 4e-4, 10**4)}
    with pytest.raises(ValueError, match=r"10000 x 10000 = 100000000 scenarios; at most 1000000"):
        sweep(base, grid=grid, progress=False)


def test_stability_map_caps_delay_and_size():
    kwargs = {
        "J_ratio": [1.0],
        "b": 0.0,
        "bandwidth": [100.0],
        "order": 0,
        "nominal": ServoModel(2.8e-4),
        "Ts": 1e-3,
        "controller": PD(50.0, 5.0),
    }
    with pytest.raises(ValueError, match=r"^delay_samples must be .* of at most 1000, got 1000000"):
        robust_stability_map(**kwargs, delay_samples=10**6)
    grid = np.geomspace(0.1, 10.0, 1001)
    with pytest.raises(ValueError, match=r"1001 x 1001 = 1002001 points; at most 1000000"):
        robust_stability_map(**{**kwargs, "J_ratio": grid, "bandwidth": grid * 100})


# -- item 6: silently accepted ------------------------------------------------------------
def test_complex_disturbance_is_rejected():
    with pytest.raises(ValueError, match=r"^disturbance must be real-valued, got complex"):
        simulate(
            **_loop(),
            duration=0.01,
            reference=Step(0.0, 1.0),
            disturbance=lambda t: np.full(t.shape, 0.1 + 0.1j),
        )


@pytest.mark.parametrize("progress", ["no", 0, 1.0, [True]])
def test_sweep_progress_must_be_bool_none_or_callable(progress):
    base = {**paper.scenario(), "duration": 0.1}
    with pytest.raises(TypeError, match=r"^progress must be None, True, False or a callable"):
        sweep(base, grid={"plant.J": [3e-4]}, progress=progress)


def test_tiny_inertia_blames_the_ratio_not_the_gain_direction():
    with pytest.raises(ValueError, match=r"^the ratio Ts/J = 0\.001 s / 1e-320 kg m\^2 is beyond"):
        ServoModel(1e-320).discretize(1e-3)


def test_functional_core_rejects_bad_states_and_observers():
    state = initial_state(PAPER_DESIGN)
    with pytest.raises(ValueError, match=r"^state must hold finite floats, got \(nan, nan\)"):
        estimate(PAPER_DESIGN, (math.nan, math.nan), (0.0, 0.0))
    with pytest.raises(ValueError, match=r"^state must be a tuple of order \+ 1 = 2 floats"):
        update(PAPER_DESIGN, (0.0, 0.0, 0.0), (0.0, 0.0), 0.0)
    with pytest.raises(TypeError, match=r"^observer must be a DisturbanceObserver.*got str$"):
        estimate("x", state, (0.0, 0.0))
    for x in ({0: 1.0, 1: 2.0}, {1.0, 2.0}):
        with pytest.raises(TypeError, match=r"^x must be a measured state"):
            estimate(PAPER_DESIGN, state, x)


@pytest.mark.parametrize(
    "label", ["../escaped", "a\u0000b", "", ".hidden", "a/b", "..", "c:d", " padded"]
)
def test_labels_that_cannot_name_a_file(label):
    from hpdob._files import check_file_stem

    with pytest.raises(ValueError, match=r"^label .* cannot name an output file"):
        check_file_stem(label)


def test_public_names_unchanged_by_the_fixes():
    assert hpdob.design_observer is design_observer
    assert SmoothStep(0.0, 1.0, 2.0)(np.array([1.0]))[0] == 2.0


# -- the audit of the surfaces on main (benchmarks/reliability_audit.py) ----------------------
LOG_HEADER = "t,qm,vir\n"


def _log_text(n=20):
    return LOG_HEADER + "".join(f"{k * 1e-3!r},{0.001 * k!r},{0.5!r}\n" for k in range(n))


@pytest.mark.parametrize(
    ("payload", "pattern"),
    [
        (_log_text().replace("qm", "q\xe9").encode("latin-1"), r"^log\.csv is not UTF-8 text"),
        (_log_text().encode("utf-16"), r"^log\.csv is not UTF-8 text \(byte 0 is b'\\xff'\)"),
        (bytes(range(256)) * 40, r"^log\.csv is not UTF-8 text"),
        (
            (LOG_HEADER + "1" * 200_000 + ",0,0\n").encode(),
            r"^cannot read log\.csv as CSV: field larger than field limit",
        ),
    ],
    ids=["latin-1", "UTF-16", "binary", "200k-character field"],
)
def test_unreadable_csv_logs_are_one_line_errors(tmp_path, payload, pattern):
    from hpdob.identification import read_log

    path = tmp_path / "log.csv"
    path.write_bytes(payload)
    with pytest.raises(ValueError, match=pattern) as info:
        read_log(path, time="t", position="qm", input="vir")
    assert "\n" not in str(info.value)


def test_corrupt_parquet_message_is_one_line(tmp_path):
    from hpdob.identification import read_log

    path = tmp_path / "log.parquet"
    path.write_bytes(b"PAR1" + bytes(500) + b"PAR1")
    with pytest.raises(ValueError, match=r"^cannot read log\.parquet as Parquet: ") as info:
        read_log(path, time="t", position="qm", input="vir")
    assert "\n" not in str(info.value)


def test_sample_count_beyond_the_float_range():
    with pytest.raises(ValueError, match=r"^duration/Ts = 1e\+308 s / 0\.001 s = inf samples"):
        simulate(**_loop(), duration=1e308, reference=Step(0.0, 1.0))


@pytest.mark.parametrize(("J", "Ts"), [(2.8e-4, 1e-320), (1e308, 1e-3)])
def test_gains_that_overflow_are_refused(J, Ts):
    model = ServoModel(J).discretize(Ts)
    with pytest.raises(ValueError, match=r"^the gains L_i = k_i d / \(d\^T D_Dn\) overflow"):
        design_observer(model, order=1, bandwidth=100.0)


@pytest.mark.parametrize(
    ("payload", "pattern"),
    [
        ("Ts = 1e-3\n".encode("utf-16"), r"is not UTF-8 text \(it looks like UTF-16; byte 0"),
        ("# caf\xe9\nTs = 1e-3\n".encode("latin-1"), r"is not UTF-8 text \(byte 5 is b'\\xe9'\)"),
        (("x = " + "{a = " * 500 + "1" + "}" * 500 + "\n").encode(), r"nests tables or arrays"),
    ],
    ids=["UTF-16", "Latin-1", "500 nested inline tables"],
)
def test_unreadable_scenario_files(tmp_path, payload, pattern):
    from hpdob.simulation import load_scenario

    path = tmp_path / "s.toml"
    path.write_bytes(payload)
    with pytest.raises(ValueError, match=pattern) as info:
        load_scenario(path)
    assert "\n" not in str(info.value)


def test_cli_stability_map_with_a_subnormal_ratio(capsys, tmp_path):
    from hpdob.cli import main

    argv = ["analyze", "stability", "--b", "0", "--values", "1e-310,1", "--out", str(tmp_path)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("hpdob analyze: error: J_ratio entry 1e-310 gives a true plant")
    assert err.count("\n") == 1 and list(tmp_path.iterdir()) == []


def test_overflowing_signals_are_reported_by_time_without_warnings():
    from hpdob.signals import Constant

    with pytest.raises(ValueError, match=r"^disturbance is not finite at t = 0\.0 s"):
        simulate(
            **_loop(), duration=0.01, reference=Step(0.0, 1.0),
            disturbance=Constant(1e308) + Constant(1e308),
        )  # fmt: skip
    with pytest.raises(ValueError, match=r"^frequency must be a positive frequency \[Hz\] whose"):
        Sine(1.0, 1e308)


def test_written_files_have_the_usual_permissions(tmp_path):
    """Atomic writes go through mkstemp (mode 0600); the renamed file must get the mode a plain
    open() would give it under the process's umask, so that others can read the results."""
    import os
    import stat

    from hpdob import ServoModel, design_observer, export_c

    old = os.umask(0o022)
    try:
        paths = export_c(design_observer(ServoModel(2.8e-4).discretize(1e-3), order=1,
                                         bandwidth=100.0), tmp_path)  # fmt: skip
    finally:
        os.umask(old)
    for path in paths:
        assert stat.S_IMODE(path.stat().st_mode) == 0o644, path
