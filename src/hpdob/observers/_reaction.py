r"""The reaction-torque observer (RTOB): a disturbance observer minus a friction model."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from .._validation import ParameterTypeError, ParameterValueError, nonnegative, positive
from ._friction import CoulombFriction
from ._system import LinearObserver, _Designed, as_system

__all__ = ["FRICTION_PARAMETERS", "ReactionObserverDesign", "coulomb_velocity_resolution",
           "design_reaction_observer", "reaction_torque_observer"]  # fmt: skip

#: The friction model's parameters of a composition (:class:`ReactionObserverDesign`), with
#: their defaults: the keys of a scenario file's ``[reaction_observer]`` table besides the RTOB's
#: own design, and the sweep paths ``reaction_observer.<name>``.
FRICTION_PARAMETERS = {"viscous": 0.0, "coulomb": 0.0, "coulomb_velocity": 0.01,
                       "velocity_filter": None, "coulomb_deadband": 0.0}  # fmt: skip


@dataclass(frozen=True, eq=False)
class ReactionObserverDesign(_Designed):
    r"""The DOb and a reaction-torque observer as one design: the parts and the friction model.

    What :func:`design_reaction_observer` returns. Its :attr:`system` is
    :func:`reaction_torque_observer` of the same arguments; the parts stay readable, so a
    composition can be written back to a scenario file (``[observer]`` and
    ``[reaction_observer]``) and designed again on another nominal model or with other design
    arguments (:func:`hpdob.sweep`'s ``observer.*`` and ``reaction_observer.*`` paths).

    With ``follows_plant`` the friction model is not fixed numbers but the plant's (a scenario
    file's ``friction = "plant"``): a :class:`~hpdob.ServoLoop` given this design reads
    ``viscous``, ``coulomb`` and ``coulomb_velocity`` from its own plant
    (:meth:`with_plant_friction`), so the loop of another plant (``loop.replace(plant=...)``,
    each row of a sweep over ``plant.b``, ``plant.coulomb``, ...) subtracts that plant's
    friction, and :func:`hpdob.simulation.scenario_toml` writes ``friction = "plant"`` back.

    Attributes
    ----------
    dob : design or LinearObserver
        The inner loop's disturbance observer.
    reaction : design, LinearObserver or None
        The RTOB's own observer; None: the DOb itself (its bandwidth).
    viscous : float
        :math:`\Delta b` [N m s/rad] the RTOB subtracts.
    coulomb : float
        :math:`c_n` [N m] the RTOB subtracts (0: no Coulomb term).
    coulomb_velocity : float
        :math:`v_n` [rad/s] of the Coulomb term.
    velocity_filter : float or None
        Bandwidth [rad/s] of the low-pass on the Coulomb term's velocity, or None.
    follows_plant : bool
        True: ``viscous``, ``coulomb`` and ``coulomb_velocity`` are the loop's plant's
        (``b - b_n``, ``coulomb``, ``coulomb_velocity``), read again by every
        :class:`~hpdob.ServoLoop` it is put in; False (default): they are fixed numbers.
    coulomb_deadband : float
        :math:`d` [rad/s], the dead band on the Coulomb term's velocity (0: none).
    system : LinearObserver
        The composition (outputs ``tau_hat``, [``omega_hat``,] ``tau_reac``).
    model : DiscreteServoModel or None
        The DOb's nominal model (the RTOB's too).

    Raises
    ------
    ParameterTypeError, ParameterValueError
        As :func:`reaction_torque_observer`; ``ParameterTypeError`` if ``follows_plant`` is
        not a bool.

    Examples
    --------
    >>> from hpdob import ServoModel, design_observer
    >>> from hpdob.observers import ReactionObserverDesign
    >>> model = ServoModel(2.8e-4).discretize(1e-3)
    >>> both = ReactionObserverDesign(design_observer(model, order=1, bandwidth=100.0),
    ...                               viscous=5e-5)
    >>> both.system.outputs, both.reaction is None
    (('tau_hat', 'tau_reac'), True)
    """

    dob: object
    reaction: object = None
    viscous: float = 0.0
    coulomb: float = 0.0
    coulomb_velocity: float = 0.01
    velocity_filter: float | None = None
    follows_plant: bool = False
    coulomb_deadband: float = 0.0
    system: LinearObserver = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.follows_plant, (bool, np.bool_)):
            raise ParameterTypeError(
                f"follows_plant must be True or False, got {self.follows_plant!r} of type "
                f"{type(self.follows_plant).__name__}"
            )
        object.__setattr__(self, "follows_plant", bool(self.follows_plant))
        system = reaction_torque_observer(
            self.dob, self.reaction, viscous=self.viscous, coulomb=self.coulomb,
            coulomb_velocity=self.coulomb_velocity, velocity_filter=self.velocity_filter,
            coulomb_deadband=self.coulomb_deadband,
        )  # fmt: skip
        # the values as validated (a sweep's numpy floats and ints become floats)
        for name in ("viscous", "coulomb", "coulomb_velocity", "coulomb_deadband"):
            object.__setattr__(self, name, float(getattr(self, name)))
        if self.velocity_filter is not None:
            object.__setattr__(self, "velocity_filter", float(self.velocity_filter))
        object.__setattr__(self, "system", system)

    @property
    def model(self):
        """The DOb's nominal model (None for a DOb without one)."""
        return self.system.model

    @property
    def friction(self) -> dict:
        """The friction model as ``{name: value}``, the values at their default left out.

        Returns
        -------
        dict
            A subset of ``viscous``, ``coulomb``, ``coulomb_velocity`` (only with a Coulomb
            term), ``velocity_filter`` and ``coulomb_deadband``: the friction keys of
            ``[reaction_observer]``.
        """
        out = {}
        for name, default in FRICTION_PARAMETERS.items():
            value = getattr(self, name)
            if name == "coulomb_velocity" and not self.coulomb:
                continue  # no Coulomb term: its velocity scale is not used
            if value != default:
                out[name] = value
        return out

    def with_plant_friction(self, plant) -> ReactionObserverDesign:
        """This design with the friction model read from ``plant`` (what a loop does with a
        design that :attr:`follows_plant`).

        Parameters
        ----------
        plant : ServoModel or InContact
            The rigid plant whose friction the RTOB subtracts: ``viscous = plant.b - b_n``
            (``b_n`` of the DOb's nominal model), ``coulomb = plant.coulomb``,
            ``coulomb_velocity = plant.coulomb_velocity``; an
            :class:`~hpdob.models.InContact` of a rigid plant (what the analysis views put in
            the loop in contact) has that plant's friction.

        Returns
        -------
        ReactionObserverDesign
            ``self`` if its numbers are already the plant's, else a new design of the same
            parts, ``velocity_filter`` and ``follows_plant`` with the plant's numbers.

        Raises
        ------
        ParameterTypeError
            If ``plant`` is not a rigid :class:`~hpdob.ServoModel` (a two-mass plant has two
            friction models, the motor's and the load's).
        ParameterValueError
            If ``plant.b`` is below the nominal ``b_n``, or the composition refuses the
            numbers (a ``velocity_filter`` with ``plant.coulomb = 0``).

        Examples
        --------
        >>> from hpdob import ServoModel, design_observer
        >>> from hpdob.observers import ReactionObserverDesign
        >>> dob = design_observer(ServoModel(2.8e-4).discretize(1e-3), order=1, bandwidth=100.0)
        >>> both = ReactionObserverDesign(dob, coulomb=0.01, follows_plant=True)
        >>> both.with_plant_friction(ServoModel(3.06e-4, 5e-5, coulomb=0.02)).friction
        {'viscous': 5e-05, 'coulomb': 0.02}
        """
        from ..models import InContact

        # a plant held in contact (the analysis views' linear plant) has its plant's friction
        rigid = plant.plant if isinstance(plant, InContact) else plant
        values = _model_friction(
            rigid, self.system, "plant",
            "a rigid ServoModel for a reaction-torque observer whose friction model is the "
            "plant's (follows_plant=True; a scenario file's friction = 'plant')",
            ": the reaction-torque observer's friction model is the plant's (follows_plant=True) "
            "and subtracts the viscous friction beyond b_n",
        )  # fmt: skip
        numbers = dict(zip(("viscous", "coulomb", "coulomb_velocity"), values, strict=True))
        if all(float(getattr(self, name)) == value for name, value in numbers.items()):
            return self
        return dataclasses.replace(self, **numbers)


