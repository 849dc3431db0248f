"""Offline estimation: estimate_disturbance runs any observer over a log, compiled, and agrees
with the runtime object and with the closed loop that produced the log."""

from __future__ import annotations

import numpy as np
import pytest

from hpdob import (
    DisturbanceObserver,
    Encoder,
    LinearObserver,
    Observer,
    ServoModel,
    design_observer,
    estimate_disturbance,
    paper,
    simulate,
)

MODEL = paper.NOMINAL.discretize(paper.TS)


def runtime_trace(observer, theta, omega, u):
    obs = observer.copy() if isinstance(observer, Observer) else Observer(observer)
    out = []
    for k in range(theta.size):
        y = (theta[k], omega[k]) if omega is not None else theta[k]
        out.append(obs.estimate(y))
        obs.update(y, u[k])
    return np.array(out)


@pytest.mark.parametrize("name", ["DOb-100", "HPDOb-100"])
def test_reproduces_the_closed_loops_estimate_bit_for_bit(name):
    """The observer inside simulate saw (theta_measured, omega_measured, u): run offline on
    those, it gives the same estimate, sample by sample."""
    run = paper.run(name, duration=3.0)
    result = estimate_disturbance(
        paper.observer(name), theta=run.theta_measured, omega=run.omega_measured, u=run.u
    )
    assert np.array_equal(result.tau_hat, run.tau_hat)
    assert np.array_equal(result.t, run.t) and result.omega_hat is None


def test_backward_difference_is_the_encoders():
    """Without omega, a state observer gets the backward difference of theta with 0 at the
    first sample: the velocity hpdob's Encoder gives the loop, so the estimate is the loop's."""
    run = paper.run("virtual-experiment", duration=2.0)
    result = estimate_disturbance(paper.observer("HPDOb-100"), theta=run.theta_measured, u=run.u)
    assert np.array_equal(result.omega, run.omega_measured)
    assert np.array_equal(result.tau_hat, run.tau_hat)


def test_agrees_with_the_runtime_object_from_its_state(rng):
    obs = paper.observer("HPDOb-100")
    obs.update((0.1, 2.0), 0.05)  # not at rest: the offline run continues from this state
    theta = np.cumsum(rng.normal(scale=1e-3, size=800))
    u = rng.normal(scale=0.05, size=800)
    before = obs.state
    result = estimate_disturbance(obs, theta=theta, u=u, state=obs.state)
    assert np.array_equal(obs.state, before)  # the runtime object is not changed
    assert np.array_equal(result.tau_hat, runtime_trace(obs, theta, result.omega, u))


def test_position_only_observer_and_its_velocity(rng):
    """A position-only observer of the protocol (written here: a DOb on a differenced angle
    would need omega, so take the plain position-measuring tracking filter x = [theta, omega,
    tau] with fixed gains) returns tau_hat and omega_hat."""
    Ts, J = paper.TS, paper.NOMINAL.J
    A = np.array([[1.0, Ts, -(Ts**2) / (2 * J)], [0.0, 1.0, -Ts / J], [0.0, 0.0, 1.0]])
    B = np.array([Ts**2 / (2 * J), Ts / J, 0.0])
    L = np.array([0.6, 80.0, -0.02])  # a stable predictor gain for this model
    F = A - np.outer(L, [1.0, 0.0, 0.0])
    assert np.abs(np.linalg.eigvals(F)).max() < 1
    system = LinearObserver(
        F=F, G=np.column_stack([L, B]), H=np.eye(3)[[2, 1]], E=np.zeros((2, 2)),
        N=np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]]), Ts=Ts, measures=("theta",),
        outputs=("tau_hat", "omega_hat"), model=MODEL,
    )  # fmt: skip
    theta = np.cumsum(rng.normal(scale=1e-3, size=600))
    u = rng.normal(scale=0.05, size=600)
    result = estimate_disturbance(system, theta=theta, u=u)
    obs = Observer(system, x0=(theta[0], 0.0))  # the offline run starts at rest at theta[0]
    for k in range(theta.size):
        assert result.tau_hat[k] == obs.estimate(theta[k])
        assert result.omega_hat[k] == obs.velocity
        obs.update(theta[k], u[k])
    assert result.omega is None
    with pytest.raises(ValueError, match="omega must be None for an observer that measures the"):
        estimate_disturbance(system, theta=theta, u=u, omega=np.zeros(600))


def test_result_table_plot_and_rms(tmp_path):
    run = paper.run("DOb-100", duration=1.0)
    result = estimate_disturbance(paper.observer("DOb-100"), theta=run.theta, u=run.u,
                                  t=run.t, omega=run.omega)  # fmt: skip
    frame = result.to_pandas()
    assert list(frame.columns) == ["t", "theta", "omega", "u", "tau_hat"]
    path = result.to_csv(tmp_path / "estimate.csv")
    assert path.read_text().splitlines()[0] == "t,theta,omega,u,tau_hat"
    assert result.rms_error(result.tau_hat) == 0.0
    fig = result.plot(reference=run.tau_dn, reference_label=r"$\tau_{dn}$")
    assert fig.axes[1].get_ylabel() == "disturbance [N m or N]"


