"""``hpdob design``: synthesise an observer and print its matrices and gains."""

from __future__ import annotations

import argparse
import json

import numpy as np

from ..models import ServoModel
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


_KIND_TYPES = {"int": _integer, "float": finite, "complex_list": _number_list(complex),
               "float_list": _number_list(float)}  # fmt: skip
#: Options every family shares: a bandwidth (what a design at a bandwidth sets, for every
#: family) or explicit poles.
_SHARED = ("bandwidth", "poles")
#: The default bandwidth [rad/s] when neither --bandwidth nor the tuned parameter is given.
DEFAULT_BANDWIDTH = 100.0


def _option(name: str) -> str:
    return "--" + name.replace("_", "-")


def _observer_options() -> dict:
    """``{name: [(family, Parameter), ...]}``: every registered family's parameters."""
    from ..observers import families

    options: dict = {}
    for family in families():
        for p in family.parameters:
            options.setdefault(p.name, []).append((family, p))
    return options


def add_observer_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the observer options: ``--type`` and one option per parameter of every registered
    family (:func:`hpdob.observers.families`), ``--bandwidth`` and ``--poles`` exclusive."""
    from ..observers import families

    names = [f.name for f in families()]
    obs = parser.add_argument_group("observer")
    obs.add_argument(
        "--type",
        choices=names,
        default="dob",
        help="observer family: "
        + "; ".join(f"{f.name}: {f.title}" for f in families() if f.title)
        + " (default: %(default)s)",
    )
    which = obs.add_mutually_exclusive_group()
    which.add_argument(
        "--bandwidth",
        type=finite,
        default=None,
        help="bandwidth g [rad/s], all poles at exp(-g Ts); a family tuned by another parameter "
        f"(kalman: its process noise) is designed for it (default: {DEFAULT_BANDWIDTH:g})",
    )
    which.add_argument(
        "--poles",
        type=_number_list(complex),
        default=None,
        help="order+1 comma-separated poles (order+3 with --measurement position), "
        "e.g. 0.9,0.9 or 0.9+0.1j,0.9-0.1j",
    )
    for name, owners in _observer_options().items():
        if name in _SHARED:
            continue
        parameter = owners[0][1]
        described = "; ".join(f"{f.name}: {p.help}" for f, p in owners)
        defaults = [f"{f.name} {f.defaults[name]}" for f, _ in owners if name in f.defaults]
        if defaults:
            described += f" (default: {', '.join(defaults)})"
        kwargs = {"choices": parameter.choices} if parameter.kind == "choice" else {
            "type": _KIND_TYPES[parameter.kind]}  # fmt: skip
        obs.add_argument(_option(name), default=None, help=described, **kwargs)


def design_from_args(args: argparse.Namespace):
    """Build the design described by parsed ``add_design_arguments``."""
    return design_on(args, ServoModel(args.J_n, args.b_n).discretize(args.Ts))


def observer_spec_of_args(args: argparse.Namespace) -> tuple[dict, float | None]:
    """``(spec, bandwidth)`` parsed ``add_observer_arguments`` describe: the family's spec
    and, where the spec leaves the tuned parameter out, the bandwidth to design it at."""
    from ..observers import families, get_family
    from ._errors import CLIError

    family = get_family(getattr(args, "type", "dob"), "--type")
    kind = family.name
    owners = _observer_options()
    given = {name: getattr(args, name) for name in owners
             if getattr(args, name, None) is not None}  # fmt: skip
    if family.order is not None:  # an order key several families share: name this one's
        for other in families():
            key = other.order
            shared = len(owners.get(key, ())) > 1
            if (
                key not in (None, family.order)
                and key in given
                and key not in family.keys
                and shared
            ):
                raise CLIError(f"--type {kind} takes {_option(family.order)}, not {_option(key)}")
    # options of another family are refused, not silently ignored
    for other in families():
        if other is family:
            continue
        foreign = [_option(k) for k in other.keys
                   if k in given and k not in family.keys and k != "bandwidth"]  # fmt: skip
        if foreign:
            verb = "applies" if len(foreign) == 1 else "apply"
            raise CLIError(
                f"{', '.join(foreign)} {verb} to --type {other.name} only, not --type {kind}"
            )
    spec = {"type": kind, **{k: v for k, v in family.defaults.items() if k not in given},
            **{k: v for k, v in given.items() if k in family.keys}}  # fmt: skip
    tuned_given = any(k in given for k in family.set_at_bandwidth)
    if family.tuned != "bandwidth" and family.tuned in given and "bandwidth" in given:
        raise CLIError(
            f"--type {kind} takes --bandwidth (the {family.tuned.replace('_', ' ')} is chosen for "
            f"it) or {_option(family.tuned)}, not both"
        )
    missing = [k for k in family.required if k not in spec and k not in family.set_at_bandwidth]
    if missing:
        help_ = family.parameter(missing[0]).help
        raise CLIError(f"--type {kind} needs {_option(missing[0])} ({help_})")
    if tuned_given:
        return spec, None
    spec.pop("bandwidth", None)
    return spec, DEFAULT_BANDWIDTH if args.bandwidth is None else args.bandwidth


def design_on(args: argparse.Namespace, model):
    """The design parsed ``add_observer_arguments`` describe, on the discrete ``model``."""
    from ..observers import design_at_bandwidth, design_from_spec

    spec, bandwidth = observer_spec_of_args(args)
    if bandwidth is None:
        return design_from_spec(model, spec)
    return design_at_bandwidth(model, spec, bandwidth)


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
