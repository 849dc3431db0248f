"""Bad input to the describing functions and contact_limit_cycle (review of 2026-12-02):
a ParameterTypeError/ParameterValueError naming the parameter and the value, no numpy
warning (the suite runs with filterwarnings=error), no memory blow-up and no nonsense at the
edges of the float range; the bonded loop analysed as the unilateral one."""

from __future__ import annotations

import numpy as np
import pytest

from hpdob import Environment, ParameterTypeError, ParameterValueError, ServoLoop, paper
from hpdob.analysis import (
    contact_limit_cycle,
    quantiser_df,
    relay_df,
    saturation_df,
    tanh_friction_df,
)
from hpdob.analysis._describing import QUANTISER_EXACT_STEPS
from hpdob.controllers import ForceControl
from hpdob.models import InContact
from hpdob.observers import design_observer, reaction_torque_observer

DFS = {
    "relay": lambda a: relay_df(a, level=0.1),
    "tanh": lambda a: tanh_friction_df(a, coulomb=0.1, velocity=0.01),
    "tanh_noisy": lambda a: tanh_friction_df(a, coulomb=0.1, velocity=0.01, sigma=0.005),
    "quantiser": lambda a: quantiser_df(a, step=0.1),
    "saturation": lambda a: saturation_df(a, limit=1.0),
}


@pytest.mark.parametrize("df", DFS)
@pytest.mark.parametrize("amplitude", ["abc", "1.0", True, [1.0, "x"], 1 + 2j, {"a": 1}, [True]])
def test_an_amplitude_that_is_not_a_number_is_a_type_error(df, amplitude):
    with pytest.raises(ParameterTypeError, match=r"^amplitude must be positive finite ampl"):
        DFS[df](amplitude)


@pytest.mark.parametrize("df", DFS)
@pytest.mark.parametrize("amplitude", [np.nan, np.inf, -1.0, 0.0, [], [0.1, np.nan]])
def test_a_non_positive_or_non_finite_amplitude_is_a_value_error(df, amplitude):
    with pytest.raises(ParameterValueError, match=r"^amplitude must be positive finite ampl"):
        DFS[df](amplitude)


def test_numpy_scalars_are_accepted_as_centres_and_strings_refused_as_types():
    assert quantiser_df(1.0, step=0.1, offset=np.float32(0.01)) == quantiser_df(
        1.0, step=0.1, offset=float(np.float32(0.01)))  # fmt: skip
    assert quantiser_df(1.0, step=0.1, offset=np.int64(0)) == quantiser_df(1.0, step=0.1)
    assert saturation_df(2.0, limit=1.0, bias=np.int64(0)) == saturation_df(2.0, limit=1.0)
    for bad in ("0.01", None, True):
        with pytest.raises(ParameterTypeError, match=r"^offset must be a finite centre"):
            quantiser_df(1.0, step=0.1, offset=bad)
        with pytest.raises(ParameterTypeError, match=r"^bias must be a finite centre"):
            saturation_df(1.0, limit=1.0, bias=bad)
    with pytest.raises(ParameterValueError, match=r"\|offset\| <= 0\.05\).*got 0\.06"):
        quantiser_df(1.0, step=0.1, offset=0.06)
    with pytest.raises(ParameterValueError, match=r"\|bias\| < 1\.0\).*got 1\.0"):
        saturation_df(1.0, limit=1.0, bias=1.0)
    with pytest.raises(ParameterValueError, match=r"^offset must .* got nan"):
        quantiser_df(1.0, step=0.1, offset=np.nan)


def test_quantiser_df_of_a_huge_amplitude_is_one_without_the_exact_sum():
    """Beyond 2**20 steps the DF is 1 (the exact sum needed ~2 A/q thresholds: 1e300 of them
    raised 'Maximum allowed size exceeded', 1e9 exhausted the memory); at the bound the exact
    sum is within 1e-9 of 1 (its deviation falls as (q/A)^1.5: ~1e-5 at 1e3 steps)."""
    assert quantiser_df(1e300, step=1.0) == 1.0
    assert quantiser_df(1.0, step=1e-9, offset=3e-10) == 1.0
    below = QUANTISER_EXACT_STEPS * (1 - 1e-9)
    for x0 in (0.0, 0.2, 0.5, -0.37):
        assert abs(quantiser_df(below, step=1.0, offset=x0) - 1.0) < 1e-9
        assert abs(quantiser_df(1e3, step=1.0, offset=x0) - 1.0) > 1e-6  # the exact sum
    # mixed: the small amplitudes keep their exact values, bit for bit
    mixed = quantiser_df([0.4, 0.7, 1e300], step=1.0)
    assert mixed[0] == 0.0 and mixed[1] == quantiser_df(0.7, step=1.0) and mixed[2] == 1.0


