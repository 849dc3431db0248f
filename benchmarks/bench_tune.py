"""``hpdob.tune`` against brute-force simulation (issue 15).

The paper's motor (J_n = 2.8e-4 kg m^2, Ts = 1 ms, PD(50, 5)) with the virtual experiment's
encoder (16384 counts/rev), one sample of delay and the 0.444 N m torque limit, Coulomb friction
0.01 N m, J in [0.7, 1.3] J_n, a 2 Hz disturbance. ``tune`` returns a recommendation; the brute
force simulates every family (state- and position-measuring order-m observers, ESO, Kalman),
orders 0-2 and a fine grid of 60 bandwidths (process noises for the Kalman observer) on the same
verification scenario at the centre of the uncertainty set, and reports the best RMS estimation
error found. Targets: the recommendation is stable at every corner, its simulated RMS estimation
error is within 25 % of the brute force's best, and ``tune`` takes < 30 s.

    python benchmarks/bench_tune.py
"""

from __future__ import annotations

import math
import time
import warnings

import numpy as np

from hpdob import (
    PD,
    ParameterValueError,
    ServoModel,
    SimulationDivergedWarning,
    paper,
    simulate,
    tune,
)
from hpdob.observers import design_eso, design_kalman, design_observer, kalman_process_noise

NOMINAL = paper.NOMINAL
TS = paper.TS
J_RANGE = (0.7, 1.3)
COULOMB = 0.01
SETTINGS = {
    "nominal": NOMINAL,
    "Ts": TS,
    "sensor": paper.VIRTUAL_SENSOR,
    "actuator": paper.VIRTUAL_ACTUATOR,
    "J_range": J_RANGE,
    "disturbance_frequency": 2.0,
    "coulomb": COULOMB,
}


def _realisable(design, *args, **kwargs):
    """The design, or None where it cannot be realised in double precision (its realised
    poles off by more than the default pole_tolerance: the tuner skips those too)."""
    try:
        return design(*args, **kwargs)
    except ParameterValueError:
        return None


def candidates(n: int):
    """Every family, orders 0-2, ``n`` bandwidths (or process noises) each; ``None`` for a
    design that cannot be realised."""
    model = NOMINAL.discretize(TS)
    sigma = paper.VIRTUAL_SENSOR.resolution / math.sqrt(12.0)
    bandwidths = np.geomspace(5.0, 0.4 * math.pi / TS, n)
    for m in (0, 1, 2):
        for g in bandwidths:
            for measurement in ("state", "position"):
                yield (
                    (f"{measurement} m={m}", g),
                    _realisable(design_observer, model, order=m, bandwidth=g,
                                measurement=measurement),
                )  # fmt: skip
            yield (f"eso m={m}", g), _realisable(design_eso, model, bandwidth=g, extended_order=m)
        ends = [kalman_process_noise(model, bandwidth=g, position_noise_std=sigma, order=m)
                for g in (bandwidths[0], 0.45 * math.pi / TS)]  # fmt: skip
        for q in np.geomspace(*ends, n):
            yield (
                (f"kalman m={m}", q),
                _realisable(design_kalman, model, order=m, position_noise_std=sigma,
                            process_noise_std=q),
            )  # fmt: skip


def simulated_error(design, scenario) -> float:
    velocity = "observer" if design.system.has_velocity else "measured"
    plant = ServoModel(0.5 * sum(J_RANGE) * NOMINAL.J, NOMINAL.b, coulomb=COULOMB)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SimulationDivergedWarning)
        result = simulate(plant=plant, nominal=NOMINAL, Ts=TS,
                          controller=PD(50.0, 5.0, velocity=velocity), observer=design,
                          sensor=paper.VIRTUAL_SENSOR, actuator=paper.VIRTUAL_ACTUATOR,
                          **scenario)  # fmt: skip
    return math.inf if result.diverged else result.metrics()["rms_estimation_error"]


def brute_force(n: int, scenario) -> tuple:
    """``((best error, its label), candidates, skipped)``: skipped are the unrealisable."""
    best = (math.inf, None)
    count = skipped = 0
    for label, design in candidates(n):
        count += 1
        if design is None:
            skipped += 1
            continue
        error = simulated_error(design, scenario)
        if error < best[0]:
            best = (error, label)
    return best, count, skipped


def main(n: int = 60) -> dict:
    start = time.perf_counter()
    result = tune(**SETTINGS)
    elapsed = time.perf_counter() - start
    scenario = result.scenario
    recommended = simulated_error(result.design, scenario)
    start = time.perf_counter()
    (best, label), count, skipped = brute_force(n, scenario)
    brute = time.perf_counter() - start
    print(result.report())
    print(f"\ntune: {elapsed:.1f} s; recommended simulated RMS estimation error {recommended:.4g}")
    print(
        f"brute force: {count - skipped} simulations ({skipped} of {count} candidates not "
        f"realisable) in {brute:.0f} s; best {best:.4g} N m "
        f"({label[0]} at {label[1]:.4g}); recommended / best = {recommended / best:.3f}"
    )
    stable = all(not c["diverged"] and c["radius"] < 1 for c in result.verification)
    print(f"recommended stable at every corner: {stable}")
    return {"tune_seconds": elapsed, "recommended": recommended, "best": best,
            "ratio": recommended / best, "stable": stable}  # fmt: skip


if __name__ == "__main__":
    main()
