"""The compiled kernel: lazily imported, cached, identical to the plain-Python kernel."""

from __future__ import annotations

import subprocess
import sys

import numpy as np

from hpdob import Actuator, Encoder, paper
from hpdob.simulation._compiled import closed_loop_kernel
from hpdob.simulation._kernel import run_closed_loop
from hpdob.simulation._simulate import simulate


def test_import_hpdob_loads_no_heavy_modules():
    code = (
        "import sys, hpdob; heavy = [m for m in ('numba', 'matplotlib', 'pandas', 'dask', "
        "'control', 'scipy.signal', 'mujoco') if m in sys.modules]; print(heavy)"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"


def test_kernel_is_numba_compiled_with_cache():
    kernel = closed_loop_kernel()
    assert kernel.py_func is run_closed_loop
    assert kernel.targetoptions.get("nogil") is True
    assert kernel._cache.__class__.__name__ != "NullCache"  # cache=True


def test_compiled_equals_plain_python(monkeypatch):
    """Same inputs, bit-identical outputs: compiled vs the uncompiled Python function."""
    kw = paper.scenario()
    kw.update(
        duration=0.6,
        sensor=Encoder(4096, noise_std=2e-4, seed=1),
        actuator=Actuator(torque_limit=0.06, delay_samples=1),
        observer=paper.observer("HPDOb-100"),
        substeps=4,
    )
    compiled = simulate(**kw)
    monkeypatch.setattr("hpdob.simulation._simulate.closed_loop_kernel", lambda: run_closed_loop)
    plain = simulate(**kw)
    for name in ("theta", "omega", "u", "tau_hat", "tau_dn", "theta_measured"):
        np.testing.assert_array_equal(getattr(compiled, name), getattr(plain, name), err_msg=name)
