"""Values derived from a frozen input of a run, computed once and kept on that input.

A plant's sub-step matrices for ``(Ts, substeps)``, its default sub-steps, a loop's compiled
records: pure functions of objects that cannot change (frozen dataclasses), so a second run
of the same loop, or a sweep's scenarios sharing a plant, reuse them instead of recomputing.
"""

from __future__ import annotations

import dataclasses

from ..models import ExactSubsteps

__all__ = ["derived", "frozen", "plant_sampler", "run_substeps"]

_KEY = "_hpdob_derived"  # the observer and controller designs leave it out of their pickles
_NONE = object()
#: Entries kept per owner; a full store is emptied (keys such as a run's ``x0`` are unbounded).
LIMIT = 32


def derived(owner, key, make):
    """``make()``, computed once per ``(owner, key)`` and kept in ``owner``'s ``__dict__``
    where ``owner`` is immutable (a frozen dataclass, :func:`frozen`); any other owner gets
    ``make()`` every time.

    ``make()`` must be a pure function of ``owner`` (and of ``key``). At most :data:`LIMIT`
    entries are kept per owner. Threads may race to fill an entry: both compute the same
    value, one is kept.
    """
    if not frozen(owner):
        return make()
    store = owner.__dict__
    cache = store.get(_KEY)
    if cache is None:
        cache = store.setdefault(_KEY, {})
    value = cache.get(key, _NONE)
    if value is _NONE:
        value = make()
        if len(cache) >= LIMIT:
            cache.clear()  # one call: safe against another thread's insertion
        cache[key] = value
    return value


def frozen(value) -> bool:
    """Whether ``value`` is an instance of a frozen dataclass (its fields cannot change)."""
    params = getattr(type(value), "__dataclass_params__", None)
    return params is not None and params.frozen and dataclasses.is_dataclass(value)


def plant_sampler(plant, Ts: float, substeps: int):
    """``plant.sampler(Ts, substeps)``, kept on a frozen plant when it is the exact sub-step
    kind (immutable matrices; a sampler advanced from Python, MuJoCo's, is made per run)."""
    if not frozen(plant):
        return plant.sampler(Ts, substeps)
    key = ("sampler", Ts, substeps)
    cache = plant.__dict__.get(_KEY)
    sampler = None if cache is None else cache.get(key)
    if sampler is None:
        sampler = plant.sampler(Ts, substeps)
        if isinstance(sampler, ExactSubsteps):
            derived(plant, key, lambda: sampler)
    return sampler


def run_substeps(plant, Ts: float, substeps) -> int:
    """``plant.substeps(Ts, substeps)``; a frozen plant keeps its default (``substeps`` None)
    per ``Ts``."""
    if substeps is not None:
        return plant.substeps(Ts, substeps)
    return derived(plant, ("substeps", Ts), lambda: plant.substeps(Ts, None))
