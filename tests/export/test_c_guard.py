"""Issue 16, item 8: the exported C observer's opt-in NaN guard, and prefixes that would
shadow the C standard headers.

Without the guard one NaN measurement makes the C state NaN until ``_init`` (documented in
docs/deployment.md, and shown below). With ``export_c(..., nan_guard=True)`` a sample with a
non-finite input, or whose result would overflow, is skipped: the state is unchanged,
``_estimate`` returns the last estimate from finite inputs, and ``s.fault``/``s.skipped``
say so. The reference here is the Python observer (the functional core) with the same
skipping rule written out; a double build must match it bit for bit on the finite samples.
"""

from __future__ import annotations

import math
import shutil
import subprocess

import numpy as np
import pytest

from hpdob import LinearObserver, design_observer, estimate, export_c, initial_state, paper, update
from hpdob.export import render_c
from hpdob.testing import (
    STRICT_FLAGS,
    CObserver,
    compile_c,
    find_compiler,
    sanitized_run,
    sanitizer_available,
)

MODEL = paper.NOMINAL.discretize(paper.TS)
ORDERS = (0, 1, 2, 3)
needs_cc = pytest.mark.skipif(find_compiler() is None, reason="no C compiler (gcc or $CC)")


# -- prefixes --------------------------------------------------------------------------------
# ISO/IEC 9899:1999, 7.1.2: the 24 standard headers of C99; ISO/IEC 9899:2011, 7.1.2 adds 5.
C99_HEADERS = (
    "assert", "complex", "ctype", "errno", "fenv", "float", "inttypes", "iso646", "limits",
    "locale", "math", "setjmp", "signal", "stdarg", "stdbool", "stddef", "stdint", "stdio",
    "stdlib", "string", "tgmath", "time", "wchar", "wctype",
)  # fmt: skip
C11_HEADERS = ("stdalign", "stdatomic", "stdnoreturn", "threads", "uchar")


@pytest.mark.parametrize("prefix", [*C99_HEADERS, *C11_HEADERS, "Math", "STDIO"])
def test_prefixes_that_shadow_standard_headers_are_refused(tmp_path, prefix):
    design = design_observer(MODEL, order=1, bandwidth=100.0)
    with pytest.raises(ValueError, match=rf"^prefix '{prefix}' would write {prefix}\.h, which"):
        export_c(design, tmp_path, prefix=prefix)
    assert list(tmp_path.iterdir()) == []
    render_c(design, prefix=f"{prefix}_dob")  # as part of a longer name it is fine


def test_nan_guard_must_be_a_bool():
    design = design_observer(MODEL, order=1, bandwidth=100.0)
    with pytest.raises(TypeError, match=r"^nan_guard must be True or False, got 'yes'"):
        render_c(design, nan_guard="yes")


def test_unguarded_export_is_unchanged_by_the_option():
    design = design_observer(MODEL, order=2, bandwidth=100.0)
    assert render_c(design) == render_c(design, nan_guard=False)
    header, source = render_c(design, nan_guard=True)
    assert "#define DOB_NAN_GUARD 1" in header and "int fault;" in header
    assert "dob_finite" in source
    assert [line for line in source.splitlines() if "#include" in line] == ['#include "dob.h"']


# -- the reference: the Python observer with the guard's rule written out ---------------------
def guarded_reference(system, theta, omega, u, init=(0.0, 0.0, 0.0)):
    """``(tau_hat, states, skipped, fault)`` of the guard applied to the Python observer."""
    state, last, skipped, fault = initial_state(system, init[:2], init[2]), init[2], 0, 0
    tau, states = [], []
    for th, om, uk in zip(theta.tolist(), omega.tolist(), u.tolist(), strict=True):
        states.append(state)
        inputs_ok = all(math.isfinite(v) for v in (th, om))
        y = estimate(system, state, (th, om)) if inputs_ok else math.nan
        if inputs_ok and math.isfinite(y):
            last, fault = y, 0
        else:
            fault = 1
        tau.append(last)
        nxt = update(system, state, (th, om), uk) if inputs_ok and math.isfinite(uk) else None
        if nxt is not None and all(math.isfinite(v) for v in nxt):
            state, fault = nxt, 0
        else:
            skipped, fault = skipped + 1, 1
    return np.array(tau), np.array(states), skipped, fault


