"""
The contact map's verdict on the paper's motor, and the RTOB's own bandwidth (a command-line script)
=====================================================================================================

Regenerate the figure and the tables of docs/force-control.md's sections "The verdict on the
paper's motor" (the a-priori decidability rule on its fixed 7 x 7 grid, the 6 x 6 grid under
the old 50 % rule, the stiff and soft rows), "The describing-function verdict" (its fixed
6 x 6 grid) and "The RTOB's own bandwidth"::

    python examples/force_contact_verdict.py [OUT_DIR]
    python examples/force_contact_verdict.py --df     # the describing-function grid alone
    python examples/force_contact_verdict.py --hunting    # its hunting points, dead band on
    python examples/force_contact_verdict.py --deadband   # the dead-band grid (DF and linear)
    python examples/force_contact_verdict.py --deadband-off   # that grid without the dead band

writes force_rtob_bandwidth.png (100 dpi) into OUT_DIR (default docs/figures) and prints the
Markdown tables of the page, computed here from the library (copy them into the page when the
numbers change). Takes ~5 min of CPU, 4 of them the describing-function grid (``--df``).

The loop: the paper's motor (J = 3.06e-4 kg m^2, b = 5e-5 N m s/rad, Coulomb 0.01 N m smoothed
over 0.01 rad/s) and nominal model (J_n = 2.8e-4, b_n = 0), its 16384-count encoder with
backward-difference velocity, one sample of delay and the 0.444 N m torque limit;
ForceControl(kf = 1000, kv = 40); the DOb of order 0 or 1 and the RTOB. The verdict tables run
the RTOB with the friction model known (``friction=paper.PLANT, velocity_filter=100.0``); the
map itself is linear and leaves the Coulomb friction (of the plant and of the RTOB's model),
the torque limit and the quantisation out.

The figure as committed in ``docs/figures/`` (this page does not run the script):

.. image:: ../figures/force_rtob_bandwidth.png
   :alt: Stability of the force loop in contact over wall stiffness and the RTOB's own bandwidth
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from hpdob import (
    Actuator,
    Environment,
    ServoLoop,
    SimulationDivergedWarning,
    closed_loop,
    closed_loop_poles,
    paper,
    simulate,
)
from hpdob.analysis import contact_stability_map
from hpdob.controllers import ForceControl
from hpdob.models import InContact
from hpdob.observers import LinearObserver, design_observer, reaction_torque_observer

DPI = 100
TAU_REF = 0.05  # N m
DELTA_B = paper.PLANT.b - paper.NOMINAL.b
FRICTION = {"friction": paper.PLANT, "velocity_filter": 100.0}
NAMES = {0: "DOb (m=0)", 1: "HPDOb (m=1)"}
COUNT = 2 * np.pi / paper.VIRTUAL_SENSOR.counts_per_rev  # [rad]


def loop(order, *, friction=None):
    dob = design_observer(paper.NOMINAL.discretize(paper.TS), order=order, bandwidth=100.0)
    rtob = reaction_torque_observer(dob, **(friction or {"viscous": DELTA_B}))
    return ServoLoop(plant=paper.PLANT.replace(environment=Environment(10.0)),
                     nominal=paper.NOMINAL, Ts=paper.TS, controller=ForceControl(1000.0, kv=40.0),
                     observer=rtob, sensor=paper.VIRTUAL_SENSOR,
                     actuator=paper.VIRTUAL_ACTUATOR)  # fmt: skip


def save(fig, out: Path, name: str) -> None:
    fig.savefig(out / name, dpi=DPI, pil_kwargs={"optimize": True})
    plt.close(fig)
    print(f"wrote {out / name}")


def run(point, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SimulationDivergedWarning)
        return simulate(point, duration=kwargs.pop("duration", 5.0), **kwargs)


def step(t):
    return np.where(t >= 0.01, TAU_REF, 0.0), 0 * t, 0 * t


def verdict(point) -> tuple[bool, float]:
    """The stated rule (tests/analysis/test_contact_map.py::_papers_verdict)."""
    result = run(point, reference=step)
    error = float(np.max(np.abs(result.tau_contact[-500:] - TAU_REF)) / TAU_REF)
    if not np.isfinite(error) or result.theta.size < 5000:
        return False, np.inf
    return bool(error <= 0.5 and result.in_contact[-500:].all()), error


def perturbed(point, k_e: float, counts: int) -> float:
    """Local check: from the settled contact (at rest at tau_ref / k_e, the observers converged
    on tau_ref) displaced by ``counts`` encoder counts into the wall, the worst deviation
    |tau_contact - tau_ref| over the last 0.5 s of 2 s over that over 0.05-0.3 s (< 1: it
    decays)."""
    theta = TAU_REF / k_e + counts * COUNT
    state = np.asarray(point.system.N) @ np.array([theta, 0.0, TAU_REF])
    result = run(point, reference=lambda t: (np.full_like(t, TAU_REF), 0 * t, 0 * t),
                 duration=2.0, x0=(theta, 0.0), observer_state=state)  # fmt: skip
    if result.theta.size < 2000:
        return np.inf
    deviation = np.abs(result.tau_contact - TAU_REF)
    return float(deviation[-500:].max() / deviation[50:300].max())


def slope_radius(point) -> float:
    """The loop linearised at the in-contact equilibrium (omega = 0): the plant's Coulomb
    friction c tanh(omega/v) by its slope c/v, the RTOB's Coulomb term c_n tanh(w/v_n) by its
    slope on its velocity w (the low-passed one, output omega_hat)."""
    plant = point.plant
    linear = plant.replace(b=plant.b + plant.coulomb / plant.coulomb_velocity, coulomb=0.0)
    system = point.system
    H, E = np.array(system.H), np.array(system.E)
    r, w = system.outputs.index("tau_reac"), system.outputs.index("omega_hat")
    slope = system.coulomb.c / system.coulomb.v
    H[r] -= slope * H[w]
    E[r] -= slope * E[w]
    observer = LinearObserver(F=system.F, G=system.G, H=H, E=E, N=system.N, Ts=system.Ts,
                              measures=system.measures, outputs=system.outputs,
                              model=system.model)  # fmt: skip
    bonded = point.replace(plant=InContact(linear), observer=observer,
                           actuator=Actuator(delay_samples=1))  # fmt: skip
    return float(np.max(np.abs(closed_loop_poles(bonded))))


def rtob_bandwidth(out: Path) -> None:
    """The map over the RTOB's own bandwidth, the DOb at 100 rad/s."""
    fig, axes = plt.subplots(1, 2, figsize=(11.0, 4.6), layout="constrained")
    bandwidths = (25.0, 50.0, 100.0, 200.0, 400.0, 700.0, 1000.0, 2000.0)
    edges = {}
    for order, ax in zip((0, 1), axes, strict=True):
        spec = {"observer": {"order": order}, "reaction": {"order": order}, "viscous": DELTA_B,
                "bandwidth_of": "reaction", "fixed_bandwidth": 100.0}  # fmt: skip
        cmap = contact_stability_map(loop(order), stiffness=np.geomspace(1.0, 1000.0, 41),
                                     bandwidth=np.geomspace(25.0, 2000.0, 37), **spec)  # fmt: skip
        cmap.plot(ax, mark=(100.0, 10.0), mark_label="RTOB = DOb: 100 rad/s, 10 N m/rad")
        edge = contact_stability_map(loop(order), stiffness=np.geomspace(1.0, 1000.0, 61),
                                     bandwidth=bandwidths, **spec).boundary()  # fmt: skip
        edges[order] = {g: [e for e in edge if e["bandwidth"] == g] for g in bandwidths}
    save(fig, out, "force_rtob_bandwidth.png")
    heads = " | ".join(f"{NAMES[m]}: k_e [N m/rad]" for m in (0, 1))
    print(f"\n| RTOB's bandwidth [rad/s] | {heads} |\n|---:|---|---|")
    for g in bandwidths:
        cells = []
        for order in (0, 1):
            parts = [f"{'stable below' if e['kind'] == 'upper' else 'stable above'} "
                     f"{e['stiffness']:.1f}" for e in edges[order][g]]  # fmt: skip
            cells.append(", ".join(parts) or "none in 1-1000")
        print(f"| {g:g} | {cells[0]} | {cells[1]} |")


