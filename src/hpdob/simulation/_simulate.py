"""Sampled-data closed-loop simulation: continuous plant, sampled PD, observer inner loop."""

from __future__ import annotations

import collections
import math
import threading
import warnings
from typing import NamedTuple

import numpy as np

from .._generated import read_only_view
from .._signals import Constant, Ramp, Signal, SmoothStep, Step, Sum, _Trajectory, trajectory
from .._validation import (
    ParameterTypeError,
    ParameterValueError,
    as_int,
    as_real_vector,
    positive,
)
from .._waveforms import Chirp, Noise, Sine
from ..models import DEFAULT_SUBSTEPS, MAX_PLANT_STEPS, ExactSubsteps
from ._derived import derived, plant_sampler, run_substeps
from ._loop import ServoLoop, accepts_loop, controller_sources
from ._records import (
    SENSOR_ENCODER_DIFFERENCE,
    SENSOR_ENCODER_EXACT,
    SENSOR_IDEAL,
    ActuatorRecord,
    ControllerRecord,
    LinearPlantRecord,
    ObserverRecord,
    Outputs,
    SensorRecord,
    SignalRecord,
    Work,
)
from ._result import SimulationResult
from ._signal_table import midpoint_table

__all__ = [
    "DEFAULT_SUBSTEPS",
    "DIVERGENCE_LIMIT",
    "MAX_PLANT_STEPS",
    "SimulationDivergedWarning",
    "default_substeps",
    "metrics_run_inputs",
    "run_loop",
    "run_metrics",
    "simulate",
]

#: A run stops when |theta| [rad] or |omega| [rad/s] exceeds this, or the state is not finite.
DIVERGENCE_LIMIT = 1e9


class SimulationDivergedWarning(RuntimeWarning):
    """A simulation stopped early because the closed loop diverged."""


def default_substeps(plant, Ts: float) -> int:
    """Default sub-steps per sample of ``plant`` (see :meth:`hpdob.models.Plant.substeps`):
    8 for the rigid servo, more (an even number) for stiff Coulomb friction
    (``h c / (v J) <= 0.5``) or a stiff environment (``h sqrt(k_e / J) <= 0.06``)."""
    return plant.substeps(Ts, None)


#: The default initial state of a run: at rest at 0 (by identity: no check needed).
AT_REST = (0.0, 0.0)


def check_run_arguments(Ts, duration, substeps=None, x0=AT_REST):
    """``(Ts, duration, substeps, x0)`` checked with :func:`simulate`'s messages: two positive
    floats [s], a positive int or None, and a new float array ``[theta, omega]``."""
    Ts = positive(Ts, "Ts", "a positive finite sampling period [s]")
    duration = positive(duration, "duration", "a positive finite duration [s]")
    if substeps is not None:
        substeps = as_int(
            substeps, "substeps", "a positive integer number of sub-steps per sample", minimum=1
        )
    if x0 is AT_REST:
        x0 = np.zeros(2)
    else:
        x0 = as_real_vector(x0, "x0", "an initial state [theta (rad), omega (rad/s)]", length=2)
    return Ts, duration, substeps, x0


def sample_count(Ts: float, duration: float) -> int:
    ratio = duration / Ts
    if not ratio <= MAX_PLANT_STEPS:  # also inf: duration/Ts beyond the float range
        raise ParameterValueError(
            f"duration/Ts = {duration!r} s / {Ts!r} s = {ratio:.3g} samples exceeds the limit "
            f"of {MAX_PLANT_STEPS:.0e} per run; shorten duration or raise Ts"
        )
    n = round(ratio)
    if n < 1 or abs(n * Ts - duration) > 1e-9 * duration:
        raise ParameterValueError(
            f"duration must be a positive multiple of Ts={Ts!r} s, got "
            f"{duration!r} s ({duration / Ts:.6g} samples)"
        )
    return n


def _call(function, t: np.ndarray, name: str):
    try:
        # floating-point overflow shows up as a non-finite sample, reported with its time by
        # _as_samples: numpy's RuntimeWarning on top of that would only add lines
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            return function(t)
    except (ParameterValueError, ParameterTypeError):
        raise
    except Exception as err:
        raise ParameterValueError(
            f"{name} failed when called on an array of {t.size} times: {type(err).__name__}: {err}"
        ) from err


def _as_samples(values, t: np.ndarray, name: str) -> np.ndarray:
    try:
        raw = np.asarray(values)
    except (TypeError, ValueError):
        raw = None
    if raw is not None and raw.dtype.kind == "c":  # a cast would drop the imaginary part
        raise ParameterValueError(
            f"{name} must be real-valued, got complex values of dtype {raw.dtype.name}"
        )
    try:
        values = np.asarray(raw if raw is not None else values, dtype=float)
    except OverflowError:  # an object array holding an int beyond the float range
        raise ParameterValueError(f"{name} has a value beyond the float range") from None
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


