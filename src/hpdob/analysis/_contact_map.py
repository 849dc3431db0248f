r"""Stability of the force loop in contact over environment stiffness, or the nominal inertia,
and the observer bandwidth.

At every grid point the loop is held in contact (:class:`hpdob.models.InContact`: plant +
spring-damper, exact ZOH), the DOb and the reaction-torque observer (RTOB) are designed at the
bandwidth on the nominal model, the controller (e.g. :class:`hpdob.controllers.ForceControl`)
on the same nominal model, the actuator delay is kept; the spectral radius of the linear closed
loop (:func:`hpdob.closed_loop_poles`'s matrix) decides: below 1 stable, above 1 unstable.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._validation import (
    ParameterTypeError,
    ParameterValueError,
    as_grid,
    as_int,
    check_choice,
    nonnegative,
    positive,
    require_instance,
)
from ..controllers import Controller, controller_system
from ..models import Environment, InContact, ServoModel, TwoMassServo
from ..observers import (
    check_spec,
    coulomb_velocity_resolution,
    design_at_bandwidth,
    get_family,
    reaction_torque_observer,
    spec_label,
)
from ..simulation import ServoLoop
from ._linear_loop import LoopSpec, loop_matrices
from ._radius_map import _RadiusMap

__all__ = ["ContactStabilityMap", "contact_stability_map"]

#: The quantities a contact map varies along its vertical axis.
CONTACT_PARAMETERS = ("stiffness", "nominal_ratio")
#: Most grid points of one contact map.
MAX_CONTACT_POINTS = 100_000

_UNITS = {
    "stiffness": "environment stiffness k_e [N m/rad]",
    "nominal_ratio": "nominal/true inertia J_n/J [-]",
}
_RTOB_UNITS = "the RTOB's nominal/true inertia J_n/J [-]"
#: What a ``nominal_ratio`` grid varies: the nominal model of the whole loop, or the RTOB's.
NOMINAL_OF = ("loop", "reaction")
#: Whose bandwidth the map's bandwidth axis is: DOb and RTOB together, the DOb's or the RTOB's.
BANDWIDTH_OF = ("both", "dob", "reaction")
_XLABELS = {
    "both": "observer bandwidth g (DOb and RTOB) [rad/s]",
    "dob": "the DOb's bandwidth g [rad/s]",
    "reaction": "the RTOB's bandwidth g_R [rad/s]",
}


@dataclass(frozen=True, eq=False)
class _ContactSetting:
    """What a contact map holds fixed: the loop and the observers' specs (internal)."""

    loop: ServoLoop
    observer: dict
    reaction: dict | None
    viscous: float
    nominal_of: str = "loop"  # what a nominal_ratio grid varies: "loop" or "reaction"
    bandwidth_of: str = "both"  # whose bandwidth the axis is: "both", "dob" or "reaction"
    fixed_bandwidth: float | None = None  # [rad/s] the other observer's, unless "both"
    friction: object = None  # the RTOB's friction model (a ServoModel), or None
    velocity_filter: float | None = None
    coulomb_deadband: object = 0.0  # [rad/s], or "encoder": the loop's encoder's resolution

    @property
    def Ts(self) -> float:
        return self.loop.Ts

    def parts(self, parameter: str, value: float):
        """``(plant, nominal of controller and DOb, nominal of the RTOB)`` at one point."""
        plant, nominal = self.loop.plant, self.loop.nominal
        if parameter == "stiffness":
            wall = plant.environment
            plant = plant.replace(
                environment=Environment(value, damping=wall.damping, position=wall.position)
            )
            return plant, nominal, nominal
        varied = nominal.replace(J=value * plant.J)
        return plant, (nominal if self.nominal_of == "reaction" else varied), varied

    def observer_at(self, nominal: ServoModel, reaction_nominal: ServoModel, bandwidth: float):
        g_dob = self.fixed_bandwidth if self.bandwidth_of == "reaction" else bandwidth
        g_rtob = self.fixed_bandwidth if self.bandwidth_of == "dob" else bandwidth
        dob = design_at_bandwidth(nominal.discretize(self.Ts), self.observer, g_dob)
        rtob = None if self.reaction is None else design_at_bandwidth(
            reaction_nominal.discretize(self.Ts), self.reaction, g_rtob, "reaction")  # fmt: skip
        # the friction model's Coulomb term is the observer's nonlinear one: simulated by
        # loop_at, left out of the linear analysis like the plant's Coulomb friction
        friction = {"viscous": self.viscous} if self.friction is None else {
            "friction": self.friction, "velocity_filter": self.velocity_filter}  # fmt: skip
        other = self.nominal_of == "reaction"
        deadband = self.coulomb_deadband
        if isinstance(deadband, str):  # "encoder": the resolution of this point's term
            plain = reaction_torque_observer(dob, rtob, **friction, other_nominal=other)
            deadband = coulomb_velocity_resolution(
                plain, counts_per_rev=self.loop.sensor.counts_per_rev
            )
        if deadband:
            friction["coulomb_deadband"] = deadband
        return reaction_torque_observer(dob, rtob, **friction, other_nominal=other)

    def loop_at(self, parameter: str, value: float, bandwidth: float, *, bonded: bool):
        plant, nominal, reaction_nominal = self.parts(parameter, value)
        return self.loop.replace(
            plant=InContact(plant) if bonded else plant,
            nominal=nominal,
            observer=self.observer_at(nominal, reaction_nominal, bandwidth),
        )

    def radius(self, parameter: str, value: float, bandwidth: float) -> float:
        plant, nominal, reaction_nominal = self.parts(parameter, value)
        spec = LoopSpec(
            plant=InContact(plant).discretize(self.Ts),
            controller=controller_system(self.loop.controller, nominal, self.Ts),
            system=self.observer_at(nominal, reaction_nominal, bandwidth),
            backward_difference=self.loop.sensor is not None
            and self.loop.sensor.velocity == "backward-difference",
            delay=self.loop.actuator.delay_samples,
        )
        return float(np.abs(np.linalg.eigvals(loop_matrices(spec)[0])).max())

    @property
    def name(self) -> str:
        reaction = "the DOb itself" if self.reaction is None else spec_label(self.reaction)
        return f"{spec_label(self.observer)}; RTOB: {reaction}"


