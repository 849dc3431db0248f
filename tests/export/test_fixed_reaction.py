"""Fixed-point export of a reaction-torque observer composition (issue 21): ``<prefix>_reaction``
and ``<prefix>_estimates`` (tau_hat and tau_reac in one call) in q31, bit for bit the Python
model (:class:`FixedPointObserver`) on the host build and on the emulated Cortex-M0+/M3, and
within the derived bound of the double observer, on a force-controlled run against a wall."""

from __future__ import annotations

import math

import numpy as np
import pytest
from toolchains import needs_host_cc, needs_zig

from hpdob import (
    Actuator,
    Encoder,
    Environment,
    ParameterValueError,
    ServoLoop,
    design_observer,
    export_c,
    paper,
    simulate,
)
from hpdob.controllers import ForceControl
from hpdob.export import FixedPointObserver, fixed_point_design, fixed_point_error_bound
from hpdob.observers import reaction_torque_observer
from hpdob.testing import (
    EmulatedCortexM,
    HostFixedObserver,
    cross_compile,
    export_error_bound,
    fixed_drive_source,
)

MODEL = paper.NOMINAL.discretize(paper.TS)
CPR = 16384
RANGES = {"counts_per_rev": CPR, "omega_max": 50.0, "u_max": 0.5, "tau_max": 0.5}
DELTA_B = paper.PLANT.b - paper.NOMINAL.b  # the viscous friction model: known
TAU_REF = 0.05  # N m
CPUS = ("cortex-m0plus", "cortex-m3")


def _dob(m=1):
    return design_observer(MODEL, order=m, bandwidth=100.0)


COMPOSITIONS = {
    "shared": lambda: reaction_torque_observer(_dob(), viscous=DELTA_B),
    "separate-order-2": lambda: reaction_torque_observer(
        _dob(), design_observer(MODEL, order=2, bandwidth=80.0), viscous=DELTA_B),
    "position-only": lambda: reaction_torque_observer(
        design_observer(MODEL, order=1, bandwidth=150.0, measurement="position"),
        viscous=DELTA_B),
}  # fmt: skip


@pytest.fixture(scope="module")
def force_run():
    """2 s of the paper's motor (Coulomb friction) pressing a 10 N m/rad wall under force
    control on the HPDOb's RTOB: 16384-count encoder, torque limit, one sample of delay, a
    0.05 N m step of tau_ref at 0.1 s. Returns the logged counts, velocity and torque."""
    loop = ServoLoop(
        plant=paper.PLANT.replace(environment=Environment(10.0)), nominal=paper.NOMINAL,
        Ts=paper.TS, controller=ForceControl(1000.0, kv=40.0),
        observer=COMPOSITIONS["shared"](), sensor=Encoder(CPR),
        actuator=Actuator(torque_limit=0.444, delay_samples=1),
    )  # fmt: skip

    def reference(t):
        return np.where(t >= 0.1, TAU_REF, 0.0), 0 * t, 0 * t

    run = simulate(loop, reference=reference, duration=2.0, x0=(-0.01, 0.0))
    assert run.in_contact[-500:].all() and np.max(run.tau_contact) > 0.04  # it presses
    counts = np.rint(run.theta_measured / (2 * math.pi / CPR)).astype(np.int64)
    return counts, run.omega_measured, run.u


@pytest.fixture(scope="module", params=list(COMPOSITIONS))
def composition(request, force_run):
    fx = fixed_point_design(COMPOSITIONS[request.param](), **RANGES)
    counts, omega, u = force_run
    return request.param, fx, (counts, fx.to_int("omega0", omega), fx.to_int("u", u))


def _double(fx, counts, omega, u, init):
    """The double observer (generated Python) on the same quantised inputs."""
    reset, outputs, _, update = fx.system.python
    theta = counts * fx.radians_per_count
    s = reset(init[0] * fx.radians_per_count, 0.0, 0.0)
    ys, zs = [], []
    for th, om, v in zip(theta.tolist(), omega.tolist(), u.tolist(), strict=True):
        zs.append(s)
        meas = (th, om) if fx.measures_omega else (th,)
        ys.append(outputs(s, *meas))
        s = update(s, *meas, v)
    return np.array(ys), np.array(zs), theta


