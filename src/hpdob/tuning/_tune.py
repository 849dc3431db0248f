r"""``tune``: recommend the observer for a motor, a sensor and an uncertainty, and prove it.

The search (``docs/tuning.md``):

1. **Candidates**: every family (the order-m observers measuring the state, their
   position-only versions, ADRC's ESO in current form, the Kalman observer) x orders x a
   log-spaced grid of bandwidths from 5 rad/s to ``0.4 pi/Ts`` (for the Kalman observer, of
   process noises spanning the same bandwidths).
2. **Analytic figures**, no simulation: the estimation error for a disturbance at
   ``disturbance_frequency`` (``|1 - Q|`` of the closed-form or state-space estimation
   response, or its RMS over a band), the noise in the estimate and in ``u`` from the sensor
   (exact closed-loop noise gains from the Lyapunov equation, times the encoder's ``q/sqrt(12)``
   and the sensor's noise std), and the closed-loop spectral radius at every corner of the
   inertia/friction uncertainty set, with the actuator's delay and with **one extra sample of
   delay** (the documented robustness margin).
3. **Robust set**: the candidates stable at every corner with the extra sample of delay and
   within ``noise_limit`` (their Pareto front of error and noise is marked for reference).
4. **Simulation**: each candidate of the robust set runs the nonlinear loop (sensor, actuator,
   Coulomb friction) on the verification scenario at the centre of the uncertainty set (a few
   milliseconds each: the compiled kernel); the best for ``objective`` is then **verified at
   every corner** of the set (a divergent corner, or one whose linear loop is unstable,
   disqualifies it and the next one is tried). The analytic figures alone rank badly: the
   error at one frequency misses the steps, the delay and the friction a real run has (an
   order-2 observer looks best at 2 Hz, a first-order one is best in simulation).
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np

from .._blas import one_blas_thread
from .._interrupts import checkpoint
from .._validation import (
    ParameterTypeError,
    ParameterValueError,
    check_choice,
    nonnegative,
    positive,
    require_instance,
)
from ..analysis import MAX_DELAY_SAMPLES
from ..controllers import PD, Controller, controller_settings, controller_system
from ..models import ServoModel
from ..simulation import MISSING, Actuator, Encoder, loop_parts
from ._result import TuningResult
from ._runs import VerificationRuns

__all__ = ["OBJECTIVES", "candidate_families", "tune"]


def candidate_families() -> dict:
    """The families the tuner searches, by name: ``{name: (family, spec, orders)}``.

    Every registered family's ``variants`` (:func:`hpdob.observers.register_family`): the
    paper's family as ``"state"`` and ``"position"``, ``"eso"`` (current form), ``"kalman"``,
    and any family registered since.

    Returns
    -------
    dict
        ``{name: (Family, spec, orders)}``: the spec without the order and the tuned
        parameter, and the orders searched.
    """
    from ..observers import families

    return {
        name: (family, {"type": family.name, **spec}, family.orders)
        for family in families()
        for name, spec in family.variants.items()
    }


OBJECTIVES = ("estimation", "position")
N_BANDWIDTHS = 24
MIN_BANDWIDTH = 5.0  # rad/s
#: The delay margin scan stops here [extra samples]: a margin reported as this is "at least".
MAX_EXTRA_DELAY = 20


def _range(value, name: str, what: str, *, allow_zero: bool) -> tuple[float, float]:
    if isinstance(value, (str, bytes)) or np.ndim(value) != 1 or len(value) != 2:
        raise ParameterValueError(f"{name} must be a (low, high) pair of {what}, got {value!r}")
    check = nonnegative if allow_zero else positive
    low, high = (check(v, name, f"a pair of {what}") for v in value)
    if low > high:
        raise ParameterValueError(f"{name} must have low <= high, got {value!r}")
    return low, high


def _frequencies(disturbance_frequency, Ts: float) -> np.ndarray:
    if disturbance_frequency is None:
        frequencies = np.geomspace(0.1, 10.0, 25)
    elif np.ndim(disturbance_frequency) == 0:
        what = "a positive frequency [Hz] or a (low, high) band"
        frequencies = np.array([positive(disturbance_frequency, "disturbance_frequency", what)])
    else:
        low, high = _range(disturbance_frequency, "disturbance_frequency",
                           "positive frequencies [Hz]", allow_zero=False)  # fmt: skip
        frequencies = np.geomspace(low, high, 25) if high > low else np.array([low])
    nyquist = 0.5 / Ts
    if not frequencies[-1] < nyquist and disturbance_frequency is None:
        raise ParameterValueError(
            f"the default disturbance band 0.1-10 Hz reaches the Nyquist frequency 1/(2 Ts) = "
            f"{nyquist:.6g} Hz of Ts = {Ts!r} s; give disturbance_frequency (--frequency) below it"
        )
    if not frequencies[-1] < nyquist:  # a sampled loop cannot tell it from its alias
        raise ParameterValueError(
            f"disturbance_frequency must be below the Nyquist frequency 1/(2 Ts) = {nyquist:.6g} "
            f"Hz, got {disturbance_frequency!r}"
        )
    return frequencies


def _sensor_noise(sensor) -> float:
    """Std [rad] of the white angle noise the sensor adds: q/sqrt(12) and its noise_std."""
    if sensor is None:
        return 0.0
    return math.hypot(sensor.resolution / math.sqrt(12.0), sensor.noise_std)


def _scenario(nominal, Ts, disturbance_frequency, scenario):
    """The verification run: the paper's reference and disturbance shape, with the sine at the
    disturbance frequency and the amplitudes scaled by J_n (the same disturbance acceleration
    as the paper's), unless given."""
    from ..signals import Sine, Step
    from ..simulation import MAX_PLANT_STEPS
    from ..simulation import canonical as paper  # the paper's set-up, as data

    if scenario is not None:
        if not isinstance(scenario, dict):
            raise ParameterTypeError(
                "scenario must be a dict with reference, disturbance and duration, got "
                f"{type(scenario).__name__}"
            )
        unknown = sorted(set(scenario) - {"reference", "disturbance", "duration"})
        if unknown or "reference" not in scenario or "duration" not in scenario:
            raise ParameterValueError(
                "scenario must have the keys reference and duration (and may have "
                f"disturbance), got {sorted(scenario)}"
            )
        return dict(scenario)
    f = 2.0 if disturbance_frequency is None else float(np.atleast_1d(disturbance_frequency)[0])
    scale = nominal.J / paper.NOMINAL.J  # the paper's disturbance acceleration at any J_n
    disturbance = Step(1.5005, 0.05 * scale) + Sine(0.02 * scale, f, start=2.5005)
    samples = paper.DURATION / Ts  # inf for a subnormal Ts: round() would overflow
    if not samples <= MAX_PLANT_STEPS:
        raise ParameterValueError(
            f"Ts must be at least {paper.DURATION:g} s / {MAX_PLANT_STEPS:.0e} = "
            f"{paper.DURATION / MAX_PLANT_STEPS:g} s (tune's {paper.DURATION:g} s verification "
            f"run holds at most {MAX_PLANT_STEPS:.0e} samples), got {Ts!r}"
        )
    duration = Ts * max(1, round(samples))  # the paper's 10 s, in whole samples
    return {"reference": paper.REFERENCE, "disturbance": disturbance, "duration": duration}


def _candidates(model, families, sigma, notes):
    """``[(family, order, parameter, value, design)]`` over the bandwidth grid (each family's
    tuned parameter over the values giving those bandwidths)."""
    from ..observers import design_from_spec, tuned_value

    g_max = 0.4 * math.pi / model.Ts
    bandwidths = np.geomspace(MIN_BANDWIDTH, g_max, N_BANDWIDTHS)
    out = []
    variants = candidate_families()
    for name in families:
        family, base, orders = variants[name]
        for m in orders:
            spec = dict(base) if family.order is None else {**base, family.order: m}
            if family.noise_parameter is not None:
                if sigma == 0.0:
                    notes.append(f"{name}: left out, it needs a measurement noise (no sensor)")
                    break
                spec[family.noise_parameter] = sigma
            if family.tuned_from_bandwidth is None:
                values = bandwidths
            else:  # the tuned parameter at the grid's two ends, log-spaced between
                low, high = (tuned_value(model, spec, float(g)) for g in bandwidths[[0, -1]])
                values = np.geomspace(low, high, N_BANDWIDTHS)
            grid = (family.tuned, values)
            left_out = []
            for value in grid[1]:
                try:
                    design = design_from_spec(model, {**spec, grid[0]: float(value)})
                except ParameterValueError as err:  # e.g. not realisable in double precision
                    left_out.append((float(value), str(err)))
                    continue
                out.append((name, m, grid[0], float(value), design))
            if left_out:
                values = [v for v, _ in left_out]
                first = left_out[0][1] if not out else left_out[0][1].split(":")[0]
                notes.append(
                    f"{name} m={m}: {len(values)} of {len(grid[1])} {grid[0]} values in "
                    f"[{min(values):.4g}, {max(values):.4g}] left out ({first})"
                )
            if family.order is None:
                break
    return out


def _radius(loop) -> float:
    from ..analysis import closed_loop_poles

    return float(np.abs(closed_loop_poles(loop)).max())


def _delay_margin(scan, delay: int) -> int:
    """Largest d <= MAX_EXTRA_DELAY such that the loop is stable at every corner with every
    extra delay of 0..d samples (a robust candidate is known to be stable with 0 and 1); the
    scan also stops where the linear loop's delay limit (MAX_DELAY_SAMPLES) does. ``scan`` is
    the candidate's :class:`~hpdob.analysis.RadiiScan` over the corners' plants."""
    for extra in range(2, min(MAX_EXTRA_DELAY, MAX_DELAY_SAMPLES - delay) + 1):
        if (scan.radii([delay + extra]) >= 1.0).any():
            return extra - 1
    return MAX_EXTRA_DELAY


@one_blas_thread
def tune(
    loop=None,
    /,
    *,
    nominal: ServoModel = MISSING,
    Ts: float = MISSING,
    controller: Controller | None = MISSING,
    sensor: Encoder | None = MISSING,
    actuator: Actuator | None = MISSING,
    J_range=(1.0, 1.0),
    b_range=None,
    disturbance_frequency=None,
    families=None,
    objective: str = "estimation",
    noise_limit: float | None = None,
    coulomb: float | None = None,
    scenario: dict | None = None,
    progress=None,
) -> TuningResult:
    r"""Recommend an observer for a motor, a sensor and an uncertainty, verified by simulation.

    Parameters
    ----------
    loop : ServoLoop, optional
        The loop to tune the observer of: its nominal model, ``Ts``, controller, sensor,
        actuator and (unless ``coulomb`` is given) its plant's Coulomb friction; its observer
        is what the search replaces. Instead of a loop, its parts ``nominal``, ``Ts``,
        ``controller``, ``sensor`` and ``actuator`` as keyword arguments, with the defaults
        below (the loop functions' one alias rule, :data:`hpdob.simulation.LOOP_KEYS`).
    nominal : ServoModel
        The nominal model (``J_n``, ``b_n``) of controller and observer.
    Ts : float
        Sampling period [s], below 0.25 s (the bandwidths searched run from 5 rad/s to
        ``0.4 pi/Ts``).
    controller : Controller, optional
        Outer loop (:class:`~hpdob.PD`, :class:`~hpdob.PID`, :class:`~hpdob.FilteredPD`,
        :class:`~hpdob.ADRC` or another controller of the protocol); default
        ``PD(50, 5, velocity="observer")`` (the paper's gains). With ``velocity="observer"``
        the derivative uses the observer's velocity estimate where it has one and the
        measured velocity otherwise.
    sensor : Encoder, optional
        Default: the ideal state. Its quantisation (``q/sqrt(12)``) and noise set the noise
        figures; without a sensor the noise is zero and the Kalman observer is left out.
    actuator : Actuator, optional
        Torque limit (in the simulations) and delay (in every figure). Default ideal.
    J_range : (float, float), optional
        True/nominal inertia ratios ``J/J_n`` the loop must be stable over. Default (1, 1).
    b_range : (float, float), optional
        True viscous frictions [N m s/rad]; default ``(b_n, b_n)``.
    disturbance_frequency : float or (float, float), optional
        Frequency [Hz] of the disturbance the accuracy is judged at (``|1 - Q|``), or a band
        (RMS of ``|1 - Q|`` over it), below the Nyquist frequency ``1/(2 Ts)``. Default: the band
        0.1-10 Hz (and 2 Hz for the verification scenario's sine).
    families : sequence of str, optional
        Any of ``"state"``, ``"position"``, ``"eso"``, ``"kalman"`` and the variants of any
        family registered since (:func:`candidate_families`). Default all.
    objective : {"estimation", "position"}, optional
        What the simulations rank by: the RMS estimation error, or the RMS position error
        (the larger of the regulation and tracking windows). Default ``"estimation"``.
    noise_limit : float, optional
        Largest RMS noise the sensor may cause in the estimate [N m]. Default: no limit.
    coulomb : float, optional
        Coulomb friction of the simulated plant [N m] (``tanh`` scale 0.01 rad/s). Default: the
        paper scenario's 0.01 N m (:data:`hpdob.paper.PLANT`) scaled by ``J_n / 2.8e-4 kg m^2``
        (as the default disturbance is); 0
        for none.
    scenario : dict, optional
        The verification run: ``reference``, ``duration`` [s] and optionally ``disturbance``
        (as for :func:`hpdob.simulate`). Default: the paper's reference, a load step at 1.5 s and
        a sine at the disturbance frequency from 2.5 s, amplitudes scaled with ``J_n`` from the
        paper's (0.05 and 0.02 N m at ``J_n`` = 2.8e-4 kg m^2); 10 s (in whole samples). Its
        duration and signals are checked before the search.
    progress : callable, optional
        Called as ``progress(stage, done, total)`` while the search works (``stage`` one of
        ``"analysis"``, ``"simulation"``, ``"verification"``; ``done`` of ``total`` steps), e.g.
        to show progress; its return value is ignored. Default: silent.

    Returns
    -------
    TuningResult
        ``.observer`` (ready to use), ``.design``, ``.table``, ``.pareto()``, ``.plot()``,
        ``.report()``, ``.to_dict()``.

    Raises
    ------
    TypeError, ValueError
        For bad arguments (named); ValueError if no candidate qualifies, saying which constraint
        rules everything out.

    References
    ----------
    ``docs/tuning.md``: the search, the margin, and the benchmark against brute-force
    simulation.

    Examples
    --------
    >>> from hpdob import Actuator, Encoder, ServoModel, tune
    >>> result = tune(nominal=ServoModel(2.8e-4), Ts=1e-3, sensor=Encoder(16384),
    ...               actuator=Actuator(delay_samples=1), J_range=(0.7, 1.3),
    ...               disturbance_frequency=2.0, families=["position"])   # doctest: +SKIP
    >>> print(result.report())                                            # doctest: +SKIP
    """
    from ..analysis import RadiiScan, channel_noise_gains, estimation_response, loop_margins
    from ..simulation import ServoLoop, sample_count, sample_signals

    legacy = {"nominal": nominal, "Ts": Ts, "controller": controller, "sensor": sensor,
              "actuator": actuator}  # fmt: skip
    parts = loop_parts(loop, legacy, "tune")
    missing = [k for k in ("nominal", "Ts") if k not in parts]
    if missing:
        raise ParameterTypeError(
            "tune() needs a ServoLoop as first argument, or the keyword arguments nominal and "
            f"Ts (missing: {', '.join(missing)})"
        )
    nominal, Ts = parts["nominal"], parts["Ts"]
    controller, sensor = parts.get("controller"), parts.get("sensor")
    actuator = parts.get("actuator")
    if loop is not None and coulomb is None:
        coulomb = getattr(loop.plant, "coulomb", None)
    nominal = require_instance(nominal, ServoModel, "nominal")
    Ts = positive(Ts, "Ts", "a positive finite sampling period [s]")
    if not 0.4 * math.pi / Ts > MIN_BANDWIDTH:  # the grid of bandwidths, 5 rad/s .. 0.4 pi/Ts
        raise ParameterValueError(
            f"Ts must be below 0.4 pi / {MIN_BANDWIDTH:g} rad/s = "
            f"{0.4 * math.pi / MIN_BANDWIDTH:.4g} s (the bandwidths searched run from "
            f"{MIN_BANDWIDTH:g} rad/s to 0.4 pi/Ts), got {Ts!r}"
        )
    controller = PD(50.0, 5.0, velocity="observer") if controller is None else controller
    controller_system(controller, nominal, Ts)  # refuses what is not a controller, named
    sensor = require_instance(sensor, Encoder, "sensor", optional=True)
    actuator = require_instance(actuator, Actuator, "actuator", optional=True) or Actuator()
    if actuator.delay_samples + 1 > MAX_DELAY_SAMPLES:
        raise ParameterValueError(
            f"actuator.delay_samples must be at most {MAX_DELAY_SAMPLES - 1} for tune (the "
            f"linear loop holds at most {MAX_DELAY_SAMPLES} samples and tune adds one), got "
            f"{actuator.delay_samples}"
        )
    J_low, J_high = _range(J_range, "J_range", "positive inertia ratios J/J_n", allow_zero=False)
    b_low, b_high = (nominal.b, nominal.b)
    if b_range is not None:
        b_low, b_high = _range(
            b_range, "b_range", "non-negative viscous frictions [N m s/rad]", allow_zero=True
        )
    frequencies = _frequencies(disturbance_frequency, Ts)
    variants = candidate_families()
    if families is None:
        families = tuple(variants)
    if isinstance(families, str) or not families:
        raise ParameterValueError(
            f"families must be a non-empty sequence of {', '.join(map(repr, variants))}, got "
            f"{families!r}"
        )
    families = tuple(dict.fromkeys(check_choice(f, "families", variants) for f in families))
    objective = check_choice(objective, "objective", OBJECTIVES)
    if progress is not None and not callable(progress):
        raise ParameterTypeError(f"progress must be callable or None, got {progress!r}")
    report = progress or (lambda stage, done, total: None)  # silent by default
    if noise_limit is not None:
        noise_limit = positive(noise_limit, "noise_limit", "a positive RMS noise [N m]")
    if coulomb is None:
        from ..simulation import canonical as paper

        # The paper scenario's Coulomb friction (the paper's model has viscous friction only;
        # hpdob's scenario adds it), at the same acceleration for any J_n.
        coulomb = paper.PLANT.coulomb * nominal.J / paper.NOMINAL.J
    coulomb = nonnegative(coulomb, "coulomb", "a non-negative Coulomb friction [N m]")
    run = _scenario(nominal, Ts, disturbance_frequency, scenario)
    # The verification run, checked before the search (not after it): duration, size, signals
    duration = positive(run["duration"], "scenario duration", "a positive finite duration [s]")
    sample_count(Ts, duration)
    sample_signals(run["reference"], run.get("disturbance"), Ts=Ts, n=2, substeps=1)

    model = nominal.discretize(Ts)
    sigma = _sensor_noise(sensor)
    notes: list[str] = []
    candidates = _candidates(model, families, sigma, notes)
    corners = sorted(set(itertools.product((J_low, J_high), (b_low, b_high))))
    centre = (0.5 * (J_low + J_high), 0.5 * (b_low + b_high))
    margin_actuator = Actuator(delay_samples=actuator.delay_samples + 1)
    linear_actuator = Actuator(delay_samples=actuator.delay_samples)

    def plant(J_ratio: float, b: float) -> ServoModel:
        return ServoModel(J_ratio * nominal.J, b)

    corner_plants = [plant(*c) for c in corners]

    def analyse(family, m, parameter, value, design) -> dict:
        """The candidate's analytic figures: its row of the table."""
        ctrl = controller
        if getattr(controller, "velocity", None) == "observer" and not design.system.has_velocity:
            ctrl = dataclasses.replace(controller, velocity="measured")
        base = ServoLoop(plant=plant(*centre), nominal=nominal, Ts=Ts, controller=ctrl,
                         observer=design, sensor=sensor, actuator=linear_actuator)  # fmt: skip
        error = np.abs(estimation_response(design, frequencies, error=True))
        accuracy = float(np.sqrt(np.mean(error**2)))
        # the corners with the actuator's delay and with one more sample (margin_actuator's)
        scan = RadiiScan(base, corner_plants)  # the loop checked once for both uses
        radius, radius_margin = (float(v) for v in scan.radii(
            [actuator.delay_samples, margin_actuator.delay_samples]).max(axis=1))  # fmt: skip
        tau_noise = u_noise = 0.0
        if sigma > 0.0 and radius < 1.0:
            try:
                gains = channel_noise_gains(base, "position")  # noise_gains' figures
                tau_noise, u_noise = float(gains[0]) * sigma, float(gains[1]) * sigma
            except ParameterValueError:
                tau_noise = u_noise = math.inf
        elif radius >= 1.0:
            tau_noise = u_noise = math.inf
        robust = radius < 1.0 and radius_margin < 1.0
        if robust:
            delay_margin = _delay_margin(scan, actuator.delay_samples)
        else:
            delay_margin = 0 if radius < 1.0 else -1
        return {
            "family": family, "order": m, "name": design.system.name, "parameter": parameter,
            "value": value, "accuracy": accuracy, "tau_noise": tau_noise, "u_noise": u_noise,
            "radius": radius, "radius_margin": radius_margin, "delay_margin_samples": delay_margin,
            "robust": robust,
            "within_noise": noise_limit is None or tau_noise <= noise_limit,
            "pareto": False, "simulated": math.nan, "_design": design, "_controller": ctrl,
            "_base": base,
        }  # fmt: skip

    def qualified_rows(rows) -> list:
        """The robust candidates within the noise limit (their Pareto front marked), or the
        error saying which constraint rules everything out."""
        if not rows:
            raise ParameterValueError("no candidate could be designed: " + "; ".join(notes[:3]))
        qualified = [r for r in rows if r["robust"] and r["within_noise"]]
        if not qualified:
            robust = [r for r in rows if r["robust"]]
            if not robust:
                smallest = min(max(r["radius"], r["radius_margin"]) for r in rows)
                raise ParameterValueError(
                    f"no candidate is stable over J/J_n in [{J_low:g}, {J_high:g}] and b in "
                    f"[{b_low:g}, {b_high:g}] with {actuator.delay_samples} and with "
                    f"{actuator.delay_samples} + 1 samples of delay (smallest worst-case spectral "
                    f"radius {smallest:.4f}); narrow the uncertainty, lower the PD gains or "
                    "reduce the delay"
                )
            quietest = min(r["tau_noise"] for r in robust)
            raise ParameterValueError(
                f"no robustly stable candidate meets noise_limit={noise_limit!r} N m: the quietest "
                f"makes {quietest:.3g} N m RMS of noise in the estimate; raise the limit or use a "
                "finer encoder"
            )
        # Pareto front of (accuracy, noise) among the qualified, then simulated at the centre.
        best_noise = math.inf
        for r in sorted(qualified, key=lambda r: (r["accuracy"], r["tau_noise"])):
            if r["tau_noise"] < best_noise:
                r["pareto"] = True
                best_noise = r["tau_noise"]
        return qualified

    def tracks(result) -> bool:  # RMS error below a loop that never moves (torque limit 1e-300)
        with np.errstate(all="ignore"):
            scale = float(np.sqrt(np.mean(result.r**2)))
            error = float(np.sqrt(np.mean((result.theta - result.r) ** 2)))
        return scale == 0.0 or error < scale

    runs = VerificationRuns(nominal=nominal, Ts=Ts, sensor=sensor, actuator=actuator,
                            coulomb=coulomb, run=run)  # fmt: skip
    simulate_at = runs.simulate
    rows = []
    # the centre runs start as their candidates qualify, while the analysis goes on
    with runs.started(*centre) as centre_runs:
        for done, candidate in enumerate(candidates):
            checkpoint("tune-candidate")  # a signal Python ignored ends the search here
            report("analysis", done, len(candidates))
            rows.append(row := analyse(*candidate))
            if row["robust"] and row["within_noise"]:
                centre_runs.submit(row)
        qualified = qualified_rows(rows)
        report("analysis", len(candidates), len(candidates))
        for r, (diverged, metrics, position) in zip(qualified, centre_runs.results(report),
                                                    strict=True):  # fmt: skip
            value = metrics["rms_estimation_error"] if objective == "estimation" else position
            r["simulated"] = math.inf if diverged else value
            r["simulated_estimation"] = metrics["rms_estimation_error"]
            r["simulated_position"] = position
    report("simulation", len(qualified), len(qualified))
    verification = None
    for r in sorted(qualified, key=lambda r: r["simulated"]):
        if not math.isfinite(r["simulated"]):
            break
        checks = []
        for done, (J_ratio, b) in enumerate(corners):
            report("verification", done, len(corners))
            result, metrics, position = simulate_at(r, J_ratio, b)
            loop = ServoLoop(plant=plant(J_ratio, b), nominal=nominal, Ts=Ts,
                             controller=r["_controller"], observer=r["_design"],
                             actuator=linear_actuator, sensor=sensor)  # fmt: skip
            checks.append({
                "J_ratio": J_ratio, "b": b, "diverged": result.diverged,
                "tracks": tracks(result),
                "radius": _radius(loop), "rms_estimation_error": metrics["rms_estimation_error"],
                "rms_position_error": position,
                "delay_margin": loop_margins(loop).delay_margin,
            })  # fmt: skip
        if all(not c["diverged"] and c["tracks"] and c["radius"] < 1.0 for c in checks):
            report("verification", len(corners), len(corners))
            verification = (r, checks)
            break
        notes.append(f"{r['name']} at {r['parameter']}={r['value']:.4g} failed at a corner")
    if verification is None:
        raise ParameterValueError(
            "no robustly stable candidate stays bounded and tracks its reference (RMS position "
            "error below the reference's RMS) in the nonlinear simulation at every corner of "
            "the uncertainty set (torque limit and Coulomb friction included); narrow the "
            "uncertainty or relax the scenario"
        )
    return TuningResult(
        rows=rows,
        recommended=verification[0],
        verification=verification[1],
        settings={
            "nominal": {"J": nominal.J, "b": nominal.b},
            "Ts": Ts,
            "controller": controller_settings(controller),
            "sensor_noise_std": sigma,
            "delay_samples": actuator.delay_samples,
            "torque_limit": actuator.torque_limit,
            "J_range": (J_low, J_high),
            "b_range": (b_low, b_high),
            "frequencies_Hz": frequencies.tolist(),
            "families": families,
            "objective": objective,
            "noise_limit": noise_limit,
            "coulomb": coulomb,
            "margin": "stable at every corner with the actuator's delay and with one extra "
            "sample of delay",
            "max_extra_delay": MAX_EXTRA_DELAY,
            "bandwidth_grid": {
                "low": MIN_BANDWIDTH,
                "high": 0.4 * math.pi / Ts,
                "points": N_BANDWIDTHS,
            },
        },
        notes=tuple(notes),
        scenario=run,
    )
