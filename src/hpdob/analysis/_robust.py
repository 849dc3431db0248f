r"""Robust stability maps: closed-loop spectral radius over model error and observer bandwidth.

The true plant differs from the nominal model in inertia (``J = J_ratio * J_n``) or in viscous
friction (``b``), optionally with an actuator delay the observer does not know; for each
observer bandwidth the linear closed loop of :func:`hpdob.closed_loop` is built and the largest
magnitude of its eigenvalues (the spectral radius) decides: below 1 stable, above 1 unstable.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .._validation import (
    ParameterTypeError,
    ParameterValueError,
    as_grid,
    as_int,
    as_real_vector,
    check_choice,
    nonnegative,
    positive,
)
from ..controllers import Controller, LinearController, controller_system
from ..models import ServoModel
from ..observers import MEASUREMENTS, design_at_bandwidth, spec_label
from ..simulation import MISSING, Encoder, ServoLoop, loop_parts
from ._linear_loop import MAX_DELAY_SAMPLES, LoopSpec, loop_matrices
from ._radius_map import _RadiusMap

__all__ = ["StabilityMap", "robust_stability_map"]

# -- checks of a map's arguments, made before any work ----------------------------------------
# Checks of a stability map's arguments made before any work: sizes, delay, plants.
#
# A map costs one closed-loop eigenvalue problem per grid point and one state per sample of
# delay, so both are bounded up front with a message that states the limit (issue 16: a
# 10^6-sample delay asked numpy for 7 TiB); a grid entry whose true plant cannot be
# discretised is named instead of failing later inside the linear algebra.

#: Most grid points (values x bandwidths) of one map.
MAX_MAP_POINTS = 1_000_000


def check_delay(delay_samples) -> int:
    """The actuator delay [samples]: an int in ``[0, MAX_DELAY_SAMPLES]``."""
    return as_int(
        delay_samples,
        "delay_samples",
        "a non-negative integer number of samples (each adds a state to the linear loop)",
        minimum=0,
        maximum=MAX_DELAY_SAMPLES,
    )


def check_map_size(values, bandwidths) -> None:
    """Refuse maps of more than :data:`MAX_MAP_POINTS` points."""
    points = values.size * bandwidths.size
    if points > MAX_MAP_POINTS:
        raise ParameterValueError(
            f"the map has {values.size} x {bandwidths.size} = {points} points; at most "
            f"{MAX_MAP_POINTS} are supported (use coarser grids)"
        )


def check_plants(values, ratio_grid: bool, ratios, frictions, nominal, Ts: float) -> None:
    """Discretise every true plant of the grid; name the entry of one that cannot be."""
    for v in values:
        J_r, b_r = (float(v), float(frictions)) if ratio_grid else (float(ratios), float(v))
        try:
            ServoModel(J_r * nominal.J, b_r).discretize(Ts)
        except ParameterValueError as err:
            raise ParameterValueError(
                f"{'J_ratio' if ratio_grid else 'b'} entry {float(v)!r} gives a true plant "
                f"ServoModel(J={J_r * nominal.J!r}, b={b_r!r}) that cannot be discretised at "
                f"Ts={Ts!r}: {err}"
            ) from None


def observer_spec(observer, measurement, gain_direction) -> tuple[dict, int]:
    """``(spec, order)`` of ``robust_stability_map(observer=...)``, validated before any work.

    The spec's keys are checked for its family (``observer.<key>``), its order is an integer,
    and what the map sets itself is refused instead of silently replaced: the family's
    ``set_at_bandwidth`` (the bandwidth or poles; for the Kalman observer the process noise,
    chosen per bandwidth), and the ``measurement``/``gain_direction`` arguments, which
    describe the paper's family only.
    """
    from ..observers import check_spec, get_family

    if not isinstance(observer, dict):
        raise ParameterTypeError(
            f"observer must be a dict of design arguments (a family spec), got {observer!r}"
        )
    family = get_family(observer.get("type", "dob"), "observer.type")
    check_spec({**observer, family.tuned: 1.0}, "observer")
    given = [k for k in family.set_at_bandwidth if k in observer]
    if given:
        raise ParameterValueError(
            f"observer must not give {', '.join(given)}: the map designs the observer at every "
            f"bandwidth of its grid, got {observer!r}"
        )
    if measurement != "state" or tuple(np.ravel(gain_direction).tolist()) != (1.0, 1.0):
        raise ParameterValueError(
            "measurement and gain_direction apply with order (the paper's family); with "
            f"observer give them in the spec, got measurement={measurement!r}, "
            f"gain_direction={gain_direction!r}"
        )
    m = 0
    if family.order is not None:
        key = family.order
        m = as_int(observer.get(key, 0), f"observer.{key}", "a non-negative integer", minimum=0)
    return dict(observer), m


PARAMETERS = ("J_ratio", "b")


def _map_spec(loop) -> dict:
    """The family spec of the loop's observer without what the map sets at each bandwidth."""
    from ..observers import get_family

    spec = loop.observer_spec
    if spec is None:
        raise ParameterValueError(
            "robust_stability_map needs order, observer (a family spec) or a loop whose "
            "observer is a spec or a design of a registered family, got "
            + ("no observer" if loop.system is None else f"observer {loop.system.name!r}")
        )
    family = get_family(spec.get("type", "dob"))
    return {k: v for k, v in spec.items() if k not in family.set_at_bandwidth}


