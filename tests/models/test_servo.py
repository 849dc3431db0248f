"""Tests of ServoModel and its exact ZOH discretisation (eqs. 1, 4, 5, 8)."""

from __future__ import annotations

import dataclasses
import math

import mpmath
import numpy as np
import pytest
import scipy.integrate
import scipy.linalg
import scipy.signal

from hpdob import DiscreteServoModel, ServoModel

mpmath.mp.dps = 50

SYSTEMS = [  # (J [kg m^2], b [N m s/rad], Ts [s])
    (3.06e-4, 5e-5, 1e-3),  # the paper's motor
    (2.8e-4, 0.0, 1e-3),  # the paper's nominal model
    (1.0, 0.3, 0.01),
    (5e-6, 2e-4, 5e-5),  # small motor, 20 kHz
    (10.0, 100.0, 0.2),  # b Ts / J = 2
]


def closed_form(J, b, Ts):
    """A_D, B_D from the closed forms, evaluated with 50-digit mpmath (independent of expm).

    A_D = [[1, Ts phi1], [0, exp(-a)]], B_D = D_D = [Ts^2 phi2, Ts phi1] / J with a = b Ts / J,
    phi1 = (1 - e^-a) / a, phi2 = (a - 1 + e^-a) / a^2 (phi1 = 1, phi2 = 1/2 at a = 0).
    """
    J, b, Ts = (mpmath.mpf(v) for v in (J, b, Ts))
    a = b * Ts / J
    if a == 0:
        decay, phi1, phi2 = mpmath.mpf(1), mpmath.mpf(1), mpmath.mpf(1) / 2
    else:
        decay = mpmath.exp(-a)
        phi1 = (1 - decay) / a
        phi2 = (a - 1 + decay) / a**2
    A = np.array([[1.0, float(Ts * phi1)], [0.0, float(decay)]])
    B = np.array([float(Ts * Ts * phi2 / J), float(Ts * phi1 / J)])
    return A, B


def ulp_tolerance(alpha):
    """Relative tolerance of a few ulp, widened by the conditioning of exp(-alpha).

    alpha = b*Ts/J is itself rounded (relative eps), and exp(-alpha) turns that into a relative
    error alpha*eps: no algorithm can do better from float inputs.
    """
    return 4.5e-16 * (1.0 + alpha)


class TestServoModel:
    def test_continuous_matrices_eq1(self):
        m = ServoModel(J=2.0, b=0.5, coulomb=0.1, coulomb_velocity=0.2)
        np.testing.assert_array_equal(m.A_C, [[0.0, 1.0], [0.0, -0.25]])
        np.testing.assert_array_equal(m.B_C, [0.0, 0.5])
        np.testing.assert_array_equal(m.D_C, [0.0, 0.5])

    def test_coulomb_torque(self):
        m = ServoModel(J=1.0, coulomb=0.01, coulomb_velocity=0.01)
        omega = np.array([-1.0, -0.01, 0.0, 0.01, 1.0])
        np.testing.assert_allclose(m.coulomb_torque(omega), 0.01 * np.tanh(omega / 0.01))

    def test_defaults_and_frozen(self):
        m = ServoModel(1e-3)
        assert (m.b, m.coulomb, m.coulomb_velocity) == (0.0, 0.0, 0.01)
        with pytest.raises(dataclasses.FrozenInstanceError):
            m.J = 2.0

    def test_values_are_python_floats(self):
        m = ServoModel(np.float32(2.0), np.int64(1))
        assert type(m.J) is float and type(m.b) is float

    def test_replace_validates(self):
        m = ServoModel(1.0, 0.1)
        assert m.replace(J=2.0) == ServoModel(2.0, 0.1)
        with pytest.raises(ValueError, match="J must be a positive finite inertia"):
            m.replace(J=0.0)
        with pytest.raises(TypeError, match="unknown parameter"):
            m.replace(inertia=1.0)

    @pytest.mark.parametrize(
        ("kwargs", "name"),
        [
            ({"J": 0.0}, "J"),
            ({"J": -1.0}, "J"),
            ({"J": math.nan}, "J"),
            ({"J": math.inf}, "J"),
            ({"J": 1.0, "b": -1e-9}, "b"),
            ({"J": 1.0, "b": math.nan}, "b"),
            ({"J": 1.0, "coulomb": -0.1}, "coulomb"),
            ({"J": 1.0, "coulomb_velocity": 0.0}, "coulomb_velocity"),
            ({"J": 1.0, "coulomb_velocity": math.inf}, "coulomb_velocity"),
        ],
    )
    def test_bad_values(self, kwargs, name):
        bad = kwargs[name]
        with pytest.raises(ValueError, match=rf"^{name} must be .*got {bad!r}"):
            ServoModel(**kwargs)

    def test_message_example(self):
        with pytest.raises(ValueError, match=r"^J") as info:
            ServoModel(J=-1.0)
        assert str(info.value) == "J must be a positive finite inertia [kg m^2], got -1.0"

    @pytest.mark.parametrize("bad", ["1.0", None, True, [1.0], 1 + 0j])
    def test_bad_types(self, bad):
        with pytest.raises(TypeError, match=r"^J must be"):
            ServoModel(J=bad)


