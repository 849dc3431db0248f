"""Plugins of the ``hpdob`` command: modules that register observer families when imported.

A family registered with :func:`hpdob.observers.register_family` in a user's module reaches the
installed ``hpdob`` command in either of two standard ways, both read when the command starts
(before its options, which list every family's, are built):

- the environment variable ``HPDOB_PLUGINS``: module names separated by commas
  (``HPDOB_PLUGINS=mylab.observers hpdob design --type mine ...``), imported in that order;
- the entry-point group ``hpdob.families`` of an installed package (``pyproject.toml``:
  ``[project.entry-points."hpdob.families"] mine = "mylab.observers"``): each entry point names a
  module (importing it registers its families) or a :class:`~hpdob.observers.Family`
  (registered as it is).

Plant types of scenario files have their own group, ``hpdob.plant_types`` (hpdob.simulation).
"""

from __future__ import annotations

import functools
import os

__all__ = ["ENTRY_POINT_GROUP", "ENVIRONMENT_VARIABLE", "installed_entry_points", "load_plugins"]

ENVIRONMENT_VARIABLE = "HPDOB_PLUGINS"
ENTRY_POINT_GROUP = "hpdob.families"

_LOADED: set[str] = set()  # the entry points and modules loaded already (once per process)


@functools.cache
def installed_entry_points(group: str) -> tuple:
    """The entry points of ``group`` installed when the process first asks for them: a scan
    of every installed distribution costs about 4 ms and leaves some 40 kB of cyclic
    garbage, once per process rather than at every command or scenario (a package installed
    meanwhile is seen by the next process)."""
    import importlib.metadata

    return tuple(importlib.metadata.entry_points(group=group))


def _import(module: str, where: str):
    import importlib

    try:
        return importlib.import_module(module)
    except Exception as err:  # a plugin's own failure, named on one line by the command
        from ._validation import ParameterValueError  # here: `import hpdob.cli` stays light

        raise ParameterValueError(
            f"{where} names the module {module!r}, which cannot be imported: "
            f"{type(err).__name__}: {err}"
        ) from err


def load_plugins(environ=None) -> tuple:
    """Import the plugin modules of ``HPDOB_PLUGINS`` and the ``hpdob.families`` entry points.

    Parameters
    ----------
    environ : mapping, optional
        The environment to read ``HPDOB_PLUGINS`` from. Default ``os.environ``.

    Returns
    -------
    tuple of str
        The modules and entry points loaded by this call (each is loaded once per process;
        the entry points are those installed when the process first called it).

    Raises
    ------
    ParameterValueError
        If a named module (or an entry point's object) cannot be imported; the message names
        the variable or the entry point and the module.
    """
    environ = os.environ if environ is None else environ
    loaded = []
    for name in (n.strip() for n in environ.get(ENVIRONMENT_VARIABLE, "").split(",")):
        if name and name not in _LOADED:
            _import(name, ENVIRONMENT_VARIABLE)
            _LOADED.add(name)
            loaded.append(name)
    for entry in installed_entry_points(ENTRY_POINT_GROUP):
        if entry.value in _LOADED:
            continue
        where = f"the entry point {entry.name!r} of {ENTRY_POINT_GROUP}"
        module, _, attribute = entry.value.partition(":")
        value = _import(module.strip(), where)
        for part in filter(None, attribute.strip().split(".")):
            value = getattr(value, part)
        from .observers import Family, families, register_family

        if isinstance(value, Family) and value not in families():
            register_family(value)
        _LOADED.add(entry.value)
        loaded.append(entry.value)
    return tuple(loaded)
