"""Sphinx extension: the hpdob API reference, generated from the public ``__all__`` lists.

At ``builder-inited`` it writes ``docs/api/index.rst`` and one page per public subpackage of
:mod:`hpdob` (every ``hpdob.<name>`` whose name does not start with ``_``), each holding an
entry for every name in that subpackage's ``__all__``. Names in ``hpdob.__all__`` that are
re-exported from a subpackage are documented once, on the subpackage's page; a reference to
``hpdob.<name>`` is resolved to it. Names only the top level has get entries on the index
page. There is no hand-maintained list of names: a new public name, or a new public
subpackage, gets its entry at the next build (``tests/test_docsite.py`` checks the inventory).

It also adds the ``optional-toctree`` directive: a toctree whose entries that are not pages
of the project are left out (a page another branch is still writing).
"""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import pkgutil
import posixpath
import re
from dataclasses import dataclass
from pathlib import Path

from docutils.statemachine import StringList
from sphinx.directives.other import TocTree
from sphinx.util import logging

logger = logging.getLogger(__name__)

#: Order and titles of the sections: the architecture of the package. A public subpackage
#: missing here still gets a page (after these, titled with its name).
SECTIONS = {
    "models": "Models and plants",
    "observers": "Observers",
    "controllers": "Controllers",
    "simulation": "Loop and simulation",
    "robots": "Robots: N-joint arms",
    "analysis": "Analysis",
    "identification": "Real data and identification",
    "tuning": "Tuning",
    "export": "Export",
    "paper": "The paper's set-up",
    "signals": "Signals",
    "testing": "Testing helpers",
    "cli": "Command line",
}

#: reStructuredText that comes before a section's entries: the command-line reference opens
#: with the commands, not with the module's internals (``CLIError``, ``main``).
FIRST = {
    "cli": """
Commands and options
--------------------

Generated from the argparse parser of the ``hpdob`` command (``hpdob.cli.build_parser()``).

.. argparse::
   :module: hpdob.cli
   :func: build_parser
   :prog: hpdob
""",
}

TOP = "hpdob"


@dataclass(frozen=True)
class Entry:
    """One documented name: where it lives and how autodoc shows it."""

    module: str  # the public module whose page holds the entry, e.g. "hpdob.models"
    name: str
    kind: str  # "class", "exception", "function", "data", "module"

    @property
    def target(self) -> str:
        return f"{self.module}.{self.name}"


def public_subpackages() -> list[str]:
    """``hpdob.<name>`` for every public subpackage or module, in the architecture's order."""
    package = importlib.import_module(TOP)
    names = [
        name
        for _, name, _ in pkgutil.iter_modules(package.__path__)
        if not name.startswith("_") and hasattr(importlib.import_module(f"{TOP}.{name}"), "__all__")
    ]
    order = list(SECTIONS)
    names.sort(key=lambda n: (order.index(n) if n in order else len(order), n))
    return [f"{TOP}.{name}" for name in names]


def _kind(obj) -> str:
    if inspect.ismodule(obj):
        return "module"
    if inspect.isclass(obj):
        return "exception" if issubclass(obj, BaseException) else "class"
    if inspect.isroutine(obj):
        return "function"
    return "data"  # constants, including callable instances such as a Signal


def entries() -> dict[str, list[Entry]]:
    """``{module: [Entry, ...]}`` for the subpackages and the top level (key ``"hpdob"``)."""
    out: dict[str, list[Entry]] = {}
    homes: dict[int, Entry] = {}
    for modname in public_subpackages():
        module = importlib.import_module(modname)
        out[modname] = []
        for name in module.__all__:
            obj = getattr(module, name)
            entry = Entry(modname, name, _kind(obj))
            out[modname].append(entry)
            if entry.kind != "data":
                homes.setdefault(id(obj), entry)
    top = importlib.import_module(TOP)
    out[TOP] = []
    for name in top.__all__:
        obj = getattr(top, name)
        if inspect.ismodule(obj) and obj.__name__ in out:
            continue  # a public subpackage: its own page
        if id(obj) in homes and homes[id(obj)].name == name:
            continue  # re-exported: documented on its subpackage's page
        out[TOP].append(Entry(TOP, name, _kind(obj)))
    return out


def aliases() -> dict[str, str]:
    """``{"hpdob.<name>": "hpdob.<subpackage>.<name>"}`` for the top level's re-exports."""
    table = entries()
    homes = {
        id(getattr(importlib.import_module(e.module), e.name)): e
        for module, items in table.items()
        if module != TOP
        for e in items
        if e.kind != "data"
    }
    top = importlib.import_module(TOP)
    out = {}
    for name in top.__all__:
        obj = getattr(top, name)
        if inspect.ismodule(obj) and obj.__name__ in table:
            out[f"{TOP}.{name}"] = obj.__name__
        elif id(obj) in homes and homes[id(obj)].name == name:
            out[f"{TOP}.{name}"] = homes[id(obj)].target
    return out