@accepts_loop
def simulate(
    loop: ServoLoop,
    *,
    reference,
    duration: float,
    disturbance=None,
    substeps: int | None = None,
    x0=AT_REST,
    label: str = "",
    observer_state=None,
    progress=None,
) -> SimulationResult:
    r"""Simulate the sampled-data loop: continuous plant, sampled PD, observer inner loop.

    The rigid plant's continuous dynamics are
    :math:`J\ddot\theta = u - b\omega - c\tanh(\omega/v) - \tau_{ext}(t)` with ``u`` held over
    each sample (ZOH). It is advanced in ``substeps`` sub-steps per sample: the linear part by
    its exact discretisation, the Coulomb friction and ``disturbance`` by an exponential midpoint
    rule (see ``hpdob.simulation._kernel``); a :class:`~hpdob.TwoMassServo` likewise, a
    :class:`~hpdob.MujocoServo` by MuJoCo. At each sample the controller and the observer see
    the sensor's measurement, in the order: estimate, control, update (see
    :class:`~hpdob.Observer`).

    Parameters
    ----------
    loop : ServoLoop
        Plant, nominal model, ``Ts``, controller, observer, sensor and actuator; or its parts
        as keyword arguments (the loop functions' one alias rule,
        :data:`hpdob.simulation.LOOP_KEYS`).
    reference : Signal or callable
        A :class:`~hpdob.signals.Signal`, or a callable taking the array of sampling instants and
        returning ``(r, r_dot, r_ddot)`` arrays [rad, rad/s, rad/s^2].
    duration : float
        Simulated time [s], a multiple of ``Ts``; samples are at ``k Ts`` for
        ``0 <= k < duration/Ts``.
    disturbance : callable, optional
        External torque [N m] as a vectorised function of time (a Signal or any callable). It
        is evaluated once per run, on two arrays: the sampling instants ``k Ts`` (recorded as
        ``tau_ext`` and used for the ground truth) and the sub-step midpoints
        ``k Ts + (j + 1/2) Ts/substeps`` (used by the integrator). On a two-mass plant it acts
        on the load. None: no disturbance.
    substeps : int, optional
        Plant sub-steps per sample. Default: 8, raised to an even number with
        ``h c / (v J) <= 0.5`` for stiff Coulomb friction (:func:`default_substeps`; e.g. 66 for
        the canonical plant with ``coulomb_velocity = 1e-3``) and with
        ``h sqrt(k_e / J) <= 0.06`` for a stiff :class:`~hpdob.Environment` (32 at
        1000 N m/rad on the paper's motor). For a :class:`MujocoServo` these
        are MuJoCo steps of ``Ts/substeps``; if the servo has its own ``timestep``, ``substeps``
        is ``Ts/timestep`` (None or that value).
    x0 : sequence of 2 floats, optional
        Initial motor state ``[theta (rad), omega (rad/s)]``; default at rest at 0 (a two-mass
        plant starts with the load at the motor's angle and velocity).
    label : str, optional
        Name stored in the result.
    observer_state : sequence of float, optional
        The observer's state at the first sample (e.g. ``initial_state(design, x0, tau0)``,
        or a runtime observer's ``.state``). Default: the loop's (converged on zero
        disturbance at ``x0``, :meth:`ServoLoop.initial_observer_state`).
    progress : callable, optional
        Called as ``progress(done, total)`` with the samples completed, at the start and
        after every chunk of about 2**20 plant steps. The run is then a sequence of calls of
        the same compiled sample loop over consecutive samples, its whole state carried
        between them in the same arrays, so the result is bit for bit that of one call. It
        sees counts only; a display with the time left is the caller's (``hpdob simulate
        --progress``).

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
    >>> from hpdob import PD, ServoLoop, ServoModel, simulate
    >>> from hpdob.signals import Step, SmoothStep
    >>> plant, nominal = ServoModel(3.06e-4, 5e-5), ServoModel(2.8e-4)
    >>> loop = ServoLoop(plant=plant, nominal=nominal, Ts=1e-3, controller=PD(50, 5),
    ...                  observer={"order": 1, "bandwidth": 100.0})
    >>> result = simulate(loop, duration=2.0, reference=SmoothStep(0.2, 1.2, 1.0),
    ...                   disturbance=Step(1.5005, 0.05))
    >>> m = result.metrics(regulation=(1.2, 2.0))
    >>> print(f"{m['rms_position_error_regulation']:.4f} rad")
    0.0064 rad
    """
    Ts, duration, substeps, x0 = check_run_arguments(loop.Ts, duration, substeps, x0)
    n = sample_count(Ts, duration)
    S = run_substeps(loop.plant, Ts, substeps)
    if not isinstance(label, str):
        raise ParameterTypeError(f"label must be a str, got {type(label).__name__}")
    state = None if observer_state is None else check_observer_state(loop, observer_state)
    if progress is not None and not callable(progress):
        raise ParameterTypeError(
            f"progress must be a callable progress(done, total), got {progress!r}"
        )
    signals = sample_signals(reference, disturbance, Ts=Ts, n=n, substeps=S)
    result = run_loop(loop, signals, x0, label=label, observer_state=state, progress=progress,
                      ahead_of_time=True)  # fmt: skip
    if result.diverged:
        warnings.warn(result.message, SimulationDivergedWarning, stacklevel=3)
    return result


