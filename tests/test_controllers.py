"""PD, PID, FilteredPD and ADRC through the controller protocol.

Each controller is checked against its equations written out in this file as a plain Python
step (``tests/zoh_loop.py`` closes the loop on the exact ZOH recurrence of a frictionless
plant), ADRC also against pyadrc itself (its ``StateSpace`` class, replayed on the recorded
measurement) and the closed-loop poles its design places; and every consumer of a controller
is exercised with the new ones: simulate, the MuJoCo loop, sweep, the linear analysis views,
TOML scenarios and ``hpdob simulate``.
"""

from __future__ import annotations

import ctypes
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from hpdob import (
    ADRC,
    PD,
    PID,
    Actuator,
    FilteredPD,
    ServoLoop,
    ServoModel,
    closed_loop,
    closed_loop_poles,
    paper,
    simulate,
    sweep,
)
from hpdob.controllers import LinearController
from hpdob.export import render_c
from hpdob.signals import Step
from hpdob.testing import STRICT_FLAGS, compile_c, find_compiler

sys.path.insert(0, str(Path(__file__).resolve().parent))
from zoh_loop import reference_step, zoh_loop

TS = 1e-3
PLANT = ServoModel(3.0e-4, 4e-5)  # no Coulomb friction: the ZOH recurrence is exact
NOMINAL = ServoModel(2.8e-4)
DISTURBANCE = Step(0.5, 0.02)  # at a sample instant
N = 800


def run(controller, *, limit=None, disturbance=DISTURBANCE, n=N):
    loop = ServoLoop(plant=PLANT, nominal=NOMINAL, Ts=TS, controller=controller,
                     actuator=Actuator(torque_limit=limit))  # fmt: skip
    return simulate(loop, reference=reference_step, disturbance=disturbance, duration=n * TS)


