"""Tests of the unified synthesis (eqs. 12, 22, 24, 25 and their order-m generalisation)."""

from __future__ import annotations

import cmath
import dataclasses
import inspect
import math
from fractions import Fraction

import numpy as np
import pytest
import scipy.optimize
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from hpdob import (
    ServoModel,
    characteristic_polynomial,
    design_observer,
    error_matrix,
    extrapolation_weights,
)


# -- literal equations of the paper ------------------------------------------------------
def test_error_matrix_order0_is_eq12():
    np.testing.assert_array_equal(error_matrix([0.3]), [[1 - 0.3]])


def test_error_matrix_order1_is_eq22():
    k1, k2 = 0.2, 0.45
    np.testing.assert_array_equal(error_matrix([k1, k2]), [[0.0, 1 - k1], [-1.0, 2 - k2]])


def test_extrapolation_weights_are_finite_differences():
    # Delta^{m+1} tau_{k+1} = 0  <=>  tau_{k+1} = sum_i p_i tau_{k-(m+1-i)}
    # eqs. (17)-(19): [-1, 2].
    np.testing.assert_array_equal(extrapolation_weights(0), [1.0])
    np.testing.assert_array_equal(extrapolation_weights(1), [-1.0, 2.0])
    np.testing.assert_array_equal(extrapolation_weights(2), [1.0, -3.0, 3.0])
    np.testing.assert_array_equal(extrapolation_weights(3), [-1.0, 4.0, -6.0, 4.0])
    for m in range(6):  # exact for every polynomial of degree m
        k = np.arange(m + 2, dtype=float)
        for degree in range(m + 1):
            samples = (k - 3.0) ** degree
            assert extrapolation_weights(m) @ samples[:-1] == pytest.approx(samples[-1], abs=1e-9)


@pytest.mark.parametrize("poles", [(0.9,), (0.5,), (-0.3,), (0.0,)])
def test_order0_gain_places_the_pole(paper_model, poles):
    design = design_observer(paper_model, order=0, poles=poles)
    assert design.k[0] == pytest.approx(1 - poles[0], abs=1e-15)  # eq. (12): 1 - L^T D = lambda


@pytest.mark.parametrize(
    "poles", [(0.9, 0.8), (0.9, 0.9), (0.5 + 0.3j, 0.5 - 0.3j), (-0.2, 0.7), (0.0, 0.0)]
)
def test_order1_gains_are_eq24(paper_model, poles):
    design = design_observer(paper_model, order=1, poles=poles)
    l1, l2 = poles
    assert design.k[0] == pytest.approx((1 - l1 * l2).real, abs=1e-15)
    assert design.k[1] == pytest.approx((2 - l1 - l2).real, abs=1e-15)


def test_gains_are_eq25(paper_model):
    # L_i = k_i / |D_Dn|_1 [1, 1]^T with the default gain direction.
    design = design_observer(paper_model, order=1, bandwidth=100.0)
    norm1 = np.sum(np.abs(paper_model.D))
    expected = np.outer(design.k, [1.0, 1.0]) / norm1
    np.testing.assert_allclose(design.gains, expected, rtol=1e-15)
    np.testing.assert_allclose(design.gains @ paper_model.D, design.k, rtol=1e-15)


@pytest.mark.parametrize("direction", [(0.0, 1.0), (1.0, 0.0), (2.0, -1e-4), (-3.0, -1.0)])
def test_gain_direction(paper_model, direction):
    design = design_observer(paper_model, order=2, bandwidth=150.0, gain_direction=direction)
    d = np.asarray(direction)
    np.testing.assert_allclose(design.gains @ paper_model.D, design.k, rtol=1e-14)
    for row in design.gains:  # every L_i is parallel to d
        assert abs(row[0] * d[1] - row[1] * d[0]) <= 1e-15 * np.linalg.norm(row) * np.linalg.norm(d)


def test_bandwidth_places_all_poles_at_exp(paper_model):
    for order in range(5):
        design = design_observer(paper_model, order=order, bandwidth=200.0)
        np.testing.assert_array_equal(design.poles, np.full(order + 1, math.exp(-200.0 * 1e-3)))
        assert design.bandwidth == 200.0


