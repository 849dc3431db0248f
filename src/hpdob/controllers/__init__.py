"""Controllers: the controller protocol and its implementations.

LinearController, ControllerProgram, ProgramBuilder
    The protocol: a controller is a linear discrete-time system from its named inputs (the
    reference, the measurement, observer outputs) to the torque command, evaluated in the
    order of its program by Python, the compiled kernel and exported C alike.
Controller, controller_system
    The base of controller specifications (designed on the loop's nominal model and ``Ts``),
    and the linear system of any controller in a loop.
PD, FilteredPD, PID, ADRC
    The paper's PD, PD with a filtered derivative, PID with back-calculation anti-windup,
    and linear ADRC (state feedback on its own extended state observer).
ForceControl, ImpedanceControl, PositionForceSwitch
    Force control without a force sensor: explicit force and impedance control on the
    reaction-torque estimate ``tau_reac``, and position control that latches over to force
    control on contact (issue 21).
Switch
    The one nonlinear extension of a controller program: a latching switch of the command.
"""

from ._adrc import ADRC
from ._base import Controller, controller_system
from ._force import ForceControl, ImpedanceControl
from ._pd import PD, VELOCITY_SOURCES, FilteredPD
from ._pid import PID
from ._program import ControllerProgram, Switch
from ._settings import controller_settings
from ._switching import PositionForceSwitch
from ._system import LOOP_SIGNALS, LinearController, ProgramBuilder

#: The controller types of scenario files (``[controller] type = "pid"``). The last three read
#: the reaction-torque estimate ``tau_reac``: a servo scenario gives them a
#: ``[reaction_observer]`` (docs/force-control.md).
CONTROLLER_TYPES = {"pd": PD, "pid": PID, "filtered-pd": FilteredPD, "adrc": ADRC,
                    "force": ForceControl, "impedance": ImpedanceControl,
                    "position-force": PositionForceSwitch}  # fmt: skip

__all__ = [
    "ADRC",
    "CONTROLLER_TYPES",
    "LOOP_SIGNALS",
    "PD",
    "PID",
    "VELOCITY_SOURCES",
    "Controller",
    "ControllerProgram",
    "FilteredPD",
    "ForceControl",
    "ImpedanceControl",
    "LinearController",
    "PositionForceSwitch",
    "ProgramBuilder",
    "Switch",
    "controller_settings",
    "controller_system",
]
