r"""A controller of the protocol as dependency-free C99: ``<prefix>.h`` and ``<prefix>.c``.

The header declares, with ``T`` the chosen ``dtype`` and ``v...`` the controller's inputs::

    typedef struct { T c[max(n, 1)]; } <prefix>_state;
    void <prefix>_init(<prefix>_state *s, T theta0, T omega0, T tau0);
    T    <prefix>_command(const <prefix>_state *s, T v...);
    void <prefix>_update(<prefix>_state *s, T v..., T u_bar);

Every row of the controller's program is printed term by term in its order (the signals as
``const`` locals), so a ``double`` build reproduces the Python form and the compiled kernel
bit for bit (without floating-point contraction).
"""

from __future__ import annotations

import re

from .._validation import ParameterTypeError, ParameterValueError, check_choice
from .._version import __version__
from ..observers import render_sum

__all__ = ["render_controller"]

_RESET = ("theta0", "omega0", "tau0")


def _sum(terms, operands, dtype, literal) -> str:
    return render_sum(terms, operands, lambda v: literal(v, dtype, "(inline)"), named=False)


def _body(controller, dtype: str, literal) -> tuple[list[str], list[str]]:
    program = controller.program
    n = controller.n_states
    state = [f"c{i}" for i in range(n)]
    signals = [f"y_{name}" for name in program.signal_names]
    operands = [*state, *controller.inputs, "u_bar", *signals]
    load = [f"    const {dtype} {c} = s->c[{i}];" for i, c in enumerate(state)]
    lines = [
        f"    const {dtype} {y} = {_sum(terms, operands, dtype, literal)};"
        for y, terms in zip(signals, program.signals, strict=True)
    ]
    # a state or signal that no later row reads would warn under -Wall
    quiet = [f"    (void){name};" for name in (*state, *signals)]
    return load + lines + quiet, operands


def _unused(names, body: str) -> list[str]:
    return [f"    (void){n};" for n in names if not re.search(rf"\b{n}\b", body)]


def render_controller(controller, *, prefix: str, dtype: str, nan_guard, literal, ranges=None):
    """Text of ``<prefix>.h`` and ``<prefix>.c`` for a :class:`LinearController` (the
    arguments as for :func:`hpdob.export.render_c`; floating point only: ``nan_guard`` False,
    no ``ranges``; ``literal(value, dtype, name)`` prints a constant, from ``_c.py``)."""
    from ._c_names import check_prefix

    _literal = literal

    dtype = check_choice(dtype, "dtype", ("double", "float"))
    prefix = check_prefix(prefix)
    if ranges is not None:
        raise ParameterValueError(
            "ranges are for the fixed-point export of observers; a controller is exported in "
            "double or float"
        )
    if nan_guard is not False:
        raise ParameterTypeError(
            f"nan_guard must be False for a controller (the guard is for observers), got "
            f"{nan_guard!r}"
        )
    if controller.program.switch is not None:
        raise ParameterValueError(
            f"controller {controller.name!r} has a latching switch, which export_c does not "
            "generate; export the controllers of its two modes instead"
        )
    n = controller.n_states
    reserved = re.compile(r"(s|c[0-9]+|next[0-9]+|y_.*|theta0|omega0|tau0)\Z")
    clash = [v for v in controller.inputs if reserved.match(v)]
    if clash:
        raise ParameterValueError(
            f"controller input {clash[0]!r} clashes with a name of the generated C (s, c<i>, "
            "next<i>, y_<signal>, theta0, omega0, tau0); rename the input"
        )
    up = prefix.upper()
    args = ", ".join(f"{dtype} {v}" for v in controller.inputs) or "void"
    info = list(controller.info) or [("controller", controller.name)]
    info += [("sampling period", f"Ts = {controller.Ts!r} s"), ("states", str(n)),
             ("inputs", ", ".join(controller.inputs)), ("scalar type", dtype)]  # fmt: skip
    width = max(len(key) for key, _ in info) + 1
    design = "\n".join(f" *   {key:<{width}}{value}" for key, value in info)
    const = "const " if n else ""
    header = f"""\
/*
 * {prefix}.h -- controller exported by hpdob {__version__} (hpdob.export_c).
 * Generated file: re-export from the design instead of editing it.
 *
 * Design
{design}
 *
 * Sample loop, at every sample k (Ts = {controller.Ts!r} s):
 *   u = {prefix}_command(&s, inputs);      torque command [N m]
 *   u_bar = limit(u); apply(u_bar);
 *   {prefix}_update(&s, inputs, u_bar);   with the torque really applied
 * Call {prefix}_init(&s, theta0, omega0, tau0) once before the first sample.
 *
 * No dynamic memory, no I/O, no library calls: plain C99 arithmetic on {dtype}.
 */
#ifndef {up}_H
#define {up}_H

#ifdef __cplusplus
extern "C" {{
#endif

/** Number of states of the controller. */
#define {up}_STATES {n}
/** Sampling period Ts [s] the controller was designed for. */
#define {up}_TS {_literal(controller.Ts, dtype, "Ts")}

/** Controller state (one unused entry when it has none). */
typedef struct {{
    {dtype} c[{max(n, 1)}];
}} {prefix}_state;

/** Reset at theta0 [rad], omega0 [rad/s] with a constant disturbance tau0 [N m]. */
void {prefix}_init({prefix}_state *s, {dtype} theta0, {dtype} omega0, {dtype} tau0);

/** Torque command u_k [N m] from the inputs ({", ".join(controller.inputs)}). */
{dtype} {prefix}_command({const}{prefix}_state *s, {args});

/** Advance to sample k+1 with the same inputs and the command really applied u_bar [N m]. */
void {prefix}_update({prefix}_state *s, {args}, {dtype} u_bar);

#ifdef __cplusplus
}}
#endif

#endif /* {up}_H */
"""
    program = controller.program
    body, operands = _body(controller, dtype, literal)
    init = [f"    s->c[{i}] = {_sum(row, _RESET, dtype, literal)};"
            for i, row in enumerate(program.reset)]  # fmt: skip
    if not n:
        init = ["    s->c[0] = 0;"]
    init_text = "\n".join(init)
    init_text = "\n".join([*_unused(_RESET, init_text), init_text])
    command = "\n".join(body)
    command_unused = _unused(controller.inputs, command)
    if not n:
        command_unused.insert(0, "    (void)s;")
    update = [f"    const {dtype} next{i} = {_sum(row, operands, dtype, literal)};"
              for i, row in enumerate(program.update)]  # fmt: skip
    store = [f"    s->c[{i}] = next{i};" for i in range(n)]
    update_text = "\n".join(body + update + store) if n else ""
    update_unused = _unused([*controller.inputs, "u_bar"], update_text)
    if not n:
        update_unused.insert(0, "    (void)s;")
    y_u = f"y_{program.signal_names[-1]}"
    source = f"""\
/* {prefix}.c -- controller exported by hpdob {__version__}; see {prefix}.h. */
#include "{prefix}.h"

void {prefix}_init({prefix}_state *s, {dtype} theta0, {dtype} omega0, {dtype} tau0)
{{
{init_text}
}}

{dtype} {prefix}_command({const}{prefix}_state *s, {args})
{{
{chr(10).join([*command_unused, command])}
    return {y_u};
}}

void {prefix}_update({prefix}_state *s, {args}, {dtype} u_bar)
{{
{chr(10).join([*update_unused, update_text])}
}}
"""
    return header, source
