"""Linear ESO: tests that kill the mutants benchmarks/mutation.py found surviving."""

from __future__ import annotations

import itertools

import pytest

from hpdob import ServoModel
from hpdob.observers import design_eso, initial_state, outputs

#: The paper's nominal motor (sec. IV) but with a viscous b_n large enough that b_n omega0 is
#: of the order of tau0 (the reset's b_n term is then visible): 1e-3 N m s/rad at 50 rad/s
#: gives 0.05 N m against tau0 = 0.01 N m.
MODEL = ServoModel(2.8e-4, 1e-3).discretize(1e-3)


@pytest.mark.parametrize(
    ("form", "extended_order"), list(itertools.product(("current", "predictive"), (0, 1, 2)))
)
@pytest.mark.parametrize(("x0", "tau0"), [((0.0, 50.0), 0.01), ((0.3, -20.0), -0.02)])
def test_reset_state_reports_tau0_and_omega0(form, extended_order, x0, tau0):
    """An ESO reset on (theta0, omega0, tau0) is converged: it reports tau_hat = tau0 and
    omega_hat = omega0 at the measured theta0. With f = -(tau + b_n omega)/J_n this needs the
    b_n term (and its sign) in the reset matrix N (issue 20's planted bug)."""
    design = design_eso(MODEL, bandwidth=200.0, extended_order=extended_order, form=form)
    tau_hat, omega_hat = outputs(design, initial_state(design, x0=x0, tau0=tau0), x0[0])
    assert tau_hat == pytest.approx(tau0, rel=1e-9, abs=1e-12)
    assert omega_hat == pytest.approx(x0[1], rel=1e-9)


def test_extended_order_limit_is_four():
    """Orders up to 4 design (Ackermann's formula stays accurate); 5 is refused, naming it."""
    assert design_eso(MODEL, bandwidth=200.0, extended_order=4).system.n_states == 7
    with pytest.raises(ValueError, match="extended_order must be at most 4"):
        design_eso(MODEL, bandwidth=200.0, extended_order=5)
