r"""The inverse-dynamic-model regression of IDIM-LS: filtered differentiation and decimation.

The inverse dynamic model of a rigid axis (EMPS description, eq. 1),

.. math:: u = J\ddot q + b\dot q + c\,\mathrm{sign}(\dot q) + \mathrm{offset},

is linear in :math:`[J, b, c, \mathrm{offset}]`. From a logged position the regressors are
built as in the benchmark's ``Script_IDIM_LS.m`` (EMPS description, section 3):

1. the position is low-pass filtered by a Butterworth filter run forward and backward
   (``filtfilt``: no lag), cut-off ``cutoff`` (rule of thumb 5x the closed-loop bandwidth);
2. velocity and acceleration are central differences of the filtered position;
3. every column of the observation matrix and the measured input are filtered by the same
   low-pass filter and down-sampled by ``decimation`` ("parallel filtering and decimation",
   eq. 9: the order-8 Chebyshev type I filter of MATLAB's and scipy's ``decimate`` at
   0.8x the new Nyquist frequency, run forward and backward);
4. rows within ``border`` samples of either end (filter edge transients) are dropped, and
   optionally rows where the speed is below ``min_speed`` (stick phases, where
   :math:`\mathrm{sign}(\dot q)` does not describe the friction), or the rows of the log's
   *rests* (``rests``: see :func:`rest_rows`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from .._validation import ParameterValueError, as_int, nonnegative, positive
from . import _lean
from ._lean import (
    decimated_at,
    filtfilt,
    filtfilt_blocks,
    gradient_block,
    gradient_blocks,
    gradient_inplace,
    welch,
)

__all__ = [
    "MIN_ROWS",
    "PARAMETERS",
    "Regression",
    "Settings",
    "build_regression",
    "resolve_settings",
]

#: The parameters in the order of the observation matrix's columns.
PARAMETERS = ("J", "b", "coulomb", "offset")
#: Fewest regression rows accepted (ten per parameter).
MIN_ROWS = 10 * len(PARAMETERS)
#: The decimation filter: order and pass-band ripple [dB] of MATLAB's and scipy's decimate.
_DECIMATE_ORDER, _DECIMATE_RIPPLE = 8, 0.05


@dataclass(frozen=True)
class Settings:
    """Resolved filter settings of one identification (see :func:`resolve_settings`)."""

    Ts: float
    bandwidth: float
    cutoff: float
    order: int
    decimation: int
    border: int
    min_speed: float
    zoh: bool = False
    rests: bool = False  # drop the rows of the log's rests (rest_rows)

    @property
    def decimation_cutoff(self) -> float:
        """Cut-off [Hz] of the parallel (decimation) filter: 0.8x the decimated Nyquist."""
        return 0.8 * 0.5 / (self.Ts * self.decimation)

    def to_dict(self) -> dict:
        out = asdict(self)
        out["decimation_cutoff"] = self.decimation_cutoff
        return out


#: The adaptive defaults keep frequencies where the position's spectrum stands this far above
#: its noise floor (20 dB): there the differentiated noise is a hundredth of the motion.
SIGNAL_TO_NOISE = 100.0
#: A *rest* of the adaptive defaults is a stretch where the filtered speed stays below this
#: fraction of its largest value (2 %) ...
REST_SPEED_FRACTION = 0.02
#: ... for longer than this many decimated rows (one): the brief stick events of PD step
#: responses (the axis stops short of the target, slips again) are rests too, while the
#: reversals of the grid's chirp, PRBS, multisine and PD logs pass faster and are kept. Measured
#: on synthetic PD steps both ways (4096 counts, 0.5 ms): J +1.1 %, b +7.7 %, where stretches
#: longer than the main lobe (4 rows) left J +5.2 %, b +27 %.
REST_LENGTH = 1


def _whitened_psd(theta: np.ndarray, Ts: float):
    """Frequencies [Hz] and PSD of the position [unit^2/Hz] estimated from its second
    difference (Welch) divided by the difference's gain ``(2 sin(pi f Ts))^4``: the window's
    leakage from the large slow motion would otherwise mask the noise floor."""
    n = max(theta.size - 2, 0)  # np.diff(theta, 2), read a segment at a time

    def second(lo: int, hi: int) -> np.ndarray:
        return np.diff(theta[lo : hi + 2], 2)

    # scipy.signal.welch bit for bit, in a fraction of its memory
    f, psd = welch((n, second), fs=1.0 / Ts, window="blackmanharris", nperseg=min(n, 4096))
    gain = (2.0 * np.sin(np.pi * f * Ts)) ** 4
    with np.errstate(divide="ignore", invalid="ignore"):
        return f[1:], psd[1:] / gain[1:]


def _smallest_step(theta: np.ndarray) -> float:
    """The smallest positive ``|step|`` between consecutive samples (0 if none), block by
    block (a minimum is exact; its blocks let go before the spectrum is taken)."""
    q = math.inf
    block = _lean.block_of(theta.size)
    for lo in range(0, theta.size - 1, block):
        steps = np.abs(np.diff(theta[lo : lo + block + 1]))
        steps = steps[steps > 0]
        if steps.size:
            q = min(q, float(steps.min()))
    return 0.0 if q == math.inf else q


def noise_floor(theta: np.ndarray, Ts: float) -> tuple[float, float]:
    """One-sided noise PSD [unit^2/Hz] of a logged position, and its quantisation step.

    The larger of the encoder's quantisation noise ``q^2 Ts / 6`` (``q`` the smallest step
    between consecutive samples; white noise of variance ``q^2/12`` over ``fs/2``) and the
    median PSD of the top quarter of the band, where a motion system's position is noise.
    """
    q = _smallest_step(theta)
    f, psd = _whitened_psd(theta, Ts)
    top = psd[f >= 0.375 / Ts]
    return max(q * q * Ts / 6.0, float(np.median(top)) if top.size else 0.0), q


def signal_bandwidth(theta: np.ndarray, Ts: float) -> float:
    """Highest frequency [Hz] where the position's PSD is :data:`SIGNAL_TO_NOISE` times its
    noise floor (:func:`noise_floor`); 0 if none is (also with fewer than 3 samples: no
    second difference, no spectrum)."""
    if theta.size < 3:
        return 0.0
    floor, _ = noise_floor(theta, Ts)
    f, psd = _whitened_psd(theta, Ts)
    above = np.flatnonzero(psd > SIGNAL_TO_NOISE * floor)
    return float(f[above[-1]]) if above.size else 0.0


def adaptive_bandwidth(theta: np.ndarray, Ts: float) -> float:
    """The ``bandwidth`` [Hz] that puts the decimation filter's cut-off ``2 bandwidth`` at the
    log's :func:`signal_bandwidth`, within ``[fs/500, fs/12]`` (the cut-off ``5 bandwidth``
    below Nyquist; at least 0.4 % of the band kept)."""
    fs = 1.0 / Ts
    return float(np.clip(0.5 * signal_bandwidth(theta, Ts), fs / 500.0, fs / 12.0))


def resolve_settings(
    Ts: float,
    *,
    bandwidth=None,
    cutoff=None,
    order=4,
    decimation=None,
    border=None,
    min_speed=0.0,
    zoh=False,
    rests=False,
) -> Settings:
    """Fill in and check the filter settings for sampling period ``Ts`` [s].

    ``bandwidth`` is the closed-loop bandwidth :math:`\\omega_{dyn}` [Hz] (default ``fs/50``,
    20 Hz at 1 kHz as for EMPS). The benchmark's rules give ``cutoff = 5 bandwidth`` and
    ``decimation = round(0.8 (fs/2) / (2 bandwidth))``; ``border`` defaults to
    ``max(50, 5 decimation)`` samples. Each can be given directly instead.
    """
    fs = 1.0 / Ts
    nyquist = 0.5 * fs
    if bandwidth is None:
        bandwidth = fs / 50.0
    bandwidth = positive(bandwidth, "bandwidth", "a positive closed-loop bandwidth [Hz]")
    if cutoff is None:
        cutoff = 5.0 * bandwidth
    cutoff = positive(cutoff, "cutoff", "a positive cut-off frequency [Hz]")
    if cutoff >= nyquist:
        raise ParameterValueError(
            f"cutoff must be below the Nyquist frequency {nyquist:g} Hz of Ts = {Ts:g} s, got "
            f"{cutoff:g} Hz (5x bandwidth = {bandwidth:g} Hz by default)"
        )
    order = as_int(order, "order", "a Butterworth filter order from 1 to 10", minimum=1)
    if order > 10:
        raise ParameterValueError(
            f"order must be a Butterworth filter order from 1 to 10, got {order}"
        )
    if decimation is None:
        decimation = max(1, round(0.8 * nyquist / (2.0 * bandwidth)))
    decimation = as_int(decimation, "decimation", "a positive integer factor", minimum=1)
    decimation_cutoff = 0.8 * nyquist / decimation
    if decimation > 1 and cutoff < decimation_cutoff:
        raise ParameterValueError(
            f"cutoff = {cutoff:g} Hz is below the decimation filter's cut-off "
            f"{decimation_cutoff:g} Hz (0.8 fs / (2 decimation), decimation = {decimation}): "
            "the regressors would be filtered more than the input; raise cutoff or decimation"
        )
    if border is None:
        border = max(50, 5 * decimation)
    border = as_int(border, "border", "a non-negative number of samples", minimum=0)
    min_speed = nonnegative(min_speed, "min_speed", "a non-negative speed [rad/s or m/s]")
    return Settings(
        Ts=Ts,
        bandwidth=bandwidth,
        cutoff=cutoff,
        order=order,
        decimation=decimation,
        border=border,
        min_speed=min_speed,
        zoh=bool(zoh),
        rests=bool(rests),
    )


def velocity_filter(settings: Settings) -> np.ndarray:
    """The position's low-pass of step 1 (Butterworth, ``settings.order`` and ``cutoff``),
    in second-order sections."""
    from scipy import signal

    return signal.butter(settings.order, settings.cutoff, fs=1.0 / settings.Ts, output="sos")


def filtered_velocity(theta: np.ndarray, settings: Settings, *, overwrite: bool = False):
    """The velocity of steps 1-2 of the module docstring, ``np.gradient`` of the
    ``scipy.signal.sosfiltfilt``-filtered position (:func:`velocity_filter`), bit for bit
    (``tests/identification/test_lean.py`` keeps that construction), holding one new array of
    ``theta``'s size (the filtered position is differenced in place, :mod:`._lean`), or none
    with ``overwrite`` (the velocity written over ``theta``)."""
    sos = velocity_filter(settings)
    return gradient_inplace(filtfilt(sos, theta, out=theta if overwrite else None), settings.Ts)


#: The block [samples] of :func:`velocity_blocks` (8 kB of float64: it runs once a fit).
VELOCITY_BLOCK = 1 << 10


def velocity_blocks(theta: np.ndarray, settings: Settings):
    """:func:`filtered_velocity` of ``theta`` block by block, from the last block to the first:
    ``(lo, hi, v)`` with ``v`` equal to ``filtered_velocity(theta, settings)[lo:hi]``, bit
    for bit, holding a few blocks of :data:`VELOCITY_BLOCK` samples, no array of the log's
    length."""
    sos, n = velocity_filter(settings), theta.size
    blocks = filtfilt_blocks(sos, n, lambda lo, hi: theta[lo:hi], VELOCITY_BLOCK)
    return gradient_blocks(blocks, n, settings.Ts)


def _decimate_sos(factor: int) -> np.ndarray:
    """The parallel filter: MATLAB's and scipy's ``decimate`` default (Chebyshev type I,
    order 8, 0.05 dB ripple, cut-off 0.8/factor of Nyquist), in second-order sections."""
    from scipy import signal

    return signal.cheby1(_DECIMATE_ORDER, _DECIMATE_RIPPLE, 0.8 / factor, output="sos")


def decimated_rows(velocity: np.ndarray, Ts: float, factor: int, samples: np.ndarray):
    """Rows ``samples`` (increasing raw sample indices, multiples of ``factor``) of the
    observation matrix ``[qdd, qd, sign(qd), 1]`` (EMPS eq. 2; ``qdd = np.gradient(velocity,
    Ts)``) filtered forward and backward by the parallel filter (none at ``factor = 1``),
    ``scipy.signal.sosfiltfilt`` bit for bit, column by column: the full-rate observation
    matrix, the filter's padded copies of it and the whole decimated matrix are never held."""
    if factor == 1:
        X = np.empty((samples.size, 4))  # the observation matrix's rows, column by column
        X[:, 0] = np.gradient(velocity, Ts)[samples]
        X[:, 1] = velocity[samples]
        X[:, 2] = np.sign(X[:, 1])
        X[:, 3] = 1.0
        return X
    sos, n = _decimate_sos(factor), velocity.size
    columns = (
        lambda lo, hi: gradient_block(velocity, lo, hi, Ts),
        lambda lo, hi: velocity[lo:hi],
        lambda lo, hi: np.sign(velocity[lo:hi]),
        lambda lo, hi: np.ones(hi - lo),
    )
    X = np.empty((samples.size, len(columns)))
    for j, column in enumerate(columns):
        decimated_at(sos, n, column, samples, out=X[:, j])
    return X


