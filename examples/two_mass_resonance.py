"""
Resonance: where the DOb and the HPDOb lose stability (a command-line script)
=============================================================================

    python examples/two_mass_resonance.py [OUT_DIR]

The paper's motor (J_m = 2.8e-4 kg m^2) drives a load J_l = R J_m through a torsional spring
with 2 % damping of the relative mode; controller and observer use the rigid-body nominal
model J_n = J_m + J_l, PD(50, 5), Ts = 1 ms. For each load/motor inertia ratio R and resonance
frequency f_r the spectral radius of the linear closed loop (hpdob.closed_loop_poles) decides
stability; the map is drawn for the DOb and the HPDOb at the same bandwidth, then one point on
each side of the HPDOb's boundary is simulated with the nonlinear plant (Coulomb friction on
the motor) to confirm it. Writes two_mass_stability.png (100 dpi) into OUT_DIR (default
docs/figures) and prints the verification. Takes ~20 s.

The figure as committed in ``docs/figures/`` (this page does not run the script):

.. image:: ../figures/two_mass_stability.png
   :alt: Stability of DOb and HPDOb on a two-mass drive
"""

# sphinx_gallery_thumbnail_path = 'figures/two_mass_stability.png'

from __future__ import annotations

import math
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from hpdob import (
    PD,
    ServoLoop,
    ServoModel,
    SimulationDivergedWarning,
    TwoMassServo,
    closed_loop_poles,
    design_observer,
    paper,
    simulate,
)

TS = 1e-3  # s
J_MOTOR = 2.8e-4  # kg m^2, the paper's nominal motor
BANDWIDTH = 200.0  # rad/s, both observers
DAMPING_RATIO = 0.02  # of the relative (spring) mode
CONTROLLER = PD(50.0, 5.0)
RATIOS = np.geomspace(0.1, 10.0, 41)  # J_l / J_m
RESONANCES = np.geomspace(5.0, 480.0, 41)  # f_r [Hz], below the Nyquist frequency 500 Hz


def drive(ratio: float, resonance_hz: float, *, coulomb: float = 0.0) -> TwoMassServo:
    """The two-mass plant with load ``ratio * J_m`` resonating at ``resonance_hz``."""
    J_load = ratio * J_MOTOR
    inverse_mass = 1.0 / J_MOTOR + 1.0 / J_load
    w = 2.0 * math.pi * resonance_hz
    stiffness = w**2 / inverse_mass
    damping = 2.0 * DAMPING_RATIO * w / inverse_mass
    return TwoMassServo(J_MOTOR, J_load, stiffness, damping, coulomb=coulomb)


def loop(ratio: float, resonance_hz: float, order: int, *, coulomb: float = 0.0) -> ServoLoop:
    plant = drive(ratio, resonance_hz, coulomb=coulomb)
    nominal = ServoModel(plant.J)  # the rigid-body inertia J_m + J_l
    observer = design_observer(nominal.discretize(TS), order=order, bandwidth=BANDWIDTH)
    return ServoLoop(plant=plant, nominal=nominal, Ts=TS, controller=CONTROLLER, observer=observer)


def radius_map(order: int) -> np.ndarray:
    return np.array(
        [[abs(closed_loop_poles(loop(r, f, order))).max() for f in RESONANCES] for r in RATIOS]
    )


def simulated(ratio: float, resonance_hz: float, order: int) -> bool:
    """True if the nonlinear loop (motor Coulomb friction 0.01 N m) stays bounded for 3 s."""
    kwargs = paper.scenario()
    run = loop(ratio, resonance_hz, order, coulomb=0.01)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SimulationDivergedWarning)
        result = simulate(
            run, reference=kwargs["reference"], disturbance=kwargs["disturbance"], duration=3.0
        )
    return not result.diverged


#: Points simulated on each side of the HPDOb's boundary: (J_l/J_m, f_r [Hz]).
CHECKS = ((2.0, 20.0), (6.0, 20.0))


def figure(maps: dict, checks: dict):
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    fig, ax = plt.subplots(figsize=(8.0, 4.2), layout="constrained")
    styles = {"DOb": ("tab:blue", "-", 0.25), "HPDOb": ("tab:red", "--", 0.2)}
    handles = []
    for name, rho in maps.items():
        color, style, alpha = styles[name]
        ax.contourf(RESONANCES, RATIOS, rho, levels=[1.0, np.inf], colors=[color], alpha=alpha)
        ax.contour(RESONANCES, RATIOS, rho, levels=[1.0], colors=[color], linestyles=style)
        handles.append(Line2D([], [], color=color, linestyle=style, label=f"{name} boundary"))
        handles.append(Patch(color=color, alpha=alpha, label=f"{name} unstable"))
    for (ratio, f_r), bounded in checks.items():
        marker = "o" if bounded else "x"
        ax.plot(f_r, ratio, marker, color="black", markersize=8, markerfacecolor="none")
    handles.append(Line2D([], [], color="black", marker="o", linestyle="none",
                          markerfacecolor="none", label="HPDOb simulated: bounded"))  # fmt: skip
    handles.append(Line2D([], [], color="black", marker="x", linestyle="none",
                          label="HPDOb simulated: diverged"))  # fmt: skip
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("resonance frequency $f_r$ [Hz]")
    ax.set_ylabel("load/motor inertia ratio $J_l/J_m$ [-]")
    ax.set_title(f"observers at {BANDWIDTH:g} rad/s, $J_n = J_m + J_l$", fontsize="medium")
    fig.legend(handles=handles, loc="outside right upper", fontsize="small")
    return fig


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    maps = {"DOb": radius_map(0), "HPDOb": radius_map(1)}
    for name, rho in maps.items():
        stable = rho < 1.0
        largest = max((RATIOS[i] for i in range(RATIOS.size) if stable[i].all()), default=0.0)
        print(f"{name}: stable at every f_r up to J_l/J_m = {largest:.3g}")
    # one point on each side of the HPDOb's boundary, confirmed by nonlinear simulation
    checks = {}
    for ratio, f_r in CHECKS:
        for order, name in ((0, "DOb"), (1, "HPDOb")):
            rho = abs(closed_loop_poles(loop(ratio, f_r, order))).max()
            bounded = simulated(ratio, f_r, order)
            if order == 1:
                checks[(ratio, f_r)] = bounded
            print(
                f"{name:5} J_l/J_m = {ratio:g}, f_r = {f_r:g} Hz: spectral radius {rho:.4f}, "
                f"simulation {'bounded' if bounded else 'diverged'}"
            )
    fig = figure(maps, checks)
    fig.savefig(out / "two_mass_stability.png", dpi=100)
    plt.close(fig)
    print(f"wrote {out / 'two_mass_stability.png'}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parents[1] / "docs/figures")