@pytest.mark.parametrize(
    ("kwargs", "error", "pattern"),
    [
        ({"theta": np.zeros(10), "u": np.zeros(11)}, ValueError, r"theta has 10, u has 11"),
        ({"theta": [0.0, np.nan] * 5, "u": np.zeros(10)}, ValueError, r"theta.*not finite|nan"),
        ({"theta": "abc", "u": np.zeros(3)}, TypeError, r"theta"),
        (
            {"theta": np.zeros(10), "u": np.zeros(10), "t": np.arange(10) * 2e-3},
            ValueError,
            r"t must advance by the observer's sampling period Ts = 0.001 s",
        ),
        (
            {"theta": np.zeros(10), "u": np.zeros(10), "t": np.r_[0.0, np.cumsum(np.ones(9))]},
            ValueError,
            r"t must advance by",
        ),
    ],
)
def test_bad_logs_are_named(kwargs, error, pattern):
    with pytest.raises(error, match=pattern):
        estimate_disturbance(paper.observer("DOb-100"), **kwargs)


def test_bad_observer():
    with pytest.raises(TypeError, match="observer must be a DisturbanceObserver, an Observ"):
        estimate_disturbance("dob", theta=np.zeros(10), u=np.zeros(10))


def test_encoder_log_from_a_simulation_runs_through_read_log(tmp_path):
    from hpdob import read_log

    kwargs = {**paper.scenario(), "duration": 2.0}
    run = simulate(**kwargs, observer=paper.observer("HPDOb-100").design, sensor=Encoder(16384))
    path = tmp_path / "log.csv"
    run.to_csv(path)
    log = read_log(path, time="t", position="theta_measured", input="u")
    result = estimate_disturbance(paper.observer("HPDOb-100"), theta=log.theta, u=log.u, t=log.t)
    assert np.array_equal(result.tau_hat, run.tau_hat)


def test_one_start_rule_for_designs_systems_and_runtime_objects(rng):
    """Every form starts converged at the log's first sample (theta[0] far from 0 here), so a
    design, its system and a fresh runtime object give the same estimate bit for bit; and it
    is the runtime object reset there and stepped by hand."""
    design = design_observer(MODEL, order=1, bandwidth=100.0)
    theta = 1.0 + np.cumsum(rng.normal(scale=1e-3, size=400))
    u = rng.normal(scale=0.05, size=400)
    forms = (design, design.system, DisturbanceObserver.from_design(design))
    runs = [estimate_disturbance(form, theta=theta, u=u, tau0=0.01) for form in forms]
    for other in runs[1:]:
        np.testing.assert_array_equal(other.tau_hat, runs[0].tau_hat)
    obs = DisturbanceObserver.from_design(design, x0=(theta[0], 0.0), tau0=0.01)
    np.testing.assert_array_equal(runs[0].tau_hat, runtime_trace(obs, theta, runs[0].omega, u))
    assert runs[0].tau_hat[0] == pytest.approx(0.01, rel=1e-12)  # converged at the start


def test_start_state_is_checked():
    design = design_observer(MODEL, order=1, bandwidth=100.0)
    theta, u = np.zeros(10), np.zeros(10)
    with pytest.raises(ValueError, match="state must"):
        estimate_disturbance(design, theta=theta, u=u, state=[0.0])
    with pytest.raises(ValueError, match="give tau0 or state, not both"):
        estimate_disturbance(design, theta=theta, u=u, state=[0.0, 0.0], tau0=0.1)


def test_one_machine_code_for_read_only_and_writeable_logs():
    """The offline loop is compiled (or loaded from numba's cache) once per structure: a
    result's read-only columns and writeable arrays of the same samples reach it as one
    argument type (read-only), with the same estimate (issue 25)."""
    from hpdob.identification import _estimate_kernel
    from hpdob.observers import as_system, program_structure

    run = paper.run("HPDOb-100", duration=0.5)
    observer = paper.observer("HPDOb-100")
    shared = estimate_disturbance(observer, theta=run.theta_measured, omega=run.omega_measured,
                                  u=run.u)  # fmt: skip
    copied = estimate_disturbance(observer, theta=run.theta_measured.copy(),
                                  omega=run.omega_measured.copy(), u=run.u.copy())  # fmt: skip
    assert shared.tau_hat.tobytes() == copied.tau_hat.tobytes() == run.tau_hat.tobytes()
    system = as_system(observer)
    kernel = _estimate_kernel.offline_kernel(
        program_structure(system.program), system.n_states, _estimate_kernel.VELOCITY_GIVEN
    )
    assert len(kernel.signatures) == 1, kernel.signatures


