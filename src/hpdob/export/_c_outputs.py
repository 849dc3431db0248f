"""Pieces of the exported C observer for its optional outputs (the reaction torque)."""

from __future__ import annotations

__all__ = ["reaction_declaration", "reaction_definition", "reaction_steps", "signature"]


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
    return [(f"tau_reac = {prefix}_reaction(&s, {args});", "reaction torque [N m]")]


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
