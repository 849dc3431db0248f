"""``hpdob design``: synthesise an observer and print its matrices and gains."""

from __future__ import annotations

import argparse
import json

import numpy as np

from ..models._servo import ServoModel
from ..observers._synthesis import design_observer
from ._options import add_nominal_arguments, finite, reject_plant_arguments

__all__ = ["register"]


def _number_list(kind):
    def parse(text: str):
        try:
            return [kind(item.strip().replace("i", "j")) for item in text.split(",")]
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"expected comma-separated numbers, got {text!r}"
            ) from None

    return parse


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None


def add_design_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the model and observer options shared by commands that design an observer."""
    add_nominal_arguments(parser.add_argument_group("nominal model"))
    reject_plant_arguments(parser)
    add_observer_arguments(parser)


def add_observer_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the observer options: family, order, bandwidth or poles, and each family's own."""
    obs = parser.add_argument_group("observer")
    obs.add_argument(
        "--type",
        choices=("dob", "eso", "kalman"),
        default="dob",
        help="observer family: the paper's order-m observers (dob), ADRC's extended state "
        "observer (eso) or the Kalman disturbance observer (kalman) (default: %(default)s)",
    )
    obs.add_argument(
        "--order",
        type=_integer,
        default=None,
        help="truncation order: 0 DOb, 1 HPDOb, >= 2 generalised (dob, default 1); disturbance "
        "order of the Kalman observer (default 0)",
    )
    obs.add_argument(
        "--extended-order",
        type=_integer,
        default=None,
        help="eso: f^(m+1) = 0 (0 the classical ESO, default)",
    )
    obs.add_argument(
        "--form",
        choices=("current", "predictive"),
        default=None,
        help="eso: discrete implementation (default: current)",
    )
    obs.add_argument(
        "--position-noise-std",
        type=finite,
        default=None,
        help="kalman: angle noise std [rad] (an encoder's resolution/sqrt(12))",
    )
    obs.add_argument(
        "--process-noise-std",
        type=finite,
        default=None,
        help="kalman: process noise std (default: chosen for --bandwidth, 100 rad/s)",
    )
    which = obs.add_mutually_exclusive_group()
    which.add_argument(
        "--bandwidth",
        type=finite,
        default=None,
        help="bandwidth g [rad/s], all poles at exp(-g Ts) (default: 100)",
    )
    which.add_argument(
        "--poles",
        type=_number_list(complex),
        default=None,
        help="order+1 comma-separated poles (order+3 with --measurement position), "
        "e.g. 0.9,0.9 or 0.9+0.1j,0.9-0.1j",
    )
    obs.add_argument(
        "--measurement",
        choices=("state", "position"),
        default="state",
        help="what the observer measures: angle and velocity (state, the paper's) or the "
        "angle only (position; the velocity is estimated) (default: %(default)s)",
    )
    obs.add_argument(
        "--velocity-bandwidth",
        type=finite,
        default=None,
        help="--measurement position: bandwidth of the two velocity poles [rad/s] "
        "(default: the bandwidth)",
    )
    obs.add_argument(
        "--gain-direction",
        type=_number_list(float),
        default=None,
        help="--measurement state: gain direction d, e.g. 1,1 (eq. 25) or 0,1 (default: 1,1)",
    )


#: The options of each family (the others refuse them); --order is dob's and kalman's.
_FAMILY_OPTIONS = {
    "dob": ("poles", "velocity_bandwidth", "gain_direction"),
    "eso": ("extended_order", "form"),
    "kalman": ("position_noise_std", "process_noise_std"),
}


def design_from_args(args: argparse.Namespace):
    """Build the design described by parsed ``add_design_arguments``."""
    return design_on(args, ServoModel(args.J_n, args.b_n).discretize(args.Ts))


