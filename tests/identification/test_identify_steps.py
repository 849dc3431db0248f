"""Issue 23: step responses, the most common logs of all, identified with the defaults. Every
log is SYNTHETIC (hpdob.simulate, tests/synthetic_logs.py): PD steps of 1 rad every second one
way (a staircase, up or down) or both ways, and open-loop torque pulses of 0.1 s every second
that leave the axis to coast to rest, one way or alternating. The defaults drop the rows where
the log rests (stretches slower than 2 % of the largest speed for more than one decimated row):
there the friction is static, which sign(velocity) does not describe. A log that moves one
way is refused, and each way out the refusal names works on that log. The grid of these logs
is benchmarks/bench_identify_grid.py --steps."""

from __future__ import annotations

import re

import pytest

from hpdob import ParameterValueError, identify
from hpdob.identification import IdentificationWarning
from synthetic_logs import synthetic_log, within_targets


@pytest.fixture(scope="module")
def staircase():
    """PD steps up, 4096 counts, 0.5 ms, Coulomb friction 10 % of the input's RMS."""
    return synthetic_log(kind="steps", counts=4096, Ts=5e-4, coulomb_fraction=0.1, seed=1)


def test_steps_both_ways_identify_by_default_once_the_rests_are_dropped():
    s = synthetic_log(kind="steps-both", counts=4096, Ts=5e-4, coulomb_fraction=0.1, seed=1)
    fit = s.log.identify()
    assert all(within_targets(fit, s).values()), within_targets(fit, s)
    assert fit.settings["rests"] and fit.settings["rest_rows"] > fit.t.size
    assert fit.settings["rest_speed"] == pytest.approx(0.02 * fit.max_speed, rel=0.05)
    assert fit.warnings == ()
    # every row kept: the holds read as friction, b moves by a third with the filters
    with pytest.warns(IdentificationWarning, match="b moves by"):
        kept = s.log.identify(min_speed=0)
    assert not kept.settings["rests"] and kept.settings["rest_rows"] == 0


def test_torque_pulses_both_ways_identify_by_default():
    s = synthetic_log(kind="pulses", counts=4096, Ts=1e-3, coulomb_fraction=0.3, seed=1)
    fit = s.log.identify()
    assert all(within_targets(fit, s).values()), within_targets(fit, s)
    assert fit.warnings == ()


def test_logs_that_never_rest_keep_their_rows():
    """The reversals of a chirp are brief and kept; only the first instants, where the axis
    starts from rest and the chirp is slowest, are dropped (5 of 785 rows)."""
    s = synthetic_log(kind="chirp", counts=1024, Ts=2.5e-4, coulomb_fraction=0.3, seed=1)
    fit = s.log.identify(diagnostics=False)
    assert fit.settings["rest_rows"] < 0.01 * fit.t.size
    assert fit.t[0] < 0.6  # the rows dropped are at the start, not all of the first second


def test_a_one_way_log_is_refused_with_the_calls_that_work_on_it(staircase):
    s = staircase
    with pytest.raises(ParameterValueError) as refusal:
        s.log.identify()
    message = str(refusal.value)
    assert "one direction only (positive" in message and "rows at rest" in message
    for way_out in ("friction='viscous'", "fixed={'coulomb': VALUE}",
                    "identify([log, other], offsets='shared')"):  # fmt: skip
        assert way_out in message
    # friction='viscous': J, b, and the Coulomb friction lumped into the offset (true offset 0)
    lumped = s.log.identify(friction="viscous")
    assert lumped.warnings == ()
    targets = within_targets(lumped, s)
    assert targets["J"] and targets["b"]
    assert abs(lumped.offset - s.coulomb) <= max(0.05 * s.coulomb, 0.02 * s.input_rms)
    # fixed={'coulomb': VALUE}: the offset alone is left
    known = s.log.identify(fixed={"coulomb": s.coulomb})
    assert abs(known.offset) <= 0.02 * s.input_rms and within_targets(known, s)["J"]
    # with a staircase down and one offset for both, Coulomb friction is identified
    down = synthetic_log(kind="steps-down", counts=4096, Ts=5e-4, coulomb_fraction=0.1, seed=1)
    both = identify([s.log, down.log], offsets="shared")
    assert all(within_targets(both, s).values()), within_targets(both, s)


def test_one_way_torque_pulses_with_the_coulomb_friction_lumped():
    """The lumped model is simulated with the lumped term as Coulomb friction, so it stays at
    rest where the log does: no spurious 'does not reproduce' warning."""
    s = synthetic_log(kind="pulses-one-way", counts=4096, Ts=1e-3, coulomb_fraction=0.3, seed=1)
    with pytest.raises(ParameterValueError, match="friction='viscous'"):
        s.log.identify()
    fit = s.log.identify(friction="viscous")
    assert fit.warnings == () and fit.fits[0]["velocity_fit_percent"] > 90.0
    assert within_targets(fit, s)["J"] and within_targets(fit, s)["b"]
    assert fit.offset == pytest.approx(s.coulomb, rel=0.05)


def test_a_log_that_rests_most_of_the_time_says_what_to_set():
    """Two torque pulses in 2 s: 66 of 81 rows are rests. The message counts them and names
    the bandwidth that doubles the rows per move, which then identifies the log."""
    s = synthetic_log(kind="pulses", counts=4096, Ts=5e-4, coulomb=0.03, seed=1, duration=2.0)
    with pytest.raises(ParameterValueError, match="rests most of the time") as refusal:
        s.log.identify()
    message = str(refusal.value)
    assert re.search(r"\d+ of \d+ regression rows are at rest", message)
    assert "min_speed=0" in message
    bandwidth = float(re.search(r"filter_bandwidth=([0-9.]+)", message).group(1))
    fit = s.log.identify(filter_bandwidth=bandwidth)
    assert within_targets(fit, s)["J"]
