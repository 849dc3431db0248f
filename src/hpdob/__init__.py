"""hpdob: discrete-time disturbance observers for motion control.

Conventional DOb (order 0), the High-Performance DOb (order 1) and observers of any
truncation order from one synthesis, after E. Sariyildiz, "A High Performance Disturbance
Observer: A Unified Synthesis Approach".

Public namespace
----------------
ServoModel, DiscreteServoModel
    Servo model (eq. 1) and its exact zero-order-hold discretisation (eqs. 4-8).
design_observer, ObserverDesign, PositionObserverDesign
    Pure synthesis of an observer of any order by eigenvalue placement or bandwidth, measuring
    the state (the paper's) or the angle only (``measurement="position"``).
LinearObserver
    The observer protocol: every observer as a linear discrete-time system.
ExtendedStateObserver, KalmanDisturbanceObserver
    The observers the field compares against: ADRC's extended state observer and a Kalman
    filter with a disturbance state.
DisturbanceObserver, Observer
    Stateful runtime objects for the sample loop (``estimate`` then ``update``).
initial_state, estimate, update
    The pure functional core of the sample loop.
export_c
    Export a design as dependency-free C99 for a microcontroller.
ServoLoop
    The closed loop as a value: the first argument of simulate and the analysis functions.
PD, PID, FilteredPD, ADRC, LinearController
    Controllers: the controller protocol (a linear system from the reference, the
    measurement and the observer's outputs to the torque command) and its implementations.
Encoder, Actuator, simulate, SimulationResult
    Sampled-data closed-loop simulation (continuous plant, sampled PD, DOb inner loop).
TwoMassServo
    Motor and load coupled by a torsional spring and damper (a resonant drive), as ``plant=``.
Environment
    A unilateral spring-damper contact the axis (or the load) presses against.
MujocoServo
    A servo (optionally with a pendulum link) simulated by MuJoCo, as ``plant=`` of
    ``simulate`` and ``sweep``; MuJoCo is imported only when a model is built.
sweep
    Batch sweeps and Monte Carlo studies, locally or on a dask cluster.
signals
    Built-in reference and disturbance signals (steps, quintic steps, sines, ramps, ...).
estimation_transfer, estimation_response
    Closed-form disturbance-estimation response (the "Q-filter") of an observer.
closed_loop, closed_loop_poles, gang_of_four, loop_transfer, loop_margins
    The linear sampled-data loop as a python-control system, its poles, sensitivities, margins.
noise_gains, observer_noise_gain, noise_tradeoff
    Exact noise gains (discrete Lyapunov equation) and the accuracy/noise trade-off.
robust_stability_map
    Closed-loop stability over inertia or friction errors and observer bandwidths.
read_log, Log, identify, Identification
    Real data: read a logged run (CSV, Parquet, .mat) and identify J, b, Coulomb friction and
    offset (IDIM-LS, IDIM-IV); see :mod:`hpdob.identification`.
"""

# The names are imported on first use (PEP 562), so that ``import hpdob`` (and the ``hpdob``
# command, which installs its signal handlers first) does not import numpy, scipy and
# python-control up front: see hpdob._interrupts.
from ._version import __version__