def _data_doc(module, name: str) -> str:
    """The ``#:`` comment of a re-exported constant, found in the module that defines it."""
    from sphinx.pycode import ModuleAnalyzer

    obj = getattr(module, name)
    candidates = [module.__name__]
    if hasattr(module, "__path__"):
        candidates += [
            f"{module.__name__}.{sub}"
            for _, sub, _ in pkgutil.iter_modules(module.__path__)
            if sub != "__main__"  # importing it runs the command line
        ]
    for candidate in candidates:
        try:
            mod = importlib.import_module(candidate)
            docs = ModuleAnalyzer.for_module(candidate).find_attr_docs()
        except Exception:  # a module without source (or that fails to import): no comment
            continue
        if getattr(mod, name, None) is obj and ("", name) in docs:
            return "\n".join(docs[("", name)]).strip()
    return ""


def _value(obj) -> str:
    text = re.sub(r"\s+", " ", repr(obj))
    return text if len(text) <= 120 else text[:117] + "..."


def _private_bases(cls) -> list[type]:
    """The private (``_Name``) classes in ``cls``'s MRO: their members belong to its page."""
    return [base for base in cls.__mro__[1:] if base.__name__.startswith("_")]


def _public_base(cls) -> type:
    """``cls`` itself if public, else its nearest public base (for "Bases:" lines)."""
    while cls.__name__.startswith("_") and cls.__bases__:
        cls = cls.__bases__[0]
    return cls


def _process_bases(app, name, obj, options, bases) -> None:
    """Show the public class a private base stands for (``_DesignedObserver`` -> ``Observer``)."""
    bases[:] = list(dict.fromkeys(_public_base(base) for base in bases))


def _entry_rst(entry: Entry) -> str:
    if entry.kind == "class":
        cls = getattr(importlib.import_module(entry.module), entry.name)
        inherited = ""
        if _private_bases(cls):  # a private base's members (e.g. .design) shown as the class's
            inherited = f"   :inherited-members: {_public_base(_private_bases(cls)[0]).__name__}\n"
        return f".. autoclass:: {entry.name}\n   :members:\n{inherited}   :show-inheritance:\n"
    if entry.kind == "exception":
        return f".. autoexception:: {entry.name}\n   :show-inheritance:\n"
    if entry.kind == "function":
        return f".. autofunction:: {entry.name}\n"
    if entry.kind == "module":
        return f".. py:data:: {entry.name}\n\n   The module :mod:`{entry.target}`.\n"
    module = importlib.import_module(entry.module)
    doc = _data_doc(module, entry.name)
    lines = [f".. py:data:: {entry.name}", f"   :value: {_value(getattr(module, entry.name))}", ""]
    lines += [f"   {line}" if line else "" for line in doc.splitlines()]
    return "\n".join(lines) + "\n"


def _title(text: str, char: str = "=") -> str:
    return f"{text}\n{char * len(text)}\n"


def section_rst(modname: str, items: list[Entry]) -> str:
    short = modname.split(".", 1)[1]
    title = SECTIONS.get(short, f"``{modname}``")
    parts = [
        ".. This page is generated by docs/_ext/hpdob_api.py from "
        f"{modname}.__all__; do not edit.\n",
        _title(f"{title}: ``{modname}``"),
        f".. automodule:: {modname}\n   :no-members:\n",
        f".. currentmodule:: {modname}\n",
    ]
    parts.append(FIRST.get(short, ""))
    if items:
        if short in FIRST:
            parts.append(_title("Python entry points", "-"))
        parts.append(
            ".. autosummary::\n   :nosignatures:\n\n" + "".join(f"   {e.name}\n" for e in items)
        )
        parts += [_entry_rst(e) for e in items]
    return "\n".join(parts)


def index_rst(table: dict[str, list[Entry]]) -> str:
    top = table[TOP]
    alias = aliases()
    parts = [
        ".. This page is generated by docs/_ext/hpdob_api.py; do not edit.\n",
        _title("API reference"),
        "Every public name of hpdob, grouped like the package: one page per public subpackage, "
        "generated from its ``__all__``. The main entry points are also importable from "
        "``hpdob`` itself (``from hpdob import ServoModel``); the table below says where each "
        "is documented.\n",
        ".. toctree::\n   :maxdepth: 1\n\n"
        + "".join(f"   {m.split('.', 1)[1]}\n" for m in table if m != TOP),
        _title("The top-level namespace ``hpdob``", "-"),
        ".. list-table::\n   :header-rows: 1\n   :widths: 30 70\n\n"
        "   * - ``from hpdob import``\n     - documented as\n"
        + "".join(
            f"   * - ``{name}``\n     - :py:obj:`{alias[name]}`\n"
            for name in sorted(alias, key=str.lower)
        ),
    ]
    if top:
        parts += [
            "Names defined at the top level only:\n",
            ".. currentmodule:: hpdob\n",
            *(_entry_rst(e) for e in top),
        ]
    return "\n".join(parts)