def design_reaction_observer(
    dob,
    reaction=None,
    *,
    viscous: float = 0.0,
    coulomb: float = 0.0,
    coulomb_velocity: float = 0.01,
    friction=None,
    velocity_filter: float | None = None,
    follows_plant: bool = False,
    coulomb_deadband: float = 0.0,
) -> ReactionObserverDesign:
    """The DOb and a reaction-torque observer as a :class:`ReactionObserverDesign`.

    The arguments are those of :func:`reaction_torque_observer` (without ``other_nominal``: the
    RTOB is designed on the DOb's nominal model); ``friction`` (a ServoModel) is read into
    ``viscous``, ``coulomb`` and ``coulomb_velocity``. With ``follows_plant=True`` (a scenario
    file's ``friction = "plant"``) ``friction`` is the loop's plant and the design remembers
    it: a loop with another plant reads that plant's friction instead
    (:meth:`ReactionObserverDesign.with_plant_friction`).

    Parameters
    ----------
    dob : design or LinearObserver
        The inner loop's disturbance observer; a design of a registered family to be written
        to a scenario file or swept.
    reaction : design or LinearObserver, optional
        The RTOB's own observer (default None: the DOb itself).
    viscous, coulomb, coulomb_velocity, friction, velocity_filter, coulomb_deadband
        The friction model, as in :func:`reaction_torque_observer`.
    follows_plant : bool, optional
        True: ``friction`` is the plant's model and follows the plant of the loop the design
        is put in (:attr:`ReactionObserverDesign.follows_plant`); needs ``friction`` given.
        Default False: the numbers are fixed.

    Returns
    -------
    ReactionObserverDesign
        ``.system`` is the composed :class:`LinearObserver`.

    Raises
    ------
    ParameterTypeError, ParameterValueError
        As :func:`reaction_torque_observer`; ``ParameterValueError`` if ``follows_plant`` is
        True without ``friction``.

    Examples
    --------
    >>> from hpdob import ServoModel, design_observer
    >>> from hpdob.observers import design_reaction_observer
    >>> model = ServoModel(2.8e-4).discretize(1e-3)
    >>> plant = ServoModel(3.06e-4, 5e-5, coulomb=0.01)
    >>> both = design_reaction_observer(design_observer(model, order=1, bandwidth=100.0),
    ...                                 friction=plant, velocity_filter=100.0)
    >>> both.friction
    {'viscous': 5e-05, 'coulomb': 0.01, 'velocity_filter': 100.0}
    >>> both.system.outputs
    ('tau_hat', 'omega_hat', 'tau_reac')
    """
    if isinstance(follows_plant, (bool, np.bool_)) and follows_plant and friction is None:
        raise ParameterValueError(
            "follows_plant = True reads the friction model from the plant: give the loop's "
            "plant as friction=plant (a ServoModel), got friction=None"
        )
    if friction is not None:
        viscous = nonnegative(
            viscous, "viscous", "a non-negative finite viscous friction [N m s/rad]"
        )
        coulomb = nonnegative(coulomb, "coulomb", "a non-negative finite Coulomb torque [N m]")
        viscous, coulomb, coulomb_velocity = _from_model(
            friction, as_system(dob, "dob"), viscous, coulomb
        )
    return ReactionObserverDesign(dob, reaction, viscous=viscous, coulomb=coulomb,
                                  coulomb_velocity=coulomb_velocity,
                                  velocity_filter=velocity_filter,
                                  follows_plant=follows_plant,
                                  coulomb_deadband=coulomb_deadband)  # fmt: skip


