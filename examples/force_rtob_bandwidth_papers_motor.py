"""
The RTOB's own-bandwidth boundaries simulated on the paper's motor (a command-line script)
==========================================================================================

Checks the boundaries of docs/force-control.md's table "The RTOB's own bandwidth" (the DOb at
100 rad/s, a separate RTOB of the same order at its own bandwidth; the linear, Coulomb-free map)
by simulating the paper's motor 10 % on either side of each boundary::

    python examples/force_rtob_bandwidth_papers_motor.py

prints one Markdown row per boundary (its two simulated points), the tally, and, for each
decidable point that disagrees, the same run without Coulomb friction (plant and RTOB model)
with the paper's and with an unquantised encoder (~7 s of CPU). The loop: the paper's motor
with its Coulomb friction (0.01 N m over 0.01 rad/s), its 16384-count encoder with
backward-difference velocity, one sample of delay, the 0.444 N m limit, ForceControl(kf =
1000, kv = 40), the RTOB's friction model known (``friction=paper.PLANT,
velocity_filter=100.0``); a 0.05 N m step of tau_ref at 0.01 s from rest at the wall, 5 s.

The rule, stated before the points were run. A point is *decidable* when the deflection
tau_ref / k_e is at least ``N_COUNTS`` = 3 encoder counts (a few counts of motion to
stabilise; the verdict helper's rule asks for 10) and the map's spectral radius is at least
``DELTA`` = 2e-3 from 1 (the verdict helper's margin: a mode that grows or decays visibly in
the 5 s run). The simulated verdict is the tight rule of examples/force_contact_verdict.py
(``simulated``): *unstable* if the run diverges, loses contact over the last 0.5 s, or its
deviation there exceeds 5 % of tau_ref and 1.5x that over 2.0-2.5 s; *stable* if in contact
and within 5 % over the last 0.5 s, or its deviation there is at most half that over 2.0-2.5 s;
*bounded* otherwise (agreeing with neither verdict). A point agrees when the map's verdict is
the simulated one.

The map these boundaries come from (examples/force_contact_verdict.py draws it; this script
draws nothing):

.. image:: ../figures/force_rtob_bandwidth.png
   :alt: Stability of the force loop in contact over wall stiffness and the RTOB's own bandwidth
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from hpdob import (
    Encoder,
    Environment,
    ServoLoop,
    paper,
)
from hpdob.analysis import contact_stability_map
from hpdob.controllers import ForceControl
from hpdob.observers import design_observer, reaction_torque_observer

sys.path.insert(0, str(Path(__file__).resolve().parent))
# the tight simulation rule of the verdict's script (its docstring), the same 0.05 N m step
from force_contact_verdict import TAU_REF, simulated

FRICTION = {"friction": paper.PLANT, "velocity_filter": 100.0}
COUNT = 2 * np.pi / paper.VIRTUAL_SENSOR.counts_per_rev  # one encoder count [rad]
N_COUNTS, DELTA = 3, 2e-3
BANDWIDTHS = (25.0, 50.0, 100.0, 200.0, 400.0, 700.0, 1000.0, 2000.0)  # the table's rows
NAMES = {0: "DOb (m=0)", 1: "HPDOb (m=1)"}
#: The encoder's backward-difference velocity without its quantisation (a count is 1.4e-15 rad).
FINE_ENCODER = Encoder(2**52, velocity="backward-difference")


def papers_loop(order: int) -> ServoLoop:
    dob = design_observer(paper.NOMINAL.discretize(paper.TS), order=order, bandwidth=100.0)
    return ServoLoop(plant=paper.PLANT.replace(environment=Environment(10.0)),
                     nominal=paper.NOMINAL, Ts=paper.TS, controller=ForceControl(1000.0, kv=40.0),
                     observer=reaction_torque_observer(dob, **FRICTION),
                     sensor=paper.VIRTUAL_SENSOR, actuator=paper.VIRTUAL_ACTUATOR)  # fmt: skip


def own_bandwidth_map(order: int, stiffness, bandwidths=BANDWIDTHS):
    """The table's map: the DOb at 100 rad/s, the RTOB of the same order at each bandwidth."""
    return contact_stability_map(papers_loop(order), stiffness=stiffness, bandwidth=bandwidths,
                                 observer={"order": order}, reaction={"order": order},
                                 bandwidth_of="reaction", fixed_bandwidth=100.0,
                                 **FRICTION)  # fmt: skip


def decidable(k_e: float, radius: float) -> bool:
    """The rule stated in the module docstring (before any point was run)."""
    return TAU_REF / k_e >= N_COUNTS * COUNT and abs(radius - 1.0) >= DELTA


