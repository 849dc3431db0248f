r"""The accuracy/noise trade-off of observers of different orders, families and bandwidths.

For each order ``m``, family (measuring the state, or the angle only) and bandwidth ``g``: the
steady-state estimation-error amplitude for a sinusoidal nominal disturbance of frequency ``f``
(per unit amplitude, :math:`|1 - Q|` at ``f``, closed form) against the estimate's noise gain
(:func:`observer_noise_gain`, exact).
Both are properties of the observer on its nominal model: they do not depend on the outer
controller.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from .._table import CsvTable, columns_to_pandas
from .._validation import (
    ParameterTypeError,
    ParameterValueError,
    as_grid,
    as_int,
    check_choice,
    positive,
    readonly,
)
from ..controllers import Controller, LinearController, controller_system
from ..models import ServoModel
from ..observers import (
    MEASUREMENTS,
    POLE_TOLERANCE,
    check_spec,
    design_at_bandwidth,
    design_observer,
    get_family,
    spec_label,
)
from ..simulation import MISSING, Encoder, loop_parts
from ._estimation import estimation_response
from ._noise import OBSERVER_CHANNELS, noise_gains, observer_noise_gain

__all__ = ["NoiseTradeoff", "noise_tradeoff"]


@dataclass(frozen=True, eq=False)
class NoiseTradeoff(CsvTable):
    """Estimation error against noise gain for several orders, families and bandwidths.

    Built by :func:`noise_tradeoff`. Arrays are read-only; row ``i`` belongs to ``orders[i]``
    of the family ``measurements[i]``, column ``j`` to ``bandwidths[j]``.

    Attributes
    ----------
    orders : tuple of int
        Truncation order of each row.
    measurements : tuple of str
        Family of each row: ``"state"`` (the paper's observers) or ``"position"``
        (position-only, velocity bandwidth equal to the bandwidth).
    bandwidths : ndarray
        Observer bandwidths [rad/s].
    frequency : float
        Disturbance frequency [Hz].
    noise : str
        ``"velocity"``, ``"position"`` or ``"encoder"``: the measurement noise (see
        :func:`hpdob.observer_noise_gain`).
    Ts : float
        Sampling period [s].
    error_gain : ndarray, shape (rows, len(bandwidths))
        Steady-state estimation-error amplitude per unit disturbance amplitude,
        :math:`|1 - Q(e^{j 2 \\pi f T_s})|`.
    noise_gain : ndarray, shape (rows, len(bandwidths))
        RMS of the estimate per unit white noise [N m/(rad/s)] or [N m/rad].
    u_noise_gain : ndarray or None, shape (rows, len(bandwidths))
        With a ``controller``: RMS of the command ``u`` per unit white noise in the nominal
        closed loop [N m/(rad/s)] or [N m/rad] (NaN where that loop is unstable, as a
        differenced velocity makes it at high bandwidths); None otherwise.
    family : dict or None
        The registered family's spec (``type`` and its other arguments, without the order
        and the bandwidth) the rows design, or None for the paper's family (then
        ``measurements`` says which of its versions).
    labels : tuple of str
        Display name of each row (the legend).
    """

    orders: tuple
    bandwidths: np.ndarray = field(repr=False)
    frequency: float
    noise: str
    Ts: float
    error_gain: np.ndarray = field(repr=False)
    noise_gain: np.ndarray = field(repr=False)
    measurements: tuple = ()
    u_noise_gain: np.ndarray | None = field(default=None, repr=False)
    family: dict | None = None
    labels: tuple = ()

    def __post_init__(self) -> None:
        if not self.measurements:
            object.__setattr__(self, "measurements", ("state",) * len(self.orders))
        if not self.labels:
            names = tuple(map(_row_name, self.orders, self.measurements))
            object.__setattr__(self, "labels", names)

    def _row(self, order, measurement=None) -> int:
        m = as_int(order, "order", "one of the computed orders")
        rows = [
            i
            for i, (mi, kind) in enumerate(zip(self.orders, self.measurements, strict=True))
            if mi == m and measurement in (None, kind)
        ]
        if not rows:
            if measurement is not None:
                check_choice(measurement, "measurement", sorted(set(self.measurements)))
            listed = sorted(set(self.orders))
            raise ParameterValueError(f"order must be one of {listed}, got {m}")
        if len(rows) > 1:
            raise ParameterValueError(
                f"order {m} is computed for both measurements {list(self.measurements)}: give "
                "measurement='state' or 'position'"
            )
        return rows[0]

    def _values(self, channel: str) -> np.ndarray:
        check_choice(channel, "channel", ("estimate", "command"))
        if channel == "estimate":
            return self.noise_gain
        if self.u_noise_gain is None:
            raise ParameterValueError(
                "channel='command' needs the command's noise gains: call noise_tradeoff with "
                "a controller (controller=PD(...), or a ServoLoop with one)"
            )
        return self.u_noise_gain

    def error_at_noise(
        self, order: int, noise_gain, *, measurement=None, channel="estimate"
    ) -> np.ndarray:
        """Error gain of ``order`` at the given noise gain(s), log-log interpolated.

        Parameters
        ----------
        order : int
            A truncation order of the table.
        noise_gain : float or array_like
            Noise gain(s) to read at, in the table's units (of the estimate, or of the
            command for ``channel="command"``).
        measurement : {"state", "position"}, optional
            The family, where the table holds ``order`` for both.
        channel : {"estimate", "command"}, optional
            Interpolate at noise gains of the estimate (default) or of the command ``u``.

        Returns
        -------
        ndarray
            Error gain at each noise gain; NaN outside the range its bandwidths cover.

        Raises
        ------
        ParameterValueError
            If ``order`` is not in the table, is there for both families and ``measurement``
            is not given, or ``channel="command"`` without the command's noise gains.
        """
        i = self._row(order, measurement)
        values = self._values(channel)
        target = np.atleast_1d(np.asarray(noise_gain, dtype=float))
        keep = np.isfinite(values[i])  # NaN: no stationary noise (an unstable loop)
        order = np.argsort(values[i][keep])
        x, y = np.log(values[i][keep][order]), np.log(self.error_gain[i][keep][order])
        out = np.full(target.shape, np.nan)
        ok = (target > 0) & np.isfinite(target)
        out[ok] = np.exp(np.interp(np.log(target[ok]), x, y, left=np.nan, right=np.nan))
        return out

    def improvement(
        self,
        order: int,
        *,
        reference: int = 0,
        measurement=None,
        reference_measurement=None,
        channel="estimate",
    ) -> np.ndarray:
        """Error of ``reference`` divided by the error of ``order`` at the same noise gain.

        Parameters
        ----------
        order : int
            The order compared.
        reference : int, optional
            The order compared with. Default 0 (the DOb).
        measurement, reference_measurement : {"state", "position"}, optional
            Their families, where the table holds an order for both.
        channel : {"estimate", "command"}, optional
            The noise compared. Default ``"estimate"``.

        Returns
        -------
        ndarray
            One value per bandwidth of ``reference``: > 1 where ``order`` is more accurate
            for the same noise; NaN where ``order``'s bandwidths do not reach that noise gain.

        Raises
        ------
        ParameterValueError
            As for :meth:`error_at_noise`.
        """
        r = self._row(reference, reference_measurement)
        values = self._values(channel)
        return self.error_gain[r] / self.error_at_noise(
            order, values[r], measurement=measurement, channel=channel
        )

    def to_pandas(self):
        """The table in long format.

        Returns
        -------
        pandas.DataFrame
            One row per order and bandwidth: (``family``, for a registered family other
            than the paper's,) ``measurement``, ``order``,
            ``bandwidth_rad_s``, ``frequency_Hz``, ``error_gain``, ``noise_gain_<noise>``
            (and ``u_noise_gain_<noise>`` with a controller).

        Raises
        ------
        ImportError
            If pandas is not installed (``pip install hpdob[pandas]``).
        """
        return columns_to_pandas(self._columns())

    def _columns(self) -> dict:
        n = len(self.bandwidths)
        columns = (
            {}
            if self.family is None
            else {"family": np.repeat(np.array([self.family["type"]]), n * len(self.orders))}
        )
        columns |= {
            "measurement": np.repeat(np.array(self.measurements), n),
            "order": np.repeat(np.array(self.orders), n),
            "bandwidth_rad_s": np.tile(self.bandwidths, len(self.orders)),
            "frequency_Hz": np.full(n * len(self.orders), self.frequency),
            "error_gain": self.error_gain.ravel(),
            f"noise_gain_{self.noise}": self.noise_gain.ravel(),
        }
        if self.u_noise_gain is not None:
            columns[f"u_noise_gain_{self.noise}"] = self.u_noise_gain.ravel()
        return columns

    def plot(
        self,
        ax=None,
        *,
        label_bandwidths=(25.0, 50.0, 100.0, 200.0, 400.0, 800.0),
        channel="estimate",
    ):
        """Log-log plot of error gain against noise gain, one curve per order and family.

        Position-only observers are drawn dashed. Where the curves crowd together (low noise)
        a bandwidth label that would overlap another is left out; its point stays marked.

        Parameters
        ----------
        ax : matplotlib Axes, optional
            Where to draw; default a new figure.
        label_bandwidths : sequence of float, optional
            Bandwidths [rad/s] to mark and label on each curve (those within the grid;
            positions interpolated log-log). Default 25 to 800 rad/s, doubling.
        channel : {"estimate", "command"}, optional
            Plot against the noise gain of the estimate (default) or of the command ``u``.

        Returns
        -------
        matplotlib.figure.Figure
        """
        import matplotlib.pyplot as plt

        from .._plotting import PAPER_WIDTH, label_points, style_axes

        values = self._values(channel)
        if ax is None:
            fig, ax = plt.subplots(figsize=(PAPER_WIDTH, 4.6), layout="constrained")
        else:
            fig = ax.figure
        colors = sorted(set(self.orders))  # one colour per order, dashed: position-only
        labels = []
        for i, (m, kind) in enumerate(zip(self.orders, self.measurements, strict=True)):
            line = ax.loglog(
                values[i],
                self.error_gain[i],
                "--" if kind == "position" else "-",
                color=f"C{colors.index(m) % 10}",
                label=self.labels[i],
            )[0]
            logs = np.log(self.bandwidths)
            order = np.argsort(logs)
            for g in label_bandwidths:
                if not self.bandwidths.min() <= g <= self.bandwidths.max():
                    continue
                x, y = (
                    np.exp(np.interp(math.log(g), logs[order], np.log(array[i][order])))
                    for array in (values, self.error_gain)
                )
                ax.plot(x, y, "o", color=line.get_color(), markersize=3.5)
                labels.append((x, y, f"{g:g}", line.get_color()))
        unit = "N m/(rad/s)" if self.noise == "velocity" else "N m/rad"
        signal = "estimate" if channel == "estimate" else "command u"
        noise = "angle noise" if self.noise == "encoder" else f"{self.noise} noise"
        style_axes(
            ax,
            xlabel=f"noise gain: RMS of {signal} per unit {noise} [{unit}]",
            ylabel=f"estimation error per unit\ndisturbance at {self.frequency:g} Hz [-]",
        )
        ax.legend(loc="best", fontsize="small", ncol=2 if len(self.orders) > 4 else 1)
        ax.set_title(
            f"Accuracy against noise (labels: bandwidth [rad/s], Ts = {self.Ts:g} s)",
            fontsize="medium",
        )
        label_points(ax, labels)
        return fig


def _row_name(m: int, kind: str) -> str:
    name = {0: "DOb (m=0)", 1: "HPDOb (m=1)"}.get(m, f"order m={m}")
    return f"position-only {name}" if kind == "position" else name


def _u_noise_gain(design, nominal, Ts, controller, noise) -> float:
    """RMS of ``u`` per unit white noise in the nominal closed loop (see noise_tradeoff)."""
    position_only = design.system.measurement == "position"
    if not position_only and getattr(controller, "velocity", None) == "observer":
        controller = replace(controller, velocity="measured")  # the measured one, then
    encoder = Encoder(2**20, velocity="backward-difference") if noise == "encoder" else None
    try:
        gains = noise_gains(
            plant=nominal, nominal=nominal, Ts=Ts, controller=controller, observer=design,
            sensor=encoder,
        )  # fmt: skip
    except ParameterValueError:  # the loop is unstable: no stationary noise
        return math.nan
    return gains.u_velocity if noise == "velocity" else gains.u_position


def noise_tradeoff(
    loop=None,
    /,
    *,
    nominal: ServoModel = MISSING,
    Ts: float = MISSING,
    frequency: float,
    bandwidths,
    orders=(0, 1, 2, 3),
    noise: str = "velocity",
    gain_direction=(1.0, 1.0),
    measurements=("state",),
    family=None,
    controller: Controller | LinearController | None = MISSING,
    pole_tolerance: float | None = POLE_TOLERANCE,
    progress=None,
) -> NoiseTradeoff:
    r"""Estimation error for a sinusoidal disturbance against noise gain, per order and bandwidth.

    Parameters
    ----------
    loop : ServoLoop, optional
        A loop whose ``nominal``, ``Ts`` and ``controller`` are used (its plant, observer,
        sensor and actuator are not: the figures are of the observers on the nominal model).
        Instead of a loop, the keyword arguments ``nominal``, ``Ts`` and ``controller``
        (the loop functions' one alias, :data:`hpdob.simulation.LOOP_KEYS`).
    nominal : ServoModel
        The nominal model the observers are designed on.
    Ts : float
        Sampling period [s].
    frequency : float
        Disturbance frequency [Hz], positive and below the Nyquist frequency ``1/(2 Ts)``.
    bandwidths : array_like
        Observer bandwidths [rad/s], positive (all poles at ``exp(-g Ts)``; for position-only
        observers the velocity poles too).
    orders : sequence of int, optional
        Truncation orders, default ``(0, 1, 2, 3)``.
    noise : {"velocity", "position", "encoder"}, optional
        Measurement noise (:func:`hpdob.observer_noise_gain`). Default ``"velocity"``: with an
        encoder the differenced velocity carries noise ``sqrt(2)/Ts`` times the angle's, so it
        dominates. ``"encoder"`` (angle noise, also differenced into the velocity) compares
        both families on the same sensor.
    gain_direction : sequence of 2 floats, optional
        As for :func:`hpdob.design_observer` (observers measuring the state).
    measurements : sequence of {"state", "position"}, optional
        The paper's observer families; rows are every family with every order. Default
        ``("state",)``.
    family : str or dict, optional
        Any registered observer family (:func:`hpdob.observers.families`) instead of the
        paper's: its ``type`` name or a spec (``{"type": "eso", "form": "predictive"}``,
        its other arguments, without its order key and the bandwidth). One row per order:
        ``orders`` are the values of the family's order key (``extended_order`` for the
        ESO; a family without one takes a single order, whose value only labels the row),
        each bandwidth designs it by :func:`hpdob.observers.design_at_bandwidth` (a Kalman
        observer's process noise is chosen for it). ``measurements`` and
        ``gain_direction`` then keep their defaults; each row's measurement is the
        design's. Default None: the paper's family, as ``measurements`` and
        ``gain_direction`` say.
    controller : Controller or LinearController, optional
        Also compute the command's noise gain in the nominal closed loop (plant = nominal,
        no delay), with any controller of the protocol (:class:`~hpdob.PD`,
        :class:`~hpdob.PID`, :class:`~hpdob.FilteredPD`, :class:`~hpdob.ADRC`, a
        :class:`~hpdob.controllers.LinearController`): the measured velocity comes from the
        sensor (differenced from the angle for ``noise="encoder"``); a controller with
        ``velocity == "observer"`` takes the position-only observers' estimate, and the
        measured velocity with observers measuring the state. A NaN marks a grid point
        whose nominal loop is unstable.
    pole_tolerance : float or None, optional
        As for :func:`hpdob.design_observer` (default 0.05; the paper's family only, the one
        whose design takes it): a grid point whose design cannot be realised in double
        precision (high orders at low bandwidths) raises. ``None`` accepts every design; the
        figures are then those of the rounded gains, i.e. of the observer as it would run.
    progress : callable, optional
        Called as ``progress(done, total)`` with the grid points computed so far: once with
        ``done = 0`` before the first and then after each point (``total`` = rows x
        bandwidths). Counts only: a display with the time left (``hpdob analyze tradeoff
        --progress``) keeps its own clock. Default: silent.

    Returns
    -------
    NoiseTradeoff

    Raises
    ------
    TypeError, ValueError
        For arguments of the wrong type or value (empty grids, non-positive bandwidths, a
        frequency at or above Nyquist, a velocity noise for position-only observers, ...),
        naming the parameter.

    References
    ----------
    The accuracy/noise trade-off of higher-order DObs named in the paper's introduction;
    ``docs/analysis.md``, sections 5 and 8 (the numbers for the canonical motor).

    Examples
    --------
    >>> from hpdob import ServoModel, noise_tradeoff
    >>> t = noise_tradeoff(nominal=ServoModel(2.8e-4), Ts=1e-3, frequency=2.0,
    ...                    bandwidths=[50.0, 100.0, 200.0, 400.0], orders=(0, 1))
    >>> t.error_gain.shape
    (2, 4)
    >>> bool(t.improvement(1)[2] > 1)   # HPDOb beats a 200 rad/s DOb at its noise gain
    True
    >>> both = noise_tradeoff(nominal=ServoModel(2.8e-4), Ts=1e-3, frequency=2.0,
    ...                       bandwidths=[50.0, 100.0, 200.0, 400.0], orders=(1,),
    ...                       noise="encoder", measurements=("state", "position"))
    >>> both.measurements
    ('state', 'position')
    >>> eso = noise_tradeoff(nominal=ServoModel(2.8e-4), Ts=1e-3, frequency=2.0,
    ...                      bandwidths=[100.0, 400.0], orders=(0, 1), noise="encoder",
    ...                      family={"type": "eso", "form": "predictive"})
    >>> eso.labels
    ('ESO (m=0, predictive)', 'ESO (m=1, predictive)')
    """
    parts = loop_parts(loop, {"nominal": nominal, "Ts": Ts, "controller": controller},
                       "noise_tradeoff")  # fmt: skip
    missing = [k for k in ("nominal", "Ts") if k not in parts]
    if missing:
        raise ParameterTypeError(
            "noise_tradeoff() needs a ServoLoop as first argument, or the keyword arguments "
            f"nominal and Ts (missing: {', '.join(missing)})"
        )
    nominal, Ts, controller = parts["nominal"], parts["Ts"], parts.get("controller")
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
    check_choice(noise, "noise", OBSERVER_CHANNELS)
    if isinstance(measurements, (str, bytes)) or not hasattr(measurements, "__iter__"):
        raise ParameterTypeError(
            f"measurements must be a sequence of 'state' and/or 'position', got {measurements!r}"
        )
    kinds = tuple(check_choice(k, "measurements", MEASUREMENTS) for k in measurements)
    if not kinds or len(set(kinds)) != len(kinds):
        raise ParameterValueError(
            f"measurements must hold 'state' and/or 'position' once each, got {list(kinds)}"
        )
    spec = None if family is None else _family_spec(family, ms, kinds, gain_direction)
    if "position" in kinds and noise == "velocity" and spec is None:
        raise ParameterValueError(
            "noise must be 'position' or 'encoder' when measurements include 'position' (a "
            "position-only observer measures no velocity), got 'velocity'"
        )
    if controller is not None:
        controller_system(controller, nominal, Ts)  # refuses what is not a controller, named
    if progress is not None and not callable(progress):
        raise ParameterTypeError(
            f"progress must be a callable progress(done, total) or None, got {progress!r} of "
            f"type {type(progress).__name__}"
        )
    model = nominal.discretize(Ts)
    if spec is not None:
        design = _design(model, spec, ms[0], float(grid[0]), pole_tolerance)  # the row kind
        kinds = (design.system.measurement,)
        if kinds == ("position",) and noise == "velocity":
            raise ParameterValueError(
                f"noise must be 'position' or 'encoder' for family {spec['type']!r} (it "
                "measures the angle only, no velocity), got 'velocity'"
            )
    rows = [(m, kind) for kind in kinds for m in ms]
    total = len(rows) * grid.size
    if progress is not None:
        progress(0, total)
    err = np.empty((len(rows), grid.size))
    gain = np.empty((len(rows), grid.size))
    u_gain = None if controller is None else np.empty((len(rows), grid.size))
    for i, (m, kind) in enumerate(rows):
        for j, g in enumerate(grid):
            if spec is not None:
                design = _design(model, spec, m, g, pole_tolerance)
            elif kind == "state":
                design = design_observer(model, order=m, bandwidth=g, gain_direction=gain_direction,
                                         pole_tolerance=pole_tolerance)  # fmt: skip
            else:
                design = design_observer(model, order=m, bandwidth=g, measurement="position",
                                         pole_tolerance=pole_tolerance)  # fmt: skip
            err[i, j] = abs(estimation_response(design, f, error=True)[0])
            gain[i, j] = observer_noise_gain(design, noise=noise)
            if u_gain is not None:
                u_gain[i, j] = _u_noise_gain(design, nominal, Ts, controller, noise)
            if progress is not None:
                progress(i * grid.size + j + 1, total)
    if np.any(gain <= 0.0):
        if spec is not None:
            raise ParameterValueError(
                f"noise={noise!r} does not reach the estimate of family {spec['type']!r} "
                "(noise gain 0): choose another noise channel"
            )
        raise ParameterValueError(
            f"noise={noise!r} does not reach the estimate for gain_direction="
            f"{list(gain_direction)} (noise gain 0): choose the other noise channel"
        )
    return NoiseTradeoff(
        orders=tuple(m for m, _ in rows),
        bandwidths=readonly(grid),
        frequency=f,
        noise=noise,
        Ts=Ts,
        error_gain=readonly(err),
        noise_gain=readonly(gain),
        measurements=tuple(kind for _, kind in rows),
        u_noise_gain=None if u_gain is None else readonly(u_gain),
        family=spec,
        labels=_labels(spec, ms),
    )


def _family_spec(family, orders: tuple, kinds: tuple, gain_direction) -> dict:
    """The registered family's spec ``family`` names (a type name or a spec), checked."""
    if isinstance(family, str):
        family = {"type": family}
    if not isinstance(family, dict):
        raise ParameterTypeError(
            f"family must be a registered family's type name or a spec dict, got {family!r}"
        )
    record = get_family(family.get("type"), "family")
    set_here = sorted({record.order, "bandwidth", record.tuned, *record.set_at_bandwidth}
                      & set(family) - {None})  # fmt: skip
    if set_here:
        raise ParameterValueError(
            f"family must not give {', '.join(set_here)} (noise_tradeoff sets the order from "
            f"orders and the bandwidth from bandwidths), got {family!r}"
        )
    if kinds != ("state",):
        raise ParameterValueError(
            "measurements applies to the paper's family (family=None), not family "
            f"{record.name!r}: give its measurement in the spec, got {list(kinds)}"
        )
    if [float(v) for v in np.ravel(gain_direction)] != [1.0, 1.0]:
        raise ParameterValueError(
            "gain_direction applies to the paper's family (family=None), not family "
            f"{record.name!r}: give it in the spec, got {list(gain_direction)}"
        )
    if record.order is None and len(orders) != 1:
        raise ParameterValueError(
            f"orders must hold one value for family {record.name!r} (it has no order key), "
            f"got {list(orders)}"
        )
    spec = {**family, "type": record.name}
    order = {} if record.order is None else {record.order: orders[0]}
    check_spec({**spec, **order, record.tuned: 1.0}, "family")  # the keys, before any work
    return spec


def _with_order(spec: dict, m: int) -> dict:
    key = get_family(spec["type"], "family").order
    return dict(spec) if key is None else {**spec, key: m}


def _labels(spec: dict | None, orders: tuple) -> tuple:
    """The rows' legend names: the paper's family keeps its own however it is asked for."""
    if spec is None or spec["type"] == "dob":
        return ()
    return tuple(spec_label(_with_order(spec, m)) for m in orders)


def _design(model, spec: dict, m: int, g: float, pole_tolerance):
    """The family's design of order ``m`` at ``g`` [rad/s] (the paper's with its pole check)."""
    if spec["type"] == "dob":  # the one family whose design takes a pole tolerance
        arguments = {k: v for k, v in _with_order(spec, m).items() if k != "type"}
        return design_observer(model, **arguments, bandwidth=g, pole_tolerance=pole_tolerance)
    return design_at_bandwidth(model, _with_order(spec, m), g, "family")
