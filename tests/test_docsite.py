"""The documentation site: a warning-free Sphinx build and an entry for every public name.

The site is built once per test session (``python -m sphinx -W -n``, warnings as errors,
every cross-reference checked) from a copy of ``docs/`` and ``examples/`` in a temporary
directory, so the build leaves nothing in the working tree. It needs the [docs] extra, which
the [test] extra includes; nothing here is skipped.
"""

from __future__ import annotations

import importlib
import pkgutil
import re
import shutil
import subprocess
import sys
import time
import zlib
from pathlib import Path

import pytest

import hpdob
from hpdob.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
GENERATED = ("_build", "api", "auto_examples", "sg_execution_times.rst", "__pycache__")


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """``(html directory, seconds)`` of one build of the site with -W -n."""
    tmp = tmp_path_factory.mktemp("site")
    shutil.copytree(ROOT / "docs", tmp / "docs", ignore=shutil.ignore_patterns(*GENERATED))
    shutil.copytree(
        ROOT / "examples",
        tmp / "examples",
        ignore=shutil.ignore_patterns("main", "dob.*", "*.args", "__pycache__"),
    )
    html = tmp / "html"
    cmd = [sys.executable, "-m", "sphinx", "-W", "-n", "-q", "-b", "html"]
    cmd += ["-d", str(tmp / "doctrees"), str(tmp / "docs"), str(html)]
    start = time.perf_counter()
    # A hang guard only: the build takes ~70 s on an idle 2-core machine and over 280 s
    # under a load of ~3.5, where a tighter limit failed every test of this file.
    done = subprocess.run(cmd, capture_output=True, text=True, check=False, timeout=900)
    seconds = time.perf_counter() - start
    assert done.returncode == 0, f"sphinx -W failed:\n{done.stdout}\n{done.stderr}"
    return html, seconds, done


def inventory(path: Path) -> set[tuple[str, str]]:
    """``{(domain:role, name)}`` of a Sphinx ``objects.inv`` (format version 2)."""
    header, _, body = path.read_bytes().partition(b"zlib.\n")
    assert b"# Sphinx inventory version 2" in header
    out = set()
    for line in zlib.decompress(body).decode().splitlines():
        match = re.match(r"(.+?)\s+(\S+:\S+)\s+-?\d+\s", line)
        assert match, line
        out.add((match.group(2), match.group(1)))
    return out


def public_subpackages() -> list[str]:
    """Every ``hpdob.<name>`` whose name is public and that curates an ``__all__``."""
    return [
        f"hpdob.{name}"
        for _, name, _ in pkgutil.iter_modules(hpdob.__path__)
        if not name.startswith("_") and hasattr(importlib.import_module(f"hpdob.{name}"), "__all__")
    ]


def test_build_is_warning_free(site):
    html, seconds, done = site
    assert "WARNING" not in done.stderr and "ERROR" not in done.stderr, done.stderr
    assert (html / "index.html").exists()
    print(f"sphinx -W -n html build: {seconds:.1f} s")  # shown with pytest -s


def test_every_public_name_has_an_entry(site):
    html, _, _ = site
    documented = {name for _, name in inventory(html / "objects.inv")}
    missing = []
    homes = {}
    subpackages = public_subpackages()
    assert {"hpdob.models", "hpdob.observers", "hpdob.simulation", "hpdob.analysis"} <= set(
        subpackages
    )
    for modname in subpackages:
        assert modname in documented, f"{modname} has no page"
        module = importlib.import_module(modname)
        for name in module.__all__:
            if f"{modname}.{name}" not in documented:
                missing.append(f"{modname}.{name}")
            homes.setdefault(id(getattr(module, name)), name)
    for name in hpdob.__all__:
        obj = getattr(hpdob, name)
        if getattr(obj, "__name__", None) in subpackages:
            continue  # a subpackage: its page is checked above
        if homes.get(id(obj)) == name:
            continue  # re-exported from a subpackage, whose entry is checked above
        if f"hpdob.{name}" not in documented:
            missing.append(f"hpdob.{name}")
    assert not missing, f"public names without an API entry: {missing}"


ARCHITECTURE = [
    "models",
    "observers",
    "simulation",
    "analysis",
    "identification",
    "tuning",
    "export",
    "paper",
    "signals",
    "testing",
    "cli",
]