# -- the characteristic polynomial ----------------------------------------------------------
def _exact_charpoly(M):
    """det(zI - M) by Faddeev-LeVerrier in exact rational arithmetic (independent of eig)."""
    n = len(M)
    M = [[Fraction(float(v)) for v in row] for row in M]

    def matmul(X, Y):
        return [[sum(X[i][t] * Y[t][j] for t in range(n)) for j in range(n)] for i in range(n)]

    coefficients = [Fraction(1)]
    N = [[Fraction(0)] * n for _ in range(n)]
    for j in range(1, n + 1):
        N = matmul(M, N)
        for i in range(n):
            N[i][i] += coefficients[-1]
        MN = matmul(M, N)
        coefficients.append(-sum(MN[i][i] for i in range(n)) / j)
    return np.array([float(c) for c in coefficients])


@given(st.lists(st.floats(-2.0, 2.0), min_size=1, max_size=6))
def test_characteristic_polynomial_matches_the_matrix(k):
    """The affine closed form equals det(zI - M) of the matrix itself, to rounding."""
    exact = _exact_charpoly(error_matrix(k))
    scale = 2.0 ** len(k) * (1.0 + max(abs(v) for v in k))  # binomial-weighted sums of k
    np.testing.assert_allclose(characteristic_polynomial(k), exact, rtol=0, atol=1e-15 * scale)


def _match(eigenvalues, poles):
    """Largest distance after optimally pairing eigenvalues with poles."""
    cost = np.abs(np.subtract.outer(np.asarray(eigenvalues), np.asarray(poles)))
    rows, cols = scipy.optimize.linear_sum_assignment(cost)
    return cost[rows, cols].max()


