"""The names of an observer's measured and output signals, and their units."""

from __future__ import annotations

__all__ = ["MEASUREMENTS", "OUTPUTS", "UNITS"]

#: Measured signals of the two observer kinds: ``"state"`` (angle and velocity) and
#: ``"position"`` (angle only).
MEASUREMENTS = {"state": ("theta", "omega"), "position": ("theta",)}
#: Output sets an observer may have: the estimate, optionally followed by a velocity estimate.
OUTPUTS = (("tau_hat",), ("tau_hat", "omega_hat"), ("tau_hat", "tau_reac"),
           ("tau_hat", "omega_hat", "tau_reac"))  # fmt: skip
#: Units of the signals, for messages and generated code.
UNITS = {"theta": "rad", "omega": "rad/s", "u": "N m", "tau_hat": "N m", "omega_hat": "rad/s",
         "tau_reac": "N m"}  # fmt: skip
