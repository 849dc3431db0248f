"""The estimate of a set of regressions: least squares, then the instrumental-variable
iteration with instruments from the simulated loop or the input-driven model."""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from .._validation import (
    ParameterValueError,
    readonly,
)
from ._design import MAX_CONDITION, Layout, check_design, scaled_condition
from ._lean import filtfilt, gradient_inplace
from ._loop import FeedbackLoop, run_simulation
from ._regression import (
    instrument_rows,
)

__all__ = [
    "COVARIANCE_BATCHES",
    "INPUT_LOOP_FRACTION",
    "MAX_LOOP_MISMATCH",
    "Solution",
    "estimate_iv",
    "input_loop",
    "input_simulation",
    "long_run_covariance",
    "mismatch",
    "percent",
    "relative_error",
    "simulable",
    "solve",
]

#: The correction that keeps the input-driven simulation of ``"idim-iv-input"`` from drifting
#: has this bandwidth, as a fraction of the decimation filter's cut-off: its noise enters the
#: instruments' acceleration (1/20)^2 as strongly as the measured position's at the band edge.
INPUT_LOOP_FRACTION = 0.05

#: ... and by more than this [%] with the IDIM-LS estimate, the loop cannot be the one that
#: produced the log (EMPS: 0.001 %; the synthetic PD logs of the tests: 0.1-4 %).
MAX_LOOP_MISMATCH = 50.0


def relative_error(measured: np.ndarray, simulated: np.ndarray, *, out=None) -> float:
    """``100 ||measured - simulated|| / ||measured||`` [%]; ``out``: an array of their size
    the difference may be written to (the same numbers as numpy's temporary)."""
    scale = float(np.linalg.norm(measured))
    return percent(float(np.linalg.norm(np.subtract(measured, simulated, out=out))), scale)


def percent(error: float, scale: float) -> float:
    """``100 error / scale`` [%]: 0 for no error of nothing, inf for an error of nothing."""
    return 100.0 * error / scale if scale > 0 else (0.0 if error == 0 else math.inf)


#: Samples per block of :func:`mismatch`.
MISMATCH_BLOCK = 4096


def mismatch(measured: np.ndarray, simulated: np.ndarray) -> float:
    """:func:`relative_error` with the difference's squares summed block by block of
    :data:`MISMATCH_BLOCK` samples (to rounding the same number; not a third array of the
    log's length beside the two): the loop's check, whose number only a refusal prints."""
    squares = 0.0
    for lo in range(0, measured.size, MISMATCH_BLOCK):
        difference = measured[lo : lo + MISMATCH_BLOCK] - simulated[lo : lo + MISMATCH_BLOCK]
        squares += float(difference @ difference)
    return percent(math.sqrt(squares), float(np.linalg.norm(measured)))


def simulable(parameters: np.ndarray, iteration: int, name: str = "") -> np.ndarray:
    """``parameters`` with negative friction set to 0, so that the loop can be simulated.

    ``iteration`` (1 for the IDIM-LS estimate) names the estimate in the error for ``J <= 0``.
    """
    if parameters[0] <= 0.0:
        source = "the IDIM-LS estimate" if iteration == 1 else f"IV iteration {iteration - 1}"
        raise ParameterValueError(
            f"IDIM-IV cannot simulate the loop{name}: {source} has J = {parameters[0]:.6g} <= 0; "
            "the regression is dominated by noise: lower cutoff or raise decimation (or leave "
            "the filters to method='auto'); check the loop's reference velocity and "
            "acceleration (FeedbackLoop(reference_velocity=..., feedforward=...); zero for a "
            "step reference)"
        )
    return np.array(
        [parameters[0], max(parameters[1], 0.0), max(parameters[2], 0.0), parameters[3]]
    )


#: The covariance of the estimate splits each log's rows into this many contiguous batches
#: (at most; at least 10 rows each): the batch-means (contiguous-cluster) estimate below.
COVARIANCE_BATCHES = 20


