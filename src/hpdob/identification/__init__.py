"""Identification of a real axis from a logged run, and reading logs.

read_log, read_logs, Log
    Read a logged run (time, position, input) from CSV, Parquet or MATLAB ``.mat`` files by
    column name, with validation; ``read_logs`` splits a file with a run column.
identify, Identification, Validation
    Inverse-model identification of inertia, viscous and Coulomb friction and offset from one
    log or several: by default (``"auto"``) with filters read from the log and instrumental
    variables; ``"idim-ls"`` (the EMPS benchmark's least squares) or ``"idim-iv"``
    (instrumental variables from the simulated closed loop). ``Identification.validate``
    simulates the model on another log and reports MATLAB ``compare``'s fit.
estimate_disturbance, EstimationResult
    Any observer run offline over a logged run (compiled), its estimates and velocity.
open_log, LogFile, estimate_log, LogEstimate
    A long log checked and then read block by block (a Parquet file a row group at a time), and
    the estimate run over it block by block, its traces written to CSV as they come.
FeedbackLoop, differentiate
    The controller and reference that produced a log (needed by ``"idim-iv"``), and
    identify's filtered differentiation (for a logged reference's velocity).
emps, emps_loop, EMPS_FILE, EMPS_PUBLISHED, EMPS_PUBLISHED_STD
    The EMPS benchmark's measured run (shipped with hpdob), its controller, the shipped file
    and the published IDIM-LS values with their standard deviations.

A linear axis (m, N, kg) obeys the same equations as a rotary one (rad, N m, kg m^2); pass
``axis="linear"`` or ``"rotary"`` for the units of reports, or leave it None.
"""

from ._emps import EMPS_FILE, EMPS_PUBLISHED, EMPS_PUBLISHED_STD, emps, emps_loop
from ._estimate import EstimationResult, estimate_disturbance
from ._identify import FRICTION_MODELS, METHODS, OFFSETS, IdentificationWarning, identify
from ._log import Log, read_log, read_logs
from ._log_file import LogFile, open_log
from ._loop import FeedbackLoop, simulate_loop
from ._regression import differentiate
from ._result import Identification
from ._simfit import Validation
from ._stream import LogEstimate, estimate_log

__all__ = [
    "EMPS_FILE",
    "EMPS_PUBLISHED",
    "EMPS_PUBLISHED_STD",
    "FRICTION_MODELS",
    "METHODS",
    "OFFSETS",
    "EstimationResult",
    "FeedbackLoop",
    "Identification",
    "IdentificationWarning",
    "Log",
    "LogEstimate",
    "LogFile",
    "Validation",
    "differentiate",
    "emps",
    "emps_loop",
    "estimate_disturbance",
    "estimate_log",
    "identify",
    "open_log",
    "read_log",
    "read_logs",
    "simulate_loop",
]
