"""Reliability audit, part three (issue 27): the second audit's input cases, counted.

Run with ``python benchmarks/reliability_audit.py --part second [--verbose]`` (or everything
with no ``--part``). The outcomes are classified as in reliability_audit.py. The signal, dask
and stale-temporary findings of issue 27 need subprocesses or a cluster and are tested in
tests/cli/test_reliability_second_audit.py and tests/cli/test_interrupts.py instead.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from hpdob import (
    PD,
    Encoder,
    ExtendedStateObserver,
    KalmanDisturbanceObserver,
    Observer,
    ServoModel,
    SimulationResult,
    design_observer,
    estimation_response,
    paper,
    read_log,
    signals,
    update,
)

SCENARIO = """\
label = "{label}"
Ts = 1e-3
duration = 0.05
[plant]
J = 3.06e-4
[nominal]
J = 2.8e-4
[controller]
kp = 50.0
kd = 5.0
[reference]
type = "step"
time = 0.0
amplitude = 1.0
"""

NOT_NUMBERS = {
    "np.ma.masked": np.ma.masked,
    "datetime64": np.datetime64("2020-01-01"),
    "timedelta64": np.timedelta64(3, "s"),
}


def _observers():
    model = ServoModel(2.8e-4).discretize(1e-3)
    return {
        "state": lambda: Observer.of(design_observer(model, order=1, bandwidth=100.0)),
        "position": lambda: Observer.of(
            design_observer(model, order=1, bandwidth=100.0, measurement="position")
        ),
        "eso": lambda: ExtendedStateObserver(model, bandwidth=100.0),
        "kalman": lambda: KalmanDisturbanceObserver(
            model, position_noise_std=1e-4, process_noise_std=1.0
        ),
    }


def audit_numbers(audit) -> None:
    """Item 11: values that are not numbers, at entry points that take numbers."""
    observer = design_observer(ServoModel(2.8e-4).discretize(1e-3), order=1, bandwidth=100.0)
    entries = {
        "ServoModel(b)": lambda v: ServoModel(2.8e-4, v),
        "ServoModel(J)": lambda v: ServoModel(v),
        "PD(kp)": lambda v: PD(v, 5.0),
        "Encoder(noise_std)": lambda v: Encoder(4096, noise_std=v),
        "Step(time)": lambda v: signals.Step(v, 1.0),
        "Sine(frequency)": lambda v: signals.Sine(1.0, v),
        "estimation_response(f)": lambda v: estimation_response(observer, v),
        "estimation_response([1, f])": lambda v: estimation_response(observer, [1.0, v]),
    }
    for entry, call in entries.items():
        for label, value in NOT_NUMBERS.items():
            audit.api("not-a-number", f"{entry} = {label}", lambda c=call, v=value: c(v))


def audit_overflow(audit) -> None:
    """Item 8: finite inputs that overflow each family's state (runtime and functional)."""
    for family, make in _observers().items():
        observer = make()
        big = (1e308, -1e308) if observer._system.measurement == "state" else 1e308

        def forty(o=observer, x=big):
            for _ in range(40):
                o.update(x, 1e308)
            return o.estimate(x if isinstance(x, float) else (0.0, 0.0))

        audit.api("overflowing state", f"{family} runtime x40", forty, check=math.isfinite)
        # the refused update itself leaves the last (finite) state
        audit.api("overflowing state", f"{family} refused update keeps the state",
                  lambda o=observer, x=big: o.update(x, 1e308),
                  state=lambda o=observer: o._state)  # fmt: skip
        system, state = observer._system, observer._state

        def functional(s=system, st=state, x=big):
            for _ in range(40):
                st = update(s, st, x, 1e308)
            return st

        audit.api("overflowing state", f"{family} update() x40", functional,
                  check=lambda st: all(map(math.isfinite, st)))  # fmt: skip


