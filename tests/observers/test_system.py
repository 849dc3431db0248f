"""The observer protocol: an observer written from scratch against LinearObserver runs unchanged
in simulate, sweep, the analysis views and export_c.

The test observer is the conventional DOb (paper eqs. 11, 13) followed by a first-order
low-pass, built here from the DOb's F, G, H, E, N by hand -- not by any hpdob family.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from hpdob import (
    PD,
    LinearObserver,
    Observer,
    ServoLoop,
    ServoModel,
    closed_loop_poles,
    design_observer,
    estimate,
    estimation_response,
    export_c,
    initial_state,
    noise_gains,
    observer_noise_gain,
    paper,
    simulate,
    sweep,
    update,
)
from hpdob.observers import Program, Term
from hpdob.testing import CObserver, find_compiler
from reference_loop import reference_loop

TS = 1e-3
A = 0.9  # low-pass pole
NOMINAL = paper.NOMINAL
MODEL = NOMINAL.discretize(TS)


def filtered_dob(pole: float = A) -> LinearObserver:
    """tau_f[k+1] = a tau_f[k] + (1 - a) tau_hat[k], the DOb's estimate low-pass filtered."""
    dob = design_observer(MODEL, order=0, bandwidth=200.0).system
    F = np.block([[dob.F, np.zeros((1, 1))], [(1 - pole) * dob.H, np.array([[pole]])]])
    G = np.vstack([dob.G, (1 - pole) * dob.E])
    N = np.vstack([dob.N, [0.0, 0.0, 1.0]])  # converged on tau0: the filter holds tau0 too
    return LinearObserver(
        F=F, G=G, H=[[0.0, 1.0]], E=np.zeros((1, 3)), N=N, Ts=TS, model=MODEL, name="DOb+LP"
    )


def python_trace(observer, theta, omega, u, init=(0.0, 0.0, 0.0)):
    obs = Observer(observer, x0=init[:2], tau0=init[2])
    tau, states = np.empty(theta.size), np.empty((theta.size, observer.n_states))
    for k, (th, om, uk) in enumerate(zip(theta.tolist(), omega.tolist(), u.tolist(), strict=True)):
        states[k] = obs.state
        tau[k] = obs.estimate((th, om))
        obs.update((th, om), uk)
    return tau, states


def test_runtime_equals_functional_core_and_matrices(rng):
    system = filtered_dob()
    obs = Observer(system)
    state = initial_state(system)
    s = np.zeros(system.n_states)
    for _ in range(200):
        x = (float(rng.normal()), float(rng.normal(scale=10)))
        u = float(rng.normal(scale=0.1))
        y = obs.estimate(x)
        assert y == estimate(system, state, x)
        v = np.array([*x, u])
        assert y == pytest.approx(float((system.H @ s + system.E @ v)[0]), rel=1e-12, abs=1e-15)
        obs.update(x, u)
        state = update(system, state, x, u)
        s = system.F @ s + system.G @ v
        assert tuple(obs.state.tolist()) == state
        np.testing.assert_allclose(obs.state, s, rtol=1e-10, atol=1e-14)


def test_estimation_response_is_the_dobs_times_the_filter():
    """Q of the cascade = Q_DOb(z) (1 - a)/(z - a): the generic state-space evaluation against
    the DOb's closed form (eq. 12) and the filter's transfer function."""
    dob = design_observer(MODEL, order=0, bandwidth=200.0)
    f = np.geomspace(0.1, 400.0, 50)
    z = np.exp(2j * math.pi * f * TS)
    expected = estimation_response(dob, f) * (1 - A) / (z - A)
    np.testing.assert_allclose(estimation_response(filtered_dob(), f), expected, rtol=1e-9)


def test_simulate_matches_the_reference_loop():
    kwargs = paper.scenario()
    system = filtered_dob()
    result = simulate(**kwargs, observer=system, substeps=8)
    expected = reference_loop(**kwargs, observer=Observer(system), substeps=8)
    for name in ("theta", "u", "tau_hat", "tau_dn"):
        np.testing.assert_allclose(
            getattr(result, name), expected[name], rtol=1e-12,
            atol=1e-12 * np.max(np.abs(expected[name])), err_msg=name,
        )  # fmt: skip
    # the filter lags the DOb: its estimate is worse than the DOb's alone, but it works
    dob = simulate(**kwargs, observer=design_observer(MODEL, order=0, bandwidth=200.0))
    assert dob.metrics()["rms_estimation_error"] < result.metrics()["rms_estimation_error"] < 0.01


