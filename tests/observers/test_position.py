"""Position-only observers (issue 12): synthesis, exactness, closed form, noise, every consumer.

Reference values come from the nominal discrete model (eq. 8) driven sample by sample, from an
independent design by python-control on the augmented model written out here, from the closed
form of docs/analysis.md section 8 written out literally, and from Monte-Carlo runs; never
from outputs of the code under test.
"""

from __future__ import annotations

import math
from pathlib import Path

import control
import numpy as np
import pytest

from hpdob import (
    PD,
    DisturbanceObserver,
    Encoder,
    ParameterTypeError,
    ParameterValueError,
    PositionObserverDesign,
    ServoLoop,
    ServoModel,
    closed_loop,
    closed_loop_poles,
    design_observer,
    estimate,
    estimation_response,
    estimation_transfer,
    gang_of_four,
    initial_state,
    loop_margins,
    noise_gains,
    observer_noise_gain,
    paper,
    robust_stability_map,
    simulate,
    update,
)
from hpdob.observers import outputs
from hpdob.signals import Ramp

TS = 1e-3
NOMINAL = ServoModel(2.8e-4, 1e-4)  # b_n != 0: every entry of A, D is exercised
MODEL = NOMINAL.discretize(TS)
PD_OMEGA_HAT = PD(50.0, 5.0, velocity="observer")


def position(order, **kwargs):
    kwargs.setdefault("bandwidth", 150.0) if "poles" not in kwargs else None
    return design_observer(MODEL, order=order, measurement="position", **kwargs)


def augmented(model, m):
    """The augmented model of docs/theory.md section 9, written out: state [theta, omega,
    tau_{k-m}, ..., tau_k]; the history shifts, the newest sample is extrapolated with
    tau_{k+1} = sum_i (-1)^(m+1-i) C(m+1, i-1) tau_{k-(m+1-i)}."""
    n = m + 3
    A = np.zeros((n, n))
    A[0, 0], A[0, 1], A[1, 1] = 1.0, model.A[0, 1], model.A[1, 1]
    A[0, -1], A[1, -1] = -model.D[0], -model.D[1]
    for i in range(2, n - 1):
        A[i, i + 1] = 1.0
    for i in range(1, m + 2):
        A[-1, 1 + i] = (-1) ** (m + 1 - i) * math.comb(m + 1, i - 1)
    B = np.zeros(n)
    B[:2] = model.B
    return A, B


def drive(design, model, tau, *, u_extra=None, pd=(50.0, 5.0), omega=None):
    """The nominal discrete model under PD on the observer's velocity, the observer fed the
    angle alone; returns the estimates and the velocity estimates (the true velocity into
    ``omega`` if given)."""
    obs = DisturbanceObserver.from_design(design)
    x = np.zeros(2)
    est, vel = np.empty(len(tau)), np.empty(len(tau))
    for k in range(len(tau)):
        est[k] = obs.estimate(float(x[0]))
        vel[k] = obs.velocity
        if omega is not None:
            omega[k] = x[1]
        u = -model.J * (pd[0] * x[0] + pd[1] * vel[k]) + est[k]
        if u_extra is not None:
            u += u_extra[k]
        obs.update(float(x[0]), u)
        x = model.step(x, u, tau[k])
    return est, vel


# -- synthesis ------------------------------------------------------------------------------


@pytest.mark.parametrize("order", [1, 2, 3])
def test_order_m_is_exact_for_degree_m_polynomials_and_order_m_minus_1_is_not(order, rng):
    """Driven by the angle alone, the estimate converges to tau_k for disturbance samples that
    are a polynomial of degree m (relative 1e-9); one order less leaves an error."""
    k = np.arange(3000)
    c = rng.normal(size=order + 1) * 0.01
    tau = sum(c[i] * (k / 300.0) ** i for i in range(order + 1))
    u_extra = 1e-3 * np.sin(0.013 * k)  # the estimate must not depend on the command
    for m, exact in ((order, True), (order - 1, False)):
        est, _ = drive(position(m, bandwidth=200.0), MODEL, tau, u_extra=u_extra)
        error = np.abs(est - tau)[-200:] / np.abs(tau[-200:])
        assert bool(error.max() <= 1e-9) is exact, (m, error.max())


