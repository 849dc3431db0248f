"""
Identifying the EMPS axis from measured data (a command-line script)
====================================================================

Identify the EMPS benchmark's axis with IDIM-LS and IDIM-IV, and compare both on noisy logs.

    python examples/emps_identification.py [OUT_DIR]

Uses the EMPS measured run shipped with hpdob (no download). Prints the Markdown tables of
docs/real-data.md, computed here from the library, and writes emps_identification.png (the
IDIM-IV fit and the loop simulated with it) into OUT_DIR (default hpdob-results/emps).
Takes ~10 s.

The figure as committed in ``docs/figures/`` (OUT_DIR = docs/figures; this page does not run the
script):

.. image:: ../figures/emps_identification.png
   :alt: EMPS: the IDIM-IV fit and the loop simulated with it
"""

# sphinx_gallery_thumbnail_path = 'figures/emps_identification.png'

from __future__ import annotations

import math
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

import hpdob
from hpdob.identification import (
    EMPS_PUBLISHED,
    EMPS_PUBLISHED_STD,
    FeedbackLoop,
    emps,
    emps_loop,
    identify,
)
from hpdob.signals import Sine

NAMES = {"J": "M [kg]", "b": "Fv [N s/m]", "coulomb": "Fc [N]", "offset": "offset [N]"}


def published_table(fits: dict) -> str:
    """Parameters with standard deviations: published IDIM-LS and hpdob's methods.

    The ± are the textbook standard deviations for a white residual (``std_iid``), as the
    benchmark publishes them; the last row gives the batch-means ones that ``identify``
    reports (``std``), which allow for the residual's correlation over neighbouring rows."""
    lines = [
        "| parameter | published IDIM-LS | " + " | ".join(f"hpdob {m}" for m in fits) + " |",
        "|---|---:|" + "---:|" * len(fits),
    ]
    for name, label in NAMES.items():
        cells = [f"{EMPS_PUBLISHED[name]:.4f} ± {EMPS_PUBLISHED_STD[name]:.4f}"]
        for fit in fits.values():
            value, std = fit.parameters[name], fit.std_iid[name]
            if name == "offset":
                deviation = f"{value - EMPS_PUBLISHED[name]:+.4f} N"
            else:
                deviation = f"{100 * (value / EMPS_PUBLISHED[name] - 1):+.2f} %"
            cells.append(f"{value:.4f} ± {std:.4f} ({deviation})")
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    errors = " | ".join(f"{fit.relative_error:.3f} %" for fit in fits.values())
    lines.append(f"| relative error (eq. 11) | 4.0834 % | {errors} |")
    honest = " | ".join(
        ", ".join(f"{fit.std[name]:.3g}" for name in NAMES) for fit in fits.values()
    )
    lines.append(f"| batch-means std: M, Fv, Fc, offset | — | {honest} |")
    return "\n".join(lines)


def settings_table(log, loop) -> str:
    """How each method's estimate moves with the filter settings on the measured data."""
    lines = [
        "| cutoff [Hz] | decimation | IDIM-LS | IDIM-IV |",
        "|---:|---:|---|---|",
    ]
    for cutoff, decimation in ((50.0, 10), (100.0, 10), (200.0, 10), (100.0, 5), (200.0, 20)):
        cells = []
        for method in ("idim-ls", "idim-iv"):
            fit = identify(log.t, log.theta, log.u, method=method, loop=loop, cutoff=cutoff,
                           decimation=decimation, diagnostics=False)  # fmt: skip
            cells.append(f"{fit.J:.2f}, {fit.b:.2f}, {fit.coulomb:.3f}")
        lines.append(f"| {cutoff:g} | {decimation} | {cells[0]} | {cells[1]} |")
    return "\n".join(lines)


def synthetic_table() -> str:
    """Errors [%] against a known plant simulated by hpdob, for encoder noise levels."""
    plant = hpdob.ServoModel(3.06e-4, 1e-3, coulomb=0.01, coulomb_velocity=1e-3)
    reference = Sine(-1.0, 0.5, phase=math.pi / 2, offset=1.0) + Sine(
        -0.3, 2.0, phase=math.pi / 2, offset=0.3
    )
    lines = [
        "| encoder noise [rad] | decimation | IDIM-LS J, b, c | IDIM-IV J, b, c |",
        "|---:|---:|---|---|",
    ]
    for noise in (1e-4, 1e-3):
        kwargs = hpdob.paper.scenario()
        kwargs.update(plant=plant, disturbance=None, reference=reference,
                      sensor=hpdob.Encoder(16384, noise_std=noise, seed=1))  # fmt: skip
        run = hpdob.simulate(**kwargs)
        loop = FeedbackLoop.from_pd(
            kwargs["controller"], J_n=kwargs["nominal"].J, reference=run.r,
            reference_velocity=run.r_dot, reference_acceleration=run.r_ddot,
        )  # fmt: skip
        for decimation in (10, 5):
            cells = []
            for method in ("idim-ls", "idim-iv"):
                # this table is the sensitivity study: no warnings about it
                fit = identify(run.t, run.theta_measured, run.u, method=method, loop=loop,
                               min_speed=0.05, decimation=decimation,
                               diagnostics=False)  # fmt: skip
                errors = [100 * (fit.J / plant.J - 1), 100 * (fit.b / plant.b - 1),
                          100 * (fit.coulomb / plant.coulomb - 1)]  # fmt: skip
                cells.append(", ".join(f"{e:+.1f}" for e in errors))
            exponent = round(math.log10(noise))
            lines.append(f"| 1e{exponent} | {decimation} | {cells[0]} | {cells[1]} |")
    return "\n".join(lines)


def main(out_dir: Path) -> None:
    log = emps()
    loop = emps_loop(log)
    fits = {
        method: identify(log.t, log.theta, log.u, method=method, loop=loop, axis="linear")
        for method in ("idim-ls", "idim-iv")
    }
    for fit in fits.values():
        print(fit.summary(), end="\n\n")
    print(published_table(fits), end="\n\n")
    print(settings_table(log, loop), end="\n\n")
    print(synthetic_table(), end="\n\n")
    out_dir.mkdir(parents=True, exist_ok=True)
    fig = fits["idim-iv"].plot(title="EMPS: IDIM-IV fit and the loop simulated with it")
    fig.savefig(out_dir / "emps_identification.png", dpi=100)
    plt.close(fig)
    print(f"wrote {out_dir / 'emps_identification.png'}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("hpdob-results") / "emps")
