"""The fixed-point observer as C99: the rows of a :class:`FixedPointDesign`, printed.

The generated functions evaluate exactly what :class:`FixedPointObserver` evaluates: products
of ``W``-bit integers summed in ``2W`` bits, one rounding per row (round half up, computed on
an offset unsigned value so that no negative number is shifted), saturation, and the count
difference in modulo-2^32 arithmetic.
"""

from __future__ import annotations

import re

from .._validation import ParameterTypeError, ParameterValueError
from .._version import __version__
from ._fixed import FixedPointDesign, fixed_point_design
from ._fixed_tables import FixedPointRow

__all__ = ["design_for", "render_fixed"]


def design_for(obs, dtype: str, ranges):
    """The :class:`FixedPointDesign` to print for ``dtype`` in ``FIXED``."""
    if isinstance(obs, FixedPointDesign):
        if ranges is not None:
            raise ParameterValueError(
                "ranges must be None when obs is a FixedPointDesign (its ranges are fixed), got "
                f"{ranges!r}"
            )
        if obs.word != dtype:
            raise ParameterValueError(
                f"dtype must be the design's word {obs.word!r} for a FixedPointDesign, got "
                f"{dtype!r}"
            )
        return obs
    if not isinstance(ranges, dict):
        raise ParameterTypeError(
            f"ranges must be a dict with counts_per_rev, omega_max, u_max and tau_max for "
            f"dtype {dtype!r}, got {ranges!r}"
        )
    keys = ("counts_per_rev", "omega_max", "u_max", "tau_max")
    unknown = sorted(set(ranges) - set(keys))
    missing = [k for k in keys if k not in ranges]
    if unknown or missing:
        raise ParameterValueError(
            f"ranges must have exactly the keys {', '.join(keys)}, got {sorted(ranges)!r}"
        )
    return fixed_point_design(obs, word=dtype, **ranges)


def _types(design: FixedPointDesign):
    w = design.bits
    return f"int{w}_t", f"int{2 * w}_t", f"uint{2 * w}_t"


def _row(design: FixedPointDesign, prefix: str, row: FixedPointRow, operands) -> str:
    _, acc, _ = _types(design)
    if not row.terms:
        return "0"
    parts = []
    for c, j, k in row.terms:
        term = f"({acc}){c} * {operands[j]}"
        if k:
            term += f" * ({acc}){2**k}"
        parts.append(term)
    total = "\n            + ".join(parts)
    return f"{prefix}_round({total},\n            {row.shift}u, {row.limit})"