def test_velocity_estimate_converges_and_reset_is_a_fixed_point():
    design = position(1)
    tau = 0.01 + 0.002 * np.arange(2000) * TS  # a ramp: order 1 is exact for it
    omega = np.empty(2000)
    _, vel = drive(design, MODEL, tau, omega=omega)
    assert np.max(np.abs(vel - omega)[-500:]) < 1e-12 * np.max(np.abs(omega))
    assert np.max(np.abs(vel - omega)[:50]) > 1e-3  # it had to converge
    obs = DisturbanceObserver.from_design(design, x0=(0.3, 0.0), tau0=0.02)
    state = obs.state
    assert obs.estimate(0.3) == pytest.approx(0.02, abs=1e-15) and obs.velocity == 0.0
    obs.update(0.3, 0.02)  # at rest with u = tau0: nothing changes
    np.testing.assert_allclose(obs.state, state, rtol=0, atol=1e-14)
    np.testing.assert_array_equal(state, [0.3, 0.0, 0.02, 0.02])  # [theta, omega, tau history]


@pytest.mark.parametrize(
    ("order", "poles"),
    [
        (0, [0.9, 0.8, 0.7]),
        (1, [0.92, 0.85, 0.5 + 0.2j, 0.5 - 0.2j]),
        (2, [0.95, 0.9, 0.8, 0.7, 0.3]),
    ],
)
def test_distinct_poles_are_placed_and_agree_with_python_control(order, poles):
    design = position(order, poles=poles)
    eig = np.linalg.eigvals(design.to_statespace().A)
    np.testing.assert_allclose(np.sort_complex(eig), np.sort_complex(poles), atol=1e-9)
    # Independent design: python-control on the augmented model written out above. The
    # predictor gain L places the eigenvalues of A_a - L c^T (the dual of state feedback);
    # the current-form gain is K = A_a^{-1} L.
    Aa, Ba = augmented(MODEL, order)
    c = np.zeros((1, order + 3))
    c[0, 0] = 1.0
    for place in (control.place, control.acker):
        L = np.asarray(place(Aa.T, c.T, poles)).ravel()
        np.testing.assert_allclose(design.predictor_gains, L, rtol=1e-7)
        np.testing.assert_allclose(design.gains, np.linalg.solve(Aa, L), rtol=1e-7)
    np.testing.assert_array_equal(design.augmented_matrix, Aa)
    np.testing.assert_array_equal(design.system.G[:, 1], Ba)


def test_order0_gains_written_out():
    """docs/theory.md section 9: for order 0 the disturbance gain is eq. (24)'s analogue,
    L_tau = -(1 - p1)(1 - p2)(1 - p3) / n(1), n(z) = d1 z + a12 d2 - a22 d1; and the
    characteristic polynomial is delta R - n S with R, S written out."""
    poles = [0.9, 0.8, 0.7]
    design = position(0, poles=poles)
    a12, a22 = float(MODEL.A[0, 1]), float(MODEL.A[1, 1])
    d1, d2 = (float(v) for v in MODEL.D)
    n1 = d1 + a12 * d2 - a22 * d1
    L = design.predictor_gains
    assert L[2] == pytest.approx(-(0.1 * 0.2 * 0.3) / n1, rel=1e-12)
    # R(z) = (z - 1)(z - a22) + L_theta (z - a22) + a12 L_omega, highest power first
    R = np.array([1.0, -(1.0 + a22) + L[0], a22 - L[0] * a22 + a12 * L[1]])
    P = np.convolve([1.0, -1.0], R) - [0.0, 0.0, d1 * L[2], (a12 * d2 - a22 * d1) * L[2]]
    np.testing.assert_allclose(P, np.poly(poles), rtol=0, atol=1e-14)