@st.composite
def stable_pole_sets(draw):
    """order in 0..4 and order+1 poles: reals and conjugate pairs, |p| <= 0.97, separated."""
    order = draw(st.integers(0, 4))
    n_pairs = draw(st.integers(0, (order + 1) // 2))
    poles = []
    for _ in range(n_pairs):
        radius = draw(st.floats(0.05, 0.97))
        angle = draw(st.floats(0.05, math.pi - 0.05))
        p = cmath.rect(radius, angle)
        poles += [p, p.conjugate()]
    poles += draw(
        st.lists(
            st.floats(-0.97, 0.97),
            min_size=order + 1 - 2 * n_pairs,
            max_size=order + 1 - 2 * n_pairs,
        )
    )
    return order, poles


@settings(max_examples=300, deadline=None)
@given(stable_pole_sets())
def test_eigenvalues_equal_requested_poles(order_poles):
    order, poles = order_poles
    separation = min((abs(a - b) for i, a in enumerate(poles) for b in poles[i + 1 :]), default=1.0)
    assume(separation > 0.05)
    model = ServoModel(3.06e-4, 5e-5).discretize(1e-3)
    design = design_observer(model, order=order, poles=poles)
    assert design.error_matrix.shape == (order + 1, order + 1)
    # Separated poles of a non-normal companion-like matrix: conditioned by 1/separation^order.
    assert _match(np.linalg.eigvals(design.error_matrix), poles) < 1e-9
    np.testing.assert_allclose(
        characteristic_polynomial(design.k), np.poly(poles).real, rtol=0, atol=1e-12
    )


@pytest.mark.parametrize("order", range(6))
def test_repeated_poles_are_placed_exactly(paper_model, order):
    """Repeated poles: the characteristic polynomial is (z - p)^(m+1) to rounding."""
    p = math.exp(-100.0 * 1e-3)
    design = design_observer(paper_model, order=order, bandwidth=100.0)
    expected = np.poly(np.full(order + 1, p))
    np.testing.assert_allclose(
        characteristic_polynomial(design.k), expected, rtol=0, atol=1e-13 * 2**order
    )
    # Eigenvalues of a Jordan-like block split by ~eps^(1/(m+1)); they still sit around p.
    eig = np.linalg.eigvals(design.error_matrix)
    assert np.max(np.abs(eig - p)) < 10 * np.finfo(float).eps ** (1 / (order + 1))
    assert abs(np.mean(eig) - p) < 1e-12


def test_deadbeat_design(paper_model):
    """All poles at 0: M is nilpotent, the error vanishes after order + 1 samples."""
    for order in range(5):
        M = design_observer(paper_model, order=order, poles=np.zeros(order + 1)).error_matrix
        np.testing.assert_allclose(np.linalg.matrix_power(M, order + 1), 0.0, atol=1e-12)


def test_general_update_satisfies_the_error_dynamics(paper_model, rng):
    """e_{k+1} = M e_k + [0, ..., 0, Delta^{m+1} tau_{k+1}] on the nominal model (eqs. 12, 22).

    z_{i,k} = tau_{k-(m+1-i)} + L_i^T x_k is built from its definition (eq. 14 generalised) and the
    observer recursion from the design; the identity must hold for arbitrary tau and u.
    """
    for order in range(5):
        design = design_observer(paper_model, order=order, poles=np.linspace(0.2, 0.8, order + 1))
        A, B, D = paper_model.A, paper_model.B, paper_model.D
        G, M = design.gains, design.error_matrix
        n_steps = 40
        tau = rng.normal(size=n_steps + order + 2)  # tau[j + order] is tau_j, j >= -order
        u = rng.normal(size=n_steps)
        x = rng.normal(size=2)
        z_hat = rng.normal(size=order + 1)
        for k in range(n_steps - 1):
            history = tau[k : k + order + 1]  # tau_{k-m}, ..., tau_k
            z = history + G @ x
            x_next = A @ x + B * u[k] - D * tau[k + order]
            z_hat_next = M @ z_hat + design.state_input @ x + design.control_input * u[k]
            z_next = tau[k + 1 : k + order + 2] + G @ x_next
            forcing = np.zeros(order + 1)
            forcing[-1] = np.diff(tau[k : k + order + 3], n=order + 1)[0]  # Delta^{m+1} tau_{k+1}
            np.testing.assert_allclose(
                z_next - z_hat_next, M @ (z - z_hat) + forcing, rtol=1e-12, atol=1e-12
            )
            x, z_hat = x_next, z_hat_next


# -- immutability and representation -------------------------------------------------------
def test_design_is_frozen_and_readonly(paper_model):
    design = design_observer(paper_model, order=1, bandwidth=100.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        design.order = 2
    for name in (
        "poles",
        "k",
        "gains",
        "error_matrix",
        "state_input",
        "control_input",
        "gain_direction",
    ):
        with pytest.raises(ValueError, match="read-only"):
            getattr(design, name)[0] = 0.0
    assert "order=1" in repr(design)
    assert design.Ts == 1e-3
    assert design.state_matrix is design.error_matrix


def test_complex_poles_kept_complex(paper_model):
    design = design_observer(paper_model, order=1, poles=[0.8 + 0.1j, 0.8 - 0.1j])
    assert np.iscomplexobj(design.poles)
    assert np.isrealobj(design.gains)
    assert np.isrealobj(design_observer(paper_model, order=1, poles=[0.8, 0.7]).poles)


# -- bad input ------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("kwargs", "pattern"),
    [
        ({"order": -1, "bandwidth": 100.0}, r"^order must be a non-negative integer .*got -1"),
        ({"order": 1, "bandwidth": 0.0}, r"^bandwidth must be a positive .*got 0.0"),
        ({"order": 1, "bandwidth": -5.0}, r"^bandwidth must be a positive .*got -5.0"),
        ({"order": 1, "bandwidth": math.nan}, r"^bandwidth must be .*got nan"),
        ({"order": 1}, r"exactly one of poles .* or bandwidth .*got neither"),
        ({"order": 1, "poles": [0.9, 0.9], "bandwidth": 10.0}, r"exactly one .*got both"),
        ({"order": 1, "poles": [0.9]}, r"^poles must have order \+ 1 = 2 entries .*got 1"),
        ({"order": 0, "poles": [0.9, 0.8]}, r"^poles must have order \+ 1 = 1 entries .*got 2"),
        ({"order": 1, "poles": [0.9, 1.0]}, r"strictly inside the unit circle .*got 1 with"),
        ({"order": 1, "poles": [0.9, -1.2]}, r"strictly inside the unit circle .*got -1.2"),
        ({"order": 1, "poles": [0.6 + 0.8j, 0.6 - 0.8j]}, r"unit circle .*\|p\| = 1"),
        (
            {"order": 1, "poles": [0.5 + 0.1j, 0.5]},
            r"conjugate pairs.*\(0.5\+0.1j\) has no partner",
        ),
        ({"order": 2, "poles": [0.5 + 0.1j, 0.5 + 0.1j, 0.3]}, r"conjugate pairs"),
        ({"order": 1, "poles": [0.5, math.nan]}, r"^poles must be finite"),
        ({"order": 1, "bandwidth": 1.0, "gain_direction": (0.0, 0.0)}, r"gain_direction"),
        (
            {"order": 1, "bandwidth": 1.0, "gain_direction": (1.0,)},
            r"^gain_direction must be .*shape \(2,\)",
        ),
        (
            {"order": 1, "bandwidth": 1.0, "gain_direction": (1.0, math.inf)},
            r"^gain_direction .*finite",
        ),
    ],
)
def test_bad_arguments(paper_model, kwargs, pattern):
    with pytest.raises(ValueError, match=pattern):
        design_observer(paper_model, **kwargs)


def test_degenerate_gain_direction(paper_model):
    D = paper_model.D
    orthogonal = (D[1], -D[0])  # d^T D_Dn == 0
    with pytest.raises(ValueError, match=r"gain_direction must not be zero or orthogonal to D_Dn"):
        design_observer(paper_model, order=1, bandwidth=100.0, gain_direction=orthogonal)


@pytest.mark.parametrize("order", [1.0, True, "1", None])
def test_order_type(paper_model, order):
    with pytest.raises(TypeError, match=r"^order must be a non-negative integer"):
        design_observer(paper_model, order=order, bandwidth=100.0)


def test_needs_a_discrete_model():
    with pytest.raises(TypeError, match=r"discretise the continuous model first"):
        design_observer(ServoModel(1.0), order=0, bandwidth=10.0)
    with pytest.raises(
        TypeError, match="must be a DiscreteServoModel or a sampled python-control servo, got str"
    ):
        design_observer("motor", order=0, bandwidth=10.0)


def test_poles_type(paper_model):
    with pytest.raises(TypeError, match="poles must be a sequence"):
        design_observer(paper_model, order=1, poles=["a", "b"])


@pytest.mark.parametrize("poles", ["0.9", b"0.9", ["0.9", "0.8"], [True, False]])
def test_poles_are_not_parsed_from_text_or_bools(paper_model, poles):
    order = 0 if isinstance(poles, (str, bytes)) else 1
    with pytest.raises(TypeError, match=r"^poles must be a sequence of \d numbers, got "):
        design_observer(paper_model, order=order, poles=poles)


def test_tiny_and_huge_gain_directions_give_the_unit_direction_gains(paper_model):
    # L_i = k_i d / (d^T D_Dn) does not depend on the scale of d; a subnormal d must neither
    # be rejected nor lose precision, a huge one must not overflow.
    reference = design_observer(paper_model, order=1, bandwidth=300.0, gain_direction=(1.0, 0.0))
    for scale in (1e-320, 1e300):
        design = design_observer(paper_model, order=1, bandwidth=300.0, gain_direction=(scale, 0.0))
        np.testing.assert_allclose(design.gains, reference.gains, rtol=1e-14)
        np.testing.assert_array_equal(design.gain_direction, [scale, 0.0])


def _radius_near_one(k) -> float:
    """Largest |eigenvalue| of M, from the exact characteristic polynomial shifted to w = z - 1.

    An independent reference for poles clustered near z = 1: the polynomial
    (z-1)^{m+1} + sum_j k_j q_j(z) is formed in rationals from the double gains, Taylor-shifted
    to w = z - 1 exactly, and only then rounded; the cluster at w0 = p - 1 then has roots
    accurate to ~|w0| eps^(1/(m+1)) instead of eps^(1/(m+1)).
    """
    from hpdob.observers._error_dynamics import characteristic_basis, unit_root_polynomial

    m = len(k) - 1
    Q = characteristic_basis(m)
    c = [Fraction(int(b)) for b in unit_root_polynomial(m)]
    for i in range(m + 1):
        c[i] += sum(int(Q[i, j]) * Fraction(float(k[j])) for j in range(m + 1))
    # p(1 + w) = sum_i c_i (1 + w)^i  ->  coefficient of w^j is sum_i c_i binom(i, j)
    shifted = [sum(c[i] * math.comb(i, j) for i in range(j, m + 2)) for j in range(m + 2)]
    roots = np.roots([float(v) for v in shifted[::-1]])
    return float(np.max(np.abs(1.0 + roots)))


# (order, bandwidth [rad/s]) at Ts = 1 ms. Stable ones were computed as stable and unstable
# ones as unstable by a reviewer with exact (80-digit mpmath) eigenvalues of the rounded design;
# numpy's eigvals got the first two and the last one wrong.
NEAR_THRESHOLD = [((3, 0.1), True), ((6, 10.0), True), ((6, 9.0), True), ((4, 1.0), False)]


@pytest.mark.parametrize(("case", "stable"), NEAR_THRESHOLD, ids=str)
def test_realisability_is_decided_exactly_near_the_threshold(paper_model, case, stable):
    order, bandwidth = case
    # pole_tolerance=None: the stability decision alone (these realised poles are far off the
    # requested ones, so the default tolerance refuses all four)
    if stable:
        design = design_observer(paper_model, order=order, bandwidth=bandwidth, pole_tolerance=None)
        assert _radius_near_one(design.k) < 1.0
    else:
        with pytest.raises(ValueError, match=rf"^bandwidth={bandwidth} rad/s cannot be realised"):
            design_observer(paper_model, order=order, bandwidth=bandwidth, pole_tolerance=None)
    with pytest.raises(ValueError, match=rf"^bandwidth={bandwidth} rad/s cannot be realised"):
        design_observer(paper_model, order=order, bandwidth=bandwidth)


def test_schur_cohn_agrees_with_roots_on_well_conditioned_polynomials(rng):
    from hpdob.observers._error_dynamics import schur_stable

    # Random real error matrices M = C - k e^T: their characteristic polynomials have distinct
    # roots well away from the unit circle (|1 - |z|| > 1e-6), where np.roots is reliable.
    checked = 0
    for _ in range(400):
        m = int(rng.integers(0, 6))
        k = rng.normal(scale=2.0, size=m + 1)
        radius = np.max(np.abs(np.linalg.eigvals(error_matrix(k))))
        if abs(radius - 1.0) < 1e-6:
            continue
        assert schur_stable(k) == (radius < 1.0), (k, radius)
        checked += 1
    assert checked > 350


def test_order_is_capped(paper_model):
    with pytest.raises(ValueError, match=r"^order must be at most 50: .*got 200"):
        design_observer(paper_model, order=200, bandwidth=500.0)
    design = design_observer(paper_model, order=50, poles=np.zeros(51))  # deadbeat: exact
    assert design.order == 50


@pytest.mark.parametrize("order", [0, 1, 2, 5])
def test_unit_root_polynomial(order):
    from hpdob.observers._error_dynamics import unit_root_polynomial

    # (z - 1)^{m+1} from its roots, highest power first; ours is ascending.
    np.testing.assert_array_equal(unit_root_polynomial(order)[::-1], np.poly(np.ones(order + 1)))


# -- realised poles (issue 16, item 7) ----------------------------------------------------
def _mpmath_roots(k, digits=80):
    """Roots of det(zI - M) for the rounded gains k: the exact rational characteristic
    polynomial (eq. 24 generalised: (z-1)^{m+1} + sum_j k_j q_j(z), with every float at its
    exact value), solved by mpmath at ``digits`` significant digits (an independent solver)."""
    mpmath = pytest.importorskip("mpmath")
    from hpdob.observers._error_dynamics import characteristic_basis, unit_root_polynomial

    m = len(k) - 1
    Q = characteristic_basis(m)
    gains = [Fraction(float(v)) for v in k]
    ascending = [
        int(base) + sum((int(Q[i, j]) * gains[j] for j in range(m + 1)), Fraction(0))
        for i, base in enumerate(unit_root_polynomial(m)[: m + 1])
    ] + [Fraction(1)]
    with mpmath.workdps(digits):
        coefficients = [mpmath.mpf(c.numerator) / c.denominator for c in ascending]
        options = {"maxsteps": 4000, "extraprec": 8 * digits}
        if "asc" in inspect.signature(mpmath.polyroots).parameters:  # mpmath >= 1.4
            roots = mpmath.polyroots(coefficients, asc=True, **options)
        else:
            roots = mpmath.polyroots(coefficients[::-1], **options)
        return np.array([complex(r) for r in roots])


REALISED_CASES = [
    # (order, design arguments): canonical designs, two of issue 16's examples (order 30 at
    # 1000 rad/s is in the refusal test below: its roots to 220 digits take seconds), order 20,
    # mixed real, repeated and complex poles
    (0, {"bandwidth": 100.0}),
    (1, {"bandwidth": 100.0}),
    (3, {"bandwidth": 50.0}),
    (8, {"poles": [0.9] * 9}),
    (10, {"bandwidth": 100.0}),
    (20, {"bandwidth": 1000.0}),
    (3, {"poles": [0.8, 0.8, 0.5 + 0.3j, 0.5 - 0.3j]}),
    (4, {"poles": [0.9, 0.9, 0.9, 0.2, 0.2]}),
]


@pytest.mark.parametrize(("order", "kwargs"), REALISED_CASES, ids=str)
def test_realised_poles_agree_with_high_precision_roots(paper_model, order, kwargs):
    design = design_observer(paper_model, order=order, pole_tolerance=None, **kwargs)
    reference = _mpmath_roots(design.k, digits=40 + 6 * order)
    spread = max(np.max(np.abs(reference - np.mean(reference))), 1e-300)
    # the same multiset of roots, to a tiny fraction of how far they spread
    assert _match(design.realised_poles, reference) < 1e-9 * max(spread, 1e-6)
    # paired with the requested poles entry by entry
    assert design.realised_poles.shape == design.poles.shape


@pytest.mark.parametrize(
    ("order", "kwargs", "realised"),
    [  # |z| of the realised pole furthest off, from the 80-digit roots of the test above
        (30, {"bandwidth": 1000.0}, 0.92),
        (10, {"bandwidth": 100.0}, 0.95),
        (8, {"poles": [0.9] * 9}, 0.924),
    ],
)
def test_far_off_realised_poles_are_refused(paper_model, order, kwargs, realised):
    design = design_observer(paper_model, order=order, pole_tolerance=None, **kwargs)
    assert np.max(np.abs(design.realised_poles)) == pytest.approx(realised, abs=0.01)
    with pytest.raises(ValueError, match=r"cannot be realised for order .* is realised at") as info:
        design_observer(paper_model, order=order, **kwargs)
    assert "more than pole_tolerance=0.05" in str(info.value) and "\n" not in str(info.value)


@pytest.mark.parametrize("order", range(4))
@pytest.mark.parametrize("bandwidth", [50.0, 100.0, 200.0])
def test_canonical_designs_are_accepted_unchanged(paper_model, order, bandwidth):
    design = design_observer(paper_model, order=order, bandwidth=bandwidth)
    free = design_observer(paper_model, order=order, bandwidth=bandwidth, pole_tolerance=None)
    for name in ("k", "gains", "error_matrix", "state_input", "control_input"):
        np.testing.assert_array_equal(getattr(design, name), getattr(free, name))
    p = math.exp(-bandwidth * 1e-3)
    off = np.abs(design.realised_poles - p) / (1 - p)
    assert np.all(off <= 0.05)
    assert np.all(off < [1e-15, 1e-6, 1e-3, 5e-3][order])  # measured: 0, 1e-7, 1e-4, 2.3e-3


def test_pole_tolerance_is_validated(paper_model):
    with pytest.raises(ValueError, match=r"^pole_tolerance must be a fraction >= 0 or None"):
        design_observer(paper_model, order=1, bandwidth=100.0, pole_tolerance=-1.0)
    with pytest.raises(TypeError, match=r"^pole_tolerance must be a fraction >= 0 or None"):
        design_observer(paper_model, order=1, bandwidth=100.0, pole_tolerance="5%")
    loose = design_observer(paper_model, order=5, bandwidth=50.0, pole_tolerance=0.1)
    assert loose.realised_poles.shape == (6,)
    with pytest.raises(ValueError, match=r"is realised at"):  # 7.4% off, measured
        design_observer(paper_model, order=5, bandwidth=50.0)