def papers_motor() -> None:
    """The verdict grid: map radius, the step run's worst error, the rule's verdict."""
    stiffness = (0.1, 1.0, 3.16, 10.0, 100.0, 1000.0)
    bandwidths = (25.0, 100.0, 400.0, 700.0, 1000.0, 2000.0)
    for order in (0, 1):
        cmap = contact_stability_map(loop(order, friction=FRICTION), stiffness=stiffness,
                                     bandwidth=bandwidths, observer={"order": order},
                                     **FRICTION)  # fmt: skip
        print(f"\n{NAMES[order]}: radius / worst error over the last 0.5 s / agrees\n")
        print("| k_e [N m/rad] | " + " | ".join(f"{g:g} rad/s" for g in bandwidths) + " |")
        print("|---:|" + "---|" * len(bandwidths))
        for i, k_e in enumerate(stiffness):
            cells = []
            for j, g in enumerate(bandwidths):
                stable, error = verdict(cmap.loop_at(k_e, g))
                rho = cmap.spectral_radius[i, j]
                mark = "yes" if stable == (rho < 1.0) else "**no**"
                cells.append(f"{rho:.4f} / {100 * error:.3g} % / {mark}")
            print(f"| {k_e:g} | " + " | ".join(cells) + " |")


def stiff_rows() -> None:
    """The stiff rows judged locally: the Coulomb-free radius, the friction-slope radius and a
    3-count perturbation from the settled contact."""
    print(
        "\n| order | g [rad/s] | k_e [N m/rad] | radius (Coulomb-free) | radius (friction "
        "slope) | 3-count perturbation: late/early |\n|---|---:|---:|---:|---:|---:|"
    )
    for order in (0, 1):
        for g in (25.0, 100.0, 400.0):
            cmap = contact_stability_map(loop(order, friction=FRICTION),
                                         stiffness=[100.0, 316.0, 1000.0], bandwidth=[g],
                                         observer={"order": order}, **FRICTION)  # fmt: skip
            for i, k_e in enumerate(cmap.values):
                point = cmap.loop_at(k_e, g)
                print(f"| {order} | {g:g} | {k_e:g} | {cmap.spectral_radius[i, 0]:.4f} | "
                      f"{slope_radius(point):.4f} | {perturbed(point, k_e, 3):.2g} |")  # fmt: skip


