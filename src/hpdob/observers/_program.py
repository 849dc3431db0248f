r"""The one definition of an observer's recurrence, and the code generated from it.

A :class:`Program` lists, for each row of ``[F G]``, ``[H E]`` and ``N`` of a
:class:`~hpdob.LinearObserver`, the ordered terms ``coefficient * operand`` whose left-to-right
sum is that row. Python code is generated from it (:func:`compile_python`), the numba kernel
interprets its arrays (:meth:`Program.arrays`) and the C exporter prints it
(:func:`render_sum`), so the three forms evaluate the same sums in the same order and agree bit
for bit.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .._validation import ParameterTypeError, ParameterValueError

__all__ = [
    "RESET_OPERANDS",
    "Program",
    "Term",
    "check_program",
    "compile_python",
    "program_coefficients",
    "program_structure",
    "render_sum",
    "structured_program",
]

#: Operands of the reset rows: :math:`s_0 = N [\theta_0, \omega_0, \tau_0]`.
RESET_OPERANDS = ("theta0", "omega0", "tau0")
_EPS = np.finfo(float).eps


class Term(NamedTuple):
    """One term ``coefficient * operand`` of a :class:`Program` row.

    Attributes
    ----------
    coefficient : float
        The signed factor.
    operand : int
        Index into the row's operand vector: ``[s_0..s_{n-1}, v_0..v_p]`` for update and output
        rows, ``[theta0, omega0, tau0]`` for reset rows.
    constant : str or None
        Name of the constant in generated C (``None``: the value is written inline).
    negated : bool
        Generated code writes ``- constant * operand`` with ``constant = -coefficient``
        (e.g. ``- K1 * z2`` with ``K1 = k_1``). Only the printed form differs:
        ``a - c*x`` and ``a + (-c)*x`` round identically.
    """

    coefficient: float
    operand: int
    constant: str | None = None
    negated: bool = False

    @property
    def value(self) -> float:
        """The constant as written in generated code (``-coefficient`` when negated)."""
        return -self.coefficient if self.negated else self.coefficient


@dataclass(frozen=True)
class Program:
    """Evaluation order of an observer's recurrence: the one definition every form runs.

    Each row is a tuple of :class:`Term`; a row's value is the left-to-right sum of its terms
    (0 for an empty row).

    Attributes
    ----------
    update : tuple of rows
        Row ``i`` gives :math:`s_{i,k+1}` from ``[s_k, v_k]``.
    output : tuple of rows
        Row ``j`` gives :math:`y_{j,k}` from ``[s_k, v_k]`` (never from ``u_k``).
    reset : tuple of rows
        Row ``i`` gives :math:`s_{i,0}` from ``[theta0, omega0, tau0]``.
    constants : tuple of (name, description)
        Descriptions of named constants, for comments in generated code.
    zero_constants : tuple of str
        Names of constants that are exactly zero and whose terms are therefore left out
        (recorded for generated code).
    """

    update: tuple
    output: tuple
    reset: tuple
    constants: tuple = ()
    zero_constants: tuple = ()

    @classmethod
    def from_matrices(cls, F, G, H, E, N, measures) -> Program:
        """The default program: the non-zero entries of each row in column order.

        Constants are named after their matrix entry (``F1_2``, ``G1_THETA``, ``H1_2``,
        ``E1_OMEGA``, ``N1_TAU0``, 1-based); coefficients of magnitude one are written inline.

        Parameters
        ----------
        F, G, H, E, N : ndarray
            The matrices of a :class:`~hpdob.LinearObserver`: shapes ``(n, n)``,
            ``(n, p + 1)``, ``(q, n)``, ``(q, p)`` and ``(n, 3)`` for ``n`` states, ``p``
            measured signals and ``q`` outputs.
        measures : sequence of str
            The measured signals, ``("theta", "omega")`` or ``("theta",)``: they name the
            columns of ``G`` and ``E`` (the last column of ``G`` is ``u``).

        Returns
        -------
        Program

        Examples
        --------
        >>> import numpy as np
        >>> from hpdob.observers import Program
        >>> F, G = np.array([[0.9]]), np.array([[0.1, 0.0, 0.5]])   # z' = 0.9 z + 0.1 th + 0.5 u
        >>> H, E, N = np.array([[1.0]]), np.array([[-0.3, 0.0]]), np.array([[0.0, 0.0, 1.0]])
        >>> program = Program.from_matrices(F, G, H, E, N, ("theta", "omega"))
        >>> [(t.coefficient, t.operand, t.constant) for t in program.update[0]]
        [(0.9, 0, 'F1_1'), (0.1, 1, 'G1_THETA'), (0.5, 3, 'G1_U')]
        """
        n = F.shape[0]
        inputs = [*(m.upper() for m in measures), "U"]

        def row(values, label):
            terms = []
            for j, c in enumerate(values):
                c = float(c)
                if c != 0.0:
                    terms.append(Term(c, j, None if abs(c) == 1.0 else label(j)))
            return tuple(terms)

        def label(state, data, i):
            return lambda j: (
                f"{state}{i + 1}_{j + 1}" if j < n else f"{data}{i + 1}_{inputs[j - n]}"
            )

        update = tuple(row(np.concatenate([F[i], G[i]]), label("F", "G", i)) for i in range(n))
        output = tuple(
            row(np.concatenate([H[r], E[r]]), label("H", "E", r)) for r in range(H.shape[0])
        )
        reset = tuple(
            row(N[i], lambda j, i=i: f"N{i + 1}_{RESET_OPERANDS[j].upper()}") for i in range(n)
        )
        return cls(update=update, output=output, reset=reset)

    def arrays(self):
        """The program as flat arrays (what the numba kernel reads).

        Returns
        -------
        tuple
            ``(update, output, reset)``, each a tuple ``(pointer, coefficient, operand)`` of
            arrays (int64, float64, int64): the terms of row ``i`` are
            ``pointer[i]:pointer[i+1]``.
        """

        def flat(rows):
            pointer = np.zeros(len(rows) + 1, dtype=np.int64)
            coefficient, operand = [], []
            for i, terms in enumerate(rows):
                pointer[i + 1] = pointer[i] + len(terms)
                coefficient += [t.coefficient for t in terms]
                operand += [t.operand for t in terms]
            return (
                pointer,
                np.array(coefficient, dtype=np.float64).reshape(-1),
                np.array(operand, dtype=np.int64).reshape(-1),
            )

        return flat(self.update), flat(self.output), flat(self.reset)

    def constant_table(self) -> dict:
        """The named constants of the program, as generated C declares them.

        Returns
        -------
        dict
            ``{name: (value, description)}``; ``value`` as written (``-coefficient`` for a
            negated term), ``description`` from :attr:`constants` or ``""``.

        Raises
        ------
        ParameterValueError
            If one name carries two different values.
        """
        notes = dict(self.constants)
        table: dict = {}
        for rows in (self.update, self.output, self.reset):
            for terms in rows:
                for t in terms:
                    if t.constant is None:
                        continue
                    if t.constant in table and table[t.constant][0] != t.value:
                        raise ParameterValueError(
                            f"program constant {t.constant} has two values, "
                            f"{table[t.constant][0]!r} and {t.value!r}"
                        )
                    table[t.constant] = (t.value, notes.get(t.constant, ""))
        return table


def check_program(program: Program, dense: dict, n: int, p: int, q: int) -> None:
    """Raise unless ``program`` computes the dense matrices (each entry to rounding)."""
    if not isinstance(program, Program):
        raise ParameterTypeError(f"program must be a Program or None, got {type(program).__name__}")
    for part, rows, width, matrix in (
        ("update", program.update, n + p + 1, dense["update"]),
        ("output", program.output, n + p + 1, dense["output"]),
        ("reset", program.reset, 3, dense["reset"]),
    ):
        if len(rows) != matrix.shape[0]:
            raise ParameterValueError(
                f"program.{part} must have {matrix.shape[0]} rows, got {len(rows)}"
            )
        for i, terms in enumerate(rows):
            total = np.zeros(width)
            size = np.zeros(width)
            for t in terms:
                if not isinstance(t, Term) or not 0 <= t.operand < width:
                    raise ParameterValueError(
                        f"program.{part}[{i}] must hold Terms with operands in 0..{width - 1}, "
                        f"got {t!r}"
                    )
                total[t.operand] += t.coefficient
                size[t.operand] += abs(t.coefficient)
            if not np.all(np.abs(total - matrix[i]) <= 4 * _EPS * size):
                j = int(np.argmax(np.abs(total - matrix[i]) - 4 * _EPS * size))
                raise ParameterValueError(
                    f"program.{part}[{i}] sums to {total[j]!r} for operand {j} but the "
                    f"matrix entry is {matrix[i, j]!r}"
                )


def render_sum(terms, operands, literal, *, named=True) -> str:
    """A row of ``terms`` as an expression in ``operands`` (names), summed left to right.

    ``literal(value)`` prints an inline constant. With ``named``, a term's ``constant`` name is
    printed instead of its value (negated terms as ``- NAME * x``). Inline coefficients of
    magnitude one are left out (``+ x``, ``- x``), which is exact, and a negative inline
    coefficient is written ``- |c| * x``: ``a - |c|*x`` rounds exactly like ``a + c*x``.
    """
    if not terms:
        return literal(0.0)
    parts = []
    for t in terms:
        x = operands[t.operand]
        if named and t.constant is not None:
            parts.append(("-" if t.negated else "+", f"{t.constant} * {x}"))
            continue
        value = t.value if t.negated else t.coefficient
        sign = "-" if t.negated else "+"
        if value < 0:
            sign, value = ("+" if t.negated else "-"), -value
        parts.append((sign, x if value == 1.0 else f"{literal(value)} * {x}"))
    first_sign, first = parts[0]
    text = ("-" if first_sign == "-" else "") + first
    for sign, part in parts[1:]:
        text += f" {sign} {part}"
    return text


def _shape(rows) -> tuple:
    """The structure of ``rows``: per term its operand and whether it is written without a
    factor (coefficient +1 or -1, as ``+ x``/``- x``); ``(operand, 0)`` for a factor."""
    return tuple(
        tuple((t.operand, 1 if t.coefficient == 1.0 else -1 if t.coefficient == -1.0 else 0)
              for t in terms)
        for terms in rows
    )  # fmt: skip


def program_structure(program: Program) -> tuple:
    """What generated code depends on, apart from the coefficients' values: for the update,
    output and reset rows, each term's operand and whether it is a unit term.

    Two programs with the same structure run the same generated function with different
    coefficients (:func:`program_coefficients`), so the code is generated and compiled once per
    structure, not once per design (a sweep designs one observer per scenario).
    """
    return (_shape(program.update), _shape(program.output), _shape(program.reset))


def program_coefficients(program: Program) -> tuple:
    """The coefficients of the non-unit terms, in the order of :func:`program_structure`."""
    return tuple(
        t.coefficient
        for rows in (program.update, program.output, program.reset)
        for terms in rows
        for t in terms
        if abs(t.coefficient) != 1.0
    )


def _sum_source(shape, operands, names) -> str:
    """A row of ``shape`` summed left to right: ``c * x`` with the coefficient's variable (the
    signed coefficient), ``x`` or ``- x`` for a unit term (exact: ``a - x`` rounds like
    ``a + (-1.0) * x``), ``0.0`` for an empty row."""
    if not shape:
        return "0.0"
    text = ""
    for operand, unit in shape:
        x = operands[operand]
        if unit:
            part, sign = x, "+" if unit > 0 else "-"
        else:
            part, sign = f"{next(names)} * {x}", "+"
        text += ("-" if sign == "-" else "") + part if not text else f" {sign} {part}"
    return text


@functools.lru_cache(maxsize=64)
def _python_factory(structure: tuple, n: int, p: int):
    """``make(*coefficients) -> (reset, outputs, estimate, update)``, generated and compiled
    once per program structure; the coefficients become the functions' closure variables."""
    update, output, reset = structure
    names = iter(f"c{i}" for i in range(10_000))
    state = [f"s{i}" for i in range(n)]
    inputs = [f"v{j}" for j in range(p)]
    operands = [*state, *inputs, "u"]
    update_rows = [_sum_source(r, operands, names) for r in update]
    output_rows = [_sum_source(r, operands, names) for r in output]
    reset_rows = [_sum_source(r, RESET_OPERANDS, names) for r in reset]
    used = [f"c{i}" for i in range(sum(1 for rows in structure for r in rows for _, u in r
                                       if not u))]  # fmt: skip
    unpack = f"        ({', '.join(state)},) = s\n"
    # update's rows, then None where they overflow: t - t is 0.0 exactly when t is finite, and
    # the left-to-right sum t is finite exactly when sum() of the state is (no call per sample)
    fresh = [f"n{i}" for i in range(n)]
    checked = "".join(
        f"        {name} = {row}\n" for name, row in zip(fresh, update_rows, strict=True)
    )
    checked += f"        t = {' + '.join(fresh)}\n"
    checked += "        if t - t != 0.0:\n            return None\n"
    checked += f"        return ({', '.join(fresh)},)\n"
    args = ", ".join(inputs)
    source = (
        f"def make({', '.join(used)}):\n"
        f"    def reset(theta0, omega0, tau0):\n        return ({', '.join(reset_rows)},)\n"
        f"    def outputs(s, {args}):\n{unpack}        return ({', '.join(output_rows)},)\n"
        f"    def estimate(s, {args}):\n{unpack}        return {output_rows[0]}\n"
        f"    def update(s, {args}, u):\n{unpack}        return ({', '.join(update_rows)},)\n"
        f"    def checked_update(s, {args}, u):\n{unpack}{checked}"
        "    return reset, outputs, estimate, update, checked_update\n"
    )
    namespace: dict = {}
    exec(compile(source, "<hpdob observer program>", "exec"), namespace)  # generated above
    return namespace["make"]


