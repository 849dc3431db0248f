r"""Identification of a rigid axis from a logged run: IDIM-LS and IDIM-IV.

The default (``method="auto"``) reads its filter settings from the log and estimates by
instrumental variables (see :func:`identify`, Notes, and docs/real-data.md).

IDIM-LS (inverse dynamic identification model, least squares) is the EMPS benchmark's
reference method: the regression of :mod:`hpdob.identification._regression` solved by least
squares, :math:`\hat\theta = (X^T X)^{-1} X^T y` (EMPS description, eq. 10).

IDIM-IV replaces the regressors by instruments :math:`Z` built the same way from the
position of the closed loop *simulated* with the previous estimate, and iterates
:math:`\hat\theta_{i+1} = (Z_i^T X)^{-1} Z_i^T y` from the IDIM-LS estimate until no
parameter changes by more than ``tolerance`` (1 %) of its standard deviation (Janot,
Vandanjon and Gautier 2014). Stick-slip makes the simulated loop depend discontinuously on the
parameters, so the iteration settles to a small fraction of a standard deviation rather than
to machine precision. The simulated position carries no measurement noise and is not
fed back through the real controller, so :math:`Z` is uncorrelated with the error of the
regression, which is what least squares lacks in closed loop: there the noise of the
measured position enters both the regressors (through the differentiated position) and the
input (through the controller), and IDIM-LS is biased, most visibly towards a smaller
inertia as the filters let more noise through.
"""

from __future__ import annotations

import functools
import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np

from .._validation import (
    ParameterTypeError,
    ParameterValueError,
    as_int,
    check_choice,
    positive,
    readonly,
)
from ._checks import DEFAULT_TIME_TOLERANCE, check_axis
from ._design import FRICTION_MODELS, OFFSETS, directions, make_layout
from ._log import Log, register_identify
from ._regression import (
    PARAMETERS,
)
from ._result import Identification
from ._runs import as_runs, prepare, resolve
from ._sensitivity import (
    ADAPTIVE_FACTORS,
    SENSITIVITY_FACTOR,
    allowances,
    sensitivity,
    sensitivity_warnings,
)
from ._simfit import MIN_FIT, simulate_fit
from ._solve import percent, relative_error, solve

__all__ = ["FRICTION_MODELS", "METHODS", "OFFSETS", "IdentificationWarning", "identify"]

#: The identification methods.
METHODS = ("auto", "idim-ls", "idim-iv", "idim-iv-input")

#: A loop simulation whose position differs from the log by more than this [%] makes poor
#: instruments (the loop model is probably wrong); IDIM-IV then warns.
MAX_LOOP_POSITION_ERROR = 10.0


class IdentificationWarning(RuntimeWarning):
    """The identification is doubtful: IDIM-IV did not converge, its loop simulation does not
    follow the log, the identified model does not reproduce the log, or the parameters
    depend on the filter settings. The message says what to try."""


def _silent(stage: str, done: int, total: int) -> None:
    """The default ``progress`` of :func:`identify`: nothing."""


def in_band(signals, settings) -> list:
    """``signals`` low-passed to the band the regression uses: a Butterworth filter (order of
    ``settings``) at the decimation filter's cut-off, forward and backward."""
    from scipy import signal

    sos = signal.butter(settings.order, settings.decimation_cutoff, fs=1.0 / settings.Ts,
                        output="sos")  # fmt: skip
    return [signal.sosfiltfilt(sos, x) for x in signals]


def _band_filter(settings):
    """:func:`in_band`'s filter, in second-order sections."""
    from scipy import signal

    return signal.butter(settings.order, settings.decimation_cutoff, fs=1.0 / settings.Ts,
                         output="sos")  # fmt: skip


def band_scale(u: np.ndarray, settings) -> float:
    """``||in_band(u)||``, the scale of :func:`band_error` (computed before the simulation
    that needs it: the filtered input then never lies beside its traces)."""
    from ._lean import filtfilt

    return float(np.linalg.norm(filtfilt(_band_filter(settings), u)))


