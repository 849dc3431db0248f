"""Observer programs: tests that kill the mutants benchmarks/mutation.py found surviving."""

from __future__ import annotations

from hpdob import ServoModel, design_observer


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
