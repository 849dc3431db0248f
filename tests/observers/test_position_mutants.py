"""Position-only observers: tests that kill the mutants benchmarks/mutation.py found
surviving."""

from __future__ import annotations

import numpy as np
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


@pytest.mark.parametrize(("bandwidth", "real"), [(100.0, False), (1200.0, True)])
def test_real_zeros_are_kept_real(bandwidth, real):
    """The two zeros of the position-only order-1 error dynamics: a complex pair at 100 rad/s,
    two real zeros at 1200 rad/s (Ts = 1 ms), kept as a float array, not complex with zero
    imaginary parts."""
    model = ServoModel(2.8e-4).discretize(1e-3)
    design = design_observer(model, order=1, bandwidth=bandwidth, measurement="position")
    zeros = design.system.error_dynamics.zeros
    assert zeros.size == 2 and np.isrealobj(zeros) is real
