"""Fixed-point export (``export_c(..., dtype="q31")``): the Python model, the host C build and the
Cortex-M0+/M3 builds (``zig cc`` + ``unicorn``) compute the same integers, and the result stays
within the derived bound of the exact observer on a closed-loop run with encoder, friction and
disturbance (docs/deployment.md, "Fixed point").
"""

from __future__ import annotations

import importlib.util
import math

import numpy as np
import pytest
from toolchains import needs_host_cc, needs_zig

from hpdob import (
    Actuator,
    DisturbanceObserver,
    Encoder,
    ParameterTypeError,
    ParameterValueError,
    design_observer,
    export_c,
    paper,
    simulate,
)
from hpdob.export import (
    FixedPointDesign,
    FixedPointObserver,
    fixed_point_design,
    fixed_point_error_bound,
    render_c,
)
from hpdob.observers import design_eso, design_kalman, kalman_process_noise
from hpdob.signals import Sine, Step
from hpdob.testing import (
    CBuildError,
    EmulatedCortexM,
    HostFixedObserver,
    cross_compile,
    export_error_bound,
    find_compiler,
    fixed_drive_source,
    float_step_source,
    read_elf,
    zig_cc,
)

MODEL = paper.NOMINAL.discretize(paper.TS)
CPR = 16384
RANGES = {"counts_per_rev": CPR, "omega_max": 50.0, "u_max": 0.5, "tau_max": 0.5}
N_RUN = 100_000
N_EMULATED = 2_000
CPUS = ("cortex-m0plus", "cortex-m3")
_R = 2 * math.pi / CPR / math.sqrt(12)  # encoder quantisation noise [rad]

FAMILIES = {
    **{f"dob-{m}": (lambda m=m: design_observer(MODEL, order=m, bandwidth=100.0))
       for m in range(3)},
    **{f"position-{m}": (lambda m=m: design_observer(MODEL, order=m, bandwidth=150.0,
                                                     measurement="position")) for m in range(3)},
    **{f"eso-{m}": (lambda m=m: design_eso(MODEL, bandwidth=150.0, extended_order=m))
       for m in range(3)},
    **{f"kalman-{m}": (lambda m=m: design_kalman(
        MODEL, order=m, position_noise_std=_R,
        process_noise_std=kalman_process_noise(MODEL, order=m, bandwidth=100.0,
                                               position_noise_std=_R))) for m in range(3)},
}  # fmt: skip


@pytest.fixture(scope="module")
def closed_loop():
    """100 s of the paper's plant (Coulomb friction) in closed loop with the HPDOb-100: 16384
    count encoder, torque limit, step and sinusoidal load: the logged encoder counts,
    measured velocity and applied torque (10^5 samples)."""
    kwargs = paper.scenario()
    kwargs.update(
        observer=paper.observer("HPDOb-100").design,
        sensor=Encoder(CPR),
        actuator=Actuator(torque_limit=0.444),
        reference=Sine(1.0, 0.3) + Sine(0.5, 1.7),
        disturbance=Step(1.5, 0.05) + Sine(0.02, 2.0, start=2.5),
        duration=N_RUN * paper.TS,
        substeps=8,
    )
    run = simulate(**kwargs)
    counts = np.rint(run.theta_measured / (2 * math.pi / CPR)).astype(np.int64)
    return counts, run.omega_measured, run.u


@pytest.fixture(scope="module", params=list(FAMILIES))
def family(request):
    design = FAMILIES[request.param]()
    return request.param, design, fixed_point_design(design, **RANGES)


def _double_reference(fx, counts, omega, u, init):
    """The double observer (generated Python, = hpdob.update bit for bit) on the same
    quantised inputs: outputs and states per sample."""
    system = fx.system
    reset, outputs, _, update = system.python
    theta = counts * fx.radians_per_count
    s = reset(init[0] * fx.radians_per_count, init[1] * fx.lsb("omega0"),
              init[2] * fx.lsb("tau_hat"))  # fmt: skip
    ys, zs = [], []
    two = fx.measures_omega
    for th, om, v in zip(theta.tolist(), omega.tolist(), u.tolist(), strict=True):
        zs.append(s)
        meas = (th, om) if two else (th,)
        ys.append(outputs(s, *meas))
        s = update(s, *meas, v)
    return np.array(ys), np.array(zs), theta