def check_observer_state(loop: ServoLoop, state) -> tuple:
    """``state`` as a tuple of the loop observer's state size, finite (checked up front)."""
    if loop.system is None:
        raise ParameterValueError("observer_state needs a loop with an observer, got none")
    n = loop.system.n_states
    values = np.asarray(state, dtype=float) if not isinstance(state, (str, bytes)) else None
    if values is None or values.shape != (n,) or not np.all(np.isfinite(values)):
        raise ParameterValueError(
            f"observer_state must be {n} finite floats (the state of {loop.system.name}), "
            f"got {state!r}"
        )
    return tuple(values.tolist())


class SampledSignals(NamedTuple):
    """Reference and disturbance evaluated on a run's time grids (see :func:`simulate`).

    ``midpoint`` is the disturbance as a table the compiled loop evaluates at the sub-step
    midpoints (``(form, table)`` of :func:`~hpdob.simulation._signal_table.midpoint_table`,
    ``tau_mid`` then empty), or None: ``tau_mid`` holds its ``n * substeps`` values. The
    midpoint values are multiplied by ``factor`` (:meth:`scaled`)."""

    Ts: float
    substeps: int
    t: np.ndarray
    r: np.ndarray
    r_dot: np.ndarray
    r_ddot: np.ndarray
    tau_sample: np.ndarray
    tau_mid: np.ndarray
    midpoint: tuple | None = None
    factor: float = 1.0
    disturbance: object = None

    def scaled(self, factor: float) -> SampledSignals:
        """The same signals with the disturbance multiplied by ``factor``."""
        if factor == 1.0:
            return self
        if self.midpoint is not None and self.factor != 1.0:  # f2 (f1 v), as twice in numpy
            return self._replace(
                tau_sample=factor * self.tau_sample, tau_mid=factor * self.midpoints(),
                midpoint=None, factor=1.0,
            )  # fmt: skip
        return self._replace(
            tau_sample=factor * self.tau_sample, tau_mid=factor * self.tau_mid,
            factor=factor if self.midpoint is not None else 1.0,
        )  # fmt: skip

    def midpoints(self) -> np.ndarray:
        """The disturbance at the ``n * substeps`` sub-step midpoints (sampled in numpy where
        the compiled loop would evaluate it: a plant advanced from Python reads the array)."""
        if self.midpoint is None:
            return self.tau_mid
        n, S, Ts = self.t.size, self.substeps, self.Ts
        if self.disturbance is None:
            values = np.zeros(n * S)
        else:
            t_mid = (self.t[:, None] + (np.arange(S) + 0.5) * (Ts / S)).ravel()
            values = _disturbance(self.disturbance, t_mid)
        return values if self.factor == 1.0 else self.factor * values


#: Signals sampled on a time grid, by (reference, disturbance, Ts, n, substeps), for hpdob's
#: Signals (frozen values: equal signals give equal samples); least recently used first.
_SAMPLED: collections.OrderedDict = collections.OrderedDict()
_SAMPLED_LOCK = threading.Lock()
_BUILT_IN = (Constant, Step, Ramp, SmoothStep, Sine, Chirp, Noise)
#: At most this many grids and bytes are kept (the canonical 10 s run's take 0.4 MB).
SAMPLED_GRIDS, SAMPLED_BYTES = 16, 64 << 20


#: The sampled arrays a result holds as its columns (t, r, r_dot, r_ddot, tau_ext).
_COLUMNS = ("t", "r", "r_dot", "r_ddot", "tau_sample")


def clear_sampled_signals() -> None:
    """Forget the signals sampled on every time grid (:func:`sample_signals` samples them anew:
    what a benchmark of a first run needs)."""
    with _SAMPLED_LOCK:
        _SAMPLED.clear()


