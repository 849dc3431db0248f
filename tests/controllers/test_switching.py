"""Position control in free space, force control on contact (issue 21 section 3): the latching
switch of the controller program (hpdob.controllers.Switch), one definition for the generated
Python and the compiled kernel, and the impact peak it leads to (contact_metrics)."""

from __future__ import annotations

import numpy as np
import pytest

from hpdob import (
    PD,
    Actuator,
    Environment,
    ParameterValueError,
    ServoLoop,
    SimulationDivergedWarning,
    closed_loop_poles,
    design_observer,
    export_c,
    paper,
    simulate,
)
from hpdob.controllers import ForceControl, PositionForceSwitch, ProgramBuilder
from hpdob.observers import reaction_torque_observer

TS = paper.TS
NOMINAL = paper.NOMINAL
J_N = NOMINAL.J
MODEL = NOMINAL.discretize(TS)
TAU_REF, THRESHOLD, SPEED = 0.05, 0.02, 0.1  # N m, N m, rad/s
LIMIT = paper.VIRTUAL_ACTUATOR.torque_limit


def _spec(threshold=THRESHOLD):
    return PositionForceSwitch(400.0, 40.0, 1000.0, kv=40.0, tau_ref=TAU_REF, threshold=threshold)


def _loop(spec=None, plant=None, actuator=paper.VIRTUAL_ACTUATOR):
    dob = design_observer(MODEL, order=1, bandwidth=100.0)
    observer = reaction_torque_observer(dob, friction=paper.PLANT, velocity_filter=100.0)
    return ServoLoop(plant=plant or paper.PLANT.replace(environment=Environment(10.0)),
                     nominal=NOMINAL, Ts=TS, observer=observer, controller=spec or _spec(),
                     sensor=paper.VIRTUAL_SENSOR, actuator=actuator)  # fmt: skip


def _ramp(t):
    """From the start angle toward the wall at 0 rad and beyond, at 0.1 rad/s."""
    return -0.02 + SPEED * t, SPEED + 0 * t, 0 * t


@pytest.fixture(scope="module")
def run():
    return simulate(_loop(), reference=_ramp, duration=1.5, x0=(-0.02, 0.0))


def test_command_is_the_pd_then_the_force_law(run):
    """The literal law: the PD (eq. of hpdob.PD) on the recorded signals up to the first
    sample whose tau_reac reaches the threshold, the force law with tau_ref from that sample
    on, for good (latched), each clipped by the actuator."""
    k = int(np.argmax(run.tau_reac >= THRESHOLD))
    assert run.tau_reac[k] >= THRESHOLD and k > 0
    assert run.in_contact[k]  # the switch trips on contact, not in free space (threshold)
    pd = J_N * (400.0 * (run.r - run.theta_measured) + 40.0 * (run.r_dot - run.omega_measured)
                + run.r_ddot) + run.tau_hat  # fmt: skip
    force = J_N * (1000.0 * (TAU_REF - run.tau_reac) - 40.0 * run.omega_measured) + run.tau_hat
    expected = np.clip(np.where(np.arange(len(run)) < k, pd, force), -LIMIT, LIMIT)
    np.testing.assert_allclose(run.u, expected, rtol=0, atol=1e-15)
    assert np.any(run.tau_reac[k:] < THRESHOLD)  # it latched: tau_reac fell back below


def test_kernel_is_the_generated_python_bit_for_bit(run):
    """The kernel's command at every sample is the generated Python's (the controller's own
    program, its latch carried by its update), to the last bit."""
    c = _loop().controller_system
    state = c.python.reset(-0.02, 0.0, 0.0)
    names = ("r", "r_dot", "r_ddot", "theta", "omega", "tau_hat", "tau_reac")
    columns = {"theta": run.theta_measured, "omega": run.omega_measured}
    columns.update({name: getattr(run, name) for name in ("r", "r_dot", "r_ddot", "tau_hat",
                                                          "tau_reac")})  # fmt: skip
    assert c.inputs == names
    commands = []
    for k in range(len(run)):
        values = [float(columns[name][k]) for name in names]
        command = c.python.command(state, *values)
        commands.append(min(max(command, -LIMIT), LIMIT))
        state = c.python.update(state, *values, commands[-1])
    np.testing.assert_array_equal(run.u, commands)
    assert state == (1.0,)


def test_latch_rule_in_python():
    c = _spec().design(NOMINAL, TS)
    free = (0.1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)  # r = 0.1 rad, nothing else
    pressed = (*free[:-1], THRESHOLD)  # tau_reac at the threshold: trips (>=)
    assert c.python.command((0.0,), *free) == pytest.approx(J_N * 400.0 * 0.1, rel=1e-15)
    force = J_N * (-1000.0 * THRESHOLD) + J_N * 1000.0 * TAU_REF
    assert c.python.command((0.0,), *pressed) == pytest.approx(force, rel=1e-14)
    assert c.python.command((1.0,), *free) == pytest.approx(J_N * 1000.0 * TAU_REF, rel=1e-15)
    assert c.python.update((0.0,), *free, 0.0) == (0.0,)
    assert c.python.update((0.0,), *pressed, 0.0) == (1.0,)
    assert c.python.update((1.0,), *free, 0.0) == (1.0,)
    # the matrices are the position mode's: the PD's feed-through, the latch a pole at 0
    pd = PD(400.0, 40.0).design(NOMINAL, TS)
    np.testing.assert_allclose(c.E[0, :-1], pd.E[0], rtol=1e-15)
    assert c.E[0, -1] == 0.0 and c.F.tolist() == [[0.0]]