def _inputs(fx, closed_loop):
    counts, omega, u = closed_loop
    return counts, fx.to_int("omega0", omega), fx.to_int("u", u)


def test_fixed_point_matches_model_and_double_within_bound(family, closed_loop, tmp_path):
    name, _design, fx = family
    counts, W, U = _inputs(fx, closed_loop)
    init = (int(counts[0]), 0, 0)
    model = FixedPointObserver(fx, *init)
    Y, S = model.run(counts, W, U)
    # 1. the host C build computes the same integers (outputs and states) at every sample
    if find_compiler() is not None or importlib.util.find_spec("ziglang") is not None:
        _, source = export_c(fx, tmp_path / "c", dtype="q31")
        Yc, Sc = HostFixedObserver(fx, source, prefix="dob", build_dir=tmp_path / "b").drive(
            counts, W, U, init=init)  # fmt: skip
        assert np.array_equal(Y, Yc), name
        assert np.array_equal(S, Sc), name
    # 2. against the double observer: within the derived bound at every sample
    ref, z, theta = _double_reference(fx, counts, fx.to_real("omega0", W), fx.to_real("u", U),
                                      init)  # fmt: skip
    for r, out in enumerate(fx.system.outputs):
        assert np.abs(Y[:, r]).max() < fx.output[r].limit, "no output saturates on this run"
        error = np.abs(fx.to_real(out, Y[:, r]) - ref[:, r])
        bound = fixed_point_error_bound(fx, counts, W, U, S, init=init, output=r)
        bound += export_error_bound(fx.system, "double", theta, fx.to_real("omega0", W),
                                    fx.to_real("u", U), z, init=(theta[0], 0.0, 0.0),
                                    output=r)  # fmt: skip
        assert np.all(error <= bound), (name, out, float((error / bound).max()))
        if r == 0:  # and it is not vacuous: the worst sample reaches 18-53 % of it
            assert (error / bound).max() > 0.1, name
        assert error.max() <= fx.error_bound[r], (name, out)  # the a-priori bound holds too
    # the estimate is useful: its error stays below 2 % of the 0.05 N m load it estimates
    assert np.abs(fx.to_real("tau_hat", Y[:, 0]) - ref[:, 0]).max() < 1e-3


def test_states_stay_within_the_proven_bounds_for_any_input(family, rng):
    """Saturating random int32 inputs: no state comes near its word limit, and every state
    stays below its proven bound (so no row can overflow: the accumulators are checked from
    the tables in the next test)."""
    _, _, fx = family
    n = 20_000
    counts = rng.integers(-(2**31), 2**31, n)
    W, U = rng.integers(-(2**31), 2**31, n), rng.integers(-(2**31), 2**31, n)
    _, S = FixedPointObserver(fx, 0, 2**31 - 1, -(2**31) + 1).run(counts, W, U)
    lsb = np.array([fx.lsb(f"q{i + 1}") for i in range(fx.system.n_states)])
    assert np.all(np.abs(S) * lsb <= fx.state_bound)
    assert np.all(np.abs(S) < 2**31 - 1)


def test_accumulators_fit_for_every_input(family):
    """From the integer tables alone: with every state at the full int32 range and the inputs
    at their saturation limits, every row's sum stays below 2^62 (the C's offset rounding
    needs it) and every coefficient fits int32."""
    _, _, fx = family
    n = fx.system.n_states
    vmax = [2**31 - 1] * n + [fx.delta_max]
    vmax += [fx.limit("omega")] if fx.measures_omega else []
    vmax += [fx.limit("u")]
    for rows, bounds in ((fx.update, vmax), (fx.output, vmax),
                         (fx.reset, [fx.limit("omega0"), fx.limit("tau_hat")])):  # fmt: skip
        for row in rows:
            total = sum(abs(c) * 2**k * bounds[j] for c, j, k in row.terms)
            total += 2 ** (row.shift - 1) if row.shift else 0
            assert total < 2**62, row.target
            assert all(abs(c) <= 2**31 - 1 for c, _, _ in row.terms)
            assert 0 <= row.shift <= 62