def test_tanh_friction_df_at_the_edges_of_the_float_range():
    """No overflow warning where A/v or the noise exceeds the float range (tanh saturated),
    and with noise below v a tiny amplitude gives the mean slope E[c/v sech^2(n/v)], not the
    nodes' rounding over A (3e281 before)."""
    c, v, sigma = 0.1, 0.01, 0.005
    n = np.linspace(-10 * sigma, 10 * sigma, 20001)
    pdf = np.exp(-0.5 * (n / sigma) ** 2)
    slope = c / v * np.sum(pdf / np.cosh(n / v) ** 2) / np.sum(pdf)
    for a in (1e-300, 1e-12, 1e-8):
        assert tanh_friction_df(a, coulomb=c, velocity=v, sigma=sigma) == pytest.approx(
            slope, rel=1e-6)  # fmt: skip
    assert tanh_friction_df(1e300, coulomb=c, velocity=v, sigma=1.0) == pytest.approx(
        relay_df(1e300, level=c), rel=1e-9)  # fmt: skip
    assert tanh_friction_df(1.0, coulomb=c, velocity=1e-310) == pytest.approx(
        relay_df(1.0, level=c), rel=1e-9)  # fmt: skip
    assert tanh_friction_df(1.0, coulomb=c, velocity=1e-300, sigma=1e-200) == pytest.approx(
        relay_df(1.0, level=c), rel=1e-6)  # fmt: skip


def _loop():
    dob = design_observer(paper.NOMINAL.discretize(paper.TS), order=1, bandwidth=100.0)
    return ServoLoop(plant=paper.PLANT.replace(environment=Environment(10.0)),
                     nominal=paper.NOMINAL, Ts=paper.TS, controller=ForceControl(1000.0, kv=40.0),
                     observer=reaction_torque_observer(dob, friction=paper.PLANT,
                                                       velocity_filter=100.0),
                     sensor=paper.VIRTUAL_SENSOR, actuator=paper.VIRTUAL_ACTUATOR)  # fmt: skip


@pytest.mark.parametrize("flag", ["friction", "reaction_friction", "quantiser", "saturation"])
@pytest.mark.parametrize("value", ["no", None, 0, 1.0])
def test_contact_limit_cycle_flags_must_be_bools(flag, value):
    with pytest.raises(ParameterTypeError, match=rf"^{flag} must be True or False, got "):
        contact_limit_cycle(_loop(), tau_ref=0.05, levels=8, **{flag: value})


@pytest.mark.parametrize("kwargs", [{"tau_ref": 1e-300}, {"tau_ref": 0.05, "smallest": 1e-300}])
def test_contact_limit_cycle_at_tiny_amplitudes_warns_nothing(kwargs):
    """Overflowed in the noisy tanh DF (RuntimeWarning: overflow in square) before."""
    cycle = contact_limit_cycle(_loop(), levels=8, **kwargs)
    assert cycle.verdict in ("stable", "limit cycle", "unstable")


def test_contact_limit_cycle_of_the_bonded_loop_is_the_unilateral_ones():
    """The docstring's 'or bonded': InContact of the plant (loop_at(..., bonded=True)) was
    refused; its analysis is the same loop's."""
    loop = _loop()
    bonded = loop.replace(plant=InContact(loop.plant))
    a = contact_limit_cycle(loop, tau_ref=0.05, levels=8)
    b = contact_limit_cycle(bonded, tau_ref=0.05, levels=8)
    assert a.verdict == b.verdict and np.array_equal(a.radius, b.radius)
    with pytest.raises(ParameterValueError, match=r"or InContact of one"):
        contact_limit_cycle(loop.replace(plant=paper.PLANT), tau_ref=0.05)


def test_contact_limit_cycle_plot_has_units_and_a_legend_off_the_axes():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = contact_limit_cycle(_loop(), tau_ref=0.05, levels=12).plot()
    ax = fig.axes[0]
    assert ax.get_xlabel().endswith("[%]") and ax.get_ylabel().endswith("[-]")
    legend = ax.get_legend()
    assert legend is not None
    texts = [t.get_text() for t in legend.get_texts()]
    assert "quasi-linear loop" in texts and "|z| = 1" in texts
    fig.canvas.draw()
    box, axes = legend.get_window_extent(), ax.get_window_extent()
    assert box.x0 >= axes.x1  # right of the axes, not over the data
    plt.close(fig)


@pytest.mark.parametrize("df", DFS)
def test_tiny_amplitudes_warn_nothing_and_subnormal_ones_are_refused(df):
    """1e-300: finite gains, no overflow warning; below the smallest normal float 1/A
    overflows, refused naming the value."""
    assert np.isfinite(DFS[df](1e-300))
    with pytest.raises(ParameterValueError, match=r"^amplitude must be positive .* got 1e-320"):
        DFS[df](1e-320)


def test_tiny_amplitudes_have_the_small_signal_limits():
    assert saturation_df(1e-300, limit=1.0, bias=0.3) == 1.0
    assert quantiser_df(1e-300, step=0.1, offset=0.01) == 0.0