def _built_in(signal) -> bool:
    """Whether ``signal`` is made of hpdob's own (frozen) signal classes only: a subclass
    written elsewhere may hold state, so its samples are not kept."""
    if type(signal) is Sum:
        return all(_built_in(term) for _, term in signal.terms)
    return type(signal) in _BUILT_IN


def _grid_key(reference, disturbance, Ts, n, substeps):
    """The cache key of a run's signals, or None unless both are hpdob's own signals (the
    disturbance may be None)."""
    signal = reference.signal if type(reference) is _Trajectory else reference
    if not _built_in(signal) or not (disturbance is None or _built_in(disturbance)):
        return None
    return (signal, disturbance, float(Ts), int(n), int(substeps))


def sample_signals(reference, disturbance, *, Ts: float, n: int, substeps: int) -> SampledSignals:
    """Evaluate ``reference`` at ``k Ts`` and ``disturbance`` at ``k Ts`` and the sub-step
    midpoints ``k Ts + (j + 1/2) Ts / substeps``, ``0 <= k < n``, with validation.

    hpdob's built-in signals that the compiled loop evaluates itself
    (:func:`~hpdob.simulation._signal_table.midpoint_table`: constants, steps, ramps, sines
    and their sums) are not evaluated at the midpoints here: their table is kept instead.
    hpdob's Signals are evaluated once per time grid: the read-only arrays of the last
    :data:`SAMPLED_GRIDS` grids are kept (a repeated run, ``tune``'s candidates, a sweep's
    scenarios of one grid) and a later call gets read-only copies of the columns a result
    holds; other callables are evaluated on every call.
    """
    key = _grid_key(reference, disturbance, Ts, n, substeps)
    if key is not None:
        with _SAMPLED_LOCK:
            cached = _SAMPLED.get(key)
            if cached is not None:
                _SAMPLED.move_to_end(key)
        if cached is not None:  # the columns of a result are its own: copies (a memcpy)
            copies = {name: getattr(cached, name).copy() for name in _COLUMNS}
            for array in copies.values():  # read-only as the kept ones (see run_loop)
                array.flags.writeable = False
            return cached._replace(**copies)
    signals = _sample_signals(reference, disturbance, Ts=Ts, n=n, substeps=substeps)
    if key is not None:
        arrays = [a for a in signals if isinstance(a, np.ndarray)]
        for array in arrays:
            array.setflags(write=False)
        with _SAMPLED_LOCK:
            _SAMPLED[key] = signals
            while _SAMPLED and (len(_SAMPLED) > SAMPLED_GRIDS or sum(
                sum(a.nbytes for a in v if isinstance(a, np.ndarray)) for v in _SAMPLED.values()
            ) > SAMPLED_BYTES):  # fmt: skip
                _SAMPLED.popitem(last=False)
    return signals


def _sample_signals(reference, disturbance, *, Ts: float, n: int, substeps: int) -> SampledSignals:
    if n * substeps > MAX_PLANT_STEPS:
        raise ParameterValueError(
            f"duration/Ts * substeps = {n} * {substeps} = {n * substeps:.3g} plant steps exceeds "
            f"the limit of {MAX_PLANT_STEPS:.0e} per run (the sub-step disturbance alone would "
            f"need {8 * n * substeps / 1e9:.3g} GB); shorten duration, raise Ts or lower "
            f"substeps (or the stiffness c/(v J) of the Coulomb friction that sets the default)"
        )
    t = np.arange(n) * Ts
    r, r_dot, r_ddot = _reference(reference, t)
    midpoint = None
    if disturbance is None:
        tau_sample, tau_mid = np.zeros(n), np.zeros(0)
        midpoint = ((True, ()), np.zeros(0))  # 0.0 at every midpoint
    elif callable(disturbance):
        tau_sample = _disturbance(disturbance, t)
        midpoint = midpoint_table(disturbance, n * Ts)
        if midpoint is None:
            t_mid = (t[:, None] + (np.arange(substeps) + 0.5) * (Ts / substeps)).ravel()
            tau_mid = _disturbance(disturbance, t_mid)
        else:
            tau_mid = np.zeros(0)
    else:
        raise ParameterTypeError(
            "disturbance must be a callable of time (e.g. an hpdob Signal) "
            f"or None, got {type(disturbance).__name__}"
        )
    return SampledSignals(Ts, substeps, t, r, r_dot, r_ddot, tau_sample, tau_mid, midpoint,
                          1.0, disturbance)  # fmt: skip


