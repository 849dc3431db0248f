"""A controller written from scratch against the protocol runs in every consumer.

The controller below is defined only here, by its matrices: a PI on the angle with a
dirty-derivative velocity and back-calculation anti-windup, plus the observer's estimate,

    u_k      = K (r_k - theta_k) + K_i c1_k - K_v (theta_k - c2_k) / T_f + tau_hat_k
    c1_{k+1} = c1_k + Ts (r_k - theta_k) + beta (u_bar_k - u_k)
    c2_{k+1} = c2_k + (Ts / T_f) (theta_k - c2_k),       c1_0 = 0, c2_0 = theta_0.

It runs in ``simulate`` (checked against the same equations in a plain Python loop, with the
observer stepped by the functional core), ``sweep``, ``closed_loop_poles`` (against the closed
loop assembled by hand) and C export (the compiled C replayed on the run's inputs gives its
commands bit for bit). A second controller reads an observer output by name (``omega_hat``
of a position-only observer), as a force controller will read a reaction-torque estimate.
"""

from __future__ import annotations

import ctypes
import sys
from pathlib import Path

import numpy as np
import pytest

from hpdob import (
    Actuator,
    LinearController,
    ServoLoop,
    ServoModel,
    closed_loop_poles,
    design_observer,
    estimate,
    initial_state,
    simulate,
    sweep,
    update,
)
from hpdob.controllers import ProgramBuilder
from hpdob.export import render_c
from hpdob.signals import Step
from hpdob.testing import STRICT_FLAGS, compile_c, find_compiler

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from zoh_loop import reference_step, zoh_loop

TS = 1e-3
PLANT = ServoModel(3.0e-4, 4e-5)
NOMINAL = ServoModel(2.8e-4)
K, KI, KV, TF = 0.1, 0.3, 0.004, 5e-3  # N m/rad, N m/(rad s), N m s/rad, s
BETA = TS / (0.05 * KI)  # back-calculation: tracking time 0.05 s
LIMIT = 0.02  # N m
DISTURBANCE = Step(0.5, 0.01)
N = 800


def from_scratch() -> LinearController:
    a = TS / TF
    H = [[KI, KV / TF]]
    E = [[K, -K - KV / TF, 1.0]]  # inputs r, theta, tau_hat
    F = [[1 - BETA * KI, -BETA * KV / TF], [0.0, 1 - a]]
    G = [[TS - BETA * K, -TS + BETA * (K + KV / TF), -BETA, BETA], [0.0, a, 0.0, 0.0]]
    N0 = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
    return LinearController(F=F, G=G, H=H, E=E, N=N0, Ts=TS, inputs=("r", "theta", "tau_hat"),
                            name="PI + dirty derivative")  # fmt: skip


OBSERVER = design_observer(NOMINAL.discretize(TS), order=1, bandwidth=100.0)


def loop(**changes):
    kwargs = {"plant": PLANT, "nominal": NOMINAL, "Ts": TS, "controller": from_scratch(),
              "observer": OBSERVER, "actuator": Actuator(torque_limit=LIMIT)}  # fmt: skip
    return ServoLoop(**{**kwargs, **changes})


def run(the_loop):
    return simulate(the_loop, reference=reference_step, disturbance=DISTURBANCE, duration=N * TS)


def python_loop():
    """The controller's equations and the observer's functional core, sample by sample."""
    c = {"c1": 0.0, "c2": 0.0}  # theta_0 = 0
    obs = {"s": initial_state(OBSERVER, (0.0, 0.0), 0.0)}

    def step(k, r, rd, rdd, th, om):
        tau_hat = estimate(OBSERVER, obs["s"], (th, om))
        u = K * (r - th) + KI * c["c1"] - KV * (th - c["c2"]) / TF + tau_hat

        def commit(ub):
            c["c1"], c["c2"] = (c["c1"] + TS * (r - th) + BETA * (ub - u),
                                c["c2"] + TS / TF * (th - c["c2"]))  # fmt: skip
            obs["s"] = update(OBSERVER, obs["s"], (th, om), ub)

        return u, commit

    return zoh_loop(PLANT, TS, N, reference_step, step, disturbance=DISTURBANCE, limit=LIMIT)


