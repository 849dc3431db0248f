"""The paper's section IV set-up, its runs and its figures (``hpdob reproduce``).

scenario()
    Keyword arguments of :func:`hpdob.simulate` for the paper's set-up, without observer.
observer(name), run(name), RUNS
    The observer and the simulation of each run of ``hpdob reproduce``.
reproduce(out_dir)
    All runs, Figs. 2-5, traces and ``metrics.json``.
PLANT, NOMINAL, TS, DURATION, CONTROLLER, REFERENCE, DISTURBANCE
    The ingredients of :func:`scenario`.
VIRTUAL_SENSOR, VIRTUAL_ACTUATOR, VIRTUAL_RUNS, VIRTUAL_POSITION_CONTROLLER
    Encoder and actuator of the virtual experiments standing in for the paper's Fig. 5, the
    runs that use them, and the PD (on the observer's velocity) of the position-only one.
"""

from ._figures import paper_figures as figures
from ._reproduce import reproduce, summary_table
from ._scenario import (
    CONTROLLER,
    DISTURBANCE,
    DURATION,
    NOMINAL,
    PLANT,
    REFERENCE,
    RUNS,
    TS,
    VIRTUAL_ACTUATOR,
    VIRTUAL_POSITION_CONTROLLER,
    VIRTUAL_RUNS,
    VIRTUAL_SENSOR,
    observer,
    run,
    scenario,
)

__all__ = [
    "CONTROLLER",
    "DISTURBANCE",
    "DURATION",
    "NOMINAL",
    "PLANT",
    "REFERENCE",
    "RUNS",
    "TS",
    "VIRTUAL_ACTUATOR",
    "VIRTUAL_POSITION_CONTROLLER",
    "VIRTUAL_RUNS",
    "VIRTUAL_SENSOR",
    "figures",
    "observer",
    "reproduce",
    "run",
    "scenario",
    "summary_table",
]