def test_state_bound_is_attained_by_a_worst_case_input():
    """The l1 part of the state bound is tight: the input that follows the sign of the impulse
    response (the worst case for state 2 of the HPDOb at sample 400, from rest) drives the
    fixed-point state to that part of the bound, computed here by an independent loop, and
    not beyond the whole bound."""
    fx = fixed_point_design(FAMILIES["dob-1"](), **RANGES)
    F, G = fx.real["Fh"], fx.real["Gh"]
    i, k = 1, 400
    limits = np.array([fx.delta_max, fx.limit("omega"), fx.limit("u")])
    signs, l1 = np.zeros((k, 3)), 0.0
    X = G.copy()
    for j in range(k):  # sample k - 1 - j reaches state i through F^j G
        signs[k - 1 - j] = np.sign(X[i])
        l1 += float(np.abs(X[i]) @ (limits * fx.real["inputs_lsb"]))
        X = F @ X
    ints = (signs * limits).astype(np.int64)
    counts = np.cumsum(ints[:, 0])
    _, S = FixedPointObserver(fx, 0, 0, 0).run(np.append(counts, counts[-1]),
                                               np.append(ints[:, 1], 0),
                                               np.append(ints[:, 2], 0))  # fmt: skip
    reached = abs(S[-1, i]) * fx.lsb(f"q{i + 1}")
    assert reached <= fx.state_bound[i]
    assert reached == pytest.approx(l1, rel=1e-6)


def test_multi_turn_counts_wrap_around_int32(closed_loop, tmp_path):
    """Only count differences enter: the same run shifted to cross the int32 wrap of the
    counter gives bit-identical estimates (Python model and C), and the double observer fed
    the unwrapped angle (8e5 rad) agrees within the bound."""
    fx = fixed_point_design(FAMILIES["dob-1"](), **RANGES)
    counts, W, U = _inputs(fx, closed_loop)
    counts, W, U = counts[:20_000], W[:20_000], U[:20_000]
    offset = 2**31 - 1 - int(counts.max()) + 3  # the counter wraps during the run
    shifted = (counts + offset + 2**31) % 2**32 - 2**31
    assert shifted.min() < 0 < shifted.max()
    Y0, S0 = FixedPointObserver(fx, int(counts[0]), 0, 0).run(counts, W, U)
    Y1, S1 = FixedPointObserver(fx, int(shifted[0]), 0, 0).run(shifted, W, U)
    assert np.array_equal(Y0, Y1)
    assert np.array_equal(S0, S1)
    theta = (counts + offset) * fx.radians_per_count
    obs = DisturbanceObserver(MODEL, order=1, bandwidth=100.0)
    obs.reset(x0=(theta[0], 0.0), tau0=0.0)
    ref = np.empty(theta.size)
    omega, u = fx.to_real("omega", W), fx.to_real("u", U)
    for k in range(theta.size):
        ref[k] = obs.estimate((theta[k], omega[k]))
        obs.update((theta[k], omega[k]), u[k])
    error = np.abs(fx.to_real("tau_hat", Y1[:, 0]) - ref)
    bound = fixed_point_error_bound(fx, shifted, W, U, S1, init=(int(shifted[0]), 0, 0),
                                    theta=theta)  # fmt: skip
    # the double observer's own rounding at 8e5 rad (L_theta theta ~ 1e6 N m inside it)
    bound += 1e-15 * np.abs(theta) * np.abs(obs.design.system.G[:, 0]).max() * 1e3
    assert np.all(error <= bound)
    if find_compiler() is not None:
        _, source = export_c(fx, tmp_path / "c", dtype="q31")
        Yc, _ = HostFixedObserver(fx, source, prefix="dob", build_dir=tmp_path / "b").drive(
            shifted, W, U, init=(int(shifted[0]), 0, 0))  # fmt: skip
        assert np.array_equal(Yc, Y1)


