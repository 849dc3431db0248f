"""Sampled-data closed-loop simulation: continuous plant, sampled PD outer loop, DOb inner loop."""

from __future__ import annotations

import math
import warnings
from typing import NamedTuple

import numpy as np

from .._signals import Signal, trajectory
from .._validation import (
    ParameterTypeError,
    ParameterValueError,
    as_int,
    as_real_vector,
    positive,
    require_instance,
)
from ..models._mujoco import MujocoServo
from ..models._servo import ServoModel
from ..observers import _core
from ..observers._runtime import DisturbanceObserver, check_designed_on
from ..observers._synthesis import ObserverDesign
from ._compiled import closed_loop_kernel
from ._controller import PD
from ._devices import Actuator, Encoder
from ._kernel import SENSOR_ENCODER_DIFFERENCE, SENSOR_ENCODER_EXACT, SENSOR_IDEAL
from ._mujoco_loop import run_mujoco_loop
from ._result import SimulationResult

__all__ = [
    "DEFAULT_SUBSTEPS",
    "DIVERGENCE_LIMIT",
    "PLANT_TYPES",
    "SimulationDivergedWarning",
    "simulate",
]

#: Default plant sub-steps per sample. Doubling it changes the canonical metrics by < 0.1 %
#: (tests/test_simulate.py::test_substep_convergence).
DEFAULT_SUBSTEPS = 8
#: Largest ``h c / (v J)`` (sub-step times the stiffness of the Coulomb term
#: ``c tanh(omega / v)``) of the default sub-step count; the midpoint rule is unstable above 2.
_COULOMB_STEP = 0.5
#: Most plant steps (samples times sub-steps) one run may take: 1e8 steps need 0.8 GB.
MAX_PLANT_STEPS = 100_000_000
#: A run stops when |theta| [rad] or |omega| [rad/s] exceeds this, or the state is not finite.
DIVERGENCE_LIMIT = 1e9


#: What ``plant=`` accepts: hpdob's own integrator, or MuJoCo.
PLANT_TYPES = (ServoModel, MujocoServo)


class SimulationDivergedWarning(RuntimeWarning):
    """A simulation stopped early because the closed loop diverged."""


def default_substeps(plant: ServoModel, Ts: float) -> int:
    """Default sub-steps per sample for ``plant``: :data:`DEFAULT_SUBSTEPS`, or more (an even
    number) when the Coulomb friction is so stiff that ``h c / (v J)`` would exceed 0.5.

    Near ``omega = 0`` the friction ``c tanh(omega / v)`` acts like a damper ``c / v``, which
    the explicit midpoint rule only integrates accurately for ``h c / (v J) <= 0.5``
    (``tests/test_simulate.py::test_stiff_coulomb_friction_converges``).
    """
    c, v, J = plant.coulomb, plant.coulomb_velocity, plant.J
    per_sample = Ts * (c / v / J) if c > 0.0 else 0.0  # Ts times the stiffness [1/s]
    if not per_sample <= MAX_PLANT_STEPS:  # also inf (overflow)
        raise ParameterValueError(
            f"plant Coulomb friction is too stiff to integrate: Ts c/(v J) = {per_sample:.3g} "
            f"for coulomb={c!r} N m, coulomb_velocity={v!r} rad/s, J={J!r} kg m^2 would need "
            f"more than {MAX_PLANT_STEPS:.0e} sub-steps per sample; raise coulomb_velocity"
        )
    return max(DEFAULT_SUBSTEPS, 2 * math.ceil(per_sample / (2.0 * _COULOMB_STEP)))


def check_run_arguments(Ts, duration, substeps=None, x0=(0.0, 0.0)):
    """``(Ts, duration, substeps, x0)`` checked with :func:`simulate`'s messages: two positive
    floats [s], a positive int or None, and a new float array ``[theta, omega]``."""
    Ts = positive(Ts, "Ts", "a positive finite sampling period [s]")
    duration = positive(duration, "duration", "a positive finite duration [s]")
    if substeps is not None:
        substeps = as_int(
            substeps, "substeps", "a positive integer number of sub-steps per sample", minimum=1
        )
    x0 = as_real_vector(x0, "x0", "an initial state [theta (rad), omega (rad/s)]", length=2)
    return Ts, duration, substeps, x0