def decimated_input(u: np.ndarray, settings: Settings, samples: np.ndarray) -> np.ndarray:
    """The input, aligned first with ``zoh`` (see :func:`build_regression`), filtered as
    :func:`decimated_rows`'s columns, at raw samples ``samples``, in blocks."""

    def aligned(lo: int, hi: int) -> np.ndarray:
        if not settings.zoh:
            return u[lo:hi]
        out = np.empty(hi - lo)
        start = max(lo, 1)
        out[start - lo :] = 0.5 * (u[start:hi] + u[start - 1 : hi - 1])
        if lo == 0:
            out[0] = u[0]
        return out

    if settings.decimation == 1:
        return np.asarray(aligned(0, u.size), dtype=float)[samples]  # one new array
    return decimated_at(_decimate_sos(settings.decimation), u.size, aligned, samples)


@dataclass(frozen=True)
class Regression:
    """The decimated regression ``y = X theta + e`` and what it was built from."""

    X: np.ndarray  # observation matrix, one row per kept decimated sample
    y: np.ndarray  # decimated input [N m or N]
    index: np.ndarray  # raw sample index of each row
    forward: float  # the travel over the rows forward: the positive filtered velocities' sum
    backward: float  # and backward: minus the negative ones' sum [rad/s or m/s]
    kept: np.ndarray  # mask over the decimated samples inside the border: row kept?
    rest_speed: float  # speed below which the log rests [rad/s or m/s] (rests only, else 0)
    rest_rows: int  # rows dropped as rests
    velocity0: float  # filtered velocity at the first sample
    max_speed: float  # largest |filtered velocity| over every sample