def test_the_estimate_does_not_depend_on_a_constant_angle_offset(family):
    """The property the count-difference form rests on: H d + E_theta = 0 (zero DC gain from
    the angle to every output), here to rounding for every family, and a double observer
    started and driven at theta + 1000 rad estimates what it estimates at theta."""
    name, _design, fx = family
    assert np.all(fx.shift_residual < 1e-9), name
    rng = np.random.default_rng(3)
    theta = np.cumsum(rng.normal(0, 1e-3, 300))
    omega, u = rng.normal(0, 1, 300), rng.normal(0, 0.05, 300)
    system = fx.system
    reset, outputs, _, update = system.python
    runs = []
    for shift in (0.0, 1000.0):
        s = reset(theta[0] + shift, 0.0, 0.0)
        ys = []
        for k in range(300):
            meas = (theta[k] + shift, omega[k])[: len(system.measures)]
            ys.append(outputs(s, *meas)[0])
            s = update(s, *meas, u[k])
        runs.append(np.array(ys))
    scale = np.abs(system.G[:, 0]).max() * 1000.0
    assert np.abs(runs[0] - runs[1]).max() < 1e-11 * max(scale, 1.0), name


@pytest.fixture(scope="module")
def target_builds(tmp_path_factory):
    """Every design's q31 export, prefix ``obs<i>``, in one image per core (one zig run each)
    and as separate object files."""
    root = tmp_path_factory.mktemp("target")
    sources, drives = [], []
    for i, name in enumerate(FAMILIES):
        fx = fixed_point_design(FAMILIES[name](), **RANGES)
        _, source = export_c(fx, root / name, prefix=f"obs{i}", dtype="q31")
        drive = root / name / f"obs{i}_drive.c"
        drive.write_text(fixed_drive_source(fx, f"obs{i}"))
        sources.append(source)
        drives.append(drive)
    builds = {}
    for cpu in CPUS:
        objects = root / f"objects-{cpu}"
        objects.mkdir()
        cross_compile(sources, objects, cpu=cpu, link=False)
        elf = cross_compile([*sources, *drives], root / f"{cpu}.elf", cpu=cpu)
        builds[cpu] = (elf, objects)
    return builds


@needs_zig
@pytest.mark.parametrize("cpu", CPUS)
def test_cortex_m_builds_match_the_model_bit_for_bit(family, closed_loop, target_builds, cpu):
    name, _, fx = family
    prefix = f"obs{list(FAMILIES).index(name)}"
    counts, W, U = _inputs(fx, closed_loop)
    sl = slice(1500, 1500 + N_EMULATED)  # around the load step
    counts, W, U = counts[sl], W[sl], U[sl]
    init = (int(counts[0]), 0, 0)
    elf, objects = target_builds[cpu]
    Ye, Se = EmulatedCortexM(elf, cpu=cpu).drive_fixed(fx, prefix, counts, W, U, init=init)
    Y, S = FixedPointObserver(fx, *init).run(counts, W, U)
    assert np.array_equal(Y, Ye), (name, cpu)
    assert np.array_equal(S, Se), (name, cpu)
    # the object file of the observer alone: integer code, no floating-point helper
    undefined = read_elf(objects / f"{prefix}.o").undefined()
    assert not [s for s in undefined if s.startswith(("__aeabi_f", "__aeabi_d"))], undefined
    assert undefined == (["__aeabi_lmul"] if cpu == "cortex-m0plus" else [])


