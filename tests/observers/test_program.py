"""Code generated from an observer's Program once per structure (issue 25): the Python
functions and the compiled offline loop evaluate exactly the program's sums, bit for bit, for
every family at orders 0-2, and designs of one structure share one generated function."""

from __future__ import annotations

import numpy as np
import pytest

from hpdob import ServoModel, design_observer, estimate_disturbance
from hpdob.identification import _estimate_kernel
from hpdob.identification._checks import check_time
from hpdob.observers import design_eso, design_kalman, initial_state
from hpdob.observers._program import _python_factory, program_structure

MODEL = ServoModel(2.8e-4, 1e-5).discretize(1e-3)


def designs(bandwidth=100.0):
    for m in range(3):
        yield design_observer(MODEL, order=m, bandwidth=bandwidth)
        yield design_observer(MODEL, order=m, bandwidth=bandwidth, measurement="position")
        yield design_eso(MODEL, bandwidth=bandwidth, extended_order=m)
        yield design_eso(MODEL, bandwidth=bandwidth, extended_order=m, form="predictive")
        yield design_kalman(MODEL, order=m, position_noise_std=1e-4, process_noise_std=1.0)


DESIGNS = list(designs())


def row_sum(terms, w):
    """The program's definition of a row, written out: its terms' products summed left to
    right (0 for an empty row), independently of any generated code."""
    if not terms:
        return 0.0
    acc = terms[0].coefficient * w[terms[0].operand]
    for t in terms[1:]:
        acc = acc + t.coefficient * w[t.operand]
    return acc


def program_trace(system, s, theta, omega, u):
    """The observer run over a log by evaluating its Program's terms one by one."""
    p = len(system.measures)
    tau, om_hat = [], []
    for k in range(theta.size):
        v = [float(theta[k])] if p == 1 else [float(theta[k]), float(omega[k])]
        w = [*s, *v]
        y = [row_sum(r, w) for r in system.program.output]
        tau.append(y[0])
        om_hat.append(y[1] if len(y) > 1 else np.nan)
        w.append(float(u[k]))
        s = tuple(row_sum(r, w) for r in system.program.update)
    return np.array(tau), np.array(om_hat)


@pytest.fixture(scope="module")
def log():
    rng = np.random.default_rng(2025)
    theta = np.cumsum(rng.normal(scale=2e-3, size=400))
    return theta, rng.normal(scale=0.05, size=400), rng.normal(scale=0.5, size=400)


@pytest.mark.parametrize("design", DESIGNS, ids=lambda d: d.system.name)
def test_offline_loop_and_python_evaluate_the_program_bit_for_bit(design, log):
    theta, u, omega = log
    system = design.system
    position = system.measurement == "position"
    given = None if position else omega
    s0 = initial_state(system, (float(theta[0]), 0.0 if position else float(omega[0])), 0.01)
    tau, om_hat = program_trace(system, s0, theta, given, u)
    result = estimate_disturbance(design, theta=theta, u=u, omega=given, tau0=0.01)
    assert np.array_equal(result.tau_hat, tau)
    if system.has_velocity:
        assert np.array_equal(result.omega_hat, om_hat)
    # the generated Python functions (the runtime objects' arithmetic) agree as well
    reset, outputs, _, update = system.python
    x0 = [float(theta[0]), 0.0 if position else float(omega[0]), 0.01]
    assert reset(*x0) == tuple(row_sum(r, x0) for r in system.program.reset) == tuple(s0)
    s = s0
    for k in range(theta.size):
        v = (theta[k],) if position else (theta[k], omega[k])
        assert outputs(s, *v)[0] == tau[k]
        s = update(s, *v, u[k])


@pytest.mark.parametrize("design", DESIGNS[:5], ids=lambda d: d.system.name)
def test_derived_velocity_time_and_copies(design, log):
    theta, u, _ = log
    result = estimate_disturbance(design, theta=theta, u=u)
    assert np.array_equal(result.t, np.arange(theta.size) * 1e-3)
    assert result.theta is not theta and np.array_equal(result.theta, theta)
    assert result.u is not u and np.array_equal(result.u, u)
    if design.system.measurement == "state":
        velocity = np.r_[0.0, np.diff(theta) / 1e-3]
        assert np.array_equal(result.omega, velocity)
        s0 = initial_state(design, (float(theta[0]), 0.0))
        assert np.array_equal(result.tau_hat, program_trace(design.system, s0, theta,
                                                            velocity, u)[0])  # fmt: skip
    given = np.arange(theta.size) * 1e-3 + 5.0
    assert np.array_equal(estimate_disturbance(design, theta=theta, u=u, t=given).t, given)
    assert not any(a.flags.writeable for a in (result.t, result.theta, result.tau_hat))