def design_on(args: argparse.Namespace, model):
    """The design parsed ``add_observer_arguments`` describe, on the discrete ``model``."""
    from ._errors import CLIError

    bandwidth = args.bandwidth
    if bandwidth is None and args.poles is None:
        bandwidth = 100.0
    kind = getattr(args, "type", "dob")
    if kind == "eso" and args.order is not None:
        raise CLIError("--type eso takes --extended-order, not --order")
    # options of another family are refused, not silently ignored
    for family, names in _FAMILY_OPTIONS.items():
        given = [f"--{k.replace('_', '-')}" for k in names if getattr(args, k) is not None]
        if family == "dob" and args.measurement != "state":
            given.append("--measurement")
        if given and family != kind:
            verb = "applies" if len(given) == 1 else "apply"
            raise CLIError(f"{', '.join(given)} {verb} to --type {family} only, not --type {kind}")
    if kind == "eso":
        from ..observers._eso import design_eso

        return design_eso(
            model,
            bandwidth=bandwidth,
            extended_order=0 if args.extended_order is None else args.extended_order,
            form=args.form or "current",
        )
    if kind == "kalman":
        from ..observers._kalman import design_kalman, kalman_process_noise

        if args.position_noise_std is None:
            raise CLIError("--type kalman needs --position-noise-std (the angle noise [rad])")
        order = 0 if args.order is None else args.order
        q = args.process_noise_std
        if q is not None and args.bandwidth is not None:
            raise CLIError(
                "--type kalman takes --bandwidth (the process noise is chosen for it) or "
                "--process-noise-std, not both"
            )
        if q is None:
            r = args.position_noise_std
            q = kalman_process_noise(model, bandwidth=bandwidth, position_noise_std=r, order=order)
        return design_kalman(model, order=order, position_noise_std=args.position_noise_std,
                             process_noise_std=q)  # fmt: skip
    return design_observer(
        model,
        order=1 if args.order is None else args.order,
        poles=args.poles,
        bandwidth=bandwidth,
        measurement=args.measurement,
        velocity_bandwidth=args.velocity_bandwidth,
        gain_direction=args.gain_direction,
    )


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "design",
        help="synthesise an observer and print A_D, B_D, D_D, gains, error matrix",
        description="Synthesise a disturbance observer on the exact ZOH discretisation of the "
        "nominal servo model (--J-n, --b-n) and print its matrices. Defaults: the paper's "
        "nominal model (J_n = 2.8e-4 kg m^2, b_n = 0), Ts = 1 ms, HPDOb (order 1) at "
        "100 rad/s.",
    )
    add_design_arguments(parser)
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.set_defaults(handler=_run)


def _complex_json(values) -> list:
    return [{"real": float(np.real(v)), "imag": float(np.imag(v))} for v in np.atleast_1d(values)]


def _system_summary(design) -> dict:
    system = design.system
    return {
        "observer": system.name,
        "model": {"J": design.model.J, "b": design.model.b, "Ts": design.model.Ts},
        "measures": list(system.measures),
        "outputs": list(system.outputs),
        "F": system.F.tolist(),
        "G": system.G.tolist(),
        "H": system.H.tolist(),
        "E": system.E.tolist(),
        "N": system.N.tolist(),
        "eigenvalues": _complex_json(np.linalg.eigvals(system.F)),
    }


def design_summary(design) -> dict:
    """JSON-ready dictionary describing ``design`` (used by ``--json``)."""
    if not hasattr(design, "error_matrix"):  # the peer families: the linear system itself
        return _system_summary(design)
    model = design.model
    if design.system.measurement == "position":
        return {
            "model": {"J": model.J, "b": model.b, "Ts": model.Ts},
            "measurement": "position",
            "order": design.order,
            "poles": _complex_json(design.poles),
            "bandwidth": design.bandwidth,
            "velocity_bandwidth": design.velocity_bandwidth,
            "A_D": model.A.tolist(),
            "B_D": model.B.tolist(),
            "D_D": model.D.tolist(),
            "augmented_matrix": design.augmented_matrix.tolist(),
            "gains": design.gains.tolist(),
            "predictor_gains": design.predictor_gains.tolist(),
            "error_matrix": design.error_matrix.tolist(),
            "eigenvalues": _complex_json(np.linalg.eigvals(design.error_matrix)),
        }
    return {
        "model": {"J": model.J, "b": model.b, "Ts": model.Ts},
        "order": design.order,
        "poles": _complex_json(design.poles),
        "bandwidth": design.bandwidth,
        "gain_direction": design.gain_direction.tolist(),
        "A_D": model.A.tolist(),
        "B_D": model.B.tolist(),
        "D_D": model.D.tolist(),
        "k": design.k.tolist(),
        "gains": design.gains.tolist(),
        "error_matrix": design.error_matrix.tolist(),
        "eigenvalues": _complex_json(np.linalg.eigvals(design.error_matrix)),
    }


def _fmt(value: complex) -> str:
    value = complex(value)
    # Drop imaginary parts below the 6 printed digits (repeated poles split by ~sqrt(eps)).
    if abs(value.imag) <= 5e-7 * max(abs(value), 1e-300):
        return f"{value.real:.6g}"
    return f"{value.real:.6g}{value.imag:+.6g}j"


def _matrix_lines(name: str, matrix) -> list[str]:
    rows = np.atleast_2d(np.asarray(matrix))
    cells = [[f"{v:.6e}" for v in row] for row in rows]
    width = max(len(c) for row in cells for c in row)
    lines = []
    for i, row in enumerate(cells):
        label = name if i == 0 else ""
        lines.append(f"  {label:<14}[ " + "  ".join(c.rjust(width) for c in row) + " ]")
    return lines


