"""What a sweep varies: the parameter paths, the distributions, and the scenario list."""

from __future__ import annotations

import itertools
import math

import numpy as np

from .._validation import ParameterTypeError, ParameterValueError, as_int, as_real, check_choice

__all__ = [
    "DISTRIBUTIONS",
    "MAX_SCENARIOS",
    "NOMINAL_PATHS",
    "PLANT_PATHS",
    "RUN_PATHS",
    "check_paths_apply",
    "controller_parameters",
    "expand_scenarios",
    "replaced_plant",
    "sweep_paths",
]

#: Most scenarios one sweep may expand to (rows and draws are held in memory): checked up front.
MAX_SCENARIOS = 1_000_000

#: The plant's parameters a sweep can vary (dotted paths into :func:`hpdob.simulate`'s
#: arguments; :func:`check_paths_apply` refuses those the base's plant does not have).
PLANT_PATHS = (
    "plant.J", "plant.b", "plant.coulomb", "plant.coulomb_velocity",
    "plant.link_mass", "plant.link_length",
    "plant.J_motor", "plant.J_load", "plant.stiffness", "plant.damping",
    "plant.b_motor", "plant.b_load",
    "plant.environment.stiffness", "plant.environment.damping", "plant.environment.position",
)  # fmt: skip
#: The friction parameters of a reaction-torque observer composition read from the plant when
#: it follows the plant (``friction = "plant"``), and the plant parameter each follows.
PLANT_FRICTION = {"viscous": "b", "coulomb": "coulomb", "coulomb_velocity": "coulomb_velocity"}
#: The nominal model's, and the run's own.
NOMINAL_PATHS, RUN_PATHS = ("nominal.J", "nominal.b"), ("Ts", "disturbance_scale")


def controller_parameters() -> tuple:
    """``controller.<name>`` for every real-valued constructor argument of the controller
    types (:data:`hpdob.controllers.CONTROLLER_TYPES`, the first type to name it first): each
    is rebuilt through its constructor, so a new controller type's gains are sweep paths."""
    import dataclasses

    from ..controllers import CONTROLLER_TYPES

    out: dict = {}
    for controller in CONTROLLER_TYPES.values():
        for f in dataclasses.fields(controller):
            if f.init and str(f.type).startswith("float"):  # not its flags and names
                out.setdefault(f"controller.{f.name}")
    return tuple(out)


def observer_parameters() -> dict:
    """``{"observer.<name>": Parameter}``: every sweepable design argument of every
    registered family (:func:`hpdob.observers.families`; the first family to name it wins,
    registration checks that the kinds agree)."""
    from ..observers import families

    out = {}
    for family in families():
        for p in family.parameters:
            if p.sweepable:
                out.setdefault(f"observer.{p.name}", p)
    return out


def reaction_parameters() -> dict:
    """``{"reaction_observer.<name>": Parameter}``: the friction model of a reaction-torque
    observer composition (:data:`hpdob.observers.FRICTION_PARAMETERS`) and the RTOB's own
    design arguments (every sweepable argument of every registered family, as
    :func:`observer_parameters`)."""
    from ..observers import FRICTION_PARAMETERS, Parameter

    friction = {f"reaction_observer.{name}": Parameter(name) for name in FRICTION_PARAMETERS}
    own = {f"reaction_{path}": p for path, p in observer_parameters().items()}
    return {**friction, **own}


def design_parameter(path: str):
    """The :class:`~hpdob.observers.Parameter` of an ``observer.*`` or ``reaction_observer.*``
    path (None for the loop's paths)."""
    return {**observer_parameters(), **reaction_parameters()}.get(path)


def sweep_paths() -> tuple:
    """Every path a sweep can vary: the loop's, the registered families' parameters and those
    of a reaction-torque observer composition."""
    return (*PLANT_PATHS, *observer_parameters(), *reaction_parameters(), *NOMINAL_PATHS,
            *controller_parameters(), *RUN_PATHS)  # fmt: skip


#: Random distributions for ``vary``: name -> meaning of its two parameters.
DISTRIBUTIONS = {
    "uniform": "low, high",
    "normal": "mean, standard deviation",
    "loguniform": "low, high (0 < low)",
}


def _check_path(path, where: str) -> str:
    paths = sweep_paths()
    if path not in paths:
        raise ParameterValueError(
            f"{where} path {path!r} is not a sweep parameter; valid paths: {', '.join(paths)}"
        )
    return path


