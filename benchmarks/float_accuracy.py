"""Accuracy of a float export: the derived rounding bound vs. the measured error, and the
drift on a continuously rotating axis.

Part 1 (bound vs. measurement): orders 0-3, gain direction (1, 1), driven by the 10^5 random
samples of tests/export/test_c.py (same seed) and by the canonical closed-loop runs
(hpdob.paper; orders 2 and 3 on the HPDOb-100 scenario): the largest float error, the
largest bound and the largest ratio error/bound over the samples.

Part 2 (long runs):

A float build computes the estimate from ``z_{m+1} - L_theta theta - L_omega omega`` where
``z_{m+1}`` carries ``L_theta theta``: with the default gain direction (1, 1) the numbers the
float arithmetic handles grow with the absolute angle, and so does its rounding error. The
velocity-only direction (0, 1) gives ``L_theta = 0`` and ``Kx[:, 0] = 0``: theta never enters.

For orders 0-3 and both directions this script drives the float export and the reference along

* one continuous rotation: the nominal plant (J_n = 2.8e-4 kg m^2, b_n = 0, Ts = 1 ms) turning
  at 100 +- 5 rad/s under the load 0.05 + 0.02 sin(4 pi t) N m for 1000 s (10^6 samples), so
  theta grows from 0 to 1e5 rad; the largest error is reported per decade of theta;
* two short runs (20 s) of the same motion started at theta = 1e6 and 1e7 rad (the state
  initialised there with <prefix>_init), standing for hours and days of rotation.

The reference is the double export, which tests/export/test_c.py shows to be bit-identical to
hpdob.DisturbanceObserver (it is 300 times faster here). Also printed: the largest rounding
bound of docs/deployment.md in each window and, for scale, the double observer's own estimation
error |tau_hat - tau| after the first second.

Part 3 (position-only observers): the float error and bound of the observers of
``measurement="position"`` near theta = 0 and shifted by 100 and 1000 rad. Run with

    python benchmarks/float_accuracy.py [--position-only]

and copy the tables into docs/deployment.md.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from hpdob import ServoModel, design_observer, export_c, paper
from hpdob.testing import CObserver, export_error_bound

J_N, TS = 2.8e-4, 1e-3
MODEL = ServoModel(J=J_N).discretize(TS)
WINDOWS = [(0.0, 10.0), (10.0, 1e2), (1e2, 1e3), (1e3, 1e4), (1e4, 1.01e5)]
OFFSETS = (1e6, 1e7)


def rotation_trace(n: int, theta0: float, speed: float = 100.0):
    """Nominal-plant trajectory: omega chosen, u and theta from eq. (8) with b = 0."""
    t = np.arange(n + 1) * TS
    omega = speed + 5.0 * np.sin(2.0 * np.pi * t)
    tau = 0.05 + 0.02 * np.sin(4.0 * np.pi * t[:-1])
    u = tau + J_N * np.diff(omega) / TS
    steps = np.cumsum(TS * (omega[:-1] + omega[1:]) / 2.0)
    theta = theta0 + np.concatenate([[0.0], steps[:-1]])
    return theta, omega[:-1], u, tau


def builds(design, workdir: Path) -> dict:
    out = {}
    for dtype in ("double", "float"):
        _, source = export_c(design, workdir / dtype, dtype=dtype)
        out[dtype] = CObserver(
            source.with_suffix(".h"),
            source,
            prefix="dob",
            dtype=dtype,
            order=design.order,
            build_dir=workdir / dtype / "lib",
        )
    return out


def run(c: dict, design, n: int, theta0: float):
    theta, omega, u, tau = rotation_trace(n, theta0)
    init = (theta[0], omega[0], tau[0])
    ref, _ = c["double"].drive(theta, omega, u, init=init)
    single, z = c["float"].drive(theta, omega, u, init=init)
    bound = export_error_bound(design, "float", theta, omega, u, z, init=init)
    return theta, np.abs(single - ref), bound, np.abs(ref - tau)


def random_trace(n: int = 100_000):
    rng = np.random.default_rng(20261123)  # the seed of tests/export/test_c.py
    return (
        rng.normal(scale=2.0, size=n),
        rng.normal(scale=50.0, size=n),
        rng.normal(scale=0.2, size=n),
    )


def bound_vs_measured(workdir: Path) -> None:
    print("Float export vs. the double reference: largest error, largest bound [N m], and the")
    print("largest ratio error/bound over the samples")
    print("| order | random 10^5: error | bound | ratio | canonical run: error | bound | ratio |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for order in range(4):
        design = design_observer(MODEL, order=order, bandwidth=100.0)
        c = builds(design, workdir / f"bound{order}")
        name = {0: "DOb-100", 1: "HPDOb-100"}.get(order)
        result = paper.run(
            name or "HPDOb-100",
            **({} if name else {"observer": design}),
        )
        cells = []
        canonical = (result.theta_measured, result.omega_measured, result.u)
        for theta, omega, u in (random_trace(), canonical):
            ref, _ = c["double"].drive(theta, omega, u)
            single, z = c["float"].drive(theta, omega, u)
            err = np.abs(single - ref)
            bound = export_error_bound(design, "float", theta, omega, u, z)
            ratio = np.divide(err, bound, out=np.zeros_like(err), where=bound > 0)
            cells += [f"{err.max():.1e}", f"{bound.max():.1e}", f"{ratio.max():.2f}"]
        print(f"| {order} | " + " | ".join(cells) + " |")
    print()


def position_only(workdir: Path) -> None:
    """Part 3: position-only observers (docs/theory.md section 9), every pole at 150 rad/s, on
    the measured angle and the command of the virtual-experiment-position run (|theta| <= 2
    rad), and on the same trace shifted by 100 and 1000 rad. Their state holds the angle."""
    result = paper.run("virtual-experiment-position")
    theta, u = result.theta_measured, result.u
    print("Position-only, float vs double: largest error, largest bound [N m], ratio")
    print(
        "| order | theta + 0: error | bound | ratio | + 100 rad: error | bound | ratio "
        "| + 1000 rad: error |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for order in range(3):
        design = design_observer(MODEL, order=order, bandwidth=150.0, measurement="position")
        c = {}
        for dtype in ("double", "float"):
            header, source = export_c(design, workdir / f"pos{order}{dtype}", dtype=dtype)
            c[dtype] = CObserver(header, source, prefix="dob", dtype=dtype, observer=design,
                                 build_dir=workdir / f"pos{order}{dtype}" / "lib")  # fmt: skip
        cells = []
        for offset in (0.0, 100.0, 1000.0):
            th, init = theta + offset, (offset, 0.0, 0.0)
            ref, _ = c["double"].drive(th, np.zeros_like(th), u, init=init)
            single, z = c["float"].drive(th, np.zeros_like(th), u, init=init)
            err = np.abs(single - ref)
            cells.append(f"{err.max():.1e}")
            if offset < 1000.0:
                bound = export_error_bound(design, "float", th, np.zeros_like(th), u, z, init=init)
                ratio = np.divide(err, bound, out=np.zeros_like(err), where=bound > 0)
                cells += [f"{bound.max():.1e}", f"{ratio.max():.2f}"]
        print(f"| {order} | " + " | ".join(cells) + " |")
    print()


def main() -> None:
    import sys

    with tempfile.TemporaryDirectory() as tmp:
        position_only(Path(tmp))
    if "--position-only" in sys.argv:
        return
    with tempfile.TemporaryDirectory() as tmp:
        bound_vs_measured(Path(tmp))
    head = [f"{lo:g}-{hi:.0e}" for lo, hi in WINDOWS] + [f"at {o:.0e}" for o in OFFSETS]
    rows_err, rows_bound = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for order in range(4):
            for direction in ((1.0, 1.0), (0.0, 1.0)):
                design = design_observer(
                    MODEL, order=order, bandwidth=100.0, gain_direction=direction
                )
                c = builds(design, Path(tmp) / f"{order}_{direction[0]:g}")
                theta, err, bound, model_err = run(c, design, 1_000_000, 0.0)
                errs, bounds = [], []
                for lo, hi in WINDOWS:
                    sel = (theta >= lo) & (theta < hi)
                    errs.append(err[sel].max())
                    bounds.append(bound[sel].max())
                for offset in OFFSETS:
                    _, e, b, _ = run(c, design, 20_000, offset)
                    errs.append(e.max())
                    bounds.append(b.max())
                label = f"| {order} | ({direction[0]:g}, {direction[1]:g}) |"
                rows_err.append(label + "".join(f" {v:.1e} |" for v in errs))
                rows_err[-1] += f" {model_err[1000:].max():.1e} |"
                rows_bound.append(label + "".join(f" {v:.1e} |" for v in bounds))
    print("Largest |tau_hat_float - tau_hat_double| [N m] while theta [rad] is in")
    print("| order | direction |" + "".join(f" {h} |" for h in head) + " |tau_hat - tau| |")
    print("|---|---|" + "---:|" * (len(head) + 1))
    print("\n".join(rows_err))
    print("\nThe rounding bound of docs/deployment.md [N m], same windows")
    print("| order | direction |" + "".join(f" {h} |" for h in head))
    print("|---|---|" + "---:|" * len(head))
    print("\n".join(rows_bound))


if __name__ == "__main__":
    main()
