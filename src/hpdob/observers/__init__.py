"""Observers: the observer protocol, the unified order-m synthesis, runtime and functional core.

LinearObserver, Program, Term, ErrorDynamics
    The observer protocol: every observer is a linear discrete-time system (F, G, H, E, N),
    evaluated in the order of its program by Python, the compiled kernel and exported C alike.
design_observer, ObserverDesign, PositionObserverDesign
    Pure synthesis of an order-m observer (eigenvalue placement or bandwidth), measuring the
    state or, with ``measurement="position"``, the angle only.
Observer, DisturbanceObserver
    Stateful runtime objects for the sample loop (``estimate`` then ``update``).
design_eso, ExtendedStateObserver, ESODesign
    The linear extended state observer of ADRC (classical and generalised, two forms).
design_kalman, KalmanDisturbanceObserver, KalmanDesign, kalman_process_noise
    The steady-state Kalman filter with a disturbance state.
Family, Parameter, register_family, unregister_family, families, get_family
    The family registry: one record per family, read by sweeps, scenario files, the CLI,
    ``tune``, ``compare_observers`` and the robust maps; ``design_from_spec``,
    ``design_at_bandwidth`` and ``spec_of`` design from and back to a spec.
reaction_torque_observer, design_reaction_observer, ReactionObserverDesign
    The DOb and a reaction-torque observer as one observer (force control without a force
    sensor); the design keeps its parts, for scenario files and sweeps.
    ``coulomb_velocity_resolution`` gives the encoder's velocity resolution through the
    Coulomb term's velocity path (its ``coulomb_deadband``).
CoulombFriction, coulomb_torque
    The one nonlinear observer term: the Coulomb part of a reaction-torque observer's friction
    model (``reaction_torque_observer(..., coulomb=)``).
initial_state, estimate, outputs, update
    The pure functional core of the sample loop, for any observer.
characteristic_polynomial, error_matrix, extrapolation_weights
    The structure of the error dynamics (eqs. 12, 22, 24 generalised).
"""

from . import _families  # noqa: F401  (registers the built-in families)
from ._core import estimate, initial_state, outputs, update
from ._error_dynamics import unit_root_polynomial as unit_root_polynomial
from ._eso import ESODesign, ExtendedStateObserver, design_eso
from ._friction import CoulombFriction, coulomb_torque
from ._kalman import KalmanDesign, KalmanDisturbanceObserver, design_kalman, kalman_process_noise
from ._position import PositionObserverDesign
from ._program import RESET_OPERANDS as RESET_OPERANDS
from ._program import program_coefficients as program_coefficients
from ._program import program_structure as program_structure
from ._program import render_sum as render_sum
from ._reaction import FRICTION_PARAMETERS as FRICTION_PARAMETERS
from ._reaction import (
    ReactionObserverDesign,
    coulomb_velocity_resolution,
    design_reaction_observer,
    reaction_torque_observer,
)
from ._realised import POLE_TOLERANCE as POLE_TOLERANCE
from ._registry import (
    Family,
    Parameter,
    check_spec,
    design_at_bandwidth,
    design_from_spec,
    families,
    family_of,
    get_family,
    register_family,
    spec_label,
    spec_of,
    tuned_value,
    unregister_family,
)
from ._response import estimation_frequency_response as estimation_frequency_response
from ._response import nominal_loop as nominal_loop
from ._response import observer_matrices as observer_matrices
from ._runtime import DisturbanceObserver, Observer
from ._synthesis import (
    ObserverDesign,
    characteristic_polynomial,
    design_observer,
    error_matrix,
    extrapolation_weights,
)
from ._system import MEASUREMENTS as MEASUREMENTS
from ._system import UNITS as UNITS
from ._system import ErrorDynamics, LinearObserver, Program, Term, as_system
from ._system import check_designed_on as check_designed_on

# Names imported "as" themselves and absent from __all__ are hpdob-internal: for the other
# subpackages, not part of the public API (docs/architecture.md, "Dependency order").
__all__ = [
    "CoulombFriction",
    "DisturbanceObserver",
    "ESODesign",
    "ErrorDynamics",
    "ExtendedStateObserver",
    "Family",
    "KalmanDesign",
    "KalmanDisturbanceObserver",
    "LinearObserver",
    "Observer",
    "ObserverDesign",
    "Parameter",
    "PositionObserverDesign",
    "Program",
    "ReactionObserverDesign",
    "Term",
    "as_system",
    "characteristic_polynomial",
    "check_spec",
    "coulomb_torque",
    "coulomb_velocity_resolution",
    "design_at_bandwidth",
    "design_eso",
    "design_from_spec",
    "design_kalman",
    "design_observer",
    "design_reaction_observer",
    "error_matrix",
    "estimate",
    "extrapolation_weights",
    "families",
    "family_of",
    "get_family",
    "initial_state",
    "kalman_process_noise",
    "outputs",
    "reaction_torque_observer",
    "register_family",
    "spec_label",
    "spec_of",
    "tuned_value",
    "unregister_family",
    "update",
]
