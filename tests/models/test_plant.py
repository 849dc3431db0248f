"""The plant names the compiled sub-step path that advances it; the generic path is exact.

A plant defined here (a motor driving a flywheel through a viscous coupling: three states, so
neither specialised path applies) declares ``path="generic"`` in its :class:`ExactSubsteps`.
With its motor spinning far above the Coulomb friction's ``tanh`` scale the friction is the
constant ``c`` (``tanh(50) == 1.0`` in double precision), so the plant is linear with constant
inputs over each sample and the exact ZOH recurrence over a whole sample, computed here with
``scipy.linalg.expm``, is the reference. Planted bugs these tests catch (checked by hand):
doubling the friction term of the generic branch's full sub-step (fails the ZOH test: the
trajectory shifts by ``c`` N m) or of its midpoint (fails the comparison with the rigid
servo's own path near rest, where ``tanh`` is not saturated).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
import scipy.linalg

from hpdob import PD, Actuator, ServoLoop, ServoModel, simulate
from hpdob.models import ExactSubsteps, Plant
from hpdob.signals import Step

TS = 1e-3


@dataclass(frozen=True)
class DiscreteFlywheel:
    A: np.ndarray
    B: np.ndarray
    D: np.ndarray
    C: np.ndarray
    Ts: float
    state_names: tuple = ("theta", "omega", "omega_flywheel")


@dataclass(frozen=True)
class FlywheelServo(Plant):
    """J w' = u - b w - d (w - w_f) - c tanh(w/v) [- tau];  J_f w_f' = d (w - w_f) [- tau]."""

    J: float = 3.0e-4
    J_f: float = 6.0e-4
    b: float = 5e-5
    d: float = 2e-3
    coulomb: float = 0.01
    coulomb_velocity: float = 0.01
    on_load: bool = False  # the external torque acts on the flywheel

    state_names = ("theta", "omega", "omega_flywheel")

    def initial_state(self, x0):
        return np.array([x0[0], x0[1], x0[1]], dtype=float)

    def continuous(self):
        J, Jf, b, d = self.J, self.J_f, self.b, self.d
        A = np.array([[0, 1, 0], [0, -(b + d) / J, d / J], [0, d / Jf, -d / Jf]])
        B = np.array([0, 1 / J, 0])
        D = np.array([0, 0, 1 / Jf]) if self.on_load else B.copy()
        return A, B, D

    def discretize(self, Ts):
        A, B, D = self.continuous()
        big = np.zeros((5, 5))
        big[:3, :3], big[:3, 3], big[:3, 4] = A * Ts, B * Ts, D * Ts
        Phi = scipy.linalg.expm(big)
        C = np.array([[1.0, 0, 0], [0, 1.0, 0]])
        return DiscreteFlywheel(Phi[:3, :3], Phi[:3, 3], Phi[:3, 4], C, Ts)

    def sampler(self, Ts, substeps):
        return ExactSubsteps.of(self, Ts, substeps, shared=not self.on_load,
                                internal=np.array([0.0, self.b + self.d, -self.d]),
                                J_motor=self.J, path="generic")  # fmt: skip


class GenericRigidServo(ServoModel):
    """The rigid servo advanced by the generic path instead of its own."""

    def sampler(self, Ts, substeps):
        rigid = super().sampler(Ts, substeps)
        return ExactSubsteps(**{**rigid.__dict__, "path": "generic"})


def ramp(t):
    return t, np.ones_like(t), np.zeros_like(t)


NOMINAL = ServoModel(9e-4)


def flywheel_run(on_load):
    """The flywheel servo's run and its exact ZOH states at the samples, ``(n, 3)``."""
    plant = FlywheelServo(on_load=on_load)
    disturbance = Step(0.1, 0.004)  # at a sample instant: constant over every sample
    loop = ServoLoop(plant=plant, nominal=NOMINAL, Ts=TS, controller=PD(400.0, 40.0))
    run = simulate(loop, reference=ramp, disturbance=disturbance, duration=0.3, x0=(0.0, 1.0))
    assert run.omega.min() / plant.coulomb_velocity > 25  # tanh(omega/v) == 1.0 throughout
    model = plant.discretize(TS)
    x = plant.initial_state((0.0, 1.0))
    states = []
    tau = disturbance(run.t + TS / 2)
    for k in range(run.t.size):
        states.append(x)
        x = model.A @ x + model.B * (run.u[k] - plant.coulomb) - model.D * tau[k]
    return plant, run, np.array(states)