def resolve_substeps(plant, Ts: float, substeps: int | None) -> int:
    """Plant steps per sample: ``substeps`` (checked by :func:`check_run_arguments`); by
    default :func:`default_substeps` for a :class:`ServoModel`, ``Ts/timestep`` for a
    :class:`MujocoServo` with its own MuJoCo time step, else :data:`DEFAULT_SUBSTEPS`."""
    if isinstance(plant, MujocoServo):
        substeps = plant.steps_per_sample(Ts, substeps)
        return DEFAULT_SUBSTEPS if substeps is None else substeps
    return default_substeps(plant, Ts) if substeps is None else substeps


def _sample_count(Ts: float, duration: float) -> int:
    n = round(duration / Ts)
    if n < 1 or abs(n * Ts - duration) > 1e-9 * duration:
        raise ParameterValueError(
            f"duration must be a positive multiple of Ts={Ts!r} s, got "
            f"{duration!r} s ({duration / Ts:.6g} samples)"
        )
    return n


def _call(function, t: np.ndarray, name: str):
    try:
        return function(t)
    except (ParameterValueError, ParameterTypeError):
        raise
    except Exception as err:
        raise ParameterValueError(
            f"{name} failed when called on an array of {t.size} times: {type(err).__name__}: {err}"
        ) from err


def _as_samples(values, t: np.ndarray, name: str) -> np.ndarray:
    try:
        values = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise ParameterValueError(
            f"{name} must be an array of numbers, got {type(values).__name__}"
        ) from None
    if values.ndim == 0:
        values = np.full(t.shape, float(values))
    if values.shape != t.shape:
        raise ParameterValueError(
            f"{name} must be an array shaped like its input times "
            f"{t.shape}, got shape {values.shape}"
        )
    if not np.all(np.isfinite(values)):
        bad = float(t[~np.isfinite(values)][0])
        raise ParameterValueError(f"{name} is not finite at t = {bad!r} s")
    return values


def _disturbance(disturbance, t: np.ndarray, name: str = "disturbance") -> np.ndarray:
    return _as_samples(_call(disturbance, t, name), t, name)


def _reference(reference, t: np.ndarray):
    if isinstance(reference, Signal):
        reference = trajectory(reference)
    if not callable(reference):
        raise ParameterTypeError(
            "reference must be a Signal or a callable t -> (r, r_dot, "
            f"r_ddot), got {type(reference).__name__}"
        )
    parts = _call(reference, t, "reference")
    if not isinstance(parts, (tuple, list)) or len(parts) != 3:
        raise ParameterValueError(
            "reference must return a tuple (r, r_dot, r_ddot) of arrays, "
            f"got {type(parts).__name__}"
        )
    return tuple(
        _as_samples(p, t, f"reference's {name}")
        for p, name in zip(parts, ("r", "r_dot", "r_ddot"), strict=True)
    )


def _observer_arrays(observer, nominal: ServoModel, Ts: float, x0):
    if observer is None:
        return None, np.zeros(1)
    if isinstance(observer, DisturbanceObserver):
        design, state = observer.design, np.array(observer.state)
    elif isinstance(observer, ObserverDesign):
        design = observer
        state = np.array(_core.initial_state(design, x0, 0.0))
    else:
        raise ParameterTypeError(
            "observer must be a DisturbanceObserver, an ObserverDesign or "
            f"None, got {type(observer).__name__}"
        )
    check_designed_on(design, nominal, Ts)
    return design, state


