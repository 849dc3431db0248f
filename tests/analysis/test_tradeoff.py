"""The accuracy/noise trade-off table: its entries, its interpolation and its outputs."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from hpdob import (
    ADRC,
    PD,
    PID,
    DisturbanceObserver,
    FilteredPD,
    NoiseTradeoff,
    ParameterTypeError,
    ParameterValueError,
    ServoLoop,
    ServoModel,
    design_observer,
    estimation_response,
    noise_gains,
    noise_tradeoff,
    observer_noise_gain,
)
from hpdob.observers import Family, Parameter, design_eso, register_family, unregister_family

TS = 1e-3
NOMINAL = ServoModel(2.8e-4)
BANDWIDTHS = np.array([20.0, 35.0, 50.0, 100.0, 200.0, 300.0, 400.0, 600.0, 800.0])


def impulse_noise_gain(order, bandwidth, samples=400):
    """RMS of the estimate per unit white velocity noise, by direct simulation: a unit impulse
    on the measured velocity fed to the runtime observer (angle and torque zero); the RMS gain
    of a stable LTI system for white noise is the root of the impulse response's sum of squares
    (400 samples: for bandwidths >= 100 rad/s the response has decayed below 1e-14 by then)."""
    obs = DisturbanceObserver(NOMINAL.discretize(TS), order=order, bandwidth=bandwidth)
    total = 0.0
    for k in range(samples):
        x = (0.0, 1.0 if k == 0 else 0.0)
        total += obs.estimate(x) ** 2
        obs.update(x, 0.0)
    return math.sqrt(total)


@pytest.fixture(scope="module")
def table():
    return noise_tradeoff(nominal=NOMINAL, Ts=TS, frequency=2.0, bandwidths=BANDWIDTHS)


def test_entries_are_the_closed_form_error_and_the_exact_noise_gain(table):
    assert isinstance(table, NoiseTradeoff)
    assert table.orders == (0, 1, 2, 3) and table.error_gain.shape == (4, 9)
    z = np.exp(2j * math.pi * 2.0 * TS)
    for i, m in enumerate(table.orders):
        lam = np.exp(-BANDWIDTHS * TS)
        # |1 - Q| = |(z - 1)/(z - lam)|^(m+1) for a bandwidth design, written out
        np.testing.assert_allclose(
            table.error_gain[i], np.abs((z - 1) / (z - lam)) ** (m + 1), rtol=1e-12
        )
        design = design_observer(NOMINAL.discretize(TS), order=m, bandwidth=BANDWIDTHS[4])
        assert table.noise_gain[i, 4] == pytest.approx(observer_noise_gain(design), rel=1e-14)
        assert np.all(np.diff(table.noise_gain[i]) > 0)  # more bandwidth, more noise
        assert np.all(np.diff(table.error_gain[i]) < 0)  # ... and less error
    with pytest.raises(ValueError, match="read-only"):
        table.error_gain[0, 0] = 0.0


def test_error_at_noise_and_improvement(table):
    # On its own grid points, an order's interpolated error is its error.
    np.testing.assert_allclose(table.error_at_noise(1, table.noise_gain[1]), table.error_gain[1])
    np.testing.assert_allclose(table.improvement(2, reference=2), 1.0)
    # Between grid points it is log-log linear; outside the covered noise range it is NaN.
    mid = math.sqrt(table.noise_gain[0, 3] * table.noise_gain[0, 4])
    expected = math.sqrt(table.error_gain[0, 3] * table.error_gain[0, 4])
    assert table.error_at_noise(0, mid)[0] == pytest.approx(expected, rel=1e-12)
    assert np.isnan(table.error_at_noise(0, [1e-9, 1e9])).all()
    # The HPDOb at the noise gain of a 400 rad/s DOb is more accurate (docs/analysis.md: 6.83).
    # Reference from first principles, sharing only design_observer with the table: noise gain =
    # root of the summed squared impulse response of the runtime observer (not the Lyapunov
    # solve of observer_noise_gain); the HPDOb bandwidth of equal noise is found by root-finding
    # on it; the errors are the closed form |1 - Q| = |(z - 1)/(z - lambda)|^(m+1) of
    # docs/analysis.md, section 2.
    gain = table.improvement(1)
    j = 6  # 400 rad/s
    assert BANDWIDTHS[j] == pytest.approx(400.0)
    target = impulse_noise_gain(0, 400.0)
    assert table.noise_gain[0, j] == pytest.approx(target, rel=1e-9)
    g1 = brentq(lambda g: impulse_noise_gain(1, g) - target, 100.0, 400.0, xtol=1e-9)
    assert g1 < 200.0  # ~184 rad/s (docs/analysis.md, section 5)
    z = np.exp(2j * math.pi * 2.0 * TS)
    error_dob = abs((z - 1) / (z - math.exp(-400.0 * TS)))
    error_hpdob = abs((z - 1) / (z - math.exp(-g1 * TS))) ** 2
    # The table interpolates log-log between its 100 and 200 rad/s HPDOb points: ~0.2 % off.
    assert gain[j] == pytest.approx(error_dob / error_hpdob, rel=1e-2)
    assert gain[j] > 1
    with pytest.raises(ParameterValueError, match=r"order must be one of \[0, 1, 2, 3\], got 5"):
        table.improvement(5)


def test_outputs(table, tmp_path):
    frame = table.to_pandas()
    assert list(frame.columns) == [
        "measurement",
        "order",
        "bandwidth_rad_s",
        "frequency_Hz",
        "error_gain",
        "noise_gain_velocity",
    ]
    assert len(frame) == 36
    path = table.to_csv(tmp_path / "tradeoff.csv")
    lines = path.read_text().splitlines()
    assert lines[0] == ",".join(frame.columns) and len(lines) == 37
    assert float(lines[5].split(",")[4]) == table.error_gain[0, 4]  # lossless
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = table.plot()
    ax = fig.axes[0]
    assert "noise gain" in ax.get_xlabel() and "[N m/(rad/s)]" in ax.get_xlabel()
    assert "2 Hz" in ax.get_ylabel()
    assert len(ax.get_lines()) >= 4
    plt.close(fig)


def test_bad_arguments():
    kw = {"nominal": NOMINAL, "Ts": TS, "frequency": 2.0, "bandwidths": [100.0]}
    with pytest.raises(ParameterValueError, match="bandwidths must hold at least one value"):
        noise_tradeoff(**{**kw, "bandwidths": []})
    with pytest.raises(ParameterValueError, match=r"bandwidths must be positive.*-5\.0"):
        noise_tradeoff(**{**kw, "bandwidths": [100.0, -5.0]})
    with pytest.raises(ParameterValueError, match=r"frequency must be below the Nyquist.*500 Hz"):
        noise_tradeoff(**{**kw, "frequency": 600.0})
    with pytest.raises(ParameterValueError, match="frequency must be a positive"):
        noise_tradeoff(**{**kw, "frequency": 0.0})
    with pytest.raises(ParameterValueError, match="orders must hold at least one"):
        noise_tradeoff(**kw, orders=())
    with pytest.raises(ParameterValueError, match=r"orders must not repeat, got \[1, 1\]"):
        noise_tradeoff(**kw, orders=(1, 1))
    with pytest.raises(ParameterValueError, match=r"orders must be non-negative.*-1"):
        noise_tradeoff(**kw, orders=(0, -1))
    with pytest.raises(ParameterTypeError, match="orders must be a sequence"):
        noise_tradeoff(**kw, orders=1)
    with pytest.raises(ParameterValueError, match="noise must be one of"):
        noise_tradeoff(**kw, noise="acceleration")
    with pytest.raises(ParameterValueError, match="does not reach the estimate"):
        noise_tradeoff(**kw, noise="position", gain_direction=(0.0, 1.0))
    with pytest.raises(ParameterTypeError, match="nominal must be a ServoModel"):
        noise_tradeoff(**{**kw, "nominal": NOMINAL.discretize(TS)})


def test_pole_tolerance_passes_through_to_the_designs():
    """Order 3 at 2.22 rad/s is not realisable to within the default tolerance (its four-fold
    pole moves by ~(1e-16)^(1/4)); the default raises naming it, ``pole_tolerance=None`` keeps
    the point and its figures are those of the same design built with ``None`` directly."""
    from hpdob import ServoModel, design_observer, estimation_response

    kwargs = {"nominal": ServoModel(2.8e-4), "Ts": 1e-3, "frequency": 2.0,
              "bandwidths": [2.220254341396507, 100.0], "orders": (3,)}  # fmt: skip
    with pytest.raises(ValueError, match=r"cannot be realised for order 3.*pole_tolerance=0\.05"):
        noise_tradeoff(**kwargs)
    table = noise_tradeoff(**kwargs, pole_tolerance=None)
    design = design_observer(ServoModel(2.8e-4).discretize(1e-3), order=3,
                             bandwidth=2.220254341396507, pole_tolerance=None)  # fmt: skip
    expected = abs(estimation_response(design, 2.0, error=True)[0])
    assert table.error_gain[0, 0] == expected


# -- the command's noise gain with any controller of the protocol (issue 20, section 2) ------

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import interconnect  # noqa: E402  (tests/interconnect.py: the loop assembled by python-control)


@pytest.mark.parametrize(
    "controller",
    [PID(50.0, 100.0, 5.0), FilteredPD(50.0, 5.0, time_constant=2e-3), ADRC(40.0)],
    ids=lambda c: type(c).__name__,
)
def test_command_noise_gain_of_any_controller_is_the_python_control_loop(controller):
    grid = [50.0, 200.0]
    loop = ServoLoop(plant=NOMINAL, nominal=NOMINAL, Ts=TS, controller=controller)
    for noise, channel in (("velocity", "n_omega"), ("position", "n_theta")):
        t = noise_tradeoff(loop, frequency=2.0, bandwidths=grid, orders=(0, 1), noise=noise)
        for i, m in enumerate(t.orders):
            for j, g in enumerate(grid):
                design = design_observer(NOMINAL.discretize(TS), order=m, bandwidth=g)
                system = interconnect.closed_loop(J=NOMINAL.J, b=NOMINAL.b, Ts=TS,
                                                  controller=loop.controller_system,
                                                  observer=design.system)  # fmt: skip
                expected = interconnect.h2(system, channel, "u")
                # abs: the round-off of a path that is structurally absent (the ADRC's
                # velocity noise: python-control gives 0, the Lyapunov route 1.9e-11 with
                # numpy 2.4.6 / scipy 1.17.1 / control 0.10.2, below 1e-11 with the registry
                # versions of 2026-12-01), against gains of 0.01-5 here
                assert t.u_noise_gain[i, j] == pytest.approx(expected, rel=1e-7, abs=1e-9)
        assert t.u_noise_gain.max() > 0 or noise == "velocity"  # ADRC reads no velocity
    # (rel=1e-7 tells them from the PD's: the PID's differ from it by 5e-5 relative)


def test_a_loop_or_its_keywords_not_both():
    loop = ServoLoop(plant=NOMINAL, nominal=NOMINAL, Ts=TS, controller=PD(50.0, 5.0))
    with pytest.raises(ParameterTypeError, match="not both; got a loop and Ts"):
        noise_tradeoff(loop, Ts=TS, frequency=2.0, bandwidths=[50.0])
    with pytest.raises(ParameterTypeError, match=r"missing: nominal, Ts"):
        noise_tradeoff(frequency=2.0, bandwidths=[50.0])
    with pytest.raises(ParameterTypeError, match="controller must be a PD, PID"):
        noise_tradeoff(nominal=NOMINAL, Ts=TS, frequency=2.0, bandwidths=[50.0], controller=3)


@pytest.mark.parametrize(
    "spec", [{"type": "eso"}, {"type": "eso", "form": "predictive"}], ids=["current", "predictive"]
)
def test_any_registered_family_the_eso_agrees_with_noise_gains_and_estimation_response(spec):
    """Each entry of the ESO's table against the direct computations on its design: the error
    |1 - Q| by estimation_response, the estimate's noise gain by the closed-loop Lyapunov
    gains of noise_gains (plant = nominal: the command cancels out of the estimate, so it
    equals the observer's own gain), the command's by the python-control loop."""
    grid, orders, loop = [100.0, 400.0], (0, 1, 2), ServoLoop(
        plant=NOMINAL, nominal=NOMINAL, Ts=TS, controller=PD(50.0, 5.0))  # fmt: skip
    t = noise_tradeoff(loop, frequency=2.0, bandwidths=grid, orders=orders, noise="position",
                       family=spec)  # fmt: skip
    assert t.orders == orders and t.measurements == ("position",) * 3
    assert t.family == spec
    assert t.labels[1] == f"ESO (m=1, {spec.get('form', 'current')})"
    for i, m in enumerate(orders):
        for j, g in enumerate(grid):
            design = design_eso(NOMINAL.discretize(TS), bandwidth=g, extended_order=m,
                                form=spec.get("form", "current"))  # fmt: skip
            gains = noise_gains(plant=NOMINAL, nominal=NOMINAL, Ts=TS, controller=PD(50.0, 5.0),
                                observer=design)  # fmt: skip
            error = abs(estimation_response(design, 2.0, error=True)[0])
            assert t.error_gain[i, j] == pytest.approx(error, rel=1e-12)
            assert t.noise_gain[i, j] == pytest.approx(gains.tau_hat_position, rel=1e-9)
            system = interconnect.closed_loop(J=NOMINAL.J, b=NOMINAL.b, Ts=TS,
                                              controller=loop.controller_system,
                                              observer=design.system)  # fmt: skip
            expected = interconnect.h2(system, "n_theta", "u")
            assert t.u_noise_gain[i, j] == pytest.approx(expected, rel=1e-7)
    assert t.improvement(2)[1] > 1  # the generalised ESO beats the classical at equal noise


def test_the_paper_family_through_the_registry_is_the_paper_path_bit_for_bit():
    kw = {"nominal": NOMINAL, "Ts": TS, "frequency": 2.0, "bandwidths": [50.0, 300.0],
          "orders": (0, 1, 2)}  # fmt: skip
    for measurement, noise in (("state", "velocity"), ("position", "encoder")):
        paper = noise_tradeoff(**kw, noise=noise, measurements=(measurement,))
        spec = noise_tradeoff(**kw, noise=noise, family={"type": "dob", "measurement": measurement})
        assert paper.family is None and spec.family["type"] == "dob"
        assert spec.measurements == paper.measurements and spec.labels == paper.labels
        for name in ("error_gain", "noise_gain"):
            assert np.array_equal(getattr(spec, name), getattr(paper, name))


@pytest.mark.parametrize(
    ("options", "error", "message"),
    [
        ({"family": "nope"}, ParameterValueError, "family must be one of 'dob', 'eso', 'kalman'"),
        ({"family": 3}, ParameterTypeError, "family must be a registered family's type name"),
        ({"family": {"type": "eso", "bandwidth": 5.0}}, ParameterValueError,
         r"family must not give bandwidth \(noise_tradeoff sets"),
        ({"family": {"type": "eso", "extended_order": 1}}, ParameterValueError,
         "family must not give extended_order"),
        ({"family": {"type": "eso", "form": "x"}}, ParameterValueError, "form must be one of"),
        ({"family": {"type": "eso", "gain": 1}}, ParameterValueError, "gain"),
        ({"family": "eso", "measurements": ("position",)}, ParameterValueError,
         r"measurements applies to the paper's family \(family=None\), not family 'eso'"),
        ({"family": "eso", "gain_direction": (0.0, 1.0)}, ParameterValueError,
         "gain_direction applies to the paper's family"),
        ({"family": "eso", "noise": "velocity"}, ParameterValueError,
         "noise must be 'position' or 'encoder' for family 'eso' .it measures the angle only"),
    ],
)  # fmt: skip
def test_family_bad_arguments(options, error, message):
    kw = {"nominal": NOMINAL, "Ts": TS, "frequency": 2.0, "bandwidths": [100.0],
          "noise": "position"}  # fmt: skip
    with pytest.raises(error, match=message) as info:
        noise_tradeoff(**{**kw, **options})
    assert "\n" not in str(info.value)


def test_a_family_without_an_order_key_takes_one_order():
    """A family registered here with no order key (the generalised ESO of order 2 as a fixed
    design): one row, the same numbers as the ESO's row of extended order 2."""
    geso2 = Family("tradeoff_geso2",
                   lambda model, *, bandwidth: design_eso(model, bandwidth=bandwidth,
                                                          extended_order=2),
                   (Parameter("bandwidth"),), required=("bandwidth",), order=None,
                   label=lambda spec: "GESO m=2")  # fmt: skip
    register_family(geso2)
    try:
        kw = {"nominal": NOMINAL, "Ts": TS, "frequency": 2.0, "bandwidths": [100.0, 400.0],
              "noise": "position"}  # fmt: skip
        with pytest.raises(ParameterValueError, match=r"orders must hold one value for family "
                           r"'tradeoff_geso2' \(it has no order key\), got \[0, 1\]"):  # fmt: skip
            noise_tradeoff(**kw, orders=(0, 1), family="tradeoff_geso2")
        fixed = noise_tradeoff(**kw, orders=(0,), family="tradeoff_geso2")
    finally:
        unregister_family("tradeoff_geso2")
    eso = noise_tradeoff(**kw, orders=(2,), family="eso")
    assert fixed.labels == ("GESO m=2",)
    np.testing.assert_array_equal(fixed.error_gain, eso.error_gain)
    np.testing.assert_array_equal(fixed.noise_gain, eso.noise_gain)