def test_time_and_differenced_velocity_are_derived_when_read():
    """A state observer's differenced velocity and the time ``k Ts`` are not written by the
    call (issue 25: a long log's call writes only what the caller did not give, and most read
    only the estimate): with read-only columns, as a Log's, the call allocates the estimate
    and nothing else of the log's length. Read later they are the loop's (the closed loop's
    Encoder velocity and time grid), read-only, kept, and survive a pickle."""
    import pickle
    import tracemalloc

    run = paper.run("virtual-experiment", duration=20.0)
    theta, u = run.theta_measured.copy(), run.u.copy()
    for x in (theta, u):
        x.flags.writeable = False
    observer = paper.observer("HPDOb-100")
    estimate_disturbance(observer, theta=theta[:10], u=u[:10])  # compiled before tracing
    tracemalloc.start()
    try:
        result = estimate_disturbance(observer, theta=theta, u=u)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    one = theta.nbytes
    assert one <= peak < 1.5 * one, (peak, one)  # tau_hat alone (no omega_hat: HPDOb-100)
    assert result.omega is result.omega and result.t is result.t  # computed once, kept
    assert np.array_equal(result.omega, run.omega_measured)
    assert np.array_equal(result.t, run.t)
    assert not result.omega.flags.writeable and not result.t.flags.writeable
    again = pickle.loads(pickle.dumps(estimate_disturbance(observer, theta=theta, u=u)))
    assert np.array_equal(again.omega, run.omega_measured) and np.array_equal(again.t, run.t)
    with pytest.raises(AttributeError):  # still frozen
        result.t = run.t


@pytest.mark.parametrize("n", [1_000, 300_000])  # the loop copies; a second thread copies
@pytest.mark.parametrize("given", ["none", "omega", "t", "both"])
def test_writable_inputs_are_copied_whichever_route(rng, n, given):
    """Writable inputs are kept as copies (the caller may change its arrays afterwards),
    written by the loop on short logs and by a second thread while the loop runs on long ones
    (issue 25); either way the result holds the inputs' values and the estimate of shared,
    read-only columns, bit for bit."""
    model = ServoModel(2.8e-4).discretize(1e-3)
    observer = design_observer(model, order=1, bandwidth=100.0)
    if given == "none":  # the position-only form, which estimates the velocity too
        observer = design_observer(model, order=1, bandwidth=100.0, measurement="position")
    theta = np.cumsum(rng.normal(scale=1e-3, size=n))
    u = rng.normal(scale=0.1, size=n)
    kwargs = {"theta": theta, "u": u}
    if given in ("omega", "both"):
        kwargs["omega"] = rng.normal(size=n)
    if given in ("t", "both"):
        kwargs["t"] = np.arange(n) * 1e-3
    frozen = {}
    for name, x in kwargs.items():
        frozen[name] = x.copy()
        frozen[name].flags.writeable = False
    values = {name: x.copy() for name, x in kwargs.items()}
    copied = estimate_disturbance(observer, **kwargs)
    shared = estimate_disturbance(observer, **frozen)
    for x in kwargs.values():
        x[:] = np.nan  # the caller reuses its buffers
    for name, x in values.items():
        kept = getattr(copied, name)
        assert np.array_equal(kept, x), name
        assert not np.shares_memory(kept, kwargs[name]) and not kept.flags.writeable, name
        assert getattr(shared, name) is frozen[name] or np.shares_memory(
            getattr(shared, name), frozen[name]
        ), name
    assert copied.tau_hat.tobytes() == shared.tau_hat.tobytes()
    if copied.omega_hat is not None:
        assert copied.omega_hat.tobytes() == shared.omega_hat.tobytes()
    assert np.array_equal(copied.state, shared.state)


@pytest.mark.parametrize("n", [1_000, 300_000])  # checked before the loop; while it runs
@pytest.mark.parametrize(
    ("fault", "pattern"),
    [
        ("step", r"t must advance by the observer's sampling period Ts = 0.001 s, got a step"),
        ("back", r"t must increase strictly \(time \[s\]\), but t\[500\] = "),
        ("jitter", r"t must be uniformly sampled: the step t\[(150000|500)\] - t\[(149999|499)\]"),
    ],
)
def test_bad_times_are_named_on_short_and_long_logs(n, fault, pattern):
    """The time check gives its error whether it runs before the loop or beside it, and the
    caller's arrays are left as they were."""
    t = np.arange(n) * 1e-3
    if fault == "step":
        t = t * 2.0
    elif fault == "back":
        t[500] = t[498]
    else:
        t[n // 2 :] += 0.5e-3
    theta, u = np.zeros(n), np.zeros(n)
    before = [x.copy() for x in (theta, u, t)]
    with pytest.raises(ValueError, match=pattern):
        estimate_disturbance(paper.observer("DOb-100"), theta=theta, u=u, t=t)
    assert all(np.array_equal(x, y) for x, y in zip((theta, u, t), before, strict=True))
