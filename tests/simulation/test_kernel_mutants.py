"""The compiled sample loop: tests that kill the mutants benchmarks/mutation.py found
surviving."""

from __future__ import annotations

import numpy as np

from hpdob import PD, Environment, ServoLoop, ServoModel, simulate


class GenericRigidServo(ServoModel):
    """The rigid servo advanced by the kernel's generic sub-step path instead of its own."""

    def sampler(self, Ts, substeps):
        rigid = super().sampler(Ts, substeps)
        return type(rigid)(**{**rigid.__dict__, "path": "generic"})


def test_a_damped_wall_on_the_generic_path_is_the_rigid_paths():
    """The unilateral spring-damper k_e (theta - theta_e) + c_e omega (hpdob.Environment) at
    the start and at the midpoint of each sub-step: the generic path (any plant) pushes a rigid
    servo against a damped wall as the rigid path does, to rounding. In contact the damping
    torque (up to 0.04 N m) is as large as the spring's (0.05 N m), so the velocity counts."""
    wall = Environment(20.0, damping=0.05, position=0.01)
    kwargs = {"coulomb": 0.002, "coulomb_velocity": 0.05, "environment": wall}
    runs = []
    for plant in (ServoModel(3.06e-4, 5e-5, **kwargs), GenericRigidServo(3.06e-4, 5e-5, **kwargs)):
        loop = ServoLoop(
            plant=plant, nominal=ServoModel(2.8e-4), Ts=1e-3, controller=PD(2500.0, 100.0)
        )
        runs.append(simulate(loop, reference=lambda t: (0.05 * np.sin(20 * t), np.cos(20 * t),
                                                        -20 * np.sin(20 * t)),
                             duration=0.5))  # fmt: skip
    assert runs[0].in_contact.any() and not runs[0].in_contact.all()
    np.testing.assert_allclose(runs[1].theta, runs[0].theta, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(runs[1].tau_dn, runs[0].tau_dn, rtol=1e-9, atol=1e-15)