@pytest.mark.parametrize("order", [0, 1, 2, 3])
def test_repeated_poles_are_placed_exactly(order):
    """All m + 3 poles at one place: the characteristic polynomial is (z - p)^(m+3) to rounding;
    the eigenvalues split only by the conditioning of the Jordan block, ~eps^(1/(m+3))."""
    p = math.exp(-150.0 * TS)
    design = position(order)
    np.testing.assert_array_equal(design.poles, np.full(order + 3, p))
    A = design.to_statespace().A
    np.testing.assert_allclose(np.poly(A), np.poly(np.full(order + 3, p)), rtol=0, atol=1e-11)
    assert np.max(np.abs(np.linalg.eigvals(A) - p)) < 10 * np.finfo(float).eps ** (1 / (order + 3))
    # distinct disturbance and velocity bandwidths: m + 1 poles at one place, two at another
    two = position(order, velocity_bandwidth=400.0)
    expected = np.poly([p] * (order + 1) + [math.exp(-0.4)] * 2)
    np.testing.assert_allclose(np.poly(two.error_matrix), expected, rtol=0, atol=1e-11)


def test_low_bandwidths_are_realisable_or_refused_clearly():
    for order in range(3):  # realised within pole_tolerance down to 0.1 rad/s here
        design_observer(MODEL, order=order, bandwidth=0.1, measurement="position")
    # order 3: stable (exact Schur-Cohn) but its poles are off: accepted only on request
    design_observer(MODEL, order=3, bandwidth=0.1, measurement="position", pole_tolerance=None)
    with pytest.raises(ParameterValueError, match=r"order 3 .* off by .* pole_tolerance=0.05"):
        design_observer(MODEL, order=3, bandwidth=0.1, measurement="position")
    with pytest.raises(ParameterValueError, match=r"cannot be realised .* exact Schur-Cohn"):
        design_observer(MODEL, order=12, bandwidth=1.0, measurement="position")


def test_design_is_frozen_and_its_system_is_the_protocol():
    design = position(1)
    assert isinstance(design, PositionObserverDesign)
    system = design.system
    assert system.measures == ("theta",) and system.outputs == ("tau_hat", "omega_hat")
    assert system.measurement == "position" and system.truncation_order == 1
    assert system.n_states == 4 and design.gain_direction is None
    with pytest.raises(ValueError, match="read-only"):
        design.gains[0] = 0.0
    obs = DisturbanceObserver(MODEL, order=1, bandwidth=150.0, measurement="position")
    np.testing.assert_array_equal(obs.gains, design.gains)
    assert obs.measurement == "position" and obs.velocity_bandwidth == 150.0
    assert "measurement='position'" in repr(obs)


# -- the closed form of Q, three ways -----------------------------------------------------


def literal_error(design, z):
    """1 - Q = (z - 1)^(m+1) R(z) / prod(z - p_i) with R the characteristic polynomial of the
    (theta, omega) block of (I - K c^T) A_a (docs/analysis.md section 8), written out."""
    K, m = design.gains, design.order
    a12, a22 = MODEL.A[0, 1], MODEL.A[1, 1]
    R = z**2 - (1 - K[0] + a22 - a12 * K[1]) * z + (1 - K[0]) * a22
    P = np.prod([z - p for p in design.poles], axis=0)
    return (z - 1) ** (m + 1) * R / P


