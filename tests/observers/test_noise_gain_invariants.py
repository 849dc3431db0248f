"""Noise gains are positive and continuous in bandwidth for every family (issue 20, section 5).

The bug this would have caught: the generalised ESO of order 2 had ``tau_hat_position = 0.0``
at 2513 rad/s (and a 2 % error at 1000 rad/s) because the Lyapunov solve on its badly scaled
physical state cancelled to a negative variance, which was clipped to zero.
"""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
from family_cases import family_specs, spec_id

from hpdob import PD, ServoModel, noise_gains, observer_noise_gain
from hpdob.observers import design_eso, design_from_spec, get_family, tuned_value

TS = 1e-3
NOMINAL = ServoModel(2.8e-4, 1e-4)
RIGID = ServoModel(2.8e-4)  # b_n = 0: the ESO reconstructs the loop exactly
MODEL = NOMINAL.discretize(TS)
BANDWIDTHS = np.geomspace(5.0, 0.4 * math.pi / TS, 24)  # the tuner's grid


ESO_FORMS = ("current", "predictive")
#: Every registered family's cases, and the ESO's highest extended orders (where the
#: cancellation was worst).
SPECS = [
    *family_specs(),
    *({"type": "eso", "extended_order": m, "form": f} for m in (3, 4) for f in ESO_FORMS),
]


def _grid(spec):
    """``(parameter, values)``: the tuned parameter over the tuner's bandwidth range."""
    family = get_family(spec["type"])
    if family.tuned_from_bandwidth is None:
        return family.tuned, BANDWIDTHS
    ends = [tuned_value(MODEL, spec, float(g)) for g in BANDWIDTHS[[0, -1]]]
    return family.tuned, np.geomspace(*ends, len(BANDWIDTHS))


@pytest.mark.parametrize("spec", SPECS, ids=spec_id)
def test_encoder_noise_gain_positive_and_continuous_in_the_tuned_parameter(spec):
    parameter, values = _grid(spec)
    gains, used = [], []
    for value in values:
        try:
            design = design_from_spec(MODEL, {**spec, parameter: float(value)})
        except ValueError:  # not realisable at this bandwidth (documented refusals)
            continue
        gains.append(observer_noise_gain(design, noise="encoder"))
        used.append(value)
    assert len(gains) >= 10
    gains = np.array(gains)
    assert np.all(np.isfinite(gains))
    assert np.all(gains > 0.0)
    # The gain grows like a power of the parameter (bandwidth: 1 for state measurement, ~2.5
    # for the angle alone; the Kalman process noise: 0.5-0.8); a jump between neighbours of a
    # 1.35x grid is a failed solve.
    slopes = np.diff(np.log(gains)) / np.diff(np.log(used))
    assert slopes.min() > 0.3
    assert slopes.max() < 3.0


def _h2_reference(design) -> float:
    """H2 norm of theta -> tau_hat from the impulse response summed in 60-digit arithmetic
    (independent of the Lyapunov solve; the poles are at |z| < 0.4, 400 terms suffice)."""
    from hpdob.analysis._estimation import observer_matrices
    from hpdob.observers import as_system

    A, B, C, D = observer_matrices(as_system(design))
    with mpmath.workdps(60):
        A = mpmath.matrix(A.tolist())
        x = mpmath.matrix(B[:, [0]].tolist())
        c = mpmath.matrix(C[:1].tolist())
        total = mpmath.mpf(float(D[0, 0])) ** 2
        for _ in range(400):
            total += (c * x)[0] ** 2
            x = A * x
        return float(mpmath.sqrt(total))


@pytest.mark.parametrize("bandwidth", [1000.0, 1116.6, 2513.0])
@pytest.mark.parametrize("extended_order", [2, 3, 4])
def test_eso_noise_gain_matches_a_high_precision_reference(extended_order, bandwidth):
    design = design_eso(RIGID.discretize(TS), bandwidth=bandwidth, extended_order=extended_order)
    reference = _h2_reference(design)
    gain = observer_noise_gain(design, noise="position")
    assert gain == pytest.approx(reference, rel=1e-9)
    # The closed loop on the nominal plant: the estimate's gain is the observer's own.
    loop = noise_gains(plant=RIGID, nominal=RIGID, Ts=TS, controller=PD(50, 5), observer=design)
    assert loop.tau_hat_position == pytest.approx(reference, rel=1e-7)