def _observer_record(system) -> ObserverRecord:
    if system is None:
        empty_i, empty_f = np.zeros(1, dtype=np.int64), np.zeros(0)
        return ObserverRecord(False, 0, 1, 1, -1, -1, 0, 0.0, 1.0, 0.0, empty_i, empty_f,
                              empty_i[:0], empty_i, empty_f, empty_i[:0])  # fmt: skip
    update, output, _ = system.kernel_arrays
    outputs = system.outputs
    velocity = outputs.index("omega_hat") if "omega_hat" in outputs else -1
    reaction = outputs.index("tau_reac") if "tau_reac" in outputs else -1
    term = system.coulomb  # the RTOB's Coulomb term, subtracted after the linear outputs
    source = 0 if term is None else (1 if term.velocity == "omega" else 2)
    return ObserverRecord(
        True,
        system.n_states,
        len(system.measures),
        len(outputs),
        velocity,
        reaction,
        source,
        0.0 if term is None else term.c,
        1.0 if term is None else term.v,
        0.0 if term is None else term.deadband,
        *update,
        *output,
    )


def _controller_record(loop) -> ControllerRecord:
    controller = loop.controller_system
    sources = controller_sources(loop.system)
    signals, update, _ = controller.kernel_arrays
    switch = controller.program.switch
    switching = (
        (-1, 0, 0.0, 0, 0.0)
        if switch is None
        else (switch.latch, switch.trigger, switch.threshold, switch.after, switch.offset)
    )
    return ControllerRecord(
        loop.nominal.J, loop.nominal.b, controller.n_states, len(controller.inputs),
        len(controller.program.signals),
        np.array([sources.index(name) for name in controller.inputs], dtype=np.int64),
        *signals, *update, *switching,
    )  # fmt: skip


#: The ideal sensor's record (immutable: one for every run without an encoder).
_IDEAL_SENSOR = SensorRecord(SENSOR_IDEAL, 1.0)


def _sensor_record(sensor, n: int) -> tuple[SensorRecord, np.ndarray]:
    if sensor is None:  # no noise: the loop reads none (the shared read-only empty array)
        return _IDEAL_SENSOR, _EMPTY
    mode = SENSOR_ENCODER_EXACT if sensor.velocity == "exact" else SENSOR_ENCODER_DIFFERENCE
    noise = np.zeros(0)  # no noise: the compiled loop reads none
    if sensor.noise_std > 0:
        seed = 0 if sensor.seed is None else sensor.seed
        noise = sensor.noise_std * np.random.default_rng(seed).standard_normal(n)
    return SensorRecord(mode, sensor.resolution), noise


def _loop_records(loop: ServoLoop) -> tuple:
    """The kernel's records of ``loop``'s controller, actuator and observer (read-only
    inputs of every run: computed once per loop)."""
    actuator = loop.actuator
    limit = math.inf if actuator.torque_limit is None else actuator.torque_limit
    system = loop.system  # a design shared by many loops (a sweep's plants): its record once
    observer = derived(system, "record", lambda: _observer_record(system))
    nominal = loop.nominal  # the controller's likewise, per nominal model and observer outputs
    key = ("record", float(nominal.J).hex(), float(nominal.b).hex(), controller_sources(system))
    record = derived(loop.controller_system, key, lambda: _controller_record(loop))
    return record, ActuatorRecord(limit, actuator.delay_samples), observer


#: Plant steps between two calls of a run's ``progress`` (the chunk of samples run by one
#: call of the compiled loop; one call for the whole run without ``progress``).
PROGRESS_PLANT_STEPS = 1 << 20


#: An empty array for the record fields a run does not use (the loop never reads them).
_EMPTY = np.zeros(0)
_EMPTY.setflags(write=False)


