"""Tests of hpdob.export_c: the generated C99 is compiled with gcc and driven side by side with
the Python DisturbanceObserver. A double build must reproduce it bit for bit (and so within the
issue's 1e-12); a float build must stay within the rounding-error bound derived in
docs/deployment.md (hpdob.testing.export_error_bound), computed independently of the C code
from the design.
"""

from __future__ import annotations

import re
import shutil
import struct
import subprocess
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

import hpdob
from hpdob import (
    DisturbanceObserver,
    ParameterTypeError,
    ParameterValueError,
    ServoModel,
    design_observer,
    export_c,
    paper,
)
from hpdob.export import render_c
from hpdob.testing import (
    STRICT_FLAGS,
    CBuildError,
    CObserver,
    compile_c,
    export_error_bound,
    find_compiler,
    sanitized_run,
    sanitizer_available,
)

ROOT = Path(__file__).resolve().parents[2]
MODEL = paper.NOMINAL.discretize(
    paper.TS
)  # the canonical nominal model: J_n = 2.8e-4, b_n = 0, 1 ms
ORDERS = (0, 1, 2, 3)
DTYPES = ("double", "float")
N_RANDOM = 100_000

needs_cc = pytest.mark.skipif(
    find_compiler() is None,
    reason="no C compiler (gcc, or $CC) is installed, so the generated C cannot be built",
)


@dataclass
class Build:
    design: object
    header: Path
    source: Path
    c: CObserver


@pytest.fixture(scope="module")
def build(tmp_path_factory):
    """``build(order, dtype, direction)``: export (bandwidth 100 rad/s), compile, load; cached."""
    cache: dict = {}

    def get(order, dtype, direction=(1.0, 1.0)):
        key = (order, dtype, tuple(direction))
        if key not in cache:
            design = design_observer(MODEL, order=order, bandwidth=100.0, gain_direction=direction)
            out = tmp_path_factory.mktemp(f"order{order}_{dtype}")
            header, source = export_c(design, out, dtype=dtype)
            c = CObserver(
                header, source, prefix="dob", dtype=dtype, order=order, build_dir=out / "lib"
            )
            cache[key] = Build(design, header, source, c)
        return cache[key]

    return get


def python_run(design, theta, omega, u, init=(0.0, 0.0, 0.0)):
    """The Python reference: DisturbanceObserver driven sample by sample; (tau_hat, states)."""
    obs = DisturbanceObserver.from_design(design, x0=init[:2], tau0=init[2])
    n = len(theta)
    tau_hat, z = np.empty(n), np.empty((n, design.order + 1))
    for k, (th, om, uk) in enumerate(zip(theta.tolist(), omega.tolist(), u.tolist(), strict=True)):
        z[k] = obs.state
        tau_hat[k] = obs.estimate((th, om))
        obs.update((th, om), uk)
    return tau_hat, z


@pytest.fixture(scope="module")
def random_trace():
    rng = np.random.default_rng(20261123)
    theta = rng.normal(scale=2.0, size=N_RANDOM)  # rad
    omega = rng.normal(scale=50.0, size=N_RANDOM)  # rad/s
    u = rng.normal(scale=0.2, size=N_RANDOM)  # N m
    return theta, omega, u, {}  # the dict caches the Python reference per order


def reference_for(random_trace, design):
    theta, omega, u, cache = random_trace
    if design.order not in cache:
        cache[design.order] = python_run(design, theta, omega, u)
    return cache[design.order]


def assert_within_bound(design, dtype, theta, omega, u, tau_c, z_c, tau_ref, init=(0, 0, 0)):
    err = np.abs(tau_c - tau_ref)
    bound = export_error_bound(design, dtype, theta, omega, u, z_c, init=init)
    worst = int(np.argmax(np.divide(err, bound, out=np.zeros_like(err), where=bound > 0)))
    assert np.all(err <= bound), (
        f"sample {worst}: |error| {err[worst]:.3g} > bound {bound[worst]:.3g}"
    )
    return err, bound


