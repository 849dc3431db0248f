"""The integer rows of a fixed-point design as Python functions (printed as C by ``_c_fixed``).

Kept apart from :class:`~hpdob.export.FixedPointDesign` so that the design's ``python``
property and the runtime can both use it without a cycle between their modules.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from ._fixed_tables import FixedPointRow

if TYPE_CHECKING:
    from ._fixed import FixedPointDesign

__all__ = ["compile_fixed"]


def _py_row(row: FixedPointRow, operands) -> str:
    total = (
        " + ".join(f"({c}) * {operands[j]}" + (f" * {2**k}" if k else "") for c, j, k in row.terms)
        or "0"
    )
    if row.shift > 0:
        total = f"(({total}) + {2 ** (row.shift - 1)}) >> {row.shift}"
    return f"_sat({total}, {row.limit})"


def compile_fixed(design: FixedPointDesign):
    """Python functions ``(init, outputs, update)`` running the design's integer rows."""
    n = design.system.n_states
    state = [f"q{i}" for i in range(n)]
    names = [*state, "d", *(("w",) if design.measures_omega else ()), "u"]
    mask = 2**32
    wrap = f"    d = (count - c + {2**31}) % {mask} - {2**31}\n"
    wrap += f"    d = -{design.delta_max} if d < -{design.delta_max} else " \
            f"({design.delta_max} if d > {design.delta_max} else d)\n"  # fmt: skip
    clamp = ""
    if design.measures_omega:
        lim = design.limit("omega")
        clamp += f"    w = -{lim} if w < -{lim} else ({lim} if w > {lim} else w)\n"
    unpack = f"    ({', '.join(state)},), c = s\n"
    args = "count, w" if design.measures_omega else "count"
    lim_u = design.limit("u")
    clamp_u = f"    u = -{lim_u} if u < -{lim_u} else ({lim_u} if u > {lim_u} else u)\n"
    lim_w0, lim_t0 = math.floor(design.omega_max * 2.0 ** design.frac_bits["omega0"]), \
        design.limit("tau_hat")  # fmt: skip
    src = [
        "def _sat(x, limit):\n    return -limit if x < -limit else (limit if x > limit else x)\n",
        "def init(count0, omega0, tau0):\n"
        f"    omega0 = _sat(omega0, {lim_w0})\n    tau0 = _sat(tau0, {lim_t0})\n"
        f"    return ({', '.join(_py_row(r, ('omega0', 'tau0')) for r in design.reset)},), "
        "count0\n",
        f"def outputs(s, {args}):\n{unpack}{wrap}{clamp}"
        f"    return ({', '.join(_py_row(r, names) for r in design.output)},)\n",
        f"def update(s, {args}, u):\n{unpack}{wrap}{clamp}{clamp_u}"
        f"    return ({', '.join(_py_row(r, names) for r in design.update)},), count\n",
    ]
    namespace: dict = {}
    exec(compile("\n".join(src), "<hpdob fixed-point observer>", "exec"), namespace)
    return namespace["init"], namespace["outputs"], namespace["update"]
