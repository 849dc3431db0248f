r"""Export a designed observer as dependency-free C99 source for a microcontroller.

:func:`export_c` writes ``<prefix>.h`` and ``<prefix>.c``: a state struct and three functions
(``_init``, ``_estimate``, ``_update``) with the design's gains baked in as constants. The
update is generated term by term in the operation order of :func:`hpdob.update`, so a build
in ``double`` reproduces the Python observer to the last bit (IEEE arithmetic without
floating-point contraction, which is GCC's default under ``-std=c99``); ``docs/deployment.md``
describes the verification and the error bound of a ``float`` build.
"""

from __future__ import annotations

import os
import re
import struct
from pathlib import Path

from .._validation import ParameterTypeError, ParameterValueError, check_choice
from .._version import __version__
from ..observers._runtime import as_design
from ..observers._synthesis import ObserverDesign

__all__ = ["export_c", "render_c"]

#: Scalar types the code can be generated for.
DTYPES = ("double", "float")
#: Longest prefix: ``<prefix>_estimate`` then stays within the 31 significant characters
#: C99 (5.2.4.1) guarantees for external identifiers.
MAX_PREFIX = 31 - len("_estimate")
_IDENTIFIER = re.compile(r"[A-Za-z][A-Za-z0-9_]*\Z")
_ORDER_NAMES = {0: "conventional DOb, paper eqs. 9-13", 1: "HPDOb, paper eqs. 14-24"}


def _check_prefix(prefix) -> str:
    if not isinstance(prefix, str):
        raise ParameterTypeError(
            f"prefix must be a str (a C identifier such as 'dob'), got {prefix!r} of type "
            f"{type(prefix).__name__}"
        )
    if not _IDENTIFIER.match(prefix):
        raise ParameterValueError(
            "prefix must be a C identifier starting with a letter (letters, digits and "
            f"underscores only, e.g. 'dob' or 'axis1_dob'), got {prefix!r}"
        )
    if len(prefix) > MAX_PREFIX:
        raise ParameterValueError(
            f"prefix must have at most {MAX_PREFIX} characters so that "
            f"'{prefix}_estimate' stays within C99's 31 significant characters, "
            f"got {prefix!r} ({len(prefix)} characters)"
        )
    return prefix


def _check_directory(directory) -> Path:
    if not isinstance(directory, (str, os.PathLike)):
        raise ParameterTypeError(
            f"directory must be a path (str or os.PathLike), got {type(directory).__name__}"
        )
    path = Path(directory)
    if path.exists() and not path.is_dir():
        raise ParameterValueError(f"directory must be a directory, got the file {str(path)!r}")
    return path


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


def _sum(terms: list[tuple[str, str]]) -> str:
    """``[(sign, text), ...]`` as a C expression, one term per line after the first."""
    first_sign, first = terms[0]
    parts = [("-" if first_sign == "-" else "") + first]
    parts += [f"{sign} {text}" for sign, text in terms[1:]]
    line = " ".join(parts)
    if len(line) <= 76:
        return line
    return "\n        ".join(parts)


def _product(constant: str, value: float, operand: str, sign: str = "+") -> list:
    """A ``constant * operand`` term, dropped when the constant is exactly zero."""
    return [] if value == 0.0 else [(sign, f"{constant} * {operand}")]


def _weight_term(p: float, operand: str, dtype: str) -> tuple[str, str]:
    """``+ p * z`` of the extrapolation weights, written without the factor 1.

    ``acc + p * z`` and ``acc - |p| * z`` round identically (negation is exact).
    """
    sign = "-" if p < 0 else "+"
    magnitude = abs(p)
    if magnitude == 1.0:
        return (sign, operand)
    return (sign, f"{_literal(magnitude, dtype, 'p')} * {operand}")


def _unused(names: list[str], body: str) -> list[str]:
    """``(void)name;`` for parameters that no term uses (keeps -Wextra quiet)."""
    return [f"    (void){n};" for n in names if not re.search(rf"\b{n}\b", body)]


def _fmt_complex(p) -> str:
    p = complex(p)
    return repr(p.real) if p.imag == 0.0 else f"{p.real!r}{p.imag:+}j"