def long_run_covariance(Z: np.ndarray, error: np.ndarray, logs) -> np.ndarray:
    r"""Batch-means estimate of :math:`\operatorname{cov}(\sum_k z_k e_k)`, the covariance of
    the sum of the scores :math:`z_k e_k` (rows of ``Z`` times ``error``), for scores
    correlated over neighbouring rows; the scores are formed batch by batch, never whole.

    Each log's rows (``logs``: their ranges) are split into ``G`` contiguous batches
    (:data:`COVARIANCE_BATCHES`, fewer for short logs); with :math:`s_g` the sum of the scores
    of batch ``g``, :math:`\hat S = \frac{G}{G-1}\sum_g s_g s_g^T` (over every batch of every
    log). A correlation shorter than a batch is counted whole, whatever its sign: the
    Newey-West estimate with a few lags is not, and on the decimated residual, whose
    spectrum rises steeply from zero frequency (differentiated noise), it still
    overestimates the spread of b and Coulomb over seeds by 1.5-1.8 times.
    """
    S = np.zeros((Z.shape[1], Z.shape[1]))
    count = 0
    for start, stop in logs:
        G = max(2, min(COVARIANCE_BATCHES, (stop - start) // 10))
        edges = np.linspace(start, stop, G + 1).astype(int)
        for lo, hi in itertools.pairwise(edges):
            s = (Z[lo:hi] * error[lo:hi, None]).sum(axis=0)
            S += np.outer(s, s)
        count += G
    return S * count / (count - 1)


def estimate_iv(X: np.ndarray, y: np.ndarray, Z: np.ndarray, logs=None):
    r"""IV estimate ``(Z^T X)^-1 Z^T y`` (least squares for ``Z = X``), its covariance for a
    residual correlated over neighbouring rows, and the textbook one for a white residual.

    The textbook :math:`\hat\sigma^2 A Z^T Z A^T`, :math:`A = (Z^T X)^{-1}` and
    :math:`\hat\sigma^2 = \lVert e\rVert^2/(N - p)`, assumes a white residual; the decimated
    one is coloured (the filters shape the differentiated noise, stick events last several
    rows), and on the synthetic logs it is 2-4 times off the spread of b and Coulomb over
    seeds. The covariance returned first is :math:`A \hat S A^T` with :math:`\hat S` the
    batch-means covariance of the scores (:func:`long_run_covariance`); ``logs`` are the
    row ranges of the logs (default: one).

    References
    ----------
    M. S. Bester, T. G. Conley, C. B. Hansen, "Inference with dependent data using cluster
    covariance estimators", Journal of Econometrics 165(2), 2011.
    """
    theta = np.linalg.lstsq(X, y, rcond=None)[0] if Z is X else np.linalg.solve(Z.T @ X, Z.T @ y)
    error = y - X @ theta
    rows, size = X.shape
    sigma2 = float(error @ error) / (rows - size)
    A = np.linalg.inv(Z.T @ X)
    iid = sigma2 * A @ (Z.T @ Z) @ A.T
    S = long_run_covariance(Z, error, logs or [(0, rows)])
    return theta, A @ S @ A.T, iid


def input_loop(theta: np.ndarray, u: np.ndarray, J: float, settings, *, velocity=True):
    """The loop of ``"idim-iv-input"``: the logged input drives the model, and a slow PD
    (bandwidth :data:`INPUT_LOOP_FRACTION` x the decimation cut-off, gains from ``J``) pulls it
    towards the low-passed measured position so that it cannot drift away (an open-loop
    simulation integrates every error of the offset and friction). ``velocity=False``: without
    its reference velocity (the gradient of its reference; :func:`input_simulation`)."""
    from scipy import signal

    omega = 2.0 * math.pi * INPUT_LOOP_FRACTION * settings.decimation_cutoff
    sos = signal.butter(2, omega / (2 * math.pi), fs=1.0 / settings.Ts, output="sos")
    # sosfiltfilt and np.gradient bit for bit in less memory; read-only: the loop shares them
    slow = readonly(filtfilt(sos, theta))
    return FeedbackLoop(
        slow,
        kp=J * omega**2,
        kd=2.0 * J * omega,
        reference_velocity=readonly(gradient_inplace(slow.copy(), settings.Ts))
        if velocity
        else None,
        feedforward=u,
        velocity_filter=None,
    )


def input_simulation(theta, u, parameters, settings, velocity0: float) -> np.ndarray:
    """The position of :func:`input_loop` simulated with ``parameters`` from ``theta[0]`` and
    ``velocity0`` (``run_simulation(input_loop(...), ...)`` bit for bit), holding two arrays
    of the log's length: the reference velocity is given to the kernel beside the loop (not
    copied into it), and the position is written over it."""
    loop = input_loop(theta, u, parameters[0], settings, velocity=False)
    velocity = gradient_inplace(loop.reference.copy(), settings.Ts)
    simulated, _ = run_simulation(
        loop, parameters, Ts=settings.Ts, theta0=theta[0], velocity0=velocity0, command=False,
        reference_velocity=velocity, out=velocity,
    )  # fmt: skip
    return simulated


@dataclass
class Solution:
    estimate: np.ndarray
    covariance: np.ndarray  # batch means (estimate_iv)
    covariance_iid: np.ndarray  # sigma^2 A Z^T Z A^T, for a white residual
    X: np.ndarray
    y: np.ndarray  # the input minus what the fixed parameters explain
    iterations: int
    converged: bool


def _stacked(blocks: list) -> np.ndarray:
    """``np.vstack(blocks)`` (``np.concatenate`` of vectors); one block as it is, not copied."""
    if len(blocks) == 1:
        return blocks[0]
    return np.vstack(blocks) if blocks[0].ndim == 2 else np.concatenate(blocks)


def solve(runs, layout: Layout, method: str, own_sign: bool, max_iterations, tolerance,
          report=None):  # fmt: skip
    """The estimate of one set of regressions: least squares, then the IV iteration
    (``report(k)`` after iteration ``k``, if given)."""
    X = _stacked([layout.columns(run.regression.X, i) for i, run in enumerate(runs)])
    y = _stacked([layout.unexplained(run.regression.y, run.regression.X) for run in runs])
    check_design(runs, layout, X)
    sizes = np.cumsum([0] + [run.regression.X.shape[0] for run in runs])
    logs = list(itertools.pairwise(sizes.tolist()))  # the row range of each log
    estimate, covariance, iid = estimate_iv(X, y, X, logs)
    if method == "idim-ls":
        return Solution(estimate, covariance, iid, X, y, 0, True)
    converged = False
    for iteration in range(1, max_iterations + 1):
        blocks = []
        for i, run in enumerate(runs):
            name = f" of {run.name}" if len(runs) > 1 else ""
            parameters = simulable(layout.parameters(estimate, i), iteration, name)
            through_loop = run.loop is not None and method == "idim-iv"
            if through_loop:
                simulated, _ = run_simulation(
                    run.loop, parameters, Ts=run.Ts, theta0=run.theta[0],
                    velocity0=run.regression.velocity0, command=False,
                )  # fmt: skip
            else:  # the input-driven loop's arrays: not beside the instruments
                simulated = input_simulation(run.theta, run.u, parameters, run.settings,
                                             run.regression.velocity0)  # fmt: skip
            if through_loop and iteration == 1:
                mismatched = mismatch(run.theta, simulated)
                if mismatched > MAX_LOOP_MISMATCH:
                    raise ParameterValueError(
                        f"loop{name} does not describe the controller that produced the log: "
                        f"simulated with the IDIM-LS estimate it differs from the logged position "
                        f"by {mismatched:.3g} % (eq. 11; limit {MAX_LOOP_MISMATCH:g} %); check its "
                        "reference, gains, velocity filter and units"
                    )
            Z = instrument_rows(simulated, run.regression, run.settings, overwrite=True)
            del simulated
            if own_sign:
                # sign(velocity) is its own instrument: noise changes it only near rest, and
                # the simulated one jumps with every stick event (IV then does not converge)
                Z[:, 2] = run.regression.X[:, 2]
            blocks.append(layout.columns(Z, i))
            del Z
        Z = _stacked(blocks)
        del blocks
        try:
            if scaled_condition(Z) > MAX_CONDITION:
                raise np.linalg.LinAlgError
            new, covariance, iid = estimate_iv(X, y, Z, logs)
            del Z  # not beside the next iteration's
        except np.linalg.LinAlgError:
            J, b, c, _ = layout.parameters(estimate, 0)
            raise ParameterValueError(
                "IDIM-IV: the instruments from the simulated loop are singular (the loop "
                f"simulated with J = {J:.6g}, b = {b:.6g}, coulomb = {c:.6g} barely moves or "
                "never reverses); check the loop's reference, gains and units"
            ) from None
        change = np.abs(new - estimate)
        estimate = new
        if report is not None:
            report(iteration)
        if np.all(change <= tolerance * np.sqrt(np.diag(covariance))):
            converged = True
            break
    return Solution(estimate, covariance, iid, X, y, iteration, converged)
