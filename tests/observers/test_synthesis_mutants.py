"""Order-m synthesis: tests that kill the mutants benchmarks/mutation.py found surviving."""

from __future__ import annotations

import pytest

from hpdob import ServoModel, design_observer


@pytest.mark.parametrize(
    ("order", "kind"),
    [
        (0, "(conventional DOb, paper eqs. 9-13)"),
        (1, "(HPDOb, paper eqs. 14-24)"),
        (2, "(generalised DOb, Delta^(m+1) tau = 0)"),
        (3, "(generalised DOb, Delta^(m+1) tau = 0)"),
    ],
)
def test_design_summary_names_the_paper_family_of_each_order(order, kind):
    """The summary written into generated code's header names the family of the order."""
    model = ServoModel(2.8e-4, 5e-5).discretize(1e-3)  # the paper's nominal motor (sec. IV)
    info = dict(design_observer(model, order=order, bandwidth=300.0).system.info)
    assert info["order"] == f"{order} {kind}"