def soft_rows() -> None:
    """The friction-slope radius where it says unstable: the HPDOb at 25 rad/s on soft walls."""
    print("\n| k_e [N m/rad] | radius (Coulomb-free) | radius (friction slope) | step run: "
          "worst error |\n|---:|---:|---:|---:|")  # fmt: skip
    stiffness = (1.0, 1.78, 3.16, 5.62, 10.0)
    cmap = contact_stability_map(loop(1, friction=FRICTION), stiffness=stiffness,
                                 bandwidth=[25.0], observer={"order": 1}, **FRICTION)  # fmt: skip
    for i, k_e in enumerate(stiffness):
        point = cmap.loop_at(k_e, 25.0)
        print(f"| {k_e:g} | {cmap.spectral_radius[i, 0]:.4f} | {slope_radius(point):.4f} | "
              f"{verdict(point)[1]:.2g} |")  # fmt: skip


def causes() -> None:
    """What bounds or drives the oscillations of the undecided and the limit-cycle points: the
    step run's worst error on the paper's motor, without the friction (plant and RTOB model,
    quantised) and with it but an unquantised encoder."""
    from hpdob import Encoder

    fine = Encoder(2**52, velocity="backward-difference")
    print("\n| order | g [rad/s] | k_e [N m/rad] | paper's motor | no friction | friction, "
          "unquantised |\n|---|---:|---:|---:|---:|---:|")  # fmt: skip
    for order, g, k_e in ((1, 400.0, 10.0), (0, 2000.0, 10.0), (1, 700.0, 10.0),
                          (0, 2000.0, 100.0)):  # fmt: skip
        cmap = contact_stability_map(loop(order, friction=FRICTION), stiffness=[k_e],
                                     bandwidth=[g], observer={"order": order},
                                     **FRICTION)  # fmt: skip
        point = cmap.loop_at(k_e, g)
        dob = design_observer(paper.NOMINAL.discretize(paper.TS), order=order, bandwidth=g)
        free = point.replace(plant=point.plant.replace(coulomb=0.0),
                             observer=reaction_torque_observer(dob, viscous=DELTA_B))  # fmt: skip
        cells = []
        for case in (point, free, point.replace(sensor=fine)):
            stable, error = verdict(case)
            cells.append(f"{100 * error:.3g} %" + ("" if stable else " (unstable)"))
        print(f"| {order} | {g:g} | {k_e:g} | " + " | ".join(cells) + " |")


