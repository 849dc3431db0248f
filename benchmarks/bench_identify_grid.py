"""Issue 23's accuracy grid: identification with default settings on SYNTHETIC logs.

Every log is made by ``hpdob.simulate`` (tests/synthetic_logs.py): J = 1.2e-3 kg m^2,
b = 2e-3 N m s/rad, encoders of 1024 to 65536 counts/rev, Ts of 0.25 to 2 ms, 20 s of open-loop
chirp, PRBS or multisine torque (bandwidth 10 Hz) or a closed-loop PD tracking run (5 Hz), Coulomb
friction 0 to 30 % of the input's RMS, 1 % noise on the logged input. The targets: J within
3 %, b within 10 % or 0.02 J 2 pi B (B the excitation bandwidth), Coulomb within 5 % or 2 % of
the input's RMS.

Step responses (``--steps``, or ``--kinds`` naming them): PD steps of 1 rad every second one
way (``steps``, a staircase) or both ways (``steps-both``); open-loop torque pulses of 0.1 N m
for 0.1 s every second, alternating (``pulses``) or one way (``pulses-one-way``), each resting
between moves. A one-way log cannot tell Coulomb friction from the offset: identify refuses it,
and the grid checks that the refusal's first way out, ``friction="viscous"``, works: J and b
against their targets, and the lumped offset (the true offset is 0) against Coulomb's target.
``steps pair`` identifies a staircase up and one down together with ``offsets="shared"`` (the
refusal's other way out), with the targets of the both-ways logs. Run with

    python benchmarks/bench_identify_grid.py            # the 192 logs (about 3 minutes, loaded)
    python benchmarks/bench_identify_grid.py --steps    # the step responses (240 logs)
    python benchmarks/bench_identify_grid.py --quick    # 1024 and 65536 counts, 0.25 and 2 ms
                                                        # (48 logs, about 2 minutes)

It prints one line per log (errors of J, b, Coulomb; ok or --, and the warnings of the default
identification) and, for comparison, the errors of the benchmark's IDIM-LS with its own
default settings on the same logs and whether its diagnostics warn; then how often the
filter-sensitivity rule would warn without its floors (a parameter moving by more than one
standard deviation when the filters' bandwidth is halved).
"""

from __future__ import annotations

import argparse
import itertools
import math
import sys
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from hpdob import ParameterValueError, identify
from synthetic_logs import KINDS, synthetic_log

COUNTS = (1024, 4096, 16384, 65536)
PERIODS = (2.5e-4, 5e-4, 1e-3, 2e-3)
GRID_KINDS = tuple(k for k in KINDS if k != "chirp+prbs")
STEP_KINDS = ("steps", "steps-both", "pulses", "pulses-one-way", "steps pair")
FRACTIONS = (0.0, 0.1, 0.3)
ONE_WAY = ("steps", "pulses-one-way")


def errors(fit, s, lumped: bool = False) -> tuple[float, float, float, bool]:
    """Errors of J [%], b [% of the allowance] and Coulomb [% of the allowance], and pass.
    ``lumped``: the Coulomb friction is the offset (friction="viscous" on a one-way log)."""
    e_J = 100.0 * (fit.J / s.J - 1.0)
    b_allow = max(0.1 * s.b, 0.02 * s.J * 2 * math.pi * s.bandwidth)
    c_allow = max(0.05 * s.coulomb, 0.02 * s.input_rms)
    e_b = 100.0 * (fit.b - s.b) / b_allow
    coulomb = abs(fit.offset) if lumped else fit.coulomb
    e_c = 100.0 * (coulomb - s.coulomb) / c_allow
    return e_J, e_b, e_c, abs(e_J) <= 3.0 and abs(e_b) <= 100.0 and abs(e_c) <= 100.0


def literal_rule(fit) -> bool:
    """Whether J, b or Coulomb moves by more than one standard deviation when the filters'
    bandwidth is halved (the sensitivity rule without its floors)."""
    moves = (fit.sensitivity or {}).get("/2", {})
    return any(abs(moves.get(name, 0.0)) > 1.0 for name in ("J", "b", "coulomb"))


