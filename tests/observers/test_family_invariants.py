"""Invariants of every registered family, parametrised from the registry (issue 20, sec. 5).

- the reset: ``estimate`` right after ``initial_state(x0, tau0)`` is ``tau0``, with a
  nominal viscous friction and a non-zero initial velocity (dropping the ``b_n`` term of the
  ESO's reset matrix ``N`` fails it: checked by planting it);
- the spec round trip: ``design_from_spec(model, spec_of(d))`` is ``d`` bit for bit;
- every sweep path of the family applies: a sweep over it equals the direct redesign;
- the realised error poles are inside the unit circle, and the order-m families' closed
  form ``1 - Q`` agrees with the matrices;
- runtime object = functional core = the compiled loop (against the plain-Python reference
  loop of tests/reference_loop.py) = exported C (bit for bit).
"""

from __future__ import annotations

import numpy as np
import pytest
from family_cases import design, family_specs, spec_id

from hpdob import (
    PD,
    LinearObserver,
    ServoModel,
    estimation_response,
    export_c,
    paper,
    simulate,
    sweep,
)
from hpdob.observers import (
    Observer,
    design_from_spec,
    estimate,
    get_family,
    initial_state,
    outputs,
    spec_of,
    update,
)
from hpdob.signals import Step
from hpdob.testing import CObserver
from reference_loop import reference_loop

TS = 1e-3
NOMINAL = ServoModel(2.8e-4, 5e-4)  # b_n != 0: the reset must carry the b_n omega0 term
MODEL = NOMINAL.discretize(TS)
SPECS = family_specs()
CASES = pytest.mark.parametrize("spec", SPECS, ids=spec_id)


def _measurement(system, x):
    return tuple(x) if len(system.measures) == 2 else x[0]


def test_the_cases_cover_every_registered_family():
    from hpdob.observers import families

    assert {s["type"] for s in SPECS} == {f.name for f in families()}
    assert len(SPECS) >= 12


@CASES
def test_estimate_after_the_reset_is_tau0(spec):
    d = design(MODEL, spec)
    for x0, tau0 in (((0.0, 50.0), 0.01), ((0.3, -20.0), -0.02), ((1.0, 0.0), 0.005)):
        state = initial_state(d, x0=x0, tau0=tau0)
        tau_hat = outputs(d, state, _measurement(d.system, x0))[0]
        assert tau_hat == pytest.approx(tau0, rel=1e-9, abs=1e-12), (x0, tau0)
        assert estimate(d, state, _measurement(d.system, x0)) == tau_hat


@CASES
def test_spec_round_trip(spec):
    d = design(MODEL, spec)
    again = spec_of(d)
    assert again is not None and again["type"] == spec["type"]
    redesigned = design_from_spec(MODEL, again)
    for name in ("F", "G", "H", "E", "N"):
        np.testing.assert_array_equal(getattr(redesigned.system, name), getattr(d.system, name))
    assert spec_of(redesigned) == again


def _sweep_cases():
    """``(spec, path, value)``: each sweepable parameter of each family, on the first case
    it applies to, moved to another valid value."""
    cases, seen = [], set()
    for spec in SPECS:
        family = get_family(spec["type"])
        for p in family.parameters:
            if not p.sweepable or (family.name, p.name) in seen:
                continue
            if p.only_with is not None and spec.get(p.only_with[0]) != p.only_with[1]:
                continue
            current = spec_of(design(MODEL, spec))
            if p.kind == "choice":
                value = next(c for c in p.choices if c != current.get(p.name, p.default))
            elif p.kind == "int":
                value = 1 if current.get(p.name, 0) != 1 else 0
            else:
                value = 1.2 * current.get(p.name, 100.0)
            seen.add((family.name, p.name))
            cases.append(
                pytest.param(spec, f"observer.{p.name}", value, id=f"{family.name}:{p.name}")
            )
    return cases


def test_every_sweepable_parameter_has_a_case():
    from hpdob.observers import families

    covered = {c.id for c in _sweep_cases()}
    for family in families():
        for p in family.parameters:
            if p.sweepable:
                assert f"{family.name}:{p.name}" in covered


