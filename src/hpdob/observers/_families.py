"""The built-in families' registry records: the paper's order-m observers, the ESO, Kalman.

Registered when :mod:`hpdob.observers` is imported; see :mod:`hpdob.observers._registry`.
"""

from __future__ import annotations

import math

from .._validation import ParameterValueError
from ._eso import ESO_FORMS, ESODesign, ExtendedStateObserver, design_eso
from ._kalman import KalmanDesign, KalmanDisturbanceObserver, design_kalman, kalman_process_noise
from ._position import PositionObserverDesign
from ._registry import Family, Parameter, register_family
from ._runtime import DisturbanceObserver
from ._synthesis import ObserverDesign, design_observer

__all__ = ["DOB", "ESO", "KALMAN"]

_ORDER_NAMES = {0: "DOb (m=0)", 1: "HPDOb (m=1)"}


def _dob_spec(design) -> dict:
    if isinstance(design, ObserverDesign):
        spec = {"type": "dob", "order": design.order,
                "gain_direction": tuple(design.gain_direction)}  # fmt: skip
        if design.bandwidth is not None:
            spec["bandwidth"] = design.bandwidth
        else:
            spec["poles"] = tuple(design.poles)
        return spec
    spec = {"type": "dob", "order": design.order, "measurement": "position"}
    if design.bandwidth is not None:
        spec["bandwidth"] = design.bandwidth
        if design.velocity_bandwidth != design.bandwidth:
            spec["velocity_bandwidth"] = design.velocity_bandwidth
    else:
        spec["poles"] = tuple(design.poles)
    return spec


def _dob_label(spec: dict) -> str:
    m = spec.get("order")
    name = _ORDER_NAMES.get(m, f"order-{m} DOb")
    return ("position-only " if spec.get("measurement") == "position" else "") + name


def _dob_respec(spec: dict, varied: set, base_spec: dict) -> dict:
    """A sweep's redesign: a varied measurement drops the other measurement's arguments (the
    number of poles differs between them)."""
    if "measurement" in varied:
        other = "gain_direction" if spec["measurement"] == "position" else "velocity_bandwidth"
        spec.pop(other, None)
        if "poles" in spec and spec["measurement"] != base_spec.get("measurement", "state"):
            raise ParameterValueError(
                "observer.measurement can vary only for an observer designed by bandwidth "
                f"(the number of poles differs between the families), got poles={spec['poles']}"
            )
    return spec


DOB = Family(
    name="dob",
    design=design_observer,
    parameters=(
        Parameter("order", "int", "truncation order m: 0 DOb, 1 HPDOb, >= 2 generalised"),
        Parameter("poles", "complex_list", "the m+1 poles (m+3 measuring the position)"),
        Parameter("bandwidth", "float", "bandwidth g [rad/s], all poles at exp(-g Ts)"),
        Parameter(
            "measurement",
            "choice",
            "what it measures: angle and velocity, or the angle",
            choices=("state", "position"),
            default="state",
        ),
        Parameter(
            "velocity_bandwidth",
            "float",
            "bandwidth of the two velocity poles [rad/s]",
            only_with=("measurement", "position"),
        ),
        Parameter(
            "gain_direction",
            "float_list",
            "gain direction d (eq. 25)",
            only_with=("measurement", "state"),
        ),
    ),
    required=("order",),
    order="order",
    tuned="bandwidth",
    replaced_by_bandwidth=("poles",),
    designs=(ObserverDesign, PositionObserverDesign),
    spec_of=_dob_spec,
    runtime=lambda design, x0, tau0: DisturbanceObserver.from_design(design, x0=x0, tau0=tau0),
    label=_dob_label,
    title="the paper's order-m observers (eqs. 11-25), measuring the state or the angle only",
    variants={"state": {"measurement": "state"}, "position": {"measurement": "position"}},
    orders=(0, 1, 2),
    compared={
        "DOb": {"order": 0},
        "HPDOb": {"order": 1},
        "order 2": {"order": 2},
        "DOb, position": {"order": 0, "measurement": "position"},
        "HPDOb, position": {"order": 1, "measurement": "position"},
        "order 2, position": {"order": 2, "measurement": "position"},
    },
    respec=_dob_respec,
    defaults={"order": 1},
)

ESO = Family(
    name="eso",
    design=design_eso,
    parameters=(
        Parameter("bandwidth", "float", "observer bandwidth omega_o [rad/s]"),
        Parameter("extended_order", "int", "f^(m+1) = 0: 0 the classical ESO"),
        Parameter(
            "form", "choice", "discrete implementation", choices=ESO_FORMS, default="current"
        ),
    ),
    required=("bandwidth",),
    order="extended_order",
    tuned="bandwidth",
    designs=(ESODesign,),
    spec_of=lambda d: {
        "type": "eso",
        "bandwidth": d.bandwidth,
        "extended_order": d.extended_order,
        "form": d.form,
    },
    runtime=lambda design, x0, tau0: ExtendedStateObserver._of(design, x0, tau0),
    label=lambda spec: f"ESO (m={spec.get('extended_order', 0)}, {spec.get('form', 'current')})",
    title="ADRC's linear extended state observer (classical and generalised)",
    variants={"eso": {"form": "current"}},
    orders=(0, 1, 2),
    compared={
        "ESO, current": {"extended_order": 0, "form": "current"},
        "ESO, predictive": {"extended_order": 0, "form": "predictive"},
        "GESO m=1, current": {"extended_order": 1, "form": "current"},
        "GESO m=1, predictive": {"extended_order": 1, "form": "predictive"},
    },
)


def _kalman_process_noise(model, arguments: dict, bandwidth: float) -> float:
    """The Kalman process-noise-from-bandwidth rule (written once)."""
    if "position_noise_std" not in arguments:
        raise ParameterValueError(
            "a Kalman observer designed for a bandwidth needs position_noise_std (the angle "
            f"noise [rad]), got {arguments!r}"
        )
    return kalman_process_noise(
        model,
        bandwidth=bandwidth,
        position_noise_std=arguments["position_noise_std"],
        order=arguments.get("order", 0),
    )


def _kalman_range(model, arguments: dict) -> tuple[float, float]:
    """The process noises the comparison searches: 12 decades around sigma J/Ts^2."""
    centre = math.log10(arguments["position_noise_std"] * model.J / model.Ts**2)
    return 10 ** (centre - 8), 10 ** (centre + 4)


KALMAN = Family(
    name="kalman",
    design=design_kalman,
    parameters=(
        Parameter("order", "int", "disturbance order m of the random-walk model"),
        Parameter("position_noise_std", "float", "angle noise std [rad] (resolution/sqrt(12))"),
        Parameter("process_noise_std", "float", "process noise std (sets the bandwidth)"),
    ),
    required=("position_noise_std", "process_noise_std"),
    order="order",
    tuned="process_noise_std",
    tuned_from_bandwidth=_kalman_process_noise,
    noise_parameter="position_noise_std",
    designs=(KalmanDesign,),
    spec_of=lambda d: {
        "type": "kalman",
        "order": d.order,
        "position_noise_std": d.position_noise_std,
        "process_noise_std": d.process_noise_std,
    },
    runtime=lambda design, x0, tau0: KalmanDisturbanceObserver._of(design, x0, tau0),
    label=lambda spec: f"Kalman (m={spec.get('order', 0)})",
    title="the steady-state Kalman filter with a disturbance state",
    orders=(0, 1, 2),
    compared={"Kalman m=0": {"order": 0}, "Kalman m=1": {"order": 1}},
    tuned_range=_kalman_range,
)

for _family in (DOB, ESO, KALMAN):
    register_family(_family, replace=True)