@dataclass(frozen=True, eq=False)
class ContactStabilityMap(_RadiusMap):
    """Spectral radius of the force loop in contact over a grid and observer bandwidths.

    Built by :func:`contact_stability_map`. ``spectral_radius[i, j]`` belongs to
    ``values[i]`` (of ``parameter``) and ``bandwidths[j]``. Arrays are read-only.

    Attributes
    ----------
    parameter : str
        ``"stiffness"`` (environment stiffness :math:`k_e` [N m/rad]) or ``"nominal_ratio"``
        (:math:`J_n/J`: the nominal inertia over the true one, of DOb, RTOB and controller or
        of the RTOB alone, see ``nominal_of``).
    values : ndarray
        Its grid (strictly increasing).
    bandwidths : ndarray
        Observer bandwidths [rad/s] (strictly increasing): of the DOb and the RTOB alike, or
        of the one ``bandwidth_of`` names.
    spectral_radius : ndarray, shape (len(values), len(bandwidths))
        Largest closed-loop eigenvalue magnitude.
    stiffness : float or None
        The fixed stiffness [N m/rad] (None when it is varied).
    nominal_ratio : float or None
        The fixed :math:`J_n/J` (None when it is varied, or for a two-mass plant).
    delay_samples : int
        Actuator delay [samples].
    observer : dict
        The DOb's family spec but the bandwidth.
    reaction : dict or None
        The RTOB's family spec but the bandwidth; None: the RTOB is the DOb itself.
    nominal_of : str
        ``"loop"`` (a ``nominal_ratio`` grid varies the nominal model of DOb, RTOB and
        controller) or ``"reaction"`` (of the RTOB alone).
    bandwidth_of : str
        ``"both"`` (``bandwidths`` are the DOb's and the RTOB's), ``"dob"`` (the DOb's, the
        RTOB at ``fixed_bandwidth``) or ``"reaction"`` (the RTOB's, the DOb at
        ``fixed_bandwidth``).
    fixed_bandwidth : float or None
        The other observer's bandwidth [rad/s]; None for ``"both"``.
    """

    parameter: str
    values: np.ndarray = field(repr=False)
    bandwidths: np.ndarray = field(repr=False)
    spectral_radius: np.ndarray = field(repr=False)
    stiffness: float | None
    nominal_ratio: float | None
    delay_samples: int
    observer: dict = field(repr=False)
    reaction: dict | None = field(repr=False)
    _setting: _ContactSetting = field(repr=False, compare=False)
    nominal_of: str = "loop"
    bandwidth_of: str = "both"
    fixed_bandwidth: float | None = None

    def _check_point(self, value, bandwidth) -> tuple[float, float]:
        if self.parameter == "stiffness":
            value = positive(value, "value", "a positive finite contact stiffness [N m/rad]")
        else:
            value = positive(value, "value", "a positive finite inertia ratio J_n/J")
        return value, positive(bandwidth, "bandwidth", "a positive observer bandwidth [rad/s]")

    def radius_at(self, value: float, bandwidth: float) -> float:
        """Spectral radius of the loop in contact at one point (need not be on the grid).

        Parameters
        ----------
        value : float
            The varied parameter: :math:`k_e` [N m/rad] or :math:`J_n/J`, positive.
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
        value, g = self._check_point(value, bandwidth)
        return self._setting.radius(self.parameter, value, g)

    def loop_at(self, value: float, bandwidth: float, *, bonded: bool = False) -> ServoLoop:
        """The loop of one point, to simulate or analyse.

        Parameters
        ----------
        value : float
            The varied parameter: :math:`k_e` [N m/rad] or :math:`J_n/J`, positive.
        bandwidth : float
            Observer bandwidth [rad/s], positive.
        bonded : bool, optional
            False (default): the plant with its unilateral environment (what
            :func:`hpdob.simulate` runs, contact lost and regained); True: the plant bonded
            to it, :class:`~hpdob.models.InContact` (the linear loop the map analyses).

        Returns
        -------
        ServoLoop
            The map's loop with this point's plant, nominal model and observers; its sensor
            and actuator (torque limit included) as given to the map.

        Raises
        ------
        ParameterTypeError, ParameterValueError
            For a value out of range.
        """
        value, g = self._check_point(value, bandwidth)
        return self._setting.loop_at(self.parameter, value, g, bonded=bool(bonded))

    def boundary(self) -> list[dict]:
        """The stability boundary, refined between grid points by Brent's method.

        Returns
        -------
        list of dict
            One entry per crossing of ``spectral_radius = 1`` along the ``values`` axis at each
            bandwidth: ``{"bandwidth": g, parameter: critical value, "kind": "upper" or
            "lower"}``; ``"upper"``: stable just below the critical value, unstable above.
        """
        from scipy.optimize import brentq

        out = []
        for j, g in enumerate(self.bandwidths):
            col = self.spectral_radius[:, j] - 1.0
            for i in np.nonzero(np.sign(col[:-1]) * np.sign(col[1:]) < 0)[0]:

                def f(x, g=float(g)):
                    return self._setting.radius(self.parameter, float(np.exp(x)), g) - 1.0

                lo, hi = np.log(self.values[i]), np.log(self.values[i + 1])
                x = brentq(f, lo, hi, xtol=1e-12, rtol=1e-10)
                out.append({"bandwidth": float(g), self.parameter: float(np.exp(x)),
                            "kind": "upper" if col[i] < 0 else "lower"})  # fmt: skip
        return out

    def limit_cycles(self, *, tau_ref: float, **options):
        """The describing-function verdict at every grid point, as a table.

        :func:`hpdob.analysis.contact_limit_cycle` of :meth:`loop_at` each point (the
        unilateral loop with the map's sensor, actuator and the RTOB's friction model).

        Parameters
        ----------
        tau_ref : float
            The force reference [N m], positive, below the torque limit.
        **options
            Passed to :func:`~hpdob.analysis.contact_limit_cycle` (``friction``,
            ``reaction_friction``, ``quantiser``, ``saturation``, ``levels``, ``smallest``).

        Returns
        -------
        pandas.DataFrame
            The columns of :meth:`to_pandas` and ``df_verdict`` (``"stable"``, ``"limit
            cycle"`` or ``"unstable"``), ``df_amplitude`` (over ``tau_ref``) and
            ``df_frequency_hz``.

        Raises
        ------
        ParameterTypeError, ParameterValueError
            As :func:`~hpdob.analysis.contact_limit_cycle`, before any point is analysed; an
            option it does not take (a ParameterTypeError naming it).

        Examples
        --------
        >>> from hpdob import Environment, ServoLoop, paper
        >>> from hpdob.analysis import contact_stability_map
        >>> from hpdob.controllers import ForceControl
        >>> from hpdob.observers import design_observer, reaction_torque_observer
        >>> dob = design_observer(paper.NOMINAL.discretize(1e-3), order=1, bandwidth=100.0)
        >>> loop = ServoLoop(plant=paper.PLANT.replace(environment=Environment(10.0)),
        ...                  nominal=paper.NOMINAL, Ts=1e-3,
        ...                  controller=ForceControl(1000.0, kv=40.0),
        ...                  observer=reaction_torque_observer(dob, friction=paper.PLANT,
        ...                                                    velocity_filter=100.0),
        ...                  sensor=paper.VIRTUAL_SENSOR, actuator=paper.VIRTUAL_ACTUATOR)
        >>> cmap = contact_stability_map(loop, stiffness=[10.0], bandwidth=[100.0],
        ...                              observer={"order": 1}, friction=paper.PLANT,
        ...                              velocity_filter=100.0)
        >>> frame = cmap.limit_cycles(tau_ref=0.05, levels=8)
        >>> from hpdob.analysis import contact_limit_cycle
        >>> point = contact_limit_cycle(cmap.loop_at(10.0, 100.0), tau_ref=0.05, levels=8)
        >>> len(frame), frame["df_verdict"].iloc[0] == point.verdict   # the point's verdict
        (1, True)
        """
        from ._describing import contact_limit_cycle

        known = ("friction", "reaction_friction", "quantiser", "saturation", "levels", "smallest")
        unknown = sorted(set(options) - set(known))
        if unknown:
            raise ParameterTypeError(
                f"limit_cycles got unknown option {unknown[0]!r}; the options are "
                f"{', '.join(known)}"
            )
        first = self.loop_at(float(self.values[0]), float(self.bandwidths[0]))
        # the checks, on a short scan (levels checked as given first, as the function does)
        if "levels" in options:
            as_int(options["levels"], "levels", "an integer number of amplitudes, at least 8",
                   minimum=8)  # fmt: skip
        contact_limit_cycle(first, tau_ref=tau_ref, **{**options, "levels": 8})
        verdicts, amplitudes, frequencies = [], [], []
        for value in self.values:
            for g in self.bandwidths:
                cycle = contact_limit_cycle(self.loop_at(float(value), float(g)),
                                            tau_ref=tau_ref, **options)  # fmt: skip
                verdicts.append(cycle.verdict)
                amplitudes.append(cycle.amplitude)
                frequencies.append(cycle.frequency)
        frame = self.to_pandas()
        frame["df_verdict"] = verdicts
        frame["df_amplitude"] = amplitudes
        frame["df_frequency_hz"] = frequencies
        return frame

    def _columns(self) -> dict:
        n_v, n_g = self.spectral_radius.shape
        fixed = "nominal_ratio" if self.parameter == "stiffness" else "stiffness"
        if self.bandwidth_of == "both":
            bandwidths = {"bandwidth_rad_s": np.tile(self.bandwidths, n_v)}
        else:  # the varied observer's bandwidth, then the other's (fixed)
            other = "reaction" if self.bandwidth_of == "dob" else "dob"
            bandwidths = {
                f"{self.bandwidth_of}_bandwidth_rad_s": np.tile(self.bandwidths, n_v),
                f"{other}_bandwidth_rad_s": np.full(n_v * n_g, self.fixed_bandwidth),
            }
        return {
            self.parameter: np.repeat(self.values, n_g),
            **bandwidths,
            fixed: np.full(n_v * n_g, getattr(self, fixed)),
            "delay_samples": np.full(n_v * n_g, self.delay_samples),
            "spectral_radius": self.spectral_radius.ravel(),
            "stable": self.stable.ravel(),
        }

    def plot(self, ax=None, *, mark=None, mark_label: str | None = None):
        r"""Heat-map of the loop's slowest decay rate with the stability boundary drawn.

        As :meth:`hpdob.StabilityMap.plot`: colour :math:`-\ln(\rho)/T_s` [1/s], black line
        :math:`\rho = 1`, the legend above the map.

        Parameters
        ----------
        ax : matplotlib Axes, optional
        mark : tuple of float, optional
            ``(bandwidth, value)`` of a design to mark with a star. Default: no mark.
        mark_label : str, optional
            Its legend entry.

        Returns
        -------
        matplotlib.figure.Figure
        """
        from ._robust_plot import plot_radius_map

        if self.parameter == "stiffness":
            fixed = [] if self.nominal_ratio is None else [f"J_n/J = {self.nominal_ratio:.3g}"]
        else:
            fixed = [f"k_e = {self.stiffness:.3g} N m/rad"]
        if self.delay_samples:
            fixed.append(f"{self.delay_samples}-sample delay")
        if self.bandwidth_of != "both":
            other = "RTOB" if self.bandwidth_of == "dob" else "DOb"
            fixed.append(f"{other} at {self.fixed_bandwidth:g} rad/s")
        return plot_radius_map(
            bandwidths=self.bandwidths,
            values=self.values,
            radius=self.spectral_radius,
            Ts=self._setting.Ts,
            ylabel=_UNITS[self.parameter] if self.nominal_of == "loop" else _RTOB_UNITS,
            title="\n".join(
                [self._setting.name, self._setting.loop.controller_system.name, ", ".join(fixed)]
            ),
            log_values=True,
            what="k_e" if self.parameter == "stiffness" else "J_n/J",
            ax=ax,
            mark=mark,
            mark_label=mark_label,
            xlabel=_XLABELS[self.bandwidth_of],
        )


def _check_loop(loop, parameter: str) -> None:
    require_instance(loop, ServoLoop, "loop")
    plant = loop.plant
    if not isinstance(plant, (ServoModel, TwoMassServo)) or plant.environment is None:
        raise ParameterValueError(
            "loop.plant must be a ServoModel or TwoMassServo with an environment (the wall the "
            f"loop presses), got {plant!r}"
        )
    if parameter == "nominal_ratio":
        if not isinstance(plant, ServoModel):
            raise ParameterValueError(
                "nominal_ratio needs a rigid plant (a ServoModel: J_n/J of one inertia), got "
                f"{type(plant).__name__}"
            )
        if not isinstance(loop.controller, Controller):
            raise ParameterTypeError(
                "nominal_ratio needs loop.controller to be a Controller (designed again on each "
                f"nominal model), got {type(loop.controller).__name__}"
            )


def contact_stability_map(
    loop: ServoLoop,
    /,
    *,
    bandwidth,
    observer: dict,
    stiffness=None,
    nominal_ratio=None,
    reaction: dict | None = None,
    viscous: float = 0.0,
    nominal_of: str = "loop",
    bandwidth_of: str = "both",
    fixed_bandwidth: float | None = None,
    friction=None,
    velocity_filter: float | None = None,
    coulomb_deadband=0.0,
    progress=None,
) -> ContactStabilityMap:
    r"""Stability of the force loop in contact over stiffness or :math:`J_n/J`, and bandwidth.

    Give a grid (a 1-D sequence) for exactly one of ``stiffness`` and ``nominal_ratio``. At
    every point the plant is bonded to its environment (:class:`~hpdob.models.InContact`,
    stiffness :math:`k_e` from the grid or the loop's environment, its damping kept), the
    nominal model is the loop's (or ``loop.nominal`` with :math:`J_n = ` ratio
    :math:`\times J`), the DOb ``observer`` and the RTOB ``reaction`` are designed at the
    bandwidth on it and composed by :func:`hpdob.observers.reaction_torque_observer`, the
    loop's controller is designed on it, and the spectral radius of the linear closed loop
    (plant + spring-damper, ZOH, DOb, RTOB, controller, the actuator's delay; Coulomb friction,
    saturation and quantisation left out) is recorded.

    Parameters
    ----------
    loop : ServoLoop
        Plant (a ServoModel or TwoMassServo with an ``environment``), nominal model, ``Ts``,
        controller (e.g. :class:`~hpdob.controllers.ForceControl`), sensor (only its velocity
        method matters) and actuator (only its delay); its observer is replaced at every point.
    bandwidth : array_like
        Observer bandwidths [rad/s], positive, strictly increasing: of the DOb and the RTOB
        alike, or of the one ``bandwidth_of`` names.
    observer : dict
        The DOb's family spec without the bandwidth, e.g. ``{"order": 1}`` (the HPDOb) or
        ``{"type": "eso", "extended_order": 1}``.
    stiffness : array_like, optional
        Environment stiffnesses :math:`k_e` [N m/rad], positive, strictly increasing.
    nominal_ratio : array_like, optional
        :math:`J_n/J`, positive, strictly increasing: above 1 the nominal inertia (of DOb,
        RTOB and controller) is over-estimated. Needs a ServoModel plant and a
        :class:`~hpdob.controllers.Controller`.
    reaction : dict, optional
        The RTOB's family spec without the bandwidth. Default None: the DOb is the RTOB.
    viscous : float, optional
        :math:`\Delta b` [N m s/rad] the RTOB subtracts (as in
        :func:`~hpdob.observers.reaction_torque_observer`). Default 0.
    friction : ServoModel, optional
        The RTOB's friction model instead of ``viscous`` (as in
        :func:`~hpdob.observers.reaction_torque_observer`: :math:`\Delta b = b - b_n` and the
        Coulomb term :math:`c_n\tanh(w/v_n)`). The Coulomb term is not linear: the map leaves
        it out, as it leaves out the plant's Coulomb friction; :meth:`~ContactStabilityMap.loop_at`
        keeps it, so the point's simulation runs the RTOB with its friction model known.
    velocity_filter : float, optional
        The Coulomb term's velocity low-pass [rad/s] (with ``friction``), as in
        :func:`~hpdob.observers.reaction_torque_observer`; its state is in the linear loop.
    coulomb_deadband : float or "encoder", optional
        The Coulomb term's dead band [rad/s] (with ``friction``), as in
        :func:`~hpdob.observers.reaction_torque_observer`; ``"encoder"``: at each point the
        velocity resolution of the term's velocity path behind the loop's encoder
        (:func:`~hpdob.observers.coulomb_velocity_resolution`; the loop needs a backward-difference
        :class:`~hpdob.Encoder`). Default 0: none. Non-linear, so the map leaves it out with
        the term; :meth:`~ContactStabilityMap.loop_at` keeps it.
    nominal_of : {"loop", "reaction"}, optional
        What a ``nominal_ratio`` grid varies: ``"loop"`` (default), the nominal model of DOb,
        RTOB and controller; ``"reaction"``, the RTOB's alone (needs ``reaction``; DOb and
        controller stay on ``loop.nominal``).
    bandwidth_of : {"both", "dob", "reaction"}, optional
        Whose bandwidth the ``bandwidth`` axis is: ``"both"`` (default: DOb and RTOB designed
        at it), ``"reaction"`` (the RTOB's own bandwidth :math:`g_R`, the DOb at
        ``fixed_bandwidth``) or ``"dob"`` (the DOb's, the RTOB at ``fixed_bandwidth``). The
        last two need a separate ``reaction`` spec.
    fixed_bandwidth : float, optional
        The bandwidth [rad/s] of the observer the axis does not vary; only with
        ``bandwidth_of="dob"`` or ``"reaction"``.
    progress : callable, optional
        Called as ``progress(done, total)``: with ``done = 0`` first, then after each row.

    Returns
    -------
    ContactStabilityMap
        With ``.stable``, ``.boundary()``, ``.loop_at()``, ``.plot()``, ``.to_pandas()`` and
        ``.to_csv()``.

    Raises
    ------
    TypeError, ValueError
        Naming the parameter: grids for both or neither of ``stiffness`` and
        ``nominal_ratio``, empty or not strictly increasing grids, non-positive values, a plant
        without an environment, a spec that does not design.

    References
    ----------
    Issue 21, section 4; ``docs/force-control.md``. Force control on the RTOB: S. Katsura,
    Y. Matsumoto, K. Ohnishi, IEEE Trans. Ind. Electron. 54(1), 2007.

    Examples
    --------
    >>> from hpdob import Environment, ServoLoop, paper
    >>> from hpdob.analysis import contact_stability_map
    >>> from hpdob.controllers import ForceControl
    >>> from hpdob.observers import design_observer, reaction_torque_observer
    >>> dob = design_observer(paper.NOMINAL.discretize(1e-3), order=1, bandwidth=100.0)
    >>> loop = ServoLoop(plant=paper.PLANT.replace(environment=Environment(10.0)),
    ...                  nominal=paper.NOMINAL, Ts=1e-3, controller=ForceControl(1000.0, kv=40.0),
    ...                  observer=reaction_torque_observer(dob), sensor=paper.VIRTUAL_SENSOR,
    ...                  actuator=paper.VIRTUAL_ACTUATOR)
    >>> cmap = contact_stability_map(loop, stiffness=[10.0, 1000.0], bandwidth=[100.0],
    ...                              observer={"order": 1})
    >>> cmap.stable[:, 0].tolist()         # the 1000 N m/rad wall is too stiff for kf = 1000
    [True, False]
    """
    if (stiffness is None) == (nominal_ratio is None):
        raise ParameterValueError(
            "give a grid for exactly one of stiffness and nominal_ratio, got "
            + ("both" if stiffness is not None else "neither")
        )
    parameter = "stiffness" if stiffness is not None else "nominal_ratio"
    _check_loop(loop, parameter)
    nominal_of = check_choice(nominal_of, "nominal_of", NOMINAL_OF)
    if nominal_of == "reaction" and (parameter != "nominal_ratio" or reaction is None):
        raise ParameterValueError(
            "nominal_of='reaction' varies the RTOB's own nominal inertia: it needs a "
            "nominal_ratio grid and a separate reaction observer spec, got "
            + ("a stiffness grid" if parameter != "nominal_ratio" else "reaction=None")
        )
    bandwidth_of = check_choice(bandwidth_of, "bandwidth_of", BANDWIDTH_OF)
    if bandwidth_of == "both":
        if fixed_bandwidth is not None:
            raise ParameterValueError(
                "fixed_bandwidth is the bandwidth of the observer the axis does not vary: give "
                f"it only with bandwidth_of='dob' or 'reaction', got {fixed_bandwidth!r}"
            )
    else:
        if reaction is None:
            raise ParameterValueError(
                f"bandwidth_of={bandwidth_of!r} varies one observer's bandwidth alone: it needs "
                "a separate reaction observer spec, got reaction=None"
            )
        fixed_bandwidth = positive(fixed_bandwidth, "fixed_bandwidth",
                                   "a positive finite observer bandwidth [rad/s]")  # fmt: skip
    if friction is None and velocity_filter is not None:
        raise ParameterValueError(
            "velocity_filter low-passes the velocity of the RTOB's Coulomb term: give it with "
            f"friction, got velocity_filter={velocity_filter!r} and friction=None"
        )
    if isinstance(coulomb_deadband, str):
        sensor = loop.sensor
        if coulomb_deadband != "encoder":
            raise ParameterValueError(
                "coulomb_deadband must be a non-negative dead band [rad/s] or 'encoder', got "
                f"{coulomb_deadband!r}"
            )
        if getattr(sensor, "velocity", None) != "backward-difference":
            raise ParameterValueError(
                "coulomb_deadband = 'encoder' needs the loop's sensor to be an encoder with "
                f"backward-difference velocity, got {sensor!r}"
            )
    elif coulomb_deadband is not None:
        coulomb_deadband = nonnegative(
            coulomb_deadband, "coulomb_deadband", "a non-negative dead band [rad/s] or 'encoder'"
        )
    if friction is None and coulomb_deadband:
        raise ParameterValueError(
            "coulomb_deadband is the dead band of the RTOB's Coulomb term: give it with "
            f"friction, got coulomb_deadband={coulomb_deadband!r} and friction=None"
        )
    if friction is not None and viscous:
        raise ParameterValueError(
            f"give the RTOB's friction as viscous or as friction, not both, got viscous={viscous!r}"
        )
    if progress is not None and not callable(progress):
        raise ParameterTypeError(
            f"progress must be a callable progress(done, total) or None, got {progress!r}"
        )
    if parameter == "stiffness":
        values = as_grid(stiffness, "stiffness", "positive contact stiffnesses [N m/rad]",
                         increasing=True)  # fmt: skip
    else:
        values = as_grid(nominal_ratio, "nominal_ratio", "positive inertia ratios J_n/J",
                         increasing=True)  # fmt: skip
    bandwidths = as_grid(bandwidth, "bandwidth", "positive observer bandwidths [rad/s]",
                         increasing=True)  # fmt: skip
    if values.size * bandwidths.size > MAX_CONTACT_POINTS:
        raise ParameterValueError(
            f"the map has {values.size} x {bandwidths.size} points; at most "
            f"{MAX_CONTACT_POINTS} are supported (use coarser grids)"
        )
    for name, spec in (("observer", observer), ("reaction", reaction)):
        if spec is None and name == "reaction":
            continue
        if not isinstance(spec, dict):
            raise ParameterTypeError(
                f"{name} must be a dict of design arguments without the bandwidth (a family "
                f"spec such as {{'order': 1}}), got {spec!r}"
            )
        family = get_family(spec.get("type", "dob"), f"{name}.type")
        check_spec({**spec, family.tuned: 1.0}, name)
        given = [k for k in family.set_at_bandwidth if k in spec]
        if given:
            raise ParameterValueError(
                f"{name} must not give {', '.join(given)}: the map designs it at every "
                f"bandwidth of its grid, got {spec!r}"
            )
    setting = _ContactSetting(
        loop=loop,
        observer=dict(observer),
        reaction=None if reaction is None else dict(reaction),
        viscous=nonnegative(viscous, "viscous", "a non-negative viscous friction [N m s/rad]"),
        nominal_of=nominal_of,
        bandwidth_of=bandwidth_of,
        fixed_bandwidth=fixed_bandwidth,
        friction=friction,
        velocity_filter=velocity_filter,
        coulomb_deadband=coulomb_deadband,
    )
    # every design of the first row (and its plant) before the grid: a bad spec fails first
    setting.radius(parameter, float(values[0]), float(bandwidths[0]))
    rho = np.empty((values.size, bandwidths.size))
    if progress is not None:
        progress(0, rho.size)
    for i, v in enumerate(values):
        for j, g in enumerate(bandwidths):
            rho[i, j] = setting.radius(parameter, float(v), float(g))
        if progress is not None:
            progress((i + 1) * bandwidths.size, rho.size)
    for array in (values, bandwidths, rho):
        array.setflags(write=False)
    wall = loop.plant.environment
    return ContactStabilityMap(
        parameter=parameter,
        values=values,
        bandwidths=bandwidths,
        spectral_radius=rho,
        stiffness=None if parameter == "stiffness" else wall.stiffness,
        nominal_ratio=None if parameter == "nominal_ratio" else _ratio(loop),
        delay_samples=loop.actuator.delay_samples,
        observer=dict(observer),
        reaction=None if reaction is None else dict(reaction),
        _setting=setting,
        nominal_of=nominal_of,
        bandwidth_of=bandwidth_of,
        fixed_bandwidth=fixed_bandwidth,
    )


def _ratio(loop) -> float | None:
    """``J_n/J`` of a rigid plant; None for a two-mass drive (no single inertia)."""
    return loop.nominal.J / loop.plant.J if isinstance(loop.plant, ServoModel) else None
