"""The design check's refusal of an ill-conditioned regression (``_design.check_design``):
decided as by the full singular value decomposition of the column-scaled regression, which
it computes only near the limit (issue 25: no left vectors as long as the log otherwise); and
the layout's columns, a read-only view of the rows when all four are estimated in order; the
singular cases of the condition and the variance inflation; and the refusals of logs that move
one way, in the words of one log or several."""

from __future__ import annotations

import re

import numpy as np
import pytest

from hpdob._validation import ParameterValueError
from hpdob.identification._design import MAX_CONDITION, check_design, make_layout


def _regression(condition: float) -> np.ndarray:
    """Rows ``[qdd, qd, 1]`` (friction="viscous") whose speed barely varies: scaled condition
    about ``condition`` (1.98 / the speed's spread, measured)."""
    rng = np.random.default_rng(3)
    n = 2000
    spread = 1.98 / condition
    return np.column_stack([rng.standard_normal(n), 1.0 + spread * rng.standard_normal(n),
                            np.ones(n)])  # fmt: skip


@pytest.mark.parametrize("condition", [3e5, 7e5, 9.9e5, 1.01e6, 3e6])
def test_condition_check_decides_as_the_full_decomposition(condition):
    X = _regression(condition)
    norms = np.linalg.norm(X, axis=0)
    _, singular, vt = np.linalg.svd(X / norms, full_matrices=False)  # the check before
    expected = singular[0] / singular[-1]
    layout = make_layout("viscous", None, "per-log", 1)
    if expected <= MAX_CONDITION:
        check_design([], layout, X)
        return
    weakest = ["J", "b", "offset"][int(np.argmax(np.abs(vt[-1])))]
    with pytest.raises(ParameterValueError, match="does not excite") as err:
        check_design([], layout, X)
    assert f"condition number {expected:.3g} " in str(err.value)
    assert f"{weakest} is the least identifiable" in str(err.value)


