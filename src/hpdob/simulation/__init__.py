"""The sampled-data loop and its simulation: sensor, actuator, simulate, sweep.

ServoLoop, LOOP_KEYS
    The closed loop as a value (plant, nominal model, Ts, controller, observer, sensor,
    actuator): the first argument of simulation and analysis; its parts as keyword arguments
    instead (the one alias rule).
Encoder, Actuator
    Sensor and actuator models (the controllers are in :mod:`hpdob.controllers`).
simulate, SimulationResult, SimulationDivergedWarning
    One closed-loop run (continuous plant, sampled controller, observer inner loop).
load_scenario, Scenario, scenario_toml
    A TOML scenario file read into a :class:`ServoLoop` and the run settings, and written from a
    loop and a run.
PlantType, register_plant_type, unregister_plant_type, plant_types, get_plant_type
    The registry of ``[plant] type`` values of scenario files: how a table becomes a plant and
    which loop runs it (the N-joint arms register theirs from :mod:`hpdob.robots`).
sweep
    Batch sweeps and Monte Carlo studies, locally or on a dask cluster.
build_loop_extension, LoopBuildError, AheadOfTimeWarning
    A run structure's sample loop built ahead of time with ``numba.pycc`` (opt-in), which
    :func:`simulate` runs in a later process without numba.
"""

from ..controllers import PD as PD  # the PD lives in hpdob.controllers; kept importable here
from . import _canonical as canonical  # noqa: F401 (the paper's set-up as one namespace)
from ._devices import Actuator, Encoder
from ._force_run import force_reference as force_reference
from ._force_run import force_run_columns as force_run_columns
from ._force_run import force_run_metrics as force_run_metrics
from ._force_run import position_metrics_apply as position_metrics_apply
from ._loop import LOOP_KEYS, ServoLoop
from ._loop import MISSING as MISSING
from ._loop import accepts_loop as accepts_loop
from ._loop import loop_parts as loop_parts
from ._plant_types import (
    PlantType,
    get_plant_type,
    plant_types,
    register_plant_type,
    unregister_plant_type,
)
from ._result import SimulationResult
from ._result import json_ready as json_ready
from ._result import metric_window as metric_window
from ._result import metrics_json as metrics_json
from ._scenario import Scenario, load_scenario
from ._scenario import load_sweep as load_sweep
from ._scenario import metric_windows as metric_windows
from ._scenario import plant_type_of as plant_type_of
from ._scenario import read_toml as read_toml
from ._scenario import scenario_from_dict as scenario_from_dict
from ._scenario_toml import scenario_toml
from ._simulate import MAX_PLANT_STEPS as MAX_PLANT_STEPS
from ._simulate import SimulationDivergedWarning, simulate
from ._simulate import clear_sampled_signals as clear_sampled_signals
from ._simulate import run_loop as run_loop
from ._simulate import sample_count as sample_count
from ._simulate import sample_signals as sample_signals
from ._sweep import SweepIncomplete, SweepInterrupted, sweep

# Names imported "as" themselves and absent from __all__ are hpdob-internal: for the other
# subpackages, not part of the public API (docs/architecture.md, "Dependency order").


def __getattr__(name: str):
    """``program_row`` (hpdob-internal, for the robots' kernel), imported on first use: it is
    compiled by numba, and importing numba (~0.3 s) is for the first simulation, not for every
    user of a loop, an analysis or the paper's set-up; the ahead-of-time build's names
    likewise (its modules are for the few who build a loop)."""
    if name == "program_row":
        from ._kernel import program_row

        return program_row
    if name in ("build_loop_extension", "LoopBuildError"):  # not needed by ``import hpdob``
        from . import _aot_build

        return getattr(_aot_build, name)
    if name == "AheadOfTimeWarning":
        from ._aot import AheadOfTimeWarning

        return AheadOfTimeWarning
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "LOOP_KEYS",
    "Actuator",
    "AheadOfTimeWarning",
    "Encoder",
    "LoopBuildError",
    "PlantType",
    "Scenario",
    "ServoLoop",
    "SimulationDivergedWarning",
    "SimulationResult",
    "SweepIncomplete",
    "SweepInterrupted",
    "build_loop_extension",
    "get_plant_type",
    "load_scenario",
    "plant_types",
    "register_plant_type",
    "scenario_toml",
    "simulate",
    "sweep",
    "unregister_plant_type",
]
