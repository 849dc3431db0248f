"""Checks of a stability map's arguments made before any work: sizes, delay, plants.

A map costs one closed-loop eigenvalue problem per grid point and one state per sample of
delay, so both are bounded up front with a message that states the limit (issue 16: a
10^6-sample delay asked numpy for 7 TiB); a grid entry whose true plant cannot be
discretised is named instead of failing later inside the linear algebra.
"""

from __future__ import annotations

from .._validation import ParameterValueError, as_int
from ..models._servo import ServoModel
from ._linear_loop import MAX_DELAY_SAMPLES

__all__ = ["MAX_MAP_POINTS", "check_delay", "check_map_size", "check_plants"]

#: Most grid points (values x bandwidths) of one map.
MAX_MAP_POINTS = 1_000_000


def check_delay(delay_samples) -> int:
    """The actuator delay [samples]: an int in ``[0, MAX_DELAY_SAMPLES]``."""
    return as_int(
        delay_samples,
        "delay_samples",
        "a non-negative integer number of samples (each adds a state to the linear loop)",
        minimum=0,
        maximum=MAX_DELAY_SAMPLES,
    )


def check_map_size(values, bandwidths) -> None:
    """Refuse maps of more than :data:`MAX_MAP_POINTS` points."""
    points = values.size * bandwidths.size
    if points > MAX_MAP_POINTS:
        raise ParameterValueError(
            f"the map has {values.size} x {bandwidths.size} = {points:.3g} points; at most "
            f"{MAX_MAP_POINTS} are supported (use coarser grids)"
        )


def check_plants(values, ratio_grid: bool, ratios, frictions, nominal, Ts: float) -> None:
    """Discretise every true plant of the grid; name the entry of one that cannot be."""
    for v in values:
        J_r, b_r = (float(v), float(frictions)) if ratio_grid else (float(ratios), float(v))
        try:
            ServoModel(J_r * nominal.J, b_r).discretize(Ts)
        except ParameterValueError as err:
            raise ParameterValueError(
                f"{'J_ratio' if ratio_grid else 'b'} entry {float(v)!r} gives a true plant "
                f"ServoModel(J={J_r * nominal.J!r}, b={b_r!r}) that cannot be discretised at "
                f"Ts={Ts!r}: {err}"
            ) from None
