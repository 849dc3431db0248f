"""The family registry: one record per observer family, read by every layer that names one.

A *spec* is a dict of a family's design arguments plus an optional ``type`` (default
``"dob"``, the paper's order-m family). The record of a family (:class:`Family`) says how to
design it from a spec, which key is its order, which parameter a bandwidth sets, how a design
turns back into its spec, its runtime class, its display name and the parameters the
command line, the scenario files and the sweeps accept. Sweeps, scenario files, the command
line (``hpdob design``, ``export-c``, ``estimate``), ``tune``, ``compare_observers`` and the
robust-stability maps read the records; a new family is one :func:`register_family` call.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

from .._validation import ParameterTypeError, ParameterValueError, check_keys

__all__ = [
    "Family",
    "Parameter",
    "check_spec",
    "design_at_bandwidth",
    "design_from_spec",
    "families",
    "family_of",
    "get_family",
    "register_family",
    "spec_label",
    "spec_of",
    "tuned_value",
    "unregister_family",
]

#: Kinds of design arguments: how the command line parses them and how a sweep checks them.
KINDS = ("int", "float", "choice", "complex_list", "float_list")


@dataclass(frozen=True)
class Parameter:
    """One design argument of a family.

    Attributes
    ----------
    name : str
        The keyword of the design function (and ``--name-with-dashes`` on the command line,
        ``observer.name`` in sweeps and scenario files).
    kind : {"int", "float", "choice", "complex_list", "float_list"}
        Its type. Integers, floats and choices can be swept; the lists (poles, directions)
        cannot.
    help : str
        One line for ``--help`` and the docs' tables (with the unit).
    choices : tuple of str
        The values of a ``"choice"``.
    only_with : tuple, optional
        ``(key, value)``: the argument applies only when the spec's ``key`` is ``value``
        (``velocity_bandwidth`` with ``measurement="position"``).
    default : optional
        The design function's default where a spec leaves it out (None: none, or not
        needed by any layer).
    """

    name: str
    kind: str = "float"
    help: str = ""
    choices: tuple = ()
    only_with: tuple | None = None
    default: object = None

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ParameterValueError(
                f"Parameter.kind must be one of {', '.join(map(repr, KINDS))}, got {self.kind!r}"
            )
        if (self.kind == "choice") != bool(self.choices):
            raise ParameterValueError(
                f"Parameter {self.name!r}: choices go with kind 'choice' only, got "
                f"kind={self.kind!r}, choices={self.choices!r}"
            )

    @property
    def sweepable(self) -> bool:
        """Whether a sweep can vary it (a number or a name, not a list)."""
        return self.kind in ("int", "float", "choice")


def _bandwidth_itself(model, arguments: dict, bandwidth: float) -> float:
    return bandwidth


@dataclass(frozen=True, eq=False)
class Family:
    """The record of one observer family (see :func:`register_family`).

    Attributes
    ----------
    name : str
        The spec's ``type`` (``"dob"``, ``"eso"``, ``"kalman"``, ...).
    design : callable
        ``design(model, **arguments)`` on a :class:`~hpdob.DiscreteServoModel`; returns a
        design whose ``.system`` is a :class:`~hpdob.observers.LinearObserver`.
    parameters : tuple of Parameter
        Every argument ``design`` takes besides the model.
    required : tuple of str
        The arguments a spec must give.
    order : str or None
        The key of the family's order (``"order"``, ``"extended_order"``), None if it has
        none.
    tuned : str
        The argument a bandwidth sets (``"bandwidth"``, or the Kalman observer's
        ``"process_noise_std"``): what the maps, the comparison and the tuner vary.
    tuned_from_bandwidth : callable, optional
        ``f(model, arguments, bandwidth) -> value`` of ``tuned`` giving that bandwidth [rad/s].
        Default: the bandwidth itself.
    replaced_by_bandwidth : tuple of str
        Other arguments a design at a bandwidth drops (``poles``).
    noise_parameter : str, optional
        The argument set from the sensor's angle noise std [rad] (the Kalman observer's
        ``position_noise_std``) by the comparison and the tuner.
    designs : tuple of type
        The design classes ``design`` returns (to find a design's family).
    spec_of : callable, optional
        ``spec_of(design) -> dict`` of its arguments: the round trip
        ``design_from_spec(model, spec_of(d))`` designs ``d`` again.
    runtime : callable, optional
        ``runtime(design, x0, tau0)``: the stateful runtime object (default
        :class:`~hpdob.observers.Observer`).
    label : callable
        ``label(spec) -> str``: the display name of a spec (``"HPDOb (m=1)"``).
    title : str
        One line naming the family (``--help``, the docs).
    variants : mapping of str to dict
        The tuner's candidate families: name -> spec (without ``type``, order or tuned
        argument). Default ``{name: {}}``.
    orders : tuple of int
        The orders the tuner searches.
    compared : mapping of str to dict
        The default candidates of :func:`hpdob.compare_observers`: display name -> spec
        (without ``type`` and the tuned argument).
    defaults : mapping of str to value
        What the command line uses for arguments it is not given (``{"order": 1}``: the
        HPDOb).
    tuned_range : callable, optional
        ``f(model, arguments) -> (low, high)`` of ``tuned`` searched by the comparison.
        Default: bandwidths 0.5 rad/s to ``min(1400, 0.45 pi/Ts)`` rad/s.
    respec : callable, optional
        ``respec(spec, varied, base_spec) -> spec``: a sweep's redesign when the keys
        ``varied`` change (drop what no longer applies), after ``replaced_by_bandwidth`` is
        dropped where ``tuned`` varies.
    """

    name: str
    design: Callable
    parameters: tuple
    required: tuple = ()
    order: str | None = "order"
    tuned: str = "bandwidth"
    tuned_from_bandwidth: Callable | None = None
    replaced_by_bandwidth: tuple = ()
    noise_parameter: str | None = None
    designs: tuple = ()
    spec_of: Callable | None = None
    runtime: Callable | None = None
    label: Callable | None = None
    title: str = ""
    variants: Mapping | None = None
    orders: tuple = (0, 1, 2)
    compared: Mapping = field(default_factory=dict)
    defaults: Mapping = field(default_factory=dict)
    tuned_range: Callable | None = None
    respec: Callable | None = None

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ParameterValueError(f"Family.name must be an identifier, got {self.name!r}")
        if not callable(self.design):
            raise ParameterTypeError(f"Family.design must be callable, got {self.design!r}")
        params = tuple(self.parameters)
        if not all(isinstance(p, Parameter) for p in params):
            raise ParameterTypeError(
                f"Family.parameters must be Parameter records, got {self.parameters!r}"
            )
        object.__setattr__(self, "parameters", params)
        names = self.keys
        for what, keys in (("required", self.required), ("replaced_by_bandwidth",
                           self.replaced_by_bandwidth)):  # fmt: skip
            unknown = [k for k in keys if k not in names]
            if unknown:
                raise ParameterValueError(
                    f"Family {self.name!r}: {what} names {unknown[0]!r}, not a parameter "
                    f"(parameters: {', '.join(names)})"
                )
        for what in ("order", "noise_parameter"):
            key = getattr(self, what)
            if key is not None and key not in names:
                raise ParameterValueError(
                    f"Family {self.name!r}: {what} {key!r} is not a parameter ({', '.join(names)})"
                )
        if self.tuned not in names:
            raise ParameterValueError(
                f"Family {self.name!r}: tuned {self.tuned!r} is not a parameter "
                f"({', '.join(names)})"
            )
        object.__setattr__(self, "required", tuple(self.required))
        if self.variants is None:
            object.__setattr__(self, "variants", {self.name: {}})

    @property
    def keys(self) -> tuple:
        """The parameter names, in order."""
        return tuple(p.name for p in self.parameters)

    def parameter(self, name: str) -> Parameter:
        """The :class:`Parameter` called ``name``.

        Parameters
        ----------
        name : str

        Returns
        -------
        Parameter

        Raises
        ------
        KeyError
            If the family has no such parameter.
        """
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(name)

    @property
    def set_at_bandwidth(self) -> tuple:
        """What a design at a bandwidth sets itself, so a spec for one must leave it out."""
        return (self.tuned, *self.replaced_by_bandwidth)

    def display(self, spec: dict) -> str:
        """The display name of a spec of this family.

        Parameters
        ----------
        spec : dict

        Returns
        -------
        str
        """
        return self.label(spec) if self.label is not None else f"{self.name} {spec!r}"


_REGISTRY: dict[str, Family] = {}


def register_family(family: Family, *, replace: bool = False) -> Family:
    """Register an observer family for every layer that designs observers by name.

    After it, specs ``{"type": family.name, ...}`` work in :func:`hpdob.sweep` (with the
    sweep paths ``observer.<parameter>``), TOML scenario files (``[observer] type = ...``),
    ``hpdob design``/``export-c``/``estimate`` (``--type name`` and one option per
    parameter), :func:`hpdob.tune` (its ``variants``), :func:`hpdob.compare_observers` (its
    ``compared`` candidates) and :func:`hpdob.robust_stability_map`.

    Parameters
    ----------
    family : Family
        The record.
    replace : bool, optional
        Allow replacing a family of the same name. Default False.

    Returns
    -------
    Family
        ``family``.

    Raises
    ------
    TypeError
        If ``family`` is not a :class:`Family`.
    ValueError
        If the name is taken (and not ``replace``), or a parameter shared with another
        family has another kind there (the command line has one option per name).

    Examples
    --------
    >>> from hpdob.observers import Family, Parameter, design_eso, register_family
    >>> from hpdob.observers import families, unregister_family
    >>> eso2 = Family("eso_fixed", lambda model, bandwidth: design_eso(model,
    ...               bandwidth=bandwidth, extended_order=2), (Parameter("bandwidth"),),
    ...               required=("bandwidth",), order=None, label=lambda spec: "GESO m=2")
    >>> _ = register_family(eso2)
    >>> "eso_fixed" in [f.name for f in families()]
    True
    >>> unregister_family("eso_fixed")
    """
    if not isinstance(family, Family):
        raise ParameterTypeError(f"family must be a Family, got {type(family).__name__}")
    if family.name in _REGISTRY and not replace:
        raise ParameterValueError(
            f"family {family.name!r} is already registered (pass replace=True to replace it)"
        )
    for other in _REGISTRY.values():
        if other.name == family.name:
            continue
        for p in family.parameters:
            if p.name in other.keys and other.parameter(p.name).kind != p.kind:
                raise ParameterValueError(
                    f"family {family.name!r}: parameter {p.name!r} is a {p.kind!r}, but a "
                    f"{other.parameter(p.name).kind!r} in family {other.name!r}"
                )
    _REGISTRY[family.name] = family
    return family


def unregister_family(name: str) -> None:
    """Remove the family ``name`` (see :func:`register_family`).

    Parameters
    ----------
    name : str

    Raises
    ------
    ValueError
        If no family of that name is registered.
    """
    if name not in _REGISTRY:
        raise ParameterValueError(f"no family {name!r} is registered ({', '.join(_REGISTRY)})")
    del _REGISTRY[name]


def families() -> tuple:
    """The registered families, in registration order.

    Returns
    -------
    tuple of Family
    """
    return tuple(_REGISTRY.values())


def get_family(name, where: str = "observer.type") -> Family:
    """The family registered as ``name``.

    Parameters
    ----------
    name : str
    where : str, optional
        How the caller names it in the error message.

    Returns
    -------
    Family

    Raises
    ------
    ValueError
        If there is none.
    """
    if not isinstance(name, str) or name not in _REGISTRY:
        raise ParameterValueError(
            f"{where} must be one of {', '.join(repr(k) for k in _REGISTRY)}; got {name!r}"
        )
    return _REGISTRY[name]


def _family(spec: dict, where: str) -> Family:
    return get_family(spec.get("type", "dob"), f"{where}.type")


def check_spec(spec, where: str = "observer", *, owner: str | None = None) -> dict:
    """``spec`` validated for its keys (not its values); returns a copy.

    Parameters
    ----------
    spec : dict
        ``{"type": name, argument: value, ...}``.
    where : str, optional
        Unknown keys are reported as ``<where>.<key>``.
    owner : str, optional
        A missing key is reported against it (default ``where``).

    Returns
    -------
    dict

    Raises
    ------
    TypeError, ValueError
        For a non-dict, an unknown family or key, a missing required key.
    """
    owner = owner or where
    if not isinstance(spec, dict):
        raise ParameterTypeError(f"{owner} must be a dict of design arguments, got {spec!r}")
    family = _family(spec, where)
    check_keys(spec, (*family.keys, "type"), where)
    missing = [k for k in family.required if k not in spec]
    if missing:
        raise ParameterValueError(
            f"{owner} must have the required key {missing[0]!r} (keys: "
            f"{', '.join(family.keys)}), got {spec!r}"
        )
    return dict(spec)


def design_from_spec(model, spec: dict, where: str = "observer"):
    """Design the observer ``spec`` describes on the nominal discrete ``model``.

    Parameters
    ----------
    model : DiscreteServoModel
    spec : dict
    where : str, optional
        How errors name the spec.

    Returns
    -------
    design
        What the family's design function returns.

    Raises
    ------
    TypeError, ValueError
        As :func:`check_spec` and the family's design function.

    Examples
    --------
    >>> from hpdob import ServoModel
    >>> from hpdob.observers import design_from_spec
    >>> d = design_from_spec(ServoModel(2.8e-4).discretize(1e-3), {"type": "eso",
    ...                      "bandwidth": 200.0, "extended_order": 1})
    >>> d.extended_order
    1
    """
    spec = check_spec(spec, where)
    arguments = {k: v for k, v in spec.items() if k != "type"}
    return _family(spec, where).design(model, **arguments)


def family_of(observer) -> Family | None:
    """The registered family of a design (or of a runtime object holding one).

    Parameters
    ----------
    observer : design or runtime object

    Returns
    -------
    Family or None
        None for an observer of no registered family.
    """
    for candidate in (observer, getattr(observer, "design", None)):
        if candidate is None:
            continue
        for family in _REGISTRY.values():
            if family.designs and isinstance(candidate, family.designs):
                return family
    return None


def spec_of(observer) -> dict | None:
    """The spec of a design of a registered family (None for any other observer).

    Parameters
    ----------
    observer : design or runtime object

    Returns
    -------
    dict or None
        ``{"type": name, **arguments}``; ``design_from_spec(observer.model, spec)`` designs
        the same observer.
    """
    family = family_of(observer)
    if family is None or family.spec_of is None:
        return None
    design = observer if isinstance(observer, family.designs) else observer.design
    return {"type": family.name, **family.spec_of(design)}


def spec_label(spec: dict) -> str:
    """The display name of ``spec`` (its family's ``label``).

    Parameters
    ----------
    spec : dict

    Returns
    -------
    str
    """
    return _family(spec, "observer").display(spec)


def design_at_bandwidth(model, spec: dict, bandwidth: float, where: str = "observer"):
    """Design ``spec``'s family at ``bandwidth`` [rad/s] (what robust-stability maps, the
    comparison and the tuner sweep over).

    The family's ``tuned`` argument is set for the bandwidth (the bandwidth itself, or, for
    the Kalman observer, the process noise giving it, :func:`kalman_process_noise`); its
    ``replaced_by_bandwidth`` arguments (``poles``) are dropped.

    Parameters
    ----------
    model : DiscreteServoModel
    spec : dict
        The family and its other arguments.
    bandwidth : float
        [rad/s].
    where : str, optional
        How errors name the spec.

    Returns
    -------
    design

    Raises
    ------
    TypeError, ValueError
        As :func:`design_from_spec`.
    """
    if not isinstance(spec, dict):
        raise ParameterTypeError(f"{where} must be a dict of design arguments, got {spec!r}")
    family = _family(spec, where)
    arguments = {k: v for k, v in spec.items() if k not in ("type", *family.set_at_bandwidth)}
    check_spec({**spec, family.tuned: 1.0}, where)  # the keys, with the tuned one supplied
    rule = family.tuned_from_bandwidth or _bandwidth_itself
    arguments[family.tuned] = rule(model, arguments, bandwidth)
    return family.design(model, **arguments)


def tuned_value(model, spec: dict, bandwidth: float) -> float:
    """The value of ``spec``'s tuned argument that gives ``bandwidth`` [rad/s].

    Parameters
    ----------
    model : DiscreteServoModel
    spec : dict
    bandwidth : float
        [rad/s].

    Returns
    -------
    float
        The bandwidth itself, or the family's ``tuned_from_bandwidth`` of it.
    """
    family = _family(spec, "observer")
    arguments = {k: v for k, v in spec.items() if k not in ("type", *family.set_at_bandwidth)}
    return (family.tuned_from_bandwidth or _bandwidth_itself)(model, arguments, bandwidth)