class TestDiscretize:
    @pytest.mark.parametrize(("J", "b", "Ts"), SYSTEMS)
    def test_against_closed_form(self, J, b, Ts):
        model = ServoModel(J, b).discretize(Ts)
        A, B = closed_form(J, b, Ts)
        rtol = ulp_tolerance(b * Ts / J)
        np.testing.assert_allclose(model.A, A, rtol=rtol, atol=0)
        np.testing.assert_allclose(model.B, B, rtol=rtol, atol=0)
        np.testing.assert_array_equal(model.D, model.B)

    @pytest.mark.parametrize(
        "alpha", [0.0, 1e-12, 1e-10, 1e-8, 1e-6, 1e-4, 1e-2, 0.5, 1.0, 3.0, 10.0]
    )
    def test_accurate_over_friction_range(self, alpha):
        """b Ts / J from 1e-12 to 10: every entry to a few ulp (no cancellation)."""
        J, Ts = 2.8e-4, 1e-3
        b = alpha * J / Ts
        model = ServoModel(J, b).discretize(Ts)
        A, B = closed_form(J, b, Ts)
        np.testing.assert_allclose(model.A, A, rtol=ulp_tolerance(alpha), atol=0)
        np.testing.assert_allclose(model.B, B, rtol=ulp_tolerance(alpha), atol=0)

    def test_dense_sweep_against_mpmath(self):
        J, Ts = 1.0, 1.0
        for alpha in np.concatenate([[0.0], np.logspace(-13, 2, 301)]):
            model = ServoModel(J, alpha).discretize(Ts)
            A, B = closed_form(J, alpha, Ts)
            np.testing.assert_allclose(
                model.A, A, rtol=ulp_tolerance(alpha), atol=0, err_msg=f"alpha={alpha}"
            )
            np.testing.assert_allclose(
                model.B, B, rtol=ulp_tolerance(alpha), atol=0, err_msg=f"alpha={alpha}"
            )

    @pytest.mark.parametrize(("J", "b", "Ts"), SYSTEMS)
    def test_is_the_matrix_exponential_of_the_augmented_matrix(self, J, b, Ts):
        m = ServoModel(J, b)
        augmented = np.zeros((3, 3))
        augmented[:2, :2], augmented[:2, 2] = m.A_C, m.B_C
        E = scipy.linalg.expm(augmented * Ts)
        model = m.discretize(Ts)
        np.testing.assert_allclose(model.A, E[:2, :2], rtol=1e-12, atol=1e-15 * Ts)
        np.testing.assert_allclose(model.B, E[:2, 2], rtol=1e-12)

    @pytest.mark.parametrize(("J", "b", "Ts"), SYSTEMS)
    def test_against_scipy_cont2discrete(self, J, b, Ts):
        m = ServoModel(J, b)
        Bc = np.column_stack([m.B_C, m.D_C])
        Ad, Bd, *_ = scipy.signal.cont2discrete(
            (m.A_C, Bc, np.eye(2), np.zeros((2, 2))), Ts, method="zoh"
        )
        model = m.discretize(Ts)
        # cont2discrete exponentiates the unscaled augmented matrix: close, not ulp-exact.
        np.testing.assert_allclose(model.A, Ad, rtol=1e-11, atol=1e-14 * Ts)
        np.testing.assert_allclose(model.B, Bd[:, 0], rtol=1e-11)
        np.testing.assert_allclose(model.D, Bd[:, 1], rtol=1e-11)

    @pytest.mark.parametrize(("J", "b", "Ts"), SYSTEMS)
    def test_step_invariance(self, J, b, Ts):
        """ZOH is exact for piecewise-constant inputs: compare with a tight ODE integration."""
        m = ServoModel(J, b)
        model = m.discretize(Ts)
        x0, u, tau = np.array([0.3, -2.0]), 0.7 * J / Ts, 0.2 * J / Ts
        sol = scipy.integrate.solve_ivp(
            lambda t, x: m.A_C @ x + m.B_C * u - m.D_C * tau,
            (0.0, Ts),
            x0,
            method="DOP853",
            rtol=1e-13,
            atol=1e-15,
        )
        np.testing.assert_allclose(model.step(x0, u, tau), sol.y[:, -1], rtol=1e-11)

    def test_continuity_as_b_goes_to_zero(self):
        J, Ts = 2.8e-4, 1e-3
        exact = ServoModel(J, 0.0).discretize(Ts)
        previous = None
        for b in [1e-3, 1e-6, 1e-9, 1e-12, 1e-15, 1e-18]:
            model = ServoModel(J, b).discretize(Ts)
            gap = max(
                np.max(np.abs(model.A - exact.A) / np.maximum(np.abs(exact.A), 1e-300)),
                np.max(np.abs(model.B - exact.B) / np.abs(exact.B)),
            )
            assert gap <= 2 * b * Ts / J + 1e-15  # first-order in b, no jump at b = 0
            if previous is not None:
                assert gap <= previous
            previous = gap

    def test_large_friction_underflows_gracefully(self):
        model = ServoModel(1e-6, 1.0).discretize(1.0)  # b Ts / J = 1e6
        np.testing.assert_allclose(model.A, [[1.0, 1e-6], [0.0, 0.0]], rtol=1e-15)
        assert np.all(np.isfinite(model.B))

    def test_frozen_readonly_and_equality(self):
        model = ServoModel(1.0, 0.1).discretize(0.01)
        with pytest.raises(dataclasses.FrozenInstanceError):
            model.Ts = 0.02
        with pytest.raises(ValueError, match="read-only"):
            model.A[0, 0] = 2.0
        assert model == ServoModel(1.0, 0.1).discretize(0.01)
        assert model == DiscreteServoModel(ServoModel(1.0, 0.1), 0.01)
        assert hash(model) == hash(ServoModel(1.0, 0.1).discretize(0.01))
        assert model != ServoModel(1.0, 0.1).discretize(0.02)
        assert model != ServoModel(1.0, 0.2).discretize(0.01)
        assert model.continuous == ServoModel(1.0, 0.1)
        assert (model.J, model.b) == (1.0, 0.1)

    @pytest.mark.parametrize("Ts", [0.0, -1e-3, math.nan, math.inf])
    def test_bad_sampling_period(self, Ts):
        with pytest.raises(
            ValueError, match=rf"^Ts must be a positive finite sampling period \[s\], got {Ts!r}"
        ):
            ServoModel(1.0).discretize(Ts)

    def test_bad_sampling_period_type(self):
        with pytest.raises(TypeError, match=r"^Ts must be"):
            ServoModel(1.0).discretize("1e-3")

    def test_needs_servo_model(self):
        with pytest.raises(TypeError, match="continuous must be a ServoModel"):
            DiscreteServoModel("motor", 1e-3)
