"""The cases of the per-family invariants, read from the family registry (not listed here).

Every registered family contributes its tuner variants at each of its orders and its
comparison candidates, designed at a bandwidth by the family's own rule
(``design_at_bandwidth``); the family's noise parameter, if it has one, is an encoder's
``q/sqrt(12)``.
"""

from __future__ import annotations

from hpdob.observers import design_at_bandwidth, families

ANGLE_NOISE = 1.1e-4  # rad, a 16384-count encoder's q/sqrt(12)


def family_specs() -> list[dict]:
    """``[spec]`` without the tuned parameter, every registered family's, deduplicated."""
    specs = []
    for family in families():
        candidates = [
            spec if family.order is None else {**spec, family.order: m}
            for spec in family.variants.values()
            for m in family.orders
        ]
        candidates += list(family.compared.values())
        for spec in candidates:
            spec = {"type": family.name, **spec}
            if family.noise_parameter is not None:
                spec[family.noise_parameter] = ANGLE_NOISE
            if spec not in specs:
                specs.append(spec)
    return specs


def spec_id(spec: dict) -> str:
    return ",".join(f"{k}={v}" for k, v in spec.items())


_DESIGNS: dict = {}


def design(model, spec: dict, bandwidth: float = 150.0):
    """The design of ``spec`` at ``bandwidth`` [rad/s] (kept: designs are immutable, and the
    Kalman rule solves for its process noise)."""
    key = (model.J, model.b, model.Ts, spec_id(spec), bandwidth)
    if key not in _DESIGNS:
        _DESIGNS[key] = design_at_bandwidth(model, spec, bandwidth)
    return _DESIGNS[key]