def _run_inputs(loop: ServoLoop, signals: SampledSignals, x0, observer_state=None,
                tau_mid=None):  # fmt: skip
    """``(records, work, sampler, midpoint)`` of a run of ``loop`` on ``signals`` from ``x0``:
    the kernel's read-only records (``sig``, ``sen``, ``ctl``, ``act``, ``obs``, and ``plant``
    for a plant the compiled loop advances), its ``Work`` state, the plant's sampler and the
    disturbance's midpoint table (``(form, table)``, or None: the loop reads ``sig.tau_mid``).
    ``tau_mid``: the disturbance at the sub-step midpoints, already sampled (a sweep's grid),
    read instead of the table."""
    Ts, S, n = signals.Ts, signals.substeps, signals.t.size
    plant = loop.plant
    sensor, noise = _sensor_record(loop.sensor, n)
    ctl, act, obs = derived(loop, "records", lambda: _loop_records(loop))  # once per loop
    records = {"ctl": ctl, "sen": sensor, "act": act, "obs": obs}
    x = plant.initial_state(x0)
    sampler = plant_sampler(plant, Ts, S)
    compiled = isinstance(sampler, ExactSubsteps)
    # the disturbance at the sub-step midpoints: evaluated by the compiled loop from its table
    # (factor first), else read from the sampled array
    midpoint = signals.midpoint if compiled and tau_mid is None else None
    table = _EMPTY if midpoint is None else np.concatenate(([signals.factor], midpoint[1]))
    if tau_mid is None:
        tau_mid = signals.tau_mid if compiled else signals.midpoints()
    noise.flags.writeable = table.flags.writeable = False  # this run's own: no views needed
    # read-only, so that every run of a structure is one numba signature (read_only_view)
    records["sig"] = SignalRecord(*map(read_only_view, (
        signals.r, signals.r_dot, signals.r_ddot, signals.tau_sample, tau_mid, noise, table,
    )))  # fmt: skip
    state = observer_state
    if state is None:  # a pure function of the design and x0
        key = ("initial state", np.asarray(x0, dtype=float).tobytes())
        state = derived(loop.system, key, lambda: loop.initial_observer_state(x0))
    s = np.array(state if state is not None else (), dtype=float)
    c = np.array(loop.controller_system.python.reset(float(x0[0]), float(x0[1]), 0.0))
    work = Work(s, s.copy(), np.zeros(s.size + 3), c, c.copy(),
                np.zeros(ctl.n + ctl.p + 1 + ctl.q), np.zeros(5 + obs.q),
                np.zeros(1), x, x.copy(), np.zeros(1))  # fmt: skip
    if compiled:  # a frozen sampler's record, made once (the sampler is kept on its plant)
        records["plant"] = derived(sampler, "record", lambda: _plant_record(sampler))
    return records, work, sampler, midpoint


def _plant_record(sampler: ExactSubsteps) -> LinearPlantRecord:
    wall = sampler.environment
    return LinearPlantRecord(
        True, sampler.path_index, sampler.velocity_index, sampler.A_h, sampler.B_h, sampler.D_h,
        sampler.A_half, sampler.B_half, sampler.D_half, sampler.shared, sampler.internal,
        sampler.J_motor, sampler.coulomb, sampler.coulomb_velocity, wall is not None,
        sampler.contact_index, *((wall.stiffness, wall.damping, wall.position)
                                 if wall is not None else (1.0, 0.0, 0.0)),
    )  # fmt: skip


