r"""Export a designed observer as dependency-free C99 source for a microcontroller.

:func:`export_c` writes ``<prefix>.h`` and ``<prefix>.c``: a state struct and three functions
(``_init``, ``_estimate``, ``_update``) with the design's gains baked in as constants. The
update is generated term by term in the operation order of :func:`hpdob.update`, so a build
in ``double`` reproduces the Python observer to the last bit (IEEE arithmetic without
floating-point contraction, which is GCC's default under ``-std=c99``); ``docs/deployment.md``
describes the verification and the error bound of a ``float`` build.
"""

from __future__ import annotations

import re
import struct
from pathlib import Path

import numpy as np

from .._files import staged_outputs
from .._validation import ParameterTypeError, ParameterValueError, check_choice
from .._version import __version__
from ..controllers import LinearController
from ..observers import RESET_OPERANDS, UNITS, LinearObserver, as_system, render_sum
from ._c_fixed import design_for, render_fixed
from ._c_guard import guard_header, guard_helpers, guarded_init, guarded_output, guarded_update
from ._c_names import check_directory, check_prefix
from ._c_outputs import (
    coulomb_constants,
    coulomb_expression,
    coulomb_include,
    coulomb_note,
    estimates_declaration,
    estimates_definition,
    reaction_declaration,
    reaction_definition,
    reaction_steps,
)
from ._c_outputs import signature as _signature
from ._controller_c import render_controller
from ._fixed import FixedPointDesign

__all__ = ["export_c", "render_c"]

#: Scalar types the code can be generated for (the last two: fixed point, ``_fixed.py``).
DTYPES = ("double", "float", "q31", "q15")
FIXED = ("q31", "q15")


def _literal(value: float, dtype: str, name: str) -> str:
    """C literal that reads back exactly as ``value`` rounded to ``dtype``."""
    value = float(value)
    if dtype == "double":
        return repr(value)  # shortest string that round-trips a binary64
    try:
        single = struct.unpack("f", struct.pack("f", value))[0]
    except OverflowError:
        single = None
    if single is None or (value != 0.0 and abs(single) < 2.0**-126):
        raise ParameterValueError(
            f"dtype 'float' cannot hold the constant {name} = {value!r} (it overflows or "
            "underflows binary32); export with dtype='double'"
        )
    text = f"{single:.9g}"  # 9 significant digits round-trip any binary32
    if not any(c in text for c in ".e"):
        text += ".0"
    return text + "f"


_SIGNAL_NOTES = {
    "theta": "angle [rad]",
    "omega": "velocity [rad/s]",
}


def _c_literal(dtype: str):
    return lambda value: _literal(value, dtype, "(inline)")


def _expression(terms, operands, dtype: str) -> str:
    """A program row as C, one term per line when long (left-to-right sum, as in Python)."""
    text = render_sum(terms, operands, _c_literal(dtype))
    if len(text) <= 76:
        return text
    # break before each top-level " + " / " - " (render_sum separates terms exactly so)
    return re.sub(r" ([+-]) ", r"\n        \1 ", text)


def _unused(names: list[str], body: str) -> list[str]:
    """``(void)name;`` for parameters that no term uses (keeps -Wextra quiet)."""
    return [f"    (void){n};" for n in names if not re.search(rf"\b{n}\b", body)]


def _paper_form(system: LinearObserver) -> bool:
    """Whether ``system`` is the paper's auxiliary-variable observer (order m, measuring the
    state): the comments then cite its equations."""
    return system.truncation_order is not None and len(system.measures) == 2


def _state_note(system: LinearObserver) -> str:
    return " (z_(i+1) of the paper's auxiliary variables)" if _paper_form(system) else ""


