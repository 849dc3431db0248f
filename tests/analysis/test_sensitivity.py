"""Gang of four and loop margins, checked against identities built from independent pieces."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hpdob import (
    PD,
    Actuator,
    Encoder,
    ServoModel,
    closed_loop,
    closed_loop_poles,
    design_observer,
    estimation_response,
    gang_of_four,
    loop_margins,
    loop_transfer,
)

TS = 1e-3
NOMINAL = ServoModel(2.8e-4)
PLANT = ServoModel(3.06e-4, 5e-5)
PDC = PD(50.0, 5.0)
F = np.array([0.3, 2.0, 11.0, 60.0, 240.0, 490.0])  # Hz
W = 2 * np.pi * F


def fr(sys):
    return sys.frequency_response(W).frdata[0, 0]


def observer(order, bandwidth=100.0):
    return design_observer(NOMINAL.discretize(TS), order=order, bandwidth=bandwidth)


def plant_response(plant):
    """theta/a and omega/a of the true plant's exact ZOH model, C (zI - A)^-1 B by hand."""
    model = plant.discretize(TS)
    z = np.exp(1j * W * TS)
    out = np.array([np.linalg.solve(zz * np.eye(2) - model.A, model.B) for zz in z])
    return out[:, 0], out[:, 1]


def controller_response(design):
    """K_theta, K_omega with u = -K_theta theta_m - K_omega omega_m (r = 0), from the observer's
    own state space: u = -J_n (kp theta + kd omega) + O_theta theta + O_omega omega + O_u u."""
    O = design.to_statespace().frequency_response(W).frdata[0]  # noqa: E741
    den = 1.0 - O[2]
    return (
        (NOMINAL.J * PDC.kp - O[0]) / den,
        (NOMINAL.J * PDC.kd - O[1]) / den,
    )


@pytest.mark.parametrize(("order", "delay"), [(0, 0), (1, 0), (1, 1), (3, 0)])
def test_loop_gain_and_gang_of_four_from_independent_pieces(order, delay):
    design = observer(order)
    kw = {
        "plant": PLANT,
        "nominal": NOMINAL,
        "Ts": TS,
        "controller": PDC,
        "observer": design,
        "actuator": Actuator(delay_samples=delay),
    }
    P_th, P_om = plant_response(PLANT)
    K_th, K_om = controller_response(design)
    z_d = np.exp(-1j * W * TS * delay)
    L = z_d * (K_th * P_th + K_om * P_om)
    g4 = gang_of_four(**kw)
    S = 1.0 / (1.0 + L)
    pairs = [
        (fr(loop_transfer(**kw)), L),
        (fr(g4.S), S),
        (fr(g4.PS), P_th * S),
        (fr(g4.CS), K_th * S),
        (fr(g4.T), L * S),  # T = L/(1 + L)
        # ... = a/tau_ext: the actuator torque a is the closed loop's command u delayed
        (z_d * fr(closed_loop(**kw)["u", "tau_ext"]), L * S),
    ]
    for mine, independent in pairs:
        # Above 1 Hz they agree to 1e-6 or better; at 0.3 Hz, where |L| reaches 1e8 with the
        # m + 3 integrators, evaluations near z = 1 keep ~4-5 digits either way.
        np.testing.assert_allclose(mine[1:], independent[1:], rtol=1e-6)
        np.testing.assert_allclose(mine[0], independent[0], rtol=1e-3)
    np.testing.assert_allclose(fr(g4.S) + fr(g4.T), 1.0, atol=1e-12)


@pytest.mark.parametrize("order", [0, 1, 2])
def test_input_sensitivity_is_one_minus_q_times_pd_sensitivity(order):
    design = observer(order, bandwidth=80.0)
    S = fr(gang_of_four(plant=NOMINAL, nominal=NOMINAL, Ts=TS, controller=PDC, observer=design).S)
    S_pd = fr(gang_of_four(plant=NOMINAL, nominal=NOMINAL, Ts=TS, controller=PDC).S)
    np.testing.assert_allclose(S, estimation_response(design, F, error=True) * S_pd, atol=1e-9)


