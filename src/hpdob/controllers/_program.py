"""The one definition of a controller's recurrence (:class:`ControllerProgram`) and the
Python code generated from it (:func:`compile_python`); see :mod:`hpdob.controllers._system`."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from .._validation import ParameterTypeError, ParameterValueError
from ..observers import Program, Term, render_sum

__all__ = ["RESET_OPERANDS", "ControllerProgram", "PythonController", "Switch", "compile_python"]

#: Operands of the reset rows (as for observers).
RESET_OPERANDS = ("theta0", "omega0", "tau0")


@dataclass(frozen=True)
class Switch:
    r"""The one nonlinear extension of a controller program: a latching switch of the command.

    At sample ``k``, with :math:`\ell_k` the latch state (0 or 1) and :math:`y` the signals:

    .. math::

        \text{on}_k = (\ell_k \ne 0) \lor (v_{\text{trigger},k} \ge \text{threshold}),\qquad
        u_k = \begin{cases} y_{\text{after},k} + \text{offset} & \text{on}_k \\
        y_{\text{last},k} & \text{otherwise,} \end{cases}\qquad
        \ell_{k+1} = \text{on}_k.

    The signal rows, the other states' updates and the matrices are those of the program
    without the switch: the linear controller *before* the switch (the analysis views see that
    mode). The generated Python (:func:`compile_python`) and the compiled kernel evaluate this
    rule after the signal rows, the same comparisons and the same one addition.

    Attributes
    ----------
    trigger : int
        Operand index of the input that trips the switch (``n <= trigger < n + p``).
    threshold : float
        The switch trips at ``input >= threshold``.
    latch : int
        Index of the latch state (its update row is empty: 0 in the linear view).
    after : int
        Index of the signal that is the command once switched.
    offset : float
        Constant added to that signal [N m] (a setpoint the rows cannot hold: they have no
        constant operand).
    """

    trigger: int
    threshold: float
    latch: int
    after: int
    offset: float = 0.0


@dataclass(frozen=True)
class ControllerProgram:
    """Evaluation order of a controller: signal rows, update rows and reset rows.

    Operands are indexed ``[c_0..c_{n-1}, v_0..v_{p-1}, u_bar, y_0..y_{q-1}]``: the state, the
    inputs, the limited command and the signals. Each row is a tuple of
    :class:`~hpdob.observers.Term`, summed left to right (0 when empty).

    Attributes
    ----------
    signals : tuple of rows
        Signal ``j`` from the state, the inputs and the signals ``< j`` (never ``u_bar``);
        the last one is the command :math:`u_k` [N m].
    update : tuple of rows
        Row ``i`` gives :math:`c_{i,k+1}` from every operand.
    reset : tuple of rows
        Row ``i`` gives :math:`c_{i,0}` from ``[theta0, omega0, tau0]``.
    signal_names : tuple of str
        A name per signal (for generated code), the last ``"u"``.
    constants : tuple of (name, description)
        Descriptions of named constants (for comments in generated code).
    state_names : tuple of str
        Names of the states (for generated code); default ``c1, c2, ...``.
    switch : Switch or None
        A latching switch of the command (:class:`Switch`); None for a linear controller.
    """

    signals: tuple
    update: tuple
    reset: tuple
    signal_names: tuple
    constants: tuple = ()
    state_names: tuple = ()
    switch: Switch | None = None

    @classmethod
    def from_matrices(cls, F, G, H, E, N) -> ControllerProgram:
        """The default program: one signal (the command), the non-zero entries in column order.

        Parameters
        ----------
        F, G, H, E, N : ndarray
            The matrices of a :class:`LinearController`.

        Returns
        -------
        ControllerProgram

        Examples
        --------
        >>> import numpy as np
        >>> from hpdob.controllers import ControllerProgram
        >>> F, G = np.zeros((0, 0)), np.zeros((0, 3))            # u = 2 r - 2 theta
        >>> H, E, N = np.zeros((1, 0)), np.array([[2.0, -2.0]]), np.zeros((0, 3))
        >>> program = ControllerProgram.from_matrices(F, G, H, E, N)
        >>> [(t.coefficient, t.operand) for t in program.signals[0]]
        [(2.0, 0), (-2.0, 1)]
        """

        def row(values, prefix):
            return tuple(
                Term(float(c), j, None if abs(c) == 1.0 else f"{prefix}{j + 1}")
                for j, c in enumerate(values)
                if c != 0.0
            )

        n = np.asarray(F).shape[0]
        update = tuple(row(np.concatenate([F[i], G[i]]), f"CF{i + 1}_") for i in range(n))
        signals = (row(np.concatenate([H[0], E[0]]), "CH1_"),)
        reset = tuple(row(N[i], f"CN{i + 1}_") for i in range(n))
        return cls(signals=signals, update=update, reset=reset, signal_names=("u",))

    def arrays(self):
        """The program as flat arrays (what the compiled kernel reads).

        Returns
        -------
        tuple
            ``(signals, update, reset)``, each ``(pointer, coefficient, operand)`` (int64,
            float64, int64): the terms of row ``i`` are ``pointer[i]:pointer[i+1]``.
        """
        return tuple(
            Program(update=rows, output=(), reset=()).arrays()[0]
            for rows in (self.signals, self.update, self.reset)
        )

    def matrices(self, n: int, p: int):
        """The dense ``(F, G, H, E, N)`` the rows amount to after substituting the signals.

        Parameters
        ----------
        n, p : int
            States and inputs.

        Returns
        -------
        matrices : tuple of ndarray
            ``(F, G, H, E, N)``.
        sizes : tuple of ndarray
            The sums of the terms' magnitudes behind each entry of ``[F G]`` and of
            ``[H E]`` (the rounding tolerance of the check of given matrices).

        Raises
        ------
        ParameterTypeError, ParameterValueError
            For a row that is not made of Terms or uses an operand it may not.
        """
        width = n + p + 1  # [c, v, u_bar]
        q = len(self.signals)
        values = np.zeros((q, width))
        sizes = np.zeros((q, width))

        def expand(terms, label, allow_bar, upto):
            total, size = np.zeros(width), np.zeros(width)
            for t in terms:
                if not isinstance(t, Term):
                    raise ParameterTypeError(f"{label} must hold Terms, got {t!r}")
                j = t.operand
                if 0 <= j < n + p or (allow_bar and j == n + p):
                    total[j] += t.coefficient
                    size[j] += abs(t.coefficient)
                elif n + p + 1 <= j < n + p + 1 + upto:
                    total += t.coefficient * values[j - n - p - 1]
                    size += abs(t.coefficient) * sizes[j - n - p - 1]
                else:
                    what = "the signals before it" if not allow_bar else "u_bar and the signals"
                    raise ParameterValueError(
                        f"{label} may use the state, the inputs and {what} (operands "
                        f"0..{n + p - 1 + (1 if allow_bar else 0)} and signals), got "
                        f"operand {j}"
                    )
            return total, size

        for j, terms in enumerate(self.signals):
            values[j], sizes[j] = expand(terms, f"program.signals[{j}]", False, j)
        F, G = np.zeros((n, n)), np.zeros((n, p + 1))
        size_update = np.zeros((n, width))
        for i, terms in enumerate(self.update):
            total, size_update[i] = expand(terms, f"program.update[{i}]", True, q)
            F[i], G[i] = total[:n], total[n:]
        H, E = values[-1:, :n], values[-1:, n : n + p]
        N = np.zeros((n, 3))
        for i, terms in enumerate(self.reset):
            for t in terms:
                if not isinstance(t, Term) or not 0 <= t.operand < 3:
                    raise ParameterValueError(
                        f"program.reset[{i}] must hold Terms with operands 0..2, got {t!r}"
                    )
                N[i, t.operand] += t.coefficient
        return (F, G, H, E, N), (size_update, sizes[-1])


def _py_literal(value: float) -> str:
    text = repr(float(value))
    return f"({text})" if text.startswith("-") else text


@functools.lru_cache(maxsize=256)
def _compiled(source: str):
    return compile(source, "<hpdob controller program>", "exec")


class PythonController(tuple):
    """``(reset, signals, command, update)`` generated from a controller's program."""

    __slots__ = ()

    @property
    def reset(self):
        """``reset(theta0, omega0, tau0) -> c``."""
        return self[0]

    @property
    def signals(self):
        """``signals(c, *inputs) -> (y_0, ..., u)``."""
        return self[1]

    @property
    def command(self):
        """``command(c, *inputs) -> u``."""
        return self[2]

    @property
    def update(self):
        """``update(c, *inputs, u_bar) -> c_next``."""
        return self[3]


