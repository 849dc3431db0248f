"""Plugins of the ``hpdob`` command (hpdob/_plugins.py): a family registered by a user's module
reaches the installed command through ``HPDOB_PLUGINS`` or the entry-point group
``hpdob.families`` (issue 20). The family is tests/low_pass_family.py's DOb followed by a
low-pass, defined in the tests only; each run is a fresh interpreter, as the command is.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from hpdob import ServoModel
from low_pass_family import design_filtered

ROOT = Path(__file__).resolve().parents[1]
DESIGN = ["design", "--type", "dob_lp", "--order", "1", "--bandwidth", "150",
          "--filter-bandwidth", "300", "--json"]  # fmt: skip


def _hpdob(argv, *path, **env) -> subprocess.CompletedProcess:
    python_path = os.pathsep.join([*map(str, path), str(ROOT / "tests"),
                                   str(ROOT / "src")])  # fmt: skip
    environ = {k: v for k, v in os.environ.items() if k != "HPDOB_PLUGINS"}
    environ |= {"PYTHONPATH": python_path, **env}
    return subprocess.run([sys.executable, "-m", "hpdob", *argv], capture_output=True, text=True,
                          env=environ, timeout=120, check=False)  # fmt: skip


def _expected_F():
    design = design_filtered(
        ServoModel(2.8e-4).discretize(1e-3), order=1, bandwidth=150.0, filter_bandwidth=300.0
    )
    return design.system.F


def test_a_family_of_a_module_named_in_hpdob_plugins_reaches_the_command(tmp_path):
    (tmp_path / "lab_families.py").write_text(
        "from hpdob.observers import register_family\n"
        "from low_pass_family import FILTERED\n"
        "register_family(FILTERED)\n"
    )
    without = _hpdob(DESIGN, tmp_path)
    assert without.returncode == 2
    assert "dob_lp" in without.stderr
    done = _hpdob(DESIGN, tmp_path, HPDOB_PLUGINS=" lab_families, ")
    assert done.returncode == 0, done.stderr[-2000:]
    np.testing.assert_array_equal(np.array(json.loads(done.stdout)["F"]), _expected_F())


def test_a_family_of_an_entry_point_reaches_the_command(tmp_path):
    (tmp_path / "lab_package.py").write_text("from low_pass_family import FILTERED\n")
    info = tmp_path / "lab_package-1.0.dist-info"  # what pip install writes for the package
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: lab-package\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text("[hpdob.families]\ndob_lp = lab_package:FILTERED\n")
    done = _hpdob(DESIGN, tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    np.testing.assert_array_equal(np.array(json.loads(done.stdout)["F"]), _expected_F())


def test_a_plugin_that_cannot_be_imported_is_one_line(tmp_path):
    done = _hpdob(["design", "--order", "1"], HPDOB_PLUGINS="no_such_lab_module")
    assert done.returncode == 2
    assert done.stderr.strip() == (
        "hpdob: error: HPDOB_PLUGINS names the module 'no_such_lab_module', which cannot be "
        "imported: ModuleNotFoundError: No module named 'no_such_lab_module'"
    )


def test_the_entry_points_are_read_once_per_process(monkeypatch):
    """Every command of a process calls load_plugins; the installed distributions are
    scanned on the first call only (a scan costs milliseconds and leaves cyclic garbage)."""
    import importlib.metadata

    from hpdob import _plugins

    scans = []

    def entry_points(**kwargs):
        scans.append(kwargs)
        return []

    monkeypatch.setattr(importlib.metadata, "entry_points", entry_points)
    _plugins.installed_entry_points.cache_clear()
    try:
        assert _plugins.load_plugins({}) == ()
        assert _plugins.load_plugins({}) == ()
    finally:  # the real entry points for the next caller
        _plugins.installed_entry_points.cache_clear()
    assert scans == [{"group": _plugins.ENTRY_POINT_GROUP}]