def poisoned_trace(n=5000, seed=7):
    rng = np.random.default_rng(seed)
    theta = rng.normal(scale=2.0, size=n)
    omega = rng.normal(scale=50.0, size=n)
    u = rng.normal(scale=0.2, size=n)
    theta[[100, 101, 2500]] = math.nan
    omega[[700, 3000]] = [math.inf, -math.inf]
    u[[1200, 4000]] = [math.nan, math.inf]
    theta[1800] = 1e308  # finite and huge: used (the gains are below 1, nothing overflows)
    return theta, omega, u


def build_guarded(tmp_path_factory, design, dtype, tag):
    """``(design, source, CObserver)`` of ``design`` exported with the NaN guard."""
    out = tmp_path_factory.mktemp(tag)
    header, source = export_c(design, out, dtype=dtype, nan_guard=True)
    c = CObserver(
        header, source, prefix="dob", dtype=dtype, observer=design,
        build_dir=out / "lib", nan_guard=True,
    )  # fmt: skip
    return design, source, c


@pytest.fixture(scope="module")
def guarded(tmp_path_factory):
    cache = {}

    def get(order, dtype):
        if (order, dtype) not in cache:
            design = design_observer(MODEL, order=order, bandwidth=100.0)
            cache[order, dtype] = build_guarded(
                tmp_path_factory, design, dtype, f"guard{order}{dtype}"
            )
        return cache[order, dtype]

    return get


@needs_cc
@pytest.mark.parametrize("order", ORDERS)
def test_double_guard_skips_bad_samples_and_matches_python(guarded, order):
    design, _, c = guarded(order, "double")
    theta, omega, u = poisoned_trace()
    tau_c, z_c = c.drive(theta, omega, u, init=(0.1, 0.0, 0.02))
    tau_r, z_r, _, _ = guarded_reference(design.system, theta, omega, u, init=(0.1, 0.0, 0.02))
    assert np.all(np.isfinite(tau_c)) and np.all(np.isfinite(z_c))
    np.testing.assert_array_equal(z_c, z_r)  # bit for bit, skipped samples included
    np.testing.assert_array_equal(tau_c, tau_r)
    bad = ~(np.isfinite(theta) & np.isfinite(omega) & np.isfinite(u))
    skipped = np.flatnonzero(bad[:-1])
    np.testing.assert_array_equal(z_c[skipped + 1], z_c[skipped])  # state unchanged


@needs_cc
@pytest.mark.parametrize("order", [0, 3])
@pytest.mark.parametrize("dtype", ["double", "float"])
def test_guard_flags_per_call(guarded, order, dtype):
    _, _, c = guarded(order, dtype)
    c.init(0.0, 0.0, 0.05)
    assert (c.fault, c.skipped) == (0, 0)
    good = c.estimate(0.0, 0.0)
    assert good == pytest.approx(0.05, abs=1e-6) and c.fault == 0
    state = c.state
    assert c.estimate(math.nan, 0.0) == good and c.fault == 1  # the last good estimate
    c.update(0.0, math.inf, 0.0)
    assert c.state == state and (c.fault, c.skipped) == (1, 1)
    c.update(0.0, 0.0, math.nan)
    assert c.state == state and c.skipped == 2
    c.update(0.01, 0.0, 0.0)
    assert c.state != state and c.fault == 0 and c.skipped == 2
    c.init(math.nan, 0.0, 0.0)  # a bad init: the zero state, flagged
    assert c.state == (0.0,) * (order + 1) and c.fault == 1 and c.skipped == 0
    assert c.estimate(0.0, 0.0) == 0.0 and c.fault == 0


@needs_cc
def test_results_that_would_overflow_are_skipped(tmp_path):
    # J_n = 1e290 kg m^2: D_Dn ~ 2e-294, so the gains L ~ 1e292 and L theta overflows
    huge = design_observer(
        paper.NOMINAL.replace(J=1e290).discretize(paper.TS), order=1, bandwidth=100.0
    )
    header, source = export_c(huge, tmp_path, nan_guard=True)
    c = CObserver(
        header, source, prefix="dob", dtype="double", observer=huge,
        build_dir=tmp_path / "b", nan_guard=True,
    )  # fmt: skip
    c.init(0.0, 0.0, 1.0)
    state = c.state
    assert c.estimate(1e20, 0.0) == 1.0 and c.fault == 1  # the estimate would be -inf
    c.update(1e20, 0.0, 0.0)
    assert c.state == state and (c.fault, c.skipped) == (1, 1)
    c.init(1e20, 0.0, 0.0)  # the reset would overflow: the zero state, flagged
    assert c.state == (0.0, 0.0) and c.fault == 1


