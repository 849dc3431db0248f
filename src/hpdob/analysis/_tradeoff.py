r"""The accuracy/noise trade-off of observers of different orders and bandwidths.

For each order ``m`` and bandwidth ``g``: the steady-state estimation-error amplitude for a
sinusoidal nominal disturbance of frequency ``f`` (per unit amplitude, :math:`|1 - Q|` at
``f``, closed form) against the estimate's noise gain (:func:`observer_noise_gain`, exact).
Both are properties of the observer on its nominal model: they do not depend on the outer
controller.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .._table import columns_to_csv, columns_to_pandas
from .._validation import (
    ParameterTypeError,
    ParameterValueError,
    as_grid,
    as_int,
    check_choice,
    positive,
    readonly,
)
from ..models._servo import ServoModel
from ..observers._synthesis import design_observer
from ._estimation import estimation_response
from ._noise import CHANNELS, observer_noise_gain

__all__ = ["NoiseTradeoff", "noise_tradeoff"]


@dataclass(frozen=True, eq=False)
class NoiseTradeoff:
    """Estimation error against noise gain for several orders and bandwidths.

    Built by :func:`noise_tradeoff`. Arrays are read-only; row ``i`` belongs to
    ``orders[i]``, column ``j`` to ``bandwidths[j]``.

    Attributes
    ----------
    orders : tuple of int
    bandwidths : ndarray
        Observer bandwidths [rad/s].
    frequency : float
        Disturbance frequency [Hz].
    noise : str
        ``"velocity"`` or ``"position"``: the measurement that carries the noise.
    Ts : float
        Sampling period [s].
    error_gain : ndarray, shape (len(orders), len(bandwidths))
        Steady-state estimation-error amplitude per unit disturbance amplitude,
        :math:`|1 - Q(e^{j 2 \\pi f T_s})|`.
    noise_gain : ndarray, shape (len(orders), len(bandwidths))
        RMS of the estimate per unit white noise [N m/(rad/s)] or [N m/rad].
    """

    orders: tuple
    bandwidths: np.ndarray = field(repr=False)
    frequency: float
    noise: str
    Ts: float
    error_gain: np.ndarray = field(repr=False)
    noise_gain: np.ndarray = field(repr=False)

    def _row(self, order) -> int:
        m = as_int(order, "order", "one of the computed orders")
        if m not in self.orders:
            raise ParameterValueError(f"order must be one of {list(self.orders)}, got {m}")
        return self.orders.index(m)

    def error_at_noise(self, order: int, noise_gain) -> np.ndarray:
        """Error gain of ``order`` at the given noise gain(s), log-log interpolated.

        NaN outside the range of noise gains its bandwidths cover.
        """
        i = self._row(order)
        target = np.atleast_1d(np.asarray(noise_gain, dtype=float))
        order = np.argsort(self.noise_gain[i])
        x, y = np.log(self.noise_gain[i][order]), np.log(self.error_gain[i][order])
        out = np.full(target.shape, np.nan)
        ok = (target > 0) & np.isfinite(target)
        out[ok] = np.exp(np.interp(np.log(target[ok]), x, y, left=np.nan, right=np.nan))
        return out

    def improvement(self, order: int, *, reference: int = 0) -> np.ndarray:
        """Error of ``reference`` divided by the error of ``order`` at the same noise gain.

        One value per bandwidth of ``reference`` (> 1: ``order`` is more accurate for the same
        noise); NaN where ``order``'s bandwidths do not reach that noise gain.
        """
        r = self._row(reference)
        return self.error_gain[r] / self.error_at_noise(order, self.noise_gain[r])

    def to_pandas(self):
        """Long-format ``pandas.DataFrame``: one row per order and bandwidth."""
        return columns_to_pandas(self._columns())

    def _columns(self) -> dict:
        n = len(self.bandwidths)
        return {
            "order": np.repeat(np.array(self.orders), n),
            "bandwidth_rad_s": np.tile(self.bandwidths, len(self.orders)),
            "frequency_Hz": np.full(n * len(self.orders), self.frequency),
            "error_gain": self.error_gain.ravel(),
            f"noise_gain_{self.noise}": self.noise_gain.ravel(),
        }

    def to_csv(self, path):
        """Write the long-format table of :meth:`to_pandas` to ``path`` (no pandas needed)."""
        return columns_to_csv(self._columns(), path)

    def plot(self, ax=None, *, label_bandwidths=(25.0, 50.0, 100.0, 200.0, 400.0, 800.0)):
        """Log-log plot of error gain against noise gain, one curve per order.

        Bandwidths in ``label_bandwidths`` [rad/s] within the grid are marked and labelled
        (positions interpolated log-log along each curve). Where the curves crowd together
        (low noise) a label that would overlap another is left out; its point stays marked.
        Returns the matplotlib Figure.
        """
        import matplotlib.pyplot as plt

        from .._plotting import PAPER_WIDTH, label_points, style_axes

        if ax is None:
            fig, ax = plt.subplots(figsize=(PAPER_WIDTH, 4.6), layout="constrained")
        else:
            fig = ax.figure
        names = {0: "DOb (m=0)", 1: "HPDOb (m=1)"}
        labels = []
        for i, m in enumerate(self.orders):
            line = ax.loglog(
                self.noise_gain[i], self.error_gain[i], label=names.get(m, f"order m={m}")
            )[0]
            logs = np.log(self.bandwidths)
            order = np.argsort(logs)
            for g in label_bandwidths:
                if not self.bandwidths.min() <= g <= self.bandwidths.max():
                    continue
                x, y = (
                    np.exp(np.interp(math.log(g), logs[order], np.log(values[i][order])))
                    for values in (self.noise_gain, self.error_gain)
                )
                ax.plot(x, y, "o", color=line.get_color(), markersize=3.5)
                labels.append((x, y, f"{g:g}", line.get_color()))
        unit = "N m/(rad/s)" if self.noise == "velocity" else "N m/rad"
        style_axes(
            ax,
            xlabel=f"noise gain: RMS of estimate per unit {self.noise} noise [{unit}]",
            ylabel=f"estimation error per unit\ndisturbance at {self.frequency:g} Hz [-]",
        )
        ax.legend(loc="best", fontsize="small")
        ax.set_title(
            f"Accuracy against noise (labels: bandwidth [rad/s], Ts = {self.Ts:g} s)",
            fontsize="medium",
        )
        label_points(ax, labels)
        return fig


def noise_tradeoff(
    *,
    nominal: ServoModel,
    Ts: float,
    frequency: float,
    bandwidths,
    orders=(0, 1, 2, 3),
    noise: str = "velocity",
    gain_direction=(1.0, 1.0),
) -> NoiseTradeoff:
    r"""Estimation error for a sinusoidal disturbance against noise gain, per order and bandwidth.

    Parameters
    ----------
    nominal : ServoModel
        The nominal model the observers are designed on.
    Ts : float
        Sampling period [s].
    frequency : float
        Disturbance frequency [Hz], positive and below the Nyquist frequency ``1/(2 Ts)``.
    bandwidths : array_like
        Observer bandwidths [rad/s], positive (all poles at ``exp(-g Ts)``).
    orders : sequence of int, optional
        Truncation orders, default ``(0, 1, 2, 3)``.
    noise : {"velocity", "position"}, optional
        Measurement carrying the white noise. Default ``"velocity"``: with an encoder the
        differenced velocity carries noise ``sqrt(2)/Ts`` times the angle's, so it dominates.
    gain_direction : sequence of 2 floats, optional
        As for :func:`hpdob.design_observer`.

    Returns
    -------
    NoiseTradeoff

    Raises
    ------
    TypeError, ValueError
        For arguments of the wrong type or value (empty grids, non-positive bandwidths, a
        frequency at or above Nyquist, ...), naming the parameter.

    References
    ----------
    The accuracy/noise trade-off of higher-order DObs named in the paper's introduction;
    ``docs/analysis.md``, section 5 (the numbers for the canonical motor).

    Examples
    --------
    >>> from hpdob import ServoModel, noise_tradeoff
    >>> t = noise_tradeoff(nominal=ServoModel(2.8e-4), Ts=1e-3, frequency=2.0,
    ...                    bandwidths=[50.0, 100.0, 200.0, 400.0], orders=(0, 1))
    >>> t.error_gain.shape
    (2, 4)
    >>> bool(t.improvement(1)[2] > 1)   # HPDOb beats a 200 rad/s DOb at its noise gain
    True
    """
    if not isinstance(nominal, ServoModel):
        raise ParameterTypeError(f"nominal must be a ServoModel, got {type(nominal).__name__}")
    Ts = positive(Ts, "Ts", "a positive finite sampling period [s]")
    f = positive(frequency, "frequency", "a positive finite disturbance frequency [Hz]")
    if f >= 0.5 / Ts:
        raise ParameterValueError(
            f"frequency must be below the Nyquist frequency 1/(2 Ts) = {0.5 / Ts:g} Hz, got {f!r}"
        )
    grid = as_grid(bandwidths, "bandwidths", "positive observer bandwidths [rad/s]")
    if isinstance(orders, (str, bytes)) or not hasattr(orders, "__iter__"):
        raise ParameterTypeError(f"orders must be a sequence of integers, got {orders!r}")
    ms = tuple(
        as_int(m, "orders", "non-negative integer truncation orders", minimum=0) for m in orders
    )
    if not ms:
        raise ParameterValueError("orders must hold at least one truncation order, got []")
    if len(set(ms)) != len(ms):
        raise ParameterValueError(f"orders must not repeat, got {list(ms)}")
    check_choice(noise, "noise", CHANNELS)
    model = nominal.discretize(Ts)
    err = np.empty((len(ms), grid.size))
    gain = np.empty((len(ms), grid.size))
    for i, m in enumerate(ms):
        for j, g in enumerate(grid):
            design = design_observer(model, order=m, bandwidth=g, gain_direction=gain_direction)
            err[i, j] = abs(estimation_response(design, f, error=True)[0])
            gain[i, j] = observer_noise_gain(design, noise=noise)
    if np.any(gain <= 0.0):
        raise ParameterValueError(
            f"noise={noise!r} does not reach the estimate for gain_direction="
            f"{list(gain_direction)} (noise gain 0): choose the other noise channel"
        )
    return NoiseTradeoff(
        orders=ms,
        bandwidths=readonly(grid),
        frequency=f,
        noise=noise,
        Ts=Ts,
        error_gain=readonly(err),
        noise_gain=readonly(gain),
    )
