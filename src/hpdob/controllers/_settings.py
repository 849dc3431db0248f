"""A controller as plain data (settings files)."""

from __future__ import annotations

import dataclasses

from ._pd import PD

__all__ = ["controller_settings"]


def controller_settings(controller) -> dict:
    """A controller as plain data, for settings files (``tune``'s JSON).

    Parameters
    ----------
    controller : Controller or LinearController

    Returns
    -------
    dict
        The PD's ``kp``, ``kd``, ``velocity`` (the form ``tune`` has always written); another
        specification's ``type`` (class name) and constructor arguments; a
        :class:`LinearController`'s ``type`` and ``name``.

    Examples
    --------
    >>> from hpdob import PID
    >>> from hpdob.controllers import controller_settings
    >>> controller_settings(PID(50.0, 100.0, 5.0))["ki"]
    100.0
    """
    if type(controller) is PD:
        return {"kp": controller.kp, "kd": controller.kd, "velocity": controller.velocity}
    if dataclasses.is_dataclass(controller):
        fields = {f.name: getattr(controller, f.name) for f in dataclasses.fields(controller)
                  if f.init and f.name != "_"}  # fmt: skip
        return {"type": type(controller).__name__, **fields}
    return {"type": type(controller).__name__, "name": getattr(controller, "name", "")}
