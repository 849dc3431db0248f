"""What the loop accepts as its controller, and the controller types of scenario files."""

from __future__ import annotations

import functools
from abc import ABC, abstractmethod

from .._validation import ParameterTypeError
from ._system import LinearController

__all__ = ["Controller", "controller_system"]


class Controller(ABC):
    """A controller specification: it designs its :class:`LinearController` on the loop's
    nominal model and sampling period (:class:`~hpdob.PD`, :class:`~hpdob.PID`,
    :class:`~hpdob.FilteredPD`, :class:`~hpdob.ADRC`; a :class:`LinearController` is
    accepted by the loop as it is)."""

    __slots__ = ()

    @abstractmethod
    def design(self, nominal, Ts: float) -> LinearController:
        """The controller as a linear system for this loop.

        Parameters
        ----------
        nominal : ServoModel
            The nominal model (``J_n``, ``b_n``) the controller scales by.
        Ts : float
            Sampling period [s].

        Returns
        -------
        LinearController
        """


def controller_system(controller, nominal, Ts: float, name: str = "controller"):
    """The :class:`LinearController` of ``controller`` in a loop on ``nominal`` at ``Ts``.

    Parameters
    ----------
    controller : Controller or LinearController
        A specification (designed here; a frozen one's design is kept and reused) or a
        linear controller (checked to run at ``Ts``).
    nominal : ServoModel
        The loop's nominal model.
    Ts : float
        The loop's sampling period [s].
    name : str, optional
        The parameter name of error messages. Default ``"controller"``.

    Returns
    -------
    LinearController

    Raises
    ------
    ParameterTypeError
        If ``controller`` is neither a :class:`Controller` nor a :class:`LinearController`.
    ParameterValueError
        If its design refuses ``nominal`` or ``Ts``.

    Examples
    --------
    >>> from hpdob import PD, ServoModel
    >>> from hpdob.controllers import controller_system
    >>> controller_system(PD(50.0, 5.0), ServoModel(2.8e-4), 1e-3).n_states
    0
    """
    if isinstance(controller, LinearController):
        return controller.design(nominal, Ts)
    if isinstance(controller, Controller):
        try:
            return _design(controller, nominal, Ts)
        except TypeError:  # an unhashable specification: designed every time
            return controller.design(nominal, Ts)
    raise ParameterTypeError(
        f"{name} must be a PD, PID, FilteredPD, ADRC or another Controller (or a "
        f"LinearController), got {type(controller).__name__}"
    )


@functools.lru_cache(maxsize=256)
def _design(controller, nominal, Ts: float):
    """The design of a hashable (frozen) specification, kept: designs are immutable, and a
    loop built again (every ``paper.run``, every sweep scenario) then reuses the controller's
    generated code and kernel arrays instead of paying ~0.7 ms to rebuild them."""
    return controller.design(nominal, Ts)