#: The a-priori decidability rule (docs/force-control.md, "An a-priori rule, tested"), fixed
#: before the grid below was run: the step's deflection at least N_COUNTS encoder counts, the
#: radius at least DELTA from 1, on the stable side the quantisation's predicted torque noise
#: at most NOISE of tau_ref, on the unstable side a growth beating the Coulomb friction.
N_COUNTS, DELTA, NOISE = 10, 2e-3, 0.0125
#: The grid, fixed before it was run: a regular log grid over the audit's ranges.
GRID_STIFFNESS, GRID_BANDWIDTH = np.geomspace(0.3, 300.0, 7), np.geomspace(30.0, 1500.0, 7)


def simulated(point) -> tuple[str, float]:
    """The tight simulation rule: ``("stable" | "unstable" | "bounded", worst deviation over
    the last 0.5 s / tau_ref)`` of the 5 s step run. Unstable: it diverges, loses contact in
    the last 0.5 s, or its deviation there exceeds 5 % and 1.5x that over 2.0-2.5 s (grows);
    stable: in contact and within 5 % of tau_ref over the last 0.5 s, or its deviation there at
    most half that over 2.0-2.5 s (decays); bounded: neither (agrees with no verdict)."""
    result = run(point, reference=step)
    if result.theta.size < 5000 or not np.all(np.isfinite(result.tau_contact)):
        return "unstable", np.inf
    deviation = np.abs(result.tau_contact - TAU_REF) / TAU_REF
    last, middle = deviation[-500:].max(), deviation[2000:2500].max()
    if not result.in_contact[-500:].all() or (last > 0.05 and last > 1.5 * middle):
        return "unstable", float(last)
    if last <= 0.05 or last <= 0.5 * middle:
        return "stable", float(last)
    return "bounded", float(last)


