"""Which parameters a regression estimates (free, fixed, one offset per log or shared) and
whether the logs can separate them; refusals say how to proceed."""

from __future__ import annotations

import math
import types
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .._validation import (
    ParameterTypeError,
    ParameterValueError,
    as_real,
    check_choice,
    readonly,
)
from ._regression import (
    PARAMETERS,
)

__all__ = [
    "FRICTION_MODELS",
    "MAX_CONDITION",
    "MAX_VARIANCE_INFLATION",
    "OFFSETS",
    "Layout",
    "check_design",
    "make_layout",
    "scaled_condition",
    "variance_inflation",
]

#: The friction models: viscous and Coulomb (default), or viscous only (Coulomb friction 0,
#: or lumped into the offset of a log that moves one way).
FRICTION_MODELS = ("viscous+coulomb", "viscous")

#: With several logs: one offset per log (default) or one for all.
OFFSETS = ("per-log", "shared")

#: Largest condition number (columns scaled to unit norm) of an identifiable regression.
MAX_CONDITION = 1e6

#: Largest variance inflation factor 1/(1 - R^2) of J, b or coulomb: above it the column is
#: all but a combination of the others (R^2 > 0.999) and its estimate is meaningless. Measured:
#: 5.2 for b and coulomb on EMPS, 3.1 on two superposed sines, 3.8e4 at one constant speed.
MAX_VARIANCE_INFLATION = 1e3


@dataclass(frozen=True)
class Layout:
    """Which parameters are estimated: the free ones of J, b, coulomb, then the offsets."""

    free: tuple  # indices into (J, b, coulomb) of the estimated ones
    fixed: Mapping  # name -> value of the fixed ones (offset included)
    n_offsets: int  # 0 (offset fixed), 1 (shared or one log) or one per log
    n_runs: int

    def offset_column(self, run: int) -> int | None:
        if self.n_offsets == 0:
            return None
        return len(self.free) + (run if self.n_offsets > 1 else 0)

    @property
    def size(self) -> int:
        return len(self.free) + self.n_offsets

    def columns(self, M: np.ndarray, run: int) -> np.ndarray:
        """The estimated columns of run ``run`` from its rows ``[qdd, qd, sign(qd), 1]``:
        a read-only view of ``M`` (the same numbers, not a copy) when those are the four
        estimated, in order, else a new array."""
        if self.size == 4 and self.free == (0, 1, 2) and self.offset_column(run) == 3:
            # zero-copy, but a caller's in-place edit must not reach the regression's M
            return readonly(M.view())
        out = np.zeros((M.shape[0], self.size))
        out[:, : len(self.free)] = M[:, list(self.free)]
        column = self.offset_column(run)
        if column is not None:
            # the decimated constant column (its DC gain is the Chebyshev filter's, 0.989)
            out[:, column] = M[:, 3]
        return out

    def unexplained(self, y: np.ndarray, M: np.ndarray) -> np.ndarray:
        """The input ``y`` minus what the fixed parameters explain on rows ``M``: ``y`` itself
        (not a copy) when they explain nothing, which ``y - M @ 0`` is bit for bit."""
        values = np.array([self.fixed.get(name, 0.0) for name in PARAMETERS])
        if self.n_offsets:
            values[3] = 0.0
        return y if not values.any() else y - M @ values

    def parameters(self, estimate: np.ndarray, run: int) -> np.ndarray:
        """``(J, b, coulomb, offset)`` of run ``run``."""
        values = np.array([self.fixed.get(name, 0.0) for name in PARAMETERS])
        values[list(self.free)] = estimate[: len(self.free)]
        column = self.offset_column(run)
        if column is not None:
            values[3] = estimate[column]
        return values

    def transform(self) -> np.ndarray:
        """Rows mapping the estimate to ``(J, b, coulomb, mean offset)`` (0 for fixed ones)."""
        T = np.zeros((4, self.size))
        for k, j in enumerate(self.free):
            T[j, k] = 1.0
        if self.n_offsets:
            T[3, len(self.free) :] = 1.0 / self.n_offsets
        return T