@pytest.mark.parametrize(("spec", "path", "value"), _sweep_cases())
def test_every_sweep_path_applies(spec, path, value):
    base_spec = spec_of(design(MODEL, spec))
    run = {
        "plant": ServoModel(3.06e-4, 5e-5),
        "nominal": NOMINAL,
        "Ts": TS,
        "controller": PD(50, 5),
        "duration": 0.3,
        "reference": Step(0.05, 1.0),
        "disturbance": Step(0.1, 0.05),
    }
    table = sweep({**run, "observer": base_spec}, grid={path: [value]}, progress=False)
    assert table["error"][0] == "", table["error"][0]
    name = path.split(".", 1)[1]
    changed = {**base_spec, name: value}
    family = get_family(spec["type"])
    if name == family.tuned:
        for key in family.replaced_by_bandwidth:
            changed.pop(key, None)
    if family.respec is not None:
        changed = family.respec(changed, {name}, base_spec)
    direct = simulate(**run, observer=design_from_spec(MODEL, changed))
    assert table["rms_estimation_error"][0] == direct.metrics()["rms_estimation_error"]
    unchanged = simulate(**run, observer=design_from_spec(MODEL, base_spec))
    assert direct.metrics()["rms_estimation_error"] != unchanged.metrics()["rms_estimation_error"]


@CASES
def test_realised_error_poles(spec):
    """Stable in double precision; where the family gives ``1 - Q`` in closed form (from its
    intended poles), the rounded matrices realise it."""
    system = design(MODEL, spec).system
    assert np.abs(np.linalg.eigvals(system.F)).max() < 1.0
    if system.error_dynamics is not None:
        generic = LinearObserver(
            F=system.F,
            G=system.G,
            H=system.H,
            E=system.E,
            N=system.N,
            Ts=system.Ts,
            measures=system.measures,
            outputs=system.outputs,
            model=system.model,
        )
        f = np.geomspace(0.1, 100.0, 7)
        np.testing.assert_allclose(
            estimation_response(system, f), estimation_response(generic, f), rtol=1e-6
        )


def _trace(system, theta, omega, u, init):
    obs = Observer(system, x0=init[:2], tau0=init[2])
    state = initial_state(system, init[:2], init[2])
    tau, states = np.empty(theta.size), np.empty((theta.size, system.n_states))
    for k, (th, om, uk) in enumerate(zip(theta.tolist(), omega.tolist(), u.tolist(), strict=True)):
        x = _measurement(system, (th, om))
        states[k] = obs.state
        tau[k] = obs.estimate(x)
        assert tau[k] == estimate(system, state, x)  # object = functional core, bit for bit
        obs.update(x, uk)
        state = update(system, state, x, uk)
        assert tuple(obs.state.tolist()) == state
    return tau, states


@CASES
def test_object_core_kernel_and_c_agree(spec, tmp_path, rng):
    d = design(paper.NOMINAL.discretize(TS), spec)
    system = d.system
    kwargs = {**paper.scenario(), "duration": 0.5}
    result = simulate(**kwargs, observer=d, substeps=4)
    expected = reference_loop(**kwargs, observer=Observer.of(d), substeps=4)
    for name in ("theta", "u", "tau_hat"):
        np.testing.assert_allclose(
            getattr(result, name),
            expected[name],
            rtol=1e-12,
            atol=1e-12 * np.max(np.abs(expected[name])),
            err_msg=name,
        )
    header, source = export_c(system, tmp_path, prefix="inv")
    c = CObserver(
        header, source, prefix="inv", dtype="double", observer=system, build_dir=tmp_path / "lib"
    )
    theta, omega, u = rng.normal(size=500), rng.normal(scale=30, size=500), rng.normal(size=500)
    init = (0.3, -1.0, 0.02)
    tau_c, s_c = c.drive(theta, omega, u, init=init)
    tau_py, s_py = _trace(system, theta, omega, u, init)
    assert np.array_equal(tau_c, tau_py) and np.array_equal(s_c, s_py)
