"""The opt-in NaN guard of the exported C observer (``export_c(..., nan_guard=True)``).

Without it, one non-finite measurement or torque makes every later state and estimate NaN
until ``<prefix>_init``. With it, a call whose inputs (or results) are not finite is skipped:
``_update`` leaves the state unchanged and counts the sample in ``s.skipped``, ``_estimate``
returns the last estimate computed from finite inputs, and both set ``s.fault``. Finiteness is
decided by two ordered comparisons with the largest finite value of the scalar type (NaN fails
every ordered comparison), so the code stays freestanding: no ``math.h``, no ``float.h``.
Calls with finite inputs run exactly the arithmetic of the unguarded export (same expressions,
same order), so a double build still reproduces :func:`hpdob.update` bit for bit.
"""

from __future__ import annotations

__all__ = ["REAL_MAX", "guard_header", "guard_helpers", "guarded_init", "guarded_output",
           "guarded_update"]  # fmt: skip

#: Largest finite value of each scalar type, as C literals (binary64 and binary32 maxima).
REAL_MAX = {"double": "1.7976931348623157e308", "float": "3.40282347e38f"}


def _finite(prefix: str, names) -> str:
    return " && ".join(f"{prefix}_finite({name})" for name in names)


def guard_header(prefix: str, dtype: str, outputs: int) -> tuple[str, str, str]:
    """``(struct fields, header comment, #define)`` of a guarded export."""
    up = prefix.upper()
    fields = (
        f"    {dtype} last[{outputs}]; /* latest output(s) computed from finite inputs */\n"
        f"    unsigned int skipped; /* updates skipped since init (saturates) */\n"
        f"    int fault; /* 1 if the latest call got a non-finite input, else 0 */\n"
    )
    doc = f"""\
 * NaN guard ({up}_NAN_GUARD): a call with a non-finite input (NaN or +-inf; also a result
 * that would overflow) is skipped instead of poisoning the state until {prefix}_init:
 * {prefix}_update leaves the state unchanged, counts the sample in s.skipped and sets
 * s.fault = 1; {prefix}_estimate returns the last estimate computed from finite inputs
 * (tau0 of {prefix}_init before the first one) and sets s.fault = 1. A call with finite
 * inputs clears s.fault. Finiteness is tested by comparisons, without math.h: do not
 * compile with -ffast-math or -ffinite-math-only, which assume that no NaN occurs.
 *
"""
    define = (
        f"/** The observer skips and flags non-finite inputs (see above). */\n"
        f"#define {up}_NAN_GUARD 1\n"
    )
    return fields, doc, define


def guard_helpers(prefix: str, dtype: str, states: int) -> str:
    """The static helper functions ``_finite``, ``_all_finite`` and ``_skip``."""
    limit = REAL_MAX[dtype]
    return f"""
/* 1 if x is finite: NaN fails every ordered comparison and +-inf lies beyond the largest
   finite value, so two comparisons decide it without math.h. */
static int {prefix}_finite({dtype} x)
{{
    return x >= -{limit} && x <= {limit};
}}

static int {prefix}_all_finite(const {dtype} *v)
{{
    int i;
    for (i = 0; i < {states}; ++i) {{
        if (!{prefix}_finite(v[i])) {{
            return 0;
        }}
    }}
    return 1;
}}

/* A skipped update: the state is left as it was. */
static void {prefix}_skip({prefix}_state *s)
{{
    s->fault = 1;
    if (s->skipped + 1u != 0u) {{
        s->skipped += 1u;
    }}
}}
"""


def guarded_init(prefix, dtype, states, rows, operands, zero, *, velocity: bool) -> str:
    """Body of ``_init``: ``rows`` assign ``next[i]``; non-finite arguments or results give
    the zero state (and ``last`` 0) with ``fault`` set."""
    last = ["    s->last[0] = tau0;"] + (["    s->last[1] = omega0;"] if velocity else [])
    return "\n".join(
        [
            f"    {dtype} next[{states}];",
            "    int i;",
            *rows,
            f"    if (!({_finite(prefix, operands)} && {prefix}_all_finite(next))) {{",
            f"        for (i = 0; i < {states}; ++i) {{",
            f"            next[i] = {zero};",
            "        }",
            f"        tau0 = {zero};",
            f"        omega0 = {zero};",
            "        s->fault = 1;",
            "    } else {",
            "        s->fault = 0;",
            "    }",
            f"    for (i = 0; i < {states}; ++i) {{",
            "        s->z[i] = next[i];",
            "    }",
            *last,
            "    s->skipped = 0u;",
        ]
    )


def guarded_output(prefix, dtype, expression, measures, index: int) -> str:
    """Body of an output function (``_estimate``, ``_velocity``) with the guard."""
    return "\n".join(
        [
            f"    const {dtype} y = {expression};",
            f"    if (!({_finite(prefix, [*measures, 'y'])})) {{",
            "        s->fault = 1;",
            f"        return s->last[{index}];",
            "    }",
            "    s->fault = 0;",
            f"    s->last[{index}] = y;",
            "    return y;",
        ]
    )


def guarded_update(prefix, dtype, states, reads, rows, measures) -> str:
    """Body of ``_update``: ``rows`` assign ``next[i]``, committed only if all is finite."""
    return "\n".join(
        [
            *reads,
            f"    {dtype} next[{states}];",
            "    int i;",
            *rows,
            f"    if (!({_finite(prefix, [*measures, 'u'])} && {prefix}_all_finite(next))) {{",
            f"        {prefix}_skip(s);",
            "        return;",
            "    }",
            f"    for (i = 0; i < {states}; ++i) {{",
            "        s->z[i] = next[i];",
            "    }",
            "    s->fault = 0;",
        ]
    )