def _header(design: ObserverDesign, prefix: str, dtype: str) -> str:
    m, model = design.order, design.model
    up = prefix.upper()
    kind = _ORDER_NAMES.get(m, "generalised DOb, Delta^(m+1) tau = 0")
    poles = ", ".join(_fmt_complex(p) for p in design.poles)
    if design.bandwidth is not None:
        poles += f" (bandwidth {design.bandwidth!r} rad/s)"
    d = design.gain_direction
    ts = _literal(model.Ts, dtype, "Ts")
    steps = [
        ("theta, omega = measure();", "angle [rad], velocity [rad/s]"),
        (f"tau_hat = {prefix}_estimate(&s, theta, omega);", "disturbance [N m], eq. 13/23"),
        ("u = u_outer + tau_hat;", "compensate it"),
        ("apply(u);", "held over [k Ts, (k+1) Ts)"),
        (f"{prefix}_update(&s, theta, omega, u);", "with the torque really applied"),
    ]
    width = max(len(code) for code, _ in steps) + 2
    loop = "\n".join(f" *   {code:<{width}}{note}" for code, note in steps)
    return f"""\
/*
 * {prefix}.h -- disturbance observer exported by hpdob {__version__} (hpdob.export_c).
 * Generated file: re-export from the design instead of editing it.
 *
 * Design
 *   nominal model   J_n = {model.J!r} kg m^2, b_n = {model.b!r} N m s/rad
 *   sampling period Ts = {model.Ts!r} s
 *   order           {m} ({kind})
 *   poles           {poles}
 *   gain direction  ({float(d[0])!r}, {float(d[1])!r}): L_i = k_i d / (d^T D_Dn)
 *   scalar type     {dtype}
 *
 * Sample loop, at every sample k and in this order (Ts = {model.Ts!r} s):
{loop}
 * Call {prefix}_init(&s, theta0, omega0, tau0) once before the first sample: it sets the
 * state a constant disturbance tau0 [N m] at rest in (theta0, omega0) would give.
 *
 * No dynamic memory, no I/O, no library calls: plain C99 arithmetic on {dtype}.
 */
#ifndef {up}_H
#define {up}_H

#ifdef __cplusplus
extern "C" {{
#endif

/** Scalar type of the observer. */
typedef {dtype} {prefix}_real;

/** Truncation order m of the observer (the state holds m + 1 values). */
#define {up}_ORDER {m}
/** Sampling period Ts [s] the observer was designed for. */
#define {up}_TS {ts}

/** Observer state: z[i-1] is the auxiliary variable z_i of docs/theory.md. */
typedef struct {{
    {dtype} z[{m + 1}];
}} {prefix}_state;

/** Reset to the state of a constant disturbance tau0 [N m] at rest in theta0, omega0. */
void {prefix}_init({prefix}_state *s, {dtype} theta0, {dtype} omega0, {dtype} tau0);

/** Disturbance estimate tau_hat_k [N m] from the measured theta_k [rad], omega_k [rad/s]. */
{dtype} {prefix}_estimate(const {prefix}_state *s, {dtype} theta, {dtype} omega);

/** Advance to sample k+1 with theta_k, omega_k and the torque u_k [N m] really applied. */
void {prefix}_update({prefix}_state *s, {dtype} theta, {dtype} omega, {dtype} u);

#ifdef __cplusplus
}}
#endif

#endif /* {up}_H */
"""


def _constants(design: ObserverDesign, dtype: str, code: str) -> list[str]:
    """Definitions of the constants ``code`` uses (an unused ``static const`` would warn)."""
    lines, zero = [], []
    for i in range(1, design.order + 2):
        row = i - 1
        kt, kw, ku = design._rows[row]
        for name, value, comment in (
            (f"K{i}", design._k[row], f"k_{i} = L_{i}^T D_Dn"),
            (f"L{i}_THETA", design.gains[row, 0], f"L_{i}, theta entry [N m/rad]"),
            (f"L{i}_OMEGA", design.gains[row, 1], f"L_{i}, omega entry [N m s/rad]"),
            (f"KX{i}_THETA", kt, f"(G A - M G)[{row}][0]"),
            (f"KX{i}_OMEGA", kw, f"(G A - M G)[{row}][1]"),
            (f"KU{i}", ku, f"(G B)[{row}]"),
        ):
            if float(value) == 0.0:
                zero.append(name)
            elif re.search(rf"\b{name}\b", code):
                literal = _literal(value, dtype, name)
                lines.append(f"static const {dtype} {name} = {literal}; /* {comment} */")
    if zero:
        lines.append(f"/* exactly zero, their terms are left out: {', '.join(zero)} */")
    return lines


def _init_body(design: ObserverDesign) -> list[str]:
    lines = []
    for i in range(1, design.order + 2):
        g = design.gains[i - 1]
        terms = [("+", "tau0")]
        terms += _product(f"L{i}_THETA", g[0], "theta0") + _product(f"L{i}_OMEGA", g[1], "omega0")
        lines.append(f"    s->z[{i - 1}] = {_sum(terms)};")
    return _unused(["theta0", "omega0"], "\n".join(lines)) + lines


def _estimate_body(design: ObserverDesign) -> list[str]:
    n, g = design.order + 1, design.gains[-1]
    terms = [("+", f"s->z[{n - 1}]")]
    terms += _product(f"L{n}_THETA", g[0], "theta", "-")
    terms += _product(f"L{n}_OMEGA", g[1], "omega", "-")
    line = f"    return {_sum(terms)};"
    return [*_unused(["theta", "omega"], line), line]


