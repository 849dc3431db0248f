"""The built-in two-link arm: its written-out dynamics against MuJoCo, and the N-joint loop
with a DOb per joint against a straightforward Python loop integrated by scipy."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from hpdob import PD, Actuator, Encoder, ParameterTypeError, ParameterValueError
from hpdob.robots import ArmLoop, ComputedTorque, JointSines, TwoLinkArm, simulate_arm

mujoco = pytest.importorskip("mujoco")

ARM = TwoLinkArm(m=(1.3, 0.9), l=(0.5, 0.4), lc=(0.22, 0.17), I=(0.021, 0.013), J=(0.05, 0.03),
                 b=(0.1, 0.05))  # fmt: skip
G0 = 9.81


def literal(q, qd):
    """M, C qd and g written from docs/robots.md again (not through the class)."""
    (m1, m2), (l1, _), (c1, c2), (I1, I2), (J1, J2) = ARM.m, ARM.l, ARM.lc, ARM.I, ARM.J
    co, si = math.cos(q[1]), math.sin(q[1])
    M = np.array([
        [m1 * c1**2 + I1 + J1 + m2 * (l1**2 + c2**2 + 2 * l1 * c2 * co) + I2,
         m2 * (c2**2 + l1 * c2 * co) + I2],
        [m2 * (c2**2 + l1 * c2 * co) + I2, m2 * c2**2 + I2 + J2],
    ])  # fmt: skip
    h = m2 * l1 * c2 * si
    C = np.array([-h * (2 * qd[0] * qd[1] + qd[1] ** 2), h * qd[0] ** 2])
    s12 = math.sin(q[0] + q[1])
    g = np.array(
        [(m1 * c1 + m2 * l1) * G0 * math.sin(q[0]) + m2 * c2 * G0 * s12, m2 * c2 * G0 * s12]
    )
    return M, C, g


def mujoco_terms(q, qd):
    model = mujoco.MjModel.from_xml_string(ARM.to_mjcf())
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = q, qd
    mujoco.mj_forward(model, data)
    M = np.zeros((2, 2))
    for j in range(2):
        unit = np.zeros(2)
        unit[j] = 1.0
        column = np.zeros(2)
        mujoco.mj_mulM(model, data, column, unit)
        M[:, j] = column
    bias = data.qfrc_bias.copy()
    data.qvel[:] = 0.0
    mujoco.mj_forward(model, data)
    jac = np.zeros((3, 2))
    mujoco.mj_jacSite(model, data, jac, None, 0)
    return M, bias, data.qfrc_bias.copy(), jac[[0, 2]], data.site_xpos[0][[0, 2]]


def test_dynamics_match_mujoco_and_the_written_equations():
    rng = np.random.default_rng(7)
    for _ in range(20):
        q, qd = rng.uniform(-math.pi, math.pi, 2), rng.uniform(-6.0, 6.0, 2)
        M, bias, gravity, jac, tip = mujoco_terms(q, qd)
        assert np.abs(ARM.mass_matrix(q) - M).max() <= 1e-9
        assert np.abs(ARM.coriolis(q, qd) + ARM.gravity_torque(q) - bias).max() <= 1e-9
        assert np.abs(ARM.gravity_torque(q) - gravity).max() <= 1e-9
        assert np.abs(ARM.jacobian(q) - jac).max() <= 1e-12
        assert np.abs(ARM.end_effector(q) - tip).max() <= 1e-12
        M2, C2, g2 = literal(q, qd)
        assert np.abs(ARM.mass_matrix(q) - M2).max() <= 1e-12
        assert np.abs(ARM.coriolis(q, qd) - C2).max() <= 1e-12
        assert np.abs(ARM.gravity_torque(q) - g2).max() <= 1e-12


def test_coriolis_transpose_is_the_energy_gradient_and_mdot_is_c_plus_ct():
    rng = np.random.default_rng(3)
    q, qd = rng.uniform(-2, 2, 2), rng.uniform(-3, 3, 2)
    step = 1e-6
    grad = []
    for i in range(2):
        dq = np.zeros(2)
        dq[i] = step
        energy = [0.5 * qd @ ARM.mass_matrix(q + s * dq) @ qd for s in (1, -1)]
        grad.append((energy[0] - energy[1]) / (2 * step))
    assert np.allclose(ARM.coriolis_transpose(q, qd), grad, atol=1e-8)
    Mdot = (ARM.mass_matrix(q + step * qd) - ARM.mass_matrix(q - step * qd)) / (2 * step)
    assert np.allclose(ARM.coriolis(q, qd) + ARM.coriolis_transpose(q, qd), Mdot @ qd, atol=1e-8)


def reference_loop(loop, duration, ref, tau_ext):
    """Per-joint observer (its matrices F, G, H, E), PD, limit and delay per joint, the plant
    integrated by scipy (DOP853, tight tolerance) over each sample with the torque held."""
    Ts, N = loop.Ts, 2
    K = round(duration / Ts) + 1
    t = np.arange(K) * Ts
    r, rd, rdd = ref(t)
    x = np.array([*loop.q0, 0.0, 0.0])
    s = [np.array(sys.N @ np.array([loop.q0[i], 0.0, 0.0])) for i, sys in enumerate(loop.systems)]
    out = {k: np.zeros((K, N)) for k in ("q", "u", "tau_hat", "tau_dn")}
    J_n, b_n = np.array(loop.nominal_inertia), np.array(loop.nominal_friction)

    def rhs(_, y, applied, load):
        M, C, g = literal(y[:2], y[2:])
        f = applied - load - C - g - np.array(ARM.b) * y[2:]
        return np.concatenate([y[2:], np.linalg.solve(M, f)])

    for k in range(K):
        q, qd = x[:2].copy(), x[2:].copy()
        u = np.zeros(N)
        for i in range(N):
            v = np.array([q[i], qd[i], 0.0])
            sys = loop.systems[i]
            est = float(sys.H[0] @ s[i] + sys.E[0] @ v)
            pd = loop.controllers[i]
            a = pd.kp * (r[k, i] - q[i]) + pd.kd * (rd[k, i] - qd[i]) + rdd[k, i]
            lim = loop.actuators[i].torque_limit or math.inf
            u[i] = min(max(J_n[i] * a + est, -lim), lim)
            v[2] = u[i]
            s[i] = sys.F @ s[i] + sys.G @ v
            out["tau_hat"][k, i] = est
        out["u"][k], out["q"][k] = u, q
        applied = np.array([out["u"][k - a.delay_samples, i] if k >= a.delay_samples else 0.0
                            for i, a in enumerate(loop.actuators)])  # fmt: skip
        load = -tau_ext(np.array([t[k] + Ts / 2]))[0]
        qdd = rhs(0, x, applied, -tau_ext(np.array([t[k]]))[0])[2:]
        out["tau_dn"][k] = u - b_n * qd - J_n * qdd
        sol = solve_ivp(rhs, (0, Ts), x, method="DOP853", rtol=1e-12, atol=1e-12,
                        args=(applied, load))  # fmt: skip
        x = sol.y[:, -1]
    return out


def test_loop_with_a_dob_per_joint_matches_a_python_reference():
    loop = ArmLoop(ARM, 1e-3, (PD(400.0, 40.0), PD(300.0, 35.0)),
                   observers=({"order": 0, "bandwidth": 80.0}, {"order": 1, "bandwidth": 120.0}),
                   nominal_friction=(0.08, 0.0), q0=(0.2, -0.3),
                   actuator=(Actuator(torque_limit=5.0), Actuator(delay_samples=1)))  # fmt: skip
    ref = JointSines(center=(0.2, -0.3), amplitude=(1.0, -0.8), frequency=(0.8, 1.1))

    def tau_ext(t):  # a constant external torque on joint 2 from 0.2 s (held: constant)
        return np.stack([np.zeros_like(t), np.where(t >= 0.2, 0.7, 0.0)], axis=1)

    result = simulate_arm(loop, duration=0.4, reference=ref, external=tau_ext, substeps=16)
    expected = reference_loop(loop, 0.4, ref, tau_ext)
    for name, got in (("q", result.q), ("u", result.u), ("tau_hat", result.tau_hat),
                      ("tau_dn", result.tau_dn)):  # fmt: skip
        scale = np.abs(expected[name]).max(axis=0)
        assert np.all(np.abs(got - expected[name]).max(axis=0) <= 1e-6 * scale), name
    assert np.abs(result.u[:, 0]).max() == 5.0  # the limit binds
    # eq. (3) per joint: tau_dn = u - b_n qd - J_n qdd holds by construction; the observers track it
    late = result.t >= 0.3
    assert np.abs(result.estimation_error[late]).max() < 0.05 * np.abs(result.tau_dn[late]).max()


def test_encoder_per_joint_quantises_and_differences():
    enc = Encoder(4096)
    loop = ArmLoop(ARM, 1e-3, PD(400.0, 40.0), sensor=(enc, None))
    ref = JointSines(center=(0.0, 0.0), amplitude=0.5, frequency=1.0)
    res = simulate_arm(loop, duration=0.2, reference=ref)
    counts = res.q_measured[:, 0] / enc.resolution
    assert np.allclose(counts, np.round(counts), atol=1e-9)
    assert np.abs(res.q_measured[:, 0] - res.q[:, 0]).max() <= enc.resolution / 2 + 1e-12
    assert np.allclose(res.qd_measured[1:, 0], np.diff(res.q_measured[:, 0]) / 1e-3)
    assert np.array_equal(res.q_measured[:, 1], res.q[:, 1])


def test_computed_torque_with_the_exact_model_tracks_closely():
    ref = JointSines(center=(0.0, 0.0), amplitude=(1.0, 1.0), frequency=(0.7, 1.1))
    pd = simulate_arm(ArmLoop(ARM, 1e-3, PD(400.0, 40.0)), duration=1.0, reference=ref)
    ct = simulate_arm(ArmLoop(ARM, 1e-3, ComputedTorque(ARM, 400.0, 40.0)), duration=1.0,
                      reference=ref)  # fmt: skip
    e_pd, e_ct = pd.metrics()["rms_position_error"], ct.metrics()["rms_position_error"]
    assert all(c < p / 50 for c, p in zip(e_ct, e_pd, strict=True))


def test_result_exports_and_plots():
    pytest.importorskip("pandas")
    loop = ArmLoop(ARM, 1e-3, PD(400.0, 40.0), observers={"order": 1, "bandwidth": 100.0})
    res = simulate_arm(loop, duration=0.05, reference=JointSines((0.0, 0.0)))
    frame = res.to_pandas()
    assert "tau_dn[elbow]" in frame.columns and len(frame) == len(res) == 51
    import matplotlib

    matplotlib.use("Agg")
    fig = res.plot()
    # one row per joint (error, command, disturbance), the time axis on the last row
    assert len(fig.axes) == 3 * len(res.joint_names) == 6
    assert [ax.get_xlabel() for ax in fig.axes[-3:]] == ["time [s]"] * 3
    assert "[N m]" in fig.axes[1].get_ylabel() and "elbow" in fig.axes[3].get_ylabel()
    truth, estimate = fig.axes[5].get_lines()  # the estimate drawn over the truth, unlike it
    assert truth.get_linewidth() > estimate.get_linewidth() and estimate.get_linestyle() == "--"
    assert not any(ax.get_legend() for ax in fig.axes) and len(fig.legends) == 1  # off the data
    plt_close(fig)


def test_a_numpy_array_of_observer_specs_is_a_list_of_them():
    """np.array([spec, spec]) is one spec per joint (not one object for every joint), and an
    array of the wrong length is refused by its length."""
    spec = {"order": 1, "bandwidth": 100.0}
    runs = [simulate_arm(ArmLoop(ARM, 1e-3, PD(400.0, 40.0), observers=specs), duration=0.05,
                         reference=JointSines((0.0, 0.0)), tau0="gravity")
            for specs in (np.array([spec, spec]), [spec, spec])]  # fmt: skip
    np.testing.assert_array_equal(runs[0].tau_hat, runs[1].tau_hat)
    with pytest.raises(ParameterValueError, match=r"observers must have one entry per joint \(2\)"
                       r", got 3"):  # fmt: skip
        ArmLoop(ARM, 1e-3, PD(400.0, 40.0), observers=np.array([spec] * 3))
    with pytest.raises(ParameterValueError, match=r"controller must have one entry per joint"):
        ArmLoop(ARM, 1e-3, np.array([PD(1.0, 1.0)] * 3, dtype=object))


def plt_close(fig):
    import matplotlib.pyplot as plt

    plt.close(fig)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"controller": (PD(1.0, 1.0),) * 3}, "controller must have one entry per joint (2)"),
        ({"observers": [{"order": 1, "bandwidth": 50.0}]}, "observers must have one entry per"),
        ({"nominal_inertia": (1.0, -1.0)}, "nominal_inertia[1] must be a positive finite inertia"),
        ({"actuator": [Actuator()] * 3}, "actuator must have one entry per joint (2), got 3"),
        ({"q0": (0.0,)}, "q0 must have one entry per joint (2)"),
    ],
)  # fmt: skip
def test_bad_per_joint_inputs_are_refused(kwargs, message):
    arguments = {"controller": PD(1.0, 1.0), **kwargs}
    with pytest.raises(ParameterValueError) as info:
        ArmLoop(ARM, 1e-3, **arguments)
    assert message in str(info.value)
    assert "\n" not in str(info.value)


def test_bad_arm_parameters_are_refused():
    with pytest.raises(ParameterValueError, match=r"m\[1\] must be positive finite masses"):
        TwoLinkArm(m=(1.0, -1.0), l=(1, 1), lc=(0.5, 0.5), I=(0.1, 0.1))
    with pytest.raises(ParameterValueError, match="l must have one entry per joint"):
        TwoLinkArm(m=(1.0, 1.0), l=(1, 1, 1), lc=(0.5, 0.5), I=(0.1, 0.1))
    with pytest.raises(ParameterTypeError, match="plant must be an arm"):
        ArmLoop(object(), 1e-3, PD(1.0, 1.0))


def test_bad_trajectories_are_refused():
    with pytest.raises(ParameterValueError, match="amplitude must have one entry per joint"):
        JointSines(center=(0.0, 0.0), amplitude=(1.0, 1.0, 1.0))
    with pytest.raises(ParameterValueError, match=r"frequency\[1\] must be a positive finite"):
        JointSines(center=(0.0, 0.0), frequency=(1.0, -1.0))
    with pytest.raises(ParameterValueError, match=r"amplitude\[0\] must be a finite swing"):
        JointSines(center=(0.0, 0.0), amplitude=(math.nan, 1.0))
    with pytest.raises(ParameterValueError, match="center must be one finite start angle"):
        JointSines(center=(math.inf, 0.0))
    loop = ArmLoop(ARM, 1e-3, PD(1.0, 1.0))
    with pytest.raises(ParameterValueError, match="reference's r must give an array of shape"):
        simulate_arm(loop, duration=0.01, reference=JointSines((0.0, 0.0, 0.0)))
    with pytest.raises(ParameterValueError, match="external must give an array of shape"):
        simulate_arm(loop, duration=0.01, reference=JointSines((0.0, 0.0)),
                     external=lambda t: np.zeros((len(t), 3)))  # fmt: skip


def test_replace_derives_defaults_again():
    loop = ArmLoop(ARM, 1e-3, PD(1.0, 1.0))
    moved = loop.replace(q0=(0.0, 1.0))
    assert moved.nominal_inertia == tuple(np.diag(ARM.mass_matrix((0.0, 1.0))))
    other = TwoLinkArm(m=(2.0, 1.0), l=(0.5, 0.4), lc=(0.22, 0.17), I=(0.021, 0.013))
    assert loop.replace(plant=other).nominal is other
    fixed = ArmLoop(ARM, 1e-3, PD(1.0, 1.0), nominal_inertia=(0.5, 0.1))
    assert fixed.replace(q0=(0.0, 1.0)).nominal_inertia == (0.5, 0.1)
