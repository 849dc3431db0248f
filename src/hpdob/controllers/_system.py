r"""The controller protocol: every controller is a linear discrete-time system.

At sample ``k`` a controller reads its named inputs :math:`v_k` -- the reference, the
measurement and observer outputs, wired by the loop (:data:`LOOP_SIGNALS`) -- and returns the
torque command :math:`u_k`; after the loop has limited it to :math:`\bar u_k` (the actuator's
torque limit) the controller updates its state with it:

.. math::

    u_k = H c_k + E v_k, \qquad c_{k+1} = F c_k + G [v_k, \bar u_k], \qquad
    c_0 = N\,[\theta_0, \omega_0, \tau_0]^T.

Passing :math:`\bar u_k` back is what an anti-windup scheme needs (PID's back-calculation uses
:math:`\bar u_k - u_k`); in the linear analysis views :math:`\bar u_k = u_k`.
:class:`LinearController` holds the matrices and the :class:`ControllerProgram`, the one
definition that the generated Python (:func:`compile_python`), the compiled kernel
(:meth:`ControllerProgram.arrays`) and exported C evaluate in the same order.

A program is a straight-line code: **signal rows**, evaluated in order, each the
left-to-right sum of ``coefficient * operand`` over the state, the inputs and the signals
before it; the **last signal is the command** :math:`u_k`. The update rows may also read
:math:`\bar u_k` and every signal. This is how the PD keeps its form
:math:`u = J_n (k_p (r - \theta) + k_d (\dot r - \omega) + \ddot r) + \hat\tau` term for term
(so its runs are bit for bit those of the hand-written loop before the protocol); the dense
matrices are what the signals amount to after substitution.
"""

from __future__ import annotations

import functools
import keyword
import re
from dataclasses import dataclass, field

import numpy as np

from .._validation import (
    ParameterTypeError,
    ParameterValueError,
    _show,
    numeric_array,
    positive,
    shaped_matrix,
)
from ..observers import Term
from ._program import RESET_OPERANDS, ControllerProgram, Switch, compile_python

__all__ = ["LOOP_SIGNALS", "LinearController", "ProgramBuilder"]

#: The inputs the loop provides to every controller, in this order: the reference and its
#: derivatives [rad, rad/s, rad/s^2] and the measurement (the sensor's angle [rad] and
#: velocity [rad/s], the latter a backward difference with an encoder). Any other input name
#: is an **observer output** of the same name, wired by the loop: ``tau_hat`` [N m] (0 without
#: an observer), ``omega_hat`` [rad/s] (position-only observers), and whatever outputs future
#: observers add (e.g. a reaction-torque estimate ``tau_reac`` for force control).
LOOP_SIGNALS = ("r", "r_dot", "r_ddot", "theta", "omega")
_NAME = re.compile(r"[a-z][a-z0-9_]*\Z")
_EPS = np.finfo(float).eps