# -- what is generated ---------------------------------------------------------------------
def test_header_records_design_and_sample_loop(tmp_path):
    design = design_observer(ServoModel(3.06e-4, 5e-5).discretize(1e-3), order=1, poles=[0.9, 0.8])
    header, source = export_c(design, tmp_path / "out", prefix="axis", dtype="float")
    assert (header, source) == (tmp_path / "out" / "axis.h", tmp_path / "out" / "axis.c")
    text = header.read_text()
    for needle in (
        f"hpdob {hpdob.__version__}",
        "J_n = 0.000306 kg m^2, b_n = 5e-05 N m s/rad",
        "Ts = 0.001 s",
        "order           1 (HPDOb",
        "poles           0.9, 0.8",
        "gain direction  (1.0, 1.0)",
        "scalar type     float",
        "typedef struct {\n    float z[2];\n} axis_state;",
        "void axis_init(axis_state *s, float theta0, float omega0, float tau0);",
        "float axis_estimate(const axis_state *s, float theta, float omega);",
        "void axis_update(axis_state *s, float theta, float omega, float u);",
        "#define AXIS_ORDER 1",
    ):
        assert needle in text, needle
    loop = text[text.index("Sample loop") :]
    assert loop.index("axis_estimate(&s") < loop.index("u = u_outer + tau_hat")
    assert loop.index("u = u_outer + tau_hat") < loop.index("axis_update(&s")
    includes = re.findall(r"#include\s*(\S+)", text + source.read_text())
    assert includes == ['"axis.h"'], "the code must need no header but its own"


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("direction", [(1.0, 1.0), (0.0, 1.0)])
def test_constants_read_back_exactly(dtype, direction):
    design = design_observer(MODEL, order=3, bandwidth=150.0, gain_direction=direction)
    _, source = render_c(design, dtype=dtype)
    found = dict(re.findall(rf"static const {dtype} (\w+) = ([^;]+);", source))
    zero = re.search(r"exactly zero, their terms are left out: ([\w, ]+)", source)
    zero = zero.group(1).strip().split(", ") if zero else []
    expected = {}
    for i in range(4):
        expected[f"K{i + 1}"] = design.k[i]
        expected[f"L{i + 1}_THETA"], expected[f"L{i + 1}_OMEGA"] = design.gains[i]
        expected[f"KX{i + 1}_THETA"], expected[f"KX{i + 1}_OMEGA"] = design.state_input[i]
        expected[f"KU{i + 1}"] = design.control_input[i]
    # Every constant is either printed or exactly zero; L_i for i <= m only serve _init.
    assert set(found) | set(zero) == set(expected)
    assert zero == ([] if direction[0] else [n for n in expected if n.endswith("THETA")])
    for name in zero:
        assert expected[name] == 0.0
    for name, text in found.items():
        if dtype == "double":
            assert float(text) == expected[name], name
        else:
            assert text.endswith("f")
            as_single = struct.unpack("f", struct.pack("f", float(text[:-1])))[0]
            assert as_single == np.float32(expected[name]), name


def test_observer_and_design_export_the_same_code(tmp_path):
    obs = DisturbanceObserver(MODEL, order=2, bandwidth=120.0)
    obs.update((0.3, 1.0), 0.2)  # the runtime state is not part of the export
    a = export_c(obs, tmp_path / "a")
    b = export_c(obs.design, tmp_path / "b")
    assert [p.read_text() for p in a] == [p.read_text() for p in b]


# -- bad input -----------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("kwargs", "error", "needle"),
    [
        ({"dtype": "single"}, ParameterValueError, "dtype must be one of 'double', 'float', 'q31'"),
        ({"dtype": None}, ParameterValueError, "dtype must be one of 'double', 'float'"),
        ({"prefix": "1dob"}, ParameterValueError, "prefix must be a C identifier"),
        ({"prefix": "my-dob"}, ParameterValueError, "got 'my-dob'"),
        ({"prefix": "_dob"}, ParameterValueError, "starting with a letter"),
        ({"prefix": ""}, ParameterValueError, "prefix must be a C identifier"),
        ({"prefix": "a" * 23}, ParameterValueError, "at most 22 characters"),
        ({"prefix": 3}, ParameterTypeError, "prefix must be a str"),
    ],
)
def test_bad_arguments_raise_and_write_nothing(tmp_path, kwargs, error, needle):
    target = tmp_path / "out"
    with pytest.raises(error, match=re.escape(needle)):
        export_c(design_observer(MODEL, order=1, bandwidth=100.0), target, **kwargs)
    assert not target.exists()


