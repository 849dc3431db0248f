r"""The observers side by side: the paper's, their position-only versions, ADRC's ESO, Kalman.

Every observer is tuned to the **same noise gain in the estimate**: the RMS of
:math:`\hat\tau` per unit white angle noise, the noise an encoder's quantisation adds to every
observer alike (std ``q/sqrt(12)``; an observer that takes a velocity gets the backward
difference of the noisy angle, ``observer_noise_gain(..., noise="encoder")``). The tuned
parameter is the bandwidth (the order-m families and the ESO) or the process noise (Kalman).
Then each runs the paper's scenario (:func:`hpdob.paper.scenario`) with the ideal sensor and
with the virtual experiment's encoder, delay and torque limit, and the linear loop gives its
noise in ``u``, delay margin and the range of true/nominal inertia it stays stable over.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from .._table import columns_to_csv, columns_to_pandas
from .._validation import ParameterTypeError, ParameterValueError, check_choice, positive
from ..simulation import MISSING, loop_parts

__all__ = ["Comparison", "compare_observers", "default_candidates"]


def default_candidates() -> dict:
    """The observers compared by default, by name: every registered family's ``compared``
    specs (:func:`hpdob.observers.families`), without the tuned parameter."""
    from ..observers import families

    return {
        name: {"type": family.name, **spec}
        for family in families()
        for name, spec in family.compared.items()
    }


SENSORS = ("ideal", "encoder")
#: Default target noise gain [N m/rad]: with the virtual experiment's 16384-count encoder
#: (q/sqrt(12) = 1.1e-4 rad) an estimate noise of 1.1e-3 N m RMS; the lowest level at which
#: every family has a design (the paper's observers, with a differenced velocity, have no
#: usable bandwidth below about 3 N m/rad).
DEFAULT_NOISE_GAIN = 10.0
_BANDWIDTHS = (0.5, 1400.0)  # rad/s, the tuning's search range at Ts = 1 ms
METRICS = (
    "rms_estimation_error",
    "rms_position_error_regulation",
    "rms_position_error_tracking",
)


def _noise_gain(design) -> float:
    from ._noise import observer_noise_gain

    return observer_noise_gain(design, noise="encoder")


def _tune(model, spec: dict, target: float, sigma: float):
    """``(design, parameter, value, matched)``: the design whose noise gain is ``target``."""
    from scipy.optimize import brentq

    from ..observers import design_from_spec, get_family

    family = get_family(spec.get("type", "dob"))
    name = family.tuned
    if family.noise_parameter is not None:  # set from the encoder's angle noise
        spec = {**spec, family.noise_parameter: sigma}

    def design(log_value):
        return design_from_spec(model, {**spec, name: 10**log_value})

    if family.tuned_range is not None:
        arguments = {k: v for k, v in spec.items() if k != "type"}
        lo, hi = (math.log10(v) for v in family.tuned_range(model, arguments))
    else:
        upper = min(_BANDWIDTHS[1], 0.45 * math.pi / model.Ts)
        lo, hi = math.log10(_BANDWIDTHS[0]), math.log10(upper)

    def mismatch(log_value):
        return math.log(_noise_gain(design(log_value)) / target)

    def realisable(log_value) -> bool:
        try:
            design(log_value)
        except ParameterValueError:  # e.g. the realised poles of a slow design are off
            return False
        return True

    while not realisable(lo) and lo < hi:  # the low end: the slowest realisable design
        lo = min(lo + 0.25, hi)

    f_lo, f_hi = mismatch(lo), mismatch(hi)
    if f_lo > 0:
        return design(lo), name, 10**lo, "noise gain above the target even at the lowest setting"
    if f_hi < 0:
        return design(hi), name, 10**hi, "noise gain below the target even at the highest setting"
    best = brentq(mismatch, lo, hi, xtol=1e-7)
    return design(best), name, 10**best, "matched"


def _check_candidates(candidates) -> dict:
    """``{name: spec}`` with string names and family specs that leave the tuned parameter to
    the comparison (a bandwidth or noise given in a spec would be silently replaced)."""
    from ..observers import check_spec, get_family

    if not isinstance(candidates, dict) or not candidates:
        raise ParameterTypeError(
            f"candidates must be a non-empty dict of name -> family spec, got {candidates!r}"
        )
    for name, spec in candidates.items():
        if not isinstance(name, str) or not name:
            raise ParameterTypeError(f"candidates names must be non-empty str, got {name!r}")
        if not isinstance(spec, dict):
            raise ParameterTypeError(
                f"candidates[{name!r}] must be a family spec (a dict), got {spec!r}"
            )
        family = get_family(spec.get("type", "dob"), f"candidates[{name!r}].type")
        tuned = family.set_at_bandwidth + ((family.noise_parameter,) if family.noise_parameter
                                           else ())  # fmt: skip
        given = [k for k in tuned if k in spec]
        if given:
            what = "the bandwidth" if family.tuned == "bandwidth" else f"{family.tuned}"
            if family.noise_parameter is not None:
                what += f" (at the encoder's noise, which sets {family.noise_parameter})"
            raise ParameterValueError(
                f"candidates[{name!r}] must not give {', '.join(given)}: the comparison tunes "
                f"{what} to the target noise gain, got {spec!r}"
            )
        placeholder = {k: 1.0 for k in tuned if k not in family.replaced_by_bandwidth}
        check_spec({**spec, **placeholder}, f"candidates[{name!r}]")
    return dict(candidates)


def _inertia_range(loop) -> tuple[float, float]:
    """The interval of true/nominal inertia ratios around 1 over which the linear loop stays
    stable (the true plant's J scaled; its viscous friction kept)."""
    from scipy.optimize import brentq

    from ._closed_loop import closed_loop_poles

    plant = loop.plant

    def margin(ratio: float) -> float:
        scaled = loop.replace(plant=plant.replace(J=ratio * loop.nominal.J))
        return float(np.abs(closed_loop_poles(scaled)).max()) - 1.0

    if margin(1.0) >= 0:
        return math.nan, math.nan
    low, high = 1.0, 1.0
    while low > 1e-3 and margin(low / 2) < 0:
        low /= 2
    low = 1e-3 if low <= 1e-3 else brentq(margin, low / 2, low, xtol=1e-6)
    while high < 1e3 and margin(high * 2) < 0:
        high *= 2
    high = math.inf if high >= 1e3 else brentq(margin, high, high * 2, xtol=1e-6)
    return low, high


@dataclass(frozen=True, eq=False)
class Comparison:
    """The result of :func:`compare_observers`: one row per observer and sensor.

    Attributes
    ----------
    rows : list of dict
        Columns: ``observer``, ``sensor``, ``family``, ``tuned``/``value`` (the tuned parameter
        and its value), ``tuning`` ("matched" or why not), ``noise_gain`` [N m/rad],
        ``rms_estimation_error`` [N m], ``rms_position_error_regulation`` and
        ``rms_position_error_tracking`` [rad], ``u_noise_gain`` [N m/rad] and ``u_noise``
        [N m RMS at the encoder's quantisation], ``delay_margin`` [s],
        ``J_ratio_low``/``J_ratio_high`` (the stable range of J/J_n), ``diverged``.
    noise_gain : float
        The target noise gain [N m/rad] every observer was tuned to.
    angle_noise : float
        The encoder's quantisation noise std [rad] (q/sqrt(12)).
    """

    rows: list = field(repr=False)
    noise_gain: float
    angle_noise: float
    _results: dict = field(default_factory=dict, repr=False)

    def to_pandas(self):
        """The table as a :class:`pandas.DataFrame`.

        Returns
        -------
        pandas.DataFrame
            One row per observer and sensor, the columns of ``rows``.

        Raises
        ------
        ImportError
            If pandas is not installed (``pip install hpdob[pandas]``).
        """
        return columns_to_pandas(self._columns(), caller="Comparison.to_pandas()")

    def _columns(self) -> dict:
        names = list(self.rows[0])
        return {name: [row[name] for row in self.rows] for name in names}

    def to_csv(self, path):
        """Write the table as CSV (atomically: a temporary file, then renamed).

        Parameters
        ----------
        path : str or os.PathLike
            The file to write (replaced if it exists).

        Returns
        -------
        str or os.PathLike
            ``path``, as given.
        """
        columns_to_csv(self._columns(), path)  # atomic itself: no temporary of a temporary
        return path

    def to_dict(self) -> dict:
        """The comparison as plain Python data.

        Returns
        -------
        dict
            JSON-ready (numpy scalars as Python numbers, non-finite values as None):
            ``rule`` (how the observers were matched), ``noise_gain`` [N m/rad],
            ``angle_noise`` [rad] and ``rows``.
        """
        from ..simulation import json_ready

        return json_ready(
            {
                "rule": "every observer tuned to the same RMS of tau_hat per unit white angle "
                "noise (velocity by backward difference where the observer takes one)",
                "noise_gain": self.noise_gain,
                "angle_noise": self.angle_noise,
                "rows": self.rows,
            }
        )

    def to_json(self, path):
        """Write :meth:`to_dict` as JSON (atomically: a temporary file, then renamed).

        Parameters
        ----------
        path : str or os.PathLike
            The file to write (replaced if it exists).

        Returns
        -------
        pathlib.Path
            ``path``.
        """
        from .._files import write_json_atomic

        return write_json_atomic(path, self.to_dict())

    def to_markdown(self) -> str:
        """The table as Markdown, one section per sensor.

        Returns
        -------
        str
            For each sensor a bold heading and a table: observer, tuned parameter, RMS
            estimation error [N m], regulation and tracking errors [rad], command noise
            [N m], delay margin [ms] and the stable range of J/J_n; "(!)" marks an observer
            that could not be matched to the target noise gain.
        """
        lines = []
        for sensor in SENSORS:
            rows = [r for r in self.rows if r["sensor"] == sensor]
            if not rows:
                continue
            lines += [
                f"**{sensor} sensor**",
                "",
                "| observer | tuned | RMS est. error [N m] | regulation [rad] | tracking [rad] | "
                "u noise [N m] | delay margin [ms] | stable J/J_n |",
                "|---|---|---:|---:|---:|---:|---:|---|",
            ]
            for r in rows:
                tuned = f"{r['tuned']} = {r['value']:.4g}" + (
                    "" if r["tuning"] == "matched" else " (!)"
                )
                lines.append(
                    f"| {r['observer']} | {tuned} | {r['rms_estimation_error']:.3e} | "
                    f"{r['rms_position_error_regulation']:.3e} | "
                    f"{r['rms_position_error_tracking']:.3e} | {r['u_noise']:.2e} | "
                    f"{r['delay_margin'] * 1e3:.2f} | "
                    f"{r['J_ratio_low']:.2f}–{r['J_ratio_high']:.2f} |"
                )
            lines.append("")
        return "\n".join(lines)

    def plot(self):
        """Bar chart: RMS estimation and position errors per observer, for each sensor.

        Returns
        -------
        matplotlib.figure.Figure
        """
        import matplotlib.pyplot as plt

        from .._plotting import PAPER_WIDTH

        names = list(dict.fromkeys(r["observer"] for r in self.rows))
        sensors = [s for s in SENSORS if any(r["sensor"] == s for r in self.rows)]
        fig, axes = plt.subplots(2, 1, figsize=(PAPER_WIDTH, 6.4), sharex=True,
                                 layout="constrained")  # fmt: skip
        width = 0.8 / len(sensors)
        x = np.arange(len(names))
        for i, sensor in enumerate(sensors):
            by_name = {r["observer"]: r for r in self.rows if r["sensor"] == sensor}
            est = [by_name[n]["rms_estimation_error"] for n in names]
            pos = [by_name[n]["rms_position_error_tracking"] for n in names]
            axes[0].bar(x + (i - (len(sensors) - 1) / 2) * width, est, width, label=sensor)
            axes[1].bar(x + (i - (len(sensors) - 1) / 2) * width, pos, width, label=sensor)
        axes[0].set_yscale("log")
        axes[1].set_yscale("log")
        axes[0].set_ylabel("RMS estimation error [N m]")
        axes[1].set_ylabel("RMS position error,\ntracking [rad]")
        axes[1].set_xticks(x, names, rotation=45, ha="right", fontsize="small")
        for ax in axes:
            ax.grid(True, axis="y", which="both", alpha=0.3)
        axes[0].legend(title="sensor", loc="upper left", bbox_to_anchor=(1.0, 1.0),
                       fontsize="small")  # fmt: skip
        fig.suptitle(
            f"every observer at the same estimate noise gain, {self.noise_gain:g} N m/rad",
            fontsize="medium",
        )
        return fig


def _with_velocity(controller, has_velocity: bool):
    """The loop's controller for one candidate: one with a ``velocity`` source (the PD, the
    filtered PD, the PID) takes the candidate's velocity estimate where it has one and the
    measured velocity otherwise; any other controller (ADRC, a
    :class:`~hpdob.controllers.LinearController`) runs as it is."""
    import dataclasses

    from ..controllers import VELOCITY_SOURCES

    if getattr(controller, "velocity", None) not in VELOCITY_SOURCES or not (
        dataclasses.is_dataclass(controller)
    ):
        return controller
    return dataclasses.replace(controller, velocity="observer" if has_velocity else "measured")


def _loop_scenario(loop, scenario: dict, encoder, actuator):
    """The comparison's run in ``loop``: its plant, nominal, Ts and controller; the paper's
    reference and its disturbance at the same acceleration; the loop's sensor and actuator, if
    any."""
    from ..simulation import MAX_PLANT_STEPS, ServoLoop

    if not isinstance(loop, ServoLoop):
        raise ParameterTypeError(
            f"compare_observers() takes a ServoLoop as its first argument, got "
            f"{type(loop).__name__}"
        )
    scale = loop.nominal.J / scenario["nominal"].J
    disturbance = scenario["disturbance"] if scale == 1.0 else scale * scenario["disturbance"]
    samples = scenario["duration"] / loop.Ts  # inf for a subnormal Ts: round() would overflow
    if not samples <= MAX_PLANT_STEPS:
        raise ParameterValueError(
            f"Ts must be at least {scenario['duration']:g} s / {MAX_PLANT_STEPS:.0e} = "
            f"{scenario['duration'] / MAX_PLANT_STEPS:g} s (the {scenario['duration']:g} s "
            f"comparison run holds at most {MAX_PLANT_STEPS:.0e} samples), got {loop.Ts!r}"
        )
    run = {**scenario, "plant": loop.plant, "nominal": loop.nominal, "Ts": loop.Ts,
           "controller": loop.controller, "disturbance": disturbance,
           "duration": scenario["duration"] if loop.Ts == scenario["Ts"]
           else loop.Ts * max(1, round(samples))}  # fmt: skip
    if loop.sensor is not None:
        encoder, actuator = loop.sensor, loop.actuator
    return run, encoder, actuator


def compare_observers(
    loop=None,
    /,
    *,
    plant=MISSING,
    nominal=MISSING,
    Ts=MISSING,
    controller=MISSING,
    sensor=MISSING,
    actuator=MISSING,
    sensors=SENSORS,
    noise_gain: float = DEFAULT_NOISE_GAIN,
    candidates=None,
    duration: float | None = None,
) -> Comparison:
    r"""Compare the paper's observers, their position-only versions, ESO and Kalman.

    Each candidate is tuned so that its estimate has the noise gain ``noise_gain`` [N m/rad]
    per unit white angle noise (``observer_noise_gain(..., noise="encoder")``: the noise an
    encoder adds to every observer alike, differenced into the velocity where one is taken),
    then runs the paper's scenario with each sensor: ``"ideal"`` (the paper's simulations) and
    ``"encoder"`` (the virtual experiment: 16384 counts/rev, one sample of delay, 0.444 N m
    limit). Observers with a velocity estimate drive the controller's derivative with it
    (``velocity="observer"`` of the PD, the filtered PD and the PID); the paper's
    state-measuring observers use the measured (with the encoder: differenced) velocity. A
    controller without a velocity source (:class:`~hpdob.ADRC`, a
    :class:`~hpdob.controllers.LinearController`) runs as it is.

    Parameters
    ----------
    loop : ServoLoop, optional
        The loop the observers are compared in: its plant, nominal model, ``Ts`` and
        controller (any of the protocol; its observer is replaced by each candidate's), and,
        if it has one, its sensor and actuator for the ``"encoder"`` case. The run is the
        paper's reference and disturbance, the disturbance scaled by ``J_n / 2.8e-4 kg m^2``
        (the paper's acceleration), over the paper's 10 s in whole samples. Default: the
        paper's loop (:func:`hpdob.paper.scenario`) with the virtual experiment's encoder and
        actuator.
    plant, nominal, Ts, controller, sensor, actuator : optional
        Instead of a loop, its parts (the loop functions' one alias rule,
        :data:`hpdob.simulation.LOOP_KEYS`; the observer is the comparison's): ``plant``,
        ``nominal``, ``Ts`` and ``controller`` together, ``sensor`` and ``actuator``
        optional.
    sensors : sequence of {"ideal", "encoder"}, optional
        Default both.
    noise_gain : float, optional
        Target noise gain [N m/rad]. Default 10 (see :data:`DEFAULT_NOISE_GAIN`).
    candidates : dict, optional
        ``{name: family spec}`` with ``str`` names; default every registered family's
        ``compared`` specs (:func:`hpdob.observers.register_family`). A spec must not give
        what the comparison sets (the family's ``tuned`` parameter and what it replaces:
        ``bandwidth`` or ``poles``; for the Kalman observer ``process_noise_std`` and its
        ``noise_parameter``, ``position_noise_std``): it is refused, not replaced.
    duration : float, optional
        Simulated time [s]; default the scenario's 10 s.

    Returns
    -------
    Comparison

    Raises
    ------
    TypeError, ValueError
        For an unknown sensor, a non-positive noise gain or a bad candidate spec.

    References
    ----------
    ``docs/comparison.md`` (the findings and the theory of where the families coincide).

    Examples
    --------
    >>> import math
    >>> from hpdob import compare_observers
    >>> table = compare_observers(sensors=("ideal",), duration=2.0)   # ~1 s
    >>> [row["observer"] for row in table.rows][:3]
    ['DOb', 'HPDOb', 'order 2']
    >>> all(math.isclose(row["noise_gain"], table.noise_gain, rel_tol=1e-3)
    ...     for row in table.rows if row["tuning"] == "matched")   # all at the same noise
    True
    """
    from ..simulation import ServoLoop, sample_count, simulate
    from ..simulation import canonical as paper  # the paper's set-up, as data
    from ._noise import noise_gains
    from ._sensitivity import loop_margins

    legacy = {"plant": plant, "nominal": nominal, "Ts": Ts, "controller": controller,
              "sensor": sensor, "actuator": actuator}  # fmt: skip
    parts = loop_parts(loop, legacy, "compare_observers")
    if loop is None and parts:  # the loop of the parts given (the observer is the comparison's)
        missing = [k for k in ("plant", "nominal", "Ts", "controller") if k not in parts]
        if missing:
            raise ParameterTypeError(
                "compare_observers() needs a ServoLoop as first argument, or the keyword "
                f"arguments plant, nominal, Ts and controller (missing: {', '.join(missing)})"
            )
        loop = ServoLoop(**parts)
    if isinstance(sensors, str):
        sensors = (sensors,)
    if not isinstance(sensors, (tuple, list)):
        raise ParameterTypeError(
            f"sensors must be a sequence of 'ideal', 'encoder', got {sensors!r} of type "
            f"{type(sensors).__name__}"
        )
    sensors = tuple(dict.fromkeys(check_choice(s, "sensors", SENSORS) for s in sensors))
    if not sensors:
        raise ParameterValueError("sensors must name at least one of 'ideal', 'encoder'")
    target = positive(noise_gain, "noise_gain", "a positive finite noise gain [N m/rad]")
    candidates = _check_candidates(default_candidates() if candidates is None else candidates)
    scenario = paper.canonical_run()
    encoder, actuator = paper.VIRTUAL_SENSOR, paper.VIRTUAL_ACTUATOR
    if loop is not None:
        scenario, encoder, actuator = _loop_scenario(loop, scenario, encoder, actuator)
    if duration is not None:
        scenario["duration"] = positive(duration, "duration", "a positive duration [s]")
        sample_count(scenario["Ts"], scenario["duration"])  # before the tuning, not after
    nominal, Ts = scenario["nominal"], scenario["Ts"]
    model = nominal.discretize(Ts)
    sigma = encoder.resolution / math.sqrt(12.0)
    linear_plant = scenario["plant"].replace(coulomb=0.0)
    rows, results = [], {}
    for name, spec in candidates.items():
        try:
            design, parameter, value, tuning = _tune(model, spec, target, sigma)
        except (ParameterTypeError, ParameterValueError) as err:
            raise type(err)(f"candidates[{name!r}]: {err}") from None
        controller = _with_velocity(scenario["controller"], design.system.has_velocity)
        for sensor in sensors:
            devices = {"sensor": encoder, "actuator": actuator} if sensor == "encoder" else {}
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # a diverged run is a result
                result = simulate(**{**scenario, "controller": controller}, observer=design,
                                  label=f"{name} ({sensor})", **devices)  # fmt: skip
            results[(name, sensor)] = result
            linear = ServoLoop(
                plant=linear_plant, nominal=nominal, Ts=Ts, controller=controller,
                observer=design, sensor=encoder if sensor == "encoder" else None,
                actuator=type(actuator)(delay_samples=actuator.delay_samples)
                if sensor == "encoder" else None,
            )  # fmt: skip
            low, high = _inertia_range(linear)
            noise_loop = linear.replace(sensor=encoder)
            try:
                u_gain = noise_gains(noise_loop).u_position
            except ParameterValueError:  # the linear loop is unstable
                u_gain = math.inf
            metrics = result.metrics()
            rows.append(
                {
                    "observer": name,
                    "sensor": sensor,
                    "family": spec.get("type", "dob"),
                    "tuned": parameter,
                    "value": value,
                    "tuning": tuning,
                    "noise_gain": _noise_gain(design),
                    **{k: metrics[k] for k in METRICS},
                    "u_noise_gain": u_gain,
                    "u_noise": u_gain * sigma,
                    "delay_margin": loop_margins(linear).delay_margin,
                    "J_ratio_low": low,
                    "J_ratio_high": high,
                    "diverged": result.diverged,
                }
            )
    return Comparison(rows=rows, noise_gain=target, angle_noise=sigma, _results=results)