def simulate(
    *,
    plant: ServoModel | MujocoServo,
    nominal: ServoModel,
    Ts: float,
    duration: float,
    controller: PD,
    observer=None,
    reference,
    disturbance=None,
    substeps: int | None = None,
    sensor: Encoder | None = None,
    actuator: Actuator | None = None,
    x0=(0.0, 0.0),
    label: str = "",
) -> SimulationResult:
    r"""Simulate the sampled-data loop: continuous plant, sampled PD, DOb inner loop.

    The plant's continuous dynamics are
    :math:`J\ddot\theta = u - b\omega - c\tanh(\omega/v) - \tau_{ext}(t)` with ``u`` held over
    each sample (ZOH). It is advanced in ``substeps`` sub-steps per sample: the linear part by
    its exact discretisation, the Coulomb friction and ``disturbance`` by an exponential midpoint
    rule (see ``hpdob.simulation._kernel``). At each sample the controller and the observer see the
    sensor's measurement, in the order: estimate, control, update (see
    :class:`DisturbanceObserver`).

    Parameters
    ----------
    plant : ServoModel or MujocoServo
        The true motor: a :class:`ServoModel` (``J``, ``b``, ``coulomb``,
        ``coulomb_velocity``) integrated by hpdob, or a :class:`MujocoServo` integrated by
        MuJoCo (its dry friction is MuJoCo's ``frictionloss``; see docs/mujoco.md).
    nominal : ServoModel
        The model the controller (``J_n``) and the observer use.
    Ts : float
        Sampling period [s].
    duration : float
        Simulated time [s], a multiple of ``Ts``; samples are at ``k Ts`` for
        ``0 <= k < duration/Ts``.
    controller : PD
    observer : DisturbanceObserver or ObserverDesign, optional
        Designed on ``nominal.discretize(Ts)`` (else ValueError). A ``DisturbanceObserver``
        starts from its current state and is not modified (the run uses a copy); an
        ``ObserverDesign`` starts from ``initial_state(design, x0, 0)``. None: PD only.
    reference : Signal or callable
        A :class:`~hpdob.signals.Signal`, or a callable taking the array of sampling instants and
        returning ``(r, r_dot, r_ddot)`` arrays [rad, rad/s, rad/s^2].
    disturbance : callable, optional
        External torque [N m] as a vectorised function of time (a Signal or any callable). It
        is evaluated once per run, on two arrays: the sampling instants ``k Ts`` (recorded as
        ``tau_ext`` and used for the ground truth) and the sub-step midpoints
        ``k Ts + (j + 1/2) Ts/substeps`` (used by the integrator). None: no disturbance.
    substeps : int, optional
        Plant sub-steps per sample. Default: :data:`DEFAULT_SUBSTEPS` (8), raised to an even
        number with ``h c / (v J) <= 0.5`` for stiff Coulomb friction (:func:`default_substeps`;
        e.g. 66 for the canonical plant with ``coulomb_velocity = 1e-3``). For a
        :class:`MujocoServo` these are MuJoCo steps of ``Ts/substeps``; if the servo has its
        own ``timestep``, ``substeps`` is ``Ts/timestep`` (None or that value).
    sensor : Encoder, optional
        Default: the ideal state.
    actuator : Actuator, optional
        Default: ideal (no limit, no delay).
    x0 : sequence of 2 floats, optional
        Initial plant state ``[theta (rad), omega (rad/s)]``; default at rest at 0.
    label : str, optional
        Name stored in the result.

    Returns
    -------
    SimulationResult
        If the loop diverges (``|theta|`` or ``|omega|`` above 1e9 or non-finite) the run stops,
        the result holds the samples computed so far with ``diverged=True`` and a message, and a
        :class:`SimulationDivergedWarning` is issued.

    Raises
    ------
    TypeError, ValueError
        For arguments of the wrong type or value, with the parameter named.

    Examples
    --------
    >>> from hpdob import PD, DisturbanceObserver, ServoModel, simulate
    >>> from hpdob.signals import Step, SmoothStep
    >>> plant, nominal = ServoModel(3.06e-4, 5e-5), ServoModel(2.8e-4)
    >>> obs = DisturbanceObserver(nominal.discretize(1e-3), order=1, bandwidth=100.0)
    >>> result = simulate(plant=plant, nominal=nominal, Ts=1e-3, duration=2.0,
    ...                   controller=PD(50, 5), observer=obs,
    ...                   reference=SmoothStep(0.2, 1.2, 1.0), disturbance=Step(1.5005, 0.05))
    >>> m = result.metrics(regulation=(1.2, 2.0))
    >>> print(f"{m['rms_position_error_regulation']:.4f} rad")
    0.0064 rad
    """
    plant = require_instance(plant, PLANT_TYPES, "plant")
    nominal = require_instance(nominal, ServoModel, "nominal")
    Ts, duration, substeps, x0 = check_run_arguments(Ts, duration, substeps, x0)
    n = _sample_count(Ts, duration)
    controller = require_instance(controller, PD, "controller")
    sensor = require_instance(sensor, Encoder, "sensor", optional=True)
    actuator = require_instance(actuator, Actuator, "actuator", optional=True) or Actuator()
    S = resolve_substeps(plant, Ts, substeps)
    if not isinstance(label, str):
        raise ParameterTypeError(f"label must be a str, got {type(label).__name__}")
    design, z0 = _observer_arrays(observer, nominal, Ts, x0)
    signals = sample_signals(reference, disturbance, Ts=Ts, n=n, substeps=S)
    result = run_prepared(
        plant=plant,
        nominal=nominal,
        controller=controller,
        design=design,
        z0=z0,
        sensor=sensor,
        actuator=actuator,
        x0=x0,
        signals=signals,
        label=label,
    )
    if result.diverged:
        warnings.warn(result.message, SimulationDivergedWarning, stacklevel=2)
    return result