@pytest.mark.parametrize("order", [0, 1, 2, 3])
def test_closed_form_three_ways(order):
    design = position(order, velocity_bandwidth=300.0)
    f = np.array([0.3, 2.0, 17.0, 80.0, 311.0, 499.0])
    z = np.exp(2j * np.pi * f * TS)
    closed = estimation_response(design, f, error=True)
    # 1. the literal formula
    np.testing.assert_allclose(closed, literal_error(design, z), rtol=1e-10)
    # 2. the observer's state space in series with the nominal plant (python-control)
    plant = control.ss(
        MODEL.A,
        np.column_stack([MODEL.B, -MODEL.D]),
        [[1.0, 0.0]],
        [[0.0, 0.0]],
        TS,
        inputs=["u", "tau_dn"],
        outputs=["theta"],
    )
    series = control.interconnect(
        [plant, design.to_statespace()],
        inplist=["tau_dn", "u"],
        outlist=["tau_hat"],
        check_unused=False,  # omega_hat is not needed here
    )
    resp = series.frequency_response(2 * np.pi * f).frdata[0, 0]
    # (evaluating the series state space, with the plant's double pole at z = 1 and the
    # observer's cluster at 0.86, loses ~5e-8 at 0.3 Hz; the closed form does not)
    np.testing.assert_allclose(1 - closed, resp, rtol=0, atol=1e-7)
    tf = estimation_transfer(design).frequency_response(2 * np.pi * f).frdata[0, 0]
    np.testing.assert_allclose(tf, resp, rtol=0, atol=1e-7)
    # 3. a sampled sine on the nominal model under PD: amplitude and phase of the estimate
    f0, settle, n_win = 5.0, 1500, 2000  # 200 samples per period, 10 periods
    k = np.arange(settle + n_win)
    tau = 0.02 * np.sin(2 * np.pi * f0 * k * TS + 0.4)
    est, _ = drive(design, MODEL, tau)
    window = slice(settle, None)
    phasor = np.exp(-2j * np.pi * f0 * k[window] * TS)
    measured = np.mean(est[window] * phasor) / np.mean(tau[window] * phasor)
    expected = estimation_response(design, f0)[0]
    assert abs(measured - expected) < 1e-9 * abs(expected)
    # structure: unit DC gain, error ~ f^(m+1) at low frequency, Q strictly proper
    assert estimation_response(design, 0.0)[0] == pytest.approx(1.0, abs=1e-14)
    small = np.abs(estimation_response(design, [1e-3, 2e-3], error=True))
    assert small[1] / small[0] == pytest.approx(2.0 ** (order + 1), rel=1e-5)
    assert len(estimation_transfer(design).den[0][0]) == order + 4


# -- one recurrence, every executable form --------------------------------------------------


def test_object_core_kernel_and_c_agree_bit_for_bit(tmp_path):
    from hpdob import export_c
    from hpdob.testing import (
        CObserver,
        export_error_bound,
        find_compiler,
        sanitized_run,
        sanitizer_available,
    )

    design = position(2)
    kwargs = paper.scenario()
    kwargs.update(
        duration=2.0,
        nominal=NOMINAL,
        observer=design,
        sensor=paper.VIRTUAL_SENSOR,
        actuator=paper.VIRTUAL_ACTUATOR,
        controller=PD_OMEGA_HAT,
    )
    result = simulate(**kwargs)  # the compiled kernel
    theta, u = result.theta_measured, result.u
    obs = DisturbanceObserver.from_design(design)
    state = initial_state(design)
    tau_obj, tau_core = np.empty(len(u)), np.empty(len(u))
    vel_obj, states = np.empty(len(u)), np.empty((len(u), 5))
    for k, (th, uk) in enumerate(zip(theta.tolist(), u.tolist(), strict=True)):
        states[k] = state
        tau_obj[k] = obs.estimate(th)
        vel_obj[k] = obs.velocity
        obs.update(th, uk)
        tau_core[k] = estimate(design, state, th)
        assert outputs(design, state, th) == (tau_core[k], vel_obj[k])
        state = update(design, state, th, uk)
    np.testing.assert_array_equal(tau_obj, result.tau_hat)
    np.testing.assert_array_equal(tau_core, result.tau_hat)
    np.testing.assert_array_equal(vel_obj, result.omega_hat)
    if find_compiler() is None:
        pytest.skip("no C compiler: the exported C is not checked")
    header, source = export_c(design, tmp_path / "c", prefix="pos")
    assert "double pos_velocity(const pos_state *s, double theta);" in header.read_text()
    c = CObserver(
        header, source, prefix="pos", dtype="double", observer=design, build_dir=tmp_path / "lib"
    )
    tau_c, z_c = c.drive(theta, np.zeros_like(theta), u)
    np.testing.assert_array_equal(tau_c, result.tau_hat)
    np.testing.assert_array_equal(z_c, states)
    c.init(0.0, 0.0, 0.0)
    assert c.estimate(theta[0]) == result.tau_hat[0]
    assert c.velocity(theta[0]) == result.omega_hat[0]
    # a float build stays within the rounding bound of docs/deployment.md
    files = export_c(design, tmp_path / "f", prefix="pos", dtype="float")
    single = CObserver(
        *files, prefix="pos", dtype="float", observer=design, build_dir=tmp_path / "fl"
    )
    tau_f, z_f = single.drive(theta, np.zeros_like(theta), u)
    bound = export_error_bound(design, "float", theta, np.zeros_like(theta), u, z_f)
    assert np.all(np.abs(tau_f - result.tau_hat) <= bound)
    reason = sanitizer_available(tmp_path / "probe")
    if reason is not None:
        pytest.skip(reason)
    tau_s, _ = sanitized_run(
        source,
        prefix="pos",
        dtype="double",
        build_dir=tmp_path / "asan",
        theta=theta,
        omega=np.zeros_like(theta),
        u=u,
        observer=design,
    )
    np.testing.assert_array_equal(tau_s, result.tau_hat)


