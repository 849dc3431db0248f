"""Issue 23: diagnostics, several logs, restricted friction models and validation on data the
model was not fitted to. Logs are SYNTHETIC (hpdob.simulate, tests/synthetic_logs.py) unless
they are EMPS's."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

import hpdob
from hpdob import PD, Encoder, ParameterTypeError, ParameterValueError, ServoModel, identify
from hpdob.identification import FeedbackLoop, IdentificationWarning, Log, emps, emps_loop
from hpdob.identification._result import _relative
from hpdob.identification._simfit import nrmse_fit
from synthetic_logs import J_TRUE, synthetic_log


@pytest.fixture(scope="module")
def issue_log():
    return synthetic_log(kind="chirp+prbs", counts=4096, Ts=5e-4, coulomb=0.03, seed=0)


# -- diagnostics -----------------------------------------------------------------------------------
def test_a_right_identification_is_silent(issue_log):
    fit = issue_log.log.identify()  # filterwarnings = error: any warning fails
    assert fit.warnings == ()
    assert fit.fits[0]["velocity_fit_percent"] > 95.0
    assert set(fit.sensitivity) == {"x2", "/2"}


def test_a_biased_identification_warns_and_says_what_to_try(issue_log):
    """IDIM-LS with the benchmark's rules on the issue's log (J -5.9 %): halving the filters'
    bandwidth moves J by far more than 2 % and its standard deviation."""
    with pytest.warns(IdentificationWarning, match=r"J moves by .*Try method='auto'"):
        fit = issue_log.log.identify(method="idim-ls")
    assert fit.J / issue_log.J - 1.0 < -0.04


def test_a_model_that_does_not_reproduce_the_log_warns(issue_log):
    """J held at half its value: the simulated velocity fits the log by less than 90 %."""
    with pytest.warns(IdentificationWarning):
        fit = issue_log.log.identify(fixed={"J": 0.5 * J_TRUE})
    assert fit.fits[0]["velocity_fit_percent"] < 90.0
    message = next(m for m in fit.warnings if "does not reproduce" in m)
    assert "velocity fit" in message and "Try min_speed" in message


def test_near_zero_parameters_print_absolute_uncertainties(issue_log):
    """An offset within noise of 0: the summary gives its absolute standard deviation, not a
    relative one of thousands of %."""
    fit = issue_log.log.identify()
    fit = replace(fit, offset=0.045 * fit.offset_std)
    line = next(x for x in fit.summary().splitlines() if x.strip().startswith("offset"))
    assert "within 2 std of 0" in line and "%" not in line
    assert _relative(0.045, 1.0, False) == "within 2 std of 0"  # the issue's 2232 %
    assert _relative(2.0, 0.5, False) == "25.00 %"
    assert _relative(2.0e-3, 0.0, True) == "fixed"


def test_the_loop_input_error_is_measured_in_the_band_identified():
    """The audit's "input error 86 %": on a 4096-count PD log at 0.5 ms the logged input is
    mostly the controller's response to the encoder's quantisation, which the noise-free loop
    simulation lacks. In the band the regression uses (below the decimation filter's cut-off)
    the simulated input matches to 1 %; the summary gives both and says why."""
    s = synthetic_log(kind="pd", counts=4096, Ts=5e-4, coulomb=0.03, seed=1)
    fit = s.log.identify(loop=s.loop)
    simulation = fit.simulation
    assert simulation["input_error_percent"] > 50.0
    assert simulation["input_error_band_percent"] < 2.0
    assert simulation["band_hz"] == fit.settings["decimation_cutoff"]
    line = next(x for x in fit.summary().splitlines() if "loop simulated" in x)
    assert "(the band identified)" in line and "quantisation" in line


def test_the_loop_errors_are_those_of_the_simulated_traces_bit_for_bit():
    """identify computes the loop's errors in two arrays of the log's length (the command
    simulated twice): they are the formulas' numbers on the traces of one simulation through
    the loop (simulate_fit with keep=True), bit for bit, and the fit's position is its."""
    import dataclasses

    from hpdob.identification._identify import in_band
    from hpdob.identification._regression import Settings
    from hpdob.identification._simfit import simulate_fit

    s = synthetic_log(kind="pd", counts=4096, Ts=5e-4, coulomb=0.03, seed=1)
    fit = s.log.identify(loop=s.loop)
    settings = Settings(**{f.name: fit.settings[f.name] for f in dataclasses.fields(Settings)})
    log = s.log
    traces = simulate_fit((fit.J, fit.b, fit.coulomb, fit.offset), log.t, log.theta, log.u,
                          s.loop, settings, keep=True)  # fmt: skip

    def relative(measured, simulated):
        return 100.0 * float(np.linalg.norm(measured - simulated)) / float(np.linalg.norm(measured))

    assert np.array_equal(fit.theta_simulated, traces.theta_simulated)
    assert fit.simulation["position_error_percent"] == relative(log.theta, traces.theta_simulated)
    assert fit.simulation["input_error_percent"] == relative(log.u, traces.u_simulated)
    band = in_band((log.u, traces.u_simulated), settings)
    assert fit.simulation["input_error_band_percent"] == relative(*band)
    assert fit.fits[0]["position_fit_percent"] == traces.position_fit


def test_in_band_keeps_the_band_and_removes_what_is_above():
    """A 2 Hz sine plus a 200 Hz one, band 17 Hz: the 2 Hz sine is what is left (to 1e-3)."""
    from hpdob.identification._identify import in_band
    from hpdob.identification._regression import resolve_settings

    settings = resolve_settings(5e-4, bandwidth=8.5)  # decimation cut-off 0.8 fs / (2 dec)
    t = np.arange(20000) * 5e-4
    slow = np.sin(2 * np.pi * 2.0 * t)
    (kept,) = in_band([slow + np.sin(2 * np.pi * 200.0 * t)], settings)
    assert settings.decimation_cutoff < 20.0
    np.testing.assert_allclose(kept[1000:-1000], slow[1000:-1000], atol=1e-3)


def test_the_summary_says_how_far_the_filters_move_the_estimate(issue_log):
    fit = issue_log.log.identify()
    line = next(x for x in fit.summary().splitlines() if "bandwidth halved" in x)
    assert "moves in standard deviations: J" in line


def test_the_sensitivity_allowances_are_the_targets_own():
    """Issue 23's targets, written out: b within 10 % or 0.02 J 2 pi B with B the
    EXCITATION's bandwidth (a chirp to 10 Hz: B between 5 and 10 Hz, whatever the filters),
    Coulomb within 5 % or 2 % of the input's RMS, J 2 % (inside its 3 % target)."""
    import math
    from types import SimpleNamespace

    from hpdob.identification._sensitivity import allowances, excitation_bandwidth

    s = synthetic_log(kind="chirp", counts=65536, Ts=2.5e-4, coulomb=0.03, seed=0)
    band = excitation_bandwidth(s.log)
    assert 5.0 <= band <= 10.5
    layout = SimpleNamespace(parameters=lambda estimate, i: estimate)
    J, b, c = 1.2e-3, 2e-3, 0.03
    allowed = allowances(SimpleNamespace(estimate=np.array([J, b, c, 0.0])), layout, [s.log])
    rms = math.sqrt(np.mean(s.log.u**2))
    assert allowed["J"] == pytest.approx(0.02 * J)
    assert allowed["b"] == pytest.approx(max(0.1 * b, 0.02 * J * 2 * math.pi * band))
    assert allowed["coulomb"] == pytest.approx(max(0.05 * c, 0.02 * rms))
    # a coarse encoder's PD: the input is mostly the loop's answer to quantisation (its 95 %
    # power frequency near 2 kHz); capped at the position's signal band
    pd = synthetic_log(kind="pd", counts=1024, Ts=2.5e-4, seed=0)
    assert excitation_bandwidth(pd.log) < 20.0


def test_in_auto_mode_the_doubled_line_cannot_warn(issue_log):
    """The summary's "doubled" line says it is for information: with the filters read from
    the log only halving counts; with the benchmark's rules both lines can warn."""
    fit = issue_log.log.identify()
    doubled = next(x for x in fit.summary().splitlines() if "bandwidth doubled" in x)
    assert "for information only" in doubled and "only halving can warn" in doubled
    halved = next(x for x in fit.summary().splitlines() if "bandwidth halved" in x)
    assert "b 10 % or 0.02 J 2 pi B, Coulomb 5 % or 2 % of the input's RMS" in halved
    with pytest.warns(IdentificationWarning):
        ls = issue_log.log.identify(method="idim-ls")
    doubled = next(x for x in ls.summary().splitlines() if "bandwidth doubled" in x)
    assert "for information only" not in doubled


def test_a_short_log_says_the_halving_was_not_checked():
    """0.65 s of the issue's excitation: the filters with their bandwidth halved need more
    samples than the log has, so the check is skipped, and the result and summary say so."""
    s = synthetic_log(kind="chirp+prbs", counts=65536, Ts=1e-3, coulomb=0.03, seed=0,
                      duration=0.65)  # fmt: skip
    fit = s.log.identify()
    assert "/2" not in fit.sensitivity
    assert any("halved was not checked" in note for note in fit.notes)
    assert "note: the filters' sensitivity with their bandwidth halved was not checked" in (
        fit.summary()
    )
    assert fit.to_dict()["notes"] == list(fit.notes)


@pytest.mark.parametrize(
    ("kind", "counts", "Ts", "fraction", "closed"),
    [("chirp+prbs", 4096, 5e-4, 0.1, False), ("pd", 1024, 2.5e-4, 0.1, True),
     ("multisine", 16384, 1e-3, 0.1, False), ("chirp", 65536, 2.5e-4, 0.0, False)],
)  # fmt: skip
def test_the_truth_lies_within_statistical_plus_systematic(kind, counts, Ts, fraction, closed):
    """The audit: the reported +- excluded the truth by 5-20 standard deviations (the method's
    bias under the filters is not in it). ``systematic`` (the spread over the filters'
    bandwidth x1, x2, /2) beside ``std``: the truth within 2 (std + systematic), the
    2-standard-deviation band of the EMPS test, on grid points at Ts <= 1 ms (at 2 ms the
    sampling's bias of J is not revealed by the filters: docs/real-data.md)."""
    s = synthetic_log(kind=kind, counts=counts, Ts=Ts, coulomb_fraction=fraction, seed=0)
    fit = s.log.identify(loop=s.loop if closed else None)
    assert set(fit.systematic) == {"J", "b", "coulomb", "offset"}
    for name, truth in (("J", s.J), ("b", s.b), ("coulomb", s.coulomb)):
        band = fit.std[name] + fit.systematic[name]
        assert abs(getattr(fit, name) - truth) <= 2.0 * band, (name, getattr(fit, name), band)
    line = next(x for x in fit.summary().splitlines() if x.strip().startswith("inertia"))
    assert "systematic +-" in line
    assert fit.to_dict()["systematic"] == dict(fit.systematic)


# -- restricted models -----------------------------------------------------------------------------
def test_fixed_parameters_are_held_at_their_value(issue_log):
    s = issue_log
    fit = s.log.identify(fixed={"b": s.b})
    assert fit.b == s.b and fit.b_std == 0.0
    np.testing.assert_allclose(fit.J, s.J, rtol=0.015)
    np.testing.assert_allclose(fit.coulomb, s.coulomb, rtol=0.025)
    assert "(fixed)" in fit.summary()


def test_viscous_only_model_on_a_log_without_coulomb_friction():
    s = synthetic_log(kind="multisine", counts=16384, Ts=1e-3, coulomb=0.0, seed=2)
    fit = s.log.identify(friction="viscous")
    assert fit.coulomb == 0.0 and fit.coulomb_std == 0.0
    np.testing.assert_allclose(fit.J, s.J, rtol=0.01)
    np.testing.assert_allclose(fit.b, s.b, rtol=0.05)
    # the audit: the lumped Coulomb friction printed as "0 (fixed)"
    line = next(x for x in fit.summary().splitlines() if x.strip().startswith("Coulomb"))
    assert "lumps it into the offset" in line and "(fixed)" not in line


#: A motor that only moves one way: closed-loop tracking of a ramp with a ripple,
#: r_dot = 2 + 1.5 cos(2 pi t) > 0, from its initial speed (SYNTHETIC).
ONE_WAY_PLANT = ServoModel(J_TRUE, 2e-3, coulomb=0.03, coulomb_velocity=1e-3)


def one_way_log(direction: float, offset: float, seed: int):
    Ts, n = 5e-4, 12000
    t = np.arange(n) * Ts
    w = 2 * np.pi
    r = direction * (2 * t + 1.5 / w * np.sin(w * t))
    r_dot = direction * (2 + 1.5 * np.cos(w * t))
    r_ddot = direction * (-1.5 * w * np.sin(w * t))
    table = {"r": r, "r_dot": r_dot, "r_ddot": r_ddot}

    def reference(times):
        k = np.rint(np.asarray(times) / Ts).astype(int)
        return table["r"][k], table["r_dot"][k], table["r_ddot"][k]

    omega = 2 * np.pi * 5
    controller = PD(omega**2, 2 * omega)
    result = hpdob.simulate(
        plant=ONE_WAY_PLANT, nominal=ServoModel(J_TRUE), Ts=Ts, controller=controller,
        sensor=Encoder(16384), reference=reference, duration=n * Ts, x0=(0.0, r_dot[0]),
    )  # fmt: skip
    rng = np.random.default_rng(seed)
    u = result.u + offset + 0.01 * np.std(result.u) * rng.standard_normal(n)
    log = Log(result.t, result.theta_measured, u, source=f"one-way {direction:+g}")
    # the logged input carries the offset: the loop's command does not
    loop = FeedbackLoop.from_pd(controller, J_n=J_TRUE, reference=r, reference_velocity=r_dot,
                                reference_acceleration=r_ddot)  # fmt: skip
    return log, loop


@pytest.fixture(scope="module")
def one_way():
    return one_way_log(+1.0, 0.004, 1), one_way_log(-1.0, 0.004, 2)


def test_a_one_way_log_is_refused_with_the_way_out(one_way):
    log, loop = one_way[0]
    with pytest.raises(ParameterValueError, match=r"one direction only.*friction='viscous'"):
        log.identify(loop=loop)


def test_a_one_way_log_is_identified_with_coulomb_and_offset_lumped(one_way):
    """friction='viscous': the offset takes offset + coulomb (0.004 + 0.03 N m)."""
    log, loop = one_way[0]
    fit = log.identify(loop=loop, friction="viscous")
    np.testing.assert_allclose(fit.J, J_TRUE, rtol=0.03)
    np.testing.assert_allclose(fit.b, 2e-3, rtol=0.1)
    np.testing.assert_allclose(fit.offset, 0.004 + 0.03, atol=0.02 * 0.03 + 5e-4)
    known = log.identify(loop=loop, fixed={"coulomb": 0.03})
    assert known.offset == pytest.approx(0.004, abs=1e-3)


def test_one_way_logs_in_opposite_directions_identify_coulomb_with_a_shared_offset(one_way):
    logs = [log for log, _ in one_way]
    loops = [loop for _, loop in one_way]
    with pytest.raises(ParameterValueError, match="offsets='shared'"):
        identify(logs, loop=loops)  # one offset per log: each lumps its Coulomb friction
    fit = identify(logs, loop=loops, offsets="shared")
    np.testing.assert_allclose(fit.J, J_TRUE, rtol=0.03)
    np.testing.assert_allclose(fit.coulomb, 0.03, rtol=0.05)
    assert fit.offset == pytest.approx(0.004, abs=1e-3)
    assert fit.offsets == (fit.offset, fit.offset)


# -- several logs ----------------------------------------------------------------------------------
def _with_offset(s, offset):
    log = s.log
    return Log(log.t, log.theta, log.u + offset, source=f"{log.source}{offset:+g}")


def test_several_logs_share_J_b_coulomb_with_one_offset_each():
    a = synthetic_log(kind="chirp", counts=4096, Ts=5e-4, coulomb=0.03, seed=3)
    b = synthetic_log(kind="multisine", counts=4096, Ts=1e-3, coulomb=0.03, seed=4)
    logs = [_with_offset(a, 0.01), _with_offset(b, -0.02)]
    fit = identify(logs)
    np.testing.assert_allclose(fit.J, a.J, rtol=0.015)
    np.testing.assert_allclose(fit.b, a.b, rtol=0.05)
    np.testing.assert_allclose(fit.coulomb, 0.03, rtol=0.025)
    np.testing.assert_allclose(fit.offsets, [0.01, -0.02], atol=1e-3)
    assert fit.offset == pytest.approx(np.mean(fit.offsets))
    assert fit.sources == tuple(log.source for log in logs)
    assert len(fit.settings["logs"]) == 2 and set(fit.run.tolist()) == {0, 1}
    alone = [identify(log) for log in logs]
    # the shared J lies between the logs' own; its batch-means standard deviation counts how
    # far the logs disagree (each log's scores no longer sum to zero), so it is not below
    # both of theirs (chirp alone J +1.3 %, 6 of its std off the truth; multisine +0.07 %)
    assert min(f.J for f in alone) <= fit.J <= max(f.J for f in alone)
    assert fit.J_std < max(f.J_std for f in alone)
    assert "offset of" in fit.summary()
    assert "(Ts = 0.0005, 0.001 s)" in fit.summary().splitlines()[0]  # each log's, not the first's
    assert "run" in fit.to_pandas().columns


def test_several_logs_refuse_bad_arguments(issue_log):
    log = issue_log.log
    with pytest.raises(ParameterTypeError, match="one FeedbackLoop for several logs"):
        identify([log, log], loop=FeedbackLoop(np.zeros(len(log)), kp=1.0, kd=1.0))
    with pytest.raises(ParameterTypeError, match=r"logs\[1\] must be a Log"):
        identify([log, "run.csv"])
    with pytest.raises(ParameterTypeError, match="give t, theta and u"):
        identify(log.t, log.theta)
    with pytest.raises(ParameterValueError, match="fixed has an unknown parameter 'c'"):
        identify(log, fixed={"c": 0.03})
    with pytest.raises(ParameterValueError, match="friction must be one of"):
        identify(log, friction="coulomb")
    with pytest.raises(ParameterValueError, match=r"friction='viscous' has no Coulomb"):
        identify(log, friction="viscous", fixed={"coulomb": 0.03})


# -- validation ------------------------------------------------------------------------------------
def test_nrmse_fit_is_matlabs_compare():
    """100 (1 - ||y - yh|| / ||y - mean(y)||), written out for y = (1, 2, 3, 6)."""
    y = np.array([1.0, 2.0, 3.0, 6.0])
    yh = np.array([1.0, 2.5, 3.0, 5.0])
    expected = 100 * (1 - math.sqrt(0.25 + 1.0) / math.sqrt(4.0 + 1.0 + 0.0 + 9.0))
    assert nrmse_fit(y, yh) == pytest.approx(expected, rel=1e-12)
    assert nrmse_fit(y, y) == 100.0 and nrmse_fit(y, np.full(4, 3.0)) == 0.0


def test_validate_on_a_log_it_was_not_fitted_to(issue_log):
    fit = issue_log.log.identify()
    other = synthetic_log(kind="multisine", counts=4096, Ts=5e-4, coulomb=0.03, seed=5)
    check = fit.validate(other.log)
    assert not check.closed_loop
    assert check.velocity_fit > 97.0 and check.position_fit > 80.0
    wrong = replace(fit, J=2 * fit.J).validate(other.log)
    assert wrong.velocity_fit < 70.0
    assert "open loop from its input" in check.summary()
    assert check.to_dict()["velocity_fit_percent"] == check.velocity_fit


def test_validate_through_the_logged_loop():
    s = synthetic_log(kind="pd", counts=4096, Ts=5e-4, coulomb=0.03, seed=0)
    other = synthetic_log(kind="pd", counts=4096, Ts=1e-3, coulomb=0.03, seed=6)
    check = s.log.identify(loop=s.loop).validate(other.log, loop=other.loop)
    assert check.closed_loop and check.position_fit > 99.0 and check.velocity_fit > 97.0
    with pytest.raises(ParameterValueError, match="one reference sample per logged sample"):
        s.log.identify(loop=s.loop).validate(other.log, loop=s.loop)


def test_emps_identified_on_one_half_fits_the_other():
    """docs/real-data.md: M, Fv, Fc from the first 12.42 s fit the last 12.42 s by 91 % in
    position and 94 % in velocity open loop, 99.99 % and 99.8 % through the EMPS loop."""
    log = emps()
    first, second = log.slice(0.0, 12.42), log.slice(12.42, None)
    fit = first.identify()
    open_loop = fit.validate(second)
    closed = fit.validate(second, loop=emps_loop(second))
    assert open_loop.position_fit > 88.0 and open_loop.velocity_fit > 92.0
    assert closed.position_fit > 99.9 and closed.velocity_fit > 99.5
    assert len(first) + len(second) == len(log)


def test_emps_defaults_fit_the_unseen_half_no_worse_than_the_published_method():
    """The defaults differ from the published IDIM-LS (Fv -2.6 %, Fc +3.1 %: the rests are
    dropped, docs/real-data.md): the difference must not cost the model its prediction.
    Identified on the first half, simulated open loop on the second, the defaults fit it at
    least as well as the benchmark's method (the reference: the published method itself)."""
    log = emps()
    first, second = log.slice(0.0, 12.42), log.slice(12.42, None)
    defaults = first.identify().validate(second)
    published = first.identify(method="idim-ls").validate(second)
    assert defaults.position_fit >= published.position_fit
    assert defaults.velocity_fit >= published.velocity_fit


def test_validation_figure_labels_carry_units(issue_log):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    check = issue_log.log.identify().validate(issue_log.log)
    fig = replace(check, axis="rotary").plot()
    labels = [ax.get_ylabel() for ax in fig.axes]
    assert labels == ["position [rad]", "velocity [rad/s]"]
    assert fig.axes[1].get_xlabel() == "time [s]"
    plt.close(fig)


def test_log_slice():
    log = emps()
    part = log.slice(1.0, 2.0)
    assert len(part) == 1000 and part.t[0] == pytest.approx(1.0)
    assert part.reference is not None and part.axis == log.axis
    with pytest.raises(ParameterValueError, match="keeps 0 samples"):
        log.slice(100.0, 200.0)