@dataclass(frozen=True)
class _Setting:
    nominal: ServoModel
    Ts: float
    controller: LinearController  # the loop's controller, designed on nominal and Ts once
    spec: dict  # the observer family and its arguments but the bandwidth
    delay: int
    backward_difference: bool

    def radius(self, design, J_ratio: float, b: float) -> float:
        plant = ServoModel(J_ratio * self.nominal.J, b).discretize(self.Ts)
        spec = LoopSpec(
            plant=plant,
            controller=self.controller,
            system=design.system,
            backward_difference=self.backward_difference,
            delay=self.delay,
        )
        return float(np.abs(np.linalg.eigvals(loop_matrices(spec)[0])).max())

    def design(self, bandwidth: float):
        return design_at_bandwidth(self.nominal.discretize(self.Ts), self.spec, bandwidth)

    @property
    def name(self) -> str:
        return spec_label(self.spec)


@dataclass(frozen=True, eq=False)
class StabilityMap(_RadiusMap):
    """Closed-loop spectral radius over a model-error grid and observer bandwidths.

    Built by :func:`robust_stability_map`. ``spectral_radius[i, j]`` belongs to
    ``values[i]`` (of ``parameter``) and ``bandwidths[j]``. Arrays are read-only.

    Attributes
    ----------
    parameter : str
        ``"J_ratio"`` (true/nominal inertia) or ``"b"`` (true viscous friction [N m s/rad]):
        the quantity varied along the vertical axis.
    values : ndarray
        Its grid (strictly increasing).
    bandwidths : ndarray
        Observer bandwidths [rad/s] (strictly increasing).
    spectral_radius : ndarray, shape (len(values), len(bandwidths))
        Largest closed-loop eigenvalue magnitude.
    order : int
        Observer truncation order.
    J_ratio, b : float or None
        The fixed value of the parameter that is not varied (None for the varied one).
    delay_samples : int
        Actuator delay [samples] (unknown to the observer).
    measurement : str
        ``"state"`` or ``"position"``: what the observer measures.
    observer : dict
        The observer family and its design arguments but the bandwidth.
    """

    parameter: str
    values: np.ndarray = field(repr=False)
    bandwidths: np.ndarray = field(repr=False)
    spectral_radius: np.ndarray = field(repr=False)
    order: int
    J_ratio: float | None
    b: float | None
    delay_samples: int
    _setting: _Setting = field(repr=False, compare=False)
    measurement: str = "state"
    observer: dict = field(default_factory=dict, repr=False)

    def radius_at(self, value: float, bandwidth: float) -> float:
        """Spectral radius at one point (need not be on the grid).

        Parameters
        ----------
        value : float
            The varied parameter: ``J/J_n`` (positive) or ``b`` [N m s/rad] (>= 0).
        bandwidth : float
            Observer bandwidth [rad/s], positive.

        Returns
        -------
        float
            The closed loop's spectral radius (< 1: stable).

        Raises
        ------
        ParameterTypeError, ParameterValueError
            For a value out of range.
        """
        if self.parameter == "J_ratio":
            value = positive(value, "value", "a positive true/nominal inertia ratio J/J_n")
        else:
            value = nonnegative(value, "value", "a non-negative viscous friction [N m s/rad]")
        g = positive(bandwidth, "bandwidth", "a positive observer bandwidth [rad/s]")
        J_ratio, b = (value, self.b) if self.parameter == "J_ratio" else (self.J_ratio, value)
        return self._setting.radius(self._setting.design(g), J_ratio, b)

    def boundary(self) -> list[dict]:
        """The stability boundary, refined between grid points by Brent's method.

        Returns
        -------
        list of dict
            One entry per crossing of ``spectral_radius = 1`` along the ``values`` axis at each
            bandwidth: ``{"bandwidth": g, parameter: critical value, "kind": "upper" or
            "lower"}``. ``"upper"`` means stable just below the critical value and unstable
            just above; ``"lower"`` the reverse.
        """
        from scipy.optimize import brentq

        out = []
        logs = self.parameter == "J_ratio" or np.all(self.values > 0)
        for j, g in enumerate(self.bandwidths):
            design = self._setting.design(float(g))
            col = self.spectral_radius[:, j] - 1.0
            for i in np.nonzero(np.sign(col[:-1]) * np.sign(col[1:]) < 0)[0]:
                lo, hi = float(self.values[i]), float(self.values[i + 1])

                def f(x, design=design):
                    v = math.exp(x) if logs else x
                    J_ratio, b = (v, self.b) if self.parameter == "J_ratio" else (self.J_ratio, v)
                    return self._setting.radius(design, J_ratio, b) - 1.0

                a, c = (math.log(lo), math.log(hi)) if logs else (lo, hi)
                x = brentq(f, a, c, xtol=1e-13, rtol=1e-12)
                out.append(
                    {
                        "bandwidth": float(g),
                        self.parameter: math.exp(x) if logs else x,
                        "kind": "upper" if col[i] < 0 else "lower",
                    }
                )
        return out

    def _columns(self) -> dict:
        n_v, n_g = self.spectral_radius.shape
        fixed = "b" if self.parameter == "J_ratio" else "J_ratio"
        return {
            self.parameter: np.repeat(self.values, n_g),
            "bandwidth_rad_s": np.tile(self.bandwidths, n_v),
            fixed: np.full(n_v * n_g, getattr(self, fixed)),
            "order": np.full(n_v * n_g, self.order),
            "delay_samples": np.full(n_v * n_g, self.delay_samples),
            "spectral_radius": self.spectral_radius.ravel(),
            "stable": self.stable.ravel(),
        }

    def plot(self, ax=None, *, mark=None, mark_label: str | None = None):
        r"""Heat-map of the closed loop's slowest decay rate with the stability boundary drawn.

        Colour: :math:`-\ln(\rho)/T_s` [1/s] for spectral radius :math:`\rho` (blue decays,
        red grows, symmetric-log scale); black line: :math:`\rho = 1`. The legend above the
        map names the boundary and the marked design. Log axes spanning less than a decade
        (e.g. ``J/J_n`` within +-30 %) get evenly spaced, labelled ticks.

        Parameters
        ----------
        ax : matplotlib Axes, optional
        mark : tuple of float, optional
            ``(bandwidth, value)`` of a design to mark with a star: your observer bandwidth
            [rad/s] and your plant's value of the varied parameter. Default: no mark.
        mark_label : str, optional
            Its legend entry. Default: ``"design: g = <bandwidth> rad/s, <parameter> =
            <value>"``.

        Returns
        -------
        matplotlib.figure.Figure
        """
        from ._robust_plot import plot_stability_map

        return plot_stability_map(self, ax, mark=mark, mark_label=mark_label)