def reaction_torque_observer(
    dob,
    reaction=None,
    *,
    viscous: float = 0.0,
    coulomb: float = 0.0,
    coulomb_velocity: float = 0.01,
    friction=None,
    velocity_filter: float | None = None,
    coulomb_deadband: float = 0.0,
    other_nominal: bool = False,
) -> LinearObserver:
    r"""The DOb and a reaction-torque observer as one :class:`LinearObserver`.

    .. math::

        \hat\tau_{reac,k} = \hat\tau^R_k - \hat f(\omega_k),\qquad
        \hat f(\omega) = \Delta b\,\omega + c_n\tanh(\operatorname{dz}_d(w)/v_n),

    with :math:`\hat\tau^R` the disturbance estimate of ``reaction`` (an observer of any
    registered family and order on the same nominal model, with its own bandwidth) and
    :math:`\Delta b` the viscous friction beyond the nominal :math:`b_n` (:math:`b - b_n`),
    :math:`c_n\tanh(\omega/v_n)` the Coulomb friction in the plant's smooth shape
    (:meth:`hpdob.ServoModel.coulomb_torque`), read on the velocity :math:`w` (measured,
    low-passed or estimated) through an optional dead band :math:`\operatorname{dz}_d`
    (``coulomb_deadband``; none by default, :math:`\operatorname{dz}_0(w) = w`). The viscous
    part is the linear ``tau_reac`` row; the Coulomb part is not linear, so it is the
    observer's :attr:`LinearObserver.coulomb` term, subtracted after the linear outputs of
    each sample by the Python runtime, the compiled kernel and the exported C
    (``<prefix>_reaction``) alike.
    The state is the DOb's followed by the RTOB's, the outputs are the DOb's (``tau_hat``
    and, if it has one, ``omega_hat``) then ``tau_reac``: the loop compensates with
    ``tau_hat`` as before and a controller input named ``tau_reac`` reads the reaction-torque
    estimate, in :func:`hpdob.simulate`, :func:`hpdob.sweep` and the analysis views alike.

    Parameters
    ----------
    dob : observer
        The inner loop's disturbance observer (a design or a :class:`LinearObserver`).
    reaction : observer, optional
        The RTOB's observer, measuring what ``dob`` measures. Default None: ``dob`` itself
        (the DOb's bandwidth); :math:`\hat\tau^R = \hat\tau_{dn}` then, and no state is added.
    viscous : float, optional
        :math:`\Delta b` [N m s/rad], non-negative: the viscous friction the RTOB subtracts
        (``identify(...)``'s ``b`` minus the nominal ``b_n``). Default 0. The friction uses the
        measured velocity (``omega``) or, for a position-only ``reaction``, its ``omega_hat``.
    coulomb : float, optional
        :math:`c_n` [N m], non-negative: the Coulomb torque the RTOB subtracts (``identify``'s
        ``coulomb``). Default 0 (no nonlinear term). It reads the measured velocity or, for
        position-only observers, the composition's ``omega_hat`` (the DOb's).
    coulomb_velocity : float, optional
        :math:`v_n` [rad/s], positive: the smoothing's velocity scale (the plant's
        ``coulomb_velocity``). Default 0.01.
    friction : ServoModel, optional
        The friction model as a plant model, e.g. ``identify(...).model()`` or the simulated
        plant: ``viscous = friction.b - b_n`` (``b_n`` of ``dob``'s nominal model),
        ``coulomb = friction.coulomb``, ``coulomb_velocity = friction.coulomb_velocity``.
        Default None; given, ``viscous`` and ``coulomb`` must be left at 0.
    velocity_filter : float, optional
        Bandwidth :math:`\omega_f` [rad/s] of a first-order low-pass on the measured velocity
        that the Coulomb term reads instead of the velocity itself: one more state, and the
        filtered velocity as the output ``omega_hat`` (before ``tau_reac``). An encoder's
        backward-difference velocity moves in steps of one count per sample (0.38 rad/s for
        16384 counts at 1 kHz), far above a smoothing scale such as 0.01 rad/s, so
        :math:`\tanh(\omega_m/v_n)` of it averages to much less than the friction of the mean
        velocity; low-passed, it does not. Default None (the velocity as measured). Needs a
        non-zero ``coulomb``, a measured velocity and a ``dob`` without ``omega_hat``.
    coulomb_deadband : float, optional
        :math:`d` [rad/s], non-negative: a dead band on the Coulomb term's velocity,
        :math:`c_n\tanh(\operatorname{dz}_d(w)/v_n)` with :math:`\operatorname{dz}_d(w) =
        w \mp d` beyond :math:`\pm d` and 0 between (:func:`coulomb_torque`). Set it to the
        velocity resolution of the measurement path,
        :func:`coulomb_velocity_resolution` (one encoder count through the filter:
        :math:`(1 - e^{-\omega_f T_s})\,q/T_s`, 0.0365 rad/s for 16384 counts, 1 kHz and
        100 rad/s), and a single count change from rest no longer moves the term at all: the
        term answers motion the sensor resolves, not quantisation
        (``docs/force-control.md``, "The Coulomb term's dead band"). Default 0: none, the
        term as without the option, bit for bit. Needs a non-zero ``coulomb``.
    other_nominal : bool, optional
        Accept a ``reaction`` designed on another nominal model than ``dob``'s (the RTOB's own
        ``J_n/J`` study, ``contact_stability_map(..., nominal_of="reaction")``). Default
        False: refused, since ``tau^R`` of another ``J_n'`` adds ``(J - J_n') a`` to the
        estimate.

    Returns
    -------
    LinearObserver
        Outputs ``("tau_hat", ["omega_hat",] "tau_reac")``.

    Raises
    ------
    ParameterValueError
        If the observers measure different signals, were designed at different ``Ts`` or on
        different nominal models, or
        ``viscous``, ``coulomb`` or ``coulomb_deadband`` is negative; if
        ``coulomb_deadband`` is given without a Coulomb term; if no velocity is available for
        a non-zero ``viscous`` or ``coulomb``; if ``friction`` is given with ``viscous`` or
        ``coulomb``, or its ``b`` is below ``b_n``.
    ParameterTypeError
        If an argument is not an observer, or ``friction`` is not a ServoModel.

    Notes
    -----
    Without the Coulomb term the estimate keeps the plant's Coulomb torque: near rest the
    smoothed friction acts in ``tau_reac`` as a damper :math:`c/v`, which slows a force loop on
    a soft environment (``docs/force-control.md``). The analysis views (linear) see the linear
    part only, as they see the plant without its Coulomb friction.

    References
    ----------
    T. Murakami, F. Yu, K. Ohnishi, "Torque sensorless control in multidegree-of-freedom
    manipulator", IEEE Trans. Ind. Electron. 40(2), 1993.

    Examples
    --------
    >>> from hpdob import ServoModel, design_observer
    >>> from hpdob.observers import reaction_torque_observer
    >>> model = ServoModel(3.06e-4, 5e-5).discretize(1e-3)
    >>> dob = design_observer(model, order=1, bandwidth=100.0)
    >>> rtob = design_observer(model, order=0, bandwidth=200.0)
    >>> both = reaction_torque_observer(dob, rtob)
    >>> both.outputs, both.n_states
    (('tau_hat', 'tau_reac'), 3)
    >>> plant = ServoModel(3.06e-4, 5e-5, coulomb=0.01)        # the friction model known
    >>> full = reaction_torque_observer(dob, friction=plant)
    >>> full.coulomb.c, full.coulomb.v
    (0.01, 0.01)
    """
    first = as_system(dob, "dob")
    second = first if reaction is None else as_system(reaction, "reaction")
    viscous = nonnegative(viscous, "viscous", "a non-negative finite viscous friction [N m s/rad]")
    coulomb = nonnegative(coulomb, "coulomb", "a non-negative finite Coulomb torque [N m]")
    coulomb_velocity = positive(
        coulomb_velocity, "coulomb_velocity", "a positive finite velocity scale [rad/s]"
    )
    coulomb_deadband = nonnegative(
        coulomb_deadband, "coulomb_deadband", "a non-negative finite dead band [rad/s]"
    )
    if friction is not None:
        viscous, coulomb, coulomb_velocity = _from_model(friction, first, viscous, coulomb)
    if "tau_reac" in first.outputs:
        raise ParameterValueError("dob already has a tau_reac output (it is an RTOB composition)")
    if second.measures != first.measures:
        raise ParameterValueError(
            f"reaction must measure what dob measures {first.measures}, got {second.measures}"
        )
    if second.Ts != first.Ts:
        raise ParameterValueError(f"reaction.Ts = {second.Ts!r} must equal dob.Ts = {first.Ts!r}")
    if (
        not other_nominal
        and None not in (first.model, second.model)
        and second.model != first.model
    ):
        # tau_reac = tau^R - f: a J_n or b_n other than the DOb's puts (J - J_n') a into it
        raise ParameterValueError(
            f"reaction must be designed on dob's nominal model {first.model!r}, "
            f"got {second.model!r}"
        )
    n1 = first.n_states
    if reaction is None:  # one observer: tau_reac is tau_hat minus the friction
        F, G, N = first.F, first.G, first.N
        row_H, row_E = first.H[0].copy(), first.E[0].copy()
        velocity = None
        if "omega_hat" in first.outputs:
            velocity = (first.H[1], first.E[1])
    else:
        n2 = second.n_states
        F = np.block([[first.F, np.zeros((n1, n2))], [np.zeros((n2, n1)), second.F]])
        G, N = np.vstack([first.G, second.G]), np.vstack([first.N, second.N])
        row_H, row_E = np.concatenate([np.zeros(n1), second.H[0]]), second.E[0].copy()
        velocity = None
        if "omega_hat" in second.outputs:
            velocity = (np.concatenate([np.zeros(n1), second.H[1]]), second.E[1])
    if viscous:
        if "omega" in first.measures:  # the measured velocity: a feed-through
            row_E[first.measures.index("omega")] -= viscous
        elif velocity is not None:
            row_H, row_E = row_H - viscous * velocity[0], row_E - viscous * velocity[1]
        else:
            raise ParameterValueError(
                f"viscous = {viscous!r} needs a velocity: the observers measure "
                f"{first.measures} and the reaction observer has no omega_hat"
            )
    outputs = (*first.outputs, "tau_reac")
    info = [*first.info, ("reaction observer", second.name),
            ("viscous friction subtracted", f"{viscous!r} N m s/rad")]  # fmt: skip
    term = None
    if coulomb:
        source = "omega" if "omega" in first.measures else "omega_hat"
        if source not in outputs and source not in first.measures:
            raise ParameterValueError(
                f"coulomb = {coulomb!r} needs a velocity: the observers measure "
                f"{first.measures} and dob has no omega_hat"
            )
        term = CoulombFriction(coulomb, coulomb_velocity, source, coulomb_deadband)
        info.append(("Coulomb friction subtracted",
                     f"{term.c!r} N m * tanh({source} / {term.v!r} rad/s)"))  # fmt: skip
        if coulomb_deadband:
            info.append(("Coulomb dead band", f"{coulomb_deadband!r} rad/s"))
    elif coulomb_deadband:
        raise ParameterValueError(
            f"coulomb_deadband = {coulomb_deadband!r} is the Coulomb term's dead band, but "
            "coulomb is 0; leave it 0"
        )
    pad = F.shape[0] - n1
    H = np.vstack([np.hstack([first.H, np.zeros((len(first.outputs), pad))]), row_H])
    E = np.vstack([first.E, row_E])
    if velocity_filter is not None:
        F, G, H, E, N, outputs = _with_velocity_filter(
            velocity_filter, first, F, G, H, E, N, outputs, term
        )
        term = CoulombFriction(term.c, term.v, "omega_hat", term.deadband)
        info.append(("Coulomb velocity", f"omega low-passed at {velocity_filter!r} rad/s"))
    return LinearObserver(
        F=F,
        G=G,
        H=H,
        E=E,
        N=N,
        Ts=first.Ts,
        measures=first.measures,
        outputs=outputs,
        model=first.model,
        name=f"{first.name} + RTOB({second.name})",
        info=tuple(info),
        coulomb=term,
    )


