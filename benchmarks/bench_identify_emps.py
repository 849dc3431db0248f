"""The EMPS benchmark's measured run: identify's defaults against the published IDIM-LS.

Prints, for the shipped DATA_EMPS.mat (measured data, not synthetic): the published IDIM-LS
values (EMPS description, section 3.4), hpdob's ``method="idim-ls"`` (the benchmark's method
and rules), the defaults (filters from the log, IV through the EMPS loop, the rests dropped)
and the defaults with every row kept (``min_speed=0``), each with its batch-means standard
deviation and the difference to the published value in % and in IDIM-LS's batch-means
standard deviations; then, identified on the first half (0-12.42 s) and simulated open loop on
the second, the fit (MATLAB compare) of each. ``tests/cli/test_cli_identify.py`` checks the
defaults against the published values within 2 of these standard deviations, and that the
defaults fit the unseen half at least as well as IDIM-LS (docs/real-data.md, *On EMPS*). Run

    python benchmarks/bench_identify_emps.py        # a few seconds
"""

from __future__ import annotations

import warnings

from hpdob.identification import EMPS_PUBLISHED, IdentificationWarning, emps, emps_loop

NAMES = (("J", "M [kg]"), ("b", "Fv [N s/m]"), ("coulomb", "Fc [N]"))


def main() -> None:
    log = emps()
    warnings.simplefilter("ignore", IdentificationWarning)
    fits = {
        "IDIM-LS (benchmark's method)": log.identify(method="idim-ls"),
        "defaults (auto, EMPS loop)": log.identify(loop=emps_loop(log)),
        "defaults, min_speed=0": log.identify(loop=emps_loop(log), min_speed=0.0),
    }
    reference = fits["IDIM-LS (benchmark's method)"].std
    print("published IDIM-LS: " + ", ".join(f"{t} {EMPS_PUBLISHED[n]:g}" for n, t in NAMES))
    for label, fit in fits.items():
        cells = []
        for name, title in NAMES:
            value, std = getattr(fit, name), fit.std[name]
            delta = value - EMPS_PUBLISHED[name]
            cells.append(
                f"{title} {value:.4g} ± {std:.3g} ({100 * delta / EMPS_PUBLISHED[name]:+.2f} %, "
                f"{delta / reference[name]:+.2f} sd)"
            )
        rest = fit.settings.get("rest_rows", 0)
        print(f"{label:30s} " + "; ".join(cells) + f"; rest rows dropped {rest}")
    first, second = log.slice(0.0, 12.42), log.slice(12.42, None)
    print("identified on 0-12.42 s, simulated open loop on 12.42-24.84 s (position, velocity fit):")
    for label, options in (("IDIM-LS", {"method": "idim-ls"}), ("defaults", {}),
                           ("defaults, min_speed=0", {"min_speed": 0.0})):  # fmt: skip
        check = first.identify(**options).validate(second)
        print(f"  {label:24s} {check.position_fit:.2f} %, {check.velocity_fit:.2f} %")


if __name__ == "__main__":
    main()
