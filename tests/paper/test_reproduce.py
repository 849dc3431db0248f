"""``hpdob reproduce`` end to end into a temporary folder."""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hpdob import SimulationResult, paper


@pytest.fixture(scope="module")
def reproduced(tmp_path_factory):
    out = tmp_path_factory.mktemp("results")
    script = shutil.which("hpdob", path=str(Path(sys.executable).parent))
    done = subprocess.run(
        [script, "reproduce", "--out", str(out)],
        capture_output=True,
        text=True,
        check=False,
        timeout=300,
    )
    return out, done


def test_exit_code_and_summary(reproduced):
    _, done = reproduced
    assert done.returncode == 0, done.stderr
    for name in paper.RUNS:
        assert name in done.stdout
    assert "rms_estimation_error" in done.stdout


def test_files(reproduced):
    out, _ = reproduced
    for fig in ("fig2", "fig3", "fig4", "fig5"):
        assert (out / f"{fig}.png").stat().st_size > 50_000
        assert (out / f"{fig}.pdf").stat().st_size > 10_000
    for name in paper.RUNS:
        trace = SimulationResult.from_csv(out / "traces" / f"{name}.csv")
        assert len(trace) == 10_000


def test_metrics_json(reproduced):
    out, _ = reproduced
    metrics = json.loads((out / "metrics.json").read_text())
    assert list(metrics) == list(paper.RUNS)
    for values in metrics.values():
        assert set(values) == {
            "rms_estimation_error",
            "rms_position_error_regulation",
            "rms_position_error_tracking",
        }
        assert all(math.isfinite(v) for v in values.values())
    hp, dob = metrics["HPDOb-100"], metrics["DOb-100"]
    assert all(hp[k] < dob[k] for k in hp)
    trace = SimulationResult.from_csv(out / "traces" / "HPDOb-100.csv")
    assert trace.metrics()["rms_estimation_error"] == pytest.approx(
        hp["rms_estimation_error"], rel=1e-12
    )
    np.testing.assert_array_equal(trace.t[:3], [0.0, 1e-3, 2e-3])


def test_a_canonical_run_reuses_its_design_and_equals_one_with_a_fresh_design():
    from hpdob import simulate
    from hpdob.paper._scenario import _design

    first = paper.run("HPDOb-100", duration=0.5)
    spec = tuple(sorted(paper.RUNS["HPDOb-100"].items()))
    assert _design(spec) is _design(spec)  # made once
    fresh = simulate(**{**paper.scenario(), "duration": 0.5},
                     observer=paper.observer("HPDOb-100").design, label="HPDOb-100")  # fmt: skip
    for name in ("theta", "u", "tau_hat", "tau_dn"):
        assert getattr(first, name).tobytes() == getattr(fresh, name).tobytes()
    assert paper.run("HPDOb-100", duration=0.5).metrics() == first.metrics()
    with pytest.raises(ValueError, match="name"):
        paper.run("HPDOb-101")
