r"""The plant types of scenario files: ``[plant] type = ...`` -> the plant and its loop.

A :class:`PlantType` says how a ``[plant]`` table becomes a plant and, for a plant that the
single-axis :class:`~hpdob.ServoLoop` does not run, how the whole file becomes a scenario of
its own loop. :func:`~hpdob.simulation.load_scenario` and ``hpdob simulate`` look the type up
here instead of listing the types. The single-axis types (``"rigid"``, ``"two-mass"``,
``"mujoco"``) are registered by this package; a package above it registers its own when it
is imported (``hpdob.robots``: ``"two-link-arm"``, ``"mujoco-arm"``; the ``hpdob`` command
imports it). Plugins -- ``hpdob.robots`` among them -- are also found through the standard
entry points of the group ``hpdob.plant_types`` (``[project.entry-points."hpdob.plant_types"]``
in a ``pyproject.toml``), loaded on the first lookup of a type not registered yet: this package
names no package above it, so the dependency order of the subpackages holds.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from .._plugins import installed_entry_points
from .._validation import ParameterTypeError, ParameterValueError

__all__ = [
    "ENTRY_POINT_GROUP",
    "PlantType",
    "get_plant_type",
    "plant_types",
    "register_plant_type",
    "unregister_plant_type",
]

#: The entry-point group of plant-type plugins: each entry point names a module (importing it
#: registers its types) or a :class:`PlantType` (registered as it is).
ENTRY_POINT_GROUP = "hpdob.plant_types"

#: Added to the message of an unknown type while hpdob.robots is not imported (an install
#: whose entry points are stale, or a source tree on PYTHONPATH without its metadata).
_ROBOTS_HINT = " (the arm types register when hpdob.robots is imported: import hpdob.robots)"


@dataclass(frozen=True)
class PlantType:
    """A ``[plant] type`` of scenario files.

    Parameters
    ----------
    name : str
        The ``type`` value (``"rigid"``, ``"mujoco-arm"``, ...).
    build : callable
        ``build(table, where, base) -> plant``: the ``[plant]`` (or ``[nominal]``) table without
        its ``type``, the key for messages (``"plant"``), and the directory relative paths in the
        table resolve against (None: the working directory).
    scenario : callable, optional
        For a plant with a loop of its own: ``scenario(data, base) -> Scenario``, the whole
        parsed file (its ``.simulate()`` runs it). None (default): the single-axis loop.
    description : str, optional
        One line for messages and docs.
    """

    name: str
    build: Callable
    scenario: Callable | None = None
    description: str = ""

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise ParameterTypeError(f"name must be a non-empty str, got {self.name!r}")
        if not callable(self.build):
            raise ParameterTypeError(f"build must be callable, got {type(self.build).__name__}")
        if self.scenario is not None and not callable(self.scenario):
            raise ParameterTypeError(
                f"scenario must be callable or None, got {type(self.scenario).__name__}"
            )


_REGISTRY: dict[str, PlantType] = {}


def register_plant_type(plant_type: PlantType, *, replace: bool = False) -> PlantType:
    """Register a ``[plant] type`` for scenario files (:func:`load_scenario`, ``hpdob simulate``).

    Parameters
    ----------
    plant_type : PlantType
        The record.
    replace : bool, optional
        Allow replacing a type of the same name. Default False.

    Returns
    -------
    PlantType
        ``plant_type``.

    Raises
    ------
    TypeError
        If ``plant_type`` is not a :class:`PlantType`.
    ValueError
        If the name is taken (and not ``replace``).

    Examples
    --------
    >>> from hpdob import ServoModel
    >>> from hpdob.simulation import (PlantType, plant_types, register_plant_type,
    ...                               unregister_plant_type)
    >>> heavy = PlantType("heavy", lambda table, where, base: ServoModel(J=2.0 * table["J"]))
    >>> _ = register_plant_type(heavy)
    >>> "heavy" in plant_types()
    True
    >>> unregister_plant_type("heavy")
    """
    if not isinstance(plant_type, PlantType):
        raise ParameterTypeError(f"plant_type must be a PlantType, got {type(plant_type).__name__}")
    if plant_type.name in _REGISTRY and not replace:
        raise ParameterValueError(
            f"plant_type.name {plant_type.name!r} is registered already (pass replace=True)"
        )
    _REGISTRY[plant_type.name] = plant_type
    return plant_type


def unregister_plant_type(name: str) -> None:
    """Remove a registered plant type.

    Parameters
    ----------
    name : str
        Its ``type`` value.

    Raises
    ------
    ValueError
        If no type of that name is registered.
    """
    if name not in _REGISTRY:
        raise ParameterValueError(f"name must be a registered plant type, got {name!r}")
    del _REGISTRY[name]


_LOADED: set[str] = set()  # the entry points loaded already (each once per process)


def _load_plugins() -> None:
    for entry in installed_entry_points(ENTRY_POINT_GROUP):
        if entry.value in _LOADED:
            continue
        _LOADED.add(entry.value)
        try:
            value = entry.load()  # importing a plugin module registers its types
        except ImportError:  # a plugin that cannot load (a missing dependency) offers nothing
            continue
        if isinstance(value, PlantType) and _REGISTRY.get(value.name) is not value:
            register_plant_type(value)


def plant_types() -> dict:
    """The registered plant types, those of the entry points' plugins included.

    Returns
    -------
    dict
        ``type`` value -> :class:`PlantType`, in registration order.
    """
    _load_plugins()
    return dict(_REGISTRY)


def get_plant_type(name, where: str = "plant.type") -> PlantType:
    """The registered plant type ``name``.

    Parameters
    ----------
    name : str
        The ``type`` value of a ``[plant]`` table.
    where : str, optional
        The key named in the message. Default ``"plant.type"``.

    Returns
    -------
    PlantType

    Raises
    ------
    ParameterValueError
        If no such type is registered (the message lists the registered ones).
    """
    if isinstance(name, str) and name in _REGISTRY:
        return _REGISTRY[name]
    names = plant_types()  # the plugins' types register on their import
    if isinstance(name, str) and name in names:
        return names[name]
    import sys

    hint = "" if "hpdob.robots" in sys.modules else _ROBOTS_HINT
    raise ParameterValueError(
        f"{where} must be one of {', '.join(map(repr, names))}; got {name!r}{hint}"
    )
