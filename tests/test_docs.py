"""The documentation runs: README and docs code blocks, doctests, the CI contract, ruff."""

from __future__ import annotations

import doctest
import importlib
import pkgutil
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import hpdob

ROOT = Path(__file__).resolve().parents[1]


def code_blocks(path: Path, language: str) -> list[str]:
    return re.findall(rf"```{language}\n(.*?)```", path.read_text(), flags=re.S)


#: Every Markdown page with Python blocks: the README and all of docs/ (guides included).
MARKDOWN = [
    ROOT / "README.md",
    *sorted(
        p for p in (ROOT / "docs").rglob("*.md") if not {"_build", "auto_examples"} & set(p.parts)
    ),
]


@pytest.mark.parametrize("path", MARKDOWN, ids=lambda p: str(p.relative_to(ROOT)))
def test_python_blocks_run(path, tmp_path, monkeypatch):
    # a page's ahead-of-time build (docs/simulation.md) goes to a folder of its own: in the
    # suite's folder it would change which loop later tests in this worker run
    monkeypatch.setenv("HPDOB_AOT_DIR", str(tmp_path / "aot"))
    if path.name in ("mujoco.md", "robots.md"):
        pytest.importorskip("mujoco")  # the [mujoco] extra (part of [test])
    hidden = re.findall(
        r"^```(py|python3|pycon|\{code-block\}\s*python)\s*$", path.read_text(), re.M
    )
    assert not hidden, f"{path.name}: Python blocks must be ```python to be run here"
    namespace: dict = {}
    for block in code_blocks(path, "python"):
        exec(compile(block, str(path), "exec"), namespace)


PRIVATE_IMPORT = re.compile(
    r"^\s*(?:from\s+hpdob(?:\.\w+)*\.(_\w+)\s+import|import\s+hpdob(?:\.\w+)*\.(_\w+))",
    re.M,
)


def test_docs_examples_and_benchmarks_use_public_names_only():
    """hpdob's public namespaces are what users get: the material they copy from must not
    import a private module (``hpdob._x`` or ``hpdob.sub._x``)."""
    paths = [
        ROOT / "README.md",
        *(ROOT / "docs").rglob("*.md"),
        *(ROOT / "examples").glob("*.py"),
        *(ROOT / "benchmarks").glob("*.py"),
    ]
    offenders = []
    for path in paths:
        if "_build" in path.parts or "auto_examples" in path.parts:
            continue
        for match in PRIVATE_IMPORT.finditer(path.read_text()):
            offenders.append(f"{path.relative_to(ROOT)}: {match.group(0).strip()}")
    assert offenders == []


def test_readme_quick_start_is_short():
    blocks = code_blocks(ROOT / "README.md", "python")
    assert len(blocks) == 1
    assert len(blocks[0].strip().splitlines()) <= 20


def test_ci_runs_the_readme_test_command_verbatim():
    commands = [b.strip() for b in code_blocks(ROOT / "README.md", "bash")]
    assert len(commands) == 2, "the README has exactly two commands: main job and tests"
    test_command = next(c for c in commands if "pytest" in c)
    ci_lines = (ROOT / ".ci" / "run").read_text().splitlines()
    assert test_command in ci_lines


MODULES = sorted(
    name
    for _, name, _ in pkgutil.walk_packages(hpdob.__path__, "hpdob.")
    if name != "hpdob.__main__"
)


@pytest.mark.parametrize("name", MODULES)
def test_doctests(name):
    if name.startswith(("hpdob.models._mujoco", "hpdob.robots._panda")):
        pytest.importorskip("mujoco")  # the [mujoco] extra (part of [test])
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0


def test_public_namespace_is_curated():
    for name in hpdob.__all__:
        assert hasattr(hpdob, name), name
    for name in hpdob.__all__:
        obj = getattr(hpdob, name)
        if callable(obj):
            assert obj.__doc__, f"{name} has no docstring"


def test_ruff_clean():
    ruff = shutil.which("ruff", path=str(Path(sys.executable).parent)) or shutil.which("ruff")
    if ruff is None:
        pytest.skip("ruff is not installed (it is in the [test] extra)")
    done = subprocess.run([ruff, "check", str(ROOT)], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stdout + done.stderr
