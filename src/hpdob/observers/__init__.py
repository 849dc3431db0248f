"""Observers: the unified order-m synthesis, its runtime object and its functional core.

design_observer, ObserverDesign
    Pure synthesis of an observer of any truncation order (eigenvalue placement or bandwidth).
DisturbanceObserver
    Stateful runtime object for the sample loop (``estimate`` then ``update``).
initial_state, estimate, update
    The pure functional core of the sample loop.
characteristic_polynomial, error_matrix, extrapolation_weights
    The structure of the error dynamics (eqs. 12, 22, 24 generalised).
"""

from ._core import estimate, initial_state, update
from ._runtime import DisturbanceObserver
from ._synthesis import (
    ObserverDesign,
    characteristic_polynomial,
    design_observer,
    error_matrix,
    extrapolation_weights,
)

__all__ = [
    "DisturbanceObserver",
    "ObserverDesign",
    "characteristic_polynomial",
    "design_observer",
    "error_matrix",
    "estimate",
    "extrapolation_weights",
    "initial_state",
    "update",
]