def _update_body(design: ObserverDesign, dtype: str) -> list[str]:
    n = design.order + 1
    z = [f"z{i}" for i in range(1, n + 1)]
    last = z[-1]
    reads = [f"    const {dtype} {z[i]} = s->z[{i}];" for i in range(n)]
    rows = []
    for i in range(1, n):  # rows 1..m: shift the disturbance history
        kt, kw, ku = design._rows[i - 1]
        terms = [("+", z[i]), *_product(f"K{i}", design._k[i - 1], last, "-")]
        terms += _product(f"KX{i}_THETA", kt, "theta") + _product(f"KX{i}_OMEGA", kw, "omega")
        terms += _product(f"KU{i}", ku, "u")
        rows.append(f"    s->z[{i - 1}] = {_sum(terms)};")
    kt, kw, ku = design._rows[-1]  # row m+1: extrapolate the newest disturbance
    terms = _product(f"K{n}", design._k[-1], last, "-")
    terms += _product(f"KX{n}_THETA", kt, "theta") + _product(f"KX{n}_OMEGA", kw, "omega")
    terms += _product(f"KU{n}", ku, "u")
    terms += [_weight_term(p, zi, dtype) for p, zi in zip(design._p, z, strict=True)]
    rows.append(f"    s->z[{n - 1}] = {_sum(terms)};")
    return reads + _unused(["theta", "omega", "u"], "\n".join(rows)) + rows


def _source(design: ObserverDesign, prefix: str, dtype: str) -> str:
    n = design.order + 1
    weights = " ".join(f"{p:+g}" for p in design._p)
    init = "\n".join(_init_body(design))
    est = "\n".join(_estimate_body(design))
    upd = "\n".join(_update_body(design, dtype))
    constants = "\n".join(_constants(design, dtype, init + est + upd))
    return f"""\
/*
 * {prefix}.c -- disturbance observer exported by hpdob {__version__}; see {prefix}.h for the
 * design and the sample loop. Generated file: re-export instead of editing it.
 *
 * Recursion (docs/theory.md, paper eqs. 11/13 for order 0, 20/21/23 for order 1):
 *   z_{{k+1}} = M z_k + (G A - M G) x_k + G B u_k,   tau_hat_k = z_{{m+1,k}} - L_{{m+1}}^T x_k,
 *   M = C - k e_{{m+1}}^T, C the companion matrix of (z - 1)^{n} (last row {weights}).
 * Every sum is evaluated left to right in the order of hpdob.update (terms whose constant
 * is exactly zero are left out), so a double build reproduces the Python observer bit for
 * bit when the compiler does not contract a*b + c into fused multiply-adds.
 * z_i of the paper is s->z[i-1] here.
 */
#include "{prefix}.h"

{constants}

void {prefix}_init({prefix}_state *s, {dtype} theta0, {dtype} omega0, {dtype} tau0)
{{
{init}
}}

{dtype} {prefix}_estimate(const {prefix}_state *s, {dtype} theta, {dtype} omega)
{{
{est}
}}

void {prefix}_update({prefix}_state *s, {dtype} theta, {dtype} omega, {dtype} u)
{{
{upd}
}}
"""


def render_c(obs, *, prefix: str = "dob", dtype: str = "double") -> tuple[str, str]:
    """Text of ``<prefix>.h`` and ``<prefix>.c`` for ``obs``; see :func:`export_c`."""
    design = as_design(obs, "obs")
    dtype = check_choice(dtype, "dtype", DTYPES)
    prefix = _check_prefix(prefix)
    return _header(design, prefix, dtype), _source(design, prefix, dtype)


def export_c(obs, directory, *, prefix: str = "dob", dtype: str = "double") -> tuple[Path, Path]:
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
    obs : DisturbanceObserver or ObserverDesign
        The observer to export; only its design is used (the C state starts from
        ``<prefix>_init``, not from the Python object's current state).
    directory : str or os.PathLike
        Output directory, created if missing; existing files of the same name are replaced.
    prefix : str, optional
        C identifier prefix of every exported name and of the file names, default ``"dob"``.
        Letters, digits and underscores, starting with a letter, at most 22 characters.
    dtype : {"double", "float"}, optional
        Scalar type of the generated code. ``"double"`` reproduces :func:`hpdob.update` bit
        for bit; ``"float"`` suits single-precision FPUs, within the error bound derived in
        ``docs/deployment.md``. Default ``"double"``.

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
        If ``dtype`` is not one of ``"double"``, ``"float"``, ``prefix`` is not a valid C
        identifier prefix, ``directory`` is an existing file, or a constant does not fit in
        binary32 for ``dtype="float"``. Nothing is written then.

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
    design = as_design(obs, "obs")
    dtype = check_choice(dtype, "dtype", DTYPES)
    prefix = _check_prefix(prefix)
    path = _check_directory(directory)
    header, source = _header(design, prefix, dtype), _source(design, prefix, dtype)
    path.mkdir(parents=True, exist_ok=True)
    written = (path / f"{prefix}.h", path / f"{prefix}.c")
    for target, text in zip(written, (header, source), strict=True):
        target.write_text(text, encoding="ascii")
    return written