def _position_table(design) -> str:
    model = design.model
    bandwidths = ""
    if design.bandwidth is not None:
        bandwidths = (
            f"   (bandwidth {design.bandwidth:.6g} rad/s, velocity bandwidth "
            f"{design.velocity_bandwidth:.6g} rad/s)"
        )
    kind = {0: "DOb", 1: "HPDOb"}.get(design.order, "generalised DOb")
    lines = [
        f"Position-only disturbance observer: order {design.order} ({kind}), the angle "
        "is the only measurement",
        f"  nominal model   J_n = {model.J:.6g} kg m^2, b_n = {model.b:.6g} N m s/rad, "
        f"Ts = {model.Ts:.6g} s",
        f"  poles           {', '.join(_fmt(p) for p in np.atleast_1d(design.poles))}" + bandwidths,
        "",
        "Discrete nominal model x[k+1] = A_D x[k] + B_D u[k] - D_D tau[k]   (eq. 8)",
        *_matrix_lines("A_D", model.A),
        *_matrix_lines("B_D^T", model.B),
        *_matrix_lines("D_D^T", model.D),
        "",
        "Augmented state xi = [theta, omega, tau_(k-m), ..., tau_k]   (docs/theory.md, sec. 9)",
        *_matrix_lines("A_a", design.augmented_matrix),
        "",
        "Gains: xi_hat = s + K (theta - s_1),  s[k+1] = (A_a - L c^T) s + L theta + B_a u",
        *_matrix_lines("K^T", design.gains),
        *_matrix_lines("L^T", design.predictor_gains),
        "",
        "Estimation-error matrix A_a - L c^T",
        *_matrix_lines("F", design.error_matrix),
        "  eigenvalues   " + ", ".join(_fmt(v) for v in np.linalg.eigvals(design.error_matrix)),
    ]
    return "\n".join(lines)


def _system_table(design) -> str:
    system = design.system
    lines = [
        f"Observer: {system.name}",
        *(f"  {key:<16}{value}" for key, value in system.info),
        f"  measures        {', '.join(system.measures)}; outputs {', '.join(system.outputs)}",
        "",
        "s[k+1] = F s[k] + G [y[k]; u[k]],  outputs H s[k] + E [y[k]; u[k]]",
        *_matrix_lines("F", system.F),
        *_matrix_lines("G", system.G),
        *_matrix_lines("H", system.H),
        *_matrix_lines("E", system.E),
        "  eigenvalues   " + ", ".join(_fmt(v) for v in np.linalg.eigvals(system.F)),
    ]
    return "\n".join(lines)


def design_table(design) -> str:
    """Human-readable table of ``design`` (the default output of ``hpdob design``)."""
    if not hasattr(design, "error_matrix"):
        return _system_table(design)
    if design.system.measurement == "position":
        return _position_table(design)
    model = design.model
    kind = {0: "conventional DOb", 1: "HPDOb"}.get(design.order, "generalised DOb")
    lines = [
        f"Disturbance observer: order {design.order} ({kind})",
        f"  nominal model   J_n = {model.J:.6g} kg m^2, b_n = {model.b:.6g} N m s/rad, "
        f"Ts = {model.Ts:.6g} s",
        f"  poles           {', '.join(_fmt(p) for p in np.atleast_1d(design.poles))}"
        + (f"   (bandwidth {design.bandwidth:.6g} rad/s)" if design.bandwidth else ""),
        f"  gain direction  {design.gain_direction.tolist()}",
        "",
        "Discrete nominal model x[k+1] = A_D x[k] + B_D u[k] - D_D tau[k]   (eq. 8)",
        *_matrix_lines("A_D", model.A),
        *_matrix_lines("B_D^T", model.B),
        *_matrix_lines("D_D^T", model.D),
        "",
        "Gains (row i is L_i^T; k_i = L_i^T D_D)",
    ]
    for i, (row, k) in enumerate(zip(design.gains, design.k, strict=True), start=1):
        lines.append(f"  L_{i:<13}[ {row[0]: .6e}  {row[1]: .6e} ]   k_{i} = {k:.6g}")
    lines += [
        "",
        "Estimation-error matrix M  (eqs. 12, 22)",
        *_matrix_lines("M", design.error_matrix),
        "  eigenvalues   " + ", ".join(_fmt(v) for v in np.linalg.eigvals(design.error_matrix)),
    ]
    return "\n".join(lines)


def _run(args: argparse.Namespace) -> int:
    design = design_from_args(args)
    if args.json:
        print(json.dumps(design_summary(design), indent=2))
    else:
        print(design_table(design))
    return 0