def _header(system: LinearObserver, prefix: str, dtype: str, guard: bool = False) -> str:
    up = prefix.upper()
    n = system.n_states
    meas = ", ".join(system.measures)
    info = list(system.info) or [
        ("observer", system.name),
        ("sampling period", f"Ts = {system.Ts!r} s"),
        ("states", str(n)),
    ]
    info.append(("measures", meas))
    info.append(("scalar type", dtype))
    if guard:
        info.append(("NaN guard", "on: non-finite inputs are skipped and flagged"))
    width = max(len(key) for key, _ in info) + 1
    design = "\n".join(f" *   {key:<{width}}{value}" for key, value in info)
    args = ", ".join(system.measures)
    est_note = "disturbance [N m], eq. 13/23" if _paper_form(system) else "disturbance [N m]"
    measure_note = "angle [rad], velocity [rad/s]" if len(system.measures) == 2 else "angle [rad]"
    steps = [
        (f"{args} = measure();", measure_note),
        (f"tau_hat = {prefix}_estimate(&s, {args});", est_note),
        ("u = u_outer + tau_hat;", "compensate it"),
        ("apply(u);", "held over [k Ts, (k+1) Ts)"),
        (f"{prefix}_update(&s, {args}, u);", "with the torque really applied"),
    ]
    if system.has_velocity:
        steps.insert(2, (f"omega_hat = {prefix}_velocity(&s, {args});", "velocity [rad/s]"))
    steps[2:2] = reaction_steps(system, prefix, args)
    step_width = max(len(code) for code, _ in steps) + 2
    loop = "\n".join(f" *   {code:<{step_width}}{note}" for code, note in steps)
    order = ""
    if system.truncation_order is not None:
        holds = " (the state holds m + 1 values)" if _paper_form(system) else ""
        order = (
            f"/** Truncation order m of the observer{holds}. */\n"
            f"#define {up}_ORDER {system.truncation_order}\n"
        )
    meas_doc = ", ".join(f"{m} [{UNITS[m]}]" for m in system.measures)
    const = "" if guard else "const "
    velocity_decl = ""
    if system.has_velocity:
        velocity_decl = (
            f"\n/** Velocity estimate omega_hat_k [rad/s] from the measured {meas_doc}. */\n"
            f"{dtype} {prefix}_velocity({const}{prefix}_state *s, "
            f"{_signature(system, dtype, with_u=False)});\n"
        )
    velocity_decl += reaction_declaration(system, prefix, dtype, const, meas_doc)
    velocity_decl += estimates_declaration(system, prefix, dtype, const, meas_doc)
    guard_fields = guard_doc = guard_define = ""
    if guard:
        guard_fields, guard_doc, guard_define = guard_header(prefix, dtype, len(system.outputs))
    return f"""\
/*
 * {prefix}.h -- disturbance observer exported by hpdob {__version__} (hpdob.export_c).
 * Generated file: re-export from the design instead of editing it.
 *
 * Design
{design}
 *
 * Sample loop, at every sample k and in this order (Ts = {system.Ts!r} s):
{loop}
 * Call {prefix}_init(&s, theta0, omega0, tau0) once before the first sample: it sets the
 * state a constant disturbance tau0 [N m] at rest in (theta0, omega0) would give.
 *
{guard_doc}{coulomb_note(system, dtype)}
 */
#ifndef {up}_H
#define {up}_H

#ifdef __cplusplus
extern "C" {{
#endif

/** Scalar type of the observer. */
typedef {dtype} {prefix}_real;

{order}/** Number of states of the observer. */
#define {up}_STATES {n}
{guard_define}/** Sampling period Ts [s] the observer was designed for. */
#define {up}_TS {_literal(system.Ts, dtype, "Ts")}

/** Observer state: z[i] is state s_(i+1) of the observer (docs/theory.md). */
typedef struct {{
    {dtype} z[{n}];
{guard_fields}}} {prefix}_state;

/** Reset to the state of a constant disturbance tau0 [N m] at rest in theta0, omega0. */
void {prefix}_init({prefix}_state *s, {dtype} theta0, {dtype} omega0, {dtype} tau0);

/** Disturbance estimate tau_hat_k [N m] from the measured {meas_doc}. */
{dtype} {prefix}_estimate({const}{prefix}_state *s, {_signature(system, dtype, with_u=False)});
{velocity_decl}
/** Advance to sample k+1 with the same measurement and the torque u_k [N m] applied. */
void {prefix}_update({prefix}_state *s, {_signature(system, dtype, with_u=True)});

#ifdef __cplusplus
}}
#endif

#endif /* {up}_H */
"""


def _constants(system: LinearObserver, dtype: str, code: str) -> list[str]:
    """Definitions of the named constants ``code`` uses (an unused ``static const`` warns)."""
    lines = []
    table = system.program.constant_table()
    order = [name for name, _ in system.program.constants]
    for name in sorted(table, key=lambda c: order.index(c) if c in order else len(order)):
        value, note = table[name]
        if re.search(rf"\b{name}\b", code):
            comment = f" /* {note} */" if note else ""
            lines.append(f"static const {dtype} {name} = {_literal(value, dtype, name)};{comment}")
    zero = system.program.zero_constants
    if zero:
        lines.append(f"/* exactly zero, their terms are left out: {', '.join(zero)} */")
    return lines