def test_simulate_runs_it_as_the_python_loop():
    result = run(loop())
    theta, _, u = python_loop()
    assert np.sum(np.abs(result.u) == LIMIT) > 20  # the anti-windup path is exercised
    np.testing.assert_allclose(result.theta, theta, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(result.u, u, rtol=1e-9, atol=1e-12)
    assert abs(result.theta[-1] - 1.0) < 0.1  # it tracks the 1 rad step


def test_sweep_runs_it():
    base = {"loop": loop(), "reference": reference_step, "disturbance": DISTURBANCE,
            "duration": N * TS}  # fmt: skip
    windows = {"regulation": (0.4, 0.8), "tracking": (0.0, 0.4)}
    rows = sweep(base, grid={"plant.J": [2.5e-4, 3.5e-4]}, metric_windows=windows,
                 progress=False, scheduler=1)  # fmt: skip
    key = "rms_position_error_tracking"
    for J, got in zip((2.5e-4, 3.5e-4), rows[key], strict=True):
        assert got == run(loop(plant=PLANT.replace(J=J))).metrics(**windows)[key]


def test_closed_loop_poles_are_the_hand_assembled_loop():
    """No observer, no limit: x' = A x + B u, u = H c + E_r r + E_th theta,
    c' = F c + G_v v + G_u u; with r = 0 the poles of the block matrix below."""
    controller = from_scratch()
    plant = PLANT.discretize(TS)
    A, B = plant.A, plant.B[:, None]
    C = np.array([[1.0, 0.0]])  # theta
    H, E, F, G = controller.H, controller.E, controller.F, controller.G
    E_th, G_th, G_u = E[:, 1:2], G[:, 1:2], G[:, 3:4]
    top = np.hstack([A + B @ E_th @ C, B @ H])
    bottom = np.hstack([(G_th + G_u @ E_th) @ C, F + G_u @ H])
    expected = np.sort_complex(np.linalg.eigvals(np.vstack([top, bottom])))
    got = np.sort_complex(closed_loop_poles(loop(observer=None, actuator=None)))
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)


@pytest.mark.skipif(find_compiler() is None, reason="no C compiler")
def test_exported_c_gives_the_runs_commands_bit_for_bit(tmp_path):
    controller = from_scratch()
    header, source = render_c(controller, prefix="ctl")
    (tmp_path / "ctl.h").write_text(header)
    (tmp_path / "ctl.c").write_text(source)
    flags = (*STRICT_FLAGS, "-ffp-contract=off")
    built = compile_c([tmp_path / "ctl.c"], tmp_path / "libctl.so", flags=flags, shared=True)
    lib = ctypes.CDLL(str(built))
    state = (ctypes.c_double * 2)()
    d = ctypes.c_double
    lib.ctl_init.argtypes = [ctypes.c_void_p, d, d, d]
    lib.ctl_command.argtypes = [ctypes.c_void_p, d, d, d]
    lib.ctl_command.restype = d
    lib.ctl_update.argtypes = [ctypes.c_void_p, d, d, d, d]
    result = run(loop())
    lib.ctl_init(state, 0.0, 0.0, 0.0)
    python = controller.python
    c = python.reset(0.0, 0.0, 0.0)
    for r, th, tau, u in zip(result.r, result.theta_measured, result.tau_hat, result.u,
                             strict=True):  # fmt: skip
        command = lib.ctl_command(state, r, th, tau)
        assert min(max(command, -LIMIT), LIMIT) == u
        assert python.command(c, r, th, tau) == command
        lib.ctl_update(state, r, th, tau, u)
        c = python.update(c, r, th, tau, u)
    assert tuple(state) == c


def test_a_controller_reads_an_observer_output_by_name():
    """u = -0.02 omega_hat: the loop wires the position-only observer's velocity estimate."""
    observer = design_observer(NOMINAL.discretize(TS), order=1, bandwidth=100.0,
                               measurement="position")  # fmt: skip
    damper = LinearController(F=[], G=[], H=[], E=[[-0.02]], N=[], Ts=TS, inputs=("omega_hat",))
    result = simulate(
        ServoLoop(plant=PLANT, nominal=NOMINAL, Ts=TS, controller=damper, observer=observer),
        reference=reference_step, duration=0.3, x0=(0.0, 2.0),
    )  # fmt: skip
    np.testing.assert_array_equal(result.u, -0.02 * result.omega_hat)
    assert abs(result.omega[-1]) < 0.5 * 2.0  # it damps
    with pytest.raises(ValueError, match=r"controller input 'omega_hat' must be a loop signal"):
        ServoLoop(plant=PLANT, nominal=NOMINAL, Ts=TS, controller=damper, observer=OBSERVER)


