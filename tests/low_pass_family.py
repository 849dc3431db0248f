"""A family defined in the tests only, registered at run time by the ``registered`` fixture:
the paper's order-m DOb followed by a first-order low-pass of its estimate,
``tau_f[k+1] = a tau_f[k] + (1 - a) tau_hat[k]`` with ``a = exp(-filter_bandwidth Ts)``, built
from the DOb's F, G, H, E, N by hand (as tests/observers/test_system.py does for one design).
Shared by tests/observers/test_registry.py and tests/cli/test_cli_families.py: it works in every
layer that designs observers by name with no edit under src/ (issue 20).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from hpdob import LinearObserver, design_observer
from hpdob.observers import Family, Parameter, register_family, unregister_family


@dataclass(frozen=True, eq=False)
class FilteredDesign:
    model: object
    order: int
    bandwidth: float
    filter_bandwidth: float
    system: LinearObserver


def design_filtered(model, *, order: int = 0, bandwidth: float, filter_bandwidth: float):
    """The DOb of ``order`` at ``bandwidth`` [rad/s], its estimate low-pass filtered."""
    if not filter_bandwidth > 0:
        raise ValueError(f"filter_bandwidth must be positive [rad/s], got {filter_bandwidth!r}")
    dob = design_observer(model, order=order, bandwidth=bandwidth).system
    a = math.exp(-filter_bandwidth * model.Ts)
    n = dob.F.shape[0]
    F = np.block([[dob.F, np.zeros((n, 1))], [(1 - a) * dob.H, np.array([[a]])]])
    G = np.vstack([dob.G, (1 - a) * dob.E])
    H = np.hstack([np.zeros((1, n)), [[1.0]]])
    N = np.vstack([dob.N, [0.0, 0.0, 1.0]])  # converged on tau0: the filter holds tau0 too
    system = LinearObserver(
        F=F, G=G, H=H, E=np.zeros((1, 3)), N=N, Ts=model.Ts, model=model, name=f"DOb m={order} + LP"
    )
    return FilteredDesign(model, order, bandwidth, filter_bandwidth, system)


FILTERED = Family(
    name="dob_lp",
    design=design_filtered,
    parameters=(
        Parameter("order", "int", "truncation order of the DOb"),
        Parameter("bandwidth", "float", "DOb bandwidth [rad/s]"),
        Parameter("filter_bandwidth", "float", "low-pass bandwidth [rad/s]"),
    ),
    required=("bandwidth", "filter_bandwidth"),
    order="order",
    tuned="bandwidth",
    designs=(FilteredDesign,),
    spec_of=lambda d: {
        "order": d.order,
        "bandwidth": d.bandwidth,
        "filter_bandwidth": d.filter_bandwidth,
    },
    label=lambda spec: f"DOb m={spec.get('order', 0)} + LP",
    title="a DOb followed by a first-order low-pass (defined in a test)",
    variants={"filtered": {"filter_bandwidth": 2000.0}},
    orders=(0, 1),
    compared={"DOb + LP": {"order": 0, "filter_bandwidth": 2000.0}},
)


@pytest.fixture
def registered():
    register_family(FILTERED)
    yield FILTERED
    unregister_family("dob_lp")
