"""Notebook users: designs and results show a compact Markdown table in Jupyter
(``_repr_markdown_``), with the figures that identify them and their units."""

from __future__ import annotations

import pytest

from hpdob import PD, ServoModel, design_observer, estimate_disturbance, identify, simulate
from hpdob.observers import design_eso, design_kalman
from hpdob.signals import Step

MODEL = ServoModel(2.8e-4, 1e-5).discretize(1e-3)


def _table_rows(text: str) -> dict:
    lines = text.strip().splitlines()
    assert lines[0].startswith("**") and lines[2:4] == ["| | |", "|---|---|"]
    rows = [line.strip("|").split(" | ") for line in lines[4:]]
    assert all(len(r) == 2 for r in rows), rows
    return {name.strip(): value.strip() for name, value in rows}


@pytest.mark.parametrize(
    "design",
    [
        design_observer(MODEL, order=1, bandwidth=100.0),
        design_observer(MODEL, order=1, bandwidth=100.0, measurement="position"),
        design_eso(MODEL, bandwidth=200.0),
        design_kalman(MODEL, position_noise_std=1e-4, process_noise_std=1.0),
    ],
    ids=["order-m", "position", "eso", "kalman"],
)
def test_designs_show_a_compact_table(design):
    text = design._repr_markdown_()
    rows = _table_rows(text)
    assert design.system.name in text.splitlines()[0]
    assert rows["nominal model"] == "J_n = 0.00028 kg m², b_n = 1e-05 N m s/rad"
    assert rows["Ts [s]"] == "0.001" and rows["states"] == str(design.system.n_states)
    assert rows["measures"] == ", ".join(design.system.measures)
    assert len(text) < 600  # compact: no arrays spelled out


def test_results_show_a_compact_table():
    design = design_observer(MODEL, order=1, bandwidth=100.0)
    run = simulate(plant=ServoModel(3e-4), nominal=ServoModel(2.8e-4, 1e-5), Ts=1e-3,
                   controller=PD(50, 5), observer=design, reference=Step(0.1, 1.0),
                   duration=0.5, label="hp")  # fmt: skip
    rows = _table_rows(run._repr_markdown_())
    assert rows["samples"] == "500 (Ts = 0.001 s, 0.5 s)" and rows["status"] == "ok"
    assert float(rows["rms_estimation_error [N m]"]) == pytest.approx(
        run.metrics()["rms_estimation_error"], rel=1e-3)  # fmt: skip
    estimate = estimate_disturbance(design, theta=run.theta, u=run.u)
    rows = _table_rows(estimate._repr_markdown_())
    assert rows["samples"] == "500 (Ts = 0.001 s)" and "last" in rows["tau_hat [N m or N]"]


def test_identification_result_shows_its_parameters():
    from hpdob.identification import emps

    log = emps()
    result = identify(log.t, log.theta, log.u, axis="linear")
    rows = _table_rows(result._repr_markdown_())
    assert rows["method"].startswith(result.method)
    assert any(name.startswith("mass") or "kg" in name for name in rows), rows
    assert "±" in next(v for k, v in rows.items() if "kg" in k)