def _grid_or_scalar(value, name: str, what: str, *, allow_zero: bool):
    """``(array, is_grid)``: a scalar stays a 0-d value, a sequence becomes a checked grid.

    A grid must be strictly increasing: :meth:`StabilityMap.boundary` brackets each crossing
    between neighbouring grid values and names its kind from their order.
    """
    if np.ndim(value) == 0:
        check = nonnegative if allow_zero else positive
        return np.array(check(value, name, what)), False
    return as_grid(value, name, what, allow_zero=allow_zero, increasing=True), True


def robust_stability_map(
    loop=None,
    /,
    *,
    J_ratio=1.0,
    bandwidth,
    order: int | None = None,
    nominal: ServoModel = MISSING,
    Ts: float = MISSING,
    controller: Controller | LinearController = MISSING,
    b=None,
    delay_samples: int | None = None,
    gain_direction=(1.0, 1.0),
    sensor: Encoder | None = MISSING,
    measurement: str = "state",
    observer: dict | None = None,
    progress=None,
) -> StabilityMap:
    r"""Closed-loop stability over a grid of model errors and observer bandwidths.

    Give a grid (1-D sequence) for exactly one of ``J_ratio`` and ``b``; the other is held at
    its scalar value. For every grid point the true plant is ``ServoModel(J_ratio * J_n, b)``,
    the observer of ``order`` is designed at the bandwidth on ``nominal.discretize(Ts)``, and
    the spectral radius of the linear closed loop (:func:`hpdob.closed_loop_poles`, Coulomb
    friction and saturation left out) is recorded.

    Parameters
    ----------
    loop : ServoLoop, optional
        The loop: its ``nominal``, ``Ts``, ``controller``, ``sensor``, its actuator's delay and
        (unless ``order`` or ``observer`` is given) its observer's family spec; its plant is
        replaced at every grid point. Instead of a loop, its parts ``nominal``, ``Ts``,
        ``controller``, ``sensor`` and (the family spec) ``observer`` as keyword arguments
        (the loop functions' one alias rule, :data:`hpdob.simulation.LOOP_KEYS`).
    J_ratio : float or array_like, optional
        True/nominal inertia ratio(s) ``J / J_n``, positive; a grid must be strictly
        increasing. Default 1.
    bandwidth : array_like
        Observer bandwidths [rad/s], positive and strictly increasing (the horizontal axis).
    order : int, optional
        Truncation order ``m >= 0`` of the paper's family (:func:`hpdob.design_observer`);
        give ``order`` or ``observer``.
    nominal : ServoModel
        Nominal model (``J_n``, ``b_n``) of controller and observer.
    Ts : float
        Sampling period [s].
    controller : Controller or LinearController
        Any controller of the protocol (:class:`~hpdob.PD`, :class:`~hpdob.PID`,
        :class:`~hpdob.FilteredPD`, :class:`~hpdob.ADRC`, a
        :class:`~hpdob.controllers.LinearController`), designed once on ``nominal`` and
        ``Ts``; its inputs are wired as in :class:`~hpdob.ServoLoop` (checked with the first
        bandwidth's observer before the map is computed).
    b : float or array_like, optional
        True viscous friction(s) [N m s/rad], >= 0; a grid must be strictly increasing.
        Default: ``nominal.b``.
    delay_samples : int, optional
        Actuator delay [samples] the observer does not know. Default: the loop's actuator's
        (0 without a loop).
    gain_direction : sequence of 2 floats, optional
        As for :func:`hpdob.design_observer` (observers measuring the state).
    sensor : Encoder, optional
        As for :func:`hpdob.closed_loop` (only the velocity method matters).
    measurement : {"state", "position"}, optional
        Observer family (:func:`hpdob.design_observer`); position-only observers are designed
        with every pole at ``exp(-g Ts)``. Default ``"state"``. With
        ``controller.velocity == "observer"`` the PD takes the observer's velocity estimate.
    observer : dict, optional
        Any family instead of ``order``: a spec such as ``{"type": "eso", "extended_order":
        1}`` or ``{"type": "kalman", "order": 0, "position_noise_std": 1e-4}``, designed at
        every bandwidth (the Kalman observer's process noise chosen for that bandwidth by
        :func:`hpdob.observers.kalman_process_noise`). What the map sets is refused in the spec
        (``bandwidth``, ``poles``, a Kalman ``process_noise_std``), and ``measurement`` and
        ``gain_direction`` go in the spec, not beside it.
    progress : callable, optional
        Called as ``progress(done, total)`` with the grid points computed so far: once with
        ``done = 0`` before the first and then after each row of the grid (``total`` = values x
        bandwidths). Counts only: a display with the time left (``hpdob analyze stability
        --progress``) keeps its own clock. Default: silent.

    Returns
    -------
    StabilityMap
        With ``.stable``, ``.boundary()``, ``.plot()``, ``.to_pandas()`` and ``.to_csv()``.

    Raises
    ------
    TypeError, ValueError
        Naming the parameter: empty or not strictly increasing grids, non-positive ratios or
        bandwidths, negative friction, grids for both ``J_ratio`` and ``b`` (or for neither), a
        wrong order.

    References
    ----------
    The robust stability of HPDOb-based controllers, named as future work in the paper's
    conclusion; ``docs/analysis.md``, section 6.

    Examples
    --------
    >>> import numpy as np
    >>> from hpdob import PD, ServoModel, design_observer, loop_margins, robust_stability_map
    >>> nominal, pd = ServoModel(2.8e-4), PD(50, 5)
    >>> smap = robust_stability_map(J_ratio=np.geomspace(0.05, 2, 9), bandwidth=[100.0],
    ...                             order=1, nominal=nominal, Ts=1e-3, controller=pd)
    >>> bool(smap.stable[0, 0]), bool(smap.stable[-1, 0])   # J = J_n/20 unstable, 2 J_n stable
    (False, True)
    >>> edge = smap.boundary()[0]["J_ratio"]          # refined: spectral radius exactly 1
    >>> obs = design_observer(nominal.discretize(1e-3), order=1, bandwidth=100.0)
    >>> lm = loop_margins(plant=nominal, nominal=nominal, Ts=1e-3, controller=pd, observer=obs)
    >>> bool(abs(edge - 1 / lm.gain_margin) < 1e-6 * edge)  # b = 0: J/J_n = 1/gain margin
    True
    """
    legacy = {"nominal": nominal, "Ts": Ts, "controller": controller, "sensor": sensor}
    parts = loop_parts(loop, legacy, "robust_stability_map")
    missing = [k for k in ("nominal", "Ts", "controller") if k not in parts]
    if missing:
        raise ParameterTypeError(
            "robust_stability_map() needs a ServoLoop as first argument, or the keyword "
            f"arguments nominal, Ts and controller (missing: {', '.join(missing)})"
        )
    nominal, Ts, controller = parts["nominal"], parts["Ts"], parts["controller"]
    sensor = parts.get("sensor")
    if progress is not None and not callable(progress):
        raise ParameterTypeError(
            f"progress must be a callable progress(done, total) or None, got {progress!r} of "
            f"type {type(progress).__name__}"
        )
    if loop is not None:
        if delay_samples is None:
            delay_samples = loop.actuator.delay_samples
        if order is None and observer is None:
            observer = _map_spec(loop)
    delay_samples = 0 if delay_samples is None else delay_samples
    if not isinstance(nominal, ServoModel):
        raise ParameterTypeError(f"nominal must be a ServoModel, got {type(nominal).__name__}")
    if sensor is not None and not isinstance(sensor, Encoder):
        raise ParameterTypeError(f"sensor must be an Encoder or None, got {type(sensor).__name__}")
    Ts = positive(Ts, "Ts", "a positive finite sampling period [s]")
    linear_controller = controller_system(controller, nominal, Ts)  # refuses a non-controller
    if (order is None) == (observer is None):
        raise ParameterValueError(
            "give exactly one of order (the paper's family) and observer (a family spec), got "
            + ("both" if order is not None else "neither")
        )
    if observer is None:
        m = as_int(order, "order", "a non-negative integer truncation order", minimum=0)
        spec = {"order": m, "measurement": check_choice(measurement, "measurement", MEASUREMENTS)}
        if spec["measurement"] == "state":
            spec["gain_direction"] = tuple(
                as_real_vector(gain_direction, "gain_direction", "a direction vector", length=2)
            )
    else:
        spec, m = observer_spec(observer, measurement, gain_direction)
    delay = check_delay(delay_samples)
    ratios, ratio_grid = _grid_or_scalar(
        J_ratio, "J_ratio", "positive true/nominal inertia ratios J/J_n", allow_zero=False
    )
    frictions, friction_grid = _grid_or_scalar(
        nominal.b if b is None else b,
        "b",
        "non-negative true viscous frictions [N m s/rad]",
        allow_zero=True,
    )
    if ratio_grid == friction_grid:
        given = "both" if ratio_grid else "neither"
        raise ParameterValueError(
            "give a grid (a 1-D sequence) for exactly one of J_ratio and b, the other a "
            f"scalar; got {given}"
        )
    bandwidths = as_grid(
        bandwidth, "bandwidth", "positive observer bandwidths [rad/s]", increasing=True
    )
    setting = _Setting(
        nominal=nominal,
        Ts=Ts,
        controller=linear_controller,
        spec=spec,
        delay=delay,
        backward_difference=sensor is not None and sensor.velocity == "backward-difference",
    )
    values = ratios if ratio_grid else frictions
    check_map_size(values, bandwidths)
    designs = [setting.design(float(g)) for g in bandwidths]
    # the controller's inputs wired to this family's outputs, as a loop wires them (named)
    ServoLoop(plant=nominal, nominal=nominal, Ts=Ts, controller=controller, observer=designs[0],
              sensor=sensor)  # fmt: skip
    # Validate every plant before computing (ServoModel checks finiteness of J and b).
    check_plants(values, ratio_grid, ratios, frictions, nominal, Ts)
    rho = np.empty((values.size, bandwidths.size))
    if progress is not None:
        progress(0, rho.size)
    for i, v in enumerate(values):
        J_r, b_r = (float(v), float(frictions)) if ratio_grid else (float(ratios), float(v))
        for j, design in enumerate(designs):
            rho[i, j] = setting.radius(design, J_r, b_r)
        if progress is not None:
            progress((i + 1) * bandwidths.size, rho.size)
    for array in (values, bandwidths, rho):
        array.setflags(write=False)
    return StabilityMap(
        parameter="J_ratio" if ratio_grid else "b",
        values=values,
        bandwidths=bandwidths,
        spectral_radius=rho,
        order=m,
        J_ratio=None if ratio_grid else float(ratios),
        b=float(frictions) if ratio_grid else None,
        delay_samples=delay,
        _setting=setting,
        measurement=setting.spec.get("measurement", "state"),
        observer=dict(setting.spec),
    )