def test_one_generated_function_per_structure():
    """A second bandwidth changes every coefficient, not the structure: no new code."""
    for a, b in zip(DESIGNS, designs(bandwidth=60.0), strict=True):
        sa, sb = a.system, b.system
        assert program_structure(sa.program) == program_structure(sb.program)
        n, p = sa.n_states, len(sa.measures)
        assert _python_factory(program_structure(sa.program), n, p) is _python_factory(
            program_structure(sb.program), n, p
        )
    info = _estimate_kernel.offline_kernel.cache_info()
    theta, u = np.zeros(50), np.zeros(50)
    estimate_disturbance(DESIGNS[0], theta=theta, u=u)
    before = _estimate_kernel.offline_kernel.cache_info()
    estimate_disturbance(design_observer(MODEL, order=0, bandwidth=37.0), theta=theta, u=u)
    after = _estimate_kernel.offline_kernel.cache_info()
    assert after.misses == before.misses and after.hits == before.hits + 1
    assert info.currsize <= after.currsize


def test_non_finite_samples_of_float_arrays_are_named():
    theta = np.zeros(20)
    theta[7] = np.inf
    with pytest.raises(ValueError, match=r"theta has a non-finite sample inf at index 7"):
        estimate_disturbance(DESIGNS[0], theta=theta, u=np.zeros(20))
    u = np.zeros(20)
    u[3] = np.nan
    with pytest.raises(ValueError, match=r"u has a non-finite sample nan at index 3"):
        estimate_disturbance(DESIGNS[0], theta=np.zeros(20), u=u)


@pytest.mark.parametrize(
    ("t", "pattern"),
    [
        (np.r_[0.0, 1e-3, 1e-3, 3e-3], r"t\[2\] = 0.001 s is not after t\[1\]"),
        (np.r_[0.0, 1e-3, 2e-3, 3.1e-3, 4.1e-3], r"step t\[3\] - t\[2\] = 0.0011 s differs"),
        (np.r_[0.0, 1e-3, 2e-3, 2.9e-3, 3.9e-3], r"step t\[3\] - t\[2\] = 0.0009 s differs"),
    ],
)
def test_time_check_names_the_step(t, pattern):
    with pytest.raises(ValueError, match=pattern):
        check_time(t)


def test_time_check_period_and_tolerance():
    t = np.arange(1000) * 1e-3
    assert check_time(t) == (t[-1] - t[0]) / 999
    jitter = t + np.where(np.arange(1000) % 2, 4e-7, 0.0)  # steps deviate by 8e-4 relative
    assert check_time(jitter) == (jitter[-1] - jitter[0]) / 999
    with pytest.raises(ValueError, match="uniformly sampled"):
        check_time(jitter, tolerance=5e-4)


def test_immutable_signals_are_shared_others_copied():
    from hpdob.identification import Log
    from hpdob.identification._checks import immutable

    theta = np.cumsum(np.full(100, 1e-4))
    log = Log(t=np.arange(100) * 1e-3, theta=theta, u=np.zeros(100))
    assert log.theta is not theta and theta.flags.writeable  # the caller's array is untouched
    result = estimate_disturbance(DESIGNS[0], theta=log.theta, u=log.u, t=log.t)
    assert result.theta is log.theta and result.u is log.u and result.t is log.t
    view = theta[:]
    view.setflags(write=False)  # read-only, but its base is not: copied
    assert not immutable(view) and immutable(log.theta)
    assert estimate_disturbance(DESIGNS[0], theta=view, u=log.u).theta is not view
    assert not immutable(np.zeros(3)) and not immutable([0.0])


def test_a_sweep_generates_no_code_per_scenario():
    from hpdob import paper, sweep

    base = {**paper.scenario(), "observer": {"order": 1, "bandwidth": 100.0}, "duration": 0.05}
    import hpdob.simulation._sweep as sweep_module

    sweep(base, grid={"observer.order": [0, 1]}, progress=False)  # both structures seen
    sweep_module.clear_kept_designs()  # eight new designs below, none kept from other tests
    before = _python_factory.cache_info()
    grid = {"observer.order": [0, 1], "observer.bandwidth": [60.0, 80.0, 120.0, 150.0]}
    rows = sweep(base, grid=grid, progress=False)
    after = _python_factory.cache_info()
    assert len(rows) == 8 and after.misses == before.misses  # eight designs, no new source
    assert after.hits >= before.hits + 8