def test_settles_on_tau_ref_and_reports_the_impact(run):
    """After the switch the contact torque settles on tau_ref; contact_metrics gives the first
    contact (the ramp reaches the wall at 0.2 s), the impact peak and its overshoot."""
    m = run.contact_metrics(TAU_REF)
    assert m["first_contact"] == pytest.approx(0.2, abs=0.01)
    k = int(np.argmax(run.in_contact > 0))
    assert m["impact_peak"] == np.max(run.tau_contact[k:]) > TAU_REF
    assert m["overshoot"] == pytest.approx(m["impact_peak"] - TAU_REF, rel=1e-15)
    assert m["overshoot_ratio"] == pytest.approx(m["overshoot"] / TAU_REF, rel=1e-15)
    assert np.max(np.abs(run.tau_contact[-500:] - TAU_REF)) < 0.01 * TAU_REF


def test_contact_metrics_without_contact_and_without_environment():
    free = simulate(_loop(), reference=lambda t: (-0.02 + 0 * t, 0 * t, 0 * t), duration=0.1,
                    x0=(-0.02, 0.0))  # fmt: skip
    assert all(np.isnan(v) for v in free.contact_metrics(TAU_REF).values())
    loop = ServoLoop(plant=paper.PLANT, nominal=NOMINAL, Ts=TS, controller=PD(400.0, 40.0))
    result = simulate(loop, reference=_ramp, duration=0.01)
    with pytest.raises(ParameterValueError, match=r"^contact_metrics needs a run against"):
        result.contact_metrics()


def test_a_diverged_switching_run_holds_the_samples_before_the_first_state_beyond_the_limit(
    monkeypatch,
):
    """A tenth of the inertia and no torque limit: the loop diverges (after contact). The
    result holds samples 0..n-1 and the state at t_n is the first beyond
    ``DIVERGENCE_LIMIT``, read off the same run with a larger limit (the generated loop's
    divergence exit ``return k + 1`` mutated to ``k ** 1`` survived without this test:
    docs/testing.md)."""
    import hpdob.simulation._simulate as module

    plant = paper.PLANT.replace(J=paper.PLANT.J / 10, environment=Environment(10.0))
    loop = _loop(plant=plant, actuator=Actuator(delay_samples=1))
    limit = module.DIVERGENCE_LIMIT
    with pytest.warns(SimulationDivergedWarning):
        res = simulate(loop, reference=_ramp, duration=2.0, x0=(-0.02, 0.0))
    monkeypatch.setattr(module, "DIVERGENCE_LIMIT", 1e3 * limit)
    with pytest.warns(SimulationDivergedWarning):
        longer = simulate(loop, reference=_ramp, duration=2.0, x0=(-0.02, 0.0))
    n = len(res)
    beyond = np.maximum(np.abs(longer.theta), np.abs(longer.omega)) > limit
    assert res.in_contact.any() and 1 < n < len(longer)
    assert not beyond[:n].any() and beyond[n]
    np.testing.assert_array_equal(res.theta, longer.theta[:n])


def test_analysis_sees_the_position_mode():
    """closed_loop_poles of the switching loop: the PD loop's, plus the latch's pole at 0."""
    plant = paper.PLANT.replace(coulomb=0.0)
    dob = design_observer(MODEL, order=1, bandwidth=100.0)
    observer = reaction_torque_observer(dob)
    poles = [np.sort_complex(closed_loop_poles(ServoLoop(plant=plant, nominal=NOMINAL, Ts=TS,
                                                         observer=observer, controller=c)))
             for c in (_spec(), PD(400.0, 40.0))]  # fmt: skip
    assert len(poles[0]) == len(poles[1]) + 1
    extra = [p for p in poles[0] if np.min(np.abs(poles[1] - p)) > 1e-9]
    assert len(extra) == 1 and abs(extra[0]) < 1e-12


def test_bad_inputs(tmp_path):
    with pytest.raises(ParameterValueError, match=r"^threshold must be a positive"):
        _spec(threshold=0.0)
    with pytest.raises(ParameterValueError, match=r"^tau_ref must be a finite"):
        PositionForceSwitch(1.0, 1.0, 1.0, tau_ref=np.nan, threshold=0.01)
    with pytest.raises(ParameterValueError, match=r"^kf must be a positive"):
        PositionForceSwitch(1.0, 1.0, 0.0, tau_ref=0.0, threshold=0.01)
    with pytest.raises(ParameterValueError, match=r"^kp must be a non-negative"):
        PositionForceSwitch(-1.0, 1.0, 1.0, tau_ref=0.0, threshold=0.01)
    spec = _spec()
    assert spec.position == PD(400.0, 40.0) and spec.force == ForceControl(1000.0, kv=40.0)
    with pytest.raises(ParameterValueError, match=r"has a latching switch, which export_c"):
        export_c(_spec().design(NOMINAL, TS), tmp_path)
    assert not list(tmp_path.iterdir())
    b = ProgramBuilder(("r",), ("latch",))
    b.signal("u", (1.0, "r"))
    with pytest.raises(ParameterValueError, match=r"^unknown signal 'v'"):
        b.switch(trigger="r", threshold=1.0, latch="latch", after="v")
    b.signal("w", (1.0, "r"))
    b.signal("u", (1.0, "w"))
    b.update("latch", (1.0, "latch"))
    b.switch(trigger="r", threshold=1.0, latch="latch", after="w")
    with pytest.raises(ParameterValueError, match=r"^program.switch.latch = 0: the latch state"):
        b.build(Ts=TS)
