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

from . import identification, paper, signals
from ._validation import ParameterTypeError, ParameterValueError
from ._version import __version__
from .analysis import (
    Comparison,
    GangOfFour,
    LoopMargins,
    NoiseGains,
    NoiseTradeoff,
    StabilityMap,
    closed_loop,
    closed_loop_poles,
    compare_observers,
    estimation_response,
    estimation_transfer,
    gang_of_four,
    loop_margins,
    loop_transfer,
    noise_gains,
    noise_tradeoff,
    observer_noise_gain,
    robust_stability_map,
)
from .controllers import ADRC, PD, PID, FilteredPD, LinearController
from .export import export_c
from .identification import (
    EstimationResult,
    Identification,
    Log,
    estimate_disturbance,
    identify,
    read_log,
)
from .models import DiscreteServoModel, Environment, MujocoServo, ServoModel, TwoMassServo
from .observers import (
    DisturbanceObserver,
    ExtendedStateObserver,
    KalmanDisturbanceObserver,
    LinearObserver,
    Observer,
    ObserverDesign,
    PositionObserverDesign,
    characteristic_polynomial,
    design_observer,
    error_matrix,
    estimate,
    extrapolation_weights,
    initial_state,
    update,
)
from .simulation import (
    Actuator,
    Encoder,
    ServoLoop,
    SimulationDivergedWarning,
    SimulationResult,
    simulate,
    sweep,
)
from .tuning import TuningResult, tune

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