def _write_if_changed(path: Path, text: str) -> None:
    if not path.exists() or path.read_text() != text:
        path.write_text(text)


def generate(app) -> None:
    """Write ``api/index.rst`` and ``api/<subpackage>.rst`` into the source directory."""
    out = Path(app.srcdir) / "api"
    out.mkdir(exist_ok=True)
    table = entries()
    wanted = {"index.rst"}
    for modname, items in table.items():
        if modname == TOP:
            continue
        name = f"{modname.split('.', 1)[1]}.rst"
        wanted.add(name)
        _write_if_changed(out / name, section_rst(modname, items))
    _write_if_changed(out / "index.rst", index_rst(table))
    for stale in out.glob("*.rst"):
        if stale.name not in wanted:  # a subpackage that was removed or renamed
            stale.unlink()


def _homes() -> dict[str, str]:
    """``{name: "hpdob.<subpackage>.<name>"}`` for public names documented exactly once."""
    found: dict[str, list[str]] = {}
    for items in entries().values():
        for e in items:
            found.setdefault(e.name, []).append(e.target)
    return {name: targets[0] for name, targets in found.items() if len(targets) == 1}


def _exists(target: str) -> bool:
    """Whether ``target`` names something real: a dotted import path, or a name in hpdob.

    A dotted path into a package that is not installed (an optional dependency) cannot be
    checked and counts as real.
    """
    parts = target.lstrip(".~").split(".")
    if len(parts) > 1 and parts[0] != TOP and importlib.util.find_spec(parts[0]) is None:
        return True  # another package that is not installed here (pandas without the extra)
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except Exception:  # not a module (or one that cannot be imported here)
            continue
        try:
            for attr in parts[i:]:
                obj = getattr(obj, attr)
        except AttributeError:
            break
        return True
    if len(parts) == 1:
        return parts[0] in _hpdob_names()
    return False


_NAMES: set[str] = set()


def _hpdob_names() -> set[str]:
    """Every attribute of every hpdob module and of every class defined in one."""
    if not _NAMES:
        package = importlib.import_module(TOP)
        for info in pkgutil.walk_packages(package.__path__, f"{TOP}."):
            if info.name.endswith("__main__"):
                continue  # importing it runs the command line
            module = importlib.import_module(info.name)
            for name, obj in vars(module).items():
                _NAMES.add(name)
                if inspect.isclass(obj) and obj.__module__.startswith(TOP):
                    _NAMES.update(vars(obj))
    return _NAMES


def resolve(app, env, node, contnode):
    """Resolve the Python references autodoc and the pages leave unresolved.

    1. ``hpdob.<name>[.<attr>]``: the subpackage entry the top level re-exports;
    2. a bare public name (``ServoModel`` in a docstring of another subpackage): its entry;
    3. a name that exists but has no entry (a private helper, another package's object):
       plain text, no link.
    Anything else stays a broken reference, which ``-W -n`` turns into an error.
    """
    if node.get("refdomain") != "py":
        return None
    target = node.get("reftarget", "")
    if not hasattr(env, "hpdob_tables"):
        env.hpdob_tables = (aliases(), _homes())
    alias_table, homes = env.hpdob_tables
    new = None
    for alias, real in alias_table.items():
        if target == alias or target.startswith(alias + "."):
            new = real + target[len(alias) :]
            break
    head, _, rest = target.partition(".")
    if new is None and head in homes:
        new = homes[head] + (f".{rest}" if rest else "")
    if new is not None:
        domain = env.domains["py"]
        found = domain.resolve_xref(
            env, node["refdoc"], app.builder, node["reftype"], new, node, contnode
        )
        if found is not None:
            return found
    if _exists(target):
        return contnode
    return None


class OptionalTocTree(TocTree):
    """A toctree that leaves out entries which are not pages of the project."""

    def run(self):
        env = self.state.document.settings.env
        kept = []
        for line in self.content:
            entry = line.strip()
            match = re.fullmatch(r"(?:.*<)?([^<>]+?)>?", entry)
            name = match.group(1) if match else entry
            if name.startswith("/"):
                docname = name[1:]
            else:
                docname = posixpath.normpath(posixpath.join(posixpath.dirname(env.docname), name))
            if not entry or docname in env.found_docs:
                kept.append(line)
        self.content = StringList(kept, source=env.docname)
        return super().run()


def setup(app):
    app.connect("builder-inited", generate)
    app.connect("missing-reference", resolve)
    app.connect("autodoc-process-bases", _process_bases)
    app.add_directive("optional-toctree", OptionalTocTree)
    return {"version": "1.0", "parallel_read_safe": True, "parallel_write_safe": True}