def _header(design: FixedPointDesign, prefix: str) -> str:
    up = prefix.upper()
    word, _, _ = _types(design)
    system = design.system
    n = system.n_states
    info = [*(system.info or [("observer", system.name), ("sampling period",
                                                         f"Ts = {system.Ts!r} s")]),
            ("measures", ", ".join(system.measures)), *design.describe()]  # fmt: skip
    width = max(len(k) for k, _ in info) + 1
    lines = "\n".join(f" *   {k:<{width}}{v}" for k, v in info)
    omega_arg = ", int32_t omega" if design.measures_omega else ""
    macros = [
        ("STATES", str(n), "number of states"),
        ("COUNTS_PER_REV", str(design.counts_per_rev), "encoder counts per revolution"),
        ("DELTA_MAX", str(design.delta_max), "largest count difference per sample (saturated)"),
        ("OMEGA_FRAC_BITS", str(design.frac_bits["omega0"]),
         "omega [rad/s] = omega_int * 2^-OMEGA_FRAC_BITS (input and omega0 of _init)"),
        ("U_FRAC_BITS", str(design.frac_bits["u"]), "u [N m] = u_int * 2^-U_FRAC_BITS"),
        ("TAU_FRAC_BITS", str(design.frac_bits["tau_hat"]),
         "tau_hat, tau0 [N m] = value * 2^-TAU_FRAC_BITS"),
        ("OMEGA_MAX", str(design.limit("omega0")), "omega saturates at +-OMEGA_MAX"),
        ("U_MAX", str(design.limit("u")), "u saturates at +-U_MAX"),
        ("TAU_MAX", str(design.limit("tau_hat")), "tau_hat saturates at +-TAU_MAX"),
    ]  # fmt: skip
    extra = ""
    if system.has_velocity:
        macros.append(("OMEGA_HAT_FRAC_BITS", str(design.frac_bits["omega_hat"]),
                       "omega_hat [rad/s] = value * 2^-OMEGA_HAT_FRAC_BITS"))  # fmt: skip
        extra = (
            "\n/** Velocity estimate omega_hat_k (OMEGA_HAT format) from the encoder count. */\n"
            f"int32_t {prefix}_velocity(const {prefix}_state *s, int32_t count{omega_arg});\n"
        )
    args = "count, omega" if design.measures_omega else "count"
    reaction_loop = ""
    if "tau_reac" in system.outputs:
        # tau_reac has the format of its own proven bound (it never saturates), not TAU's
        macros.append(("TAU_REAC_FRAC_BITS", str(design.frac_bits["tau_reac"]),
                       "tau_reac [N m] = value * 2^-TAU_REAC_FRAC_BITS"))  # fmt: skip
        extra += (
            "\n/** Reaction-torque estimate tau_reac_k (TAU_REAC format): the RTOB's disturbance"
            "\n *  estimate minus the friction model, from the encoder count. */\n"
            f"int32_t {prefix}_reaction(const {prefix}_state *s, int32_t count{omega_arg});\n"
            "\n/** Both estimates in one call: *tau_hat = tau_hat_k (TAU format, "
            f"{prefix}_estimate),\n *  *tau_reac = tau_reac_k (TAU_REAC format, "
            f"{prefix}_reaction). */\n"
            f"void {prefix}_estimates(const {prefix}_state *s, int32_t count{omega_arg},\n"
            "    int32_t *tau_hat, int32_t *tau_reac);\n"
        )
        reaction_loop = (f"\n *   tau_reac = {prefix}_reaction(&s, {args});   reaction torque"
                         f"\n *     (or {prefix}_estimates(&s, {args}, &tau_hat, &tau_reac);"
                         " both at once)")  # fmt: skip
    defines = "\n".join(f"/** {note} */\n#define {up}_{name} {value}" for name, value, note
                        in macros)  # fmt: skip
    omega_doc = ", omega = measure_velocity_q();" if design.measures_omega else ";"
    return f"""\
/*
 * {prefix}.h -- fixed-point disturbance observer exported by hpdob {__version__}
 * (hpdob.export_c, dtype="{design.word}"). Generated file: re-export instead of editing it.
 *
 * Design and formats (docs/deployment.md, "Fixed point")
{lines}
 *
 * Sample loop, at every sample k and in this order (Ts = {system.Ts!r} s):
 *   count = read_encoder(){omega_doc}   32-bit running count; only differences are used
 *   tau_hat = {prefix}_estimate(&s, {args});{reaction_loop}
 *   u = u_outer + tau_hat;  apply(u);
 *   {prefix}_update(&s, {args}, u);
 * Call {prefix}_init(&s, count0, omega0, tau0) once before the first sample.
 *
 * Integer arithmetic only: {word} values, int{2 * design.bits}_t sums, round half up,
 * saturation. The count wraps around modulo 2^32 (multi-turn axes keep working).
 */
#ifndef {up}_H
#define {up}_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {{
#endif

{defines}

/** Observer state: q[i] is state i+1 in its Q format; count is the previous encoder count. */
typedef struct {{
    {word} q[{n}];
    int32_t count;
}} {prefix}_state;

/** Reset to rest at count0 with velocity omega0 and a constant disturbance tau0. */
void {prefix}_init({prefix}_state *s, int32_t count0, int32_t omega0, int32_t tau0);

/** Disturbance estimate tau_hat_k (TAU format) from the encoder count. */
int32_t {prefix}_estimate(const {prefix}_state *s, int32_t count{omega_arg});
{extra}
/** Advance to sample k+1 with the same measurement and the torque u_k applied (U format). */
void {prefix}_update({prefix}_state *s, int32_t count{omega_arg}, int32_t u);

#ifdef __cplusplus
}}
#endif

#endif /* {up}_H */
"""