def compile_python(controller) -> PythonController:
    """Python functions generated from ``controller.program`` (plain floats and tuples).

    Parameters
    ----------
    controller : LinearController

    Returns
    -------
    PythonController
        ``reset(theta0, omega0, tau0) -> c``, ``signals(c, *inputs) -> (y_0, ..., u)``,
        ``command(c, *inputs) -> u`` and ``update(c, *inputs, u_bar) -> c_next``, each
        evaluating the rows in the program's order (as the compiled kernel and exported C).
    """
    program = controller.program
    n, p = controller.n_states, len(controller.inputs)
    state = [f"c{i}" for i in range(n)]
    inputs = [f"v{j}" for j in range(p)]
    signals = [f"y{j}" for j in range(len(program.signals))]
    operands = [*state, *inputs, "u_bar", *signals]
    unpack = f"    ({', '.join(state)},) = c\n" if n else ""
    body = "".join(
        f"    {y} = {_render(terms, operands)}\n"
        for y, terms in zip(signals, program.signals, strict=True)
    )
    args = "".join(f", {v}" for v in inputs)
    reset = [_render(r, RESET_OPERANDS) for r in program.reset]
    update = [_render(r, operands) for r in program.update]
    command = signals[-1]
    switch = program.switch
    if switch is not None:  # Switch's rule, after the signal rows (as in the kernel)
        body += (
            f"    on = {state[switch.latch]} != 0.0 or {operands[switch.trigger]} >= "
            f"{_py_literal(switch.threshold)}\n"
        )
        command = f"({signals[switch.after]} + {_py_literal(switch.offset)}) if on else {command}"
        update[switch.latch] = "(1.0 if on else 0.0)"
    source = [
        f"def reset(theta0, omega0, tau0):\n    return ({''.join(x + ', ' for x in reset)})\n",
        f"def signals(c{args}):\n{unpack}{body}    return ({', '.join(signals)},)\n",
        f"def command(c{args}):\n{unpack}{body}    return {command}\n",
        f"def update(c{args}, u_bar):\n{unpack}{body}"
        f"    return ({''.join(x + ', ' for x in update)})\n",
    ]
    namespace: dict = {}
    exec(_compiled("\n".join(source)), namespace)  # generated above from floats
    return PythonController(namespace[k] for k in ("reset", "signals", "command", "update"))


def _render(terms, operands) -> str:
    return render_sum(terms, operands, _py_literal, named=False)