def identify_case(kind, n, Ts, fraction):
    """The log(s), the default identification, how it was reached, and IDIM-LS."""
    if kind == "steps pair":
        up, down = (synthetic_log(kind=k, counts=n, Ts=Ts, coulomb_fraction=fraction, seed=1)
                    for k in ("steps", "steps-down"))  # fmt: skip
        fit = identify([up.log, down.log], offsets="shared")
        ls = identify([up.log, down.log], offsets="shared", method="idim-ls")
        return up, fit, "offsets='shared'", ls, False
    s = synthetic_log(kind=kind, counts=n, Ts=Ts, coulomb_fraction=fraction, seed=1)
    try:
        fit, how = s.log.identify(), "defaults"
    except ParameterValueError as err:
        if kind not in ONE_WAY or "friction='viscous'" not in str(err):
            raise
        fit, how = s.log.identify(friction="viscous"), "refused; friction='viscous'"
    lumped = how != "defaults"
    ls = s.log.identify(method="idim-ls", friction="viscous" if lumped else "viscous+coulomb")
    return s, fit, how, ls, lumped


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a quarter of the grid")
    parser.add_argument("--steps", action="store_true", help="the step-response logs")
    parser.add_argument("--kinds", default=None, help="comma-separated kinds")
    args = parser.parse_args()
    kinds = args.kinds.split(",") if args.kinds else (STEP_KINDS if args.steps else GRID_KINDS)
    counts = (1024, 65536) if args.quick else COUNTS
    periods = (2.5e-4, 2e-3) if args.quick else PERIODS
    print("errors: J [%], b and Coulomb [% of their allowance]; default settings, then IDIM-LS")
    print(f"{'log':<15}{'counts':>7}{'Ts [ms]':>8}{'c/rms':>6} | {'J':>6}{'b':>6}{'c':>6}  ok "
          f"| {'LS J':>6}{'b':>6}{'c':>6}  ok | warnings")  # fmt: skip
    passed = total = ls_passed = warned = literal = silent = 0
    ls_warned = {True: 0, False: 0}
    ls_count = {True: 0, False: 0}
    worst = [0.0, 0.0, 0.0]
    table: dict = {}
    refusals: dict = {}
    for kind, n, Ts, fraction in itertools.product(kinds, counts, periods, FRACTIONS):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            s, fit, how, ls, lumped = identify_case(kind, n, Ts, fraction)
        default_warnings = [w for w in caught if w.message.args[0] in fit.warnings]
        refusals[kind] = how
        warned += bool(default_warnings)
        literal += literal_rule(fit)
        e = errors(fit, s, lumped)
        e_ls = errors(ls, s, lumped)
        ls_count[e_ls[3]] += 1
        ls_warned[e_ls[3]] += bool(ls.warnings)
        total += 1
        passed += e[3]
        silent += not e[3] and not default_warnings
        ls_passed += e_ls[3]
        worst = [max(w, abs(x)) for w, x in zip(worst, e[:3], strict=True)]
        row = table.setdefault((kind, n), [0.0, 0.0, 0.0, 0, 0, 0.0, 0, 0.0])
        row[:3] = [max(w, abs(x)) for w, x in zip(row[:3], e[:3], strict=True)]
        row[3] += e[3]
        row[4] += 1
        row[5] = max(row[5], abs(e_ls[0]))
        row[6] += e_ls[3]
        row[7] = max(row[7], abs(100.0 * (fit.b / s.b - 1.0)))
        names = sorted({type(w.message).__name__ for w in default_warnings})
        print(f"{kind:<15}{n:>7}{1e3 * Ts:>8g}{fraction:>6g} | {e[0]:>+6.2f}{e[1]:>+6.0f}"
              f"{e[2]:>+6.0f}  {'ok' if e[3] else '--'} | {e_ls[0]:>+6.1f}{e_ls[1]:>+6.0f}"
              f"{e_ls[2]:>+6.0f}  {'ok' if e_ls[3] else '--'} | {','.join(names)}")  # fmt: skip
    print(
        f"default settings: {passed}/{total} logs meet every target; worst |error| J "
        f"{worst[0]:.2f} %, b {worst[1]:.0f} %, Coulomb {worst[2]:.0f} % of the allowance"
    )
    print(f"IdentificationWarnings with the default settings: {warned}/{total} logs; logs "
          f"outside the targets without a warning: {silent}")  # fmt: skip
    print(f"... the sensitivity rule without its floors (> 1 std, halved): {literal}/{total}")
    print(f"IDIM-LS with the benchmark's rules: {ls_passed}/{total}; its diagnostics warn on "
          f"{ls_warned[False]}/{ls_count[False]} outside the targets and "
          f"{ls_warned[True]}/{ls_count[True]} within")  # fmt: skip
    for kind, how in refusals.items():
        if how != "defaults":
            print(f"{kind}: {how}")
    print("\nworst over Ts and Coulomb (Markdown, for docs/real-data.md):\n")
    print("| log | counts/rev | J [%] | b [%] | b [% of allowance] | Coulomb [% of allowance] "
          "| within | IDIM-LS: worst J [%] | within |")  # fmt: skip
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for (kind, n), r in table.items():
        print(f"| {kind} | {n} | {r[0]:.2f} | {r[7]:.1f} | {r[1]:.0f} | {r[2]:.0f} | "
              f"{r[3]}/{r[4]} | {r[5]:.1f} | {r[6]}/{r[4]} |")  # fmt: skip


if __name__ == "__main__":
    main()