def make_layout(friction, fixed, offsets, n_runs) -> Layout:
    friction = check_choice(friction, "friction", FRICTION_MODELS)
    offsets = check_choice(offsets, "offsets", OFFSETS)
    if fixed is None:
        fixed = {}
    if not isinstance(fixed, Mapping):
        raise ParameterTypeError(
            f"fixed must be a mapping of parameter names to values, e.g. {{'b': 2e-3}}; got "
            f"{type(fixed).__name__}"
        )
    values = {}
    for name, value in fixed.items():
        if name not in PARAMETERS:
            raise ParameterValueError(
                f"fixed has an unknown parameter {name!r}; the parameters are "
                f"{', '.join(PARAMETERS)}"
            )
        values[name] = as_real(value, f"fixed[{name!r}]", "a finite number")
    if values.get("J", 1.0) <= 0.0:
        raise ParameterValueError(f"fixed['J'] must be a positive inertia, got {values['J']!r}")
    if friction == "viscous":
        if values.get("coulomb", 0.0) != 0.0:
            raise ParameterValueError(
                f"friction='viscous' has no Coulomb friction, but fixed['coulomb'] = "
                f"{values['coulomb']!r}; drop one of them"
            )
        values["coulomb"] = 0.0
    free = tuple(j for j, name in enumerate(PARAMETERS[:3]) if name not in values)
    n_offsets = 0 if "offset" in values else (1 if offsets == "shared" or n_runs == 1 else n_runs)
    if not free and not n_offsets:
        raise ParameterValueError("every parameter is fixed: nothing is left to identify")
    return Layout(free, types.MappingProxyType(values), n_offsets, n_runs)


#: Rows per block of the design check's passes over a regression (128 kB at four columns):
#: its centred, scaled or triangularised copies are never held whole.
ROWS = 4096


def _blocks(n: int, rows: int | None = None):
    rows = ROWS if rows is None else rows
    return ((lo, min(lo + rows, n)) for lo in range(0, n, rows))


def variance_inflation(columns: np.ndarray) -> np.ndarray:
    """Variance inflation factor of each column given the others and a constant.

    ``1 / (1 - R^2)`` of the column's regression on the other columns and a constant: the
    diagonal of the inverse correlation matrix (inf for a constant or collinear column),
    the centred columns' products summed over blocks of :data:`ROWS` rows.
    """
    mean = columns.mean(axis=0)
    products = np.zeros((columns.shape[1], columns.shape[1]))
    for lo, hi in _blocks(columns.shape[0]):
        centred = columns[lo:hi] - mean
        products += centred.T @ centred
    # zero exactly where every centred value is (a constant column whose mean rounds to it)
    scale = np.sqrt(np.diag(products))
    if np.any(scale == 0.0):
        return np.where(scale == 0.0, math.inf, 1.0)
    correlation = products / np.outer(scale, scale)
    try:
        return np.diag(np.linalg.inv(correlation))
    except np.linalg.LinAlgError:
        return np.full(columns.shape[1], math.inf)


#: Rows per block of :func:`_triangular`: fewer than :data:`ROWS` (32 kB at four columns), as
#: each QR holds its stacked input and numpy's copy of it at once.
QR_ROWS = 1024


def _triangular(X: np.ndarray, norms: np.ndarray) -> np.ndarray:
    """``R`` of the QR decomposition of ``X / norms``, block by block of :data:`QR_ROWS` rows
    stacked under the ``R`` so far: ``X / norms`` has ``R``'s singular values (to some eps x
    its condition number)."""
    n = X.shape[1]
    stack = np.empty((n + QR_ROWS, n))
    R = np.empty((0, n))
    for lo, hi in _blocks(X.shape[0], QR_ROWS):
        k, rows = R.shape[0], hi - lo
        stack[:k] = R
        np.divide(X[lo:hi], norms, out=stack[k : k + rows])
        R = np.linalg.qr(stack[: k + rows], mode="r")
    return R


def _column_norms(X: np.ndarray) -> np.ndarray:
    """The Euclidean norms of ``X``'s columns, their squares summed :data:`ROWS` rows at a
    time (``np.linalg.norm(X, axis=0)`` squares the whole of ``X`` first)."""
    squares = np.zeros(X.shape[1])
    for lo in range(0, X.shape[0], ROWS):
        block = X[lo : lo + ROWS]
        squares += np.einsum("ij,ij->j", block, block)
    return np.sqrt(squares)


def scaled_condition(X: np.ndarray) -> float:
    """Condition number of ``X`` with its columns scaled to unit norm (inf if singular), from
    the triangular factor of the scaled ``X`` (to some eps x itself; no copy of ``X``)."""
    norms = _column_norms(X)
    if np.any(norms == 0.0) or X.shape[0] < X.shape[1]:
        return math.inf
    singular = np.linalg.svd(_triangular(X, norms), compute_uv=False)
    return singular[0] / singular[-1] if singular[-1] > 0 else math.inf


#: A log "moves one way" when less than this fraction of its travel over the regression rows
#: is in the other direction: the filters' ringing around a hard step, or a small overshoot,
#: do not make the sign column differ from the constant one.
ONE_WAY_TRAVEL = 0.01


def directions(run) -> tuple[float, float]:
    """+1 or -1 if the log moves one way (all but :data:`ONE_WAY_TRAVEL` of its travel over
    the regression rows in that direction), else 0; and the fraction of the travel that way."""
    forward, backward = run.regression.forward, run.regression.backward
    total = forward + backward
    if total == 0.0:
        return 0.0, 0.0
    way = 1.0 if forward >= backward else -1.0
    share = max(forward, backward) / total
    return (way if share > 1.0 - ONE_WAY_TRAVEL else 0.0), share