def _grid_values(path: str, values) -> list:
    if isinstance(values, (str, bytes)) or not hasattr(values, "__iter__"):
        raise ParameterTypeError(f"grid[{path!r}] must be a list of values, got {values!r}")
    values = list(values)
    if not values:
        raise ParameterValueError(f"grid[{path!r}] must be a non-empty list of values, got []")
    parameter = design_parameter(path)
    if parameter is not None and parameter.kind == "int":
        return [
            as_int(
                v, f"grid[{path!r}] entry", f"a non-negative integer {parameter.name}", minimum=0
            )
            for v in values
        ]
    if parameter is not None and parameter.kind == "choice":
        return [check_choice(v, f"grid[{path!r}] entry", parameter.choices) for v in values]
    return [as_real(v, f"grid[{path!r}] entry", "a finite number") for v in values]


def _draw(path: str, spec, n: int, rng: np.random.Generator) -> np.ndarray:
    parameter = design_parameter(path)
    if parameter is not None and parameter.kind in ("int", "choice"):
        kind = "an integer" if parameter.kind == "int" else "a name"
        raise ParameterValueError(f"vary cannot draw {path!r} ({kind}): put it in grid")
    if not isinstance(spec, (tuple, list)) or len(spec) != 3 or spec[0] not in DISTRIBUTIONS:
        listed = "; ".join(f"({name!r}, {args})" for name, args in DISTRIBUTIONS.items())
        raise ParameterValueError(f"vary[{path!r}] must be one of {listed}; got {spec!r}")
    name = spec[0]
    a = as_real(spec[1], f"vary[{path!r}] first parameter", "a finite number")
    b = as_real(spec[2], f"vary[{path!r}] second parameter", "a finite number")
    if name == "uniform":
        if not a < b:
            raise ParameterValueError(f"vary[{path!r}] uniform needs low < high, got {spec!r}")
        return rng.uniform(a, b, n)
    if name == "normal":
        if not b > 0:
            raise ParameterValueError(
                f"vary[{path!r}] normal needs a positive standard deviation, got {spec!r}"
            )
        return rng.normal(a, b, n)
    if not 0 < a < b:
        raise ParameterValueError(f"vary[{path!r}] loguniform needs 0 < low < high, got {spec!r}")
    return np.exp(rng.uniform(math.log(a), math.log(b), n))


def expand_scenarios(grid=None, vary=None, n=None, seed=0) -> list[dict]:
    """The sweep's scenarios: one ``{path: value}`` dict each, in a fixed order.

    The Cartesian product of ``grid`` (in its key order); for each grid point, ``n`` random
    draws of the ``vary`` parameters. All draws come from ``numpy.random.default_rng(seed)``,
    path by path in sorted order, before anything runs, so the same arguments give the same
    scenarios wherever they are executed.
    """
    grid = {} if grid is None else grid
    vary = {} if vary is None else vary
    if not isinstance(grid, dict):
        raise ParameterTypeError(f"grid must be a dict of path -> list, got {grid!r}")
    if not isinstance(vary, dict):
        raise ParameterTypeError(
            f"vary must be a dict of path -> (distribution, a, b), got {vary!r}"
        )
    for path in grid:
        _check_path(path, "grid")
    for path in vary:
        _check_path(path, "vary")
        if path in grid:
            raise ParameterValueError(f"path {path!r} is in both grid and vary; give it once")
    if vary and n is None:
        raise ParameterValueError("n (the number of random draws) is required with vary")
    if n is not None:
        n = as_int(n, "n", "a positive integer number of draws", minimum=1)
        if not vary:
            raise ParameterValueError(
                f"n={n} needs vary (random parameters); without vary use grid alone"
            )
    seed = as_int(seed, "seed", "a non-negative integer seed", minimum=0)
    axes = {path: _grid_values(path, values) for path, values in grid.items()}
    count = math.prod(len(values) for values in axes.values()) * (n or 1)
    if count > MAX_SCENARIOS:
        sizes = " x ".join([str(len(v)) for v in axes.values()] + ([f"n={n}"] if n else []))
        raise ParameterValueError(
            f"the sweep has {sizes} = {count} scenarios; at most {MAX_SCENARIOS} are "
            f"supported per sweep (split it into several sweeps)"
        )
    rng = np.random.default_rng(seed)
    draws = {path: _draw(path, vary[path], n, rng) for path in sorted(vary)}
    scenarios = []
    for point in itertools.product(*axes.values()):
        fixed = dict(zip(axes, point, strict=True))
        for i in range(n or 1):
            scenarios.append({**fixed, **{path: float(v[i]) for path, v in draws.items()}})
    return scenarios


def replaced_plant(plant, changes: dict):
    """``plant.replace(**changes)``, with ``environment.*`` keys applied to its environment
    (:func:`check_paths_apply` made sure the base plant has one)."""
    changes = dict(changes)
    contact = {key[len("environment.") :]: changes.pop(key) for key in list(changes)
               if key.startswith("environment.")}  # fmt: skip
    if contact:
        changes["environment"] = plant.environment.replace(**contact)
    return plant.replace(**changes)


