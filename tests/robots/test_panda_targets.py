"""The tracking claims of docs/robots.md, on short runs (benchmarks/bench_robots.py has the
full ones): a 7-joint Panda at 1 kHz, a fast trajectory, gravity and an unknown 1 kg payload."""

from __future__ import annotations

import numpy as np
import pytest

from hpdob import PD, Actuator, Encoder, ParameterValueError
from hpdob.robots import (
    PANDA_READY,
    PANDA_TORQUE_LIMITS,
    ArmLoop,
    ComputedTorque,
    JointSines,
    panda,
    simulate_arm,
)

pytest.importorskip("mujoco")

Q0 = np.array(PANDA_READY)
REFERENCE = JointSines(center=Q0, amplitude=0.5, frequency=1.4)


@pytest.fixture(scope="module")
def runs():
    nominal = panda()
    base = ArmLoop(panda(payload=1.0), 1e-3, PD(400.0, 40.0), nominal=nominal, q0=Q0,
                   actuator=[Actuator(torque_limit=t) for t in PANDA_TORQUE_LIMITS],
                   sensor=Encoder(2**18))  # fmt: skip
    # 49 rad/s: the HPDOb's bandwidth at the DOb-100's encoder-noise gain on every joint
    # (benchmarks/bench_robots.py finds it by bisection on observer_noise_gain)
    loops = {
        "PD": base,
        "DOb": base.replace(observers={"order": 0, "bandwidth": 100.0}),
        "HPDOb": base.replace(observers={"order": 1, "bandwidth": 49.0}),
        "CT": base.replace(controller=ComputedTorque(nominal, 400.0, 40.0)),
    }
    return {
        name: np.array(
            simulate_arm(loop, duration=1.5, reference=REFERENCE, tau0="gravity").metrics(
                start=0.75
            )["rms_position_error"]
        )
        for name, loop in loops.items()
    }


def test_reference_is_fast():
    assert np.all(REFERENCE.peak_velocity >= 2.0)


def test_the_dob_per_joint_beats_pd_alone(runs):
    assert np.all(runs["DOb"] < runs["PD"] / 4)


def test_the_hpdob_at_equal_noise_beats_the_dob_on_every_joint(runs):
    assert np.all(runs["HPDOb"] < 0.9 * runs["DOb"])


def test_computed_torque_suffers_from_the_unknown_payload_at_the_wrist(runs):
    # the payload's weight acts most on the light wrist joints 5-7, which CT does not know
    assert np.all(runs["CT"][4:] > 2 * runs["DOb"][4:])


def test_observers_with_computed_torque_are_refused():
    with pytest.raises(ParameterValueError, match="observers must be None with controller"):
        ArmLoop(panda(), 1e-3, ComputedTorque(panda(), 1.0, 1.0), observers={"order": 0,
                "bandwidth": 50.0})  # fmt: skip