def _source(system: LinearObserver, prefix: str, dtype: str, guard: bool = False) -> str:
    program = system.program
    n = system.n_states
    z = [f"z{i + 1}" for i in range(n)]
    operands = [*z, *system.measures, "u"]
    zero = _literal(0.0, dtype, "0")

    init_rows = [
        f"    {'next' if guard else 's->z'}[{i}] = {_expression(row, RESET_OPERANDS, dtype)};"
        for i, row in enumerate(program.reset)
    ]
    if guard:
        init = guarded_init(prefix, dtype, n, init_rows, RESET_OPERANDS, zero,
                            velocity=system.has_velocity)  # fmt: skip
    else:
        init = "\n".join(_unused(list(RESET_OPERANDS), "\n".join(init_rows)) + init_rows)

    def reads(body):
        return [
            f"    const {dtype} {z[i]} = s->z[{i}];"
            for i in range(n)
            if re.search(rf"\b{z[i]}\b", body)
        ]

    direct = [f"s->z[{i}]" for i in range(n)] + operands[n:]  # outputs read the state in place

    def velocity_expression():
        if system.coulomb.velocity == "omega":
            return "omega"
        return f"({_expression(program.output[system.outputs.index('omega_hat')], direct, dtype)})"

    def output_body(r):
        expression = _expression(program.output[r], direct, dtype)
        if system.coulomb is not None and system.outputs[r] == "tau_reac":
            expression = coulomb_expression(system, expression, dtype, velocity_expression())
        if guard:
            return guarded_output(prefix, dtype, expression, system.measures, r)
        line = f"    return {expression};"
        return "\n".join([*_unused(list(system.measures), line), line])

    est = output_body(0)
    target = "next" if guard else "s->z"
    rows = [
        f"    {target}[{i}] = {_expression(row, operands, dtype)};"
        for i, row in enumerate(program.update)
    ]
    body = "\n".join(rows)
    if guard:
        upd = guarded_update(prefix, dtype, n, reads(body), rows, system.measures)
    else:
        upd = "\n".join([*reads(body), *_unused([*system.measures, "u"], body), *rows])
    const = "" if guard else "const "
    velocity = ""
    if system.has_velocity:
        velocity = f"""
{dtype} {prefix}_velocity({const}{prefix}_state *s, {_signature(system, dtype, with_u=False)})
{{
{output_body(1)}
}}
"""
    velocity += reaction_definition(system, prefix, dtype, const, output_body)
    velocity += estimates_definition(system, prefix, dtype, const, guard)
    helpers = guard_helpers(prefix, dtype, n) if guard else ""
    constants = "\n".join(_constants(system, dtype, init + est + upd + velocity)
                          + coulomb_constants(system, dtype, _literal))  # fmt: skip
    recursion = (
        " * Recursion (docs/theory.md, paper eqs. 11/13 for order 0, 20/21/23 for order 1):\n"
        " *   z_{k+1} = M z_k + (G A - M G) x_k + G B u_k,   "
        "tau_hat_k = z_{m+1,k} - L_{m+1}^T x_k.\n"
        if _paper_form(system)
        else " * Recursion: s_{k+1} = F s_k + G [y_k; u_k], outputs H s_k + E [y_k; u_k].\n"
    )
    return f"""\
/*
 * {prefix}.c -- disturbance observer exported by hpdob {__version__}; see {prefix}.h for the
 * design and the sample loop. Generated file: re-export instead of editing it.
 *
{recursion} * Every sum is evaluated left to right in the order of the observer's program, as the
 * Python observer and the compiled simulation kernel evaluate it (terms whose constant is
 * exactly zero are left out), so a double build reproduces the Python observer bit for bit
 * when the compiler does not contract a*b + c into fused multiply-adds.
 * z[i] here is state s_(i+1) of the observer{_state_note(system)}.
 */
#include "{prefix}.h"{coulomb_include(system)}

{constants}
{helpers}
void {prefix}_init({prefix}_state *s, {dtype} theta0, {dtype} omega0, {dtype} tau0)
{{
{init}
}}

{dtype} {prefix}_estimate({const}{prefix}_state *s, {_signature(system, dtype, with_u=False)})
{{
{est}
}}
{velocity}
void {prefix}_update({prefix}_state *s, {_signature(system, dtype, with_u=True)})
{{
{upd}
}}
"""