@pytest.mark.parametrize("on_load", [False, True])
def test_generic_path_is_exact_zoh(on_load):
    _, run, states = flywheel_run(on_load)
    np.testing.assert_allclose(run.theta, states[:, 0], rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(run.omega, states[:, 1], rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("on_load", [False, True])
def test_generic_ground_truth_is_eq3_with_a_negative_internal_coefficient(on_load):
    """tau_dn,k = u_k - b_n omega_k - J_n theta_ddot(t_k^+) (eq. 3), the motor's acceleration
    written out from the flywheel's equations at the exact ZOH states: its internal row
    (0, b + d, -d) has a negative coefficient, whose term the rigid servo on the generic path
    never runs (the generated loop's ``internal[i] != 0.0`` mutated to ``>= 0.0`` survived
    without this test: docs/testing.md)."""
    plant, run, states = flywheel_run(on_load)
    omega, omega_f = states[:, 1], states[:, 2]
    tau_motor = 0.0 if on_load else run.tau_ext  # the external torque at t_k^+ on the motor
    accel = (
        run.u
        - (plant.b + plant.d) * omega
        + plant.d * omega_f
        - plant.coulomb * np.tanh(omega / plant.coulomb_velocity)
        - tau_motor
    ) / plant.J
    assert np.max(np.abs(plant.d * omega_f)) > 1e-3  # the -d term reaches 1e-3 N m
    np.testing.assert_allclose(run.tau_dn, run.u - NOMINAL.b * omega - NOMINAL.J * accel,
                               rtol=1e-9, atol=1e-12)  # fmt: skip


@pytest.mark.parametrize("delay", [0, 2])
def test_generic_path_runs_the_rigid_servo_like_its_own_path(delay):
    """Near rest (tanh far from saturated) the generic and the rigid path agree to rounding,
    also with the command applied ``delay`` samples late (the generated generic loop's
    ``u[k - delay]`` mutated to ``u[k ^ delay]`` survived with no delay: docs/testing.md)."""
    plant = ServoModel(3.06e-4, 5e-5, coulomb=0.01, coulomb_velocity=0.05)
    generic = GenericRigidServo(3.06e-4, 5e-5, coulomb=0.01, coulomb_velocity=0.05)
    runs = []
    for p in (plant, generic):
        loop = ServoLoop(plant=p, nominal=ServoModel(2.8e-4), Ts=TS, controller=PD(50.0, 5.0),
                         actuator=Actuator(delay_samples=delay))  # fmt: skip
        runs.append(simulate(loop, reference=lambda t: (0.1 * np.sin(t), 0.1 * np.cos(t),
                                                        -0.1 * np.sin(t)),
                             disturbance=Step(0.2, 0.002), duration=0.5))  # fmt: skip
    np.testing.assert_allclose(runs[1].theta, runs[0].theta, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(runs[1].tau_dn, runs[0].tau_dn, rtol=1e-9, atol=1e-15)


def test_a_specialised_path_checks_the_state_shape():
    sampler = FlywheelServo().sampler(TS, 8)
    with pytest.raises(ValueError, match=r"path 'rigid' needs \(states, shared"):
        ExactSubsteps(**{**sampler.__dict__, "path": "rigid"})
    with pytest.raises(ValueError, match="path must be one of rigid, two-mass, generic"):
        ExactSubsteps(**{**sampler.__dict__, "path": "fast"})
    assert ServoModel(1e-3).sampler(TS, 8).path == "rigid"