def test_the_four_columns_in_order_are_a_read_only_view_of_the_rows():
    """With J, b, coulomb and one offset estimated, the columns are the rows themselves:
    not copied (the same memory, bit for bit), but a write through them raises instead of
    corrupting the regression they came from; the other layouts give a new array."""
    rng = np.random.default_rng(1)
    M = rng.standard_normal((50, 4))
    before = M.copy()
    columns = make_layout("viscous+coulomb", None, "per-log", 1).columns(M, 0)
    assert np.shares_memory(columns, M) and np.array_equal(columns, M)
    with pytest.raises(ValueError, match="read-only"):
        columns[0, 0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        columns *= 2.0
    assert np.array_equal(M, before) and M.flags.writeable  # M itself stays writeable
    other = make_layout("viscous", None, "per-log", 1).columns(M, 0)
    assert not np.shares_memory(other, M)
    np.testing.assert_array_equal(other, M[:, [0, 1, 3]])


def _inflation_by_regression(columns: np.ndarray) -> np.ndarray:
    """1 / (1 - R^2) of each column regressed on the others and a constant (the definition,
    by least squares: independent of the correlation matrix the check inverts)."""
    out = []
    for j in range(columns.shape[1]):
        others = np.column_stack([np.delete(columns, j, axis=1), np.ones(columns.shape[0])])
        fit = others @ np.linalg.lstsq(others, columns[:, j], rcond=None)[0]
        centred = columns[:, j] - columns[:, j].mean()
        r2 = 1.0 - np.sum((columns[:, j] - fit) ** 2) / np.sum(centred**2)
        out.append(1.0 / (1.0 - r2))
    return np.array(out)


@pytest.mark.parametrize("mix", [0.0, 0.9, 0.999])
@pytest.mark.parametrize("rows", [50, 4096, 4097, 10_000])
def test_variance_inflation_is_its_definition_over_blocks(mix, rows):
    """Summed over blocks of ``ROWS`` rows (one, one and a row, several): the definition."""
    from hpdob.identification._design import variance_inflation

    rng = np.random.default_rng(7)
    a, b, c = rng.standard_normal((3, rows))
    columns = np.column_stack([a, mix * a + (1 - mix) * b, 3.0 + c])
    reference = _inflation_by_regression(columns)
    # The check inverts the correlation matrix: accurate to about cond * eps, its condition
    # number about twice the largest inflation (~1e6 at mix 0.999: hpdob 1.2e-9 from a 40-digit
    # mpmath inverse on numpy 2.4.6, the least-squares definition 3e-12); a few units of it
    rtol = max(1e-12, 50 * np.finfo(float).eps * reference.max())
    np.testing.assert_allclose(variance_inflation(columns), reference, rtol=rtol)
    constant = columns.copy()
    constant[:, 1] = 0.5  # its mean exactly 0.5: centred exactly 0
    assert np.isinf(variance_inflation(constant)[1])


@pytest.mark.parametrize("rows", [40, 4096, 9000])
def test_scaled_condition_is_that_of_the_singular_values(rows):
    """The triangular factor's condition, block by block: the scaled matrix's, to 1e-9."""
    from hpdob.identification._design import scaled_condition

    rng = np.random.default_rng(5)
    for spread in (1.0, 1e-3, 1e-5):
        X = np.column_stack([rng.standard_normal(rows), 1.0 + spread * rng.standard_normal(rows),
                             np.ones(rows)])  # fmt: skip
        singular = np.linalg.svd(X / np.linalg.norm(X, axis=0), compute_uv=False)
        assert scaled_condition(X) == pytest.approx(singular[0] / singular[-1], rel=1e-9)
    assert scaled_condition(np.column_stack([np.ones(rows), np.zeros(rows)])) == np.inf


def test_exactly_collinear_columns_have_infinite_inflation():
    """Two equal columns (alternating +-1: centred exactly, their correlation exactly 1): the
    correlation matrix is singular and every column's factor is inf."""
    from hpdob.identification._design import variance_inflation

    a = np.tile([1.0, -1.0], 8)
    inflation = variance_inflation(np.column_stack([a, a, np.arange(16.0)]))
    assert inflation.shape == (3,) and np.all(np.isinf(inflation))


def test_a_singular_regression_has_infinite_condition_without_a_warning():
    """A triangular factor with an exactly zero singular value: inf, not a division by 0."""
    import warnings

    from hpdob.identification._design import scaled_condition

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert scaled_condition(np.array([[1.0, 1.0], [0.0, 0.0], [0.0, 0.0]])) == np.inf
        assert scaled_condition(np.array([[3.0, -2.0, 0.0], [0.0, 0.0, 1.0], [0.0] * 3])) == np.inf


def test_a_well_conditioned_regression_is_passed_without_a_copy_of_it():
    """Far from the limit the block-wise gate decides: no scaled copy of the regression and
    no left singular vectors (each as large as it), no squares of every entry for the column
    norms (``np.linalg.norm(X, axis=0)``'s, one regression's size): blocks of rows only
    (0.055 of the regression measured, 2026-12-03)."""
    import tracemalloc

    rng = np.random.default_rng(4)
    n = 200_000
    X = np.column_stack([rng.standard_normal(n), 1.0 + rng.standard_normal(n), np.ones(n)])
    layout = make_layout("viscous", None, "per-log", 1)
    tracemalloc.start()
    try:
        check_design([], layout, X)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 0.25 * X.nbytes, (peak, X.nbytes)


T = np.arange(5000) * 1e-3
U = np.sin(2 * np.pi * T) + 0.5 * np.sin(2 * np.pi * 3.3 * T)
RAMP = 0.1 * T + 0.01 * np.sin(T)  # always forward
STOPS = 0.1 * (T - np.sin(2 * np.pi * T) / (2 * np.pi))  # forward, at rest once a second
START = "theta moves in one direction only ({}: 100 % of its travel in the regression rows{}): "


@pytest.mark.parametrize(("sign", "word"), [(1.0, "positive"), (-1.0, "negative")])
def test_a_one_way_log_is_refused_saying_which_way_and_the_rests_dropped(sign, word):
    """One log: its own message (not the several logs'), with the rows dropped at rest only
    where there were some."""
    from hpdob import identify

    with pytest.raises(ParameterValueError) as err:
        identify(T, sign * RAMP, U, diagnostics=False)
    assert str(err.value).startswith(START.format(word, ""))
    assert "identify([log, other], offsets='shared')" in str(err.value)
    with pytest.raises(ParameterValueError) as err:
        identify(T, sign * STOPS, U, diagnostics=False)
    rests = r", after dropping \d+ rows at rest \(filtered speed below 0.004, 2 % of its largest\)"
    assert re.match(re.escape(START.format(word, "@")).replace("@", rests), str(err.value))


def test_one_way_logs_are_refused_with_the_way_out_their_directions_leave():
    """Per-log offsets: logs in opposite directions are separated by a shared offset, logs
    the same way need another log; a shared offset does not separate logs the same way."""
    from hpdob import identify
    from hpdob.identification import Log

    forward, again = Log(T, RAMP, U, source="a"), Log(T, 2 * RAMP, U, source="b")
    backward = Log(T, -RAMP, U, source="b")
    start = "every log moves in one direction only ({}): coulomb and the {} cannot be told apart"
    with pytest.raises(ParameterValueError) as err:
        identify([forward, backward], diagnostics=False)
    assert str(err.value).startswith(start.format("a positive, b negative", "offsets"))
    assert "To identify them: offsets='shared' (one offset for all) separates them" in str(
        err.value
    )
    for offsets, noun in (("per-log", "offsets"), ("shared", "offset")):
        with pytest.raises(ParameterValueError) as err:
            identify([forward, again], offsets=offsets, diagnostics=False)
        assert str(err.value).startswith(start.format("a positive, b positive", noun))
        assert str(err.value).endswith("or add a log that moves the other way, with "
                                       "offsets='shared'")  # fmt: skip


def test_fewer_rows_than_columns_have_infinite_condition():
    """Rank at most the rows: a wide regression cannot separate its columns, whatever its
    triangular factor's few singular values say."""
    from hpdob.identification._design import scaled_condition

    assert scaled_condition(np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 7.0]])) == np.inf
    assert np.isfinite(scaled_condition(np.array([[1.0, 2.0], [4.0, 5.0], [0.0, 1.0]])))


