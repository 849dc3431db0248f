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

import math
import warnings

import numpy as np

from .._validation import (
    ParameterValueError,
    as_int,
    check_choice,
    positive,
    require_instance,
)
from ._checks import DEFAULT_TIME_TOLERANCE, check_axis, check_lengths, check_time, sample_vector
from ._loop import FeedbackLoop, simulate_loop
from ._regression import (
    MIN_ROWS,
    PARAMETERS,
    adaptive_bandwidth,
    build_regression,
    instrument_rows,
    minimum_samples,
    resolve_settings,
)
from ._result import Identification

__all__ = ["METHODS", "IdentificationWarning", "identify"]

#: The identification methods.
METHODS = ("auto", "idim-ls", "idim-iv", "idim-iv-input")
#: The correction that keeps the input-driven simulation of ``"idim-iv-input"`` from drifting
#: has this bandwidth, as a fraction of the decimation filter's cut-off: its noise enters the
#: instruments' acceleration (1/20)^2 as strongly as the measured position's at the band edge.
INPUT_LOOP_FRACTION = 0.05
#: Largest condition number (columns scaled to unit norm) of an identifiable regression.
MAX_CONDITION = 1e6
#: Largest variance inflation factor 1/(1 - R^2) of J, b or coulomb: above it the column is
#: all but a combination of the others (R^2 > 0.999) and its estimate is meaningless. Measured:
#: 5.2 for b and coulomb on EMPS, 3.1 on two superposed sines, 3.8e4 at one constant speed.
MAX_VARIANCE_INFLATION = 1e3
#: A loop simulation whose position differs from the log by more than this [%] makes poor
#: instruments (the loop model is probably wrong); IDIM-IV then warns.
MAX_LOOP_POSITION_ERROR = 10.0
#: ... and by more than this [%] with the IDIM-LS estimate, the loop cannot be the one that
#: produced the log (EMPS: 0.001 %; the synthetic PD logs of the tests: 0.1-4 %).
MAX_LOOP_MISMATCH = 50.0


class IdentificationWarning(RuntimeWarning):
    """IDIM-IV did not converge, or its loop simulation does not follow the log."""


def _relative_error(measured: np.ndarray, simulated: np.ndarray) -> float:
    scale = float(np.linalg.norm(measured))
    error = float(np.linalg.norm(measured - simulated))
    return 100.0 * error / scale if scale > 0 else (0.0 if error == 0 else math.inf)


def _variance_inflation(columns: np.ndarray) -> np.ndarray:
    """Variance inflation factor of each column given the others and a constant.

    ``1 / (1 - R^2)`` of the column's regression on the other columns and a constant: the
    diagonal of the inverse correlation matrix (inf for a constant or collinear column).
    """
    centred = columns - columns.mean(axis=0)
    scale = np.linalg.norm(centred, axis=0)
    if np.any(scale == 0.0):
        return np.where(scale == 0.0, math.inf, 1.0)
    correlation = (centred / scale).T @ (centred / scale)
    try:
        return np.diag(np.linalg.inv(correlation))
    except np.linalg.LinAlgError:
        return np.full(columns.shape[1], math.inf)


def _scaled_condition(X: np.ndarray) -> float:
    """Condition number of ``X`` with its columns scaled to unit norm (inf if singular)."""
    norms = np.linalg.norm(X, axis=0)
    if np.any(norms == 0.0):
        return math.inf
    singular = np.linalg.svd(X / norms, compute_uv=False)
    return singular[0] / singular[-1] if singular[-1] > 0 else math.inf


