"""The N joints' observers as one stacked program (what the N-joint kernel runs).

Joint ``i``'s observer reads ``[s_i, its measured signals, u_i]``; in the stacked work vector
``w = [s_1..s_N, theta_m (N), omega_m (N), u (N)]`` its operands are renumbered, its terms and
their order are kept, so each joint's rows are the sums its own program defines.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["StackedPrograms", "stack_programs"]


class StackedPrograms(NamedTuple):
    n_states: int
    offsets: tuple  # first state of each joint in s (None: no observer)
    update: tuple  # (pointer, coefficient, operand)
    output: tuple
    tau_row: np.ndarray  # output row of each joint's estimate (-1: none)
    omega_row: np.ndarray  # ... of its velocity estimate (-1: none)


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


def stack_programs(systems) -> StackedPrograms:
    """Stack ``systems`` (one :class:`~hpdob.LinearObserver` or None per joint)."""
    N = len(systems)
    S = sum(0 if s is None else s.n_states for s in systems)
    update, output, offsets = [], [], []
    tau_row = np.full(N, -1, dtype=np.int64)
    omega_row = np.full(N, -1, dtype=np.int64)
    offset = 0
    for i, system in enumerate(systems):
        if system is None:
            offsets.append(None)
            continue
        n = system.n_states
        where = [S + i if m == "theta" else S + N + i for m in system.measures]

        def operand(j, n=n, where=where, offset=offset, i=i):
            if j < n:
                return offset + j
            if j - n < len(where):
                return where[j - n]
            return S + 2 * N + i

        program = system.program
        update += [[(t.coefficient, operand(t.operand)) for t in row] for row in program.update]
        tau_row[i] = len(output)
        if len(program.output) > 1:
            omega_row[i] = len(output) + 1
        output += [[(t.coefficient, operand(t.operand)) for t in row] for row in program.output]
        offsets.append(offset)
        offset += n
    return StackedPrograms(S, tuple(offsets), _flat(update), _flat(output), tau_row, omega_row)
