"""Position-only observers: tests that kill the mutants benchmarks/mutation.py found
surviving."""

from __future__ import annotations

import pytest

from hpdob import ServoModel, design_observer


@pytest.mark.parametrize(
    ("order", "name"),
    [
        (0, "position-only DOb (order 0)"),
        (1, "position-only HPDOb (order 1)"),
        (2, "position-only order-2 DOb"),
    ],
)
def test_each_order_names_its_family(order, name):
    """The observer's name (design summaries, exported C) says which family the order is: the
    paper's conventional DOb (order 0) and HPDOb (order 1), measured through the angle only."""
    model = ServoModel(2.8e-4, 5e-5).discretize(1e-3)  # the paper's nominal motor (sec. IV)
    design = design_observer(model, order=order, bandwidth=100.0, measurement="position")
    assert design.system.name == name