def _source(design: FixedPointDesign, prefix: str) -> str:
    up = prefix.upper()
    word, acc, uacc = _types(design)
    w = design.bits
    system = design.system
    n = system.n_states
    offset_bits = 2 * w - 2
    names = [*(f"q{i + 1}" for i in range(n)), "d", *(("w",) if design.measures_omega else ()),
             "v"]  # fmt: skip
    omega_arg = ", int32_t omega" if design.measures_omega else ""
    narrow = "" if w == 32 else f"({word})"

    def reads(text):
        return "".join(f"    const {word} q{i + 1} = s->q[{i}];\n" for i in range(n)
                       if re.search(rf"\bq{i + 1}\b", text))  # fmt: skip

    inputs = f"    const {word} d = {narrow}{prefix}_delta(count, s->count);\n"
    if design.measures_omega:
        inputs += f"    const {word} w = {narrow}{prefix}_clamp(omega, {up}_OMEGA_MAX);\n"

    def output(r):
        body = f"    return {_row(design, prefix, design.output[r], names)};\n"
        return reads(body) + inputs + body

    upd_rows = "".join(f"    s->q[{i}] = {narrow}{_row(design, prefix, row, names)};\n"
                       for i, row in enumerate(design.update))  # fmt: skip
    update = (reads(upd_rows) + inputs
              + f"    const {word} v = {narrow}{prefix}_clamp(u, {up}_U_MAX);\n"
              + upd_rows + "    s->count = count;\n")  # fmt: skip
    reset_names = ("w0", "t0")
    init_rows = "".join(
        f"    s->q[{i}] = {narrow}{_row(design, prefix, row, reset_names)};\n"
        for i, row in enumerate(design.reset))  # fmt: skip
    used = init_rows
    init = (f"    const {word} w0 = {narrow}{prefix}_clamp(omega0, {up}_OMEGA_MAX);\n"
            if "w0" in used else "    (void)omega0;\n")  # fmt: skip
    init += (f"    const {word} t0 = {narrow}{prefix}_clamp(tau0, {up}_TAU_MAX);\n"
             if "t0" in used else "    (void)tau0;\n")  # fmt: skip
    init += init_rows + "    s->count = count0;\n"
    extra = ""
    if system.has_velocity:
        signature = f"int32_t {prefix}_velocity(const {prefix}_state *s, int32_t count{omega_arg})"
        extra = f"\n{signature}\n{{\n{output(1)}}}\n"
    if "tau_reac" in system.outputs:
        signature = f"int32_t {prefix}_reaction(const {prefix}_state *s, int32_t count{omega_arg})"
        extra += f"\n{signature}\n{{\n{output(system.outputs.index('tau_reac'))}}}\n"
        args = "count, omega" if design.measures_omega else "count"
        # the two output functions in turn: its values are theirs bit for bit
        extra += (
            f"\nvoid {prefix}_estimates(const {prefix}_state *s, int32_t count{omega_arg},\n"
            f"    int32_t *tau_hat, int32_t *tau_reac)\n{{\n"
            f"    *tau_hat = {prefix}_estimate(s, {args});\n"
            f"    *tau_reac = {prefix}_reaction(s, {args});\n}}\n"
        )
    top = 2 ** (w - 1) - 1
    return f"""\
/*
 * {prefix}.c -- fixed-point disturbance observer exported by hpdob {__version__}; see
 * {prefix}.h for the design, the formats and the sample loop. Generated file.
 *
 * In the count-difference frame q_k = s_k - d theta_(k-1) (docs/deployment.md):
 *   q_(k+1) = F q_k + (G_theta - d) delta_k + G_r r_k,  y_k = H q_k + E_theta delta_k + E_r r_k.
 * Each row is sum_j C_j x_j 2^k_j in {acc} (exact: the bounds of docs/deployment.md keep
 * every sum below 2^{offset_bits}), then one rounding to the row's Q format and saturation.
 */
#include "{prefix}.h"

/* floor((acc + 2^(shift-1)) / 2^shift) (round half up), saturated to +-limit. The shift
 * is applied to acc + 2^{offset_bits} >= 0: right-shifting a negative value is
 * implementation-defined in C99. */
static {word} {prefix}_round({acc} acc, unsigned int shift, {acc} limit)
{{
    const {uacc} offset = ({uacc})1 << {offset_bits};
    const {uacc} half = shift > 0u ? ({uacc})1 << (shift - 1u) : 0u;
    const {acc} r = ({acc})((({uacc})acc + offset + half) >> shift) - ({acc})(offset >> shift);
    return ({word})(r > limit ? limit : (r < -limit ? -limit : r));
}}

static int32_t {prefix}_clamp(int32_t x, int32_t limit)
{{
    return x > limit ? limit : (x < -limit ? -limit : x);
}}

/* count - previous modulo 2^32 as a signed value (wrap-around), saturated to DELTA_MAX. */
static int32_t {prefix}_delta(int32_t count, int32_t previous)
{{
    const uint32_t d = (uint32_t)count - (uint32_t)previous;
    const int32_t delta = d <= 0x7FFFFFFFu ? (int32_t)d : -(int32_t)(~d) - 1;
    return {prefix}_clamp(delta, {up}_DELTA_MAX);
}}

void {prefix}_init({prefix}_state *s, int32_t count0, int32_t omega0, int32_t tau0)
{{
{init}}}

int32_t {prefix}_estimate(const {prefix}_state *s, int32_t count{omega_arg})
{{
{output(0)}}}
{extra}
void {prefix}_update({prefix}_state *s, int32_t count{omega_arg}, int32_t u)
{{
{update}}}
/* word range: +-{top} */
"""


def render_fixed(design: FixedPointDesign, prefix: str) -> tuple[str, str]:
    """Text of ``<prefix>.h`` and ``<prefix>.c`` of a fixed-point design."""
    return _header(design, prefix), _source(design, prefix)