@dataclass(frozen=True, eq=False)
class LinearController:
    r"""A controller as a linear discrete-time system: the protocol every controller implements.

    .. math::

        u_k = H c_k + E v_k,\qquad c_{k+1} = F c_k + G\,[v_k, \bar u_k],\qquad
        c_0 = N\,[\theta_0,\ \omega_0,\ \tau_0]^T,

    with :math:`v_k` the named ``inputs`` (:data:`LOOP_SIGNALS` or observer outputs) and
    :math:`\bar u_k` the command after the loop's torque limit. All arrays are read-only.

    Parameters
    ----------
    F : array_like, shape (n, n)
        State matrix (``n = 0``: a static controller such as the PD).
    G : array_like, shape (n, p + 1)
        Input matrix; columns follow ``inputs`` then :math:`\bar u` [N m].
    H : array_like, shape (1, n)
        Output matrix of the command [N m].
    E : array_like, shape (1, p)
        Feed-through of the inputs into the command.
    N : array_like, shape (n, 3)
        Reset matrix: the state at the start of a run at :math:`(\theta_0, \omega_0)` with a
        constant disturbance :math:`\tau_0`.
    Ts : float
        Sampling period [s].
    inputs : tuple of str
        The ``p`` input names, distinct lower-case identifiers: :data:`LOOP_SIGNALS` and
        observer outputs (``tau_hat``, ``omega_hat``, ...); the loop checks it can wire them.
    name : str, optional
        Short description (messages, generated code).
    program : ControllerProgram, optional
        Evaluation order; default :meth:`ControllerProgram.from_matrices`. A given program
        must amount to the matrices (each entry to rounding).
    info : tuple of (str, str), optional
        Design summary lines for headers of generated code.

    Raises
    ------
    TypeError, ValueError
        Naming the argument: shapes, non-finite entries, input names, a program that does not
        match the matrices.

    Examples
    --------
    A proportional controller on the angle, written from scratch:

    >>> from hpdob.controllers import LinearController
    >>> p = LinearController(F=[], G=[], H=[], E=[[0.02, -0.02]], N=[], Ts=1e-3,
    ...                      inputs=("r", "theta"))
    >>> p.python.command((), 1.0, 0.5)   # 0.02 (r - theta) [N m]
    0.01
    """

    F: np.ndarray
    G: np.ndarray
    H: np.ndarray
    E: np.ndarray
    N: np.ndarray
    Ts: float
    inputs: tuple
    name: str = "controller"
    program: ControllerProgram | None = field(default=None, repr=False)
    info: tuple = field(default=(), repr=False)

    def __post_init__(self) -> None:
        inputs = self.inputs
        if not isinstance(inputs, (tuple, list)) or not all(isinstance(i, str) for i in inputs):
            raise ParameterTypeError(f"inputs must be a tuple of str, got {inputs!r}")
        inputs = tuple(inputs)
        bad = [i for i in inputs if not _NAME.match(i) or keyword.iskeyword(i) or i == "u_bar"]
        if bad or len(set(inputs)) != len(inputs):
            raise ParameterValueError(
                "inputs must be distinct lower-case identifiers (e.g. 'r', 'theta', 'tau_hat'), "
                f"got {inputs!r}"
            )
        F = numeric_array(self.F, "F", "a square real matrix", dtype=float)
        n = F.shape[0] if F.ndim == 2 else 0
        if F.size and (F.ndim != 2 or F.shape[0] != F.shape[1]):
            raise ParameterValueError(f"F must be a square matrix, got shape {F.shape}")
        p = len(inputs)
        F = shaped_matrix(F, "F", (n, n), empty=True)
        G = shaped_matrix(self.G, "G", (n, p + 1), empty=True)
        H = shaped_matrix(self.H, "H", (1, n), empty=True)
        E = shaped_matrix(self.E, "E", (1, p), empty=True)
        N = shaped_matrix(self.N, "N", (n, 3), empty=True)
        Ts = positive(self.Ts, "Ts", "a positive finite sampling period [s]")
        if not isinstance(self.name, str):
            raise ParameterTypeError(f"name must be a str, got {type(self.name).__name__}")
        program = self.program
        if program is None:
            program = ControllerProgram.from_matrices(F, G, H, E, N)
        elif not isinstance(program, ControllerProgram):
            raise ParameterTypeError(
                f"program must be a ControllerProgram or None, got {type(program).__name__}"
            )
        _check_program(program, (F, G, H, E, N), n, p)
        object.__setattr__(self, "inputs", inputs)
        for name, value in (("F", F), ("G", G), ("H", H), ("E", E), ("N", N)):
            object.__setattr__(self, name, value)
        object.__setattr__(self, "Ts", Ts)
        object.__setattr__(self, "program", program)
        object.__setattr__(self, "info", tuple(self.info))

    @classmethod
    def from_program(cls, program: ControllerProgram, *, Ts: float, inputs, n_states: int,
                     **options) -> LinearController:  # fmt: skip
        """The controller whose matrices are what ``program`` computes.

        Parameters
        ----------
        program : ControllerProgram
            The rows.
        Ts : float
            Sampling period [s].
        inputs : tuple of str
            The input names.
        n_states : int
            Number of states ``n``.
        **options
            ``name`` and ``info``.

        Returns
        -------
        LinearController
        """
        F, G, H, E, N = program.matrices(n_states, len(inputs))[0]
        return cls(F=F, G=G, H=H, E=E, N=N, Ts=Ts, inputs=tuple(inputs), program=program,
                   **options)  # fmt: skip

    @property
    def n_states(self) -> int:
        """Number of states ``n``."""
        return self.F.shape[0]

    def design(self, nominal, Ts: float) -> LinearController:
        """The controller itself, checked to run at ``Ts`` (the :class:`Controller` method).

        Parameters
        ----------
        nominal : ServoModel
            The loop's nominal model (unused: the coefficients are fixed).
        Ts : float
            The loop's sampling period [s].

        Returns
        -------
        LinearController

        Raises
        ------
        ParameterValueError
            If ``Ts`` is not this controller's.
        """
        if Ts != self.Ts:
            raise ParameterValueError(
                f"controller must run at the loop's sampling period: its Ts={self.Ts} but the "
                f"loop has Ts={Ts}"
            )
        return self

    @functools.cached_property
    def python(self):
        """Generated Python functions (see :func:`compile_python`)."""
        return compile_python(self)

    @functools.cached_property
    def kernel_arrays(self):
        """The program as arrays for the compiled kernel (:meth:`ControllerProgram.arrays`)."""
        return self.program.arrays()

    def to_statespace(self):
        r"""The controller as a discrete python-control ``StateSpace`` (``dt = Ts``), with
        :math:`\bar u = u` (no limit): ``A = F + G_{\bar u} H``, ``B = G_v + G_{\bar u} E``.

        Returns
        -------
        control.StateSpace
            Inputs ``inputs``, output ``u``.
        """
        import control

        p = len(self.inputs)
        Gv, Gu = self.G[:, :p], self.G[:, p:]
        n = self.n_states
        A = self.F + Gu @ self.H if n else np.zeros((0, 0))
        B = Gv + Gu @ self.E if n else np.zeros((0, p))
        return control.ss(A, B, self.H, self.E, self.Ts, inputs=list(self.inputs),
                          outputs=["u"])  # fmt: skip

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state.pop("python", None)
        state.pop("kernel_arrays", None)
        state.pop("_hpdob_derived", None)  # the simulation's values kept on it (_derived)
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)

    def __repr__(self) -> str:
        return (
            f"LinearController(name={self.name!r}, states={self.n_states}, "
            f"inputs={self.inputs}, Ts={self.Ts:g})"
        )


