"""Observers on measured data (docs/real-data.md): the EMPS log, every family offline."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "examples"))


@pytest.fixture(scope="module")
def study():
    import emps_observers

    return emps_observers, *emps_observers.study()


def test_the_paper_claim_on_measured_data(study):
    module, _, reference, results, _ = study
    for g, by_name in results.items():
        dob = by_name["DOb"].rms_error(reference, start=module.SETTLE)
        hpdob = by_name["HPDOb"].rms_error(reference, start=module.SETTLE)
        assert hpdob < dob, g
    # the friction steps of about 40 N are followed: at 100 rad/s within a few newtons
    assert results[100.0]["HPDOb"].rms_error(reference, start=module.SETTLE) < 4.0
    assert np.isfinite(results[10.0]["Kalman m=1"].tau_hat).all()


def test_docs_table_is_the_computed_one(study):
    module, _, reference, results, _ = study
    table = module.table(reference, results)
    assert table in (ROOT / "docs" / "real-data.md").read_text()