def decidable(point, k_e: float) -> tuple[bool, float, float]:
    """The a-priori rule on the point's linear loop: ``(decidable, radius, margin figure)``.

    Resolution: the deflection tau_ref / k_e is at least N_COUNTS counts (one count at most
    10 % of the motion the loop is to stabilise). Margin: |radius - 1| >= DELTA (a stable mode
    decays by 0.998^2500 = 0.7 % over the last 2.5 s of the run). Stable side: the torque
    noise the quantisation drives, k_e q / sqrt(12) times the H2 norm from the angle noise to
    the angle (white, uniform noise of one count q), at most NOISE of tau_ref (its peak over
    500 samples, ~4 sigma, inside the 5 % rule). Unstable side: radius - 1 >= 2 c Ts /
    (pi J omega_m A) with A = tau_ref / k_e and omega_m the unstable mode's frequency, the
    growth whose energy gain per cycle (2 pi eps J omega_m A^2 / Ts) beats the Coulomb
    friction's 4 c A at the step's amplitude (the figure returned: that bound)."""
    from scipy.linalg import solve_discrete_lyapunov

    bonded = point.replace(plant=InContact(point.plant.replace(coulomb=0.0)),
                           actuator=Actuator(delay_samples=1))  # fmt: skip
    system = closed_loop(bonded)
    A = np.asarray(system.A)
    poles = np.linalg.eigvals(A)
    worst = poles[np.argmax(np.abs(poles))]
    rho = float(abs(worst))
    deflection = TAU_REF / k_e
    resolved = deflection >= N_COUNTS * COUNT
    if rho < 1.0:
        b = np.asarray(system.B)[:, system.input_labels.index("n_theta")]
        c = np.asarray(system.C)[system.output_labels.index("theta")]
        P = solve_discrete_lyapunov(A, np.outer(b, b))
        sigma = k_e * COUNT / np.sqrt(12.0) * float(np.sqrt(c @ P @ c)) / TAU_REF
        return bool(resolved and 1.0 - rho >= DELTA and sigma <= NOISE), rho, sigma
    omega_m = abs(np.angle(worst)) / paper.TS
    coulomb = point.plant.coulomb
    bound = (2 * coulomb * paper.TS / (np.pi * point.plant.J * omega_m * deflection)
             if omega_m > 0 else np.inf)  # fmt: skip
    return bool(resolved and rho - 1.0 >= max(DELTA, bound)), rho, bound


def a_priori_rule() -> None:
    """The a-priori rule against the tight simulation rule at every point of the fixed grid."""
    for order in (0, 1):
        cmap = contact_stability_map(loop(order, friction=FRICTION), stiffness=GRID_STIFFNESS,
                                     bandwidth=GRID_BANDWIDTH, observer={"order": order},
                                     **FRICTION)  # fmt: skip
        counts = {"decidable": 0, "agree": 0}
        print(f"\n{NAMES[order]}: radius / decidable / simulated (worst deviation) / agrees\n")
        print("| k_e [N m/rad] | " + " | ".join(f"{g:.4g} rad/s" for g in GRID_BANDWIDTH) + " |")
        print("|---:|" + "---|" * len(GRID_BANDWIDTH))
        for k_e in GRID_STIFFNESS:
            cells = []
            for g in GRID_BANDWIDTH:
                point = cmap.loop_at(k_e, g)
                ok, rho, _ = decidable(point, k_e)
                verdict, last = simulated(point)
                agree = verdict == ("stable" if rho < 1.0 else "unstable")
                counts["decidable"] += ok
                counts["agree"] += ok and agree
                mark = ("yes" if agree else "**no**") if ok else "-"
                cells.append(f"{rho:.4f} / {'D' if ok else 'u'} / {verdict} ({100 * last:.2g} %)"
                             f" / {mark}")  # fmt: skip
            print(f"| {k_e:.3g} | " + " | ".join(cells) + " |")
        print(f"\ndecidable: {counts['decidable']} of {GRID_STIFFNESS.size * GRID_BANDWIDTH.size}"
              f", of them agreeing: {counts['agree']}")  # fmt: skip


