"""The design check's refusal of an ill-conditioned regression (``_design.check_design``):
decided as by the full singular value decomposition of the column-scaled regression, which
it computes only near the limit (issue 25: no left vectors as long as the log otherwise); and
the layout's columns, a read-only view of the rows when all four are estimated in order."""

from __future__ import annotations

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