# -- noise --------------------------------------------------------------------------------


def test_noise_gains_match_monte_carlo():
    """White angle noise through the closed loop on the nominal plant: the RMS of the estimate
    and of the command match the exact noise gains within 3 % (200 s of samples)."""
    design = position(1)
    sigma = 1e-4
    loop = {
        "plant": NOMINAL,
        "nominal": NOMINAL,
        "Ts": TS,
        "controller": PD_OMEGA_HAT,
        "observer": design,
    }
    gains = noise_gains(**loop)
    assert gains.tau_hat_position == pytest.approx(
        observer_noise_gain(design, noise="position"), rel=1e-10
    )  # on the nominal plant the estimate's noise does not depend on the controller
    assert observer_noise_gain(design, noise="encoder") == observer_noise_gain(
        design, noise="position"
    )
    result = simulate(
        **loop,
        duration=200.0,
        reference=Ramp(0.0, 0.0),
        sensor=Encoder(2**40, noise_std=sigma, seed=7),
    )
    steady = slice(1000, None)
    assert np.sqrt(np.mean(result.tau_hat[steady] ** 2)) == pytest.approx(
        gains.tau_hat_position * sigma, rel=0.03
    )
    assert np.sqrt(np.mean(result.u[steady] ** 2)) == pytest.approx(
        gains.u_position * sigma, rel=0.03
    )


def test_quantisation_acts_as_white_noise_of_std_q_over_sqrt12():
    """A real 16384-count quantiser: on a shaft turning at a constant speed v the quantisation
    error is a sawtooth of frequency frac(v Ts / q) (not white: one run alone misses the white
    prediction by up to 35 %), but over speeds drawn at random its mean power spectrum is flat.
    Monte Carlo over 256 seeded speeds: the estimate (and the command) differ from those of
    ideal-sensor runs (a linear loop: the difference is the response to the quantisation
    error) by the noise gain times q/sqrt(12), within 5 %."""
    design = position(2)
    q = 2 * math.pi / 16384
    loop = {
        "plant": NOMINAL,
        "nominal": NOMINAL,
        "Ts": TS,
        "controller": PD_OMEGA_HAT,
        "observer": design,
    }
    gains = noise_gains(**loop)
    rng = np.random.default_rng(0)
    power = np.zeros(2)
    speeds = rng.uniform(0.5, 5.0, 256)  # rad/s
    for v in speeds:
        common = {**loop, "duration": 2.0, "reference": Ramp(0.0, v)}
        ideal, quantised = simulate(**common), simulate(**common, sensor=Encoder(16384))
        for i, name in enumerate(("tau_hat", "u")):
            gap = (getattr(quantised, name) - getattr(ideal, name))[1000:]
            power[i] += np.mean(gap**2) / speeds.size
    white = q / math.sqrt(12)
    assert math.sqrt(power[0]) == pytest.approx(gains.tau_hat_position * white, rel=0.05)
    assert math.sqrt(power[1]) == pytest.approx(gains.u_position * white, rel=0.05)
    # one constant speed alone is not white: 0.37 rad/s misses by +34 % (docs/analysis.md 8)
    common = {**loop, "duration": 20.0, "reference": Ramp(0.0, 0.37)}
    gap = (simulate(**common, sensor=Encoder(16384)).tau_hat - simulate(**common).tau_hat)[2000:]
    assert np.sqrt(np.mean(gap**2)) > 1.3 * gains.tau_hat_position * white


