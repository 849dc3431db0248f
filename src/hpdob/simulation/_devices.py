"""Sensor and actuator models for the sampled-data simulation."""

from __future__ import annotations

import math
from dataclasses import KW_ONLY, dataclass

from .._validation import (
    ParameterValueError,
    as_int,
    check_choice,
    nonnegative,
    positive,
)

__all__ = ["Actuator", "Encoder"]

VELOCITY_METHODS = ("backward-difference", "exact")


@dataclass(frozen=True)
class Encoder:
    r"""Incremental encoder: quantised position and an estimated velocity.

    At each sample the measured angle is :math:`\theta_m = q\,\mathrm{round}((\theta + n)/q)`
    with resolution :math:`q = 2\pi/\mathrm{counts\_per\_rev}` and :math:`n` white Gaussian
    noise of standard deviation ``noise_std`` [rad] (0 by default). The velocity is
    ``"backward-difference"`` :math:`(\theta_{m,k} - \theta_{m,k-1})/T_s` (with
    :math:`\theta_{m,-1} = \theta_{m,0}`, i.e. at rest before the start) or ``"exact"`` (the
    true velocity, for separating quantisation effects).

    Parameters
    ----------
    counts_per_rev : int
        Counts per revolution after decoding (e.g. 16384), >= 1.
    velocity : {"backward-difference", "exact"}, optional
    noise_std : float, optional
        Position noise standard deviation [rad], >= 0.
    seed : int or None, optional
        Seed of the noise generator; ``None`` means the default seed 0, so that runs are
        reproducible. Pass different seeds for independent noise.
    """

    counts_per_rev: int
    _: KW_ONLY
    velocity: str = "backward-difference"
    noise_std: float = 0.0
    seed: int | None = None

    def __post_init__(self):
        object.__setattr__(
            self,
            "counts_per_rev",
            as_int(
                self.counts_per_rev,
                "counts_per_rev",
                "a positive integer number of counts",
                minimum=1,
                maximum=2**53,  # exactly representable: resolution is 2 pi / counts_per_rev
            ),
        )
        check_choice(self.velocity, "velocity", VELOCITY_METHODS)
        object.__setattr__(
            self,
            "noise_std",
            nonnegative(self.noise_std, "noise_std", "a non-negative finite noise level [rad]"),
        )
        if self.seed is not None:
            object.__setattr__(
                self, "seed", as_int(self.seed, "seed", "a non-negative integer seed", minimum=0)
            )

    @property
    def resolution(self) -> float:
        """Angle of one count [rad]."""
        return 2.0 * math.pi / self.counts_per_rev


@dataclass(frozen=True)
class Actuator:
    """Torque actuator: saturation and a transport delay of whole samples.

    The controller's torque command is clipped to ``[-torque_limit, torque_limit]``; the
    observer is updated with this clipped command (the controller knows its own limit). The
    plant receives it ``delay_samples`` samples later (0 before the first command); the observer
    does not know the delay, which therefore appears in the nominal disturbance.

    Parameters
    ----------
    torque_limit : float or None, optional
        Positive torque limit [N m]; ``None`` for no limit.
    delay_samples : int, optional
        Delay [samples], >= 0.
    """

    _: KW_ONLY
    torque_limit: float | None = None
    delay_samples: int = 0

    def __post_init__(self):
        if self.torque_limit is not None:
            object.__setattr__(
                self,
                "torque_limit",
                positive(
                    self.torque_limit, "torque_limit", "a positive finite torque [N m] or None"
                ),
            )
        delay = as_int(
            self.delay_samples,
            "delay_samples",
            "a non-negative integer number of samples",
            minimum=0,
        )
        if delay > 1_000_000:
            raise ParameterValueError(f"delay_samples must be at most 1000000, got {delay}")
        object.__setattr__(self, "delay_samples", delay)