def band_error(u: np.ndarray, u_simulated: np.ndarray, settings, *, overwrite=False,
               scale: float | None = None) -> float:  # fmt: skip
    """``relative_error(*in_band((u, u_simulated), settings))`` bit for bit, holding two
    filtered arrays instead of four (the filters in blocks, the difference in place), or one
    with ``overwrite`` (the filtered ``u_simulated`` and the difference written over it).
    Given ``scale`` (:func:`band_scale` of ``u``), the filtered ``u`` is taken block by block
    (the same subtraction sample by sample), never whole."""
    from ._lean import filtfilt, filtfilt_blocks

    sos = _band_filter(settings)
    simulated = filtfilt(sos, u_simulated, out=u_simulated if overwrite else None)
    if scale is None:
        measured = filtfilt(sos, u)
        scale = float(np.linalg.norm(measured))
        error = float(np.linalg.norm(np.subtract(measured, simulated, out=simulated)))
    else:
        for lo, hi, measured in filtfilt_blocks(sos, u.size, lambda a, b: u[a:b]):
            np.subtract(measured, simulated[lo:hi], out=simulated[lo:hi])
            del measured  # not beside the next block
        error = float(np.linalg.norm(simulated))
    return percent(error, scale)


def simulated_parameters(parameters: np.ndarray, run, layout) -> np.ndarray:
    """The parameters to simulate ``run`` with: as identified, but on a log that moves one way
    with the Coulomb friction lumped into the offset (``friction="viscous"``), the lumped term
    as Coulomb friction. Both read the same while the axis moves; at its rests the log stays
    put, which a constant offset would not let it do."""
    if "coulomb" not in layout.fixed or layout.fixed["coulomb"] != 0.0 or 2 in layout.free:
        return parameters
    way, _ = directions(run)
    J, b, _, offset = parameters
    if way == 0.0 or way * offset <= 0.0:
        return parameters
    return np.array([J, b, way * offset, 0.0])


def systematic(moves, solution, layout, names) -> dict:
    """The spread of each parameter over the three filter settings (as identified, bandwidth
    x2 and /2), in its units: the systematic uncertainty beside the statistical one (0 where
    fixed or not checked)."""
    std = np.sqrt(np.diag(solution.covariance))
    shifts = np.array([np.zeros_like(std)] + [m * std for m in moves.values()])
    spread = shifts.max(axis=0) - shifts.min(axis=0)
    out = dict.fromkeys(PARAMETERS, 0.0)
    for k, name in enumerate(names):
        key = "offset" if name.startswith("offset") else name
        out[key] = max(out[key], float(spread[k]))
    return out


def renamed_keywords(**renamed):
    """Refuse the keywords of ``renamed`` (old name -> new name and unit) with a
    :class:`ParameterTypeError` that names the new keyword, instead of Python's bare
    "unexpected keyword argument" (docs/changelog.md)."""

    def wrap(function):
        @functools.wraps(function)
        def call(*args, **kwargs):
            for old, new in renamed.items():
                if old in kwargs:
                    raise ParameterTypeError(
                        f"{old} was renamed: give {new.split()[0]}={kwargs[old]!r} "
                        f"(the filters' bandwidth {' '.join(new.split()[1:])}; "
                        f"{function.__name__}() takes no {old}=)"
                    )
            return function(*args, **kwargs)

        return call

    return wrap


