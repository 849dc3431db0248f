"""Observer families by name: how sweeps, scenario files and the command line build observers.

A *spec* is a dict of a family's design arguments plus an optional ``type`` (default
``"dob"``, the paper's order-m family); :func:`design_from_spec` designs it on a nominal
model. :func:`spec_of` turns a design of a known family back into its spec, so that a sweep can
redesign it when the nominal model, ``Ts`` or a design parameter varies.
"""

from __future__ import annotations

from .._validation import ParameterTypeError, ParameterValueError, check_keys
from ._eso import ESODesign, design_eso
from ._kalman import KalmanDesign, design_kalman
from ._position import PositionObserverDesign
from ._runtime import DisturbanceObserver
from ._synthesis import ObserverDesign, design_observer

__all__ = ["FAMILIES", "design_at_bandwidth", "design_from_spec", "spec_of"]

#: type -> (design function(model, **arguments), its argument names, required ones).
FAMILIES = {
    "dob": (
        design_observer,
        ("order", "poles", "bandwidth", "measurement", "velocity_bandwidth", "gain_direction"),
        ("order",),
    ),
    "eso": (design_eso, ("bandwidth", "extended_order", "form"), ("bandwidth",)),
    "kalman": (
        design_kalman,
        ("order", "position_noise_std", "process_noise_std"),
        ("position_noise_std", "process_noise_std"),
    ),
}


def _family(spec: dict, where: str):
    kind = spec.get("type", "dob")
    if kind not in FAMILIES:
        raise ParameterValueError(
            f"{where}.type must be one of {', '.join(repr(k) for k in FAMILIES)}; got {kind!r}"
        )
    return kind, FAMILIES[kind]


def check_spec(spec, where: str = "observer", *, owner: str | None = None) -> dict:
    """``spec`` validated for its keys (not its values); returns a copy.

    Unknown keys are reported as ``<where>.<key>``, a missing key against ``owner`` (default
    ``where``).
    """
    owner = owner or where
    if not isinstance(spec, dict):
        raise ParameterTypeError(f"{owner} must be a dict of design arguments, got {spec!r}")
    _, (_, keys, required) = _family(spec, where)
    check_keys(spec, (*keys, "type"), where)
    missing = [k for k in required if k not in spec]
    if missing:
        raise ParameterValueError(
            f"{owner} must have the required key {missing[0]!r} (keys: {', '.join(keys)}), "
            f"got {spec!r}"
        )
    return dict(spec)


def design_from_spec(model, spec: dict, where: str = "observer"):
    """Design the observer ``spec`` describes on the nominal discrete ``model``."""
    spec = check_spec(spec, where)
    _, (design, _, _) = _family(spec, where)
    arguments = {k: v for k, v in spec.items() if k != "type"}
    return design(model, **arguments)


def spec_of(observer) -> dict | None:
    """The spec of a design of a known family (None for any other observer)."""
    design = getattr(observer, "design", None)
    if isinstance(design, (ObserverDesign, PositionObserverDesign, ESODesign, KalmanDesign)):
        observer = design
    if isinstance(observer, ESODesign):
        return {"type": "eso", "bandwidth": observer.bandwidth,
                "extended_order": observer.extended_order, "form": observer.form}  # fmt: skip
    if isinstance(observer, KalmanDesign):
        return {"type": "kalman", "order": observer.order,
                "position_noise_std": observer.position_noise_std,
                "process_noise_std": observer.process_noise_std}  # fmt: skip
    if isinstance(observer, DisturbanceObserver):
        observer = observer.design
    if isinstance(observer, ObserverDesign):
        spec = {"order": observer.order, "gain_direction": tuple(observer.gain_direction)}
        if observer.bandwidth is not None:
            spec["bandwidth"] = observer.bandwidth
        else:
            spec["poles"] = tuple(observer.poles)
        return spec
    if isinstance(observer, PositionObserverDesign):
        spec = {"order": observer.order, "measurement": "position"}
        if observer.bandwidth is not None:
            spec["bandwidth"] = observer.bandwidth
            if observer.velocity_bandwidth != observer.bandwidth:
                spec["velocity_bandwidth"] = observer.velocity_bandwidth
        else:
            spec["poles"] = tuple(observer.poles)
        return spec
    return None


def design_at_bandwidth(model, spec: dict, bandwidth: float, where: str = "observer"):
    """Design ``spec``'s family at ``bandwidth`` [rad/s] (what robust-stability maps, the
    comparison and the tuner sweep over).

    For the order-m and ESO families the bandwidth replaces ``poles``/``bandwidth`` of the
    spec; for the Kalman observer, which has no bandwidth parameter, the process noise is
    chosen by :func:`~hpdob.observers.kalman_process_noise` so that the estimation response
    has that bandwidth (the spec must give ``position_noise_std``).
    """
    if not isinstance(spec, dict):
        raise ParameterTypeError(f"{where} must be a dict of design arguments, got {spec!r}")
    kind = spec.get("type", "dob")
    placeholder = {"process_noise_std": 1.0} if kind == "kalman" else {"bandwidth": 1.0}
    spec = {**check_spec({**spec, **placeholder}, where), **spec}
    spec.pop("process_noise_std" if kind == "kalman" else "bandwidth", None)
    arguments = {k: v for k, v in spec.items() if k not in ("type", "poles")}
    if kind == "kalman":
        from ._kalman import kalman_process_noise

        arguments["process_noise_std"] = kalman_process_noise(
            model,
            bandwidth=bandwidth,
            position_noise_std=arguments["position_noise_std"],
            order=arguments.get("order", 0),
        )
    else:
        arguments["bandwidth"] = bandwidth
    return FAMILIES[kind][0](model, **arguments)
