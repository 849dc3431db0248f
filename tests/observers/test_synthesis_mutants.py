"""Order-m synthesis: tests that kill the mutants benchmarks/mutation.py found surviving."""

from __future__ import annotations

import numpy as np
import pytest

from hpdob import ServoModel, design_observer


@pytest.mark.parametrize(
    ("order", "kind"),
    [
        (0, "(conventional DOb, paper eqs. 9-13)"),
        (1, "(HPDOb, paper eqs. 14-24)"),
        (2, "(generalised DOb, Delta^(m+1) tau = 0)"),
        (3, "(generalised DOb, Delta^(m+1) tau = 0)"),
    ],
)
def test_design_summary_names_the_paper_family_of_each_order(order, kind):
    """The summary written into generated code's header names the family of the order."""
    model = ServoModel(2.8e-4, 5e-5).discretize(1e-3)  # the paper's nominal motor (sec. IV)
    info = dict(design_observer(model, order=order, bandwidth=300.0).system.info)
    assert info["order"] == f"{order} {kind}"


def test_a_tiny_inertia_designs_as_the_unit_inertia_scaled():
    """L_i = k_i d / (d^T D_Dn) (eq. 25): with b_n = 0, D_Dn is proportional to 1 / J_n, so an
    inertia of 1e-300 kg m^2 (D_Dn ~ 1e297, whose norm overflows a double) has the same k and
    the unit inertia's gains times 1e-300. The degeneracy test on d^T D_Dn must not read it as
    orthogonal."""
    Ts = 1e-3
    unit = design_observer(ServoModel(1.0, 0.0).discretize(Ts), order=1, bandwidth=300.0)
    tiny = design_observer(ServoModel(1e-300, 0.0).discretize(Ts), order=1, bandwidth=300.0)
    np.testing.assert_allclose(tiny.k, unit.k, rtol=1e-13)
    np.testing.assert_allclose(tiny.gains, unit.gains * 1e-300, rtol=1e-13)


def test_everything_but_the_model_is_keyword_only():
    """design_observer(model, *, order, ...): a positional order is refused (the project's
    keyword-only rule), so design_observer(model, 1, 2) cannot be read as order and poles."""
    model = ServoModel(2.8e-4, 5e-5).discretize(1e-3)
    with pytest.raises(TypeError, match="positional argument"):
        design_observer(model, 1, bandwidth=300.0)


def test_a_nearly_orthogonal_gain_direction_is_refused():
    """Eq. 25 divides by d^T D_Dn: a direction within 1e-8 (relative) of orthogonal to D_Dn is
    refused. With J_n = 1 kg m^2 at Ts = 2 s, D_Dn = [Ts^2/(2 J_n), Ts/J_n] = [2, 2], so a
    direction orthogonal to it has two entries of equal magnitude (|d| = sqrt(2) max|d_j|);
    tilted by 1e-9 its cosine to D_Dn is 5e-10."""
    model = ServoModel(1.0).discretize(2.0)
    D = np.asarray(model.D, dtype=float)
    unit = D / np.linalg.norm(D)
    direction = np.array([unit[1], -unit[0]]) + 5e-10 * unit
    assert abs(direction[0]) == pytest.approx(abs(direction[1]), rel=1e-8)
    with pytest.raises(ValueError, match="gain_direction must not be zero or orthogonal"):
        design_observer(model, order=1, bandwidth=0.1, gain_direction=tuple(direction))