def _check_excitation(theta: np.ndarray, u: np.ndarray, regression, settings) -> None:
    """Refuse logs that cannot identify the four parameters, saying why."""
    if np.ptp(theta) == 0.0:
        raise ParameterValueError(
            f"theta does not move (every sample is {float(theta[0])!r}): a log at rest cannot "
            "identify J, b, coulomb and offset; log a run that moves both ways"
        )
    if np.ptp(u) == 0.0:
        raise ParameterValueError(
            f"u is constant (every sample is {float(u[0])!r}): the input must vary to identify "
            "J, b, coulomb and offset"
        )
    rows = regression.X.shape[0]
    if rows < MIN_ROWS:
        raise ParameterValueError(
            f"min_speed = {settings.min_speed:g} leaves {rows} regression rows, fewer than "
            f"{MIN_ROWS}: theta is slower than min_speed almost everywhere; lower min_speed"
        )
    direction = np.sign(regression.velocity[regression.index])
    for sign, word in ((1.0, "positive"), (-1.0, "negative")):
        if np.all(direction == sign):
            raise ParameterValueError(
                f"theta moves in one direction only (the velocity is {word} in every "
                "regression row): coulomb and offset cannot be told apart; log a run that "
                "moves both ways"
            )
    X = regression.X
    inflation = _variance_inflation(X[:, :3])
    collinear = [PARAMETERS[j] for j in np.flatnonzero(inflation > MAX_VARIANCE_INFLATION)]
    if collinear:
        hint = (
            "the speed is nearly the same in every row: log motion at several speeds"
            if {"b", "coulomb"} <= set(collinear)
            else "log a run with more varied motion"
        )
        raise ParameterValueError(
            f"{' and '.join(collinear)} cannot be told apart in this log (variance inflation "
            f"{', '.join(f'{v:.3g}' for v in inflation[inflation > MAX_VARIANCE_INFLATION])}, "
            f"limit {MAX_VARIANCE_INFLATION:g}): {hint}"
        )
    norms = np.linalg.norm(X, axis=0)
    _, singular, vt = np.linalg.svd(X / np.where(norms > 0, norms, 1.0), full_matrices=False)
    condition = singular[0] / singular[-1] if singular[-1] > 0 else math.inf
    if condition > MAX_CONDITION:
        weakest = PARAMETERS[int(np.argmax(np.abs(vt[-1])))]
        raise ParameterValueError(
            f"the log does not excite the model: the observation matrix has condition number "
            f"{condition:.3g} (limit {MAX_CONDITION:g}); {weakest} is the least identifiable "
            "parameter. Log a run with more varied motion (accelerations and constant speeds "
            "in both directions)"
        )


def _simulable(estimate: np.ndarray, iteration: int) -> np.ndarray:
    """``estimate`` with negative friction set to 0, so that the loop can be simulated.

    ``iteration`` (1 for the IDIM-LS estimate) names the estimate in the error for ``J <= 0``.
    """
    if estimate[0] <= 0.0:
        source = "the IDIM-LS estimate" if iteration == 1 else f"IV iteration {iteration - 1}"
        raise ParameterValueError(
            f"IDIM-IV cannot simulate the loop: {source} has J = {estimate[0]:.6g} <= 0; the "
            "regression is dominated by noise: lower cutoff or raise decimation"
        )
    return np.array([estimate[0], max(estimate[1], 0.0), max(estimate[2], 0.0), estimate[3]])


def _estimate(X: np.ndarray, y: np.ndarray, Z: np.ndarray):
    """IV estimate ``(Z^T X)^-1 Z^T y`` (least squares for ``Z = X``) and its covariance."""
    theta = np.linalg.lstsq(X, y, rcond=None)[0] if Z is X else np.linalg.solve(Z.T @ X, Z.T @ y)
    error = y - X @ theta
    sigma2 = float(error @ error) / (y.size - X.shape[1])
    A = np.linalg.inv(Z.T @ X)
    covariance = sigma2 * A @ (Z.T @ Z) @ A.T
    return theta, covariance


def _input_loop(theta: np.ndarray, u: np.ndarray, J: float, settings) -> FeedbackLoop:
    """The loop of ``"idim-iv-input"``: the logged input drives the model, and a slow PD
    (bandwidth :data:`INPUT_LOOP_FRACTION` x the decimation cut-off, gains from ``J``) pulls it
    towards the low-passed measured position so that it cannot drift away (an open-loop
    simulation integrates every error of the offset and friction)."""
    from scipy import signal

    omega = 2.0 * math.pi * INPUT_LOOP_FRACTION * settings.decimation_cutoff
    sos = signal.butter(2, omega / (2 * math.pi), fs=1.0 / settings.Ts, output="sos")
    slow = signal.sosfiltfilt(sos, theta)
    return FeedbackLoop(
        slow,
        kp=J * omega**2,
        kd=2.0 * J * omega,
        reference_velocity=np.gradient(slow, settings.Ts),
        feedforward=u,
        velocity_filter=None,
    )