def rows_inside_border(n: int, settings: Settings) -> np.ndarray:
    """Raw indices of the decimated samples that lie outside the border at both ends."""
    index = np.arange(0, n, settings.decimation)
    skip = math.ceil(settings.border / settings.decimation)
    return index[skip : index.size - skip]


def minimum_samples(settings: Settings) -> int:
    """Fewest raw samples that leave :data:`MIN_ROWS` rows (before any ``min_speed``)."""
    skip = math.ceil(settings.border / settings.decimation)
    return (MIN_ROWS + 2 * skip - 1) * settings.decimation + 1


def instrument_rows(theta: np.ndarray, regression: Regression, settings: Settings, *,
                    overwrite: bool = False) -> np.ndarray:  # fmt: skip
    """The observation matrix of another position trace, on the same rows as ``regression``
    (with ``overwrite``, its filtered velocity written over ``theta``)."""
    velocity = filtered_velocity(theta, settings, overwrite=overwrite)
    # decimate(...)[inside][kept] of the whole decimated matrix, without it
    return decimated_rows(velocity, settings.Ts, settings.decimation, regression.index)


def _largest_speed(velocity: np.ndarray) -> float:
    """``max(|velocity|)``, block by block (a maximum is exact in any order)."""
    block = _lean.block_of(velocity.size)
    return max(float(np.max(np.abs(velocity[lo : lo + block])))
               for lo in range(0, velocity.size, block))  # fmt: skip


