"""The controllers the loop runs live in :mod:`hpdob.controllers`; re-exported here for the
modules that import them from the simulation package."""

from __future__ import annotations

from ..controllers import PD

__all__ = ["PD"]