def compile_python(system):
    """Python functions generated from ``system.program`` (no numpy; tuples of floats).

    Returns ``(reset, outputs, estimate, update)`` with ``reset(theta0, omega0, tau0) -> s``,
    ``outputs(s, *measures) -> y``, ``estimate(s, *measures) -> tau_hat`` and
    ``update(s, *measures, u) -> s_next``; each evaluates its rows exactly as the program
    orders them (the numba kernel and exported C do the same). The code is generated once per
    program structure (:func:`program_structure`); the coefficients are bound per observer.
    """
    return _python_functions(system)[:4]


def compile_checked_update(system):
    """``update`` of :func:`compile_python` that returns None instead of a state that is not
    finite (the runtime observer's per-sample path refuses such a step)."""
    return _python_functions(system)[4]


def _python_functions(system):
    program = system.program
    make = _python_factory(program_structure(program), system.n_states, len(system.measures))
    return make(*program_coefficients(program))


def structured_program(k, G, Kx, Ku, p) -> Program:
    r"""The order-m observer's recurrence in companion form, term by term (``docs/theory.md``).

    With ``z`` the auxiliary variables (state), ``x = (theta, omega)`` and ``n = m + 1``:

    - rows ``i < m``: :math:`z_{i+1} - k_i z_n + K_{x,i} x + K_{u,i} u` (the shift of the
      disturbance history, eqs. 16 and 20 for the HPDOb);
    - row ``n``: :math:`-k_n z_n + K_{x,n} x + K_{u,n} u + \sum_j p_j z_j` (the degree-m
      extrapolation, eqs. 19 and 21), with the integer weights :math:`p_j` exact;
    - the estimate :math:`z_n - L_n^T x` (eqs. 13, 23); the reset :math:`\tau_0 + L_i^T x_0`.

    Keeping :math:`1` and :math:`p_j` apart from :math:`k_i` (instead of the rounded entries of
    ``M``) means every executable form runs exactly the polynomial the synthesis certified.
    Terms whose constant is exactly zero are left out.
    """
    n = len(k)
    last = n - 1
    theta, omega, u = n, n + 1, n + 2

    zero = []

    def product(value, operand, name, *, negated=False):
        value = float(value)
        if value == 0.0:
            if name not in zero:
                zero.append(name)
            return []
        return [Term(-value if negated else value, operand, name, negated)]

    def inputs(i):
        return (
            product(Kx[i, 0], theta, f"KX{i + 1}_THETA")
            + product(Kx[i, 1], omega, f"KX{i + 1}_OMEGA")
            + product(Ku[i], u, f"KU{i + 1}")
        )

    update = []
    for i in range(n - 1):
        terms = [Term(1.0, i + 1), *product(k[i], last, f"K{i + 1}", negated=True), *inputs(i)]
        update.append(tuple(terms))
    terms = [*product(k[last], last, f"K{n}", negated=True), *inputs(last)]
    terms += [Term(float(w), j) for j, w in enumerate(p)]
    update.append(tuple(terms))
    output = (
        (
            Term(1.0, last),
            *product(G[last, 0], theta, f"L{n}_THETA", negated=True),
            *product(G[last, 1], omega, f"L{n}_OMEGA", negated=True),
        ),
    )
    reset = tuple(
        (
            Term(1.0, 2),
            *product(G[i, 0], 0, f"L{i + 1}_THETA"),
            *product(G[i, 1], 1, f"L{i + 1}_OMEGA"),
        )
        for i in range(n)
    )
    constants = []
    for i in range(1, n + 1):
        constants += [
            (f"K{i}", f"k_{i} = L_{i}^T D_Dn"),
            (f"L{i}_THETA", f"L_{i}, theta entry [N m/rad]"),
            (f"L{i}_OMEGA", f"L_{i}, omega entry [N m s/rad]"),
            (f"KX{i}_THETA", f"(G A - M G)[{i - 1}][0]"),
            (f"KX{i}_OMEGA", f"(G A - M G)[{i - 1}][1]"),
            (f"KU{i}", f"(G B)[{i - 1}]"),
        ]
    return Program(
        update=tuple(update),
        output=output,
        reset=reset,
        constants=tuple(constants),
        zero_constants=tuple(sorted(zero, key=[name for name, _ in constants].index)),
    )
