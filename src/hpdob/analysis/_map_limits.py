"""Checks of a stability map's arguments made before any work: sizes, delay, plants.

A map costs one closed-loop eigenvalue problem per grid point and one state per sample of
delay, so both are bounded up front with a message that states the limit (issue 16: a
10^6-sample delay asked numpy for 7 TiB); a grid entry whose true plant cannot be
discretised is named instead of failing later inside the linear algebra.
"""

from __future__ import annotations

import numpy as np

from .._validation import ParameterTypeError, ParameterValueError, as_int
from ..models._servo import ServoModel
from ._linear_loop import MAX_DELAY_SAMPLES

__all__ = ["MAX_MAP_POINTS", "check_delay", "check_map_size", "check_plants", "observer_spec"]

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
            f"the map has {values.size} x {bandwidths.size} = {points} points; at most "
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


#: What the map sets at every grid point, by family: a spec must leave it out.
_SET_BY_THE_MAP = {"dob": ("bandwidth", "poles"), "eso": ("bandwidth",),
                   "kalman": ("process_noise_std",)}  # fmt: skip


def observer_spec(observer, measurement, gain_direction) -> tuple[dict, int]:
    """``(spec, order)`` of ``robust_stability_map(observer=...)``, validated before any work.

    The spec's keys are checked for its family (``observer.<key>``), its order is an integer,
    and what the map sets itself is refused instead of silently replaced: the bandwidth (or
    poles; for the Kalman observer the process noise, chosen per bandwidth), and the
    ``measurement``/``gain_direction`` arguments, which describe the paper's family only.
    """
    from ..observers._families import check_spec

    if not isinstance(observer, dict):
        raise ParameterTypeError(
            f"observer must be a dict of design arguments (a family spec), got {observer!r}"
        )
    kind = observer.get("type", "dob")
    placeholder = {"process_noise_std": 1.0} if kind == "kalman" else {"bandwidth": 1.0}
    check_spec({**observer, **placeholder}, "observer")
    given = [k for k in _SET_BY_THE_MAP.get(kind, ()) if k in observer]
    if given:
        raise ParameterValueError(
            f"observer must not give {', '.join(given)}: the map designs the observer at every "
            f"bandwidth of its grid, got {observer!r}"
        )
    if measurement != "state" or tuple(np.ravel(gain_direction).tolist()) != (1.0, 1.0):
        raise ParameterValueError(
            "measurement and gain_direction apply with order (the paper's family); with "
            f"observer give them in the spec, got measurement={measurement!r}, "
            f"gain_direction={gain_direction!r}"
        )
    key = "extended_order" if kind == "eso" else "order"
    m = as_int(observer.get(key, 0), f"observer.{key}", "a non-negative integer", minimum=0)
    return dict(observer), m
