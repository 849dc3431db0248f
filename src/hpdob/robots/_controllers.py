"""Each joint's controller as program rows, and the joints' rows stacked for the N-joint kernel.

A joint's controller is a linear discrete-time system given by its rows (the form of the
controller protocol's ``ControllerProgram``): **signal rows** evaluated in order, each a
left-to-right sum of ``coefficient * operand`` over ``[c (states), v (inputs), u_bar,
y (signals)]``, the last signal being the command; **update rows** for the next state (which
may read ``u_bar``, the command after the joint's torque limit); **reset rows** from
``[theta0, omega0, tau0]``. The inputs are named: ``r``, ``r_dot``, ``r_ddot``, ``theta``,
``omega`` (measured), ``tau_hat``, ``omega_hat`` (the joint's observer).

Stacked, the kernel's controller work vector is ``[c (all joints), the seven named inputs of
every joint (7 N), u_bar (N), y (all joints' signals)]``; each joint's terms and their order are
kept.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..observers import Term

__all__ = [
    "INPUTS",
    "JointController",
    "StackedControllers",
    "controller_types",
    "joint_controller",
    "pd_rows",
    "stack_controllers",
]

#: The named inputs the N-joint loop provides to each joint's controller.
INPUTS = ("r", "r_dot", "r_ddot", "theta", "omega", "tau_hat", "omega_hat")


class JointController(NamedTuple):
    """One joint's controller rows (a ``ControllerProgram``'s ``signals``, ``update`` and
    ``reset`` with the names of its inputs)."""

    inputs: tuple
    n_states: int
    signals: tuple
    update: tuple
    reset: tuple


def pd_rows(pd, J_n: float) -> JointController:
    """The PD :math:`u = J_n (k_p (r - \\theta) + k_d (\\dot r - \\omega) + \\ddot r) + \\hat\\tau`
    as rows, term for term in the order of the single-axis kernel: ``e = r - theta``,
    ``e_dot = r_dot - omega`` (``omega_hat`` with ``velocity="observer"``),
    ``a = kp e + kd e_dot (+ r_ddot)``, ``u = J_n a + tau_hat``."""
    omega = "omega_hat" if pd.velocity == "observer" else "omega"
    inputs = ("r", "r_dot", *(("r_ddot",) if pd.feedforward else ()), "theta", omega, "tau_hat")
    at = {name: i for i, name in enumerate(inputs)}
    y = len(inputs) + 1  # first signal operand (no state; u_bar after the inputs)
    acc = [Term(float(pd.kp), y), Term(float(pd.kd), y + 1)]
    if pd.feedforward:
        acc.append(Term(1.0, at["r_ddot"]))
    signals = (
        (Term(1.0, at["r"]), Term(-1.0, at["theta"])),
        (Term(1.0, at["r_dot"]), Term(-1.0, at[omega])),
        tuple(acc),
        (Term(float(J_n), y + 2), Term(1.0, at["tau_hat"])),
    )
    return JointController(inputs, 0, signals, (), ())


def _protocol():
    """The controller protocol's classes (``hpdob.controllers``), or None before it exists."""
    try:
        from ..controllers import Controller, LinearController
    except ImportError:
        return None
    return Controller, LinearController


def controller_types() -> tuple:
    """The classes a per-joint controller may be: the PD, and the controller protocol's."""
    from ..simulation import PD

    protocol = _protocol()
    return (PD,) if protocol is None else (PD, *protocol)


def joint_controller(controller, J_n: float, b_n: float, Ts: float, where: str):
    """Joint ``where``'s controller as rows, designed on its nominal ``ServoModel(J_n, b_n)``."""
    from .._validation import ParameterValueError
    from ..models import ServoModel

    protocol = _protocol()
    if protocol is None or not isinstance(controller, protocol):
        return pd_rows(controller, J_n)
    system = controller.design(ServoModel(J_n, b_n), Ts)
    unknown = [name for name in system.inputs if name not in INPUTS]
    if unknown:
        raise ParameterValueError(
            f"{where} reads {unknown[0]!r}, which the N-joint loop does not provide "
            f"(inputs: {', '.join(INPUTS)})"
        )
    program = system.program
    return JointController(tuple(system.inputs), int(system.F.shape[0]), tuple(program.signals),
                           tuple(program.update), tuple(program.reset))  # fmt: skip


class StackedControllers(NamedTuple):
    n_states: int
    n_signals: int
    offsets: tuple  # first state of each joint
    signals: tuple  # (pointer, coefficient, operand)
    update: tuple
    command: np.ndarray  # the signal index of each joint's command


def _flat(rows):
    pointer = np.zeros(len(rows) + 1, dtype=np.int64)
    coefficient, operand = [], []
    for i, terms in enumerate(rows):
        pointer[i + 1] = pointer[i] + len(terms)
        coefficient += [c for c, _ in terms]
        operand += [o for _, o in terms]
    return (
        pointer,
        np.array(coefficient, dtype=np.float64).reshape(-1),
        np.array(operand, dtype=np.int64).reshape(-1),
    )


def stack_controllers(controllers) -> StackedControllers:
    """Stack the joints' :class:`JointController` rows (one per joint)."""
    N = len(controllers)
    C = sum(c.n_states for c in controllers)
    bar = C + len(INPUTS) * N  # u_bar of joint 0
    first_signal = bar + N
    signals, update, offsets, command = [], [], [], []
    state = 0
    for i, ctl in enumerate(controllers):
        n, p = ctl.n_states, len(ctl.inputs)
        y0 = len(signals)

        def operand(j, n=n, p=p, inputs=ctl.inputs, state=state, y0=y0, i=i):
            if j < n:
                return state + j
            if j < n + p:
                return C + INPUTS.index(inputs[j - n]) * N + i
            if j == n + p:
                return bar + i
            return first_signal + y0 + (j - n - p - 1)

        signals += [[(t.coefficient, operand(t.operand)) for t in row] for row in ctl.signals]
        update += [[(t.coefficient, operand(t.operand)) for t in row] for row in ctl.update]
        command.append(len(signals) - 1)
        offsets.append(state)
        state += n
    return StackedControllers(C, len(signals), tuple(offsets), _flat(signals), _flat(update),
                              np.array(command, dtype=np.int64))  # fmt: skip