def audit_files(audit, tmp: Path) -> None:
    """Items 11-13: CSV cells, paths, truncated traces, oversized files."""
    log = tmp / "underscore.csv"
    rows = [f"{k * 1e-3!r},{'0_4' if k == 5 else '0.0'},0.1" for k in range(20)]
    log.write_text("t,q,i\n" + "\n".join(rows) + "\n")  # 20 samples, one cell 0_4
    audit.api("files", "CSV cell 0_4", lambda: read_log(log, time="t", position="q", input="i"))
    audit.api("files", "read_log(3)", lambda: read_log(3, time="t", position="q", input="i"))
    text = paper.run("PD", duration=0.05).to_csv(tmp / "run.csv").read_text()
    cut = tmp / "cut.csv"
    cut.write_text(text[: len(text) // 2])
    audit.api("files", "from_csv(truncated)", lambda: SimulationResult.from_csv(cut))
    big = tmp / "big.csv"
    with open(big, "wb") as handle:
        handle.truncate(300 << 20)  # sparse
    audit.api("files", "300 MB log", lambda: read_log(big, time="t", position="q", input="i"))
    big.unlink()


def audit_cli(audit, tmp: Path) -> None:
    """Items 1, 9, 11, 12, 13 on the command line."""
    a_file = tmp / "a_file"
    a_file.write_text("x\n")
    spec = tmp / "s.toml"
    spec.write_text(SCENARIO.format(label="s") + "[sweep]\nn = 2\n")
    plain = tmp / "plain.toml"
    plain.write_text(SCENARIO.format(label="s"))
    big = tmp / "big.toml"
    big.write_text(SCENARIO.format(label="s") + "# padding\n" * 200_000)
    cases = {
        "sweep --out a_file/r.csv": ["sweep", spec, "--out", a_file / "r.csv"],
        "compare --out a_file": ["compare", "--out", a_file],
        "tune --out a_file": ["tune", "--out", a_file],
        "tune --export-c a_file": ["tune", "--export-c", a_file],
        "reproduce --out a_file": ["reproduce", "--out", a_file],
        "simulate --out a_file/d": ["simulate", plain, "--out", a_file / "d"],
        "estimate --out a_file": ["estimate", "--emps", "--J-n", "95", "--out", a_file],
        "identify --out a_file": ["identify", "--emps", "--out", a_file],
        "analyze stability --out a_file": ["analyze", "stability", "--out", a_file],
        "export-c --out a_file": ["export-c", "--out", a_file],
        "bode --frequency 1000": ["analyze", "bode", "--frequency", "1000"],
        "bode --frequency 600": ["analyze", "bode", "--frequency", "600"],
        "bode --frequency 500": ["analyze", "bode", "--frequency", "500"],
        "bode --dpi 1e-300": ["analyze", "bode", "--dpi", "1e-300"],
        "noise --bandwidths 1:1e400:5": ["analyze", "noise", "--bandwidths", "1:1e400:5"],
        "noise --bandwidths 10:2000:1e8": ["analyze", "noise", "--bandwidths", "10:2000:100000000"],
        "stability --orders 1,1": ["analyze", "stability", "--orders", "1,1"],
        "stability 1001 x 1000": ["analyze", "stability", "--values", "1:2:1001",
                                  "--bandwidths", "1:2:1000"],
        "tune --Ts 0.2": ["tune", "--Ts", "0.2"],
        "export-c --J-n -5e-4": ["export-c", "--J-n", "-5e-4"],
        "design --J-n 1e-300 (valid)": ["design", "--J-n", "1e-300"],
        "sweep --scheduler ''": ["sweep", spec, "--out", tmp / "r.csv", "--scheduler", ""],
        "simulate 2 MB scenario": ["simulate", big, "--out", tmp / "big"],
    }  # fmt: skip
    out = tmp / "analysis"
    for name, argv in cases.items():
        if argv[0] in ("analyze",) and "--out" not in argv:
            argv = [*argv, "--out", out]
        audit.cli("hpdob (issue 27)", name, argv, cwd=tmp)
    for label in ("x\u202egnp.exe", "a\u200bb", "a\u2028b", "a\u2066b"):
        path = tmp / "label.toml"
        path.write_text(SCENARIO.format(label=label.encode("unicode_escape").decode()))
        argv = ["simulate", path, "--out", tmp / "labels", "--no-plot"]
        audit.cli("hpdob (issue 27)", f"label {label!a}", argv, cwd=tmp)


def run(audit, tmp: Path) -> None:
    audit_numbers(audit)
    audit_overflow(audit)
    audit_files(audit, tmp)
    audit_cli(audit, tmp)