def test_position_only_beats_the_differenced_velocity_on_the_same_angle_noise():
    """Per unit angle noise the paper's HPDOb on a differenced velocity passes ~1/Ts more into
    its estimate than the position-only HPDOb at the same bandwidth (docs/analysis.md 8)."""
    state = design_observer(MODEL, order=1, bandwidth=100.0)
    pos = position(1, bandwidth=100.0)
    assert (
        observer_noise_gain(pos, noise="position")
        < observer_noise_gain(state, noise="encoder") / 20
    )


# -- the virtual experiment ------------------------------------------------------------------


def test_virtual_experiment_position_meets_the_targets():
    """Issue 12 targets, with margin: RMS estimation error <= 2.0e-3 N m and RMS position
    error <= 7.1e-3 rad in both windows (measured 1.62e-3, 3.31e-3, 2.57e-3: benchmarks/
    bench_virtual_experiment.py); order 1 beats order 0 at equal bandwidth under the encoder."""
    metrics = paper.run("virtual-experiment-position").metrics()
    assert metrics["rms_estimation_error"] <= 2.0e-3 * 0.9
    assert metrics["rms_position_error_regulation"] <= 7.1e-3 * 0.6
    assert metrics["rms_position_error_tracking"] <= 7.1e-3 * 0.6
    assert paper.observer("virtual-experiment-position").measurement == "position"
    orders = []
    for m in (0, 1):
        obs = DisturbanceObserver(
            paper.NOMINAL.discretize(TS), order=m, bandwidth=150.0, measurement="position"
        )
        orders.append(paper.run("virtual-experiment-position", observer=obs.design).metrics())
    for key in orders[0]:
        assert orders[1][key] < 0.6 * orders[0][key], key


# -- every consumer ----------------------------------------------------------------------------


def test_analysis_views_take_a_position_only_loop():
    design = position(1)
    plant = ServoModel(3.06e-4, 5e-5)
    loop = ServoLoop(
        plant=NOMINAL, nominal=NOMINAL, Ts=TS, controller=PD_OMEGA_HAT, observer=design
    )
    # separation on the nominal plant: PD poles and the observer's placed poles
    poles = closed_loop_poles(loop)
    pd_only = closed_loop_poles(loop.replace(observer=None, controller=PD(50.0, 5.0)))
    expected = np.concatenate([pd_only, design.poles])
    np.testing.assert_allclose(np.poly(poles), np.poly(expected), rtol=0, atol=1e-10)
    true = loop.replace(plant=plant)
    assert closed_loop(true).ninputs == 6
    assert gang_of_four(true).S.dt == TS
    margins = loop_margins(true)
    assert 0 < margins.delay_margin < 0.1 and margins.gain_margin > 1
    smap = robust_stability_map(
        J_ratio=[0.05, 1.0, 8.0],
        bandwidth=[100.0, 150.0],
        order=1,
        nominal=NOMINAL,
        Ts=TS,
        controller=PD_OMEGA_HAT,
        measurement="position",
    )
    assert smap.measurement == "position"
    np.testing.assert_array_equal(smap.stable[1], [True, True])
    assert not smap.stable[0].any()
    radius = np.abs(closed_loop_poles(loop.replace(observer=position(1, bandwidth=100.0)))).max()
    assert smap.radius_at(1.0, 100.0) == pytest.approx(radius, rel=1e-12)


