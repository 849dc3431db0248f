"""Observer programs: tests that kill the mutants benchmarks/mutation.py found surviving."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hpdob import LinearObserver, ServoModel, design_observer
from hpdob.observers import Program, Term, render_sum


def test_constant_descriptions_name_their_matrix_entries():
    """Each named constant of the order-m program describes its own entry (comments of
    generated C): row i of G A - M G and G B is entry i - 1 (zero-based)."""
    model = ServoModel(2.8e-4, 5e-5).discretize(1e-3)  # the paper's nominal motor (sec. IV)
    order = 2
    program = design_observer(model, order=order, bandwidth=300.0).system.program
    described = dict(program.constants)
    for i in range(1, order + 2):
        assert described[f"K{i}"] == f"k_{i} = L_{i}^T D_Dn"
        assert described[f"L{i}_THETA"] == f"L_{i}, theta entry [N m/rad]"
        assert described[f"L{i}_OMEGA"] == f"L_{i}, omega entry [N m s/rad]"
        assert described[f"KX{i}_THETA"] == f"(G A - M G)[{i - 1}][0]"
        assert described[f"KX{i}_OMEGA"] == f"(G A - M G)[{i - 1}][1]"
        assert described[f"KU{i}"] == f"(G B)[{i - 1}]"
    assert len(described) == 6 * (order + 1)


@pytest.mark.parametrize(("part", "width"), [("update", 5), ("output", 5), ("reset", 3)])
def test_out_of_range_operand_is_refused_with_the_valid_range(part, width):
    """Operands index [s_0, s_1, theta, omega, u] (update, output) or [theta0, omega0, tau0]
    (reset) for the HPDOb: one past the end is refused, naming the valid range 0..width-1."""
    model = ServoModel(2.8e-4, 5e-5).discretize(1e-3)
    system = design_observer(model, order=1, bandwidth=300.0).system
    rows = list(getattr(system.program, part))
    rows[0] = (*rows[0], Term(1.0, width))
    program = dataclasses.replace(system.program, **{part: tuple(rows)})
    with pytest.raises(ValueError, match=rf"program\.{part}\[0\] .* operands in 0\.\.{width - 1},"):
        dataclasses.replace(system, program=program)


def test_a_program_off_in_two_entries_is_refused_naming_the_worst():
    """The refusal names the operand whose sum is furthest off the matrix entry (beyond the
    rounding allowance): here u's K_u (G B, eq. 21) off by 1e-3 relative, not s_0's 1e-9."""
    model = ServoModel(2.8e-4, 5e-5).discretize(1e-3)
    system = design_observer(model, order=1, bandwidth=300.0).system
    row = [
        t._replace(coefficient=t.coefficient * (1 + 1e-3)) if t.operand == 4 else t
        for t in system.program.update[0]
    ]
    rows = ((*row, Term(1e-9, 0)), *system.program.update[1:])
    program = dataclasses.replace(system.program, update=rows)
    with pytest.raises(ValueError, match=r"program\.update\[0\] sums to \S+ for operand 4 "):
        dataclasses.replace(system, program=program)


def test_rounding_within_the_allowance_is_not_blamed():
    """A large sum that cancels (1e6 - (1e6 - ulp)) is off by rounding only, within the
    allowance of 4 eps times the terms' magnitudes: the refusal names the operand that is
    really wrong, theta's K_x entry off by 1e-12, though its error is smaller."""
    model = ServoModel(2.8e-4, 5e-5).discretize(1e-3)
    system = design_observer(model, order=1, bandwidth=300.0).system
    big = 1e6
    cancelling = (Term(big, 3), Term(-(big - np.spacing(big)), 3), Term(1e-12, 2))
    rows = ((*system.program.update[0], *cancelling), *system.program.update[1:])
    program = dataclasses.replace(system.program, update=rows)
    with pytest.raises(ValueError, match=r"program\.update\[0\] sums to \S+ for operand 2 "):
        dataclasses.replace(system, program=program)


def test_unit_coefficients_are_written_inline_and_the_others_named():
    """Program.from_matrices: coefficients of magnitude one inline (no constant), every other
    non-zero one a named constant (F<i>_<j>, G<i>_<signal>)."""
    F = np.array([[1.0, 0.5], [-1.0, 2.0]])
    G = np.array([[0.25, -1.0, 0.0], [0.0, 1.0, -3.0]])
    H, E, N = np.array([[1.0, -0.75]]), np.array([[0.0, 0.0]]), np.zeros((2, 3))
    program = Program.from_matrices(F, G, H, E, N, ("theta", "omega"))
    for row in (*program.update, *program.output):
        for t in row:
            assert (t.constant is None) is (abs(t.coefficient) == 1.0), t
    assert [t.constant for t in program.update[0]] == [None, "F1_2", "G1_THETA", None]
    assert [t.constant for t in program.update[1]] == [None, "F2_2", None, "G2_U"]


def test_an_inline_sum_keeps_every_coefficient_but_one():
    """render_sum without names: ``c * x`` for every coefficient but +-1, signs pulled out."""
    terms = (Term(0.5, 0), Term(-0.25, 1), Term(1.0, 2), Term(-1.0, 0), Term(3.0, 1))
    text = render_sum(terms, ("a", "b", "c"), repr, named=False)
    assert text == "0.5 * a - 0.25 * b + c - a + 3.0 * b"


def test_a_program_just_outside_the_rounding_allowance_is_refused():
    """The allowance is 4 eps times the terms' magnitude: an entry of 0.5 written as
    0.5 (1 + 5 eps) (exact in double: the spacing at 0.5 is eps/2) is off by 5 eps x 0.5,
    beyond 4 eps x 0.5 (1 + 5 eps), and refused."""
    F, G = np.array([[0.5]]), np.array([[0.25, 0.0, 0.125]])
    H, E, N = np.array([[1.0]]), np.array([[-0.5, 0.0, 0.0]]), np.array([[0.0, 0.0, 1.0]])
    eps = np.finfo(float).eps
    off = Program(
        update=((Term(0.5 * (1 + 5 * eps), 0, "F1_1"), Term(0.25, 1, "G1_THETA"),
                 Term(0.125, 3, "G1_U")),),
        output=((Term(1.0, 0), Term(-0.5, 1, "E1_THETA")),),
        reset=((Term(1.0, 2),),),
    )  # fmt: skip
    kwargs = {"F": F, "G": G, "H": H, "E": E, "N": N, "Ts": 1e-3, "measures": ("theta", "omega")}
    with pytest.raises(ValueError, match=r"program\.update\[0\] sums to .* for operand 0 "):
        LinearObserver(**kwargs, program=off)
    exact = dataclasses.replace(off, update=((Term(0.5, 0, "F1_1"), *off.update[0][1:]),))
    assert LinearObserver(**kwargs, program=exact).program is exact
