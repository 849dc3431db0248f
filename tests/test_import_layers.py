"""The subpackages' dependency order and the absence of import cycles (issue 20, section 4),
checked by import-linter with the contracts of pyproject.toml's [tool.importlinter]."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _lint_imports() -> list[str]:
    exe = shutil.which("lint-imports", path=str(Path(sys.executable).parent)) or "lint-imports"
    return [exe, "--no-cache", "--config", str(ROOT / "pyproject.toml")]


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
    assert "Contracts: 2 kept, 0 broken." in done.stdout


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