@renamed_keywords(bandwidth="filter_bandwidth [Hz]")
def identify(
    t,
    theta=None,
    u=None,
    *,
    method: str = "auto",
    loop=None,
    filter_bandwidth: float | None = None,
    cutoff: float | None = None,
    order: int = 4,
    decimation: int | None = None,
    border: int | None = None,
    min_speed: float | None = None,
    zoh: bool | None = None,
    friction: str = "viscous+coulomb",
    fixed: Mapping | None = None,
    offsets: str = "per-log",
    diagnostics: bool = True,
    axis: str | None = None,
    max_iterations: int = 20,
    tolerance: float = 0.01,
    time_tolerance: float = DEFAULT_TIME_TOLERANCE,
    progress=None,
) -> Identification:
    r"""Identify inertia, viscous and Coulomb friction and offset of an axis from a logged run.

    Fits :math:`u = J\ddot\theta + b\dot\theta + c\,\mathrm{sign}(\dot\theta) + \mathrm{offset}`
    (EMPS description, eq. 1) to the log. A linear axis (m, N, kg) obeys the same equations
    as a rotary one (rad, N m, kg m^2): ``axis`` only sets the units of reports.

    Several logs of one axis (a list of :class:`Log`) are fitted together: shared ``J``,
    ``b`` and ``coulomb``, one offset per log or a shared one (``offsets``).

    Parameters
    ----------
    t : array_like, Log or sequence of Log
        Sampling instants [s], strictly increasing and uniform; or a :class:`Log`, or a list
        of them (then without ``theta`` and ``u``).
    theta : array_like
        Measured position [rad or m].
    u : array_like
        Applied torque or force [N m or N].
    method : {"auto", "idim-ls", "idim-iv", "idim-iv-input"}, optional
        ``"auto"`` (default): instrumental variables with settings read from the log
        (see Notes): ``"idim-iv"`` if ``loop`` is given, else ``"idim-iv-input"``.
        ``"idim-ls"``: the benchmark's inverse-model least squares, with its rules.
        ``"idim-iv"``: instrumental variables from the closed loop simulated with the
        current estimate, iterated from the IDIM-LS estimate; needs ``loop``. It removes
        the bias IDIM-LS suffers from measurement noise and depends much less on the filter
        settings (see docs/real-data.md).
        ``"idim-iv-input"``: the same with instruments from the model driven by the logged
        input (held by a slow PD near the low-passed measured position, so that it cannot
        drift); needs no loop, in open or closed loop.
    loop : FeedbackLoop or sequence of (FeedbackLoop or None), optional
        The controller and reference that produced the log (with several logs, one per log,
        None for an open-loop one). Required by ``"idim-iv"``; otherwise it is only
        simulated to report how well the identified model reproduces the run
        (``simulation``, ``fits``).
    filter_bandwidth : float, optional
        Bandwidth [Hz] of the motion the filters keep (not an observer's bandwidth in rad/s;
        ``bandwidth=`` before 0.2, now refused with a pointer here): it sets ``cutoff =
        5 filter_bandwidth`` and ``decimation = round(0.2 fs / filter_bandwidth)`` (the EMPS
        benchmark's rules, with its closed-loop bandwidth). Default with ``"auto"``: half the
        log's signal bandwidth (Notes); with the other methods ``fs/50`` (20 Hz at 1 kHz, the
        EMPS settings: cutoff 100 Hz, decimation 10).
    cutoff : float, optional
        Cut-off [Hz] of the Butterworth low-pass filter on the position (forward-backward).
    order : int, optional
        Order of that filter (4).
    decimation : int, optional
        Decimation factor of the parallel filtering of every regression column and the input.
    border : int, optional
        Samples dropped at each end (filter transients). Default ``max(50, 5 decimation)``.
    min_speed : float, optional
        Drop rows where the filtered speed falls below this [rad/s or m/s] (stick phases,
        where ``sign`` does not describe friction); 0 keeps every row. Default with
        ``"auto"``: drop the log's *rests*, stretches where the filtered speed stays below
        2 % of its largest value for longer than the decimation filter's main lobe (holds
        between step responses or moves; brief reversals are kept; see Notes); with the
        other methods 0, as the benchmark.
    zoh : bool, optional
        Align the input with the second difference of the position, ``(u_(k-1) + u_k)/2``:
        exact for an input held over each sample (the ZOH of :math:`1/s^2` is
        :math:`T_s^2 (z + 1) / (2 (z - 1)^2)`). Default True with ``"auto"``, False (the
        benchmark's script) otherwise.
    friction : {"viscous+coulomb", "viscous"}, optional
        The friction model: viscous and Coulomb friction (default), or viscous only
        (``coulomb`` = 0; on a log that moves one way the Coulomb friction is then lumped into
        the offset: ``offset + coulomb`` for positive motion, ``offset - coulomb`` negative).
    fixed : mapping, optional
        Parameters held at given values instead of estimated, e.g. ``{"b": 2e-3}`` or
        ``{"coulomb": 0.03}`` (keys ``J``, ``b``, ``coulomb``, ``offset``).
    offsets : {"per-log", "shared"}, optional
        With several logs: one offset per log (default; ``offsets`` of the result) or one for
        all (then logs that move one way each, in opposite directions, identify the Coulomb
        friction).
    diagnostics : bool, optional
        Simulate the identified model on the log and repeat the estimate with the filters'
        bandwidth doubled and halved, and warn if either looks wrong (default True).
    axis : {"rotary", "linear"} or None, optional
        Units of the report; None states none ("N m or N"); a Log's by default.
    max_iterations : int, optional
        Most IDIM-IV iterations (20).
    tolerance : float, optional
        IDIM-IV stops when no parameter changes by more than ``tolerance`` times its
        standard deviation (0.01). Iterations simulate the loop with negative friction
        estimates set to 0.
    time_tolerance : float, optional
        Relative tolerance of the uniform-sampling check (1e-3).
    progress : callable, optional
        Called as ``progress(stage, done, total)`` as the identification works, counts only
        (the caller may time them): ``"filtering"`` (logs filtered and regressed, of
        ``total``), ``"iterating"`` (IDIM-IV iterations done, of at most ``max_iterations``;
        when it converges sooner a last call has ``done == total`` = the iterations used),
        with ``diagnostics`` ``"sensitivity"`` (the two re-estimates with the filters'
        bandwidth doubled and halved), and ``"simulating"`` (the simulation fits, one per
        log). Each stage starts with ``done = 0`` and ends with ``done == total``. Its
        return value is ignored. Default: silent.

    Returns
    -------
    Identification

    Raises
    ------
    ParameterValueError
        If the log cannot identify the model: signals of different lengths, a non-finite
        sample, time not increasing or not uniform, too few samples for the filters, no
        motion, constant input, motion in one direction only (the message names the calls
        that identify that log: ``friction="viscous"``, ``fixed={"coulomb": ...}``, or a log
        that moves the other way with ``offsets="shared"``), a log that rests most of the
        time (the message counts the rest rows and names the ``filter_bandwidth`` that works), an
        ill-conditioned regression;
        or if a setting is out of range, or ``loop`` does not match the log (length, or a
        simulation with the IDIM-LS estimate more than 50 % off the logged position).
    ParameterTypeError
        For arguments of the wrong type.

    Warns
    -----
    IdentificationWarning
        If IDIM-IV does not converge in ``max_iterations`` or its loop simulation differs
        from the logged position by more than 10 %; with ``diagnostics``, if the identified
        model simulated on the log (through its loop, or open loop from its input) fits its
        velocity, or through a loop its position, by less than 90 % (MATLAB ``compare``), or
        if a parameter moves by more than its standard deviation when the filters' bandwidth
        is doubled or halved. The message says what to try; the result keeps them
        (``warnings``).

    Notes
    -----
    The defaults of ``"auto"`` follow the log. The position's noise floor is the larger of
    the quantisation noise :math:`q^2 T_s / 6` (``q`` the smallest step between samples) and
    the median PSD of the top quarter of the band; the signal bandwidth is the highest
    frequency where the position's PSD (Welch, from its second difference) stands 20 dB above
    that floor. The decimation filter's cut-off ``2 bandwidth`` is put there, clipped to
    ``[fs/250, fs/6]``: faster motion drowns in the differentiated noise, and a wider band
    only adds noise. Instrumental variables then remove what bias the noise still causes,
    and ``sign(velocity)`` is its own instrument (noise changes it only near rest, and a
    simulated one jumps with every stick event). The rows of the log's rests (holds between
    steps or moves, stick events: the speed below 2 % of its largest for more than one
    decimated row) are dropped, with half the decimation filter's main lobe around them: at
    rest the friction is static, which ``c sign(velocity)`` does not describe.

    The standard deviations allow for the residual's correlation over neighbouring rows
    (batch means over 20 contiguous batches per log; ``std_iid`` of the result are the
    textbook ones); a Monte Carlo over seeds matches them to the estimates' spread within a
    factor 1.4 (docs/real-data.md).

    References
    ----------
    A. Janot, M. Gautier, M. Brunot, "Data set and reference models of EMPS", Workshop on
    Nonlinear System Identification Benchmarks, 2019 (eqs. 1, 2, 9, 10, 11; section 3).
    A. Janot, P.-O. Vandanjon, M. Gautier, "A generic instrumental variable approach for
    industrial robot identification", IEEE Trans. Control Systems Technology 22(1), 2014.
    M. S. Bester, T. G. Conley, C. B. Hansen, "Inference with dependent data using cluster
    covariance estimators", Journal of Econometrics 165(2), 2011.

    Examples
    --------
    >>> import hpdob
    >>> from hpdob.identification import emps
    >>> log = emps()
    >>> fit = hpdob.identify(log.t, log.theta, log.u, method="idim-ls", axis="linear")
    >>> print(f"M = {fit.J:.1f} kg, Fv = {fit.b:.0f} N s/m, Fc = {fit.coulomb:.1f} N")
    M = 95.1 kg, Fv = 203 N s/m, Fc = 20.4 N
    >>> fit = hpdob.identify(log.t, log.theta, log.u, axis="linear")   # the defaults
    >>> print(f"{fit.method}: M = {fit.J:.1f} kg, Fv = {fit.b:.0f} N s/m, Fc = {fit.coulomb:.1f} N")
    idim-iv-input: M = 94.9 kg, Fv = 198 N s/m, Fc = 21.0 N
    """
    method = check_choice(method, "method", METHODS)
    adaptive = method == "auto"
    if axis is None and theta is None and u is None:
        first = t if isinstance(t, Log) else (t[0] if isinstance(t, Sequence) and t else None)
        axis = getattr(first, "axis", None)
    axis = check_axis(axis)
    runs = as_runs(t, theta, u, loop, time_tolerance)
    has_loop = [run.loop is not None for run in runs]
    if method == "idim-iv" and not all(has_loop):
        raise ParameterValueError(
            "method='idim-iv' needs loop=FeedbackLoop(...): the controller and reference that "
            "produced the log, to simulate the instruments (see FeedbackLoop)"
            + ("; with several logs, one per log" if len(runs) > 1 else "")
        )
    if adaptive:
        method = "idim-iv" if any(has_loop) else "idim-iv-input"
    own_sign = adaptive or method == "idim-iv-input"
    max_iterations = as_int(max_iterations, "max_iterations", "a positive integer", minimum=1)
    tolerance = positive(tolerance, "tolerance", "a positive relative tolerance")
    if not isinstance(diagnostics, bool):
        raise ParameterTypeError(f"diagnostics must be True or False, got {diagnostics!r}")
    if progress is None:
        progress = _silent
    elif not callable(progress):
        raise ParameterTypeError(
            f"progress must be a callable progress(stage, done, total) or None, got "
            f"{progress!r} of type {type(progress).__name__}"
        )
    layout = make_layout(friction, fixed, offsets, len(runs))
    for k, run in enumerate(runs):
        progress("filtering", k, len(runs))
        where = f" ({run.name})" if len(runs) > 1 else ""
        settings = resolve(
            run, adaptive, filter_bandwidth, cutoff, order, decimation, border, min_speed, zoh
        )
        prepare(run, settings, where)
    progress("filtering", len(runs), len(runs))
    iterating = None
    if method != "idim-ls":
        progress("iterating", 0, max_iterations)

        def iterating(k):
            progress("iterating", k, max_iterations)

    solution = solve(runs, layout, method, own_sign, max_iterations, tolerance, iterating)
    if method != "idim-ls" and solution.converged and solution.iterations < max_iterations:
        progress("iterating", solution.iterations, solution.iterations)  # converged: done
    caught = []
    if method != "idim-ls" and not solution.converged:
        caught.append(
            f"IDIM-IV did not converge in {max_iterations} iterations (tolerance "
            f"{tolerance:g} standard deviations); the last estimate is returned. Stick "
            "phases make the simulated loop jump between iterations: if the log rests "
            "at times, drop them with min_speed"
            + (
                "; and check the reference velocity and acceleration the loop used "
                "(FeedbackLoop(reference_velocity=..., feedforward=...); zero for a step "
                "reference)"
                if any(has_loop)
                else ""
            )
        )
    per_run = [layout.parameters(solution.estimate, i) for i in range(len(runs))]
    # what the result needs of the regressions, which then go: not beside the diagnostics'
    u_model = np.concatenate([run.regression.X @ per_run[i] for i, run in enumerate(runs)])
    singular = np.linalg.svd(solution.X, compute_uv=False)
    solution.X = None
    for run in runs:
        run.regression = replace(run.regression, X=None)
    moves = {}
    if diagnostics:  # before the simulations: its regressions not beside the kept traces
        moves = sensitivity(runs, layout, method, own_sign, solution, border is not None,
                            max_iterations, tolerance,
                            lambda k, n: progress("sensitivity", k, n))  # fmt: skip
        # the allowances read the whole input and position: not beside the kept traces either
        allowed = allowances(solution, layout, runs)
    fits, simulation, traces = [], None, None
    simulated = [
        per_run[i][0] > 0.0 and (diagnostics or (i == 0 and run.loop is not None))
        for i, run in enumerate(runs)
    ]
    for i, run in enumerate(runs):
        if not simulated[i]:
            fits.append(None)
            continue
        progress("simulating", sum(simulated[:i]), sum(simulated))
        traced = i == 0 and run.loop is not None
        # the band error's scale now, while no simulated trace is held
        scale = band_scale(run.u, run.settings) if traced else None

        def through_loop(position, command, again, run=run, scale=scale):
            # the loop's errors before the fit's velocities, in two arrays of the log's
            # length: the band error overwrites the command, which then takes the position's
            # difference; simulated again (the same numbers), it gives the input error over
            # itself. The position kept for the result's traces
            nonlocal simulation, traces
            band = band_error(run.u, command, run.settings, overwrite=True, scale=scale)
            position_error = relative_error(run.theta, position, out=command)
            again()
            simulation = {
                "position_error_percent": position_error,
                "input_error_percent": relative_error(run.u, command, out=command),
                "input_error_band_percent": band,
                "band_hz": run.settings.decimation_cutoff,
            }
            traces = (run.t, run.theta, readonly(position))  # the result shares them
            return True

        fit = simulate_fit(
            simulated_parameters(per_run[i], run, layout), run.t, run.theta, run.u, run.loop,
            run.settings, keep=False, simulated=through_loop if traced else None,
        )  # fmt: skip
        fits.append(fit)  # its numbers, not its traces
        if traced and (
            method == "idim-iv" and simulation["position_error_percent"] > MAX_LOOP_POSITION_ERROR
        ):
            caught.append(
                "the loop simulated with the IDIM-IV estimate differs from the logged "
                f"position by {simulation['position_error_percent']:.3g} % (eq. 11): the "
                "instruments are poor; check the loop's gains, velocity filter and "
                "reference, and the reference's velocity and acceleration the loop used "
                "(FeedbackLoop(reference_velocity=..., feedforward=...); zero for a step "
                "reference)"
            )
        del fit  # its simulated command: not beside the next run's simulation
    if any(simulated):
        progress("simulating", sum(simulated), sum(simulated))
    notes = []
    if diagnostics:
        for run, fit in zip(runs, fits, strict=True):
            if fit is None:
                continue
            poor = [(name, value) for name, value in
                    (("velocity", fit.velocity_fit),
                     ("position", fit.position_fit if fit.closed_loop else math.inf))
                    if value < MIN_FIT]  # fmt: skip
            if poor:
                listed = " and ".join(f"{name} fit {value:.3g} %" for name, value in poor)
                mode = "through its loop" if fit.closed_loop else "open loop from its input"
                caught.append(
                    f"the identified model does not reproduce {run.name}: simulated {mode}, "
                    f"its {listed} (MATLAB compare; below {MIN_FIT:g} %). Try min_speed "
                    "(stick phases), friction='viscous' or fixed parameters, loop= for a "
                    "closed-loop log (the controller and reference), and check input_gain "
                    "and the units"
                )
        names = [PARAMETERS[j] for j in layout.free] + (
            ["offset"] if layout.n_offsets == 1 else [f"offset of {r.name}" for r in runs]
        )[: layout.n_offsets]
        caught.extend(sensitivity_warnings(moves, solution, allowed, runs, adaptive, names))
        for factor, which in ((1.0 / SENSITIVITY_FACTOR, "halved"), (SENSITIVITY_FACTOR,
                                                                     "doubled")):  # fmt: skip
            if factor not in moves and (factor in ADAPTIVE_FACTORS or not adaptive):
                notes.append(
                    f"the filters' sensitivity with their bandwidth {which} was not checked: "
                    "the log has too few samples or rows for those filters"
                )
    for message in caught:
        warnings.warn(message, IdentificationWarning, stacklevel=2)
    T = layout.transform()
    covariance = T @ solution.covariance @ T.T
    covariance_iid = T @ solution.covariance_iid @ T.T
    offsets_values = tuple(float(p[3]) for p in per_run)
    offset_std = []
    for i in range(len(runs)):
        column = layout.offset_column(i)
        offset_std.append(
            0.0 if column is None else float(math.sqrt(solution.covariance[column, column]))
        )
    u_rows = np.concatenate([run.regression.y for run in runs])
    t_rows = np.concatenate([run.t[run.regression.index] for run in runs])
    run_rows = np.concatenate([np.full(run.regression.index.size, i) for i, run in enumerate(runs)])
    record = runs[0].settings.to_dict()
    record.update(
        method=method, adaptive=adaptive, n_rows=int(u_rows.size),
        time_tolerance=float(time_tolerance), friction=friction,
        fixed=dict(layout.fixed), offsets=offsets if len(runs) > 1 else "per-log",
        rest_rows=int(sum(run.regression.rest_rows for run in runs)),
        rest_speed=float(max(run.regression.rest_speed for run in runs)),
    )  # fmt: skip
    if len(runs) > 1:
        record["logs"] = [
            dict(run.settings.to_dict(), name=run.name, samples=int(run.theta.size)) for run in runs
        ]
    if method != "idim-ls":
        record.update(max_iterations=max_iterations, tolerance=tolerance)
    estimate4 = T @ solution.estimate + np.array(
        [layout.fixed.get(name, 0.0) for name in PARAMETERS]
    ) * np.array([1.0, 1.0, 1.0, 0.0 if layout.n_offsets else 1.0])
    return Identification(
        method=method,
        J=float(estimate4[0]),
        b=float(estimate4[1]),
        coulomb=float(estimate4[2]),
        offset=float(estimate4[3]),
        covariance=covariance,
        covariance_iid=covariance_iid,
        t=t_rows,
        u=u_rows,
        u_model=u_model,
        axis=axis,
        settings=record,
        n_samples=int(sum(run.theta.size for run in runs)),
        condition_number=float(singular[0] / singular[-1]),
        max_speed=max(run.regression.max_speed for run in runs),
        iterations=solution.iterations,
        converged=solution.converged,
        simulation=simulation,
        t_log=None if traces is None else traces[0],
        theta_log=None if traces is None else traces[1],
        theta_simulated=None if traces is None else traces[2],
        offsets=offsets_values,
        offsets_std=tuple(offset_std),
        sources=tuple(run.name for run in runs),
        run=run_rows,
        fits=tuple(None if f is None else f.to_dict() for f in fits),
        sensitivity={
            ("x2" if factor > 1 else "/2"): dict(zip(names, move.tolist(), strict=True))
            for factor, move in moves.items()
        }
        if diagnostics
        else None,
        warnings=tuple(caught),
        notes=tuple(notes),
        systematic=systematic(moves, solution, layout, names) if diagnostics else None,
    )


register_identify(identify)
