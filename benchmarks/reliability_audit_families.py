"""Reliability audit, part 2: the surfaces issues 12-15 added (run by reliability_audit.py).

Position-only designs, the ESO, the Kalman observer, the two-mass plant (constructor, as a
plant in ``simulate`` and ``sweep``, and as ``[plant] type = "two-mass"`` in a scenario
file), ``estimate_disturbance`` and ``hpdob estimate`` (logs in CSV, Parquet and MAT with
missing, renamed or non-numeric columns, wrong lengths, NaN, time not matching ``Ts``),
``tune`` and ``hpdob tune``, ``compare_observers`` and ``hpdob compare``,
``robust_stability_map(observer=...)`` and ``hpdob design``/``export-c --type eso|kalman``.
Every function takes the :class:`reliability_audit.Audit` that classifies the outcomes.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from hpdob import (
    PD,
    Actuator,
    DisturbanceObserver,
    ExtendedStateObserver,
    KalmanDisturbanceObserver,
    ServoModel,
    TwoMassServo,
    compare_observers,
    design_observer,
    estimate_disturbance,
    paper,
    robust_stability_map,
    simulate,
    sweep,
    tune,
)
from hpdob.observers import design_eso, design_kalman, kalman_process_noise

HUGE = 10**400
NAN, INF = math.nan, math.inf
MODEL = ServoModel(2.8e-4).discretize(1e-3)
#: Bad values for a positive finite number, by label.
BAD_POSITIVE = {
    "nan": NAN,
    "inf": INF,
    "zero": 0.0,
    "negative": -1.0,
    "huge int": HUGE,
    "str": "100",
    "bool": True,
    "complex": 1j,
    "array": np.array([1.0, 2.0]),
    "None": None,
}


def finite_result(result) -> bool:
    """An accepted estimate must be finite (a non-finite one is a silently wrong result)."""
    return bool(np.all(np.isfinite(result.tau_hat)))


# -- position-only designs ----------------------------------------------------------------------
def audit_position(audit) -> None:
    s = "position-only design"
    base = {"order": 1, "bandwidth": 100.0, "measurement": "position"}

    def case(name, **changes):
        kwargs = {k: v for k, v in {**base, **changes}.items() if v is not _DROP}
        audit.api(s, name, lambda: design_observer(MODEL, **kwargs))

    case("valid")
    case("valid with velocity_bandwidth", velocity_bandwidth=300.0)
    case("valid with poles", bandwidth=_DROP, poles=[0.9, 0.9, 0.8, 0.8])
    for label, value in BAD_POSITIVE.items():
        if value is not None:
            case(f"velocity_bandwidth {label}", velocity_bandwidth=value)
        case(f"bandwidth {label}", bandwidth=value)
    case("velocity_bandwidth 1e-300 (pole rounds to 1)", velocity_bandwidth=1e-300)
    case("velocity_bandwidth 1e308", velocity_bandwidth=1e308)
    case("bandwidth 1e-300", bandwidth=1e-300)
    case("velocity_bandwidth with poles", bandwidth=_DROP, poles=[0.9] * 4, velocity_bandwidth=1.0)
    case("velocity_bandwidth with measurement state", measurement="state", velocity_bandwidth=1.0)
    case("gain_direction", gain_direction=(1.0, 1.0))
    case("poles: 2 for order 1", bandwidth=_DROP, poles=[0.9, 0.9])
    case("poles unstable", bandwidth=_DROP, poles=[0.9, 0.9, 0.9, 1.1])
    case("poles nan", bandwidth=_DROP, poles=[0.9, 0.9, 0.9, NAN])
    case("poles unpaired complex", bandwidth=_DROP, poles=[0.9, 0.9, 0.5 + 0.1j, 0.5])
    case("poles strings", bandwidth=_DROP, poles=["a"] * 4)
    case("poles dict", bandwidth=_DROP, poles={0.9: 1})
    case("order 12 at 1 rad/s (unstable when rounded)", order=12, bandwidth=1.0)
    case("order 8 at 100 rad/s (poles off)", order=8)
    case("order 8, pole_tolerance None", order=8, pole_tolerance=None)
    for label, value in {
        "pole_tolerance -1": -1.0,
        "pole_tolerance nan": NAN,
        "pole_tolerance str": "5%",
        "pole_tolerance array": np.array([0.05, 0.1]),
        "pole_tolerance huge int": HUGE,
    }.items():
        case(label, pole_tolerance=value)
    for label, value in {"-1": -1, "1.5": 1.5, "'1'": "1", "huge": HUGE, "51": 51}.items():
        case(f"order {label}", order=value)
    case("measurement 'angle'", measurement="angle")
    case("measurement None", measurement=None)
    for label, model in {
        "continuous model": ServoModel(2.8e-4),
        "two-mass model": TwoMassServo(1e-4, 1e-4, 10.0).discretize(1e-3),
        "None": None,
    }.items():
        audit.api(s, f"model {label}", lambda m=model: design_observer(m, **base))
    audit.api(
        s,
        "DisturbanceObserver velocity_bandwidth nan",
        lambda: DisturbanceObserver(MODEL, **base, velocity_bandwidth=NAN),
    )


_DROP = object()


# -- ESO, Kalman: design functions and runtime objects -------------------------------------------
def _runtime(audit, surface: str, label: str, obs) -> None:
    """Bad samples and resets on a runtime observer of the angle: rejected, state unchanged."""
    obs.update(0.01, 0.02)

    def state(o=obs):
        return (np.array(o.state),)

    for name, call in {
        "estimate nan": lambda: obs.estimate(NAN),
        "estimate (theta, omega)": lambda: obs.estimate((0.0, 0.0)),
        "estimate str": lambda: obs.estimate("0"),
        "estimate huge int": lambda: obs.estimate(HUGE),
        "update theta inf": lambda: obs.update(INF, 0.0),
        "update u nan": lambda: obs.update(0.0, NAN),
        "update u complex": lambda: obs.update(0.0, 1j),
        "update 3 arguments": lambda: obs.update(0.0, 0.0, 0.0),
        "reset x0 nan": lambda: obs.reset((NAN, 0.0), 0.0),
        "reset tau0 huge": lambda: obs.reset((0.0, 0.0), HUGE),
        "reset x0 3 values": lambda: obs.reset((0.0, 0.0, 0.0), 0.0),
    }.items():
        audit.api(surface, f"{label}.{name}", call, state=state)


def audit_eso(audit) -> None:
    s = "ESO"
    audit.api(s, "valid", lambda: design_eso(MODEL, bandwidth=200.0))
    audit.api(s, "valid m=2 predictive", lambda: design_eso(
        MODEL, bandwidth=200.0, extended_order=2, form="predictive"))  # fmt: skip
    for label, value in BAD_POSITIVE.items():
        audit.api(s, f"bandwidth {label}", lambda v=value: design_eso(MODEL, bandwidth=v))
    for label, value in {"1e-300 (pole rounds to 1)": 1e-300, "1e-20": 1e-20, "1e308": 1e308,
                         "0.01 with m=1 (unstable when rounded)": 0.01}.items():  # fmt: skip
        audit.api(s, f"bandwidth {label}", lambda v=value: design_eso(
            MODEL, bandwidth=v, extended_order=1))  # fmt: skip
    for label, value in {"-1": -1, "5": 5, "1.5": 1.5, "'1'": "1", "True": True,
                         "huge": HUGE, "None": None}.items():  # fmt: skip
        audit.api(s, f"extended_order {label}", lambda v=value: design_eso(
            MODEL, bandwidth=200.0, extended_order=v))  # fmt: skip
    for label, value in {"'Current'": "Current", "''": "", "None": None, "1": 1}.items():
        audit.api(s, f"form {label}", lambda v=value: design_eso(MODEL, bandwidth=200.0, form=v))
    for label, value in {"-1": -1.0, "nan": NAN, "str": "x"}.items():
        audit.api(s, f"pole_tolerance {label}", lambda v=value: design_eso(
            MODEL, bandwidth=200.0, pole_tolerance=v))  # fmt: skip
    for label, model in {
        "continuous model": ServoModel(2.8e-4),
        "two-mass model": TwoMassServo(1e-4, 1e-4, 10.0).discretize(1e-3),
        "None": None,
        "a design": design_eso(MODEL, bandwidth=200.0),
    }.items():
        audit.api(s, f"model {label}", lambda m=model: design_eso(m, bandwidth=200.0))
    audit.api(s, "bandwidth positional", lambda: design_eso(MODEL, 200.0))
    audit.api(s, "bandwidth missing", lambda: design_eso(MODEL))
    audit.api(s, "runtime bandwidth nan", lambda: ExtendedStateObserver(MODEL, bandwidth=NAN))
    _runtime(audit, s, "ExtendedStateObserver", ExtendedStateObserver(MODEL, bandwidth=200.0))


def audit_kalman(audit) -> None:
    s = "Kalman"
    ok = {"position_noise_std": 1e-4, "process_noise_std": 1e-3}
    audit.api(s, "valid", lambda: design_kalman(MODEL, **ok))
    for key in ok:
        for label, value in BAD_POSITIVE.items():
            audit.api(s, f"{key} {label}", lambda k=key, v=value: design_kalman(
                MODEL, **{**ok, k: v}))  # fmt: skip
        for label, value in {"1e-300": 1e-300, "1e300": 1e300}.items():
            audit.api(s, f"{key} {label}", lambda k=key, v=value: design_kalman(
                MODEL, **{**ok, k: v}))  # fmt: skip
    for label, kwargs in {
        "ratio 1e-9/1e-4, order 2 (solver's answer unstable)": {
            "order": 2, "position_noise_std": 1e-9, "process_noise_std": 1e-4},
        "ratio 1e-9/1e-8, order 3": {
            "order": 3, "position_noise_std": 1e-9, "process_noise_std": 1e-8},
        "ratio 1e-9/1, order 2 (stable, slow)": {
            "order": 2, "position_noise_std": 1e-9, "process_noise_std": 1.0},
    }.items():  # fmt: skip
        audit.api(s, label, lambda kw=kwargs: design_kalman(MODEL, **kw))
    for label, value in {"-1": -1, "5": 5, "1.5": 1.5, "'0'": "0", "True": True}.items():
        audit.api(s, f"order {label}", lambda v=value: design_kalman(MODEL, order=v, **ok))
    audit.api(s, "model continuous", lambda: design_kalman(ServoModel(2.8e-4), **ok))
    audit.api(s, "noise missing", lambda: design_kalman(MODEL, position_noise_std=1e-4))
    q = "kalman_process_noise"
    good = {"bandwidth": 100.0, "position_noise_std": 1e-4}
    audit.api(s, f"{q} valid", lambda: kalman_process_noise(MODEL, **good))
    for label, value in {**BAD_POSITIVE, "above Nyquist/2": 2000.0, "1e-300": 1e-300}.items():
        audit.api(s, f"{q} bandwidth {label}", lambda v=value: kalman_process_noise(
            MODEL, **{**good, "bandwidth": v}))  # fmt: skip
    for label, value in {"0": 0.0, "nan": NAN, "1e-300": 1e-300, "1e300": 1e300}.items():
        audit.api(s, f"{q} position_noise_std {label}", lambda v=value: kalman_process_noise(
            MODEL, **{**good, "position_noise_std": v}))  # fmt: skip
    audit.api(s, f"{q} order 5", lambda: kalman_process_noise(MODEL, **good, order=5))
    audit.api(s, f"{q} model None", lambda: kalman_process_noise(None, **good))
    audit.api(s, "runtime r nan", lambda: KalmanDisturbanceObserver(
        MODEL, position_noise_std=NAN, process_noise_std=1e-3))  # fmt: skip
    _runtime(audit, s, "KalmanDisturbanceObserver", KalmanDisturbanceObserver(MODEL, **ok))


# -- the two-mass plant ------------------------------------------------------------------------
TWO_MASS = {"J_motor": 1.4e-4, "J_load": 1.4e-4, "stiffness": 20.0}


def audit_two_mass(audit, tmp: Path) -> None:
    s = "two-mass plant"
    audit.api(s, "valid", lambda: TwoMassServo(**TWO_MASS))
    names = ("J_motor", "J_load", "stiffness", "damping", "b_motor", "b_load", "coulomb",
             "coulomb_velocity")  # fmt: skip
    for name in names:
        for label in ("nan", "inf", "negative", "huge int", "str", "bool", "complex", "None"):
            value = BAD_POSITIVE[label]
            audit.api(s, f"{name} {label}", lambda n=name, v=value: TwoMassServo(
                **{**TWO_MASS, n: v}))  # fmt: skip
    audit.api(s, "stiffness 1e308 over J 1e-10", lambda: TwoMassServo(1e-10, 1e-10, 1e308))
    audit.api(s, "J_motor 1e-320", lambda: TwoMassServo(1e-320, 1e-4, 20.0))
    plant = TwoMassServo(**TWO_MASS)
    for label, Ts in {"0": 0.0, "nan": NAN, "huge int": HUGE, "1e-320": 1e-320, "1e308": 1e308,
                      "str": "1e-3"}.items():  # fmt: skip
        audit.api(s, f"discretize Ts {label}", lambda t=Ts: plant.discretize(t))
    audit.api(s, "replace unknown J", lambda: plant.replace(J=1.0))
    audit.api(s, "replace stiffness -1", lambda: plant.replace(stiffness=-1.0))
    # as a plant in simulate
    base = {**paper.scenario(), "plant": plant, "duration": 0.2}
    audit.api(s, "simulate valid", lambda: simulate(**base, observer=design_observer(
        MODEL, order=1, bandwidth=100.0)))  # fmt: skip
    for label, change in {
        "simulate nominal two-mass": {"nominal": plant},
        "simulate plant discretised": {"plant": plant.discretize(1e-3)},
        "simulate substeps 0": {"substeps": 0},
        "simulate x0 of 4 states": {"x0": (0.0, 0.0, 0.0, 0.0)},
        "simulate duration 1e12": {"duration": 1e12},
    }.items():
        audit.api(s, label, lambda c=change: simulate(**{**base, **c}))
    # sweep paths
    sweep_base = {**base, "duration": 0.05, "observer": {"order": 1, "bandwidth": 100.0}}
    rigid = {**sweep_base, "plant": paper.PLANT}
    for label, (b, grid) in {
        "sweep plant.stiffness valid": (sweep_base, {"plant.stiffness": [10.0, 20.0]}),
        "sweep plant.stiffness -1": (sweep_base, {"plant.stiffness": [-1.0]}),
        "sweep plant.stiffness nan": (sweep_base, {"plant.stiffness": [NAN]}),
        "sweep plant.J on a two-mass plant": (sweep_base, {"plant.J": [3e-4]}),
        "sweep plant.coulomb on a two-mass plant": (sweep_base, {"plant.coulomb": [0.01]}),
        "sweep plant.stiffness on a rigid plant": (rigid, {"plant.stiffness": [10.0]}),
        "sweep plant.J_motor on a rigid plant": (rigid, {"plant.J_motor": [1e-4]}),
        "sweep observer.velocity_bandwidth, state observer": (
            sweep_base, {"observer.velocity_bandwidth": [100.0]}),
        "sweep observer.bandwidth of a Kalman spec": (
            {**sweep_base, "observer": {"type": "kalman", "position_noise_std": 1e-4,
                                        "process_noise_std": 1e-3}},
            {"observer.bandwidth": [100.0]}),
        "sweep observer.order of an ESO spec": (
            {**sweep_base, "observer": {"type": "eso", "bandwidth": 100.0}},
            {"observer.order": [1]}),
        "sweep observer.measurement of an ESO spec": (
            {**sweep_base, "observer": {"type": "eso", "bandwidth": 100.0}},
            {"observer.measurement": ["position"]}),
    }.items():  # fmt: skip
        audit.api(s, label, lambda b=b, g=grid: sweep(b, grid=g, scheduler=1, progress=False))
    # [plant] type = "two-mass" in a scenario file, through hpdob simulate
    text = _TWO_MASS_TOML
    import re

    from reliability_audit import SUBSTITUTES

    lines = text.splitlines()
    start = lines.index("[plant]")
    end = lines.index("[nominal]")
    numeric = [i for i in range(start, end) if re.search(r"=\s*-?[0-9]", lines[i])]
    for count, i in enumerate(numeric):
        key = lines[i].split("=")[0].strip()
        for label, value in SUBSTITUTES.items():
            path = tmp / f"two_mass_{count}_{label.replace(' ', '_')}.toml"
            path.write_text("\n".join([*lines[:i], f"{key} = {value}", *lines[i + 1 :]]) + "\n")
            audit.cli("two-mass TOML", f"plant.{key} = {label}",
                      ["simulate", path, "--out", tmp / "o", "--no-plot"], cwd=tmp)  # fmt: skip
    for label, replacement in {
        "type 'flexible'": 'type = "flexible"',
        "type 1": "type = 1",
        "rigid keys (J) on two-mass": 'type = "two-mass"\nJ = 3e-4',
        "type 'rigid' with stiffness": 'type = "rigid"\nJ = 3e-4',
    }.items():
        path = tmp / f"two_mass_{label.split()[0]}_{len(label)}.toml"
        path.write_text(text.replace('type = "two-mass"', replacement))
        audit.cli("two-mass TOML", label, ["simulate", path, "--out", tmp / "o", "--no-plot"],
                  cwd=tmp)  # fmt: skip
    path = tmp / "two_mass_missing.toml"
    path.write_text(text.replace("stiffness = 20.0\n", ""))
    audit.cli("two-mass TOML", "stiffness missing",
              ["simulate", path, "--out", tmp / "o", "--no-plot"], cwd=tmp)  # fmt: skip


_TWO_MASS_TOML = """\
label = "two-mass"
Ts = 1e-3
duration = 0.1
[plant]
type = "two-mass"
J_motor = 1.4e-4
J_load = 1.4e-4
stiffness = 20.0
damping = 0.001
b_motor = 1e-5
b_load = 1e-5
coulomb = 0.005
coulomb_velocity = 0.01
[nominal]
J = 2.8e-4
[controller]
kp = 50.0
kd = 5.0
[observer]
order = 1
bandwidth = 100.0
[reference]
type = "step"
time = 0.0
amplitude = 1.0
"""


# -- the observer families in a scenario file ---------------------------------------------------
_OBSERVER_TABLES = {
    "eso": 'type = "eso"\nbandwidth = 200.0\nextended_order = 1\nform = "current"',
    "kalman": 'type = "kalman"\norder = 1\nposition_noise_std = 1e-4\nprocess_noise_std = 1e-5',
    "position": 'order = 1\nbandwidth = 100.0\nmeasurement = "position"\n'
    "velocity_bandwidth = 300.0",
}


def audit_observer_toml(audit, tmp: Path) -> None:
    """``[observer]`` of every family in a scenario file: 11 substitutes for each number, and
    keys of the wrong family, through ``hpdob simulate``."""
    import re

    from reliability_audit import SUBSTITUTES

    s = "observer TOML"
    rigid = (
        _TWO_MASS_TOML.split("[plant]")[0]
        + "[plant]\nJ = 3.06e-4\n[nominal]"
        + (_TWO_MASS_TOML.split("[nominal]")[1])
    )
    head, tail = rigid.split("[observer]\norder = 1\nbandwidth = 100.0\n")
    count = 0

    def run(label, table):
        nonlocal count
        count += 1
        path = tmp / f"observer_{count}.toml"
        path.write_text(f"{head}[observer]\n{table}\n{tail}")
        audit.cli(s, label, ["simulate", path, "--out", tmp / "o", "--no-plot"], cwd=tmp)

    for family, table in _OBSERVER_TABLES.items():
        run(f"{family} valid", table)
        lines = table.splitlines()
        for i, line in enumerate(lines):
            if not re.search(r"=\s*-?[0-9]", line):
                continue
            key = line.split("=")[0].strip()
            for label, value in SUBSTITUTES.items():
                changed = [*lines[:i], f"{key} = {value}", *lines[i + 1 :]]
                run(f"{family} {key} = {label}", "\n".join(changed))
    for label, table in {
        "eso with order": _OBSERVER_TABLES["eso"] + "\norder = 1",
        "eso form 'x'": _OBSERVER_TABLES["eso"].replace('"current"', '"x"'),
        "eso without bandwidth": 'type = "eso"',
        "kalman with bandwidth": _OBSERVER_TABLES["kalman"] + "\nbandwidth = 100.0",
        "kalman without process_noise_std": 'type = "kalman"\nposition_noise_std = 1e-4',
        "kalman noise 1e-9/1e-4, order 2 (unstable)": 'type = "kalman"\norder = 2\n'
        "position_noise_std = 1e-9\nprocess_noise_std = 1e-4",
        "type 'lqr'": 'type = "lqr"\nbandwidth = 1.0',
        "position order 8 (poles off)": _OBSERVER_TABLES["position"].replace(
            "order = 1", "order = 8"
        ),
        "position with gain_direction": _OBSERVER_TABLES["position"] + "\ngain_direction = [1, 1]",
    }.items():
        run(label, table)


# -- estimate_disturbance and hpdob estimate -----------------------------------------------------
def audit_estimate(audit) -> None:
    s = "estimate_disturbance"
    state = design_observer(MODEL, order=1, bandwidth=100.0)
    position = design_observer(MODEL, order=1, bandwidth=100.0, measurement="position")
    n = 300
    t = np.arange(n) * 1e-3
    theta, u = 0.1 * np.sin(t), np.full(n, 0.02)
    ok = {"theta": theta, "u": u}

    def case(name, observer=state, **changes):
        kwargs = {k: v for k, v in {**ok, **changes}.items() if v is not _DROP}
        audit.api(s, name, lambda: estimate_disturbance(observer, **kwargs), check=finite_result)

    case("valid")
    case("valid position-only", position)
    case("valid with t", t=t)
    case("valid ESO", design_eso(MODEL, bandwidth=200.0))
    dob = DisturbanceObserver(MODEL, order=1, bandwidth=100.0)
    dob.update((0.1, 0.0), 0.01)
    audit.api(s, "runtime observer (not changed)", lambda: estimate_disturbance(dob, **ok),
              state=lambda: (np.array(dob.state),))  # fmt: skip
    for label, observer in {"str": "x", "None": None, "a model": MODEL,
                            "a continuous model": ServoModel(1.0)}.items():  # fmt: skip
        case(f"observer {label}", observer)
    other = design_observer(ServoModel(2.8e-4).discretize(2e-3), order=1, bandwidth=100.0)
    case("observer at Ts 2 ms, t at 1 ms", other, t=t)
    for name in ("theta", "u"):
        for label, value in {
            "shorter": theta[:-1],
            "nan": np.where(np.arange(n) == 7, NAN, theta),
            "inf": np.where(np.arange(n) == 7, INF, theta),
            "strings": theta.astype(str),
            "2-D": theta[:, None],
            "empty": np.zeros(0),
            "scalar": 1.0,
            "None": None,
            "complex": theta + 1j,
            "object array": np.array([1.0, "a"] * (n // 2), dtype=object),
            "huge ints": [HUGE] * n,
            "1e300 (finite, overflows the estimate)": np.full(n, 1e300),
            "bool": theta > 0,
        }.items():
            case(f"{name} {label}", **{name: value})
    case("omega to a position-only observer", position, omega=np.zeros(n))
    case("omega shorter", omega=np.zeros(n - 1))
    case("omega nan", omega=np.full(n, NAN))
    for label, value in {
        "shorter": t[:-1],
        "decreasing": t[::-1],
        "non-uniform": np.concatenate([t[:100], t[100:] + 4e-4]),
        "step 2 ms": 2 * t,
        "step 1 ms (1 + 1e-7)": t * (1 + 1e-7),
        "nan": np.where(np.arange(n) == 3, NAN, t),
        "constant": np.zeros(n),
    }.items():
        case(f"t {label}", t=value)
    for label, value in {"nan": NAN, "huge int": HUGE, "str": "0", "array": np.zeros(2)}.items():
        case(f"tau0 {label}", tau0=value)
    case("one sample", theta=theta[:1], u=u[:1])
    case("one sample with t", theta=theta[:1], u=u[:1], t=t[:1])


def _write_log(path: Path, header, rows, encoding="utf-8") -> Path:
    lines = [",".join(header)] + [",".join(str(v) for v in row) for row in rows]
    path.write_bytes(("\n".join(lines) + "\n").encode(encoding))
    return path


def audit_estimate_cli(audit, tmp: Path) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq
    import scipy.io

    s = "hpdob estimate"
    n = 600
    t = np.arange(n) * 1e-3
    q, i = 0.1 * np.sin(3 * t), 0.4 + 0.1 * np.cos(3 * t)
    rows = [
        [repr(float(a)), repr(float(b)), repr(float(c))] for a, b, c in zip(t, q, i, strict=True)
    ]
    log = _write_log(tmp / "est.csv", ["t", "q", "i"], rows)
    columns = ["--time", "t", "--position", "q", "--input", "i"]
    ok = ["estimate", log, *columns, "--J-n", "2.8e-4", "--out", tmp / "est", "--no-plot"]

    def cli(name, argv):
        audit.cli(s, name, argv, cwd=tmp)

    cli("valid", ok)
    cli("valid position-only", [*ok, "--measurement", "position", "--velocity-bandwidth", "300"])

    def with_log(path, *extra):
        return ["estimate", path, *columns, "--J-n", "2.8e-4", "--out", tmp / "est",
                "--no-plot", *extra]  # fmt: skip

    # CSV logs
    for label, (header, body) in {
        "missing column": (["t", "q"], [r[:2] for r in rows]),
        "renamed column": (["time", "q", "i"], rows),
        "non-numeric cell": (["t", "q", "i"], [*rows[:5], [rows[5][0], "abc", "1"], *rows[6:]]),
        "empty cell": (["t", "q", "i"], [*rows[:5], [rows[5][0], "", "1"], *rows[6:]]),
        "nan cell": (["t", "q", "i"], [*rows[:5], [rows[5][0], "nan", "1"], *rows[6:]]),
        "ragged row": (["t", "q", "i"], [*rows[:5], rows[5][:2], *rows[6:]]),
        "header only": (["t", "q", "i"], []),
        "one row": (["t", "q", "i"], rows[:1]),
        "non-uniform time": (["t", "q", "i"], [*rows[:9], ["0.0095", *rows[9][1:]], *rows[10:]]),
        "decreasing time": (["t", "q", "i"], rows[::-1]),
        "1e300 values (estimate overflows)": (["t", "q", "i"], [[r[0], "1e300", "1e300"]
                                                               for r in rows]),
    }.items():  # fmt: skip
        path = _write_log(tmp / f"est_{label.split()[0]}_{len(label)}.csv", header, body)
        cli(f"CSV {label}", with_log(path))
    cli("UTF-16 CSV", with_log(_write_log(tmp / "est16.csv", ["t", "q", "i"], rows, "utf-16")))
    # Parquet and MAT
    table = {"t": pa.array(t), "q": pa.array(q), "i": pa.array(i)}
    for label, data in {
        "valid": table,
        "string column": {**table, "q": pa.array([str(v) for v in q])},
        "missing column": {k: v for k, v in table.items() if k != "i"},
        "null value": {**table, "q": pa.array([None if k == 9 else v for k, v in enumerate(q)])},
    }.items():
        path = tmp / f"est_{label.split()[0]}.parquet"
        pq.write_table(pa.table(data), path)
        cli(f"Parquet {label}", with_log(path))
    for label, variables in {
        "valid": {"t": t, "q": q, "i": i},
        "string variable": {"t": t, "q": "abc", "i": i},
        "missing variable": {"t": t, "q": q},
        "matrix": {"t": t, "q": np.ones((3, 4)), "i": i},
        "shorter input": {"t": t, "q": q, "i": i[:-10]},
    }.items():
        path = tmp / f"est_{label.split()[0]}.mat"
        scipy.io.savemat(path, variables)
        cli(f"MAT {label}", with_log(path))
    # options
    for label, extra in {
        "--Ts with --time, not matching": ["--Ts", "2e-3"],
        "--order -1": ["--order", "-1"],
        "--order 60": ["--order", "60"],
        "--bandwidth nan": ["--bandwidth", "nan"],
        "--bandwidth 0": ["--bandwidth", "0"],
        "--bandwidth 1e-300": ["--bandwidth", "1e-300"],
        "--poles wrong count": ["--poles", "0.9"],
        "--poles and --bandwidth": ["--poles", "0.9,0.9", "--bandwidth", "100"],
        "--poles text": ["--poles", "a,b"],
        "--gain-direction with position": ["--measurement", "position",
                                           "--gain-direction", "1,1"],
        "--velocity-bandwidth with state": ["--velocity-bandwidth", "100"],
        "--velocity-bandwidth 0": ["--measurement", "position", "--velocity-bandwidth", "0"],
        "--gain-direction 0,0": ["--gain-direction", "0,0"],
        "--gain-direction 3 values": ["--gain-direction", "1,1,1"],
        "--b-n -1": ["--b-n", "-1"],
        "--input-gain nan": ["--input-gain", "nan"],
        "--input-gain 0": ["--input-gain", "0"],
        "--input-gain unknown variable": ["--input-gain", "gtau"],
        "--axis angular": ["--axis", "angular"],
        "--type eso valid": ["--type", "eso", "--bandwidth", "200"],
        "--type kalman valid": ["--type", "kalman", "--position-noise-std", "1e-4"],
        "--type eso --order 1": ["--type", "eso", "--order", "1"],
        "--type eso --velocity-bandwidth (dob's)": ["--type", "eso", "--velocity-bandwidth",
                                                    "100"],
        "--type kalman without --position-noise-std": ["--type", "kalman"],
        "--type kalman --form (eso's)": ["--type", "kalman", "--position-noise-std", "1e-4",
                                         "--form", "current"],
        "--type kalman noise 1e-9/1e-4 --order 2 (unstable)": [
            "--type", "kalman", "--position-noise-std", "1e-9", "--process-noise-std", "1e-4",
            "--order", "2"],
        "--type eso --extended-order 2 --bandwidth 5 (poles off)": [
            "--type", "eso", "--extended-order", "2", "--bandwidth", "5"],
    }.items():  # fmt: skip
        cli(label, [*ok, *extra])
    without_jn = ["estimate", log, *columns, "--out", tmp / "est", "--no-plot"]
    for label, extra in {
        "--J-n 0": ["--J-n", "0"],
        "--J-n nan": ["--J-n", "nan"],
        "--J-n -1": ["--J-n", "-1"],
        "--J-n 1e-320": ["--J-n", "1e-320"],
        "no nominal model": [],
    }.items():
        cli(label, [*without_jn, *extra])
    ident = tmp / "ident"
    ident.mkdir()
    for label, text in {
        "not JSON": "{",
        "no parameters": '{"J": 1}',
        "J negative": '{"parameters": {"J": -1.0, "b": 0.0}}',
        "J string": '{"parameters": {"J": "big", "b": 0.0}}',
        "J 1e400 (JSON infinity)": '{"parameters": {"J": 1e400, "b": 0.0}}',
        "J NaN": '{"parameters": {"J": NaN, "b": 0.0}}',
        "b null": '{"parameters": {"J": 1.0, "b": null}}',
        "parameters a list": '{"parameters": [1, 2]}',
        "UTF-16": None,
    }.items():
        path = ident / f"{len(label)}_{label.split()[0]}.json"
        if text is None:
            path.write_bytes('{"parameters": {"J": 1.0, "b": 0.0}}'.encode("utf-16"))
        else:
            path.write_text(text)
        cli(f"--from-identification {label}", [*without_jn, "--from-identification", path])
    cli("--from-identification missing", [*without_jn, "--from-identification", tmp / "no.json"])
    cli("--from-identification a directory", [*without_jn, "--from-identification", ident])
    cli("--J-n and --from-identification", [*ok, "--from-identification", tmp / "no.json"])
    cli("--out ''", [*ok[:-3], "--out", "", "--no-plot"])
    cli("--out a file", [*ok[:-3], "--out", log, "--no-plot"])
    cli("log is a directory", ["estimate", tmp, *ok[2:]])
    cli("log missing", ["estimate", tmp / "none.csv", *ok[2:]])
    cli("log .txt", ["estimate", log.with_suffix(".txt"), *ok[2:]])
    cli("no log, no --emps", ["estimate", "--J-n", "1"])
    cli("--emps with --time", ["estimate", "--emps", "--time", "t", "--J-n", "1"])
    cli("--position missing", ["estimate", log, "--time", "t", "--input", "i", "--J-n", "1"])


# -- tune, compare ------------------------------------------------------------------------------
def audit_tune(audit) -> None:
    s = "tune"
    fast = {"nominal": ServoModel(2.8e-4), "Ts": 1e-3, "families": ["state"],
            "scenario": {"reference": paper.REFERENCE, "duration": 0.5}}  # fmt: skip
    audit.api(s, "valid (state family, short scenario)", lambda: tune(**fast))
    for label, change in {
        "nominal None": {"nominal": None},
        "nominal discretised": {"nominal": MODEL},
        "nominal two-mass": {"nominal": TwoMassServo(**TWO_MASS)},
        "Ts 0": {"Ts": 0.0},
        "Ts nan": {"Ts": NAN},
        "Ts huge int": {"Ts": HUGE},
        "Ts 1e-320": {"Ts": 1e-320},
        "controller str": {"controller": "PD"},
        "sensor str": {"sensor": "encoder"},
        "actuator delay 2000": {"actuator": Actuator(delay_samples=2000)},
        "actuator int": {"actuator": 1},
        "J_range (0, 1)": {"J_range": (0.0, 1.0)},
        "J_range (1, 0.5)": {"J_range": (1.0, 0.5)},
        "J_range (nan, 1)": {"J_range": (NAN, 1.0)},
        "J_range str": {"J_range": "1,2"},
        "J_range 3 values": {"J_range": (1, 2, 3)},
        "J_range scalar": {"J_range": 1.0},
        "J_range huge": {"J_range": (1.0, HUGE)},
        "J_range dict": {"J_range": {1: 2, 3: 4}},
        "b_range (-1, 0)": {"b_range": (-1.0, 0.0)},
        "b_range (inf, inf)": {"b_range": (INF, INF)},
        "disturbance_frequency 0": {"disturbance_frequency": 0.0},
        "disturbance_frequency nan": {"disturbance_frequency": NAN},
        "disturbance_frequency (2, 1)": {"disturbance_frequency": (2.0, 1.0)},
        "disturbance_frequency str": {"disturbance_frequency": "2"},
        "disturbance_frequency above Nyquist": {"disturbance_frequency": 600.0},
        "families []": {"families": []},
        "families 'state'": {"families": "state"},
        "families ['x']": {"families": ["x"]},
        "families [1]": {"families": [1]},
        "objective 'speed'": {"objective": "speed"},
        "noise_limit 0": {"noise_limit": 0.0},
        "noise_limit nan": {"noise_limit": NAN},
        "coulomb -1": {"coulomb": -1.0},
        "coulomb nan": {"coulomb": NAN},
        "scenario str": {"scenario": "paper"},
        "scenario {}": {"scenario": {}},
        "scenario unknown key": {"scenario": {**fast["scenario"], "plant": 1}},
        "scenario duration nan": {"scenario": {**fast["scenario"], "duration": NAN}},
        "scenario duration -1": {"scenario": {**fast["scenario"], "duration": -1.0}},
        "scenario duration 1e12": {"scenario": {**fast["scenario"], "duration": 1e12}},
        "scenario reference str": {"scenario": {**fast["scenario"], "reference": "step"}},
        "unknown argument": {"plant": ServoModel(1.0)},
    }.items():
        audit.api(s, label, lambda c=change: tune(**{**fast, **c}))


def audit_tune_cli(audit, tmp: Path) -> None:
    s = "hpdob tune"
    base = ["tune", "--out", tmp / "tune", "--no-plot", "--families", "state"]
    for label, extra in {
        "--J-range a,b": ["--J-range", "a,b"],
        "--J-range 1": ["--J-range", "1"],
        "--J-range 2,1": ["--J-range", "2,1"],
        "--J-range 0,1": ["--J-range", "0,1"],
        "--J-range nan,1": ["--J-range", "nan,1"],
        "--b-range -1,0": ["--b-range", "-1,0"],
        "--frequency 0": ["--frequency", "0"],
        "--frequency nan": ["--frequency", "nan"],
        "--frequency 1,2,3": ["--frequency", "1,2,3"],
        "--families state,x": ["--families", "state,x"],
        "--families ''": ["--families", ""],
        "--objective speed": ["--objective", "speed"],
        "--noise-limit 0": ["--noise-limit", "0"],
        "--counts-per-rev 0": ["--counts-per-rev", "0"],
        "--counts-per-rev abc": ["--counts-per-rev", "abc"],
        "--counts-per-rev 2^60": ["--counts-per-rev", str(2**60)],
        "--noise-std -1": ["--noise-std", "-1"],
        "--delay -1": ["--delay", "-1"],
        "--delay 2000": ["--delay", "2000"],
        "--delay 1.5": ["--delay", "1.5"],
        "--torque-limit 0": ["--torque-limit", "0"],
        "--coulomb -1": ["--coulomb", "-1"],
        "--J-n 0": ["--J-n", "0"],
        "--Ts 0": ["--Ts", "0"],
        "--Ts nan": ["--Ts", "nan"],
        "--kp nan": ["--kp", "nan"],
        "--J 1 (a plant)": ["--J", "1"],
        "--out ''": ["--out", ""],
        "--export-c ''": ["--export-c", ""],
        "--export-c with --prefix math": ["--export-c", tmp / "c", "--prefix", "math"],
        "--export-c with --dtype half": ["--export-c", tmp / "c", "--dtype", "half"],
        "--prefix without --export-c": ["--prefix", "axis1"],
    }.items():
        audit.cli(s, label, [*base, *extra], cwd=tmp)


def audit_compare(audit) -> None:
    s = "compare_observers"
    fast = {"sensors": ("ideal",), "candidates": {"DOb": {"order": 0}}, "duration": 0.3}
    audit.api(s, "valid (one candidate, 0.3 s)", lambda: compare_observers(**fast))
    for label, change in {
        "sensors None": {"sensors": None},
        "sensors 'lab'": {"sensors": "lab"},
        "sensors []": {"sensors": []},
        "sensors 1": {"sensors": 1},
        "sensors twice": {"sensors": ("ideal", "ideal")},
        "noise_gain 0": {"noise_gain": 0.0},
        "noise_gain nan": {"noise_gain": NAN},
        "noise_gain huge int": {"noise_gain": HUGE},
        "noise_gain str": {"noise_gain": "10"},
        "noise_gain bool": {"noise_gain": True},
        "candidates {}": {"candidates": {}},
        "candidates list": {"candidates": [{"order": 0}]},
        "candidate not a dict": {"candidates": {"x": 3}},
        "candidate name not a str": {"candidates": {1: {"order": 0}}},
        "candidate type 'lqr'": {"candidates": {"x": {"type": "lqr"}}},
        "candidate order -1": {"candidates": {"x": {"order": -1}}},
        "candidate unknown key": {"candidates": {"x": {"order": 0, "gain": 1.0}}},
        "candidate with the tuned bandwidth": {"candidates": {"x": {"order": 0,
                                                                    "bandwidth": 5.0}}},
        "candidate with poles": {"candidates": {"x": {"order": 0, "poles": [0.9]}}},
        "Kalman candidate with its noise": {"candidates": {"x": {
            "type": "kalman", "position_noise_std": 1.0, "process_noise_std": 1.0}}},
        "ESO candidate extended_order 9": {"candidates": {"x": {"type": "eso",
                                                                "extended_order": 9}}},
        "duration 0": {"duration": 0.0},
        "duration nan": {"duration": NAN},
        "duration 1e-6 (below Ts)": {"duration": 1e-6},
        "duration 1e12": {"duration": 1e12},
        "duration str": {"duration": "1"},
    }.items():  # fmt: skip
        audit.api(s, label, lambda c=change: compare_observers(**{**fast, **c}))


def audit_compare_cli(audit, tmp: Path) -> None:
    for label, extra in {
        "--sensor lab": ["--sensor", "lab"],
        "--noise-gain 0": ["--noise-gain", "0"],
        "--noise-gain nan": ["--noise-gain", "nan"],
        "--noise-gain -1": ["--noise-gain", "-1"],
        "--noise-gain abc": ["--noise-gain", "abc"],
        "--out ''": ["--out", ""],
        "--out a file": ["--out", Path(__file__)],
    }.items():
        audit.cli("hpdob compare", label, ["compare", "--no-plot", *extra], cwd=tmp)


# -- robust_stability_map(observer=...) --------------------------------------------------------
def audit_robust_map(audit) -> None:
    s = "robust_stability_map"
    base = {"J_ratio": [0.5, 1.0, 2.0], "bandwidth": [100.0, 200.0],
            "nominal": ServoModel(2.8e-4), "Ts": 1e-3, "controller": PD(50.0, 5.0)}  # fmt: skip
    kalman = {"type": "kalman", "position_noise_std": 1e-4}
    audit.api(s, "valid ESO", lambda: robust_stability_map(**base, observer={"type": "eso"}))
    audit.api(s, "valid Kalman", lambda: robust_stability_map(**base, observer=kalman))
    audit.api(s, "valid position", lambda: robust_stability_map(
        **base, observer={"order": 1, "measurement": "position"}))  # fmt: skip
    for label, observer in {
        "str": "eso",
        "type 'x'": {"type": "x"},
        "ESO extended_order 'a'": {"type": "eso", "extended_order": "a"},
        "ESO extended_order None": {"type": "eso", "extended_order": None},
        "ESO extended_order 1.5": {"type": "eso", "extended_order": 1.5},
        "ESO extended_order huge": {"type": "eso", "extended_order": HUGE},
        "ESO form 'x'": {"type": "eso", "form": "x"},
        "ESO unknown key": {"type": "eso", "order": 1},
        "Kalman without position_noise_std": {"type": "kalman"},
        "Kalman position_noise_std -1": {**kalman, "position_noise_std": -1.0},
        "Kalman with process_noise_std (chosen per bandwidth)": {**kalman,
                                                                 "process_noise_std": 1.0},
        "dob order 'a'": {"order": "a"},
        "dob order list": {"order": [1]},
        "dob without order": {"measurement": "position"},
        "dob with bandwidth (the grid's)": {"order": 1, "bandwidth": 5.0},
        "dob with poles": {"order": 1, "poles": [0.9, 0.9]},
        "dob velocity_bandwidth -1": {"order": 1, "measurement": "position",
                                      "velocity_bandwidth": -1.0},
        "dob gain_direction 0,0": {"order": 1, "gain_direction": (0.0, 0.0)},
    }.items():  # fmt: skip
        audit.api(s, f"observer {label}", lambda o=observer: robust_stability_map(
            **base, observer=o))  # fmt: skip
    for label, extra in {
        "observer and order": {"order": 1},
        "observer and measurement='position'": {"measurement": "position"},
        "observer and gain_direction": {"gain_direction": (0.0, 1.0)},
    }.items():
        audit.api(s, label, lambda e=extra: robust_stability_map(
            **base, observer={"type": "eso"}, **e))  # fmt: skip
    audit.api(
        s,
        "ESO at unrealisable bandwidths",
        lambda: robust_stability_map(
            **{**base, "bandwidth": [0.5, 100.0]}, observer={"type": "eso", "extended_order": 2}
        ),
    )


# -- hpdob design / export-c --type ----------------------------------------------------------------
def audit_design_cli(audit, tmp: Path) -> None:
    for command in ("design", "export-c"):
        s = f"hpdob {command} --type"
        tail = ["--out", tmp / "c"] if command == "export-c" else []
        for label, extra in {
            "eso valid": ["--type", "eso", "--bandwidth", "200"],
            "kalman valid": ["--type", "kalman", "--position-noise-std", "1e-4"],
            "eso --order 1": ["--type", "eso", "--order", "1"],
            "eso --extended-order -1": ["--type", "eso", "--extended-order", "-1"],
            "eso --extended-order 5": ["--type", "eso", "--extended-order", "5"],
            "eso --extended-order abc": ["--type", "eso", "--extended-order", "abc"],
            "eso --form x": ["--type", "eso", "--form", "x"],
            "eso --bandwidth 0": ["--type", "eso", "--bandwidth", "0"],
            "eso --bandwidth 1e-300": ["--type", "eso", "--bandwidth", "1e-300"],
            "eso --extended-order 2 --bandwidth 5 (poles off)": [
                "--type", "eso", "--extended-order", "2", "--bandwidth", "5"],
            "eso --position-noise-std (kalman's)": ["--type", "eso", "--position-noise-std",
                                                    "1e-4"],
            "eso --process-noise-std (kalman's)": ["--type", "eso", "--process-noise-std", "1"],
            "eso --poles": ["--type", "eso", "--poles", "0.9,0.9,0.9"],
            "eso --measurement position": ["--type", "eso", "--measurement", "position"],
            "kalman without --position-noise-std": ["--type", "kalman"],
            "kalman --position-noise-std 0": ["--type", "kalman", "--position-noise-std", "0"],
            "kalman --position-noise-std -1": ["--type", "kalman", "--position-noise-std", "-1"],
            "kalman --process-noise-std 0": ["--type", "kalman", "--position-noise-std", "1e-4",
                                             "--process-noise-std", "0"],
            "kalman --order 5": ["--type", "kalman", "--position-noise-std", "1e-4", "--order",
                                 "5"],
            "kalman --bandwidth 5000 (above Nyquist/2)": ["--type", "kalman",
                                                          "--position-noise-std", "1e-4",
                                                          "--bandwidth", "5000"],
            "kalman --bandwidth with --process-noise-std": [
                "--type", "kalman", "--position-noise-std", "1e-4", "--process-noise-std",
                "1e-3", "--bandwidth", "100"],
            "kalman --extended-order 1 (eso's)": ["--type", "kalman", "--position-noise-std",
                                                  "1e-4", "--extended-order", "1"],
            "kalman --form predictive (eso's)": ["--type", "kalman", "--position-noise-std",
                                                 "1e-4", "--form", "predictive"],
            "kalman noise 1e-9/1e-4 --order 2 (unstable)": [
                "--type", "kalman", "--position-noise-std", "1e-9", "--process-noise-std",
                "1e-4", "--order", "2"],
            "dob --extended-order 1 (eso's)": ["--extended-order", "1"],
            "dob --form predictive (eso's)": ["--form", "predictive"],
            "dob --position-noise-std (kalman's)": ["--position-noise-std", "1e-4"],
            "--type lqr": ["--type", "lqr"],
        }.items():  # fmt: skip
            audit.cli(s, label, [command, *extra, *tail], cwd=tmp)
    s = "hpdob export-c --type"
    for label, extra in {
        "eso --prefix math": ["--type", "eso", "--prefix", "math"],
        "kalman --dtype half": ["--type", "kalman", "--position-noise-std", "1e-4", "--dtype",
                                "half"],
        "eso --nan-guard --out a file": ["--type", "eso", "--nan-guard", "--out",
                                         Path(__file__)],
    }.items():  # fmt: skip
        audit.cli(s, label, ["export-c", *extra, *([] if "--out" in extra else
                                                    ["--out", tmp / "c"])], cwd=tmp)  # fmt: skip


def run(audit, tmp: Path) -> None:
    """Every part of this audit."""
    audit_position(audit)
    audit_eso(audit)
    audit_kalman(audit)
    audit_two_mass(audit, tmp)
    audit_observer_toml(audit, tmp)
    audit_estimate(audit)
    audit_estimate_cli(audit, tmp)
    audit_tune(audit)
    audit_tune_cli(audit, tmp)
    audit_compare(audit)
    audit_compare_cli(audit, tmp)
    audit_robust_map(audit)
    audit_design_cli(audit, tmp)
