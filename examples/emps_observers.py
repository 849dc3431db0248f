"""
Disturbance observers on measured data: the EMPS axis (a command-line script)
=============================================================================

Run offline over the EMPS benchmark's measured estimation run (shipped with hpdob; a
prismatic axis, so positions in m and forces in N), every observer family estimates the
disturbance force on the nominal model identified from the same log (IDIM-LS: J_n = M,
b_n = 0, so the disturbance is the whole friction plus offset), and is compared with the
identified friction model ``Fv v + Fc sign(v) + offset`` evaluated on a zero-phase filtered
velocity::

    python examples/emps_observers.py [OUT_DIR]

prints the Markdown table of docs/real-data.md and writes emps_observers.png (100 dpi) into
OUT_DIR (default docs/figures). Takes ~10 s.

The figure as committed in ``docs/figures/`` (this page does not run the script):

.. image:: ../figures/emps_observers.png
   :alt: Observers on the EMPS log against the identified friction
"""

# sphinx_gallery_thumbnail_path = 'figures/emps_observers.png'

from __future__ import annotations

import math
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from scipy import signal

from hpdob import ServoModel, estimate_disturbance
from hpdob.identification import emps
from hpdob.observers import design_eso, design_kalman, design_observer, kalman_process_noise

BANDWIDTHS = (10.0, 30.0, 100.0)  # rad/s
RESOLUTION = 5e-8  # m: the smallest step of the logged position (50 000 counts, ball screw)
SETTLE = 1.0  # s: the observers' start-up transient left out of the RMS


def families(model, bandwidth: float) -> dict:
    """Every observer family at ``bandwidth``, on the identified nominal model."""
    noise = RESOLUTION / math.sqrt(12.0)
    designs = {
        "DOb": design_observer(model, order=0, bandwidth=bandwidth),
        "HPDOb": design_observer(model, order=1, bandwidth=bandwidth),
        "DOb, position": design_observer(
            model, order=0, bandwidth=bandwidth, measurement="position"
        ),
        "HPDOb, position": design_observer(
            model, order=1, bandwidth=bandwidth, measurement="position"
        ),
        "ESO": design_eso(model, bandwidth=bandwidth),
        "GESO m=1": design_eso(model, bandwidth=bandwidth, extended_order=1),
    }
    for m in (0, 1):
        q = kalman_process_noise(model, bandwidth=bandwidth, position_noise_std=noise, order=m)
        designs[f"Kalman m={m}"] = design_kalman(
            model, order=m, position_noise_std=noise, process_noise_std=q
        )
    return designs


def friction_reference(log, identification) -> np.ndarray:
    """``Fv v + Fc sign(v) + offset`` with v the central difference of the position filtered
    forward and backward (4th-order Butterworth, 20 Hz: no lag)."""
    sos = signal.butter(4, 20.0, fs=1.0 / log.Ts, output="sos")
    velocity = np.gradient(signal.sosfiltfilt(sos, log.theta), log.Ts)
    p = identification.parameters
    return p["b"] * velocity + p["coulomb"] * np.sign(velocity) + p["offset"]


def study():
    """``(log, reference, results, identification)``: results[bandwidth][name] is an
    EstimationResult."""
    log = emps()
    identification = log.identify(method="idim-ls")
    nominal = ServoModel(identification.parameters["J"])  # b_n = 0: estimate all friction
    model = nominal.discretize(log.Ts)
    reference = friction_reference(log, identification)
    results = {}
    for g in BANDWIDTHS:
        results[g] = {
            name: estimate_disturbance(design, theta=log.theta, u=log.u, t=log.t)
            for name, design in families(model, g).items()
        }
    return log, reference, results, identification


def table(reference, results) -> str:
    names = list(next(iter(results.values())))
    header = "| observer | " + " | ".join(f"{g:g} rad/s" for g in results) + " |"
    lines = [header, "|---|" + "---:|" * len(results)]
    for name in names:
        cells = [f"{results[g][name].rms_error(reference, start=SETTLE):.2f}" for g in results]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def figure(log, reference, results):
    g = BANDWIDTHS[-1]
    fig, axes = plt.subplots(2, 1, figsize=(7.0, 5.4), sharex=True, layout="constrained")
    window = (log.t >= 3.0) & (log.t < 7.0)
    t = log.t[window]
    axes[0].plot(t, reference[window], color="black", linewidth=1.5, label="friction model")
    for name, color in (("DOb", "tab:blue"), ("HPDOb", "tab:red"),
                        ("HPDOb, position", "tab:green")):  # fmt: skip
        axes[0].plot(t, results[g][name].tau_hat[window], color=color, linewidth=0.8,
                     label=name)  # fmt: skip
    axes[0].set_ylabel("disturbance force [N]")
    axes[0].set_title(f"observers at {g:g} rad/s on the EMPS log", fontsize="medium")
    axes[0].legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize="small")
    axes[1].plot(t, log.theta[window], color="tab:blue")
    axes[1].set_ylabel("position [m]")
    axes[1].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    return fig


def main(out: Path) -> str:
    out.mkdir(parents=True, exist_ok=True)
    log, reference, results, identification = study()
    text = table(reference, results)
    print(
        f"EMPS log: {len(log)} samples, nominal M = {identification.parameters['J']:.4f} kg "
        "(IDIM-LS), b_n = 0"
    )
    print("RMS of tau_hat minus the friction model [N], after the first second:")
    print(text)
    fig = figure(log, reference, results)
    fig.savefig(out / "emps_observers.png", dpi=100)
    plt.close(fig)
    print(f"wrote {out / 'emps_observers.png'}")
    return text


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parents[1] / "docs/figures")
