"""The public API's docstrings follow numpydoc (house rules): every public function, method and
class in a public ``__all__`` documents its arguments and what it returns; no docstring holds
a control character."""

from __future__ import annotations

import ast
import importlib
import inspect
import pkgutil
import re
import textwrap
import warnings
from pathlib import Path

from numpydoc.docscrape import NumpyDocString

import hpdob

ROOT = Path(__file__).resolve().parents[1]
NAMESPACES = ["hpdob"] + [
    f"hpdob.{name}" for _, name, _ in pkgutil.iter_modules(hpdob.__path__) if name[0] != "_"
]


def public_objects():
    """``(qualified name, object, kind)`` of every public function, class, method, property."""
    seen = set()
    for modname in NAMESPACES:
        module = importlib.import_module(modname)
        for name in getattr(module, "__all__", []):
            obj = getattr(module, name)
            if id(obj) in seen or not getattr(obj, "__module__", "").startswith("hpdob"):
                continue
            seen.add(id(obj))
            if inspect.isfunction(obj):
                yield f"{modname}.{name}", obj, "function"
            elif inspect.isclass(obj):
                yield f"{modname}.{name}", obj, "class"
                for attr, value in vars(obj).items():
                    qualname = f"{modname}.{name}.{attr}"
                    if attr.startswith("_"):
                        continue
                    if isinstance(value, property):
                        yield qualname, value.fget, "property"
                    elif isinstance(value, (staticmethod, classmethod)):
                        yield qualname, value.__func__, "function"
                    elif inspect.isfunction(value):
                        yield qualname, value, "function"


def documented(doc: NumpyDocString, sections) -> set[str]:
    names = set()
    for section in sections:
        for item in doc[section]:
            names.update(n.strip().lstrip("*") for n in item.name.split(","))
    return names


def returns_a_value(func) -> bool:
    """Whether the function's own body (not a nested one) returns something other than None."""
    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(func)))
    except (OSError, TypeError, SyntaxError):
        return False
    stack = list(tree.body[0].body)
    while stack:
        node = stack.pop()
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda, ast.ClassDef)):
            continue
        if isinstance(node, (ast.Yield, ast.YieldFrom)):
            return True
        value = node.value if isinstance(node, ast.Return) else None
        if value is not None and not (isinstance(value, ast.Constant) and value.value is None):
            return True
        stack.extend(ast.iter_child_nodes(node))
    return False


def gaps(qualname: str, obj, kind: str) -> list[str]:
    doc = inspect.getdoc(obj) or ""  # inherited by an override without a docstring
    if not doc.strip():
        return [f"{qualname}: no docstring"]
    if kind == "property" or (kind == "class" and issubclass(obj, BaseException)):
        return []  # the docstring is the description
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # numpydoc warns about sections it does not know
        parsed = NumpyDocString(doc)
    try:
        params = [
            p.name
            for p in inspect.signature(obj).parameters.values()
            if p.name not in ("self", "cls") and not p.name.startswith("_")
        ]
    except (TypeError, ValueError):
        params = []
    sections = ("Parameters", "Other Parameters")
    if kind == "class":
        sections += ("Attributes",)  # dataclass fields are documented as attributes
    missing = [p for p in params if p not in documented(parsed, sections)]
    out = [f"{qualname}: parameters not documented: {missing}"] if missing else []
    if kind == "function" and returns_a_value(obj) and not (parsed["Returns"] or parsed["Yields"]):
        out.append(f"{qualname}: no Returns section")
    return out


def test_public_api_documents_parameters_and_returns():
    objects = list(public_objects())
    assert len(objects) > 250  # the walk found the API (291 objects when written)
    problems = [gap for qualname, obj, kind in objects for gap in gaps(qualname, obj, kind)]
    assert problems == [], "\n".join(problems)


def test_docstrings_hold_no_control_characters():
    r"""A ``\t``, ``\b``, ``\f``, ``\v`` or ``\a`` in a docstring that is not raw becomes a
    control character (``:math:`\tau``` reads as a tab and ``au``)."""
    found = []
    for path in sorted((ROOT / "src" / "hpdob").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
                doc = ast.get_docstring(node, clean=False)
                if doc and re.search(r"[\t\a\b\v\f\r]", doc):
                    found.append(f"{path.relative_to(ROOT)}: {getattr(node, 'name', 'module')}")
    assert found == []
