"""``export_fmu`` / ``hpdob export-fmu``: an FMI 2.0 co-simulation FMU of the observer, checked
with fmpy (validation, co-simulation over a logged closed-loop run, bit for bit against the
Python observer), and ``hpdob export-c --dtype q31``."""

from __future__ import annotations

import importlib.util
import tempfile
import xml.etree.ElementTree as ET
import zipfile

import numpy as np
import pytest

from hpdob import ParameterValueError, ServoModel, design_observer, export_c, paper
from hpdob.cli import main
from hpdob.export import FMUBuildError, export_fmu, fixed_point_design
from hpdob.observers import design_eso, reaction_torque_observer

fmpy = pytest.importorskip("fmpy", reason="fmpy (the test extra) validates and runs the FMU")
from fmpy import extract, read_model_description  # noqa: E402
from fmpy.fmi2 import FMU2Slave  # noqa: E402
from fmpy.validation import validate_fmu  # noqa: E402

MODEL = paper.NOMINAL.discretize(paper.TS)


@pytest.fixture(scope="module")
def logged_runs():
    """The paper's virtual experiments (encoder, delay, torque limit): the logged
    measurements and torques, and the simulation's own estimates."""
    return {name: paper.run(name, duration=3.0) for name in paper.VIRTUAL_RUNS}