def test_sensor_with_backward_difference_is_accepted():
    g4 = gang_of_four(
        plant=PLANT,
        nominal=NOMINAL,
        Ts=TS,
        controller=PDC,
        observer=observer(1),
        sensor=Encoder(16384, velocity="backward-difference"),
    )
    assert g4.S.nstates == 2 + 1 + 2
    assert abs(complex(g4.S(1.0))) < 1e-9  # still integral action at DC


@pytest.mark.parametrize("order", [0, 1, 2, 3])
def test_gain_margins_are_the_inertia_stability_boundaries(order):
    """Plant without friction: J -> c J divides the loop gain by c exactly, so the closed loop
    loses stability at J/J_n = 1/gain_margin and 1/gain_margin_lower (eigenvalues)."""
    design = observer(order)
    plant = ServoModel(NOMINAL.J)
    lm = loop_margins(plant=plant, nominal=NOMINAL, Ts=TS, controller=PDC, observer=design)
    assert lm.stable
    low, high = lm.inertia_factor_range
    assert (low, high) == (1 / lm.gain_margin, 1 / lm.gain_margin_lower)

    def radius(ratio):
        return np.abs(
            closed_loop_poles(
                plant=ServoModel(ratio * NOMINAL.J),
                nominal=NOMINAL,
                Ts=TS,
                controller=PDC,
                observer=design,
            )
        ).max()

    for edge in (low, high):
        assert radius(edge * 0.999) < 1.0 < radius(edge * 1.001) or (
            radius(edge * 0.999) > 1.0 > radius(edge * 1.001)
        )
    assert radius(low * 1.01) < 1 and radius(high * 0.99) < 1


@pytest.mark.parametrize("order", [0, 1, 2, 3])
def test_phase_and_delay_margin(order):
    design = observer(order)
    kw = {"plant": PLANT, "nominal": NOMINAL, "Ts": TS, "controller": PDC, "observer": design}
    lm = loop_margins(**kw)
    L = loop_transfer(**kw)
    w_c = 2 * math.pi * lm.crossover_frequency
    Lc = complex(L.frequency_response([w_c]).frdata[0, 0, 0])
    assert abs(Lc) == pytest.approx(1.0, abs=1e-9)
    assert lm.phase_margin == pytest.approx(math.degrees(np.angle(-Lc)), abs=1e-7)
    # One more sample of delay is a pure lag of Ts on the unit circle: the delay margin
    # drops by exactly Ts, and the loop with that delay is stable iff the margin exceeded Ts.
    delayed = loop_margins(**kw, actuator=Actuator(delay_samples=1))
    assert delayed.delay_margin == pytest.approx(lm.delay_margin - TS, abs=1e-9)
    stable = np.abs(closed_loop_poles(**kw, actuator=Actuator(delay_samples=1))).max() < 1
    assert stable == (lm.delay_margin > TS) == delayed.stable
    # Stability margin = 1 / peak of |S| (dense grid).
    w = np.linspace(1e-3, math.pi / TS, 20001)
    S = gang_of_four(**kw).S.frequency_response(w).frdata[0, 0]
    assert lm.stability_margin == pytest.approx(1 / np.abs(S).max(), rel=1e-4)


def test_delay_margin_predicts_one_sample_delay_verdicts_across_bandwidths():
    verdicts = []
    for g in (200.0, 600.0, 1000.0, 1600.0):
        kw = {
            "plant": PLANT,
            "nominal": NOMINAL,
            "Ts": TS,
            "controller": PDC,
            "observer": observer(2, g),
        }
        lm = loop_margins(**kw)
        stable = np.abs(closed_loop_poles(**kw, actuator=Actuator(delay_samples=1))).max() < 1
        assert stable == (lm.delay_margin > TS)
        verdicts.append(stable)
    assert verdicts[0] and not verdicts[-1]  # the check covers both outcomes


def test_unstable_loop_reports_no_gain_margins():
    kw = {
        "plant": ServoModel(0.05 * NOMINAL.J),
        "nominal": NOMINAL,
        "Ts": TS,
        "controller": PDC,
        "observer": observer(1),
    }
    lm = loop_margins(**kw)
    assert not lm.stable
    assert math.isnan(lm.gain_margin) and math.isnan(lm.gain_margin_lower)