def a_priori_causes() -> None:
    """What drives the disagreements of the a-priori rule: each decidable point that disagrees,
    simulated on the paper's motor, without the friction (plant and RTOB model), with an
    unquantised encoder, with neither, and without the torque limit (the tight rule)."""
    from hpdob import Encoder

    fine = Encoder(2**52, velocity="backward-difference")
    cases = ((0, 0, 6), (0, 1, 5), (0, 1, 6), (0, 2, 5), (0, 2, 6), (1, 0, 4), (1, 1, 4),
             (1, 2, 3), (1, 2, 4), (1, 0, 5), (1, 1, 5))  # fmt: skip
    print(
        "\n| order | k_e [N m/rad] | g [rad/s] | radius | paper's motor | no friction | "
        "unquantised | neither | no torque limit |\n|---|---:|---:|---:|---|---|---|---|---|"
    )
    for order, i, j in cases:
        k_e, g = GRID_STIFFNESS[i], GRID_BANDWIDTH[j]
        cmap = contact_stability_map(loop(order, friction=FRICTION), stiffness=[k_e],
                                     bandwidth=[g], observer={"order": order},
                                     **FRICTION)  # fmt: skip
        point = cmap.loop_at(k_e, g)
        dob = design_observer(paper.NOMINAL.discretize(paper.TS), order=order, bandwidth=g)
        free = point.replace(plant=point.plant.replace(coulomb=0.0),
                             observer=reaction_torque_observer(dob, viscous=DELTA_B))  # fmt: skip
        cells = []
        for case in (point, free, point.replace(sensor=fine), free.replace(sensor=fine),
                     point.replace(actuator=Actuator(delay_samples=1))):  # fmt: skip
            verdict, last = simulated(case)
            cells.append(f"{verdict} ({100 * last:.2g} %)")
        print(
            f"| {NAMES[order]} | {k_e:.3g} | {g:.4g} | {cmap.spectral_radius[0, 0]:.4f} | "
            + " | ".join(cells)
            + " |"
        )


#: The describing-function verdict's grid and rule (docs/force-control.md, "The
#: describing-function verdict"), fixed and committed before the grid was run: 6 x 6, regular
#: in log and offset from both earlier grids (7 x 7 over 0.3-300 x 30-1500, 6 x 6 over
#: 0.1-1000 x 25-2000), both orders. The rule: the DF's "stable", and its "limit cycle" of at
#: most SETTLED of tau_ref (the simulation rule's 5 %), predict the simulation's "stable"; a
#: larger limit cycle predicts "bounded"; "unstable" predicts "unstable".
DF_STIFFNESS, DF_BANDWIDTH = np.geomspace(0.2, 200.0, 6), np.geomspace(40.0, 1200.0, 6)
SETTLED = 0.05


def predicted(cycle) -> str:
    """The simulation rule's outcome the describing-function verdict predicts."""
    if cycle.verdict == "unstable":
        return "unstable"
    if cycle.verdict == "limit cycle" and cycle.amplitude > SETTLED:
        return "bounded"
    return "stable"


def first_harmonic(point) -> tuple[float, float]:
    """The step run's oscillation over its last 2 s: the largest spectral line's amplitude
    over tau_ref [-] and frequency [Hz] (the contact torque's, mean removed)."""
    result = run(point, reference=step)
    if result.theta.size < 5000 or not np.all(np.isfinite(result.tau_contact)):
        return np.nan, np.nan
    x = result.tau_contact[-2000:] - TAU_REF
    spectrum = np.abs(np.fft.rfft(x - x.mean()))
    i = int(np.argmax(spectrum[1:])) + 1
    return 2 * spectrum[i] / x.size / TAU_REF, float(np.fft.rfftfreq(x.size, paper.TS)[i])