def test_sweep_toml_and_cli(tmp_path, capsys):
    import json

    from hpdob import sweep
    from hpdob.cli import main
    from hpdob.simulation._scenario import scenario_from_dict

    base = {
        **paper.scenario(),
        "duration": 1.0,
        "sensor": paper.VIRTUAL_SENSOR,
        "observer": {"order": 1, "bandwidth": 100.0, "gain_direction": (1.0, 1.0)},
    }
    rows = sweep(
        base,
        grid={"observer.measurement": ["state", "position"], "observer.bandwidth": [100.0, 150.0]},
        progress=False,
    )
    assert list(rows["error"]) == [""] * 4
    kwargs = {**paper.scenario(), "duration": 1.0, "sensor": paper.VIRTUAL_SENSOR}
    for _, row in rows.iterrows():
        obs = DisturbanceObserver(
            paper.NOMINAL.discretize(TS),
            order=1,
            bandwidth=row["observer.bandwidth"],
            measurement=row["observer.measurement"],
        )
        direct = simulate(**kwargs, observer=obs.design).metrics()
        assert row["rms_estimation_error"] == direct["rms_estimation_error"]
    data = {
        "Ts": 1e-3,
        "duration": 0.5,
        "plant": {"J": 3.06e-4, "b": 5e-5},
        "nominal": {"J": 2.8e-4},
        "controller": {"kp": 50.0, "kd": 5.0, "velocity": "observer"},
        "reference": {"type": "step", "time": 0.1, "amplitude": 1.0},
        "observer": {
            "order": 2,
            "bandwidth": 150.0,
            "measurement": "position",
            "velocity_bandwidth": 200.0,
        },
    }
    scenario = scenario_from_dict(data)
    assert scenario["observer"].velocity_bandwidth == 200.0  # the design: a value
    assert scenario["observer"].system.measures == ("theta",)
    with pytest.raises(ParameterValueError, match=r"^observer\.measurement must be one of"):
        scenario_from_dict(
            {**data, "observer": {"order": 1, "bandwidth": 9.0, "measurement": "angle"}}
        )
    assert main(["design", "--measurement", "position", "--order", "2", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["measurement"] == "position" and len(summary["poles"]) == 5
    assert main(["design", "--measurement", "position", "--velocity-bandwidth", "300"]) == 0
    assert "velocity bandwidth 300 rad/s" in capsys.readouterr().out
    out = tmp_path / "c"
    assert main(["export-c", "--measurement", "position", "--order", "1", "-o", str(out)]) == 0
    assert "dob_velocity(&s, theta)" in (out / "dob.h").read_text()
    assert main(["design", "--measurement", "position", "--poles", "0.9,0.9"]) == 2
    assert "poles must have order + 3 = 4 entries" in capsys.readouterr().err
    # simulate: the scenario file's observer switched to position-only, the PD to omega_hat
    toml = Path(__file__).resolve().parents[2] / "examples" / "canonical_hpdob.toml"
    argv = ["simulate", str(toml), "--measurement", "position", "--pd-velocity", "observer"]
    assert main([*argv, "--no-plot", "--out", str(tmp_path / "sim")]) == 0
    got = json.loads((tmp_path / "sim" / "metrics.json").read_text())["HPDOb-100"]
    obs = DisturbanceObserver(
        paper.NOMINAL.discretize(TS), order=1, bandwidth=100.0, measurement="position"
    )
    expected = paper.run("HPDOb-100", observer=obs.design, controller=PD_OMEGA_HAT).metrics()
    assert got == pytest.approx(expected, rel=1e-12)


def test_estimate_cli_runs_a_position_only_observer_over_a_log(tmp_path, capsys):
    """``hpdob estimate --measurement position``: the observer run offline over an encoder
    log reproduces the closed loop's own estimate (the log of virtual-experiment-position)."""
    import json

    from hpdob.cli import main

    result = paper.run("virtual-experiment-position", duration=2.0)
    rows = ["t,q,u"] + [f"{t!r},{q!r},{u!r}" for t, q, u in
                        zip(result.t.tolist(), result.theta_measured.tolist(),
                            result.u.tolist(), strict=True)]  # fmt: skip
    (tmp_path / "log.csv").write_text("\n".join(rows) + "\n")
    argv = ["estimate", str(tmp_path / "log.csv"), "--time", "t", "--position", "q", "--input",
            "u", "--J-n", "2.8e-4", "--order", "2", "--bandwidth", "150", "--measurement",
            "position", "--out", str(tmp_path / "out"), "--no-plot"]  # fmt: skip
    assert main(argv) == 0
    table = np.genfromtxt(tmp_path / "out" / "estimate.csv", delimiter=",", names=True)
    np.testing.assert_allclose(table["tau_hat"], result.tau_hat, rtol=1e-12, atol=1e-15)
    report = json.loads((tmp_path / "out" / "estimate.json").read_text())
    assert report["observer"]["measurement"] == "position"
    assert main([*argv, "--gain-direction", "0,1"]) == 2
    assert "gain_direction applies to measurement='state' only" in capsys.readouterr().err


def test_mujoco_loop_runs_the_position_only_observer():
    pytest.importorskip("mujoco")
    from hpdob import MujocoServo

    kwargs = paper.scenario()
    observer = design_observer(
        paper.NOMINAL.discretize(TS), order=1, bandwidth=150.0, measurement="position"
    )
    kwargs.update(
        plant=paper.PLANT.replace(coulomb=0.0),
        duration=1.5,
        observer=observer,
        controller=PD_OMEGA_HAT,
    )
    reference = simulate(**kwargs)
    result = simulate(**{**kwargs, "plant": MujocoServo(paper.PLANT.J, paper.PLANT.b)})
    for key in ("theta", "u", "tau_hat", "omega_hat"):
        a, b = getattr(result, key), getattr(reference, key)
        assert np.max(np.abs(a - b)) <= 1e-8 * np.max(np.abs(b)), key


# -- bad inputs ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "exc", "pattern"),
    [
        ({"poles": [0.9, 0.9]}, ValueError, r"^poles must have order \+ 3 = 4 entries for order 1"),
        (
            {"bandwidth": 100.0, "measurement": "angle"},
            ValueError,
            r"^measurement must be one of 'state', 'position'; got 'angle'",
        ),
        (
            {"bandwidth": 100.0, "gain_direction": (0, 1)},
            ValueError,
            r"^gain_direction applies to measurement='state' only",
        ),
        (
            {"poles": [0.9] * 4, "velocity_bandwidth": 50.0},
            ValueError,
            r"^velocity_bandwidth goes with bandwidth, not with poles",
        ),
        (
            {"bandwidth": 100.0, "velocity_bandwidth": -5.0},
            ValueError,
            r"^velocity_bandwidth must be a positive finite bandwidth .*-5\.0",
        ),
        ({"bandwidth": 100.0, "velocity_bandwidth": "fast"}, TypeError, r"^velocity_bandwidth"),
        ({}, ValueError, r"^give exactly one of poles \(order \+ 3 = 4 eigenvalues\)"),
        ({"poles": [0.9, 0.9, 0.5 + 0.1j, 0.5]}, ValueError, "complex-conjugate pairs"),
    ],
)
def test_bad_arguments(kwargs, exc, pattern):
    kwargs.setdefault("measurement", "position")
    with pytest.raises(exc, match=pattern):
        design_observer(MODEL, order=1, **kwargs)


def test_bad_measurements_name_the_parameter_and_change_nothing():
    pos = DisturbanceObserver(MODEL, order=1, bandwidth=100.0, measurement="position")
    before = pos.state
    with pytest.raises(ParameterValueError, match=r"^x must be one measured angle \[rad\]"):
        pos.update([0.1, 0.0], 0.0)
    with pytest.raises(ParameterValueError, match=r"^x must be one measured angle"):
        pos.estimate(np.array([0.1, 2.0]))
    np.testing.assert_array_equal(pos.state, before)
    state = DisturbanceObserver(MODEL, order=1, bandwidth=100.0)
    with pytest.raises(ParameterValueError, match=r"^x must be a measured state .* single number"):
        state.estimate(0.1)
    with pytest.raises(ParameterValueError, match=r"^x must be a measured state"):
        estimate(state, initial_state(state), np.float64(0.1))
    with pytest.raises(AttributeError, match="after estimate"):
        _ = pos.velocity
    with pytest.raises(ParameterValueError, match="velocity_bandwidth applies to measurement"):
        DisturbanceObserver(MODEL, order=1, bandwidth=100.0, velocity_bandwidth=50.0)
    with pytest.raises(ParameterValueError, match="noise must be 'position' or 'encoder'"):
        observer_noise_gain(pos, noise="velocity")
    with pytest.raises(ParameterTypeError, match="velocity_bandwidth"):
        DisturbanceObserver(
            MODEL, order=1, bandwidth=100.0, measurement="position", velocity_bandwidth=[1.0]
        )