def test_bad_observer_and_directory(tmp_path):
    design = design_observer(MODEL, order=0, bandwidth=100.0)
    with pytest.raises(
        ParameterTypeError,
        match="obs must be a DisturbanceObserver, an ObserverDesign or another observer",
    ):
        export_c(MODEL, tmp_path)
    with pytest.raises(ParameterTypeError, match="directory must be a path"):
        export_c(design, None)
    a_file = tmp_path / "file"
    a_file.write_text("keep me")
    with pytest.raises(ParameterValueError, match="directory must be a directory"):
        export_c(design, a_file)
    assert a_file.read_text() == "keep me"


def test_float_rejects_unrepresentable_constants(tmp_path):
    # J = 1e-45 kg m^2 puts |D_Dn| near 1e42, so the gains L_i ~ 1e-43 underflow binary32.
    design = design_observer(ServoModel(J=1e-45).discretize(1e-3), order=0, bandwidth=100.0)
    with pytest.raises(ParameterValueError, match="dtype 'float' cannot hold the constant"):
        export_c(design, tmp_path / "out", dtype="float")
    assert not (tmp_path / "out").exists()
    assert all(p.exists() for p in export_c(design, tmp_path / "out", dtype="double"))


# -- it builds, warning-free and freestanding ----------------------------------------------
@needs_cc
@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("direction", [(1.0, 1.0), (0.0, 1.0), (1.0, 0.0)])
def test_compiles_warning_free_and_freestanding(tmp_path, order, dtype, direction):
    design = design_observer(MODEL, order=order, bandwidth=100.0, gain_direction=direction)
    _, source = export_c(design, tmp_path, dtype=dtype)
    nm = shutil.which("nm")
    for level in ("-O0", "-O2", "-Os"):
        # -nostdinc: no standard header at all; -ffreestanding: no hosted library assumed.
        flags = (*STRICT_FLAGS, level, "-ffreestanding", "-nostdinc", "-c")
        obj = compile_c([source], tmp_path / f"dob{level}.o", flags=flags)
        if nm is not None:
            done = subprocess.run([nm, "-u", str(obj)], capture_output=True, text=True)
            assert done.returncode == 0 and done.stdout.strip() == "", done.stdout