def describing_function_grid() -> None:
    """The DF verdict (``contact_limit_cycle``) against the simulation rule at every point
    of the fixed DF grid: the loop's linear radius, the DF's verdict (amplitude, frequency),
    the simulated outcome (worst deviation over the last 0.5 s) and the run's first harmonic
    over the last 2 s."""
    from hpdob.analysis import contact_limit_cycle

    total = agree = 0
    for order in (0, 1):
        cmap = contact_stability_map(loop(order, friction=FRICTION), stiffness=DF_STIFFNESS,
                                     bandwidth=DF_BANDWIDTH, observer={"order": order},
                                     **FRICTION)  # fmt: skip
        print(f"\n{NAMES[order]}\n")
        print("| k_e [N m/rad] | g [rad/s] | radius | DF verdict | predicts | simulated "
              "(worst deviation) | run's first harmonic | agrees |")  # fmt: skip
        print("|---:|---:|---:|---|---|---|---|---|")
        for i, k_e in enumerate(DF_STIFFNESS):
            for j, g in enumerate(DF_BANDWIDTH):
                point = cmap.loop_at(k_e, g)
                cycle = contact_limit_cycle(point, tau_ref=TAU_REF)
                outcome, last = simulated(point)
                amplitude, hz = first_harmonic(point)
                guess = predicted(cycle)
                total += 1
                agree += guess == outcome
                df = cycle.verdict + (f" {100 * cycle.amplitude:.2g} % at {cycle.frequency:.3g} Hz"
                                      if cycle.verdict == "limit cycle" else "")  # fmt: skip
                print(f"| {k_e:.3g} | {g:.4g} | {cmap.spectral_radius[i, j]:.4f} | {df} | "
                      f"{guess} | {outcome} ({100 * last:.2g} %) | {100 * amplitude:.2g} % at "
                      f"{hz:.3g} Hz | {'yes' if guess == outcome else '**no**'} |")  # fmt: skip
    print(f"\nagree: {agree} of {total}")


#: The RTOB's Coulomb term with its dead band at the encoder's velocity resolution through the
#: velocity filter (docs/force-control.md, "The Coulomb term's dead band"):
#: (1 - exp(-100 Ts)) q / Ts = 0.0365 rad/s, derived at each point from the loop's encoder.
DEADBAND = {**FRICTION, "coulomb_deadband": "encoder"}
#: The 10 points of the DF grid (DF_STIFFNESS x DF_BANDWIDTH) where the DF predicted "stable"
#: and the run hunted ("bounded") with the term on the raw spike train: (order, i, j).
HUNTING = ((0, 0, 5), (0, 1, 5), (0, 2, 5), (1, 0, 4), (1, 0, 5), (1, 1, 4), (1, 2, 3),
           (1, 2, 4), (1, 3, 3), (1, 3, 4))  # fmt: skip
#: The dead-band grid and rule, fixed and committed before the grid was run: 6 x 6, regular in
#: log and offset from the three earlier grids (7 x 7 over 0.3-300 x 30-1500, 6 x 6 over
#: 0.1-1000 x 25-2000, the DF grid over 0.2-200 x 40-1200), both orders; the loop of the DF
#: grid with the RTOB's term dead-banded (DEADBAND). The DF's verdict predicts the simulation
#: rule's outcome as on the DF grid (``predicted``: stable and cycles up to SETTLED predict
#: "stable", larger cycles "bounded", "unstable" "unstable"); the linear verdict predicts
#: "stable" for radius < 1, else "unstable". Both are judged by ``simulated`` (unchanged).
DB_STIFFNESS, DB_BANDWIDTH = np.geomspace(0.15, 150.0, 6), np.geomspace(45.0, 1350.0, 6)


def hunting_points() -> None:
    """The DF grid's hunting points, the term without and with its dead band: the simulated
    outcome (worst deviation over the last 0.5 s), and the DF's verdict with the dead band."""
    from hpdob.analysis import contact_limit_cycle

    print("\n| order | k_e [N m/rad] | g [rad/s] | no dead band: simulated | dead band: "
          "simulated | dead band: DF verdict | dead band: agrees |\n"
          "|---|---:|---:|---|---|---|---|")  # fmt: skip
    for order, i, j in HUNTING:
        k_e, g = DF_STIFFNESS[i], DF_BANDWIDTH[j]
        cells = []
        for friction in (FRICTION, DEADBAND):
            cmap = contact_stability_map(loop(order, friction=FRICTION), stiffness=[k_e],
                                         bandwidth=[g], observer={"order": order},
                                         **friction)  # fmt: skip
            point = cmap.loop_at(k_e, g)
            outcome, last = simulated(point)
            cells.append(f"{outcome} ({100 * last:.2g} %)")
        cycle = contact_limit_cycle(point, tau_ref=TAU_REF)
        df = cycle.verdict + (f" {100 * cycle.amplitude:.2g} %"
                              if cycle.verdict == "limit cycle" else "")  # fmt: skip
        mark = "yes" if predicted(cycle) == outcome else "**no**"
        print(f"| {NAMES[order]} | {k_e:.3g} | {g:.4g} | {cells[0]} | {cells[1]} | {df} | "
              f"{mark} |")  # fmt: skip