def _from_model(friction, dob: LinearObserver, viscous: float, coulomb: float) -> tuple:
    """``(viscous, coulomb, coulomb_velocity)`` from a plant model of the friction."""
    from ..models import ServoModel

    if isinstance(friction, ServoModel) and (viscous or coulomb):
        raise ParameterValueError(
            f"friction is given, so viscous and coulomb must be 0, got viscous={viscous!r}, "
            f"coulomb={coulomb!r}"
        )
    return _model_friction(friction, dob, "friction",
                           "a ServoModel (e.g. identify(...).model()) or None",
                           " (the RTOB subtracts the viscous friction beyond b_n)")  # fmt: skip


def _model_friction(model, dob: LinearObserver, name: str, expected: str, why: str) -> tuple:
    """``(viscous, coulomb, coulomb_velocity)`` of the plant model ``model``: ``viscous`` the
    friction beyond the nominal ``b_n`` of ``dob``'s model. Errors name ``name``, say what was
    ``expected`` of it, and ``why`` its ``b`` must not be below ``b_n``."""
    from ..models import ServoModel

    if not isinstance(model, ServoModel):
        raise ParameterTypeError(f"{name} must be {expected}, got {type(model).__name__}")
    b_n = dob.model.b if dob.model is not None else 0.0
    if model.b < b_n:
        raise ParameterValueError(
            f"{name}.b = {model.b!r} must be at least the nominal b_n = {b_n!r}{why}"
        )
    return model.b - b_n, model.coulomb, model.coulomb_velocity