#: The ways to identify a log that moves one way, in identify's keywords (the command line
#: translates them: hpdob.cli._identify.cli_words).
LUMP_HINT = (
    "friction='viscous' (J, b, and the offset with the Coulomb friction lumped into it: "
    "offset + coulomb for positive motion, offset - coulomb for negative), or "
    "fixed={'coulomb': VALUE} (a known Coulomb friction)"
)


def _rests(runs) -> str:
    """What the adaptive defaults dropped as rests, for a message ("" if nothing)."""
    dropped = sum(run.regression.rest_rows for run in runs)
    if not dropped:
        return ""
    speed = max(run.regression.rest_speed for run in runs)
    return (
        f", after dropping {dropped} rows at rest (filtered speed below {speed:.3g}, 2 % of "
        "its largest)"
    )


def check_design(runs, layout: Layout, X: np.ndarray) -> None:
    """Refuse a regression that cannot separate the parameters, saying how to proceed on
    this log: the hints name the keywords that make it identifiable."""
    coulomb_free = 2 in layout.free
    if coulomb_free and layout.n_offsets:
        found = [directions(run) for run in runs]
        ways = [way for way, _ in found]
        word = {1.0: "positive", -1.0: "negative"}
        rests = _rests(runs)
        if len(runs) == 1 and ways[0]:
            raise ParameterValueError(
                f"theta moves in one direction only ({word[ways[0]]}: "
                f"{100 * found[0][1]:.4g} % of its travel in the regression rows{rests}): "
                "coulomb and offset cannot be told apart. To identify this log: "
                f"{LUMP_HINT}; or together with a log that moves the other way, "
                "identify([log, other], offsets='shared')"
            )
        if all(ways) and (layout.n_offsets > 1 or len(set(ways)) == 1):
            listed = ", ".join(f"{run.name} {word[w]}" for run, w in zip(runs, ways, strict=True))
            if len(set(ways)) == 2:
                way_out = (
                    "offsets='shared' (one offset for all) separates them with these logs, "
                    f"which move in opposite directions; or {LUMP_HINT}"
                )
            else:
                way_out = (
                    f"{LUMP_HINT}; or add a log that moves the other way, with offsets='shared'"
                )
            raise ParameterValueError(
                f"every log moves in one direction only ({listed}{rests}): coulomb and the "
                f"offset{'s' if layout.n_offsets > 1 else ''} cannot be told apart. To "
                f"identify them: {way_out}"
            )
    base = list(layout.free)
    if len(base) >= 2:
        inflation = variance_inflation(X[:, : len(base)])
        names = [PARAMETERS[j] for j in base]
        collinear = [names[k] for k in np.flatnonzero(inflation > MAX_VARIANCE_INFLATION)]
        if collinear:
            hint = (
                "the speed is nearly the same in every row: log motion at several speeds, or "
                "fix one of them (friction='viscous' or fixed={'b': VALUE})"
                if {"b", "coulomb"} <= set(collinear)
                else "log a run with more varied motion"
            )
            values = inflation[inflation > MAX_VARIANCE_INFLATION]
            raise ParameterValueError(
                f"{' and '.join(collinear)} cannot be told apart in this log (variance inflation "
                f"{', '.join(f'{v:.3g}' for v in values)}, limit {MAX_VARIANCE_INFLATION:g}): "
                f"{hint}"
            )
    # scaled_condition (no copy of X, no left vectors) passes a regression far from the
    # limit; within a factor 2 of it (its error is some eps x condition) the full
    # decomposition decides, and names the weakest parameter, as it always did
    if scaled_condition(X) <= 0.5 * MAX_CONDITION:
        return
    norms = np.linalg.norm(X, axis=0)
    scaled = X / np.where(norms > 0, norms, 1.0)
    _, singular, vt = np.linalg.svd(scaled, full_matrices=False)
    del scaled
    condition = singular[0] / singular[-1] if singular[-1] > 0 else math.inf
    if condition > MAX_CONDITION:
        names = [PARAMETERS[j] for j in layout.free] + (
            ["offset"] if layout.n_offsets == 1 else [f"offset of {r.name}" for r in runs]
        )[: layout.n_offsets]
        weakest = names[int(np.argmax(np.abs(vt[-1])))]
        raise ParameterValueError(
            f"the log does not excite the model: the observation matrix has condition number "
            f"{condition:.3g} (limit {MAX_CONDITION:g}); {weakest} is the least identifiable "
            "parameter. Log a run with more varied motion (accelerations and constant speeds "
            "in both directions)"
        )
