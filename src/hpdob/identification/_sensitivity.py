"""How much the estimate depends on the filter settings: the estimate repeated with the
filters' bandwidth doubled and halved, and the warnings it gives."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from .._validation import (
    ParameterValueError,
)
from ._regression import (
    MIN_ROWS,
    build_regression,
    minimum_samples,
)
from ._runs import scaled
from ._solve import solve

__all__ = [
    "SENSITIVITY_FACTOR",
    "SENSITIVITY_STD",
    "SENSITIVITY_TOLERANCE",
    "sensitivity",
    "sensitivity_warnings",
]

#: The sensitivity check scales the filter settings by this factor both ways ...
SENSITIVITY_FACTOR = 2.0

#: ... and warns when a parameter moves by more than this many of its standard deviations
#: (the issue's rule) ...
SENSITIVITY_STD = 1.0

#: ... and by more than this fraction of its scale (b: at least 0.02 J 2 pi bandwidth;
#: coulomb: at least 2 % of the input's RMS). The standard deviations are the batch-means
#: ones (``_solve.long_run_covariance``), which match the spread of the estimates over seeds
#: within a factor 1.4 (benchmarks/bench_identify_std.py). But a move under a change of the
#: filters is not a random draw: it is a change of bias (the half-sample alignment, the
#: central differences, the sign column's switching instants), and on long rich logs the
#: standard deviation is far smaller than these biases. On the synthetic grid, where every
#: default estimate is within the targets (J within 0.6 % at Ts = 2 ms, 0.2 % at 0.25 ms),
#: J moves by up to 10 of its standard deviations (0.03-0.08 % of J) and the rule alone warns
#: on 39 of 48 logs; with these floors on none (docs/real-data.md, Diagnostics).
SENSITIVITY_TOLERANCE = {"J": 0.02, "b": 0.25, "coulomb": 0.25}

#: With the adaptive defaults only halving counts: the band read from the log ends where the
#: noise begins, so doubling it only lets the noise in (docs/real-data.md, Diagnostics).
ADAPTIVE_FACTORS = (1.0 / SENSITIVITY_FACTOR,)


def sensitivity_warnings(moves, solution, layout, runs, adaptive, names) -> list:
    """The parameters that the filters move by more than :data:`SENSITIVITY_STD` standard
    deviations and more than :data:`SENSITIVITY_TOLERANCE` of their scale."""
    std = np.sqrt(np.diag(solution.covariance))
    J = layout.parameters(solution.estimate, 0)[0]
    bandwidth = max(run.settings.bandwidth for run in runs)
    rms = math.sqrt(np.mean(np.concatenate([run.u for run in runs]) ** 2))
    floor = {"J": 0.0, "b": 0.02 * abs(J) * 2 * math.pi * bandwidth, "coulomb": 0.02 * rms}
    out = []
    for factor, move in moves.items():
        if adaptive and factor not in ADAPTIVE_FACTORS:
            continue
        which = "doubled" if factor > 1 else "halved"
        for k, name in enumerate(names):
            if name not in SENSITIVITY_TOLERANCE:
                continue
            shift = abs(move[k]) * std[k]
            scale = max(abs(solution.estimate[k]), floor[name])
            if abs(move[k]) > SENSITIVITY_STD and shift > SENSITIVITY_TOLERANCE[name] * scale:
                out.append(
                    f"{name} moves by {abs(move[k]):.3g} standard deviations "
                    f"({100 * shift / scale:.3g} %) when the filters' bandwidth is {which} "
                    f"(cutoff {runs[0].settings.cutoff * factor:.4g} Hz): the estimate depends "
                    "on the filter settings. Try method='auto' (filters from the log, "
                    "instrumental variables), loop= for a closed-loop log, min_speed for "
                    "stick phases, or a longer log with more excitation"
                )
                break
    return out


def sensitivity(runs, layout, method, own_sign, solution, border_given, max_iterations, tol,
                report=None):  # fmt: skip
    """How far the estimate moves, in standard deviations, with the filters' bandwidth x2, /2
    (``report(done, 2)`` before each and after the last, if given)."""
    std = np.sqrt(np.diag(solution.covariance))
    moves = {}
    factors = (SENSITIVITY_FACTOR, 1.0 / SENSITIVITY_FACTOR)
    for k, factor in enumerate(factors):
        if report is not None:
            report(k, len(factors))
        copies = []
        try:
            for run in runs:
                settings = scaled(run.settings, factor, border_given)
                if settings is None or run.theta.size < minimum_samples(settings):
                    raise ParameterValueError("cannot scale")
                copy = replace(run, settings=settings, regression=None)
                copy.regression = build_regression(run.theta, run.u, settings)
                if copy.regression.X.shape[0] < MIN_ROWS:
                    raise ParameterValueError("too few rows")
                copies.append(copy)
            other = solve(copies, layout, method, own_sign, max_iterations, tol)
        except (ParameterValueError, np.linalg.LinAlgError):
            continue
        moves[factor] = (other.estimate - solution.estimate) / np.where(std > 0, std, np.inf)
    if report is not None:
        report(len(factors), len(factors))
    return moves