class SampledSignals(NamedTuple):
    """Reference and disturbance evaluated on a run's time grids (see :func:`simulate`)."""

    Ts: float
    substeps: int
    t: np.ndarray
    r: np.ndarray
    r_dot: np.ndarray
    r_ddot: np.ndarray
    tau_sample: np.ndarray
    tau_mid: np.ndarray

    def scaled(self, factor: float) -> SampledSignals:
        """The same signals with the disturbance multiplied by ``factor``."""
        if factor == 1.0:
            return self
        return self._replace(tau_sample=factor * self.tau_sample, tau_mid=factor * self.tau_mid)


def sample_signals(reference, disturbance, *, Ts: float, n: int, substeps: int) -> SampledSignals:
    """Evaluate ``reference`` at ``k Ts`` and ``disturbance`` at ``k Ts`` and the sub-step
    midpoints ``k Ts + (j + 1/2) Ts / substeps``, ``0 <= k < n``, with validation."""
    if n * substeps > MAX_PLANT_STEPS:
        raise ParameterValueError(
            f"duration/Ts * substeps = {n} * {substeps} = {n * substeps:.3g} plant steps exceeds "
            f"the limit of {MAX_PLANT_STEPS:.0e} per run (the sub-step disturbance alone would "
            f"need {8 * n * substeps / 1e9:.3g} GB); shorten duration, raise Ts or lower "
            f"substeps (or the stiffness c/(v J) of the Coulomb friction that sets the default)"
        )
    t = np.arange(n) * Ts
    r, r_dot, r_ddot = _reference(reference, t)
    if disturbance is None:
        tau_sample, tau_mid = np.zeros(n), np.zeros(n * substeps)
    elif callable(disturbance):
        tau_sample = _disturbance(disturbance, t)
        t_mid = (t[:, None] + (np.arange(substeps) + 0.5) * (Ts / substeps)).ravel()
        tau_mid = _disturbance(disturbance, t_mid)
    else:
        raise ParameterTypeError(
            "disturbance must be a callable of time (e.g. an hpdob Signal) "
            f"or None, got {type(disturbance).__name__}"
        )
    return SampledSignals(Ts, substeps, t, r, r_dot, r_ddot, tau_sample, tau_mid)


