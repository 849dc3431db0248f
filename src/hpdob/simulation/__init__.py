"""The sampled-data loop and its simulation: sensor, actuator, simulate, sweep.

ServoLoop, LOOP_KEYS
    The closed loop as a value (plant, nominal model, Ts, controller, observer, sensor,
    actuator): the first argument of simulation and analysis; its parts as keyword arguments
    instead (the one alias rule).
Encoder, Actuator
    Sensor and actuator models (the controllers are in :mod:`hpdob.controllers`).
simulate, SimulationResult, SimulationDivergedWarning
    One closed-loop run (continuous plant, sampled PD, observer inner loop).
load_scenario, Scenario, scenario_toml
    A TOML scenario file read into a :class:`ServoLoop` and the run settings, and written from a
    loop and a run.
PlantType, register_plant_type, unregister_plant_type, plant_types, get_plant_type
    The registry of ``[plant] type`` values of scenario files: how a table becomes a plant and
    which loop runs it (the N-joint arms register theirs from :mod:`hpdob.robots`).
sweep
    Batch sweeps and Monte Carlo studies, locally or on a dask cluster.
"""

from ._controller import PD as PD  # the PD lives in hpdob.controllers; kept importable here
from ._devices import Actuator, Encoder
from ._loop import LOOP_KEYS, ServoLoop
from ._plant_types import (
    PlantType,
    get_plant_type,
    plant_types,
    register_plant_type,
    unregister_plant_type,
)
from ._result import SimulationResult
from ._scenario import Scenario, load_scenario
from ._scenario_toml import scenario_toml
from ._simulate import SimulationDivergedWarning, simulate
from ._sweep import SweepIncomplete, SweepInterrupted, sweep

__all__ = [
    "LOOP_KEYS",
    "Actuator",
    "Encoder",
    "PlantType",
    "Scenario",
    "ServoLoop",
    "SimulationDivergedWarning",
    "SimulationResult",
    "SweepIncomplete",
    "SweepInterrupted",
    "get_plant_type",
    "load_scenario",
    "plant_types",
    "register_plant_type",
    "scenario_toml",
    "simulate",
    "sweep",
    "unregister_plant_type",
]
