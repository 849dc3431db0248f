"""The compiled kernel: lazily imported, cached, identical to the same code run as plain Python."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from hpdob import Actuator, Encoder, paper, simulate

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


def test_import_hpdob_loads_no_heavy_modules():
    code = (
        "import sys, hpdob; heavy = [m for m in ('numba', 'matplotlib', 'pandas', 'dask', "
        "'control', 'scipy.signal', 'mujoco') if m in sys.modules]; print(heavy)"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"


def test_kernel_is_numba_compiled_with_cache():
    from hpdob.simulation import _kernel

    for function in (_kernel.run_samples, _kernel.ground_truth):
        assert function.targetoptions.get("nogil") is True
        assert function._cache.__class__.__name__ != "NullCache"  # cache=True


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