def run_prepared(
    *,
    plant: ServoModel | MujocoServo,
    nominal: ServoModel,
    controller: PD,
    design,
    z0,
    sensor: Encoder | None,
    actuator: Actuator,
    x0: np.ndarray,
    signals: SampledSignals,
    label: str = "",
) -> SimulationResult:
    """Run the compiled kernel on validated inputs and pre-sampled signals (no warning).

    The shared engine of :func:`simulate` and :func:`hpdob.sweep`; ``design`` is an
    :class:`ObserverDesign` or None and ``z0`` its initial state. A :class:`MujocoServo`
    plant runs the same loop in Python around MuJoCo (:mod:`hpdob.simulation._mujoco_loop`).
    """
    Ts, S, t = signals.Ts, signals.substeps, signals.t
    n = t.size
    sensor_mode, resolution, noise = SENSOR_IDEAL, 1.0, np.zeros(n)
    if sensor is not None:
        resolution = sensor.resolution
        sensor_mode = (
            SENSOR_ENCODER_EXACT if sensor.velocity == "exact" else SENSOR_ENCODER_DIFFERENCE
        )
        if sensor.noise_std > 0:
            seed = 0 if sensor.seed is None else sensor.seed
            noise = sensor.noise_std * np.random.default_rng(seed).standard_normal(n)

    out = {
        name: np.zeros(n)
        for name in ("theta", "omega", "theta_m", "omega_m", "u", "tau_hat", "tau_dn")
    }
    limit = math.inf if actuator.torque_limit is None else actuator.torque_limit
    if isinstance(plant, MujocoServo):
        done = run_mujoco_loop(
            plant, n_samples=n, substeps=S, Ts=Ts, x0=x0, J_n=nominal.J, b_n=nominal.b,
            kp=controller.kp, kd=controller.kd, feedforward=controller.feedforward,
            r=signals.r, r_dot=signals.r_dot, r_ddot=signals.r_ddot, tau_mid=signals.tau_mid,
            tau_sample=signals.tau_sample, sensor_mode=sensor_mode, resolution=resolution,
            position_noise=noise, torque_limit=limit, delay=actuator.delay_samples,
            design=design, z0=z0, divergence_limit=DIVERGENCE_LIMIT, out=out,
        )  # fmt: skip
    else:
        done = _run_kernel(plant, nominal, controller, design, z0, actuator, x0, signals,
                           sensor_mode, resolution, noise, limit, out)  # fmt: skip
    diverged = done < n
    message = "ok"
    if diverged:
        unstable = " or MuJoCo flagged it unstable" if isinstance(plant, MujocoServo) else ""
        message = (
            f"{label or 'simulation'} diverged: |theta| or |omega| exceeded "
            f"{DIVERGENCE_LIMIT:g} (or became non-finite{unstable}) by t = {done * Ts:.6g} s; "
            f"the result holds the {done} samples before that"
        )
    keep = slice(0, done)
    return SimulationResult(
        t=t[keep],
        theta=out["theta"][keep],
        omega=out["omega"][keep],
        theta_measured=out["theta_m"][keep],
        omega_measured=out["omega_m"][keep],
        r=signals.r[keep],
        r_dot=signals.r_dot[keep],
        r_ddot=signals.r_ddot[keep],
        u=out["u"][keep],
        tau_hat=out["tau_hat"][keep],
        tau_dn=out["tau_dn"][keep],
        tau_ext=signals.tau_sample[keep],
        Ts=Ts,
        label=label,
        diverged=diverged,
        message=message,
    )


def _run_kernel(plant, nominal, controller, design, z0, actuator, x0, signals,
                sensor_mode, resolution, noise, limit, out) -> int:  # fmt: skip
    """The compiled kernel on a :class:`ServoModel` plant; returns the samples completed."""
    Ts, S, n = signals.Ts, signals.substeps, signals.t.size
    sub = plant.discretize(Ts / S)
    half = plant.discretize(Ts / (2 * S))
    if design is None:
        k_gain, p_weight, Kx, Ku = np.zeros(1), np.zeros(1), np.zeros((1, 2)), np.zeros(1)
        last = np.zeros(2)
    else:
        k_gain, p_weight = np.array(design._k), np.array(design._p)
        Kx, Ku = design.state_input, design.control_input
        last = np.array(design._last_gain)
    # fmt: off
    done = closed_loop_kernel()(
        n, S, Ts, x0, sub.A, sub.B, half.A, half.B,
        plant.J, plant.b, plant.coulomb, plant.coulomb_velocity,
        nominal.J, nominal.b, controller.kp, controller.kd, controller.feedforward,
        signals.r, signals.r_dot, signals.r_ddot, signals.tau_mid, signals.tau_sample,
        sensor_mode, resolution, noise, limit, actuator.delay_samples,
        design is not None, k_gain, p_weight, np.ascontiguousarray(Kx),
        np.ascontiguousarray(Ku), last, np.ascontiguousarray(z0, dtype=float),
        DIVERGENCE_LIMIT,
        out["theta"], out["omega"], out["theta_m"], out["omega_m"], out["u"],
        out["tau_hat"], out["tau_dn"],
    )
    # fmt: on
    return done