@needs_zig
def test_the_symbol_check_sees_float_helpers_and_the_emulator_the_isa(tmp_path):
    """The symbol check is not vacuous: a float export compiled for the M3 calls
    __aeabi_fadd/fmul. (unicorn's Cortex-M0 model does not refuse ARMv7-M instructions -- an
    M3 image runs on it -- so the ARMv6-M code of the M0+ build rests on zig's -mcpu; the
    emulator checks its arithmetic.)"""
    design = FAMILIES["dob-1"]()
    _, source = export_c(design, tmp_path / "f", dtype="float")
    obj = cross_compile([source], tmp_path / "f.o", cpu="cortex-m3", link=False)
    assert {"__aeabi_fadd", "__aeabi_fmul"} <= set(read_elf(obj).undefined())
    fx = fixed_point_design(design, **RANGES)
    _, source = export_c(fx, tmp_path / "q", dtype="q31")
    (tmp_path / "q" / "dob_drive.c").write_text(fixed_drive_source(fx, "dob"))
    elf = cross_compile([source, tmp_path / "q" / "dob_drive.c"], tmp_path / "m3.elf",
                        cpu="cortex-m3")  # fmt: skip
    counts = np.arange(10)
    m3 = EmulatedCortexM(elf, cpu="cortex-m3").drive_fixed(fx, "dob", counts, counts, counts)
    m0 = EmulatedCortexM(elf, cpu="cortex-m0plus").drive_fixed(fx, "dob", counts, counts, counts)
    assert np.array_equal(m3[0], m0[0])
    step = tmp_path / "f" / "dob_step.c"
    step.write_text(float_step_source("dob", "float", ("theta", "omega")))
    assert "dob_step" in step.read_text()


@needs_host_cc
def test_q15_is_exact_but_not_accurate_enough(tmp_path, rng):
    """q15 (int16 words, int32 sums) runs the same arithmetic bit for bit, but its derived
    error bound is far too large for orders >= 1 (docs/deployment.md says so)."""
    fx = fixed_point_design(FAMILIES["dob-0"](), word="q15", counts_per_rev=4096,
                            omega_max=20.0, u_max=0.5, tau_max=0.5)  # fmt: skip
    assert fx.bits == 16
    _, source = export_c(fx, tmp_path / "c", dtype="q15")
    counts = np.cumsum(rng.integers(-10, 10, 3000))
    W, U = rng.integers(-(2**15), 2**15, 3000), rng.integers(-(2**15), 2**15, 3000)
    Y, S = FixedPointObserver(fx).run(counts, W, U)
    Yc, Sc = HostFixedObserver(fx, source, prefix="dob", build_dir=tmp_path / "b").drive(
        counts, W, U)  # fmt: skip
    assert np.array_equal(Y, Yc)
    assert np.array_equal(S, Sc)
    hpdob1 = fixed_point_design(FAMILIES["dob-1"](), word="q15", **RANGES)
    assert hpdob1.error_bound[0] > 0.05  # larger than the load it should estimate


# -- bad input ----------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("kwargs", "error", "needle"),
    [
        ({"counts_per_rev": 2**40, "omega_max": 1e3}, ParameterValueError, "counts_per_rev"),
        ({"counts_per_rev": 0}, ParameterValueError, "counts_per_rev"),
        ({"counts_per_rev": 1.5}, ParameterTypeError, "counts_per_rev"),
        ({"omega_max": -1.0}, ParameterValueError, "omega_max"),
        ({"u_max": float("nan")}, ParameterValueError, "u_max"),
        ({"tau_max": 1e-300}, ParameterValueError, "tau_max"),
        ({"tau_max": "big"}, ParameterTypeError, "tau_max"),
        ({"word": "q7"}, ParameterValueError, "word"),
    ],
)
def test_bad_ranges_name_the_parameter(kwargs, error, needle):
    args = {**RANGES, **kwargs}
    with pytest.raises(error, match=needle) as info:
        fixed_point_design(FAMILIES["dob-1"](), **args)
    assert "\n" not in str(info.value)


def test_q15_refuses_an_encoder_it_cannot_scale():
    with pytest.raises(ParameterValueError, match="counts_per_rev = 8388608 cannot be scaled"):
        fixed_point_design(FAMILIES["dob-0"](), word="q15", **{**RANGES, "counts_per_rev": 2**23})