def _check_program(program: ControllerProgram, dense, n: int, p: int) -> None:
    q = len(program.signals)
    if q == 0:
        raise ParameterValueError("program.signals must have at least one row (the command u)")
    if len(program.signal_names) != q or program.signal_names[-1] != "u":
        raise ParameterValueError(
            f"program.signal_names must name the {q} signals, the last 'u', got "
            f"{program.signal_names!r}"
        )
    for part, rows in (("update", program.update), ("reset", program.reset)):
        if len(rows) != n:
            raise ParameterValueError(f"program.{part} must have {n} rows, got {len(rows)}")
    _check_switch(program, n, p, q)
    computed, (size_update, size_u) = program.matrices(n, p)
    F, G, H, E, N = dense
    for name, got, want, size in (
        ("update", np.hstack([computed[0], computed[1]]), np.hstack([F, G]), size_update),
        ("command", np.hstack([computed[2], computed[3]]), np.hstack([H, E]),
         size_u[None, : n + p]),
        ("reset", computed[4], N, np.abs(N)),
    ):  # fmt: skip
        if not np.all(np.abs(got - want) <= 8 * _EPS * size):
            raise ParameterValueError(
                f"program {name} rows sum to {_show(got)} but the matrices are {_show(want)}"
            )


def _check_switch(program: ControllerProgram, n: int, p: int, q: int) -> None:
    switch = program.switch
    if switch is None:
        return
    if not isinstance(switch, Switch):
        raise ParameterTypeError(
            f"program.switch must be a Switch or None, got {type(switch).__name__}"
        )
    checks = (
        ("trigger", switch.trigger, n, n + p, "an input's operand index"),
        ("latch", switch.latch, 0, n, "a state index"),
        ("after", switch.after, 0, q - 1, "the index of a signal before the command"),
    )
    for name, value, low, high, what in checks:
        if isinstance(value, bool) or not isinstance(value, int) or not low <= value < high:
            raise ParameterValueError(
                f"program.switch.{name} must be {what} in [{low}, {high}), got {value!r}"
            )
    if program.update[switch.latch]:
        raise ParameterValueError(
            f"program.switch.latch = {switch.latch}: the latch state's update row must be empty "
            "(the switch sets it)"
        )
    for name in ("threshold", "offset"):
        value = getattr(switch, name)
        if not isinstance(value, float) or not np.isfinite(value):
            raise ParameterValueError(
                f"program.switch.{name} must be a finite float, got {value!r}"
            )