@pytest.mark.parametrize(
    ("kwargs", "pattern"),
    [
        ({"inputs": ("r", "r")}, r"^inputs must be distinct lower-case identifiers"),
        ({"inputs": ("R",)}, r"^inputs must be distinct lower-case identifiers"),
        ({"E": [[1.0, 2.0]]}, r"^E must have shape \(1, 1\)"),
        ({"Ts": 0.0}, r"^Ts must be a positive finite sampling period"),
        ({"F": [[np.nan]], "G": [[0.0, 0.0]], "H": [[0.0]], "N": [[0.0, 0.0, 0.0]]},
         r"^F must have finite entries"),
    ],
)  # fmt: skip
def test_bad_matrices_are_refused(kwargs, pattern):
    args = {"F": [], "G": [], "H": [], "E": [[1.0]], "N": [], "Ts": TS, "inputs": ("r",),
            **kwargs}  # fmt: skip
    with pytest.raises(ValueError, match=pattern):
        LinearController(**args)


def test_a_program_that_is_not_the_matrices_is_refused():
    good = from_scratch()
    with pytest.raises(ValueError, match=r"^program command rows sum to"):
        LinearController(**{**_fields(good), "E": [[K, -K, 1.0]], "program": good.program})


def _fields(c):
    return {"F": c.F, "G": c.G, "H": c.H, "E": c.E, "N": c.N, "Ts": c.Ts, "inputs": c.inputs}


def test_to_statespace_is_the_controller_without_a_limit():
    control = pytest.importorskip("control")
    controller = from_scratch()
    ss = controller.to_statespace()
    assert ss.input_labels == ["r", "theta", "tau_hat"] and ss.output_labels == ["u"]
    v = np.random.default_rng(2).normal(size=(3, 50))
    c0 = controller.python.reset(0.3, 0.0, 0.0)
    got = np.ravel(control.forced_response(ss, U=v, X0=c0).outputs)
    c, want = c0, []
    for column in v.T.tolist():
        want.append(controller.python.command(c, *column))
        c = controller.python.update(c, *column, want[-1])
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)


def test_an_extra_observer_output_is_wired_by_name():
    """Room for force control: a controller input named like an extra observer output reads
    it. LinearObserver accepts only tau_hat (and omega_hat) as output names today (issue 21
    adds a reaction-torque output), so the observer here gets its second output, half the
    estimate, and the name tau_reac set after construction. A PD on 2 tau_reac is then the
    PD on tau_hat bit for bit (halving is exact), in simulate and in the linear loop."""
    from hpdob import PD, LinearObserver, closed_loop

    dob = design_observer(NOMINAL.discretize(TS), order=1, bandwidth=100.0).system
    two = LinearObserver(F=dob.F, G=dob.G, H=np.vstack([dob.H, 0.5 * dob.H]),
                         E=np.vstack([dob.E, 0.5 * dob.E]), N=dob.N, Ts=TS,
                         outputs=("tau_hat", "omega_hat"), model=dob.model)  # fmt: skip
    object.__setattr__(two, "outputs", ("tau_hat", "tau_reac"))
    b = ProgramBuilder(("r", "r_dot", "r_ddot", "theta", "omega", "tau_reac"))
    b.signal("e", (1.0, "r"), (-1.0, "theta"))
    b.signal("e_dot", (1.0, "r_dot"), (-1.0, "omega"))
    b.signal("a_ref", (50.0, "e"), (5.0, "e_dot"), (1.0, "r_ddot"))
    b.signal("u", (NOMINAL.J, "a_ref"), (2.0, "tau_reac"))
    reaction = b.build(Ts=TS)
    runs, poles = [], []
    for controller in (PD(50.0, 5.0), reaction):
        the_loop = loop(controller=controller, observer=two, actuator=None)
        runs.append(run(the_loop))
        poles.append(np.sort_complex(np.linalg.eigvals(closed_loop(the_loop).A)))
    np.testing.assert_array_equal(runs[1].u, runs[0].u)
    np.testing.assert_allclose(poles[1], poles[0], rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match=r"controller input 'tau_reac' must be a loop signal"):
        loop(controller=reaction)