def _check_guard(nan_guard) -> bool:
    if not isinstance(nan_guard, (bool, np.bool_)):
        raise ParameterTypeError(
            f"nan_guard must be True or False, got {nan_guard!r} of type {type(nan_guard).__name__}"
        )
    return bool(nan_guard)


def render_c(
    obs,
    *,
    prefix: str = "dob",
    dtype: str = "double",
    nan_guard: bool = False,
    ranges: dict | None = None,
) -> tuple[str, str]:
    """Text of ``<prefix>.h`` and ``<prefix>.c`` for ``obs``, without writing files.

    Parameters
    ----------
    obs : observer-like or LinearController
        As for :func:`export_c`.
    prefix, dtype, nan_guard, ranges
        As for :func:`export_c`.

    Returns
    -------
    header, source : str
        The C99 texts that :func:`export_c` writes (ASCII).

    Raises
    ------
    TypeError, ValueError
        As :func:`export_c`, for the observer, ``prefix``, ``dtype`` and ``nan_guard``.

    Examples
    --------
    >>> from hpdob import ServoModel, design_observer
    >>> from hpdob.export import render_c
    >>> design = design_observer(ServoModel(J=2.8e-4).discretize(1e-3), order=1,
    ...                          bandwidth=100.0)
    >>> header, source = render_c(design, prefix="axis1")
    >>> "void axis1_update(axis1_state *s" in header
    True
    >>> [line for line in source.splitlines() if line.startswith("#include")]   # no library
    ['#include "axis1.h"']
    """
    if isinstance(obs, LinearController):  # a controller: ._controller_c (floating point)
        return render_controller(obs, prefix=prefix, dtype=dtype, nan_guard=nan_guard,
                                 literal=_literal, ranges=ranges)  # fmt: skip
    dtype = check_choice(dtype, "dtype", DTYPES)
    prefix = check_prefix(prefix)
    guard = _check_guard(nan_guard)
    if dtype in FIXED:
        if guard:
            raise ParameterValueError(
                f"nan_guard must be False for dtype {dtype!r}: integers cannot be NaN, and the "
                "fixed-point inputs saturate instead"
            )
        return render_fixed(design_for(obs, dtype, ranges), prefix)
    if ranges is not None:
        raise ParameterValueError(
            f"ranges are only used for the fixed-point dtypes q31 and q15, got dtype {dtype!r}"
        )
    if isinstance(obs, FixedPointDesign):
        raise ParameterValueError(
            f"dtype must be {obs.word!r} for a FixedPointDesign (export the observer itself for "
            f"floating point), got {dtype!r}"
        )
    system = as_system(obs, "obs")
    return _header(system, prefix, dtype, guard), _source(system, prefix, dtype, guard)


