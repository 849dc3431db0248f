"""The EMPS benchmark's measured estimation run, shipped with hpdob, and its controller.

EMPS (Electro-Mechanical Positioning System): a prismatic axis driven by a Maxon DC motor
through a ball screw, under PD position control at 1 kHz (A. Janot, M. Gautier, M. Brunot,
"Data set and reference models of EMPS", Workshop on Nonlinear System Identification
Benchmarks, 2019). ``data/DATA_EMPS.mat`` is the benchmark's file, unchanged; its origin and
citation are in ``data/README.md``.
"""

from __future__ import annotations

import types
from pathlib import Path

from .._validation import ParameterValueError, require_instance
from ._log import Log, read_log
from ._loop import FeedbackLoop

__all__ = ["EMPS_FILE", "EMPS_PUBLISHED", "EMPS_PUBLISHED_STD", "emps", "emps_loop"]

#: The shipped copy of the benchmark's DATA_EMPS.mat.
EMPS_FILE = Path(__file__).resolve().parent / "data" / "DATA_EMPS.mat"

#: The benchmark's reference IDIM-LS estimates (EMPS description, section 3.4, the output of
#: Script_IDIM_LS.m): M [kg], Fv [N s/m], Fc [N], offset [N], in hpdob's names.
EMPS_PUBLISHED = types.MappingProxyType(
    {"J": 95.1089, "b": 203.5034, "coulomb": 20.3935, "offset": -3.1648}
)
#: Their published standard deviations (same source).
EMPS_PUBLISHED_STD = types.MappingProxyType(
    {"J": 0.1085, "b": 1.1460, "coulomb": 0.1012, "offset": 0.0444}
)

#: Saturation of the controller's output [V] (``viradm`` of the benchmark's simulation,
#: EMPS description, section 3.5).
_VOLTAGE_LIMIT = 10.0


def emps() -> Log:
    """The EMPS estimation run as a :class:`Log` (linear axis: m, N).

    ``theta`` is the motor position ``qm`` [m, load side], ``u`` the motor force
    ``gtau * vir`` [N] (``gtau`` = 35.15 N/V, read from the file), ``reference`` the
    reference position ``qg`` [m]; 24 841 samples at 1 kHz.

    Returns
    -------
    Log
        Read from :data:`EMPS_FILE` (shipped with hpdob; no download).

    References
    ----------
    A. Janot, M. Gautier, M. Brunot, "Data set and reference models of EMPS", Nonlinear
    System Identification Benchmarks, 2019 (the package's ``data/README.md``).

    Examples
    --------
    >>> from hpdob.identification import emps
    >>> log = emps()
    >>> len(log), log.Ts, log.axis, log.names["position"]
    (24841, 0.001, 'linear', 'qm')
    """
    return read_log(
        EMPS_FILE,
        time="t",
        position="qm",
        input="vir",
        input_gain="gtau",
        reference="qg",
        axis="linear",
    )


def emps_loop(log: Log | None = None) -> FeedbackLoop:
    r"""The EMPS controller (description, eq. 6-7) as a :class:`FeedbackLoop` for ``log``.

    :math:`u = g_\tau\,(k_p k_v (q_r - q) - k_v \dot q_m)` with
    :math:`\dot q_m(k) = (q_k - q_{k-2})/(2 T_s)` (the FIR filter ``0.5 + 0.5 z^{-1}`` then
    a backward difference, section 2.2), saturated at 10 V. ``gtau``, ``kp`` and ``kv`` are
    read from the shipped file.

    Parameters
    ----------
    log : Log, optional
        Supplies the reference ``qg`` [m]. Default :func:`emps`.

    Returns
    -------
    FeedbackLoop
        For ``method="idim-iv"`` of :func:`hpdob.identify` and :func:`simulate_loop`.

    Raises
    ------
    ParameterTypeError, ParameterValueError
        If ``log`` is not a :class:`Log` or has no reference.

    References
    ----------
    The EMPS description (see :func:`emps`), eqs. 6-7 and sections 2.2, 3.5.

    Examples
    --------
    >>> from hpdob.identification import emps_loop
    >>> loop = emps_loop()
    >>> round(loop.kd, 1), loop.velocity_filter  # gtau * kv [N s/m]
    (8557.4, (0.5, 0.0, -0.5))
    """
    import scipy.io

    if log is None:
        log = emps()
    log = require_instance(log, Log, "log")
    if log.reference is None:
        raise ParameterValueError("log must have a reference (the EMPS qg), as emps() returns")
    gains = scipy.io.loadmat(EMPS_FILE, variable_names=("gtau", "kp", "kv"))
    gtau, kp, kv = (float(gains[name].item()) for name in ("gtau", "kp", "kv"))
    return FeedbackLoop(
        log.reference,
        kp=gtau * kv * kp,
        kd=gtau * kv,
        velocity_filter=(0.5, 0.0, -0.5),
        limit=_VOLTAGE_LIMIT * gtau,
    )