def _run_compiled(signals, records, out, work, midpoint, *, progress=None, errors=False,
                  ahead_of_time=False) -> int:  # fmt: skip
    """Run the compiled loop over the whole run (in chunks of :data:`PROGRESS_PLANT_STEPS` plant
    steps with ``progress``); the number of samples completed. ``ahead_of_time``: a built loop
    matching the run (:func:`~hpdob.simulation._aot.simulate_loop`) if there is one, without
    importing numba; else, and by default, the JIT loop."""
    Ts, S, n = signals.Ts, signals.substeps, signals.t.size
    form = None if midpoint is None else midpoint[0]
    run = None
    if ahead_of_time:
        from . import _aot

        run = _aot.simulate_loop(
            n, S, Ts, records["plant"], records["ctl"], records["sen"], records["act"],
            records["obs"], records["sig"], out, work, DIVERGENCE_LIMIT, form,
        )  # fmt: skip
    if run is None:
        from . import _kernel  # numba is imported on the first run, not by ``import hpdob``

        def run(start: int, stop: int) -> int:
            return _kernel.run_samples(
                start, stop, S, Ts, records["plant"], records["ctl"], records["sen"],
                records["act"], records["obs"], records["sig"], out, work, DIVERGENCE_LIMIT,
                form, errors,
            )  # fmt: skip

    chunk = n if progress is None else max(1, PROGRESS_PLANT_STEPS // S)
    done = 0
    if progress is not None:
        progress(0, n)
    while done < n:  # one call without progress: the chunk is the whole run
        stop = min(n, done + chunk)
        done = run(done, stop)
        if progress is not None:
            progress(done, n)
        if done < stop:  # diverged
            break
    return done


def _diverged_message(label: str, done: int, Ts: float, unstable: str = "") -> str:
    return (
        f"{label or 'simulation'} diverged: |theta| or |omega| exceeded "
        f"{DIVERGENCE_LIMIT:g} (or became non-finite{unstable}) by t = {done * Ts:.6g} s; "
        f"the result holds the {done} samples before that"
    )


def run_loop(loop: ServoLoop, signals: SampledSignals, x0, *, label: str = "",
             observer_state=None, progress=None,
             ahead_of_time=False) -> SimulationResult:  # fmt: skip
    """Run ``loop`` on pre-sampled signals from the motor state ``x0`` (no warning).

    The shared engine of :func:`simulate` and :func:`hpdob.sweep`. The plant's sampler decides
    how it is advanced: :class:`~hpdob.models.ExactSubsteps` by the compiled kernel, any other
    by the Python loop around the compiled sample step (MuJoCo). ``observer_state`` overrides
    the loop's initial observer state. ``progress(done, total)`` is called at the start and
    after every :data:`PROGRESS_PLANT_STEPS` plant steps: the kernel then runs the samples in
    consecutive chunks, its whole state (observer, controller, plant, encoder) carried in
    ``work`` and the actuator's delay line read from ``out``, as every sample does within one
    call, so the result is bit for bit the same. ``ahead_of_time`` (:func:`simulate`'s single
    runs): a loop built by :func:`~hpdob.simulation.build_loop_extension` for the run's
    structure is used if one is there; a sweep and ``tune()`` keep the JIT loop (``nogil``).
    """
    Ts, S, t = signals.Ts, signals.substeps, signals.t
    n = t.size
    plant, system = loop.plant, loop.system
    records, work, sampler, midpoint = _run_inputs(loop, signals, x0, observer_state)
    compiled = "plant" in records
    nx = work.x.size

    def optional(present):  # an output the run records, else an empty array the loop never reads
        return np.zeros(n) if present else np.zeros(0)

    contact = not compiled or sampler.environment is not None
    out = Outputs(
        *(np.zeros(n) for _ in range(7)),
        optional(system is not None and system.has_velocity),
        np.zeros((n if nx > 2 else 0, nx)),
        optional(contact),
        optional(contact),
        optional(system is not None and "tau_reac" in system.outputs),
    )
    environment = getattr(plant, "environment", None)
    if compiled:
        done = _run_compiled(signals, records, out, work, midpoint, progress=progress,
                             ahead_of_time=ahead_of_time)  # fmt: skip
        unstable = ""
    else:
        from ._python_plant import run_python_plant

        session = sampler.start(work.x)
        every = None if progress is None else max(1, PROGRESS_PLANT_STEPS // S)
        done = run_python_plant(session, n, S, Ts, records, out, work, DIVERGENCE_LIMIT,
                                progress=progress, every=every)  # fmt: skip
        unstable = f" or {getattr(session, 'engine', 'the plant')} flagged it unstable"
    diverged = done < n
    message = _diverged_message(label, done, Ts, unstable) if diverged else "ok"
    keep = slice(0, done)
    extra = {}
    if system is not None and system.has_velocity:
        extra["omega_hat"] = out.omega_hat[keep]
    if system is not None and "tau_reac" in system.outputs:
        extra["tau_reac"] = out.tau_reac[keep]
    if environment is not None or getattr(plant, "contact_geom", None) is not None:
        extra["tau_contact"] = out.tau_contact[keep]
        extra["in_contact"] = out.in_contact[keep]
    names = plant.state_names
    for name in ("theta_load", "omega_load"):
        if name in names and out.states.shape[0]:
            extra[name] = out.states[keep, names.index(name)]
    return SimulationResult._of_arrays(  # arrays this run made: no copies
        t=t[keep],
        theta=out.theta[keep],
        omega=out.omega[keep],
        theta_measured=out.theta_m[keep],
        omega_measured=out.omega_m[keep],
        r=signals.r[keep],
        r_dot=signals.r_dot[keep],
        r_ddot=signals.r_ddot[keep],
        u=out.u[keep],
        tau_hat=out.tau_hat[keep],
        tau_dn=out.tau_dn[keep],
        tau_ext=signals.tau_sample[keep],
        Ts=Ts,
        label=label,
        diverged=diverged,
        message=message,
        **extra,
    )


class _ErrorOutputs(NamedTuple):
    """What the error-recording loop writes (:func:`run_metrics`): the delay line, the two
    error traces and the optional outputs of the loop's structure."""

    u: np.ndarray
    estimation_error: np.ndarray
    position_error: np.ndarray
    omega_hat: np.ndarray
    tau_reac: np.ndarray


#: Per thread: the arrays :func:`run_metrics` lends the loop, reused by the next run of that
#: thread (a sweep's scenarios: no allocation per scenario, the memory stays in the cache).
_SCRATCH = threading.local()
#: Runs of at most this many samples use the thread's kept arrays (5 x 2 MB); longer ones get
#: their own, freed with the run (a long-lived worker thread keeps no more than that).
SCRATCH_SAMPLES = 1 << 18


def _scratch(n: int) -> _ErrorOutputs:
    """Views of ``n`` entries of this thread's scratch arrays (grown when too small, up to
    :data:`SCRATCH_SAMPLES`; beyond, new arrays not kept). The views of the last ``n`` are
    kept with them: a sweep's scenarios of one grid ask for the same ``n`` every time."""
    views = getattr(_SCRATCH, "views", None)
    if views is not None and views[0] == n:
        return views[1]
    arrays = getattr(_SCRATCH, "arrays", None)
    if arrays is None or arrays.shape[1] < n:
        arrays = np.empty((len(_ErrorOutputs._fields), n))
        if n > SCRATCH_SAMPLES:  # this run's own
            return _ErrorOutputs(*(row[:n] for row in arrays))
        _SCRATCH.arrays = arrays
    outputs = _ErrorOutputs(*(row[:n] for row in arrays))
    _SCRATCH.views = (n, outputs)
    return outputs


def error_run_applies(loop: ServoLoop, Ts: float, substeps: int) -> bool:
    """Whether :func:`run_metrics` runs ``loop`` at ``(Ts, substeps)``: a plant the compiled
    loop advances (not MuJoCo) and no environment (whose contact and force metrics read the
    contact traces of a full run)."""
    sampler = plant_sampler(loop.plant, Ts, substeps)
    return isinstance(sampler, ExactSubsteps) and sampler.environment is None


def metrics_run_inputs(loop: ServoLoop, signals: SampledSignals, x0, *, tau_mid=None):
    """The compiled loop's inputs of :func:`run_metrics` (records, work state, midpoint table),
    made before the run (a sweep prepares a batch of scenarios' at a time); the arguments
    as :func:`run_metrics` takes them."""
    records, work, _, midpoint = _run_inputs(loop, signals, x0, tau_mid=tau_mid)
    return records, work, midpoint


def run_metrics(loop: ServoLoop, signals: SampledSignals, x0, *, windows: dict, tau_mid=None,
                inputs=None):  # fmt: skip
    """The metrics of :func:`run_loop`'s result, computed without recording its traces.

    For a loop that :func:`error_run_applies` to. The compiled loop records only the
    estimation and the position error (``tau_hat - tau_dn`` and ``theta - r``: the same
    subtractions numpy performs on a result's traces, see
    :func:`~hpdob.simulation._kernel.loop_source`) into this thread's scratch arrays, and the
    metrics are computed from them in one compiled call with the arithmetic of the functions
    :class:`SimulationResult` uses (:func:`~hpdob.simulation._row_kernel.row_metrics`: numpy's
    pairwise sum), so they are bit for bit ``run_loop(...).metrics(**windows)`` and its
    ``max_abs_position_error()``.

    Parameters
    ----------
    loop : ServoLoop
        The validated loop.
    signals : SampledSignals
        The run's sampled signals (:func:`sample_signals`, scaled as the run's).
    x0 : ndarray
        The motor's initial state ``[theta (rad), omega (rad/s)]``, checked.
    windows : dict
        ``{"regulation": (start, stop), "tracking": (start, stop)}`` [s].
    tau_mid : ndarray, optional
        The disturbance at the ``n * substeps`` sub-step midpoints, as the loop would evaluate
        it from ``signals.midpoint`` (:func:`~hpdob.simulation._kernel.midpoint_filler`, a
        sweep's one array per time grid); None: the loop evaluates the table, or reads
        ``signals.tau_mid``.
    inputs : tuple, optional
        :func:`metrics_run_inputs` of the same arguments, made earlier (then ``tau_mid`` is
        the one given there); None: made here.

    Returns
    -------
    tuple
        ``(metrics, diverged, message)``: the three metrics of :meth:`SimulationResult.metrics`
        and ``max_abs_position_error`` [rad] over the samples run, whether the run diverged
        and :func:`run_loop`'s message (``"ok"``, or where it stopped).
    """
    n = signals.t.size
    if inputs is None:
        inputs = metrics_run_inputs(loop, signals, x0, tau_mid=tau_mid)
    records, work, midpoint = inputs
    out = _scratch(n)
    done = _run_compiled(signals, records, out, work, midpoint, errors=True)
    from ._row_kernel import row_metrics  # one compiled pass: error_metrics' numbers

    metrics = row_metrics(signals.t[:done], out.estimation_error[:done],
                          out.position_error[:done], **windows)  # fmt: skip
    diverged = done < n
    return metrics, diverged, _diverged_message("", done, signals.Ts) if diverged else "ok"