def deadband_grid(friction=None) -> None:
    """The DF and the linear verdict against the simulation rule at every point of the fixed
    dead-band grid (DB_STIFFNESS x DB_BANDWIDTH, the term dead-banded), and the counts per
    category (predicted / simulated) as the DF grid's table. ``friction=FRICTION``: the same
    grid and rule with the term as before (no dead band), the control."""
    friction = DEADBAND if friction is None else friction
    from collections import Counter

    from hpdob.analysis import contact_limit_cycle

    counts = {"df": Counter(), "linear": Counter()}
    for order in (0, 1):
        cmap = contact_stability_map(loop(order, friction=FRICTION), stiffness=DB_STIFFNESS,
                                     bandwidth=DB_BANDWIDTH, observer={"order": order},
                                     **friction)  # fmt: skip
        print(f"\n{NAMES[order]}\n")
        print("| k_e [N m/rad] | g [rad/s] | radius | DF verdict | predicts | simulated "
              "(worst deviation) | DF agrees | linear agrees |")  # fmt: skip
        print("|---:|---:|---:|---|---|---|---|---|")
        for i, k_e in enumerate(DB_STIFFNESS):
            for j, g in enumerate(DB_BANDWIDTH):
                point = cmap.loop_at(k_e, g)
                cycle = contact_limit_cycle(point, tau_ref=TAU_REF)
                outcome, last = simulated(point)
                guess = predicted(cycle)
                rho = cmap.spectral_radius[i, j]
                linear = "stable" if rho < 1.0 else "unstable"
                counts["df"][(order, guess, outcome)] += 1
                counts["linear"][(order, linear, outcome)] += 1
                df = cycle.verdict + (f" {100 * cycle.amplitude:.2g} % at {cycle.frequency:.3g} Hz"
                                      if cycle.verdict == "limit cycle" else "")  # fmt: skip
                print(f"| {k_e:.3g} | {g:.4g} | {rho:.4f} | {df} | {guess} | {outcome} "
                      f"({100 * last:.2g} %) | {'yes' if guess == outcome else '**no**'} | "
                      f"{'yes' if linear == outcome else '**no**'} |", flush=True)  # fmt: skip
    for name, table in counts.items():
        agree = sum(n for (_, p, o), n in table.items() if p == o)
        print(f"\n{name} verdict: agree {agree} of {sum(table.values())}")
        print("\n| predicted / simulated | DOb | HPDOb |\n|---|---:|---:|")
        for p, o in sorted({(p, o) for (_, p, o) in table}):
            print(f"| {p} / {o} | {table[(0, p, o)]} | {table[(1, p, o)]} |")


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    describing_function_grid()
    rtob_bandwidth(out)
    a_priori_rule()
    a_priori_causes()
    papers_motor()
    stiff_rows()
    soft_rows()
    causes()


if __name__ == "__main__":
    if sys.argv[1:] == ["--df"]:  # the describing-function grid alone
        describing_function_grid()
    elif sys.argv[1:] == ["--hunting"]:
        hunting_points()
    elif sys.argv[1:] == ["--deadband"]:
        deadband_grid()
    elif sys.argv[1:] == ["--deadband-off"]:  # the control: the same grid, no dead band
        deadband_grid(FRICTION)
    else:
        main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parents[1] / "docs/figures")
