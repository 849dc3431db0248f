"""How much the estimate depends on the filter settings: the estimate repeated with the
filters' bandwidth doubled and halved, and the warnings it gives."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from .._validation import (
    ParameterValueError,
)
from ._lean import welch
from ._regression import (
    MIN_ROWS,
    build_regression,
    minimum_samples,
    signal_bandwidth,
)
from ._runs import scaled
from ._solve import solve

__all__ = [
    "ADAPTIVE_FACTORS",
    "SENSITIVITY_FACTOR",
    "SENSITIVITY_STD",
    "SENSITIVITY_TOLERANCE",
    "excitation_bandwidth",
    "sensitivity",
    "sensitivity_warnings",
]

#: The sensitivity check scales the filter settings by this factor both ways ...
SENSITIVITY_FACTOR = 2.0

#: ... and warns when a parameter moves by more than this many of its standard deviations
#: (the issue's rule) ...
SENSITIVITY_STD = 1.0

#: ... and by more than the targets' own allowance (issue 23): J 2 % (its target is 3 %), b
#: 10 % or 0.02 J 2 pi B (B the excitation's bandwidth, :func:`excitation_bandwidth`), Coulomb
#: 5 % or 2 % of the input's RMS: the move the filters cause must not exceed what the target
#: itself allows. The standard deviations are the batch-means ones (``_solve``), which match
#: the spread of the estimates over seeds within a factor 1.4 (benchmarks/bench_identify_std.py),
#: but a move under a change of the filters is a change of bias (the half-sample alignment, the
#: central differences, the sign column's switching instants), and on long rich logs the
#: standard deviation is far smaller than these biases: the rule of one standard deviation
#: alone warns on most of the grid (docs/real-data.md, Diagnostics, measured 2026-12-01).
SENSITIVITY_TOLERANCE = {"J": 0.02, "b": 0.10, "coulomb": 0.05}

#: The absolute allowances beside them: b 0.02 J 2 pi B, Coulomb 2 % of the input's RMS.
B_FLOOR, COULOMB_FLOOR = 0.02, 0.02

#: The excitation's bandwidth is where this fraction of the input's power lies below ...
EXCITATION_POWER = 0.95

#: With the adaptive defaults only halving counts: the band read from the log ends where the
#: noise begins, so doubling it only lets the noise in (docs/real-data.md, Diagnostics).
ADAPTIVE_FACTORS = (1.0 / SENSITIVITY_FACTOR,)


def excitation_bandwidth(run) -> float:
    """The excitation's bandwidth [Hz] of a run: the frequency below which
    :data:`EXCITATION_POWER` of the input's power lies (Welch), capped at the position's
    signal bandwidth (above it the input is the loop's response to the encoder's noise, not
    excitation: a PD's input on a coarse encoder)."""
    u, mean = run.u, np.mean(run.u)
    # scipy's welch of u - mean(u), bit for bit, without that array: a segment at a time
    f, p = welch((u.size, lambda lo, hi: u[lo:hi] - mean), fs=1.0 / run.Ts,
                 nperseg=min(u.size, 8192))  # fmt: skip
    power = np.cumsum(p)
    band = float(f[min(np.searchsorted(power, EXCITATION_POWER * power[-1]), f.size - 1)])
    return min(band, signal_bandwidth(run.theta, run.Ts))


def squares(signals) -> np.ndarray:
    """``np.concatenate(signals) ** 2`` in one new array (not two)."""
    out = np.empty(sum(x.size for x in signals))
    start = 0
    for x in signals:
        np.square(x, out=out[start : start + x.size])  # what ** 2 computes
        start += x.size
    return out


def allowances(solution, layout, runs) -> dict:
    """The move each parameter may make under the filters' change: the targets' allowance
    (:data:`SENSITIVITY_TOLERANCE`, :data:`B_FLOOR`, :data:`COULOMB_FLOOR`)."""
    J, b, coulomb, _ = layout.parameters(solution.estimate, 0)
    band = max(excitation_bandwidth(run) for run in runs)
    rms = math.sqrt(np.mean(squares([run.u for run in runs])))
    tol = SENSITIVITY_TOLERANCE
    return {
        "J": tol["J"] * abs(J),
        "b": max(tol["b"] * abs(b), B_FLOOR * abs(J) * 2 * math.pi * band),
        "coulomb": max(tol["coulomb"] * abs(coulomb), COULOMB_FLOOR * rms),
    }


def sensitivity_warnings(moves, solution, allowed, runs, adaptive, names) -> list:
    """The parameters that the filters move by more than :data:`SENSITIVITY_STD` standard
    deviations and more than their target's allowance (``allowed``, :func:`allowances`)."""
    std = np.sqrt(np.diag(solution.covariance))
    out = []
    for factor, move in moves.items():
        if adaptive and factor not in ADAPTIVE_FACTORS:
            continue
        which = "doubled" if factor > 1 else "halved"
        for k, name in enumerate(names):
            if name not in allowed:
                continue
            shift = abs(move[k]) * std[k]
            if abs(move[k]) > SENSITIVITY_STD and shift > allowed[name]:
                out.append(
                    f"{name} moves by {abs(move[k]):.3g} standard deviations ({shift:.3g}, "
                    f"{shift / allowed[name]:.3g} times its target's allowance "
                    f"{allowed[name]:.3g}) when the filters' bandwidth is {which} "
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
        del copies, other  # their regressions: not beside the next factor's
    if report is not None:
        report(len(factors), len(factors))
    return moves