class ProgramBuilder:
    """Write a :class:`ControllerProgram` by name: signals in order, then the state's rows.

    Parameters
    ----------
    inputs : sequence of str
        The controller's input names.
    states : sequence of str, optional
        Names of its states.

    Examples
    --------
    >>> from hpdob.controllers import ProgramBuilder
    >>> b = ProgramBuilder(("r", "theta"))
    >>> b.signal("e", (1.0, "r"), (-1.0, "theta"))
    >>> b.signal("u", (0.02, "e", "KP"))
    >>> c = b.build(Ts=1e-3)
    >>> c.E.tolist(), c.python.command((), 1.0, 0.5)
    ([[0.02, -0.02]], 0.01)
    """

    def __init__(self, inputs, states=()):
        self.inputs, self.states = tuple(inputs), tuple(states)
        self._signals: list = []
        self._names: list = []
        self._update: dict = {}
        self._reset: dict = {}
        self._constants: list = []
        self._switch: Switch | None = None

    def _index(self, name: str) -> int:
        n, p = len(self.states), len(self.inputs)
        if name in self.states:
            return self.states.index(name)
        if name in self.inputs:
            return n + self.inputs.index(name)
        if name == "u_bar":
            return n + p
        if name in self._names:
            return n + p + 1 + self._names.index(name)
        raise ParameterValueError(f"unknown operand {name!r} (no state, input or signal)")

    def _state(self, name: str) -> str:
        if name not in self.states:
            raise ParameterValueError(f"unknown state {name!r}; the states are {self.states}")
        return name

    def _terms(self, terms) -> tuple:
        out = []
        for term in terms:
            coefficient, operand, *constant = term
            out.append(Term(float(coefficient), self._index(operand), *constant))
        return tuple(out)

    def signal(self, name: str, *terms) -> None:
        """Add a signal: the left-to-right sum of its terms (the last signal is the command).

        Parameters
        ----------
        name : str
            The signal's name (the last one added must be ``"u"``).
        *terms : tuple
            ``(coefficient, operand[, constant[, negated]])`` with the operand by name (a
            state, an input or an earlier signal); see :class:`~hpdob.observers.Term`.
        """
        self._signals.append(self._terms(terms))
        self._names.append(name)

    def update(self, state: str, *terms) -> None:
        """Set the update row of a state.

        Parameters
        ----------
        state : str
            The state's name.
        *terms : tuple
            As for :meth:`signal`; operands also ``u_bar`` (the limited command) and every
            signal.
        """
        self._update[self._state(state)] = self._terms(terms)

    def reset(self, state: str, *terms) -> None:
        """Set the reset row of a state (default: 0).

        Parameters
        ----------
        state : str
            The state's name.
        *terms : tuple
            ``(coefficient, operand[, constant])`` with operands ``theta0``, ``omega0`` and
            ``tau0``.
        """
        self._reset[self._state(state)] = tuple(
            Term(float(c), RESET_OPERANDS.index(x), *rest) for c, x, *rest in terms
        )

    def switch(self, *, trigger: str, threshold: float, latch: str, after: str,
               offset: float = 0.0) -> None:  # fmt: skip
        """Latch the command over to another signal when an input crosses a threshold
        (:class:`~hpdob.controllers.Switch`).

        Parameters
        ----------
        trigger : str
            The input whose value ``>= threshold`` trips the switch.
        threshold : float
            The threshold, in the input's unit.
        latch : str
            The latch state (0 before, 1 once switched; give it no update row).
        after : str
            The signal that is the command once switched (plus ``offset``).
        offset : float, optional
            A constant added to it [N m]. Default 0.
        """
        if trigger not in self.inputs:
            raise ParameterValueError(f"unknown input {trigger!r}; the inputs are {self.inputs}")
        if after not in self._names:
            raise ParameterValueError(f"unknown signal {after!r}; the signals are {self._names}")
        self._switch = Switch(self._index(trigger), float(threshold),
                              self.states.index(self._state(latch)), self._names.index(after),
                              float(offset))  # fmt: skip

    def describe(self, name: str, text: str) -> None:
        """Describe a named constant (a comment in generated code).

        Parameters
        ----------
        name : str
            The constant's name, as in its terms.
        text : str
            What it is, with its unit.
        """
        self._constants.append((name, text))

    def build(self, *, Ts: float, name: str = "controller", info=()) -> LinearController:
        """The :class:`LinearController` of the rows written so far.

        Parameters
        ----------
        Ts : float
            Sampling period [s].
        name : str, optional
            Its name.
        info : tuple of (str, str), optional
            Design summary lines.

        Returns
        -------
        LinearController
        """
        program = ControllerProgram(
            signals=tuple(self._signals),
            update=tuple(self._update.get(s, ()) for s in self.states),
            reset=tuple(self._reset.get(s, ()) for s in self.states),
            signal_names=tuple(self._names),
            constants=tuple(self._constants),
            state_names=self.states,
            switch=self._switch,
        )
        return LinearController.from_program(
            program, Ts=Ts, inputs=self.inputs, n_states=len(self.states), name=name, info=info
        )
