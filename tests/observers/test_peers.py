"""The observers the field compares against: ADRC's ESO and the Kalman disturbance observer.

Both run unchanged through the protocol's consumers (simulate, sweep, analysis, C export, TOML
scenarios, the command line, MuJoCo). Each family's own tests -- the ESO against its literal
equations, the Kalman observer against filterpy -- are in tests/observers/test_eso.py and
tests/observers/test_kalman.py.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from observer_tools import MODEL, TS, run_observer, trace

from hpdob import (
    Encoder,
    ExtendedStateObserver,
    KalmanDisturbanceObserver,
    Observer,
    ServoModel,
    closed_loop_poles,
    export_c,
    noise_gains,
    paper,
    simulate,
    sweep,
)
from hpdob.observers import ESODesign, design_eso, design_kalman, kalman_process_noise
from hpdob.testing import CObserver, find_compiler


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
