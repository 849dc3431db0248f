"""Sweep rows of a force scenario (issue 21): the contact and force metrics of single runs,
no position metrics against a force reference, and an unstable point told by its force error
although the run does not diverge."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from hpdob import simulate, sweep
from hpdob.simulation import load_scenario, read_toml, scenario_from_dict

ROOT = Path(__file__).resolve().parents[2]
FORCE = ROOT / "examples" / "force_step_stiff_wall.toml"
IMPEDANCE = ROOT / "examples" / "impedance_soft_wall.toml"
BANDWIDTHS = [100.0, 1000.0]


def _rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


@pytest.fixture(scope="module")
def force_rows():
    return sweep(load_scenario(FORCE), grid={"observer.bandwidth": BANDWIDTHS}, progress=False)


def _single(path, bandwidth):
    """The scenario file's run with ``[observer] bandwidth`` replaced, as hpdob simulate does."""
    data = read_toml(path)
    data["observer"] = {**data["observer"], "bandwidth": bandwidth}
    return simulate(**scenario_from_dict(data))


def test_force_rows_are_the_metrics_of_single_runs(force_rows):
    for bandwidth, (_, row) in zip(BANDWIDTHS, force_rows.iterrows(), strict=True):
        result = _single(FORCE, bandwidth)
        tau_ref = result.r  # the force controller's reference [N m]
        # recomputed from the traces, not through the library's metric functions
        assert row["force_rms_reaction_error"] == pytest.approx(
            _rms(result.tau_reac - result.tau_contact), rel=1e-12)  # fmt: skip
        assert row["force_rms_force_error"] == pytest.approx(
            _rms(result.tau_contact - tau_ref), rel=1e-12)  # fmt: skip
        first = int(np.argmax(result.in_contact > 0.0))
        assert row["contact_first_contact"] == pytest.approx(result.t[first], abs=1e-12)
        assert row["contact_impact_peak"] == pytest.approx(np.max(result.tau_contact[first:]))
        start = result.t[first] + 0.5  # the steady window: 0.5 s after the first contact
        keep = result.t >= start
        assert row["force_steady_start"] == pytest.approx(start, abs=1e-12)
        assert row["force_rms_force_error_steady"] == pytest.approx(
            _rms(result.tau_contact[keep] - tau_ref[keep]), rel=1e-12)  # fmt: skip
        reaction = result.tau_reac[keep] - result.tau_contact[keep]
        assert row["force_rms_reaction_error_steady"] == pytest.approx(
            _rms(reaction), rel=1e-12, abs=1e-15)  # fmt: skip


def test_force_rows_report_no_position_metrics(force_rows):
    # r is tau_ref [N m]: theta - r (an angle minus a torque) is NaN, not a number
    for name in ("rms_position_error_regulation", "rms_position_error_tracking",
                 "max_abs_position_error"):  # fmt: skip
        assert force_rows[name].isna().all(), name
    assert force_rows["rms_estimation_error"].notna().all()  # tau_hat - tau_dn [N m] stays


def test_an_unstable_point_shows_in_the_force_columns_not_in_stable(force_rows):
    # HPDOb at 1000 rad/s on the 10 N m/rad wall: the loop in contact is unstable, the torque
    # limit and the wall bound it (no divergence, so stable=True: |theta|, |omega| stayed
    # finite), and the steady force error says so: about 90 % of tau_ref = 0.05 N m
    fine, unstable = force_rows.iloc[0], force_rows.iloc[1]
    assert bool(fine["stable"]) and bool(unstable["stable"])
    assert fine["force_rms_force_error_steady"] < 0.01 * 0.05
    assert unstable["force_rms_force_error_steady"] > 0.5 * 0.05


def test_impedance_rows_keep_position_metrics_and_have_no_force_reference():
    scenario = load_scenario(IMPEDANCE)
    rows = sweep(scenario, grid={"observer.bandwidth": [100.0]}, progress=False)
    assert "force_rms_reaction_error_steady" in rows.columns
    assert "force_rms_force_error" not in rows.columns  # its target is a position
    assert math.isfinite(rows["max_abs_position_error"].iloc[0])
    assert math.isfinite(rows["contact_impact_peak"].iloc[0])
