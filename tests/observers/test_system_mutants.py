"""The observer protocol: tests that kill the mutants benchmarks/mutation.py found surviving."""

from __future__ import annotations

import numpy as np

from hpdob import ServoModel, design_observer
from hpdob.observers import LinearObserver


def test_from_statespace_is_the_inverse_of_to_statespace():
    """LinearObserver.from_statespace (a class method: F, G, H, E = A, B, C, D, Ts = dt) reads
    back what to_statespace wrote, with the measured and output signals' names."""
    model = ServoModel(2.8e-4, 5e-5).discretize(1e-3)
    system = design_observer(model, order=1, bandwidth=100.0).system
    back = LinearObserver.from_statespace(system.to_statespace(), model=model)
    assert isinstance(back, LinearObserver) and back.Ts == system.Ts
    assert (back.measures, back.outputs) == (system.measures, system.outputs)
    for name in "FGHE":
        np.testing.assert_array_equal(getattr(back, name), getattr(system, name), err_msg=name)