@needs_cc
@pytest.mark.skipif(shutil.which("g++") is None, reason="g++ is not installed")
def test_header_links_from_cpp(tmp_path):
    """C++ firmware includes the header as is (extern "C") and links the C object."""
    design = design_observer(MODEL, order=1, bandwidth=100.0)
    _, source = export_c(design, tmp_path, prefix="ax", dtype="float")
    obj = compile_c([source], tmp_path / "ax.o", flags=(*STRICT_FLAGS, "-c"))
    main_cpp = tmp_path / "main.cpp"
    main_cpp.write_text(
        '#include "ax.h"\n'
        "int main() { ax_state s; ax_init(&s, 0.0f, 0.0f, 0.5f);\n"
        "  return ax_estimate(&s, 0.0f, 0.0f) == 0.5f ? 0 : 1; }\n"
    )
    exe = tmp_path / "main"
    cmd = ["g++", "-Wall", "-Wextra", "-Werror", "-I", str(tmp_path), str(main_cpp), str(obj)]
    done = subprocess.run([*cmd, "-o", str(exe)], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    assert subprocess.run([str(exe)], check=False).returncode == 0


# -- verified against the Python reference -------------------------------------------------
@needs_cc
@pytest.mark.parametrize("order", ORDERS)
def test_double_matches_python_bit_for_bit_on_random_samples(build, random_trace, order):
    b = build(order, "double")
    theta, omega, u, _ = random_trace
    tau_ref, z_ref = reference_for(random_trace, b.design)
    tau_c, z_c = b.c.drive(theta, omega, u)
    scale = np.max(np.abs(tau_ref))
    np.testing.assert_allclose(tau_c, tau_ref, rtol=1e-12, atol=1e-12 * scale)
    assert np.array_equal(tau_c, tau_ref) and np.array_equal(z_c, z_ref)


@needs_cc
@pytest.mark.parametrize("order", ORDERS)
def test_float_within_derived_bound_on_random_samples(build, random_trace, order):
    b = build(order, "float")
    theta, omega, u, _ = random_trace
    tau_ref, _ = reference_for(random_trace, b.design)
    tau_c, z_c = b.c.drive(theta, omega, u)
    err, bound = assert_within_bound(b.design, "float", theta, omega, u, tau_c, z_c, tau_ref)
    # It really is binary32 arithmetic, and the bound is not vacuous: somewhere the error
    # reaches more than 1 % of it.
    assert np.max(err / np.maximum(np.abs(tau_ref), 1.0)) > 2.0**-30
    assert np.max(err / bound) > 0.01


@needs_cc
@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("dtype", DTYPES)
def test_per_sample_api_with_initial_state(build, rng, order, dtype):
    """init/estimate/update called one by one through ctypes, as firmware calls them."""
    b = build(order, dtype)
    theta0, omega0, tau0 = 0.25, -3.0, 0.04  # exactly representable in binary32
    b.c.init(theta0, omega0, tau0)
    # init: the state of a constant tau0 at rest, so the estimate there returns tau0.
    assert b.c.estimate(theta0, omega0) == pytest.approx(
        tau0, abs=1e-15 if dtype == "double" else 1e-6
    )
    obs = DisturbanceObserver.from_design(b.design, x0=(theta0, omega0), tau0=tau0)
    n = 2000
    theta, omega = rng.normal(scale=2.0, size=n), rng.normal(scale=50.0, size=n)
    u = rng.normal(scale=0.2, size=n)
    tau_c, tau_ref, z_c = np.empty(n), np.empty(n), np.empty((n, order + 1))
    for k in range(n):
        th, om, uk = float(theta[k]), float(omega[k]), float(u[k])
        z_c[k] = b.c.state
        tau_c[k], tau_ref[k] = b.c.estimate(th, om), obs.estimate((th, om))
        assert b.c.state == tuple(z_c[k]), "estimate must not change the state"
        b.c.update(th, om, uk)
        obs.update((th, om), uk)
    if dtype == "double":
        assert np.array_equal(tau_c, tau_ref)
        assert b.c.state == tuple(obs.state)
    else:
        init = (theta0, omega0, tau0)
        assert_within_bound(b.design, dtype, theta, omega, u, tau_c, z_c, tau_ref, init)


CANONICAL = [
    ("DOb-100", 0),
    ("HPDOb-100", 1),
    ("virtual-experiment", 1),
    ("order-2", 2),
    ("order-3", 3),
]


@pytest.fixture(scope="module")
def canonical_traces():
    cache = {}

    def get(name, order):
        if name not in cache:
            if name.startswith("order-"):
                obs = DisturbanceObserver(MODEL, order=order, bandwidth=100.0)
                result = paper.run("HPDOb-100", observer=obs.design, label=name)
            else:
                result = paper.run(name)
            assert not result.diverged
            cache[name] = result
        return cache[name]

    return get


@needs_cc
@pytest.mark.parametrize(("name", "order"), CANONICAL)
@pytest.mark.parametrize("dtype", DTYPES)
def test_canonical_closed_loop_traces(build, canonical_traces, name, order, dtype):
    """The measurements and torques of hpdob's canonical runs, fed to C and to Python."""
    result = canonical_traces(name, order)
    b = build(order, dtype)
    theta, omega, u = result.theta_measured, result.omega_measured, result.u
    tau_ref, _ = python_run(b.design, theta, omega, u)
    tau_c, z_c = b.c.drive(theta, omega, u)
    if dtype == "double":
        assert np.array_equal(tau_c, tau_ref)
        scale = np.max(np.abs(result.tau_hat))
        np.testing.assert_allclose(tau_c, result.tau_hat, rtol=1e-12, atol=1e-12 * scale)
    else:
        assert_within_bound(b.design, dtype, theta, omega, u, tau_c, z_c, tau_ref)


@needs_cc
@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("dtype", DTYPES)
def test_closed_loop_with_the_c_observer_in_the_loop(build, order, dtype):
    """Nominal discrete plant, constant 0.03 N m load, PD + the C estimate as the torque."""
    b = build(order, dtype)
    A, B, D = MODEL.A.tolist(), MODEL.B.tolist(), MODEL.D.tolist()
    load, n = 0.03, 3000
    obs = DisturbanceObserver.from_design(b.design)
    b.c.init(0.0, 0.0, 0.0)
    theta = omega = 0.0
    rec = np.empty((n, 3))
    tau_c, tau_ref, z_c = np.empty(n), np.empty(n), np.empty((n, order + 1))
    for k in range(n):
        z_c[k] = b.c.state
        tau_c[k] = b.c.estimate(theta, omega)
        tau_ref[k] = obs.estimate((theta, omega))
        u = 2.8e-4 * (400.0 * (1.0 - theta) - 40.0 * omega) + tau_c[k]
        b.c.update(theta, omega, u)
        obs.update((theta, omega), u)
        rec[k] = theta, omega, u
        theta, omega = (
            A[0][0] * theta + A[0][1] * omega + B[0] * u - D[0] * load,
            A[1][0] * theta + A[1][1] * omega + B[1] * u - D[1] * load,
        )
    if dtype == "double":
        assert np.array_equal(tau_c, tau_ref)
        # On the nominal plant every order estimates a constant load exactly once settled.
        assert abs(tau_c[-1] - load) < 1e-12
    else:
        _, bound = assert_within_bound(b.design, dtype, *rec.T, tau_c, z_c, tau_ref)
        assert abs(tau_c[-1] - load) < bound[-1] + 1e-12
    # The load is rejected: the servo sits at 1 rad (the PD alone would leave 0.27 rad); in
    # float, up to the estimate's rounding error over the PD stiffness J_n kp = 0.112 N m/rad.
    assert abs(theta - 1.0) < (1e-9 if dtype == "double" else 1e-3)


@pytest.fixture(scope="module")
def sanitizer(tmp_path_factory):
    reason = sanitizer_available(tmp_path_factory.mktemp("probe"))
    if reason is not None:
        pytest.skip(f"-fsanitize=address,undefined is unavailable here: {reason}")


@needs_cc
@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("dtype", DTYPES)
def test_sanitized_build_runs_clean(build, random_trace, sanitizer, tmp_path, order, dtype):
    b = build(order, dtype)
    theta, omega, u, _ = random_trace
    tau_s, z_s = sanitized_run(
        b.source,
        prefix="dob",
        dtype=dtype,
        order=order,
        build_dir=tmp_path,
        theta=theta,
        omega=omega,
        u=u,
    )
    tau_c, z_c = b.c.drive(theta, omega, u)
    assert np.array_equal(tau_s, tau_c) and np.array_equal(z_s, z_c)
    if dtype == "double":
        assert np.array_equal(tau_s, reference_for(random_trace, b.design)[0])


@needs_cc
def test_sanitizer_catches_a_planted_out_of_bounds_read(sanitizer, tmp_path):
    design = design_observer(MODEL, order=1, bandwidth=100.0)
    _, source = export_c(design, tmp_path / "src")
    text = source.read_text()
    planted = text.replace("return s->z[1]", "return s->z[1 + (theta > 1e300 ? 0 : 1)]")
    assert planted != text
    source.write_text(planted)
    n = 10
    with pytest.raises(CBuildError, match=r"(AddressSanitizer|runtime error)"):
        sanitized_run(
            source,
            prefix="dob",
            dtype="double",
            order=1,
            build_dir=tmp_path / "b",
            theta=np.zeros(n),
            omega=np.zeros(n),
            u=np.zeros(n),
        )


# -- float over long runs: the drift with (1, 1) and the remedy (0, 1) ---------------------
def rotation_trace(n, theta0, speed):
    """A trajectory of the nominal plant (b = 0) turning at ``speed`` +- 5 rad/s under the load
    0.05 + 0.02 sin(4 pi t) N m: omega is chosen, u and theta follow from eq. (8)."""
    t = np.arange(n + 1) * paper.TS
    omega = speed + 5.0 * np.sin(2.0 * np.pi * t)
    tau = 0.05 + 0.02 * np.sin(4.0 * np.pi * t[:-1])
    u = tau + paper.NOMINAL.J * np.diff(omega) / paper.TS
    steps = np.cumsum(paper.TS * (omega[:-1] + omega[1:]) / 2.0)
    theta = theta0 + np.concatenate([[0.0], steps[:-1]])
    return theta, omega[:-1], u, (theta[0], omega[0], tau[0])


@needs_cc
@pytest.mark.parametrize("order", [0, 1])
def test_float_drift_grows_with_position_and_velocity_direction_removes_it(build, order):
    n = 3000
    errors = {}
    for direction in [(1.0, 1.0), (0.0, 1.0)]:
        b = build(order, "float", direction)
        for theta0 in (0.0, 1e4, 1e5):
            theta, omega, u, init = rotation_trace(n, theta0, speed=20.0)
            tau_ref, _ = python_run(b.design, theta, omega, u, init)
            tau_c, z_c = b.c.drive(theta, omega, u, init=init)
            err, _ = assert_within_bound(
                b.design, "float", theta, omega, u, tau_c, z_c, tau_ref, init
            )
            errors[direction, theta0] = err.max(), tau_c
    # (1, 1): the error grows with the absolute angle (theta <= 60 rad vs 1e4 and 1e5 rad).
    assert errors[(1.0, 1.0), 1e4][0] > 20 * errors[(1.0, 1.0), 0.0][0]
    assert errors[(1.0, 1.0), 1e5][0] > 5 * errors[(1.0, 1.0), 1e4][0]
    # (0, 1): theta does not enter at all, so the float estimates are identical at any angle,
    # and far below the (1, 1) error there.
    short = errors[(0.0, 1.0), 0.0]
    for theta0 in (1e4, 1e5):
        assert np.array_equal(errors[(0.0, 1.0), theta0][1], short[1])
        assert errors[(0.0, 1.0), theta0][0] < errors[(1.0, 1.0), theta0][0] / 20


@needs_cc
def test_float_continuous_rotation_past_1e4_rad(build):
    """HPDOb turning at 200 rad/s for 60 s: theta grows from 0 to 1.2e4 rad in one run."""
    theta, omega, u, init = rotation_trace(60_000, 0.0, speed=200.0)
    assert theta[-1] > 1.19e4
    first, last = slice(0, 2000), slice(-2000, None)  # theta < 400 rad, theta > 1.16e4 rad
    worst = {}
    for direction in [(1.0, 1.0), (0.0, 1.0)]:
        b = build(1, "float", direction)
        tau_ref, _ = python_run(b.design, theta, omega, u, init)
        tau_c, z_c = b.c.drive(theta, omega, u, init=init)
        err, _ = assert_within_bound(b.design, "float", theta, omega, u, tau_c, z_c, tau_ref, init)
        worst[direction] = err[first].max(), err[last].max()
    assert worst[1.0, 1.0][1] > 10 * worst[1.0, 1.0][0]  # drifts with theta
    assert worst[0.0, 1.0][1] < 2 * worst[0.0, 1.0][0]  # stays at its short-run level
    assert worst[0.0, 1.0][1] < worst[1.0, 1.0][1] / 10
