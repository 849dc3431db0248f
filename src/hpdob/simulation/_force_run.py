"""The metrics of a run against a wall: the impact, the reaction-torque estimate and the force
tracking, as ``hpdob simulate`` reports them and as a sweep's rows hold them (one place)."""

from __future__ import annotations

import functools

import numpy as np

__all__ = ["force_reference", "force_run_columns", "force_run_metrics"]

#: Columns of a run against an environment (``contact_*``) and of a force, impedance or
#: switching controller with a reaction-torque output (``force_*``); ``force_rms_force_error*``
#: only where the controller has a force reference (not impedance control).
CONTACT_KEYS = ("first_contact", "impact_peak", "overshoot", "overshoot_ratio")
FORCE_KEYS = ("rms_reaction_error", "rms_force_error")


def _kind(controller) -> str | None:
    """The force run kind of ``controller``: "force", "impedance", "position-force" or None."""
    return _kind_of_type(type(controller))


@functools.lru_cache(maxsize=64)
def _kind_of_type(kind: type) -> str | None:
    """:func:`_kind` of an instance of ``kind`` (a sweep asks it once per row: kept)."""
    from ..controllers import ForceControl, ImpedanceControl, PositionForceSwitch

    if issubclass(kind, ForceControl):
        return "force"
    if issubclass(kind, PositionForceSwitch):
        return "position-force"
    return "impedance" if issubclass(kind, ImpedanceControl) else None


def force_reference(result, controller):
    """``(kind, tau_ref)`` of a run.

    ``kind`` is "force", "impedance" or "position-force" for such a controller in a run with a
    contact torque and a reaction-torque estimate (else None); ``tau_ref`` is the force
    reference per sample [N m]: the force controller's reference signal ``r``, the switching
    controller's ``tau_ref``, or None (impedance control: its target is a position).
    """
    if result.tau_contact is None or result.tau_reac is None:
        return None, None
    kind = _kind(controller)
    if kind == "force":
        return kind, np.asarray(result.r, dtype=float)
    if kind == "position-force":
        return kind, np.full(len(result), float(controller.tau_ref))
    return kind, None


def force_run_metrics(result, controller, *, window="steady") -> dict[str, float]:
    """The contact and force metrics of ``result``, a run of a loop with ``controller``.

    ``contact_*`` (``SimulationResult.contact_metrics`` against the switching controller's
    ``tau_ref``, the force controller's last reference value, else the last contact torque)
    for a run against an environment; ``force_*`` (``SimulationResult.force_metrics`` over
    the whole run) and ``force_*_steady`` with ``force_steady_start`` (over ``window``:
    "steady" or a ``(start, stop)`` pair [s]) for a force, impedance or switching controller
    with a reaction-torque output. Empty for a run without an environment.
    """
    metrics: dict[str, float] = {}
    if result.tau_contact is None:
        return metrics
    kind, tau_ref = force_reference(result, controller)
    impact_ref = getattr(controller, "tau_ref", None)
    if _kind(controller) == "force" and len(result):
        impact_ref = float(result.r[-1])
    metrics.update({f"contact_{k}": v for k, v in result.contact_metrics(impact_ref).items()})
    if kind is not None:  # tau_reac vs tau_contact, tau_contact vs tau_ref
        metrics.update({f"force_{k}": v for k, v in result.force_metrics(tau_ref).items()})
        # and over the steady state only (without the approach, the impact and the step)
        steady = result.force_metrics(tau_ref, window=window)
        metrics.update({f"force_{k}_steady": v for k, v in steady.items() if k != "window_start"})
        metrics["force_steady_start"] = steady["window_start"]
    return metrics


def force_run_columns(loop) -> tuple[str, ...]:
    """The names :func:`force_run_metrics` gives for runs of ``loop`` (a sweep's columns)."""
    plant = loop.plant
    if getattr(plant, "environment", None) is None and getattr(plant, "contact_geom", None) is None:
        return ()
    columns = [f"contact_{k}" for k in CONTACT_KEYS]
    system = getattr(loop.observer, "system", None)
    kind = _kind(loop.controller)
    if kind is not None and system is not None and "tau_reac" in system.outputs:
        keys = FORCE_KEYS if kind != "impedance" else FORCE_KEYS[:1]
        columns += [f"force_{k}" for k in keys]
        columns += [f"force_{k}_steady" for k in keys]
        columns.append("force_steady_start")
    return tuple(columns)


def position_metrics_apply(controller) -> bool:
    """False for a force controller: its reference ``r`` is tau_ref [N m], and ``theta - r``
    (an angle minus a torque) means nothing."""
    return _kind(controller) != "force"
