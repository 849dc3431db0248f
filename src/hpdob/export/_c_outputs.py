"""Pieces of the exported C observer for its optional outputs (the reaction torque).

An RTOB's Coulomb term (``LinearObserver.coulomb``) is printed as the Python runtime and the
kernel evaluate it (:func:`hpdob.observers.coulomb_torque`): the linear ``tau_reac`` row, then
``- COULOMB_C * tanh(velocity / COULOMB_V)`` (``tanhf`` in float), the only library call of
the export (``math.h``, link with ``-lm``); with a dead band the velocity first passes through
``coulomb_deadzone`` (``COULOMB_D``), the same three branches as the runtime's.
"""

from __future__ import annotations

__all__ = [
    "coulomb_constants",
    "coulomb_expression",
    "coulomb_include",
    "coulomb_note",
    "estimates_declaration",
    "estimates_definition",
    "reaction_declaration",
    "reaction_definition",
    "reaction_steps",
    "signature",
]


def signature(system, dtype: str, *, with_u: bool) -> str:
    """The C parameters of an observer function: the measures (and ``u``)."""
    names = [f"{dtype} {m}" for m in system.measures]
    if with_u:
        names.append(f"{dtype} u")
    return ", ".join(names)


def reaction_steps(system, prefix: str, args: str) -> list:
    """The sample-loop line of ``<prefix>_reaction`` for the header's comment (or none)."""
    if "tau_reac" not in system.outputs:
        return []
    return [
        (f"tau_reac = {prefix}_reaction(&s, {args});", "reaction torque [N m]"),
        (f"  (or {prefix}_estimates(&s, {args}, &tau_hat, &tau_reac);", "both at once)"),
    ]


def reaction_declaration(system, prefix: str, dtype: str, const: str, meas_doc: str) -> str:
    """The header's declaration of ``<prefix>_reaction`` (empty without a ``tau_reac``)."""
    if "tau_reac" not in system.outputs:
        return ""
    return (
        f"\n/** Reaction-torque estimate tau_reac_k [N m] (the RTOB's disturbance estimate minus"
        f"\n *  the friction model) from the measured {meas_doc}. */\n"
        f"{dtype} {prefix}_reaction({const}{prefix}_state *s, "
        f"{signature(system, dtype, with_u=False)});\n"
    )


def reaction_definition(system, prefix: str, dtype: str, const: str, output_body) -> str:
    """The source's definition of ``<prefix>_reaction``: the output row of ``tau_reac``."""
    if "tau_reac" not in system.outputs:
        return ""
    body = output_body(system.outputs.index("tau_reac"))
    return f"""
{dtype} {prefix}_reaction({const}{prefix}_state *s, {signature(system, dtype, with_u=False)})
{{
{body}
}}
"""


def estimates_declaration(system, prefix: str, dtype: str, const: str, meas_doc: str) -> str:
    """The header's declaration of ``<prefix>_estimates``: tau_hat and tau_reac in one call
    (issue 21: one C function giving both; empty without a ``tau_reac``)."""
    if "tau_reac" not in system.outputs:
        return ""
    return (
        f"\n/** Both estimates in one call: *tau_hat = the DOb's disturbance estimate tau_hat_k"
        f"\n *  [N m] ({prefix}_estimate), *tau_reac = the reaction-torque estimate tau_reac_k"
        f"\n *  [N m] ({prefix}_reaction), from the measured {meas_doc}. */\n"
        f"void {prefix}_estimates({const}{prefix}_state *s, "
        f"{signature(system, dtype, with_u=False)},\n"
        f"    {dtype} *tau_hat, {dtype} *tau_reac);\n"
    )


def estimates_definition(system, prefix: str, dtype: str, const: str, guard: bool) -> str:
    """The source's ``<prefix>_estimates``: the two output functions called in turn, so its
    values are theirs bit for bit; guarded, ``fault`` is set if either output faulted."""
    if "tau_reac" not in system.outputs:
        return ""
    args = ", ".join(system.measures)
    if guard:
        body = (
            f"    int fault;\n"
            f"    *tau_hat = {prefix}_estimate(s, {args});\n"
            f"    fault = s->fault;\n"
            f"    *tau_reac = {prefix}_reaction(s, {args});\n"
            f"    s->fault |= fault;"
        )
    else:
        body = (
            f"    *tau_hat = {prefix}_estimate(s, {args});\n"
            f"    *tau_reac = {prefix}_reaction(s, {args});"
        )
    return f"""
void {prefix}_estimates({const}{prefix}_state *s, {signature(system, dtype, with_u=False)},
    {dtype} *tau_hat, {dtype} *tau_reac)
{{
{body}
}}
"""


def coulomb_expression(system, linear: str, dtype: str, velocity: str) -> str:
    """``tau_reac``'s expression: the linear row minus the Coulomb term, in the runtime's order."""
    tanh = "tanhf" if dtype == "float" else "tanh"
    if system.coulomb.deadband > 0.0:
        velocity = f"coulomb_deadzone({velocity})"
    return f"({linear}) - COULOMB_C * {tanh}({velocity} / COULOMB_V)"


def coulomb_constants(system, dtype: str, literal) -> list:
    """The Coulomb term's constants (none without one)."""
    term = system.coulomb
    if term is None:
        return []
    lines = [
        f"static const {dtype} COULOMB_C = {literal(term.c, dtype, 'COULOMB_C')};"
        " /* Coulomb torque c_n of the friction model [N m] */",
        f"static const {dtype} COULOMB_V = {literal(term.v, dtype, 'COULOMB_V')};"
        " /* its velocity scale v_n [rad/s] */",
    ]
    if term.deadband > 0.0:
        zero = "0.0f" if dtype == "float" else "0.0"
        lines += [
            f"static const {dtype} COULOMB_D = {literal(term.deadband, dtype, 'COULOMB_D')};"
            " /* the dead band d on its velocity [rad/s] */",
            "",
            "/* The dead band: w - d above d, w + d below -d, 0 between (0 * w: NaN stays NaN). */",
            f"static {dtype} coulomb_deadzone({dtype} w)",
            "{",
            "    if (w > COULOMB_D) return w - COULOMB_D;",
            "    if (w < -COULOMB_D) return w + COULOMB_D;",
            f"    return {zero} * w;",
            "}",
        ]
    return lines


def coulomb_include(system) -> str:
    """``#include <math.h>`` for the Coulomb term's ``tanh`` (nothing without one)."""
    return "" if system.coulomb is None else "\n#include <math.h>"


def coulomb_note(system, dtype: str) -> str:
    """The header's line on memory and library calls."""
    if system.coulomb is None:
        return f" * No dynamic memory, no I/O, no library calls: plain C99 arithmetic on {dtype}."
    return (
        f" * No dynamic memory, no I/O: C99 arithmetic on {dtype}, and tanh from math.h for the\n"
        " * Coulomb term of the reaction torque's friction model (link with -lm)."
    )
