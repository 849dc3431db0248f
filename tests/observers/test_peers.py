"""The observers the field compares against: ADRC's ESO and the Kalman disturbance observer.

The ESO is checked against its literal equations written out here (Herbst 2013's closed-form
gains of the current observer for m = 0; an independent gain computation for m = 1), the
Kalman observer against filterpy's KalmanFilter sample by sample; both run unchanged through
the protocol's consumers.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from hpdob import (
    Encoder,
    ExtendedStateObserver,
    KalmanDisturbanceObserver,
    Observer,
    ServoModel,
    closed_loop_poles,
    estimation_response,
    export_c,
    noise_gains,
    paper,
    simulate,
    sweep,
)
from hpdob.observers import ESODesign, design_eso, design_kalman, kalman_process_noise
from hpdob.testing import CObserver, find_compiler

TS = 1e-3
J_N, B_N = 2.8e-4, 2e-5
MODEL = ServoModel(J_N, B_N).discretize(TS)


def trace(rng, n=600):
    return np.cumsum(rng.normal(scale=2e-3, size=n)), rng.normal(scale=0.05, size=n)


def run_observer(obs, theta, u):
    tau, omega = [], []
    for th, uk in zip(theta.tolist(), u.tolist(), strict=True):
        tau.append(obs.estimate(th))
        omega.append(obs.velocity)
        obs.update(th, uk)
    return np.array(tau), np.array(omega)


# -- ESO ----------------------------------------------------------------------------------------
def run_literal_eso(Phi, Gamma, L, Lp, theta, u, form):
    """The discrete ESO's two forms as written in the reference, from rest: current
    ``x_hat = x_bar + L (theta - x_bar_1)``, ``x_bar+ = Phi x_hat + Gamma u``; predictive
    ``x_hat+ = Phi x_hat + Gamma u + Lp (theta - x_hat_1)``; ``tau_hat = -J_n f - b_n omega``."""
    x = np.zeros(len(L))  # x_bar (current) or x_hat (predictive), at rest
    tau = []
    for th, uk in zip(theta, u, strict=True):
        if form == "current":
            x_hat = x + L * (th - x[0])
            tau.append(-J_N * x_hat[2] - B_N * x_hat[1])
            x = Phi @ x_hat + Gamma * uk
        else:
            tau.append(-J_N * x[2] - B_N * x[1])
            x = Phi @ x + Gamma * uk + Lp * (th - x[0])
    return np.array(tau)


def literal_eso_m0(theta, u, g, form):
    """Second-order LADRC's ESO, written out: x = [theta, omega, f], theta'' = f + b0 u,
    ZOH with Phi = [[1, T, T^2/2], [0, 1, T], [0, 0, 1]], Gamma = b0 [T^2/2, T, 0]. Current
    observer gains (all poles at beta = exp(-g T)) from G. Herbst, "A simulative study on active
    disturbance rejection control (ADRC) as a control tool for practitioners", Electronics 2
    (2013): L = [1 - beta^3, 3/(2T) (1 - beta)^2 (1 + beta), (1 - beta)^3 / T^2]; the
    predictive gains are L_p = Phi L = [3 - 3 beta, (1 - beta)^2 (5 + beta) / (2T),
    (1 - beta)^3 / T^2]."""
    T, b0, beta = TS, 1.0 / J_N, math.exp(-g * TS)
    Phi = np.array([[1.0, T, T * T / 2], [0.0, 1.0, T], [0.0, 0.0, 1.0]])
    Gamma = b0 * np.array([T * T / 2, T, 0.0])
    L = np.array([1 - beta**3, 1.5 / T * (1 - beta) ** 2 * (1 + beta), (1 - beta) ** 3 / T**2])
    Lp = np.array([3 - 3 * beta, (1 - beta) ** 2 * (5 + beta) / (2 * T), (1 - beta) ** 3 / T**2])
    return run_literal_eso(Phi, Gamma, L, Lp, theta, u, form)


def charpoly(A) -> list:
    """det(zI - A), highest power first, by the Faddeev-LeVerrier recursion in exact rational
    arithmetic on the float entries (eigenvalues of a Jordan-like Phi are too inaccurate)."""
    from fractions import Fraction

    n = len(A)
    M = [[Fraction(float(v)) for v in row] for row in A]
    coefficients = [Fraction(1)]
    B = [[Fraction(int(i == j)) for j in range(n)] for i in range(n)]
    for k in range(1, n + 1):
        MB = [[sum(M[i][h] * B[h][j] for h in range(n)) for j in range(n)] for i in range(n)]
        c = -sum(MB[i][i] for i in range(n)) / k
        coefficients.append(c)
        B = [[MB[i][j] + (c if i == j else 0) for j in range(n)] for i in range(n)]
    return coefficients


def exact_solve(A, b) -> list:
    """Gaussian elimination in rationals."""
    n = len(b)
    rows = [[*A[i], b[i]] for i in range(n)]
    for col in range(n):
        pivot = next(r for r in range(col, n) if rows[r][col] != 0)
        rows[col], rows[pivot] = rows[pivot], rows[col]
        for r in range(n):
            if r != col and rows[r][col] != 0:
                f = rows[r][col] / rows[col][col]
                rows[r] = [a - f * c for a, c in zip(rows[r], rows[col], strict=True)]
    return [rows[i][n] / rows[i][i] for i in range(n)]


def literal_eso_m1(theta, u, g, form):
    """The generalised ESO with f'' = 0: x = [theta, omega, f, f'], Phi the ZOH of the integrator
    chain written out, the gain found here by matching det(zI - Phi + L_p C) = (z - beta)^4
    coefficient by coefficient (a linear solve: the determinant is affine in L_p)."""
    T, b0, beta = TS, 1.0 / J_N, math.exp(-g * TS)
    Phi = np.array(
        [[1, T, T**2 / 2, T**3 / 6], [0, 1, T, T**2 / 2], [0, 0, 1, T], [0, 0, 0, 1]], float
    )
    Gamma = b0 * np.array([T**2 / 2, T, 0.0, 0.0])
    from fractions import Fraction

    base = charpoly(Phi)
    columns = []  # det(zI - Phi + e_j C) - det(zI - Phi): affine in L_p, so one column per j
    for j in range(4):
        shifted = Phi.copy()
        shifted[j, 0] -= 1.0
        columns.append([a - b for a, b in zip(charpoly(shifted), base, strict=True)])
    target = [Fraction(c) - b for c, b in zip(np.poly(np.full(4, beta)), base, strict=True)]
    matrix = [[columns[j][i] for j in range(4)] for i in range(1, 5)]
    Lp = np.array([float(v) for v in exact_solve(matrix, target[1:])])
    L = np.linalg.solve(Phi, Lp)
    return run_literal_eso(Phi, Gamma, L, Lp, theta, u, form)


@pytest.mark.parametrize("form", ["current", "predictive"])
@pytest.mark.parametrize(("m", "literal"), [(0, literal_eso_m0), (1, literal_eso_m1)])
def test_eso_equals_its_literal_equations(rng, form, m, literal):
    theta, u = trace(rng)
    obs = ExtendedStateObserver(MODEL, bandwidth=150.0, extended_order=m, form=form)
    tau, _ = run_observer(obs, theta, u)
    expected = literal(theta, u, 150.0, form)
    np.testing.assert_allclose(tau, expected, rtol=1e-7, atol=1e-9 * np.abs(expected).max())


@pytest.mark.parametrize("m", [0, 1, 2])
@pytest.mark.parametrize("form", ["current", "predictive"])
def test_eso_poles_and_constant_disturbance(m, form):
    eso = design_eso(MODEL, bandwidth=200.0, extended_order=m, form=form)
    beta = math.exp(-0.2)
    np.testing.assert_allclose(np.poly(eso.system.F), np.poly(np.full(m + 3, beta)), atol=1e-9)
    # on the nominal plant, a constant load torque is estimated exactly once settled
    obs = Observer(eso)
    x, tau = np.zeros(2), 0.013
    for _ in range(10000):
        tau_hat = obs.estimate(float(x[0]))
        u = -J_N * (50 * x[0] + 5 * x[1]) + tau_hat
        obs.update(float(x[0]), u)
        x = MODEL.step(x, u, tau)
    assert obs.estimate(float(x[0])) == pytest.approx(tau, rel=1e-7)


# -- Kalman -------------------------------------------------------------------------------------
@pytest.mark.parametrize("m", [0, 1])
def test_kalman_equals_filterpy_sample_by_sample(rng, m):
    from filterpy.kalman import KalmanFilter

    r, q = 1e-4, (1e-3 if m == 0 else 2e-5)
    design = design_kalman(MODEL, order=m, position_noise_std=r, process_noise_std=q)
    n = m + 3
    kf = KalmanFilter(dim_x=n, dim_z=1, dim_u=1)
    kf.F = np.array(design.A)
    kf.H = np.array(design.C)
    kf.B = np.array(design.B)[:, None]
    kf.Q = np.zeros((n, n))
    kf.Q[-1, -1] = q * q
    kf.R = np.array([[r * r]])
    kf.P = np.array(design.covariance)  # start from the DARE (steady-state a-priori) covariance
    kf.x = np.zeros((n, 1))
    obs = KalmanDisturbanceObserver(MODEL, order=m, position_noise_std=r, process_noise_std=q)
    theta, u = trace(rng, 400)
    for th, uk in zip(theta, u, strict=True):
        kf.update(np.array([[th]]))
        tau_hat = obs.estimate(float(th))
        assert tau_hat == pytest.approx(float(kf.x[2, 0]), rel=1e-7, abs=1e-12)
        assert obs.velocity == pytest.approx(float(kf.x[1, 0]), rel=1e-7, abs=1e-9)
        obs.update(float(th), float(uk))
        kf.predict(u=np.array([[uk]]))
    np.testing.assert_allclose(kf.K.ravel(), design.gain, rtol=1e-9)


@pytest.mark.parametrize("m", [0, 1])
def test_kalman_process_noise_gives_the_bandwidth(m):
    r = 2 * math.pi / 16384 / math.sqrt(12)
    q = kalman_process_noise(MODEL, bandwidth=120.0, position_noise_std=r, order=m)
    design = design_kalman(MODEL, order=m, position_noise_std=r, process_noise_std=q)
    assert abs(estimation_response(design, 120.0 / (2 * math.pi))[0]) == pytest.approx(
        1 / math.sqrt(2), rel=1e-3
    )


# -- the same loop and tools --------------------------------------------------------------------
def test_peers_run_in_simulate_sweep_and_analysis():
    enc = Encoder(16384)
    r = enc.resolution / math.sqrt(12)
    nominal = paper.NOMINAL
    model = nominal.discretize(TS)
    q = kalman_process_noise(model, bandwidth=100.0, position_noise_std=r)
    peers = [
        ExtendedStateObserver(model, bandwidth=100.0),
        KalmanDisturbanceObserver(model, position_noise_std=r, process_noise_std=q),
    ]
    for obs in peers:
        result = simulate(**{**paper.scenario(), "duration": 3.0}, observer=obs.design,
                          sensor=enc)  # fmt: skip
        assert not result.diverged and result.omega_hat is not None
        assert result.metrics()["rms_estimation_error"] < 0.01
        loop = {"plant": ServoModel(3.06e-4, 5e-5), "nominal": nominal, "Ts": TS,
                "controller": paper.CONTROLLER, "observer": obs.design}  # fmt: skip
        assert abs(closed_loop_poles(**loop)).max() < 1
        assert noise_gains(**loop).tau_hat_position > 0
    base = {**paper.scenario(), "duration": 2.0, "observer": {"type": "eso", "bandwidth": 100.0}}
    rows = sweep(base, grid={"observer.bandwidth": [80.0, 160.0]}, progress=False)
    assert rows["stable"].all()


@pytest.mark.skipif(find_compiler() is None, reason="no C compiler")
def test_export_c_matches_python(tmp_path, rng):
    eso = design_eso(MODEL, bandwidth=150.0, extended_order=1)
    header, source = export_c(eso, tmp_path, prefix="eso")
    c = CObserver(header, source, prefix="eso", dtype="double", observer=eso,
                  build_dir=tmp_path / "lib")  # fmt: skip
    theta, u = trace(rng, 2000)
    tau_c, _ = c.drive(theta, np.zeros_like(theta), u, init=(theta[0], 0.0, 0.0))
    obs = Observer(eso, x0=(theta[0], 0.0))
    tau_py, _ = run_observer(obs, theta, u)
    assert np.array_equal(tau_c, tau_py)
    assert "eso_velocity" in header.read_text()


@pytest.mark.parametrize(
    ("call", "error", "pattern"),
    [
        (lambda: design_eso(MODEL, bandwidth=0.0), ValueError, r"^bandwidth must be a positive"),
        (lambda: design_eso(MODEL, bandwidth=10.0, form="cur"), ValueError, r"^form must be one"),
        (
            lambda: design_eso(MODEL, bandwidth=10.0, extended_order=-1),
            ValueError,
            r"^extended_order must be a non-negative integer",
        ),
        (lambda: design_eso(ServoModel(1.0), bandwidth=10.0), TypeError, r"discretise"),
        (
            lambda: design_kalman(MODEL, position_noise_std=0.0, process_noise_std=1.0),
            ValueError,
            r"^position_noise_std must be a positive",
        ),
        (
            lambda: design_kalman(MODEL, position_noise_std=1e-4, process_noise_std=-1.0),
            ValueError,
            r"^process_noise_std must be a positive",
        ),
        (
            lambda: design_kalman(MODEL, order=-1, position_noise_std=1e-4, process_noise_std=1.0),
            ValueError,
            r"^order must be a non-negative integer",
        ),
        (
            lambda: kalman_process_noise(MODEL, bandwidth=3000.0, position_noise_std=1e-4),
            ValueError,
            r"^bandwidth must be below half the Nyquist",
        ),
    ],
)
def test_bad_inputs_name_the_parameter(call, error, pattern):
    with pytest.raises(error, match=pattern):
        call()


def test_scenario_files_and_the_command_line(tmp_path, capsys):
    from hpdob.cli import main
    from hpdob.simulation._scenario import scenario_from_dict

    data = {
        "Ts": 1e-3, "duration": 0.5, "plant": {"J": 3.06e-4}, "nominal": {"J": 2.8e-4},
        "controller": {"kp": 50.0, "kd": 5.0},
        "reference": {"type": "step", "time": 0.1, "amplitude": 1.0},
        "observer": {"type": "eso", "bandwidth": 150.0, "extended_order": 1},
    }  # fmt: skip
    kwargs = scenario_from_dict(data)
    assert isinstance(kwargs["observer"], ESODesign)  # a value: a loop resets it at x0
    assert not simulate(**kwargs).diverged
    data["observer"] = {"type": "kalman", "position_noise_std": 1e-4}
    with pytest.raises(ValueError, match=r"missing required key observer\.process_noise_std"):
        scenario_from_dict(data)
    assert main(["design", "--type", "eso", "--extended-order", "1", "--bandwidth", "150"]) == 0
    assert "generalised ESO (m=1), current form" in capsys.readouterr().out
    assert main(["export-c", "--type", "kalman", "--position-noise-std", "1.1e-4",
                 "--out", str(tmp_path)]) == 0  # fmt: skip
    assert "tau_hat" in (tmp_path / "dob.h").read_text()
    capsys.readouterr()
    assert main(["design", "--type", "kalman"]) == 2
    assert "needs --position-noise-std" in capsys.readouterr().err


def test_peers_run_on_a_mujoco_plant():
    """The MuJoCo loop runs the peers through the same compiled sample step: on the frictionless
    servo it agrees with hpdob's own exact integrator (RK4 at 8 steps per sample)."""
    pytest.importorskip("mujoco")
    from hpdob import MujocoServo

    model = paper.NOMINAL.discretize(TS)
    eso = design_eso(model, bandwidth=120.0, extended_order=1)
    kwargs = {**paper.scenario(), "duration": 2.0, "plant": paper.PLANT.replace(coulomb=0.0)}
    exact = simulate(**kwargs, observer=eso, substeps=8)
    mujoco = simulate(**{**kwargs, "plant": MujocoServo(paper.PLANT.J, paper.PLANT.b)},
                      observer=eso, substeps=8)  # fmt: skip
    np.testing.assert_allclose(mujoco.tau_hat, exact.tau_hat, rtol=0,
                               atol=1e-6 * np.abs(exact.tau_hat).max())  # fmt: skip
    assert mujoco.omega_hat is not None