def test_sweep_runs_it_as_it_is():
    base = {**paper.scenario(), "duration": 2.0, "observer": filtered_dob()}
    rows = sweep(base, grid={"plant.J": [2.8e-4, 3.06e-4]}, progress=False)
    assert rows["stable"].all() and (rows["error"] == "").all()
    direct = simulate(**{**paper.scenario(), "duration": 2.0}, observer=filtered_dob())
    assert rows["rms_estimation_error"][1] == direct.metrics()["rms_estimation_error"]
    bad = sweep(base, grid={"nominal.J": [3e-4]}, progress=False)  # cannot be redesigned
    assert not bad["stable"][0] and "must be designed on nominal" in bad["error"][0]


def test_closed_loop_poles_separate_on_the_nominal_plant():
    """On the nominal plant the DOb's estimate does not depend on u, so the closed-loop poles
    are the PD loop's, the DOb's exp(-200 Ts) and the filter's a."""
    loop = ServoLoop(plant=NOMINAL, nominal=NOMINAL, Ts=TS, controller=PD(50, 5),
                     observer=filtered_dob())  # fmt: skip
    poles = closed_loop_poles(loop)
    pd_only = closed_loop_poles(loop.replace(observer=None))
    for p in (*pd_only, math.exp(-200.0 * TS), A):
        assert np.min(np.abs(poles - p)) < 1e-9, p
    gains = noise_gains(loop)
    assert gains.tau_hat_velocity == pytest.approx(observer_noise_gain(filtered_dob()), rel=1e-9)


@pytest.mark.skipif(find_compiler() is None, reason="no C compiler")
def test_export_c_compiles_and_matches_python_bit_for_bit(tmp_path, rng):
    system = filtered_dob()
    header, source = export_c(system, tmp_path, prefix="lp")
    c = CObserver(header, source, prefix="lp", dtype="double", observer=system,
                  build_dir=tmp_path / "lib")  # fmt: skip
    theta, omega, u = rng.normal(size=5000), rng.normal(scale=30, size=5000), rng.normal(size=5000)
    init = (0.3, -1.0, 0.02)
    tau_c, s_c = c.drive(theta, omega, u, init=init)
    tau_py, s_py = python_trace(system, theta, omega, u, init=init)
    assert np.array_equal(tau_c, tau_py) and np.array_equal(s_c, s_py)


def test_a_custom_program_is_checked_against_the_matrices():
    system = filtered_dob()
    wrong = Program(
        update=(*system.program.update[:-1], (Term(0.5, 1),)),
        output=system.program.output,
        reset=system.program.reset,
    )
    with pytest.raises(ValueError, match=r"program.update\[1\] sums to"):
        LinearObserver(F=system.F, G=system.G, H=system.H, E=system.E, N=system.N, Ts=TS,
                       program=wrong)  # fmt: skip


@pytest.mark.parametrize(
    ("change", "error", "pattern"),
    [
        ({"F": np.eye(3)}, ValueError, r"G must have shape \(3, 3\)"),
        ({"E": [[0.0, 0.0, 1.0]]}, ValueError, r"E's last column \(feed-through from u\)"),
        ({"measures": ("omega",)}, ValueError, r"measures must be one of"),
        ({"outputs": ("omega_hat",)}, ValueError, r"outputs must be one of"),
        ({"Ts": 2e-3}, ValueError, r"model.Ts = 0.001 must equal Ts = 0.002"),
        ({"F": [["a", "b"], ["c", "d"]]}, TypeError, r"F must be a square real matrix"),
        ({"N": np.full((2, 3), np.nan)}, ValueError, r"N must have finite entries"),
        ({"model": ServoModel(1.0)}, TypeError, r"model must be a DiscreteServoModel"),
    ],
)
def test_bad_matrices_are_named(change, error, pattern):
    system = filtered_dob()
    kwargs = {"F": system.F, "G": system.G, "H": system.H, "E": system.E, "N": system.N,
              "Ts": TS, "model": MODEL, **change}  # fmt: skip
    with pytest.raises(error, match=pattern):
        LinearObserver(**kwargs)


@pytest.mark.parametrize("design_Ts", [5e-4, 2e-3])
def test_a_design_at_another_sampling_period_is_refused_by_the_loop(design_Ts):
    """The loop runs the observer at its own Ts: a design on nominal.discretize(Ts') with
    Ts' != Ts is refused, faster or slower (a mutation check of ``model.Ts == Ts``)."""
    nominal = ServoModel(2.8e-4)
    design = design_observer(nominal.discretize(design_Ts), order=1, bandwidth=100.0)
    with pytest.raises(ValueError, match=r"must be designed on nominal\.discretize\(Ts\)"):
        ServoLoop(plant=nominal, nominal=nominal, Ts=1e-3, controller=PD(50.0, 5.0),
                  observer=design)  # fmt: skip