def check_against(result, theta, u):
    np.testing.assert_allclose(result.theta, theta, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(result.u, u, rtol=1e-9, atol=1e-12 * np.abs(u).max())


# -- PD -------------------------------------------------------------------------------------
def test_pd_program_is_its_equation_bit_for_bit():
    rng = np.random.default_rng(3)
    for kp, kd, ff in ((50.0, 5.0, True), (0.0, 7.5, False), (1234.5, 0.0, True)):
        pd = PD(kp, kd, feedforward=ff)
        command = pd.design(NOMINAL, TS).python.command
        for r, rd, rdd, th, om, tau in rng.normal(size=(20, 6)):
            inputs = (r, rd, *((rdd,) if ff else ()), th, om, tau)
            want = pd.torque(J_n=NOMINAL.J, r=r, r_dot=rd, r_ddot=rdd, theta=th, omega=om,
                             tau_hat=tau)  # fmt: skip
            assert command((), *inputs) == want


def test_pd_is_stateless_and_names_its_inputs():
    c = PD(50, 5, velocity="observer").design(NOMINAL, TS)
    assert c.n_states == 0
    assert c.inputs == ("r", "r_dot", "r_ddot", "theta", "omega_hat", "tau_hat")
    assert c.program.signal_names == ("e", "e_dot", "a_ref", "u")


# -- PID ------------------------------------------------------------------------------------
def pid_step(kp, ki, kd, Tt, J_n):
    """The PID of the docstring: a = kp e + kd e' + I + r'', u = J_n a; back-calculation."""
    state = {"I": 0.0}

    def step(k, r, rd, rdd, th, om):
        e, ed = r - th, rd - om
        u = J_n * (kp * e + kd * ed + state["I"] + rdd)

        def commit(ub):
            state["I"] += ki * TS * e + TS / Tt * (ub - u) / J_n

        return u, commit

    return step


@pytest.mark.parametrize("limit", [None, 0.012])
def test_pid_is_its_equations(limit):
    pid = PID(400.0, 2000.0, 40.0)
    Tt = pid.tracking_time_for(TS)
    assert Tt == pytest.approx(math.sqrt(40.0 / 2000.0))
    result = run(pid, limit=limit)
    step = pid_step(400.0, 2000.0, 40.0, Tt, NOMINAL.J)
    theta, _, u = zoh_loop(PLANT, TS, N, reference_step, step, disturbance=DISTURBANCE,
                           limit=limit)  # fmt: skip
    if limit is not None:
        assert np.sum(np.abs(result.u) == limit) > 20  # the limit is active
    check_against(result, theta, u)


def test_pid_integral_removes_the_steady_state_error():
    pd, pid = run(PD(400.0, 40.0), n=3000), run(PID(400.0, 2000.0, 40.0), n=3000)
    assert abs(pd.r[-1] - pd.theta[-1]) > 0.1  # the load torque shifts a PD alone
    assert abs(pid.r[-1] - pid.theta[-1]) < 1e-4


def test_back_calculation_limits_the_windup_overshoot():
    """A large step against the torque limit: with the default tracking time the overshoot
    is far smaller than with (practically) none."""
    overshoot = []
    for Tt in (None, 1e6):
        result = run(PID(400.0, 4000.0, 40.0, tracking_time=Tt), limit=0.008, disturbance=None)
        overshoot.append(result.theta.max() - 1.0)
    assert overshoot[1] > 0.05
    assert overshoot[0] < 0.5 * overshoot[1]


@pytest.mark.parametrize(
    ("kwargs", "pattern"),
    [
        ({"ki": 0.0}, r"^ki must be a positive integral gain \[1/s\^3\], got 0.0"),
        ({"tracking_time": -1.0}, r"^tracking_time must be a positive tracking time"),
        ({"kp": -1.0}, r"^kp must be a non-negative finite gain"),
    ],
)
def test_pid_bad_arguments(kwargs, pattern):
    with pytest.raises(ValueError, match=pattern):
        PID(**{"kp": 50.0, "ki": 100.0, "kd": 5.0, **kwargs})


def test_pid_tracking_time_below_Ts_is_refused_by_the_loop():
    with pytest.raises(ValueError, match=r"^tracking_time must be at least Ts = 0.001 s"):
        ServoLoop(plant=PLANT, nominal=NOMINAL, Ts=TS,
                  controller=PID(50.0, 100.0, 5.0, tracking_time=1e-4))  # fmt: skip


# -- FilteredPD -----------------------------------------------------------------------------
def test_filtered_pd_is_its_equations():
    kp, kd, Tf = 400.0, 40.0, 3e-3
    a = math.exp(-TS / Tf)
    state = {"d": 0.0}  # d_{-1} = -omega_0 = 0

    def step(k, r, rd, rdd, th, om):
        d = a * state["d"] + (1 - a) * (rd - om)
        u = NOMINAL.J * (kp * (r - th) + kd * d + rdd)

        def commit(ub):
            state["d"] = d

        return u, commit

    theta, _, u = zoh_loop(PLANT, TS, N, reference_step, step, disturbance=DISTURBANCE)
    check_against(run(FilteredPD(kp, kd, time_constant=Tf)), theta, u)


def test_filtered_pd_without_filter_is_the_pd_bit_for_bit():
    """exp(-Ts/T_f) underflows to 0: d = 0 d + 1 e' is e' exactly."""
    a, b = run(PD(400.0, 40.0)), run(FilteredPD(400.0, 40.0, time_constant=1e-9))
    np.testing.assert_array_equal(a.u, b.u)


def test_filtered_pd_adds_its_pole_to_the_loop():
    loop = ServoLoop(plant=NOMINAL, nominal=NOMINAL, Ts=TS,
                     controller=FilteredPD(50.0, 5.0, time_constant=1e-2))  # fmt: skip
    poles = closed_loop_poles(loop)
    assert poles.size == 3 and np.all(np.abs(poles) < 1)


# -- ADRC -----------------------------------------------------------------------------------
def test_adrc_matrices_are_pyadrcs():
    pyadrc = pytest.importorskip("pyadrc")
    adrc = ADRC(40.0, observer_bandwidth=200.0)
    m = adrc.matrices(NOMINAL, TS)
    peer = pyadrc.StateSpace(2, TS, 1 / NOMINAL.J, 40.0, 200.0 / 40.0)
    np.testing.assert_allclose(m["L"], peer.L.ravel(), rtol=1e-12)
    np.testing.assert_allclose(m["Ao"], peer.oA, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(m["Bo"], peer.oB.ravel(), rtol=1e-12)
    assert (m["kp"], m["kd"]) == pytest.approx((peer.Kp, peer.Kd))


@pytest.mark.parametrize("limit", [None, 0.01])
def test_adrc_in_the_loop_is_pyadrc(limit):
    """Replay pyadrc's StateSpace on the run's measurements (y_k, u_{k-1}, r_k): it returns the
    run's commands (its own magnitude limit on the same limit)."""
    pyadrc = pytest.importorskip("pyadrc")
    result = run(ADRC(40.0, observer_bandwidth=200.0), limit=limit)
    lim = (None, None) if limit is None else (-limit, limit)
    peer = pyadrc.StateSpace(2, TS, 1 / NOMINAL.J, 40.0, 5.0, m_lim=lim)
    u_prev, got = 0.0, []
    for y, r in zip(result.theta_measured, result.r, strict=True):
        u_prev = peer(float(y), u_prev, float(r))
        got.append(u_prev)
    if limit is not None:
        assert np.sum(np.abs(result.u) == limit) > 10
    else:
        assert abs(result.theta[-1] - 1.0) < 1e-3  # it rejects the load step (ESO)
    scale = np.abs(result.u).max()
    np.testing.assert_allclose(result.u, got, rtol=0, atol=1e-9 * scale)


def test_adrc_places_the_closed_loop_poles():
    """On the nominal double integrator the loop separates: the state feedback's poles
    eig(Ad - Bd K) and the ESO's triple pole exp(-w_o Ts)."""
    wc, wo = 30.0, 150.0
    loop = ServoLoop(plant=NOMINAL, nominal=NOMINAL, Ts=TS,
                     controller=ADRC(wc, observer_bandwidth=wo))  # fmt: skip
    A2 = np.array([[1.0, TS], [0.0, 1.0]])
    B2 = np.array([[TS**2 / 2], [TS]])  # b0 u = acceleration
    feedback = np.linalg.eigvals(A2 - B2 @ np.array([[wc**2, 2 * wc]]))
    expected = np.poly(np.concatenate([feedback, [math.exp(-wo * TS)] * 3]))
    np.testing.assert_allclose(np.poly(closed_loop(loop).A), expected, rtol=0, atol=1e-9)
    assert closed_loop_poles(loop).size == 5


# -- consumers ------------------------------------------------------------------------------
def test_sweep_varies_any_controller_parameter():
    loop = ServoLoop(plant=PLANT, nominal=NOMINAL, Ts=TS, controller=PID(400.0, 1.0, 40.0))
    base = {"loop": loop, "reference": reference_step, "disturbance": DISTURBANCE,
            "duration": N * TS}  # fmt: skip
    windows = {"regulation": (0.4, 0.8), "tracking": (0.0, 0.4)}
    rows = sweep(base, grid={"controller.ki": [500.0, 2000.0]}, metric_windows=windows,
                 progress=False, scheduler=1)  # fmt: skip
    key = "rms_position_error_regulation"
    for ki, got in zip((500.0, 2000.0), rows[key], strict=True):
        assert got == run(PID(400.0, ki, 40.0)).metrics(**windows)[key]
    with pytest.raises(ValueError, match="a PID has no parameter 'bandwidth'"):
        sweep(base, grid={"controller.bandwidth": [1.0]}, progress=False)


def test_mujoco_loop_runs_the_controllers():
    pytest.importorskip("mujoco")
    from hpdob import MujocoServo

    for controller in (PID(400.0, 2000.0, 40.0), ADRC(40.0)):
        kwargs = {"nominal": NOMINAL, "Ts": TS, "controller": controller,
                  "actuator": Actuator(torque_limit=0.012)}  # fmt: skip
        rigid = simulate(ServoLoop(plant=PLANT, **kwargs), reference=reference_step,
                         disturbance=DISTURBANCE, duration=0.5)  # fmt: skip
        mj = simulate(ServoLoop(plant=MujocoServo(PLANT.J, PLANT.b), **kwargs),
                      reference=reference_step, disturbance=DISTURBANCE, duration=0.5)  # fmt: skip
        np.testing.assert_allclose(mj.theta, rigid.theta, rtol=0, atol=1e-8)
        np.testing.assert_allclose(mj.u, rigid.u, rtol=0, atol=1e-8 * np.abs(rigid.u).max())


SCENARIO = """
Ts = 0.001
duration = 0.8
[plant]
J = 3.0e-4
b = 4e-5
[nominal]
J = 2.8e-4
[controller]
{controller}
[actuator]
torque_limit = 0.012
[[reference]]
type = "smooth_step"
start = 0.1
end = 0.3
amplitude = 1.0
"""


@pytest.mark.parametrize(
    ("table", "controller"),
    [
        ('type = "pid"\nkp = 400.0\nki = 2000.0\nkd = 40.0', PID(400.0, 2000.0, 40.0)),
        ('type = "filtered-pd"\nkp = 400.0\nkd = 40.0\ntime_constant = 0.003',
         FilteredPD(400.0, 40.0, time_constant=0.003)),
        ('type = "adrc"\nbandwidth = 40.0', ADRC(40.0)),
        ("kp = 400.0\nkd = 40.0", PD(400.0, 40.0)),
    ],
)  # fmt: skip
def test_scenario_files_name_the_controller_type(tmp_path, table, controller):
    from hpdob.simulation import load_scenario

    path = tmp_path / "run.toml"
    path.write_text(SCENARIO.format(controller=table))
    scenario = load_scenario(path)
    assert scenario.loop.controller == controller
    expected = simulate(scenario.loop.replace(controller=controller), **scenario.run)
    np.testing.assert_array_equal(simulate(scenario.loop, **scenario.run).u, expected.u)


def test_scenario_rejects_an_unknown_controller_type(tmp_path):
    from hpdob.simulation import load_scenario

    path = tmp_path / "run.toml"
    path.write_text(SCENARIO.format(controller='type = "lqr"\nkp = 1.0'))
    with pytest.raises(ValueError, match=r"^controller.type must be one of 'pd', 'pid'"):
        load_scenario(path)
    path.write_text(SCENARIO.format(controller='type = "pid"\nkp = 1.0\nkd = 1.0'))
    with pytest.raises(ValueError, match=r"missing required key controller.ki"):
        load_scenario(path)


def test_cli_simulate_runs_a_pid_scenario(tmp_path, capsys):
    from hpdob.cli import main

    path = tmp_path / "pid.toml"
    path.write_text(SCENARIO.format(controller='type = "pid"\nkp = 400.0\nki = 2000.0\nkd = 40.0'))
    assert main(["simulate", str(path), "--no-plot", "--out", str(tmp_path / "out")]) == 0
    assert any((tmp_path / "out").iterdir())


def test_a_controller_needs_the_loop_signals_it_names():
    c = LinearController(F=[], G=[], H=[], E=[[1.0]], N=[], Ts=TS, inputs=("tau_reac",))
    with pytest.raises(ValueError, match=r"^controller input 'tau_reac' must be a loop signal"):
        ServoLoop(plant=PLANT, nominal=NOMINAL, Ts=TS, controller=c)
    with pytest.raises(ValueError, match=r"^controller must run at the loop's sampling period"):
        ServoLoop(plant=PLANT, nominal=NOMINAL, Ts=2 * TS, controller=PD(1, 1).design(NOMINAL, TS))


def test_canonical_scenario_still_uses_the_pd():
    assert paper.scenario()["controller"] == PD(50.0, 5.0)


@pytest.mark.skipif(find_compiler() is None, reason="no C compiler")
@pytest.mark.parametrize(
    "controller",
    [PD(50.0, 5.0), PID(50.0, 100.0, 5.0, velocity="observer"),
     FilteredPD(50.0, 5.0, time_constant=2e-3), ADRC(40.0, feedforward=True)],
)  # fmt: skip
def test_exported_c_builds_strictly_and_is_the_program(tmp_path, controller):
    system = controller.design(NOMINAL, TS)
    header, source = render_c(system, prefix="ctl")
    (tmp_path / "ctl.h").write_text(header)
    (tmp_path / "ctl.c").write_text(source)
    flags = (*STRICT_FLAGS, "-ffp-contract=off")
    lib = ctypes.CDLL(str(compile_c([tmp_path / "ctl.c"], tmp_path / "lib.so", flags=flags,
                                    shared=True)))  # fmt: skip
    d, p = ctypes.c_double, len(system.inputs)
    lib.ctl_init.argtypes = [ctypes.c_void_p, d, d, d]
    lib.ctl_command.argtypes = [ctypes.c_void_p, *[d] * p]
    lib.ctl_command.restype = d
    lib.ctl_update.argtypes = [ctypes.c_void_p, *[d] * (p + 1)]
    state = (d * max(system.n_states, 1))()
    lib.ctl_init(state, 0.1, -0.2, 0.003)
    c = system.python.reset(0.1, -0.2, 0.003)
    for v in np.random.default_rng(1).normal(size=(30, p)).tolist():
        u = lib.ctl_command(state, *v)
        assert u == system.python.command(c, *v)
        lib.ctl_update(state, *v, 0.9 * u)
        c = system.python.update(c, *v, 0.9 * u)
    assert tuple(state)[: system.n_states] == c


def test_tune_verifies_with_any_controller():
    """tune's candidates are analysed and simulated with the given controller (a PID here):
    the recommendation's closed loop holds its integrator state."""
    from hpdob import tune

    pid = PID(50.0, 100.0, 5.0, velocity="observer")
    r = tune(nominal=NOMINAL, Ts=TS, families=["state"], controller=pid,
             scenario={"reference": paper.REFERENCE, "duration": 0.5})  # fmt: skip
    assert r.settings["controller"]["type"] == "PID" and r.settings["controller"]["ki"] == 100.0
    assert r.controller in (pid, PID(50.0, 100.0, 5.0))  # the velocity falls back if needed
    loop = ServoLoop(plant=NOMINAL, nominal=NOMINAL, Ts=TS, controller=r.controller,
                     observer=r.recommended["_design"])  # fmt: skip
    assert "controller_integral" in closed_loop(loop).state_labels


def test_margins_see_the_integrators_phase_lag():
    """The PID's integral adds phase lag at crossover: less phase margin than the PD's at the
    same kp, kd; both loops stable, and the loop gain has the PID's extra state."""
    from hpdob import loop_margins, loop_transfer

    def loop(controller):
        return ServoLoop(plant=PLANT, nominal=NOMINAL, Ts=TS, controller=controller,
                         actuator=Actuator(delay_samples=1))  # fmt: skip

    pd, pid = loop_margins(loop(PD(400.0, 40.0))), loop_margins(loop(PID(400.0, 2000.0, 40.0)))
    assert pd.stable and pid.stable
    assert pid.phase_margin < pd.phase_margin
    assert loop_transfer(loop(PID(400.0, 2000.0, 40.0))).nstates == \
        loop_transfer(loop(PD(400.0, 40.0))).nstates + 1  # fmt: skip


def test_a_loop_with_a_controller_pickles():
    """Sweeps on a dask cluster ship the loop: the controller's generated code is rebuilt."""
    import pickle

    loop = ServoLoop(plant=PLANT, nominal=NOMINAL, Ts=TS, controller=PID(400.0, 2000.0, 40.0))
    assert loop.controller_system.python.command  # the generated code exists before pickling
    copy = pickle.loads(pickle.dumps(loop))
    a = simulate(loop, reference=reference_step, duration=0.2)
    b = simulate(copy, reference=reference_step, duration=0.2)
    np.testing.assert_array_equal(a.u, b.u)


@pytest.mark.parametrize(
    "controller",
    [PD(400.0, 40.0), PID(400.0, 2000.0, 40.0), FilteredPD(400.0, 40.0, time_constant=3e-3),
     ADRC(40.0, feedforward=True)],
    ids=["PD", "PID", "FilteredPD", "ADRC"],
)  # fmt: skip
def test_the_linear_loop_is_the_simulation(controller):
    """Without friction or limit, with the disturbance held over each sample, the analysis
    views' closed loop driven by the same signals is the simulated run (every controller, its
    states in the loop's state, with the HPDOb in the loop)."""
    control = pytest.importorskip("control")
    from hpdob import design_observer

    observer = design_observer(NOMINAL.discretize(TS), order=1, bandwidth=100.0)
    loop = ServoLoop(plant=PLANT, nominal=NOMINAL, Ts=TS, controller=controller,
                     observer=observer)  # fmt: skip
    result = simulate(loop, reference=reference_step, disturbance=DISTURBANCE, duration=N * TS)
    t = result.t
    r, rd, rdd = reference_step(t)
    inputs = np.vstack([r, rd, rdd, DISTURBANCE(t + TS / 2), 0 * t, 0 * t])
    response = control.forced_response(closed_loop(loop), T=t, U=inputs)
    theta, u = response.outputs[0], response.outputs[2]
    np.testing.assert_allclose(result.theta, theta, rtol=0, atol=1e-9 * np.abs(theta).max())
    np.testing.assert_allclose(result.u, u, rtol=0, atol=1e-9 * np.abs(u).max())