def near_slow(velocity: np.ndarray, index: np.ndarray, speed: float, half: int) -> np.ndarray:
    """Whether ``|velocity| < speed`` somewhere within ``half`` samples of each of ``index``
    (the decimation filter's main lobe around a row), counted block by block of rows."""
    n, out = velocity.size, np.zeros(index.size, dtype=bool)
    # blocks of rows spanning about a block of samples (the counts are exact in any blocks)
    step = max(1, _lean.block_of(n) * index.size // max(n, 1))
    for a in range(0, index.size, step):
        rows = index[a : a + step]
        lo, hi = max(int(rows[0]) - half, 0), min(int(rows[-1]) + half + 1, n)
        slow = np.abs(velocity[lo:hi]) < speed
        count = np.zeros(slow.size + 1, dtype=np.int64)  # [0, cumsum(slow)]
        np.cumsum(slow, out=count[1:])
        del slow
        out[a : a + rows.size] = (
            count[np.minimum(rows + half + 1, n) - lo] - count[np.maximum(rows - half, 0) - lo]
        ) > 0
    return out


def build_regression(theta: np.ndarray, u: np.ndarray, settings: Settings) -> Regression:
    """Build the decimated observation matrix and input (steps 1-4 of the module docstring).

    Bit for bit the straightforward construction (``tests/identification/test_lean.py``
    keeps it), in blocks: besides its result it holds one array of the log's length, the
    filtered velocity.
    """
    velocity = filtered_velocity(theta, settings)
    index = rows_inside_border(theta.size, settings)
    kept = np.ones(index.size, dtype=bool)
    width = 4 * settings.decimation + 1  # the decimation filter's main lobe (+-2 rows)
    if settings.min_speed > 0.0:
        # keep a row only if the speed stays above min_speed over the decimation filter's
        # main lobe around it
        kept = ~near_slow(velocity, index, settings.min_speed, width // 2)
    rest_speed, rest_rows = 0.0, 0
    if settings.rests:
        resting, rest_speed = rest_rows_mask(
            velocity, index, REST_LENGTH * settings.decimation, width // 2
        )
        rest_rows = int(np.count_nonzero(resting & kept))
        kept &= ~resting
        del resting
    # the raw samples of the rows kept: decimate(...)[inside][kept] of the whole decimated
    # X and y (inside = index // decimation), without them
    index = index[kept]
    X = decimated_rows(velocity, settings.Ts, settings.decimation, index)
    # the travel each way over the rows (all directions() needs of them)
    at_rows, velocity0, max_speed = velocity[index], float(velocity[0]), _largest_speed(velocity)
    forward, backward = float(at_rows[at_rows > 0].sum()), float(-at_rows[at_rows < 0].sum())
    del at_rows
    del velocity  # not beside the input's rows
    # y: with zoh, the input held over each sample: the second central difference of the
    # position at k sees (u_(k-1) + u_k) / 2, exactly for an inertia (ZOH of 1/s^2 is
    # Ts^2 (z + 1) / (2 (z - 1)^2)): the input is aligned with it, half a sample later
    y = decimated_input(u, settings, index)
    return Regression(
        X=X,
        y=y,
        index=index,
        forward=forward,
        backward=backward,
        kept=kept,
        rest_speed=rest_speed,
        rest_rows=rest_rows,
        velocity0=velocity0,
        max_speed=max_speed,
    )


def rest_rows_mask(velocity: np.ndarray, index: np.ndarray, length: int, margin: int):
    r"""Which rows ``index`` lie in or next to a *rest* of the log, and the rest speed.

    A rest is a stretch of more than ``length`` samples (:data:`REST_LENGTH` decimated rows)
    where the filtered speed stays below :data:`REST_SPEED_FRACTION` of its largest value
    over the rows; the rows within ``margin`` samples of one (half the decimation filter's
    main lobe) are dropped as well: the filter mixes them with the rest. At rest the friction
    is static, any value up to the breakaway torque, which :math:`c\,\mathrm{sign}(\dot q)`
    does not describe: a position held by a PD, or a constant load, would be read as offset
    or Coulomb friction. Brief slow instants (the reversals of an oscillating motion) are not rests
    and are kept.
    """
    n = velocity.size
    rest_speed = REST_SPEED_FRACTION * float(np.abs(velocity[index]).max()) if index.size else 0.0
    slow = np.empty(n, dtype=bool)
    block = _lean.block_of(n)
    for lo in range(0, n, block):
        np.less(np.abs(velocity[lo : lo + block]), rest_speed, out=slow[lo : lo + block])
    # the edges of the stretches of consecutive slow samples: where [0, slow, 0] changes
    edges = np.flatnonzero(slow[1:] != slow[:-1]) + 1
    edges = np.concatenate([[0] if n and slow[0] else [], edges, [n] if n and slow[-1] else []])
    edges = edges.astype(np.int64)
    del slow
    starts, stops = edges[0::2], edges[1::2]
    long = stops - starts > length  # longer than length samples
    # a row rests where more stretches (widened by margin) have begun than have ended
    begun = np.maximum(starts[long] - margin, 0)
    ended = np.minimum(stops[long] + margin, n)
    resting = np.searchsorted(begun, index, side="right") - np.searchsorted(
        ended, index, side="right"
    )
    return resting > 0, rest_speed


def differentiate(x, Ts: float, *, cutoff: float | None = None, order: int = 4, like=None):
    r"""Velocity and acceleration of a sampled position by identify's filtered differentiation.

    The position is low-pass filtered by a Butterworth filter run forward and backward (no
    lag) and differentiated twice by central differences: steps 1-2 of IDIM-LS (EMPS
    description, section 3). Use it for a logged reference position, to give
    :class:`FeedbackLoop` its ``reference_velocity`` and feed-forward consistently with the
    identification.

    Parameters
    ----------
    x : array_like
        Position [rad or m], uniformly sampled.
    Ts : float
        Sampling period [s].
    cutoff : float, optional
        Cut-off [Hz] of the filter. Default: the one ``identify(method="auto")`` chooses for
        the position ``like`` (5 x half its signal bandwidth; see :func:`identify`, Notes).
    order : int, optional
        Butterworth order (4).
    like : array_like, optional
        The measured position whose default cut-off to use (default ``x`` itself).

    Returns
    -------
    velocity, acceleration : ndarray
        [rad/s or m/s], [rad/s^2 or m/s^2].

    Raises
    ------
    ParameterValueError
        If ``cutoff`` is not below the Nyquist frequency, ``x`` is not finite or has no more
        samples than the filter's padding (three times its taps, 15 at order 4), or the
        position whose spectrum sets the default ``cutoff`` has fewer than 3 samples.

    Examples
    --------
    >>> import numpy as np
    >>> from hpdob.identification import differentiate
    >>> t = np.arange(4000) * 1e-3
    >>> v, a = differentiate(np.sin(2 * np.pi * t), 1e-3, cutoff=50.0)
    >>> round(float(v[2000]), 3), round(float(a[2250]), 2)   # 2 pi cos, -(2 pi)^2 sin
    (6.283, -39.48)
    """
    from ._checks import sample_vector

    x = sample_vector(x, "x", "positions [rad or m]")
    Ts = positive(Ts, "Ts", "a positive sampling period [s]")
    if cutoff is None:
        reference = x if like is None else sample_vector(like, "like", "positions [rad or m]")
        if reference.size < 3:  # its second difference's spectrum sets the cut-off
            raise ParameterValueError(
                f"{'x' if like is None else 'like'} must be positions [rad or m] of at least 3 "
                f"samples to set the default cutoff from, got {reference.size}"
            )
        cutoff = 5.0 * adaptive_bandwidth(reference, Ts)
    settings = resolve_settings(Ts, cutoff=cutoff, order=order, decimation=1, border=0)
    padding = _lean.pad_length(velocity_filter(settings))
    if x.size <= padding:  # sosfiltfilt's own error would not name x
        raise ParameterValueError(
            f"x must be positions [rad or m] of more than {padding} samples (the padding of "
            f"the order-{settings.order} filter run forward and backward), got {x.size}"
        )
    # the np.gradient of the sosfiltfilt-filtered position, in less memory
    velocity = filtered_velocity(x, settings)
    return velocity, np.gradient(velocity, settings.Ts)