def export_c(
    obs,
    directory,
    *,
    prefix: str = "dob",
    dtype: str = "double",
    nan_guard: bool = False,
    ranges: dict | None = None,
) -> tuple[Path, Path]:
    r"""Write the observer as dependency-free C99: ``<prefix>.h`` and ``<prefix>.c``.

    The header declares, with ``T`` the chosen ``dtype``::

        typedef struct { T z[order + 1]; } <prefix>_state;
        void <prefix>_init(<prefix>_state *s, T theta0, T omega0, T tau0);
        T    <prefix>_estimate(const <prefix>_state *s, T theta, T omega);
        void <prefix>_update(<prefix>_state *s, T theta, T omega, T u);

    and, for convenience, ``<prefix>_real`` (``T``), ``<PREFIX>_ORDER`` and ``<PREFIX>_TS``.
    The gains are constants printed so that they read back exactly (``repr`` for double,
    the binary32 value with 9 significant digits for float); a header comment records the
    design and the sample-loop order. The code uses no dynamic memory, no I/O and no library
    function, and compiles warning-free with
    ``gcc -std=c99 -Wall -Wextra -Wpedantic -Wconversion -Werror``.

    Parameters
    ----------
    obs : DisturbanceObserver or ObserverDesign or LinearController
        The observer to export; only its design is used (the C state starts from
        ``<prefix>_init``, not from the Python object's current state). A controller
        (:class:`~hpdob.controllers.LinearController`) gets ``_command`` and ``_update``.
    directory : str or os.PathLike
        Output directory, created if missing; existing files of the same name are replaced.
    prefix : str, optional
        C identifier prefix of every exported name and of the file names, default ``"dob"``.
        Letters, digits and underscores, starting with a letter, at most 22 characters.
    dtype : {"double", "float", "q31", "q15"}, optional
        Scalar type of the generated code. ``"double"`` reproduces :func:`hpdob.update` bit
        for bit; ``"float"`` suits single-precision FPUs, within the error bound derived in
        ``docs/deployment.md``; ``"q31"`` (``"q15"``) is fixed point for FPU-less parts: int32
        (int16) states and coefficients, int64 (int32) sums, the encoder count as input
        (:func:`hpdob.export.fixed_point_design`, bit-exact model
        :class:`hpdob.export.FixedPointObserver`). Default ``"double"``.
    nan_guard : bool, optional
        Generate the opt-in guard: a sample with a non-finite input, or whose result would
        overflow, is skipped (the state is unchanged, ``_estimate`` returns the last estimate
        from finite inputs) and the state's ``fault``/``skipped`` fields say so
        (``docs/deployment.md``). Default False; must be False in fixed point.
    ranges : dict, optional
        For ``"q31"``/``"q15"`` when ``obs`` is an observer: ``counts_per_rev``,
        ``omega_max`` [rad/s], ``u_max`` [N m] and ``tau_max`` [N m], the arguments of
        :func:`hpdob.export.fixed_point_design`. None (default) when ``obs`` is already a
        :class:`hpdob.export.FixedPointDesign`, and for the floating-point types.

    Returns
    -------
    tuple of pathlib.Path
        The paths written, ``(<directory>/<prefix>.h, <directory>/<prefix>.c)``.

    Raises
    ------
    TypeError
        If ``obs`` is neither a DisturbanceObserver nor an ObserverDesign, or ``directory``
        is not a path.
    ValueError
        If ``dtype`` is not one of ``"double"``, ``"float"``, ``"q31"``, ``"q15"``, ``prefix``
        is not a valid C identifier prefix, ``directory`` is an existing file, a constant
        does not fit in binary32 for ``dtype="float"``, or the fixed-point ``ranges`` are
        missing or cannot be represented (:func:`hpdob.export.fixed_point_design`). Nothing
        is written then.

    Notes
    -----
    The update is generated in the operation order of :func:`hpdob.update`:
    ``z_i' = z_{i+1} - k_i z_{m+1} + Kx_i0 theta + Kx_i1 omega + Ku_i u`` for ``i <= m`` and
    ``z_{m+1}' = -k_{m+1} z_{m+1} + Kx theta + Kx omega + Ku u + sum_j p_j z_j``, each sum
    evaluated left to right, and the estimate is ``z_{m+1} - L_theta theta - L_omega omega``.
    With gain direction ``(0, 1)`` neither uses ``theta``: the estimate does not depend on the
    absolute position, which keeps a float build accurate on continuously rotating axes.

    References
    ----------
    E. Sariyildiz, "A High Performance Disturbance Observer: A Unified Synthesis Approach",
    eqs. (11), (13) (conventional DOb) and (20), (21), (23) (HPDOb).

    Examples
    --------
    >>> import tempfile
    >>> from hpdob import DisturbanceObserver, ServoModel, export_c
    >>> obs = DisturbanceObserver(ServoModel(J=2.8e-4).discretize(1e-3), order=1,
    ...                           bandwidth=100.0)
    >>> with tempfile.TemporaryDirectory() as out:
    ...     header, source = export_c(obs, out, prefix="axis1", dtype="float")
    ...     print(header.name, source.name)
    ...     print("float axis1_estimate(const axis1_state *s" in header.read_text())
    axis1.h axis1.c
    True
    """
    path = check_directory(directory)
    header, source = render_c(obs, prefix=prefix, dtype=dtype, nan_guard=nan_guard, ranges=ranges)
    names = (f"{prefix}.h", f"{prefix}.c")
    for name in names:  # refused before anything is written, the other file untouched
        if (path / name).is_dir():
            raise ParameterValueError(
                f"cannot write {str(path / name)!r}: it is an existing directory (nothing written)"
            )
    # Both files are staged and renamed together: a failure leaves the previous pair.
    with staged_outputs(path) as files:
        for name, text in zip(names, (header, source), strict=True):
            files.write_text(name, text, encoding="ascii")
    return path / names[0], path / names[1]