def test_unrepresentable_design_is_refused():
    """A design whose gains span more than the accumulator can hold: the ESO of order 2 at a
    very low bandwidth (its states are scaled derivatives)."""
    with pytest.raises(ParameterValueError, match="cannot be represented") as info:
        fixed_point_design(design_eso(MODEL, bandwidth=150.0, extended_order=2),
                           **{**RANGES, "tau_max": 1e-6, "u_max": 1e3})  # fmt: skip
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"dtype": "q31"}, "ranges must be a dict"),
        ({"dtype": "q31", "ranges": {"counts_per_rev": 10}}, "ranges must have exactly"),
        ({"dtype": "q31", "ranges": RANGES, "nan_guard": True}, "nan_guard must be False"),
        ({"dtype": "double", "ranges": RANGES}, "ranges are only used"),
    ],
)
def test_export_arguments_are_checked_before_writing(tmp_path, kwargs, needle):
    out = tmp_path / "out"
    with pytest.raises((ParameterValueError, ParameterTypeError), match=needle):
        export_c(FAMILIES["dob-1"](), out, **kwargs)
    assert not out.exists()


def test_fixed_design_with_other_ranges_or_word_is_refused(tmp_path):
    fx = fixed_point_design(FAMILIES["dob-1"](), **RANGES)
    assert isinstance(fx, FixedPointDesign)
    with pytest.raises(ParameterValueError, match="ranges must be None"):
        render_c(fx, dtype="q31", ranges=RANGES)
    with pytest.raises(ParameterValueError, match="dtype must be the design's word"):
        export_c(fx, tmp_path / "x", dtype="q15")
    assert not (tmp_path / "x").exists()
    with pytest.raises(ParameterTypeError, match="count must be an integer"):
        FixedPointObserver(fx).estimate(1.5, 0)
    with pytest.raises(ParameterValueError, match="dtype must be 'q31' for a FixedPointDesign"):
        export_c(fx, tmp_path / "x")
    position = fixed_point_design(FAMILIES["position-1"](), **RANGES)
    with pytest.raises(ParameterValueError, match="omega must be None"):
        FixedPointObserver(position).update(3, 5)  # u given positionally as omega
    with pytest.raises(ParameterTypeError, match="omega must be given"):
        FixedPointObserver(fx).update(3, u=5)
    with pytest.raises(ParameterTypeError, match="design must be a FixedPointDesign"):
        FixedPointObserver(FAMILIES["dob-1"]())


def test_missing_compiler_or_emulator_is_one_line(monkeypatch, tmp_path):
    real = importlib.util.find_spec

    def hide(name, *args):
        return None if name in ("ziglang", "unicorn") else real(name, *args)

    monkeypatch.setattr(importlib.util, "find_spec", hide)
    with pytest.raises(CBuildError, match="pip install ziglang") as info:
        zig_cc()
    assert "\n" not in str(info.value)
    with pytest.raises(CBuildError, match="pip install unicorn") as info:
        EmulatedCortexM(tmp_path / "none.elf", cpu="cortex-m3")
    assert "\n" not in str(info.value)


@pytest.mark.skipif(find_compiler() is None, reason="no host C compiler (gcc or $CC)")
@pytest.mark.parametrize("name", ["dob-1", "position-2", "eso-2"])
@pytest.mark.parametrize("level", ["-O0", "-Os"])
def test_q31_source_is_integer_only_and_warning_free(tmp_path, name, level):
    """No floating-point type or literal in the generated q31 code, and a strict build at
    other optimisation levels (the target builds use -O2) has no warning."""
    from hpdob.testing import STRICT_FLAGS, compile_c

    fx = fixed_point_design(FAMILIES[name](), **RANGES)
    header, source = export_c(fx, tmp_path, dtype="q31")
    for path in (header, source):
        code = "\n".join(line for line in path.read_text().splitlines()
                         if not line.lstrip().startswith(("*", "/*")))  # fmt: skip
        assert "double" not in code and "float" not in code
    compile_c([source], tmp_path / "dob.o", flags=[*STRICT_FLAGS, level, "-ffreestanding", "-c"])