@needs_cc
def test_without_the_guard_one_nan_poisons_the_state(tmp_path):
    design = design_observer(MODEL, order=1, bandwidth=100.0)
    header, source = export_c(design, tmp_path)
    c = CObserver(header, source, prefix="dob", dtype="double", order=1, build_dir=tmp_path / "b")
    n = 50
    theta = np.zeros(n)
    theta[10] = math.nan
    tau, _ = c.drive(theta, np.zeros(n), np.zeros(n))
    assert np.all(np.isfinite(tau[:10])) and np.all(np.isnan(tau[11:]))  # until _init


@needs_cc
@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("dtype", ["double", "float"])
def test_guarded_code_compiles_warning_free_and_freestanding(tmp_path, order, dtype):
    design = design_observer(MODEL, order=order, bandwidth=100.0, gain_direction=(0.0, 1.0))
    _, source = export_c(design, tmp_path, dtype=dtype, nan_guard=True)
    nm = shutil.which("nm")
    for level in ("-O0", "-O2", "-Os"):
        flags = (*STRICT_FLAGS, level, "-ffreestanding", "-nostdinc", "-c")
        obj = compile_c([source], tmp_path / f"dob{level}.o", flags=flags)
        if nm is not None:
            done = subprocess.run([nm, "-u", str(obj)], capture_output=True, text=True)
            assert done.returncode == 0 and done.stdout.strip() == "", done.stdout


@pytest.fixture(scope="module")
def sanitizer(tmp_path_factory):
    reason = sanitizer_available(tmp_path_factory.mktemp("probe"))
    if reason is not None:
        pytest.skip(f"-fsanitize=address,undefined is unavailable here: {reason}")


@needs_cc
@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("dtype", ["double", "float"])
def test_guard_under_the_sanitizers(guarded, sanitizer, tmp_path, order, dtype):
    design, source, c = guarded(order, dtype)
    theta, omega, u = poisoned_trace()
    tau_s, z_s = sanitized_run(
        source, prefix="dob", dtype=dtype, observer=design, build_dir=tmp_path,
        theta=theta, omega=omega, u=u,
    )  # fmt: skip
    tau_c, z_c = c.drive(theta, omega, u)
    assert np.array_equal(tau_s, tau_c) and np.array_equal(z_s, z_c)
    assert np.all(np.isfinite(tau_s)) and np.all(np.isfinite(z_s))


def _with_velocity():
    """The DOb with a second output, a velocity estimate (here the measured velocity)."""
    dob = design_observer(MODEL, order=0, bandwidth=200.0).system
    return LinearObserver(
        F=dob.F, G=dob.G, H=np.vstack([dob.H, [[0.0]]]),
        E=np.vstack([dob.E, [[0.0, 1.0, 0.0]]]), N=dob.N, Ts=dob.Ts,
        outputs=("tau_hat", "omega_hat"), model=MODEL,
    )  # fmt: skip


@needs_cc
def test_guard_keeps_the_last_velocity_estimate(tmp_path):
    system = _with_velocity()
    header, source = export_c(system, tmp_path, nan_guard=True)
    assert "double dob_velocity(dob_state *s" in header.read_text()
    c = CObserver(
        header, source, prefix="dob", dtype="double", observer=system,
        build_dir=tmp_path / "b", nan_guard=True,
    )  # fmt: skip
    c.init(0.0, 2.0, 0.0)
    assert c.velocity(math.nan, 3.0) == 2.0 and c.fault == 1  # omega0 of init
    assert c.velocity(0.0, 3.0) == 3.0 and c.fault == 0
    assert c.velocity(0.0, math.inf) == 3.0 and c.fault == 1


# -- the other families: position-only, ESO, Kalman (issue 16's leftover) -----------------------
def _families():
    from hpdob.observers import design_eso, design_kalman

    return {
        "position m=1": design_observer(MODEL, order=1, bandwidth=100.0, measurement="position"),
        "position m=2, g_v": design_observer(
            MODEL, order=2, bandwidth=80.0, measurement="position", velocity_bandwidth=300.0
        ),
        "ESO m=0 current": design_eso(MODEL, bandwidth=200.0),
        "GESO m=1 predictive": design_eso(
            MODEL, bandwidth=150.0, extended_order=1, form="predictive"
        ),
        "Kalman m=0": design_kalman(MODEL, position_noise_std=1e-4, process_noise_std=1e-3),
        "Kalman m=1": design_kalman(
            MODEL, order=1, position_noise_std=1e-4, process_noise_std=1e-5
        ),
    }