def _cosimulate(fmu_path, theta, omega, u, *, tau0=0.0):
    """Drive the FMU as a co-simulation master does: set inputs, read outputs, doStep(Ts)."""
    md = read_model_description(str(fmu_path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    two = "omega" in vr
    ts = md.defaultExperiment.stepSize
    slave = FMU2Slave(
        guid=md.guid,
        unzipDirectory=extract(str(fmu_path), unzipdir=tempfile.mkdtemp(dir=fmu_path.parent)),
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName="obs",
    )
    slave.instantiate()
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.setReal([vr["theta"], vr["tau0"]], [theta[0], tau0])
    if two:
        slave.setReal([vr["omega"]], [omega[0]])
    slave.exitInitializationMode()
    inputs = [vr["theta"], vr["u"]] + ([vr["omega"]] if two else [])
    outputs = [vr[name] for name in ("tau_hat", "omega_hat", "tau_reac") if name in vr]
    ys = []
    for k in range(len(theta)):
        slave.setReal(inputs, [theta[k], u[k]] + ([omega[k]] if two else []))
        ys.append(slave.getReal(outputs))
        slave.doStep(currentCommunicationPoint=k * float(ts), communicationStepSize=float(ts))
    slave.terminate()
    slave.freeInstance()
    return np.array(ys)


def _python(observer, theta, omega, u, *, tau0=0.0):
    system = observer.system
    reset, outputs, _, update = system.python
    two = len(system.measures) == 2
    s = reset(theta[0], omega[0] if two else 0.0, tau0)
    ys = []
    for k in range(len(theta)):
        meas = (theta[k], omega[k]) if two else (theta[k],)
        ys.append(outputs(s, *meas))
        s = update(s, *meas, u[k])
    return np.array(ys)


@pytest.mark.parametrize("name", ["virtual-experiment", "virtual-experiment-position"])
def test_fmu_validates_and_reproduces_the_python_observer_bit_for_bit(name, logged_runs,
                                                                      tmp_path):  # fmt: skip
    run = logged_runs[name]
    observer = paper.observer(name)
    fmu = export_fmu(observer, tmp_path / "obs.fmu", model_identifier="hpdob_obs")
    assert validate_fmu(str(fmu)) == []
    theta, omega, u = run.theta_measured, run.omega_measured, run.u
    got = _cosimulate(fmu, theta, omega, u, tau0=0.01)
    expected = _python(observer, theta, omega, u, tau0=0.01)
    assert got.shape == expected.shape
    assert np.array_equal(got, expected)  # bit for bit, every output, every sample
    # and the same as the closed loop's own estimate (which started from tau0 = 0)
    free = _cosimulate(fmu, theta, omega, u)
    assert np.max(np.abs(free[:, 0] - run.tau_hat)) < 1e-12


def test_model_description_records_the_design(tmp_path):
    design = design_observer(ServoModel(3.06e-4, 5e-5).discretize(1e-3), order=2,
                             bandwidth=150.0, gain_direction=(0, 1))  # fmt: skip
    fmu = export_fmu(design, tmp_path / "hp.fmu")
    with zipfile.ZipFile(fmu) as z:
        names = set(z.namelist())
        root = ET.fromstring(z.read("modelDescription.xml"))
    assert {"sources/dob.c", "sources/dob.h", "sources/fmi2_dob.c"} <= names
    assert any(n.startswith("binaries/") for n in names)
    assert root.get("fmiVersion") == "2.0"
    variables = {v.get("name"): v for v in root.iter("ScalarVariable")}
    assert [n for n, v in variables.items() if v.get("causality") == "input"] == [
        "theta", "omega", "u"]  # fmt: skip
    assert [n for n, v in variables.items() if v.get("causality") == "output"] == ["tau_hat"]
    start = {n: float(v.find("Real").get("start")) for n, v in variables.items()
             if v.get("variability") == "constant"}  # fmt: skip
    assert start == {"Ts": 1e-3, "J_n": 3.06e-4, "b_n": 5e-5, "order": 2.0}
    design_keys = {d.get("key"): d.get("value") for d in root.iter("Design")}
    assert "150.0 rad/s" in design_keys["poles"] and "(0.0, 1.0)" in design_keys["gain direction"]
    assert "hpdob" in root.get("generationTool")
    assert float(root.find("DefaultExperiment").get("stepSize")) == 1e-3


def test_fmu_of_another_family_and_fmpy_simulate(tmp_path):
    """The ESO (position-only inputs, velocity output) through fmpy's own simulate_fmu."""
    fmu = export_fmu(design_eso(MODEL, bandwidth=150.0), tmp_path / "eso.fmu")
    assert validate_fmu(str(fmu)) == []
    t = np.arange(200) * 1e-3
    signals = np.array(list(zip(t, 0.1 * np.sin(3 * t), np.zeros_like(t), strict=True)),
                       dtype=[("time", float), ("theta", float), ("u", float)])  # fmt: skip
    result = fmpy.simulate_fmu(str(fmu), start_time=0.0, stop_time=0.199, step_size=1e-3,
                               input=signals, output=["tau_hat", "omega_hat"])  # fmt: skip
    assert len(result) >= 199
    assert np.all(np.isfinite(result["omega_hat"]))


def test_bad_arguments_write_nothing(tmp_path):
    design = design_observer(MODEL, order=1, bandwidth=100.0)
    with pytest.raises(ParameterValueError, match=r"path must end in \.fmu"):
        export_fmu(design, tmp_path / "obs.zip")
    with pytest.raises(ParameterValueError, match="does not exist"):
        export_fmu(design, tmp_path / "missing" / "obs.fmu")
    with pytest.raises(ParameterValueError, match="prefix"):
        export_fmu(design, tmp_path / "obs.fmu", model_identifier="1bad")
    with pytest.raises(FMUBuildError, match="compiler") as info:
        export_fmu(design, tmp_path / "obs.fmu", compiler=["no-such-compiler-hpdob"])
    assert "\n" not in str(info.value)
    assert list(tmp_path.iterdir()) == []
    # a compiler that fails: one line, and the previous FMU is left as it was
    good = export_fmu(design, tmp_path / "obs.fmu")
    before = good.read_bytes()
    with pytest.raises(FMUBuildError, match="failed to build") as info:
        export_fmu(design, good, compiler=["false"])
    assert "\n" not in str(info.value)
    assert good.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["obs.fmu"]


def test_missing_compiler_is_one_line(monkeypatch, tmp_path, capsys):
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "ziglang" else real(name, *a))  # fmt: skip
    monkeypatch.setenv("CC", "no-such-compiler-hpdob")
    code = main(["export-fmu", "-o", str(tmp_path / "x.fmu")])
    err = capsys.readouterr().err
    assert code == 2
    assert "pip install ziglang" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x.fmu").exists()


def test_cli_export_fmu(tmp_path, capsys):
    code = main(["export-fmu", "--order", "1", "--bandwidth", "100", "--model-identifier",
                 "axis1", "-o", str(tmp_path / "axis1.fmu")])  # fmt: skip
    assert code == 0
    assert capsys.readouterr().out.strip() == str(tmp_path / "axis1.fmu")
    assert validate_fmu(str(tmp_path / "axis1.fmu")) == []


def test_cli_export_c_fixed_point_matches_library(tmp_path, capsys):
    ranges = ["--counts-per-rev", "16384", "--omega-max", "50", "--u-max", "0.5",
              "--tau-max", "0.5"]  # fmt: skip
    code = main(["export-c", "--order", "1", "--bandwidth", "100", "--dtype", "q31",
                 *ranges, "-o", str(tmp_path / "cli")])  # fmt: skip
    assert code == 0
    design = design_observer(MODEL, order=1, bandwidth=100.0)
    fx = fixed_point_design(design, counts_per_rev=16384, omega_max=50.0, u_max=0.5,
                            tau_max=0.5)  # fmt: skip
    expected = export_c(fx, tmp_path / "lib", dtype="q31")
    assert [(tmp_path / "cli" / p.name).read_text() for p in expected] == [
        p.read_text() for p in expected]  # fmt: skip
    capsys.readouterr()
    code = main(["export-c", "--dtype", "q31", "--counts-per-rev", "16384", "-o",
                 str(tmp_path / "bad")])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2 and "--omega-max, --u-max, --tau-max" in err
    assert not (tmp_path / "bad").exists()
    code = main(["export-c", "--omega-max", "5", "-o", str(tmp_path / "bad")])
    assert code == 2 and "only for --dtype q31" in capsys.readouterr().err


def test_export_fmu_help_has_a_description(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["export-fmu", "--help"])
    assert exit_.value.code == 0
    out = " ".join(capsys.readouterr().out.split())  # argparse wraps the description
    assert "FMI 2.0 co-simulation FMU" in out and "docs/deployment.md" in out


@pytest.mark.parametrize("coulomb", [False, True])
def test_fmu_of_a_reaction_torque_observer(coulomb, logged_runs, tmp_path):
    """An RTOB composition's FMU has the output tau_reac (with the Coulomb term: libm's tanh),
    bit for bit the Python runtime's, every output, every sample."""
    dob = design_observer(MODEL, order=1, bandwidth=100.0)
    friction = {"friction": paper.PLANT, "velocity_filter": 100.0} if coulomb else {}
    observer = reaction_torque_observer(dob, **friction)
    fmu = export_fmu(observer, tmp_path / "rtob.fmu", model_identifier="hpdob_rtob")
    assert validate_fmu(str(fmu)) == []
    names = [v.name for v in read_model_description(str(fmu)).modelVariables]
    assert "tau_reac" in names
    run = logged_runs["virtual-experiment"]
    theta, omega, u = run.theta_measured, run.omega_measured, run.u
    got = _cosimulate(fmu, theta, omega, u, tau0=0.01)
    expected = _python(observer, theta, omega, u, tau0=0.01)
    assert got.shape == expected.shape == (len(theta), 3 if coulomb else 2)
    assert np.array_equal(got, expected)