def _replaceable(model) -> set:
    """The parameters ``model.replace`` accepts (a MujocoServo says; dataclasses by fields)."""
    import dataclasses

    if hasattr(model, "_replaceable"):
        return set(model._replaceable())
    return {f.name for f in dataclasses.fields(model) if f.init and f.name != "_"}


def check_paths_apply(paths, loop, spec) -> None:
    """Refuse, before any scenario runs, a path that could not apply to any scenario of this
    base: a plant parameter the plant does not have (``plant.J`` of a :class:`TwoMassServo`,
    ``plant.stiffness`` of a rigid servo), a design argument the observer's family does not
    take (``observer.bandwidth`` of a Kalman spec, ``observer.order`` of an ESO), or
    ``observer.velocity_bandwidth`` of an observer that measures the state, or
    ``reaction_observer.*`` of a base without a reaction-torque observer composition. With
    such a composition (:class:`~hpdob.observers.ReactionObserverDesign`) ``observer.*`` is
    the DOb's design and ``reaction_observer.*`` the friction model or the RTOB's own design
    (the DOb's family when the RTOB is the DOb itself); a friction model that follows the
    plant (``friction = "plant"``) takes its numbers from the plant, so only its
    ``velocity_filter`` is a ``reaction_observer.*`` path. (Bad *values* are reported per
    scenario, in the ``error`` column.)"""
    from ..observers import FRICTION_PARAMETERS, ReactionObserverDesign, spec_of

    paths = list(paths)
    composition = loop.design if isinstance(loop.design, ReactionObserverDesign) else None
    specs = {"observer": spec, "reaction_observer": None}
    if composition is not None:
        specs["observer"] = spec_of(composition.dob)
        own = composition.reaction
        specs["reaction_observer"] = specs["observer"] if own is None else spec_of(own)
    for path in paths:
        kind, _, name = path.partition(".")
        why = None
        if kind in ("plant", "nominal"):
            model = loop.plant if kind == "plant" else loop.nominal
            valid = _replaceable(model)
            if name.startswith("environment."):
                if getattr(model, "environment", None) is None:
                    why = (
                        f"the {kind} ({type(model).__name__}) has no environment to vary (give "
                        f"the base plant one: environment=Environment(...) or "
                        f"[plant.environment])"
                    )
            elif name not in valid:
                why = (
                    f"a {type(model).__name__} has no parameter {name!r} (it has "
                    f"{', '.join(sorted(valid))})"
                )
        elif kind == "controller":
            controller = loop.controller
            import dataclasses

            valid = (
                {f.name for f in dataclasses.fields(controller) if f.init and f.name != "_"}
                if dataclasses.is_dataclass(controller)
                else set()
            )
            if name not in valid:
                why = f"a {type(controller).__name__} has no parameter {name!r}" + (
                    f" (it has {', '.join(sorted(valid))})" if valid else ""
                )
        elif kind == "reaction_observer" and composition is None:
            why = (
                "the base has no reaction-torque observer composition (a [reaction_observer] "
                "table, or observer=design_reaction_observer(...))"
            )
        elif (kind == "reaction_observer" and composition.follows_plant
              and name in PLANT_FRICTION):  # fmt: skip
            why = (
                f"its friction model is the plant's (friction = 'plant'): {name} follows "
                f"plant.{PLANT_FRICTION[name]} in every row; vary that, or give the friction "
                "model as numbers (viscous, coulomb, coulomb_velocity) to vary them"
            )
        elif kind == "reaction_observer" and name in FRICTION_PARAMETERS:
            pass  # the friction model: any composition has it
        elif kind in ("observer", "reaction_observer") and specs[kind] is None:
            part = "dob" if kind == "observer" else "reaction"
            why = (
                f"the composition's {part} is not a design of a known family"
                if composition is not None
                else "observer.* parameters need base['observer'] as a dict of design arguments "
                "(or a design of a known family)"
            )
        elif kind in ("observer", "reaction_observer"):
            why = _design_path_why(specs[kind], name, kind, paths)
        if why is not None:
            raise ParameterValueError(f"sweep path {path!r} does not apply to this base: {why}")


def _design_path_why(spec: dict, name: str, kind: str, paths) -> str | None:
    """Why the design argument ``name`` of ``spec`` cannot be swept (None: it can)."""
    from ..observers import get_family

    family = get_family(spec.get("type", "dob"))
    if name not in family.keys:
        return (
            f"an observer spec of type {family.name!r} has no design argument {name!r} "
            f"(it takes {', '.join(family.keys)})"
        )
    if family.parameter(name).only_with is not None:
        key, value = family.parameter(name).only_with
        default = family.parameter(key).default
        if spec.get(key, default) != value and f"{kind}.{key}" not in paths:
            return f"{name} applies with {key}={value!r} only, the spec has {key}=" + repr(
                spec.get(key, default)
            )
    return None