#: Public name -> the module that defines it (a module name alone: the subpackage itself).
_LAZY = {
    "identification": ".identification",
    "paper": ".paper",
    "signals": ".signals",
    "ParameterTypeError": "._validation",
    "ParameterValueError": "._validation",
    "Comparison": ".analysis",
    "GangOfFour": ".analysis",
    "LoopMargins": ".analysis",
    "NoiseGains": ".analysis",
    "NoiseTradeoff": ".analysis",
    "StabilityMap": ".analysis",
    "closed_loop": ".analysis",
    "closed_loop_poles": ".analysis",
    "compare_observers": ".analysis",
    "estimation_response": ".analysis",
    "estimation_transfer": ".analysis",
    "gang_of_four": ".analysis",
    "loop_margins": ".analysis",
    "loop_transfer": ".analysis",
    "noise_gains": ".analysis",
    "noise_tradeoff": ".analysis",
    "observer_noise_gain": ".analysis",
    "robust_stability_map": ".analysis",
    "export_c": ".export",
    "EstimationResult": ".identification",
    "Identification": ".identification",
    "Log": ".identification",
    "estimate_disturbance": ".identification",
    "identify": ".identification",
    "read_log": ".identification",
    "DiscreteServoModel": ".models",
    "Environment": ".models",
    "MujocoServo": ".models",
    "ServoModel": ".models",
    "TwoMassServo": ".models",
    "DisturbanceObserver": ".observers",
    "ExtendedStateObserver": ".observers",
    "KalmanDisturbanceObserver": ".observers",
    "LinearObserver": ".observers",
    "Observer": ".observers",
    "ObserverDesign": ".observers",
    "PositionObserverDesign": ".observers",
    "characteristic_polynomial": ".observers",
    "design_observer": ".observers",
    "error_matrix": ".observers",
    "estimate": ".observers",
    "extrapolation_weights": ".observers",
    "initial_state": ".observers",
    "update": ".observers",
    "ADRC": ".controllers",
    "PD": ".controllers",
    "PID": ".controllers",
    "FilteredPD": ".controllers",
    "LinearController": ".controllers",
    "Actuator": ".simulation",
    "Encoder": ".simulation",
    "ServoLoop": ".simulation",
    "SimulationDivergedWarning": ".simulation",
    "SimulationResult": ".simulation",
    "simulate": ".simulation",
    "sweep": ".simulation",
    "TuningResult": ".tuning",
    "tune": ".tuning",
    # subpackages, reachable as attributes as when they were imported eagerly
    "analysis": ".analysis",
    "controllers": ".controllers",
    "robots": ".robots",
    "export": ".export",
    "models": ".models",
    "observers": ".observers",
    "simulation": ".simulation",
    "tuning": ".tuning",
}


def __getattr__(name: str):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'hpdob' has no attribute {name!r}")
    import importlib  # here, not at the top: `import hpdob` stays a few assignments

    if module == f".{name}":  # a subpackage or module of hpdob
        value = importlib.import_module(module, __name__)
    else:
        value = getattr(importlib.import_module(module, __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))


__all__ = [
    "ADRC",
    "PD",
    "PID",
    "Actuator",
    "Comparison",
    "DiscreteServoModel",
    "DisturbanceObserver",
    "Encoder",
    "Environment",
    "EstimationResult",
    "ExtendedStateObserver",
    "FilteredPD",
    "GangOfFour",
    "Identification",
    "KalmanDisturbanceObserver",
    "LinearController",
    "LinearObserver",
    "Log",
    "LoopMargins",
    "MujocoServo",
    "NoiseGains",
    "NoiseTradeoff",
    "Observer",
    "ObserverDesign",
    "ParameterTypeError",
    "ParameterValueError",
    "PositionObserverDesign",
    "ServoLoop",
    "ServoModel",
    "SimulationDivergedWarning",
    "SimulationResult",
    "StabilityMap",
    "TuningResult",
    "TwoMassServo",
    "__version__",
    "characteristic_polynomial",
    "closed_loop",
    "closed_loop_poles",
    "compare_observers",
    "design_observer",
    "error_matrix",
    "estimate",
    "estimate_disturbance",
    "estimation_response",
    "estimation_transfer",
    "export_c",
    "extrapolation_weights",
    "gang_of_four",
    "identification",
    "identify",
    "initial_state",
    "loop_margins",
    "loop_transfer",
    "noise_gains",
    "noise_tradeoff",
    "observer_noise_gain",
    "paper",
    "read_log",
    "robust_stability_map",
    "signals",
    "simulate",
    "sweep",
    "tune",
    "tuning",
    "update",
]