@pytest.mark.parametrize(("inflation", "refused"), [(1000.5, True), (999.5, False)])
def test_the_variance_inflation_limit_is_a_thousand(inflation, refused):
    """Two columns with correlation r, 1 / (1 - r^2) = ``inflation`` (exactly centred,
    orthogonal patterns a and c; b = a + k c): refused just above 1000, passed just below."""
    a, c = np.tile([1.0, -1.0, 1.0, -1.0], 4), np.tile([1.0, 1.0, -1.0, -1.0], 4)
    X = np.column_stack([a, a + c / np.sqrt(inflation - 1.0), np.ones(16)])
    layout = make_layout("viscous", None, "per-log", 1)
    if not refused:
        check_design([], layout, X)
        return
    with pytest.raises(ParameterValueError, match=r"J and b cannot .* limit 1000\)"):
        check_design([], layout, X)


def test_an_exactly_zero_column_is_refused_as_unexcited_without_a_warning():
    """The full decomposition's last singular value exactly 0: condition inf, no division
    warning, and the zero column named the least identifiable."""
    import warnings

    a, c = np.tile([1.0, -1.0, 1.0, -1.0], 4), np.tile([1.0, 1.0, -1.0, -1.0], 4)
    layout = make_layout("viscous", None, "per-log", 1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ParameterValueError, match=r"number inf .*; offset is the least"):
            check_design([], layout, np.column_stack([a, c, np.zeros(16)]))


def test_a_layout_needs_something_to_estimate_and_viscous_friction_no_coulomb():
    """The offset fixed alone leaves J, b and coulomb to estimate; everything fixed is
    refused; friction='viscous' refuses a fixed Coulomb friction of either sign."""
    layout = make_layout("viscous+coulomb", {"offset": 0.0}, "per-log", 1)
    assert layout.free == (0, 1, 2) and layout.n_offsets == 0
    every = {"J": 1.0, "b": 0.0, "coulomb": 0.0, "offset": 0.0}
    with pytest.raises(ParameterValueError, match="every parameter is fixed"):
        make_layout("viscous+coulomb", every, "per-log", 1)
    for coulomb in (0.1, -0.1):
        with pytest.raises(ParameterValueError, match="friction='viscous' has no Coulomb"):
            make_layout("viscous", {"coulomb": coulomb}, "per-log", 1)
    assert make_layout("viscous", {"coulomb": 0.0}, "per-log", 1).free == (0, 1)


@pytest.mark.parametrize("condition", [7e5, 3e6])
def test_near_the_limit_the_decomposition_holds_thin_factors_only(condition):
    """Within a factor 2 of the limit the full decomposition decides: a scaled copy and the
    thin left vectors (rows x columns), under three regressions at its tracemalloc peak
    (measured 2.12 and 2.08); the square left factor alone would be rows x rows (668)."""
    import tracemalloc

    X = _regression(condition)
    layout = make_layout("viscous", None, "per-log", 1)
    tracemalloc.start()
    try:
        try:
            check_design([], layout, X)
        except ParameterValueError:
            assert condition > MAX_CONDITION
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 3 * X.nbytes, peak / X.nbytes