def test_api_pages_follow_the_architecture(site):
    html, _, _ = site
    index = (html / "api" / "index.html").read_text()
    pages = re.findall(r'toctree-l1"><a class="reference internal" href="([\w-]+)\.html"', index)
    pages = list(dict.fromkeys(pages))  # the page's own toctree (the sidebar repeats it)
    subpackages = [m.split(".", 1)[1] for m in public_subpackages()]
    assert sorted(pages) == sorted(subpackages), "one page per public subpackage"
    known = [p for p in pages if p in ARCHITECTURE]
    assert known == [p for p in ARCHITECTURE if p in pages], "in the order of the architecture"


def _commands(parser, prefix=()):
    """``(command path, parser)`` for the parser and every subcommand, depth first."""
    yield prefix, parser
    for action in parser._actions:
        if action.__class__.__name__ == "_SubParsersAction":
            for name, sub in action.choices.items():
                yield from _commands(sub, (*prefix, name))


def test_cli_reference_is_generated_from_argparse(site):
    html, _, _ = site
    page = (html / "api" / "cli.html").read_text()
    for path, parser in _commands(build_parser()):
        if path:
            assert f">{path[-1]}<" in page, f"subcommand {' '.join(path)} missing"
        for action in parser._actions:
            if action.__class__.__name__ == "_HelpAction":
                continue  # sphinx-argparse leaves out -h/--help
            if action.help == "==SUPPRESS==":
                continue  # a refused old spelling (identify --limit): hidden from the help
            for option in action.option_strings:
                if option.startswith("--"):
                    assert option in page, f"{' '.join(path)} {option} missing"


def test_landing_page_has_the_readme_commands_and_the_papers_figure(site):
    html, _, _ = site
    blocks = re.findall(r"```bash\n(.*?)```", (ROOT / "README.md").read_text(), flags=re.S)
    landing = (ROOT / "docs" / "index.md").read_text()
    assert len(blocks) == 2
    for block in blocks:
        assert f"```bash\n{block}```" in landing, "the README's two commands, verbatim"
    page = (html / "index.html").read_text()
    images = re.findall(r'<img[^>]+src="([^"]+)"', page)
    assert any("plot_reproduce" in src for src in images)
    for src in images:
        assert (html / src).exists(), src


def test_gallery_renders_every_plot_example(site):
    html, _, _ = site
    scripts = sorted((ROOT / "examples").glob("plot_*.py"))
    assert len(scripts) >= 4
    for script in scripts:
        page = (html / "auto_examples" / f"{script.stem}.html").read_text()
        figure = f"sphx_glr_{script.stem}_001.png"
        assert figure in page and (html / "_images" / figure).exists(), script.name


def test_gallery_shows_the_figures_of_the_command_line_examples(site):
    """The scripts the build does not run show the figures they wrote into docs/figures."""
    html, _, _ = site
    scripts = [p for p in sorted((ROOT / "examples").glob("*.py")) if p.name[:5] != "plot_"]
    assert len(scripts) >= 6
    for script in scripts:
        names = re.findall(r"^\.\. image:: \.\./figures/(\S+)$", script.read_text(), flags=re.M)
        assert names, f"{script.name} shows no figure"
        page = html / "auto_examples" / f"{script.stem}.html"
        sources = re.findall(r'<img[^>]+src="([^"]+)"', page.read_text())
        for name in names:
            assert (ROOT / "docs" / "figures" / name).exists(), name
            shown = [src for src in sources if src.rsplit("/", 1)[-1] == name]
            assert shown and (page.parent / shown[0]).resolve().exists(), (script.name, name)


def test_every_markdown_page_is_on_the_site(site):
    html, _, _ = site
    for page in (ROOT / "docs").glob("*.md"):
        assert (html / f"{page.stem}.html").exists(), page.name


def test_docs_extra_is_part_of_the_test_extra():
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    extras = extras["optional-dependencies"]
    assert any(r.lower().startswith("sphinx") for r in extras["docs"]), "a [docs] extra"
    includes = [r for r in extras["test"] if r.startswith("hpdob[")]
    assert any("docs" in r[len("hpdob[") : r.index("]")].split(",") for r in includes)