FAMILIES = tuple(_families())


def guarded_position_reference(system, theta, u, init=(0.0, 0.0, 0.0)):
    """:func:`guarded_reference` for an observer that measures the angle alone."""
    state, last, skipped, fault = initial_state(system, init[:2], init[2]), init[2], 0, 0
    tau, states = [], []
    for th, uk in zip(theta.tolist(), u.tolist(), strict=True):
        states.append(state)
        y = estimate(system, state, th) if math.isfinite(th) else math.nan
        if math.isfinite(y):
            last, fault = y, 0
        else:
            fault = 1
        tau.append(last)
        nxt = update(system, state, th, uk) if math.isfinite(th) and math.isfinite(uk) else None
        if nxt is not None and all(math.isfinite(v) for v in nxt):
            state, fault = nxt, 0
        else:
            skipped, fault = skipped + 1, 1
    return np.array(tau), np.array(states), skipped, fault


def position_trace(n=3000, seed=11):
    """A plausible encoder trace (small angles, torques) with non-finite samples in it."""
    rng = np.random.default_rng(seed)
    theta = np.cumsum(rng.normal(scale=1e-3, size=n))
    u = rng.normal(scale=0.02, size=n)
    theta[[50, 51, 1700]] = math.nan
    theta[900] = math.inf
    u[[400, 2200]] = [math.nan, -math.inf]
    return theta, u


@pytest.fixture(scope="module")
def guarded_family(tmp_path_factory):
    designs, cache = _families(), {}

    def get(name, dtype):
        if (name, dtype) not in cache:
            cache[name, dtype] = build_guarded(tmp_path_factory, designs[name], dtype, "family")
        return cache[name, dtype]

    return get


@needs_cc
@pytest.mark.parametrize("name", FAMILIES)
def test_guard_of_the_other_families_matches_python(guarded_family, name):
    design, _, c = guarded_family(name, "double")
    theta, u = position_trace()
    init = (0.01, 0.0, 0.005)
    tau_c, z_c = c.drive(theta, np.zeros_like(theta), u, init=init)
    tau_r, z_r, _, _ = guarded_position_reference(design.system, theta, u, init=init)
    assert np.all(np.isfinite(tau_c)) and np.all(np.isfinite(z_c))
    np.testing.assert_array_equal(z_c, z_r)  # bit for bit, skipped samples included
    np.testing.assert_array_equal(tau_c, tau_r)
    bad = np.flatnonzero(~(np.isfinite(theta) & np.isfinite(u))[:-1])
    np.testing.assert_array_equal(z_c[bad + 1], z_c[bad])  # the state is left as it was
    # per call: a NaN angle returns the last estimate and velocity, flags, skips the update
    c.init(0.0, 0.5, 0.01)
    tau, omega = c.estimate(0.0), c.velocity(0.0)
    state = c.state
    assert c.estimate(math.nan) == tau and c.velocity(math.inf) == omega and c.fault == 1
    c.update(math.nan, 0.0)
    assert c.state == state and (c.fault, c.skipped) == (1, 1)
    c.update(1e-4, 0.0)
    assert c.state != state and c.fault == 0


@needs_cc
@pytest.mark.parametrize("name", FAMILIES)
@pytest.mark.parametrize("dtype", ["double", "float"])
def test_guard_of_the_other_families_under_the_sanitizers(
    guarded_family, sanitizer, tmp_path, name, dtype
):
    design, source, c = guarded_family(name, dtype)
    theta, u = position_trace()
    omega = np.zeros_like(theta)
    tau_s, z_s = sanitized_run(
        source, prefix="dob", dtype=dtype, observer=design, build_dir=tmp_path,
        theta=theta, omega=omega, u=u,
    )  # fmt: skip
    tau_c, z_c = c.drive(theta, omega, u)
    assert np.array_equal(tau_s, tau_c) and np.array_equal(z_s, z_c)
    assert np.all(np.isfinite(tau_s)) and np.all(np.isfinite(z_s))