def _with_velocity_filter(bandwidth, dob: LinearObserver, F, G, H, E, N, outputs, term):
    r"""Add the Coulomb term's velocity: one state, the measured velocity low-passed,
    :math:`\hat\omega_k = a\,w_k + (1 - a)\,\omega_k`, :math:`w_{k+1} = \hat\omega_k`,
    :math:`a = e^{-\omega_f T_s}`, as the output ``omega_hat`` (before ``tau_reac``)."""
    bandwidth = positive(bandwidth, "velocity_filter", "a positive finite bandwidth [rad/s]")
    if term is None:
        raise ParameterValueError(
            f"velocity_filter = {bandwidth!r} filters the Coulomb term's velocity, but coulomb is 0"
        )
    if "omega" not in dob.measures or "omega_hat" in outputs:
        raise ParameterValueError(
            f"velocity_filter = {bandwidth!r} needs a measured velocity and no omega_hat "
            f"output (dob measures {dob.measures}, outputs {dob.outputs}); leave it None"
        )
    a = math.exp(-bandwidth * dob.Ts)
    n, j = F.shape[0], dob.measures.index("omega")
    gain = np.zeros(G.shape[1])
    gain[j] = 1.0 - a
    F = np.block([[F, np.zeros((n, 1))], [np.zeros((1, n)), np.array([[a]])]])
    G = np.vstack([G, gain])
    H = np.hstack([H, np.zeros((H.shape[0], 1))])
    H = np.vstack([H[:-1], np.concatenate([np.zeros(n), [a]]), H[-1]])
    E = np.vstack([E[:-1], gain, E[-1]])
    N = np.vstack([N, [0.0, 1.0, 0.0]])
    return F, G, H, E, N, (*outputs[:-1], "omega_hat", "tau_reac")


