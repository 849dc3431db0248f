"""The subpackages' dependency order, the absence of import cycles and of imports of another
subpackage's private modules (issue 20, section 4), checked by import-linter with the contracts
of pyproject.toml's [tool.importlinter]."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _lint_imports() -> list[str]:
    exe = shutil.which("lint-imports", path=str(Path(sys.executable).parent)) or "lint-imports"
    return [exe, "--no-cache", str(ROOT / "pyproject.toml")]


def test_the_import_contracts_hold():
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    done = subprocess.run(
        _lint_imports(),
        cwd=ROOT / "src",
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-2000:]
    assert "Contracts: 13 kept, 0 broken." in done.stdout


def _lint_planted(tmp_path, module: str, line: str):
    """import-linter's output on a copy of the package with ``line`` appended to ``module``."""
    package = tmp_path / "hpdob"
    shutil.copytree(
        ROOT / "src" / "hpdob",
        package,
        ignore=shutil.ignore_patterns("__pycache__", "*.so", "data"),
    )
    target = package.joinpath(*module.split("/"))
    target.write_text(target.read_text() + f"\n{line}  # planted\n")
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    done = subprocess.run(
        _lint_imports(),
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    return done


def test_a_private_import_across_subpackages_breaks_them(tmp_path):
    """Tuning reaching into simulation's private module (not through hpdob.simulation) fails."""
    done = _lint_planted(tmp_path, "tuning/_runs.py", "from ..simulation._loop import ServoLoop")
    assert done.returncode != 0
    assert "hpdob.tuning is not allowed to import hpdob.simulation._loop" in done.stdout


def test_an_import_cycle_breaks_them(tmp_path):
    """A module of models that imports back the one importing it (a deferred import counts)."""
    done = _lint_planted(
        tmp_path, "models/_lti.py", "def _planted():\n    from ._servo import ServoModel"
    )
    assert done.returncode != 0
    assert "no import cycles between the modules of a package BROKEN" in done.stdout


def test_an_upward_import_breaks_them(tmp_path):
    """The contract is not vacuous: a copy of the package whose observers import analysis
    fails it."""
    package = tmp_path / "hpdob"
    shutil.copytree(
        ROOT / "src" / "hpdob",
        package,
        ignore=shutil.ignore_patterns("__pycache__", "*.so", "data"),
    )
    core = package / "observers" / "_core.py"
    core.write_text(core.read_text() + "\nfrom ..analysis import _noise  # planted\n")
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    done = subprocess.run(
        _lint_imports(),
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert done.returncode != 0
    assert "hpdob.observers is not allowed to import hpdob.analysis" in done.stdout