def identify(
    t,
    theta,
    u,
    *,
    method: str = "auto",
    loop: FeedbackLoop | None = None,
    bandwidth: float | None = None,
    cutoff: float | None = None,
    order: int = 4,
    decimation: int | None = None,
    border: int | None = None,
    min_speed: float = 0.0,
    zoh: bool | None = None,
    axis: str | None = None,
    max_iterations: int = 20,
    tolerance: float = 0.01,
    time_tolerance: float = DEFAULT_TIME_TOLERANCE,
) -> Identification:
    r"""Identify inertia, viscous and Coulomb friction and offset of an axis from a logged run.

    Fits :math:`u = J\ddot\theta + b\dot\theta + c\,\mathrm{sign}(\dot\theta) + \mathrm{offset}`
    (EMPS description, eq. 1) to the log. A linear axis (m, N, kg) obeys the same equations
    as a rotary one (rad, N m, kg m^2): ``axis`` only sets the units of reports.

    Parameters
    ----------
    t : array_like
        Sampling instants [s], strictly increasing and uniform.
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
    loop : FeedbackLoop, optional
        The controller and reference that produced the log. Required by ``"idim-iv"``;
        with ``"idim-ls"`` it is only simulated once to report how well the identified
        model reproduces the run (``simulation``).
    bandwidth : float, optional
        Bandwidth [Hz] of the motion to keep: it sets ``cutoff = 5 bandwidth`` and
        ``decimation = round(0.2 fs / bandwidth)`` (the EMPS benchmark's rules, with its
        closed-loop bandwidth). Default with ``"auto"``: half the log's signal bandwidth
        (Notes); with the other methods ``fs/50`` (20 Hz at 1 kHz, the EMPS settings:
        cutoff 100 Hz, decimation 10).
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
        where ``sign`` does not describe friction). Default 0: keep all, as the benchmark.
    zoh : bool, optional
        Align the input with the second difference of the position, ``(u_(k-1) + u_k)/2``:
        exact for an input held over each sample (the ZOH of :math:`1/s^2` is
        :math:`T_s^2 (z + 1) / (2 (z - 1)^2)`). Default True with ``"auto"``, False (the
        benchmark's script) otherwise.
    axis : {"rotary", "linear"} or None, optional
        Units of the report; None states none ("N m or N").
    max_iterations : int, optional
        Most IDIM-IV iterations (20).
    tolerance : float, optional
        IDIM-IV stops when no parameter changes by more than ``tolerance`` times its
        standard deviation (0.01). Iterations simulate the loop with negative friction
        estimates set to 0.
    time_tolerance : float, optional
        Relative tolerance of the uniform-sampling check (1e-3).

    Returns
    -------
    Identification

    Raises
    ------
    ParameterValueError
        If the log cannot identify the model: signals of different lengths, a non-finite
        sample, time not increasing or not uniform, too few samples for the filters, no
        motion, constant input, motion in one direction only, an ill-conditioned regression;
        or if a setting is out of range, or ``loop`` does not match the log (length, or a
        simulation with the IDIM-LS estimate more than 50 % off the logged position).
    ParameterTypeError
        For arguments of the wrong type.

    Warns
    -----
    IdentificationWarning
        If IDIM-IV does not converge in ``max_iterations`` or its loop simulation differs
        from the logged position by more than 10 %.

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
    simulated one jumps with every stick event).

    References
    ----------
    A. Janot, M. Gautier, M. Brunot, "Data set and reference models of EMPS", Workshop on
    Nonlinear System Identification Benchmarks, 2019 (eqs. 1, 2, 9, 10, 11; section 3).
    A. Janot, P.-O. Vandanjon, M. Gautier, "A generic instrumental variable approach for
    industrial robot identification", IEEE Trans. Control Systems Technology 22(1), 2014.

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
    idim-iv-input: M = 94.5 kg, Fv = 208 N s/m, Fc = 20.0 N
    """
    method = check_choice(method, "method", METHODS)
    adaptive = method == "auto"
    if adaptive:
        method = "idim-iv" if loop is not None else "idim-iv-input"
    axis = check_axis(axis)
    t = sample_vector(t, "t", "times [s]")
    theta = sample_vector(theta, "theta", "positions [rad or m]")
    u = sample_vector(u, "u", "torques or forces [N m or N]")
    n = check_lengths({"t": t, "theta": theta, "u": u})
    Ts = check_time(t, "t", time_tolerance)
    loop = require_instance(loop, FeedbackLoop, "loop", optional=True)
    if method == "idim-iv" and loop is None:
        raise ParameterValueError(
            "method='idim-iv' needs loop=FeedbackLoop(...): the controller and reference that "
            "produced the log, to simulate the instruments (see FeedbackLoop)"
        )
    if loop is not None and len(loop) != n:
        raise ParameterValueError(
            f"loop must have one reference sample per logged sample: the log has {n}, "
            f"loop.reference has {len(loop)}"
        )
    max_iterations = as_int(max_iterations, "max_iterations", "a positive integer", minimum=1)
    tolerance = positive(tolerance, "tolerance", "a positive relative tolerance")
    if adaptive and bandwidth is None and cutoff is None and decimation is None:
        bandwidth = adaptive_bandwidth(theta, Ts)
    settings = resolve_settings(
        Ts, bandwidth=bandwidth, cutoff=cutoff, order=order, decimation=decimation,
        border=border, min_speed=min_speed, zoh=adaptive if zoh is None else zoh,
    )  # fmt: skip
    needed = minimum_samples(settings)
    if n < needed:
        raise ParameterValueError(
            f"the log is too short to identify: {n} samples, but decimation = "
            f"{settings.decimation} and border = {settings.border} need at least {needed} "
            f"for {MIN_ROWS} regression rows"
        )
    regression = build_regression(theta, u, settings)
    _check_excitation(theta, u, regression, settings)
    X, y = regression.X, regression.y
    estimate, covariance = _estimate(X, y, X)
    iterations, converged = 0, True
    velocity0 = float(regression.velocity[0])
    if method in ("idim-iv", "idim-iv-input"):
        converged = False
        for iterations in range(1, max_iterations + 1):
            parameters = _simulable(estimate, iterations)
            simulated, _ = simulate_loop(
                loop if method == "idim-iv" else _input_loop(theta, u, parameters[0], settings),
                parameters, Ts=Ts, theta0=theta[0], velocity0=velocity0,
            )  # fmt: skip
            mismatch = _relative_error(theta, simulated)
            if method == "idim-iv" and iterations == 1 and mismatch > MAX_LOOP_MISMATCH:
                raise ParameterValueError(
                    "loop does not describe the controller that produced the log: simulated "
                    f"with the IDIM-LS estimate it differs from the logged position by "
                    f"{mismatch:.3g} % (eq. 11; limit {MAX_LOOP_MISMATCH:g} %); check its "
                    "reference, gains, velocity filter and units"
                )
            Z = instrument_rows(simulated, regression, settings)
            # sign(velocity) is its own instrument: noise changes it only near rest, and the
            # simulated one jumps with every stick event (IDIM-IV then does not converge)
            if adaptive or method == "idim-iv-input":
                Z[:, 2] = X[:, 2]
            try:
                if _scaled_condition(Z) > MAX_CONDITION:
                    raise np.linalg.LinAlgError
                new, covariance = _estimate(X, y, Z)
            except np.linalg.LinAlgError:
                raise ParameterValueError(
                    "IDIM-IV: the instruments from the simulated loop are singular (the loop "
                    f"simulated with J = {estimate[0]:.6g}, b = {estimate[1]:.6g}, coulomb = "
                    f"{estimate[2]:.6g} barely moves or never reverses); check the loop's "
                    "reference, gains and units"
                ) from None
            change = np.abs(new - estimate)
            estimate = new
            if np.all(change <= tolerance * np.sqrt(np.diag(covariance))):
                converged = True
                break
        if not converged:
            warnings.warn(
                f"IDIM-IV did not converge in {max_iterations} iterations (tolerance "
                f"{tolerance:g} standard deviations); the last estimate is returned. Stick "
                "phases make the simulated loop jump between iterations: if the log rests "
                "at times, drop them with min_speed",
                IdentificationWarning,
                stacklevel=2,
            )
    simulation = theta_simulated = None
    if loop is not None and estimate[0] > 0.0:
        theta_simulated, u_simulated = simulate_loop(
            loop, _simulable(estimate, 0), Ts=Ts, theta0=theta[0], velocity0=velocity0
        )
        simulation = {
            "position_error_percent": _relative_error(theta, theta_simulated),
            "input_error_percent": _relative_error(u, u_simulated),
        }
        if method == "idim-iv" and simulation["position_error_percent"] > MAX_LOOP_POSITION_ERROR:
            warnings.warn(
                "the loop simulated with the IDIM-IV estimate differs from the logged position "
                f"by {simulation['position_error_percent']:.3g} % (eq. 11): the instruments are "
                "poor; check the loop's gains, velocity filter and reference",
                IdentificationWarning,
                stacklevel=2,
            )
    singular = np.linalg.svd(X, compute_uv=False)
    record = settings.to_dict()
    record.update(
        method=method, adaptive=adaptive, n_rows=int(y.size), time_tolerance=float(time_tolerance)
    )
    if method != "idim-ls":
        record.update(max_iterations=max_iterations, tolerance=tolerance)
    return Identification(
        method=method,
        J=float(estimate[0]),
        b=float(estimate[1]),
        coulomb=float(estimate[2]),
        offset=float(estimate[3]),
        covariance=covariance,
        t=t[regression.index],
        u=y,
        u_model=X @ estimate,
        axis=axis,
        settings=record,
        n_samples=n,
        condition_number=float(singular[0] / singular[-1]),
        max_speed=float(np.max(np.abs(regression.velocity))),
        iterations=iterations,
        converged=converged,
        simulation=simulation,
        t_log=None if loop is None else t,
        theta_log=None if loop is None else theta,
        theta_simulated=theta_simulated,
    )