def coulomb_velocity_resolution(observer, *, counts_per_rev: int, samples: int = 2000) -> float:
    r"""The velocity resolution [rad/s] of an RTOB's Coulomb term behind an encoder.

    The largest :math:`|w_k|` the term's velocity shows when the encoder's count changes once,
    from rest: the angle steps by one count :math:`q = 2\pi/\text{counts}` at sample 0, its
    backward difference is :math:`q/T_s` at that sample and 0 after, and the composition's
    velocity (the measured one, its low-pass, or the observer's ``omega_hat``) answers. For
    the measured velocity it is :math:`q/T_s` (one count per sample); low-passed at
    :math:`\omega_f` it is :math:`(1 - e^{-\omega_f T_s})\,q/T_s`. A Coulomb term whose
    ``coulomb_velocity`` lies below it answers each count change with up to ``c_n``; with
    it as ``coulomb_deadband`` an isolated count change leaves the term at 0.

    Parameters
    ----------
    observer : LinearObserver or design
        An RTOB composition with a Coulomb term (:func:`reaction_torque_observer`).
    counts_per_rev : int
        The encoder's counts per revolution, positive.
    samples : int, optional
        How many samples of the response to search (default 2000).

    Returns
    -------
    float
        The resolution [rad/s].

    Raises
    ------
    ParameterValueError
        If the observer has no Coulomb term, or ``counts_per_rev`` or ``samples`` is not a
        positive integer.
    ParameterTypeError
        If ``observer`` is not an observer.

    Examples
    --------
    >>> from hpdob import paper, design_observer
    >>> from hpdob.observers import coulomb_velocity_resolution, reaction_torque_observer
    >>> dob = design_observer(paper.NOMINAL.discretize(1e-3), order=1, bandwidth=100.0)
    >>> rtob = reaction_torque_observer(dob, friction=paper.PLANT, velocity_filter=100.0)
    >>> round(coulomb_velocity_resolution(rtob, counts_per_rev=16384), 5)   # rad/s
    0.03649
    """
    from .._validation import as_int

    system = as_system(observer, "observer")
    counts = as_int(counts_per_rev, "counts_per_rev", "a positive integer count", minimum=1)
    samples = as_int(samples, "samples", "a positive integer number of samples", minimum=1)
    term = system.coulomb
    if term is None:
        raise ParameterValueError(
            f"observer {system.name!r} has no Coulomb term (coulomb = 0): it has no velocity "
            "resolution to compute"
        )
    q = 2.0 * math.pi / counts
    if term.velocity == "omega":  # the measured backward difference itself
        return q / system.Ts
    F, G, H, E = (np.asarray(m, dtype=float) for m in (system.F, system.G, system.H, system.E))
    row = system.outputs.index("omega_hat")
    x = np.zeros(F.shape[0])
    worst = 0.0
    for k in range(samples):
        u = np.zeros(G.shape[1])
        u[system.measures.index("theta")] = q
        if "omega" in system.measures and k == 0:
            u[system.measures.index("omega")] = q / system.Ts
        worst = max(worst, abs(float(H[row] @ x + E[row] @ u)))
        x = F @ x + G @ u
    return worst
