"""The compiled kernel: lazily imported, cached, identical to the same code run as plain Python."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hpdob import Actuator, Encoder, paper, simulate
from hpdob.signals import trajectory

SMALL_RUN = """
import sys, numpy as np
from hpdob import Actuator, Encoder, paper, simulate
kw = paper.scenario()
kw.update(duration=0.6, sensor=Encoder(4096, noise_std=2e-4, seed=1),
          actuator=Actuator(torque_limit=0.06, delay_samples=1),
          observer=paper.observer("HPDOb-100").design, substeps=4)
r = simulate(**kw)
np.savez(sys.argv[1], **{k: getattr(r, k) for k in
         ("theta", "omega", "u", "tau_hat", "tau_dn", "theta_measured")})
"""


@pytest.fixture(autouse=True)
def jit_loop(monkeypatch):
    """These tests are about the JIT-compiled loop: never a loop built ahead of time that an
    earlier test in this worker left in the suite's folder (its processes inherit this)."""
    monkeypatch.setenv("HPDOB_AOT", "0")


def test_import_hpdob_loads_no_heavy_modules():
    code = (
        "import sys, hpdob; heavy = [m for m in ('numba', 'matplotlib', 'pandas', 'dask', "
        "'control', 'scipy.signal', 'mujoco') if m in sys.modules]; print(heavy)"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"


def test_a_loop_and_an_analysis_load_no_numba_until_the_first_simulate():
    """numba (~0.3 s to import) is imported by the first simulation, not by building a loop,
    the paper's set-up or an analysis (``hpdob.simulation`` re-exports the compiled
    ``program_row`` lazily, issue 25)."""
    code = (
        "import sys; from hpdob import ServoLoop, paper, simulate; import hpdob.analysis; "
        "kw = paper.scenario(); kw['observer'] = paper.observer('HPDOb-100').design; "
        "before = 'numba' in sys.modules; simulate(**{**kw, 'duration': 0.01}); "
        "from hpdob.simulation import program_row; "
        "print(before, 'numba' in sys.modules, type(program_row).__name__)"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.split() == ["False", "True", "CPUDispatcher"]


def _canonical_structure(**changes):
    """The sample-loop structure of the canonical HPDOb-100 run (with ``changes`` to it)."""
    from hpdob.simulation import _kernel

    seen = []
    original = _kernel.sample_loop

    def spy(structure):
        seen.append(structure)
        return original(structure)

    kw = {**paper.scenario(), "observer": paper.observer("HPDOb-100").design, "duration": 0.01}
    kw.update(changes)
    _kernel.sample_loop = spy
    try:
        simulate(**kw)
    finally:
        _kernel.sample_loop = original
    return seen[-1]


def test_kernel_is_numba_compiled_with_cache():
    from hpdob.simulation import _kernel

    loop, fields = _kernel.sample_loop(_canonical_structure())
    assert ("sig", "r") in fields and ("out", "tau_reac") not in fields  # what the run uses
    for function in (loop, _kernel.ground_truth, _kernel.contact_torque):
        assert function.targetoptions.get("nogil") is True
        assert function._cache.__class__.__name__ != "NullCache"  # cache=True


def test_generated_source_is_kept_under_the_cache_directory():
    """As the offline estimation loops: the source is a module named by its hash under
    NUMBA_CACHE_DIR (or ~/.cache)/hpdob, so numba's cache can refer to it."""
    from hpdob._generated import cache_directory
    from hpdob.simulation import _kernel

    source = _kernel.loop_source(_canonical_structure())
    _kernel.sample_loop(_canonical_structure())
    kept = [p for p in cache_directory("sample-loops").glob("hpdob_loop_*.py")
            if p.read_text(encoding="utf-8") == source]  # fmt: skip
    assert len(kept) == 1


def test_the_source_follows_the_structure():
    """Only what the run uses is generated: no encoder arithmetic for the ideal sensor, no
    noise read without noise, no contact torque without an environment, the observer's rows
    as straight-line sums (no program_row loop), one source per structure."""
    from hpdob.simulation import _kernel

    ideal = _kernel.loop_source(_canonical_structure())
    assert "math.floor" not in ideal and "contact_torque(" not in ideal.split("def run")[1]
    assert "program_row" not in ideal and "for i in range" not in ideal
    encoder = _kernel.loop_source(_canonical_structure(sensor=Encoder(4096)))
    assert "math.floor(th / resolution + 0.5)" in encoder and "noise[k]" not in encoder
    noisy = _kernel.loop_source(_canonical_structure(sensor=Encoder(4096, noise_std=1e-4)))
    assert "noise[k]" in noisy
    pd = _kernel.loop_source(_canonical_structure(observer=None))
    assert "est = 0.0" in pd and len({ideal, encoder, noisy, pd}) == 4


def test_a_sweep_generates_and_compiles_no_source_per_scenario():
    """Bandwidths and inertias change coefficients, not the structure: after its first scenario
    a sweep adds no generated source (issue 25)."""
    from hpdob import sweep
    from hpdob.simulation import _kernel

    base = {**paper.scenario(), "observer": {"order": 1, "bandwidth": 100.0}, "duration": 0.05}
    sweep(base, grid={"observer.bandwidth": [100.0]}, progress=False)
    before = _kernel.sample_loop.cache_info()
    rows = sweep(base, grid={"observer.bandwidth": [60.0, 150.0, 280.0],
                             "plant.J": [2.5e-4, 4e-4]}, progress=False)  # fmt: skip
    after = _kernel.sample_loop.cache_info()
    assert len(rows) == 6 and rows["stable"].all()
    assert after.misses == before.misses and after.hits >= before.hits + 6


def test_compiled_equals_plain_python(tmp_path):
    """Same inputs, bit-identical outputs: the compiled kernel vs the same functions run by the
    Python interpreter (NUMBA_DISABLE_JIT=1, in a fresh process)."""
    kw = paper.scenario()
    kw.update(
        duration=0.6,
        sensor=Encoder(4096, noise_std=2e-4, seed=1),
        actuator=Actuator(torque_limit=0.06, delay_samples=1),
        observer=paper.observer("HPDOb-100").design,
        substeps=4,
    )
    compiled = simulate(**kw)
    out = tmp_path / "plain.npz"
    env = {**os.environ, "NUMBA_DISABLE_JIT": "1"}
    script = tmp_path / "run.py"
    script.write_text(SMALL_RUN)
    subprocess.run([sys.executable, str(script), str(out)], check=True, env=env)
    plain = np.load(out)
    for name in plain.files:
        np.testing.assert_array_equal(getattr(compiled, name), plain[name], err_msg=name)
    assert Path(out).exists()


def test_a_loop_file_overrides_the_generated_loop_only_under_the_mutation_variable(
    tmp_path, monkeypatch
):
    """benchmarks/mutation_kernel.py's override: unset, or set to a directory without a file
    for the structure, the generated loop runs; with ``<loop_key>.py`` there, that file's loop
    runs, compiled from memory (nothing written to the cache directory)."""
    from hpdob._generated import cache_directory
    from hpdob.simulation import _kernel

    kw = {**paper.scenario(), "observer": paper.observer("HPDOb-100").design, "duration": 0.02}
    structure = _canonical_structure(duration=0.02)
    source = _kernel.loop_source(structure)
    assert source.count("tau_hat[k] = est\n") == 1
    mutated = source.replace("tau_hat[k] = est\n", "tau_hat[k] = est + 1.0\n")  # recorded only
    monkeypatch.delenv(_kernel.OVERRIDE_VARIABLE, raising=False)
    try:
        _kernel.sample_loop.cache_clear()
        generated = simulate(**kw).tau_hat
        monkeypatch.setenv(_kernel.OVERRIDE_VARIABLE, str(tmp_path))
        _kernel.sample_loop.cache_clear()
        np.testing.assert_array_equal(simulate(**kw).tau_hat, generated)  # no file: inert
        (tmp_path / f"{_kernel.loop_key(structure)}.py").write_text(mutated, encoding="utf-8")
        _kernel.sample_loop.cache_clear()
        np.testing.assert_array_equal(simulate(**kw).tau_hat, generated + 1.0)
        kept = [p for p in cache_directory("sample-loops").glob("hpdob_loop_*.py")
                if p.read_text(encoding="utf-8") == mutated]  # fmt: skip
        assert kept == []
        monkeypatch.delenv(_kernel.OVERRIDE_VARIABLE)
        _kernel.sample_loop.cache_clear()
        np.testing.assert_array_equal(simulate(**kw).tau_hat, generated)
    finally:
        _kernel.sample_loop.cache_clear()


def test_one_machine_code_per_structure():
    """A structure is compiled (or loaded from numba's cache) once per process: the signals a
    run reads are passed read-only whether they were sampled anew, kept for the grid (the
    second run), scaled by a sweep or returned by a plain callable, so numba sees one argument
    type (a writeable array is another type: the second run of a fresh environment compiled
    the loop again, issue 25)."""
    from hpdob import sweep
    from hpdob.simulation import _kernel

    kw = {**paper.scenario(), "observer": paper.observer("HPDOb-100").design, "duration": 0.02}
    signal = paper.scenario()["reference"]
    first = simulate(**kw)
    again = simulate(**kw)  # the grid's kept signals
    plain = simulate(**{**kw, "reference": lambda t: trajectory(signal)(t)})  # sampled anew
    base = {**paper.scenario(), "observer": paper.observer("HPDOb-100").design, "duration": 0.02}
    sweep(base, grid={"disturbance_scale": [0.5]}, progress=False)  # scaled: a new array
    kernel, _ = _kernel.sample_loop(_canonical_structure(duration=0.02))
    assert len(kernel.signatures) == 1, kernel.signatures
    for name in ("theta", "u", "tau_hat"):
        assert getattr(first, name).tobytes() == getattr(again, name).tobytes()
        assert getattr(first, name).tobytes() == getattr(plain, name).tobytes()