@needs_host_cc
def test_host_build_gives_both_estimates_as_the_model(composition, tmp_path):
    name, fx, (counts, W, U) = composition
    init = (int(counts[0]), 0, 0)
    Y, S = FixedPointObserver(fx, *init).run(counts, W, U)
    r = fx.system.outputs.index("tau_reac")
    header, source = export_c(fx, tmp_path / "c", prefix="rtob", dtype="q31")
    text = header.read_text()
    assert "int32_t rtob_reaction(" in text and "void rtob_estimates(" in text
    assert f"#define RTOB_TAU_REAC_FRAC_BITS {fx.frac_bits['tau_reac']}" in text
    # the drive loop reads tau_hat and tau_reac through rtob_estimates (fixed_drive_source)
    assert "rtob_estimates(s, " in fixed_drive_source(fx, "rtob")
    Yc, Sc = HostFixedObserver(fx, source, prefix="rtob", build_dir=tmp_path / "b").drive(
        counts, W, U, init=init)  # fmt: skip
    assert np.array_equal(Y, Yc), name
    assert np.array_equal(S, Sc), name
    # the model's own one-call estimates are its outputs' columns
    model = FixedPointObserver(fx, *init)
    for k in (0, 150, 1000, len(counts) - 1):
        model.state = (tuple(int(v) for v in S[k]), int(counts[k - 1]) if k else init[0])
        w = int(W[k]) if fx.measures_omega else None
        assert model.estimates(int(counts[k]), w) == (Y[k, 0], Y[k, r])
        assert model.reaction(int(counts[k]), w) == Y[k, r]
    # against the double observer on the same inputs: within the derived bound
    ref, z, theta = _double(fx, counts, fx.to_real("omega0", W), fx.to_real("u", U), init)
    tau_reac = fx.to_real("tau_reac", Y[:, r])
    error = np.abs(tau_reac - ref[:, r])
    bound = fixed_point_error_bound(fx, counts, W, U, S, init=init, output=r)
    bound += export_error_bound(fx.system, "double", theta, fx.to_real("omega0", W),
                                fx.to_real("u", U), z, init=(theta[0], 0.0, 0.0),
                                output=r)  # fmt: skip
    assert np.all(error <= bound), (name, float((error / bound).max()))
    assert error.max() <= fx.error_bound[r]
    assert np.abs(Y[:, r]).max() < fx.output[r].limit  # no saturation on this run
    # not vacuous: tau_reac carries the contact torque, 0.05 N m, and the bound would catch
    # the tau_hat row printed in its place (the two differ by more than twice the bound)
    assert np.max(tau_reac[-500:]) > 0.04
    assert np.max(np.abs(ref[:, 0] - ref[:, r])) > 2 * bound.max(), name


@pytest.fixture(scope="module")
def target_builds(tmp_path_factory):
    """Every composition's q31 export, prefix ``rt<i>``, in one image per core."""
    root = tmp_path_factory.mktemp("target")
    files = []
    for i, name in enumerate(COMPOSITIONS):
        fx = fixed_point_design(COMPOSITIONS[name](), **RANGES)
        _, source = export_c(fx, root / name, prefix=f"rt{i}", dtype="q31")
        drive = root / name / f"rt{i}_drive.c"
        drive.write_text(fixed_drive_source(fx, f"rt{i}"))
        files += [source, drive]
    return {cpu: cross_compile(files, root / f"{cpu}.elf", cpu=cpu) for cpu in CPUS}


@needs_zig
@pytest.mark.parametrize("cpu", CPUS)
def test_cortex_m_builds_give_both_estimates_as_the_model(composition, target_builds, cpu):
    name, fx, (counts, W, U) = composition
    sl = slice(0, 1500)  # the approach, the impact and the force step
    counts, W, U = counts[sl], W[sl], U[sl]
    init = (int(counts[0]), 0, 0)
    prefix = f"rt{list(COMPOSITIONS).index(name)}"
    Ye, Se = EmulatedCortexM(target_builds[cpu], cpu=cpu).drive_fixed(
        fx, prefix, counts, W, U, init=init)  # fmt: skip
    Y, S = FixedPointObserver(fx, *init).run(counts, W, U)
    assert np.array_equal(Y, Ye), (name, cpu)
    assert np.array_equal(S, Se), (name, cpu)
    r = fx.system.outputs.index("tau_reac")
    assert np.abs(Y[:, r]).max() > 0  # tau_reac was written by the image, not left zero


def test_an_observer_without_tau_reac_has_no_estimates(tmp_path):
    fx = fixed_point_design(_dob(), **RANGES)
    header, source = export_c(fx, tmp_path, prefix="dob", dtype="q31")
    assert "_reaction" not in header.read_text() and "_estimates" not in source.read_text()
    model = FixedPointObserver(fx)
    state = model.state
    with pytest.raises(ParameterValueError, match=r"no reaction-torque output tau_reac "
                       r"\(its outputs: tau_hat\)"):  # fmt: skip
        model.estimates(0, 0)
    assert model.state == state