def points():
    """Every boundary of the table, 10 % on either side: dicts of the point and its checks."""
    rows = []
    for order in (0, 1):
        edges = own_bandwidth_map(order, np.geomspace(1.0, 1000.0, 61)).boundary()
        for edge in edges:
            g, k_b = edge["bandwidth"], edge["stiffness"]
            cmap = own_bandwidth_map(order, [0.9 * k_b, 1.1 * k_b], [g])
            for factor in (0.9, 1.1):
                k_e = factor * k_b
                radius = cmap.radius_at(k_e, g)
                verdict, last = simulated(cmap.loop_at(k_e, g))
                rows.append({
                    "order": order, "bandwidth": g, "kind": edge["kind"], "edge": k_b,
                    "factor": factor, "stiffness": k_e, "counts": TAU_REF / k_e / COUNT,
                    "radius": radius, "map": "stable" if radius < 1.0 else "unstable",
                    "decidable": decidable(k_e, radius), "simulated": verdict, "last": last,
                })  # fmt: skip
    return rows


def coulomb_free(point, order: int, bandwidth: float):
    """``point`` without Coulomb friction: the plant's ``coulomb = 0`` and the RTOB (the DOb at
    100 rad/s, the RTOB at ``bandwidth``) with the viscous friction model only."""
    model = paper.NOMINAL.discretize(paper.TS)
    rtob = reaction_torque_observer(
        design_observer(model, order=order, bandwidth=100.0),
        design_observer(model, order=order, bandwidth=bandwidth),
        viscous=paper.PLANT.b - paper.NOMINAL.b,
    )
    return point.replace(plant=point.plant.replace(coulomb=0.0), observer=rtob)


def causes(rows) -> list:
    """For each decidable point that disagrees: its simulated verdict without Coulomb friction
    with the paper's encoder and with the unquantised one (``FINE_ENCODER``)."""
    out = []
    for r in rows:
        if not r["decidable"] or r["map"] == r["simulated"]:
            continue
        point = own_bandwidth_map(r["order"], [r["stiffness"]], [r["bandwidth"]]).loop_at(
            r["stiffness"], r["bandwidth"])  # fmt: skip
        free = coulomb_free(point, r["order"], r["bandwidth"])
        out.append({**r, "free": simulated(free),
                    "free_fine": simulated(free.replace(sensor=FINE_ENCODER)),
                    "fine": simulated(point.replace(sensor=FINE_ENCODER))})  # fmt: skip
    return out


def main() -> None:
    rows = points()
    print(
        "| RTOB | bandwidth [rad/s] | boundary [N m/rad] | 0.9 x: counts, radius, decidable, "
        "simulated | 1.1 x: counts, radius, decidable, simulated | agree (0.9 x, 1.1 x) |"
    )
    print("|---|---:|---|---|---|---|")

    def cell(r):
        decided = "decidable" if r["decidable"] else "not decidable"
        return (
            f"{r['counts']:.1f}, {r['radius']:.4f}, {decided}, {r['simulated']} ({r['last']:.2g})"
        )

    for low, high in zip(rows[::2], rows[1::2], strict=True):
        side = "stable below" if low["kind"] == "upper" else "stable above"
        agree = ", ".join("yes" if r["map"] == r["simulated"] else "**no**" for r in (low, high))
        print(
            f"| {NAMES[low['order']]} | {low['bandwidth']:g} | {side} {low['edge']:.1f} | "
            f"{cell(low)} | {cell(high)} | {agree} |"
        )
    decided = [r for r in rows if r["decidable"]]
    agree = [r for r in decided if r["map"] == r["simulated"]]
    every = [r for r in rows if r["map"] == r["simulated"]]
    print(
        f"\n{len(rows)} points; {len(decided)} decidable, {len(agree)} of them agree; "
        f"{len(every)} of all {len(rows)} agree"
    )
    for c in causes(rows):
        print(
            f"{NAMES[c['order']]} at {c['bandwidth']:g} rad/s, {c['stiffness']:.1f} N m/rad "
            f"(map {c['map']}, simulated {c['simulated']}): with the unquantised encoder "
            f"{c['fine'][0]} ({c['fine'][1]:.3g}); without Coulomb friction {c['free'][0]} "
            f"({c['free'][1]:.3g}), and with the unquantised encoder {c['free_fine'][0]} "
            f"({c['free_fine'][1]:.3g})"
        )


if __name__ == "__main__":
    main()
