"""The ahead-of-time built sample loop: found, checked and called without numba.

:func:`hpdob.simulation.build_loop_extension` builds a run structure's loop (the source
:func:`~hpdob.simulation._loop_source.loop_source` writes, the one the JIT compiles) with
``numba.pycc`` into a C extension in :func:`extension_folder`. :func:`simulate_loop` is
:func:`hpdob.simulate`'s route to it: it generates the run's source (no numba needed), types
the arguments as numba's signature would (:func:`argument_types`), and looks for the extension
named by the hash of both and of the versions that make its machine code the JIT's
(:func:`extension_name`). Found, the run calls it, and numba is never imported; not found, not
loadable or disabled (``HPDOB_AOT=0``), the caller runs the JIT loop. The extension's exported
function checks no argument (a wrong dtype or layout would read garbage): the name carries
every argument's type, so an extension is only called on arguments of the types it was built
for, and arguments of any other kind (an unaligned or byte-swapped array, an array subclass,
an integer beyond 64 bits) have no type here and run the JIT loop.

Only :func:`hpdob.simulate` takes this route: ``pycc``'s wrapper holds the GIL, so a sweep and
``tune()``, which run the ``nogil`` JIT loop on threads, keep the JIT loop.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.machinery
import importlib.util
import os
import sys
import threading
import warnings
from pathlib import Path

import numpy as np

from ._loop_source import loop_source, run_structure, signature_fields

__all__ = [
    "CODE_VARIABLES",
    "CONFIG_FILE",
    "DISABLE_VARIABLE",
    "FOLDER_VARIABLE",
    "AheadOfTimeWarning",
    "argument_types",
    "code_settings",
    "extension_folder",
    "extension_name",
    "simulate_loop",
]

#: The folder of built loops (default ``~/.cache/hpdob/aot``, or ``$XDG_CACHE_HOME/hpdob/aot``).
FOLDER_VARIABLE = "HPDOB_AOT_DIR"
#: ``HPDOB_AOT=0`` (or ``false``, ``no``, ``off``): ``simulate`` never uses a built loop.
DISABLE_VARIABLE = "HPDOB_AOT"
#: The file names of built loops: this prefix, the key, the platform's extension suffix.
PREFIX = "hpdob_aot_"
SUFFIX = importlib.machinery.EXTENSION_SUFFIXES[0]


class AheadOfTimeWarning(RuntimeWarning):
    """A built loop that matches a run could not be loaded; the run used the JIT loop."""


def extension_folder(folder=None) -> Path:
    """The folder of built loops: ``folder``, else ``$HPDOB_AOT_DIR``, else ``aot`` under the
    user's cache folder (``$XDG_CACHE_HOME/hpdob`` or ``~/.cache/hpdob``)."""
    if folder is not None:
        return Path(folder)
    named = os.environ.get(FOLDER_VARIABLE)
    if named:
        return Path(named)
    cache = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(cache) / "hpdob" / "aot"


#: The folder ``simulate`` looks in (None: disabled), by the two variables that decide it; the
#: default folder is found once per process (finding the home folder costs ~25 us, a tenth of
#: a 1 s run; each variable read ~2 us).
_FOLDERS: dict = {}


@functools.cache
def _default_folder() -> Path:
    return extension_folder()


def _route_folder() -> Path | None:
    get = os.environ.get
    key = (get(DISABLE_VARIABLE), get(FOLDER_VARIABLE))
    try:
        return _FOLDERS[key]
    except KeyError:
        off = (key[0] or "").strip().lower() in ("0", "false", "no", "off")
        folder = None if off else Path(key[1]) if key[1] else _default_folder()
        _FOLDERS[key] = folder
        return folder


#: Types of a scalar argument, as numba types them (``typeof``: a Python ``int`` below 2**63
#: is ``int64``, a ``float`` ``float64``, numpy scalars their dtype).
_SCALARS = {bool: "bool", float: "float64", np.bool_: "bool", np.float64: "float64",
            np.int64: "int64", np.int32: "int32"}  # fmt: skip
#: The array dtypes a built loop may take (the records' arrays: float64, int64 and bool).
_DTYPES = {np.dtype(np.float64): "float64", np.dtype(np.int64): "int64",
           np.dtype(np.bool_): "bool"}  # fmt: skip


def argument_types(arguments) -> tuple | None:
    """The numba types of ``arguments`` as numba's dispatcher types them, one entry each:
    ``"int64"``, ``"float64"``, ``"bool"`` for scalars, ``("array", dtype, ndim, layout,
    readonly)`` for an ndarray (``layout`` ``"C"`` if C-contiguous, else ``"F"`` if
    Fortran-contiguous, else ``"A"``: numba's ``map_layout``); None if any argument has no
    type here (an array subclass, an unaligned or byte-swapped array, another dtype, an
    integer of 64 bits or more, any other object), for which the JIT loop runs.

    Examples
    --------
    >>> import numpy as np
    >>> a = np.zeros((3, 2))
    >>> argument_types([1, 0.5, a, a[:, 0]])
    ('int64', 'float64', ('array', 'float64', 2, 'C', False), ('array', 'float64', 1, 'A', False))
    >>> argument_types([np.zeros(3, dtype=np.float32)]) is None
    True
    """
    types = []
    for value in arguments:
        kind = type(value)
        if kind is np.ndarray:
            flags = value.flags
            dtype = _DTYPES.get(value.dtype)
            if dtype is None or not flags.aligned or not value.dtype.isnative:
                return None
            layout = "C" if flags.c_contiguous else "F" if flags.f_contiguous else "A"
            types.append(("array", dtype, value.ndim, layout, not flags.writeable))
        elif kind is int:
            if not -(2**63) < value < 2**63:  # numba: uint64 or an error beyond
                return None
            types.append("int64")
        else:
            scalar = _SCALARS.get(kind)
            if scalar is None:
                return None
            types.append(scalar)
    return tuple(types)


def _installed_version(name: str) -> str:
    """The installed version of distribution ``name`` without importing it (its
    ``.dist-info`` folder's name beside the package; ``importlib.metadata`` costs ~0.1 s)."""
    spec = importlib.util.find_spec(name)
    if spec is None or spec.origin is None:
        return "absent"
    site = Path(spec.origin).parent.parent
    try:
        found = [e for e in os.listdir(site) if e.startswith(f"{name}-") and
                 e.endswith(".dist-info")]  # fmt: skip
    except OSError:
        found = []
    if len(found) == 1:
        return found[0][len(name) + 1 : -len(".dist-info")]
    from importlib.metadata import version  # an unusual layout: ask the slow way

    return version(name)


@functools.cache
def environment() -> str:
    """What makes a built loop's machine code the JIT's and loadable: numba's, numpy's and
    Python's versions and the platform."""
    return repr((_installed_version("numba"), np.__version__, sys.version, sys.platform, SUFFIX))


#: numba's settings (environment variables, numba.core.config) that change the machine code
#: numba.pycc generates for a loop, or whether numba compiles at all: the optimisation level
#: and vectorisers, bounds checks, debug information (and profiling, which turns it on),
#: variable lifetimes, the reference-count pruning pass, Intel SVML, ``NUMBA_DISABLE_JIT``.
#: Not among them: ``NUMBA_CPU_NAME`` and ``NUMBA_CPU_FEATURES``, which only the JIT reads
#: (pycc compiles for the architecture's generic CPU, numba.core.codegen.AOTCPUCodegen),
#: and settings of caching, threads, diagnostics and other targets.
CODE_VARIABLES = ("NUMBA_OPT", "NUMBA_LOOP_VECTORIZE", "NUMBA_SLP_VECTORIZE",
                  "NUMBA_BOUNDSCHECK", "NUMBA_DEBUGINFO", "NUMBA_ENABLE_PROFILING",
                  "NUMBA_EXTEND_VARIABLE_LIFETIMES", "NUMBA_LLVM_REFPRUNE_PASS",
                  "NUMBA_LLVM_REFPRUNE_FLAGS", "NUMBA_DISABLE_INTEL_SVML",
                  "NUMBA_DISABLE_JIT")  # fmt: skip


#: numba's file of settings, which numba.core.config reads from the working folder (with
#: PyYAML installed) under the environment's ``NUMBA_*`` variables; a build runs there too.
CONFIG_FILE = ".numba_config.yaml"


def code_settings() -> tuple:
    """The values of :data:`CODE_VARIABLES` now as numba takes them (None where unset): from
    the environment, else from a :data:`CONFIG_FILE` in the working folder; read on every
    lookup as numba reads them on every compile."""
    settings = dict.fromkeys(CODE_VARIABLES)
    if os.path.isfile(CONFIG_FILE):
        settings.update(_config_file())
    settings.update((name, os.environ[name]) for name in CODE_VARIABLES if name in os.environ)
    return tuple(settings.values())


def _config_file() -> dict:
    """The code settings of :data:`CONFIG_FILE`, as numba reads its keys (``opt: 0`` is
    ``NUMBA_OPT``); a file numba cannot read gives a setting no build has."""
    try:
        import yaml
    except ImportError:  # numba ignores the file then (with a warning)
        return {}
    try:
        with open(CONFIG_FILE, encoding="utf-8") as handle:
            values = yaml.safe_load(handle)
        names = {f"NUMBA_{str(key).upper()}": str(value) for key, value in (values or {}).items()}
    except (OSError, UnicodeError, yaml.YAMLError, AttributeError):
        return {CODE_VARIABLES[0]: f"unreadable {CONFIG_FILE}"}
    return {name: value for name, value in names.items() if name in CODE_VARIABLES}


def extension_name(source: str, types, settings: tuple | None = None) -> str:
    """The module (and file) name of the extension built from ``source`` for ``types``
    (:func:`argument_types`) in this environment (:func:`environment`) with numba's code
    ``settings`` (:func:`code_settings`, the current ones by default): a build and a run in
    which any of them differs have different names, so the run never takes that build."""
    if settings is None:
        settings = code_settings()
    return _name(source, tuple(types), settings)


@functools.lru_cache(maxsize=256)
def _name(source: str, types: tuple, settings: tuple) -> str:  # the hash: ~35 us a call
    text = "\n".join((source, repr(types), environment(), repr(settings)))
    return PREFIX + hashlib.sha256(text.encode()).hexdigest()[:24]


@functools.lru_cache(maxsize=256)
def _source(structure: tuple) -> tuple:
    source = loop_source(structure)
    return source, signature_fields(source)


# The folder's listing, kept while its modification time stays (a build renames its file into
# it), and the functions loaded, by path (an extension cannot be unloaded).
_LISTINGS: dict = {}
_LOADED: dict = {}
_LOCK = threading.Lock()


def _listing(folder: Path) -> frozenset:
    try:
        stamp = os.stat(folder).st_mtime_ns
    except OSError:
        return frozenset()
    kept = _LISTINGS.get(folder)
    if kept is not None and kept[0] == stamp:
        return kept[1]
    try:
        names = frozenset(e for e in os.listdir(folder) if e.startswith(PREFIX) and
                          e.endswith(SUFFIX))  # fmt: skip
    except OSError:
        names = frozenset()
    _LISTINGS[folder] = (stamp, names)
    return names


def record_path(path: Path) -> Path:
    """The file beside extension ``path`` holding its size and SHA-256 (:func:`file_record`)
    and, on a second line, the build's compiler settings (:func:`recorded_build`)."""
    return path.with_name(path.name[: -len(SUFFIX)] + ".sha256")


def file_record(path: Path) -> str:
    """``"<size> <sha256>"`` of the file at ``path``."""
    data = path.read_bytes()
    return f"{len(data)} {hashlib.sha256(data).hexdigest()}"


def _record_lines(path: Path) -> list:
    try:
        return record_path(path).read_text(encoding="ascii").splitlines()
    except (OSError, UnicodeDecodeError):
        return []


def intact(path: Path) -> bool:
    """Whether the extension at ``path`` has the size and SHA-256 its build recorded."""
    lines = _record_lines(path)
    try:
        return bool(lines) and file_record(path) == lines[0].strip()
    except OSError:
        return False


def recorded_build(path: Path) -> str | None:
    """The compiler settings the build of the extension at ``path`` recorded (the record's
    second line; None if it has none: a build by an hpdob that did not record them)."""
    lines = _record_lines(path)
    return lines[1] if len(lines) > 1 else None


def forget(path: Path) -> None:
    """Let the next :func:`load_extension` of ``path`` try again (after a new build)."""
    with _LOCK:
        if _LOADED.get(path, 0) is None:
            del _LOADED[path]


def load_extension(path: Path):
    """The ``run`` function of the extension at ``path`` (its module named as the file), or
    None with an :class:`AheadOfTimeWarning` if it cannot be loaded: its size and SHA-256 are
    not those its build recorded (:func:`record_path`; loading a truncated shared object can
    crash the process, so it is checked first), or the import fails (one built for another
    module name)."""
    with _LOCK:
        if path in _LOADED:
            return _LOADED[path]
        name = path.name[: -len(SUFFIX)]
        try:
            if not intact(path):
                raise ImportError("its size or SHA-256 is not the one its build recorded")
            loader = importlib.machinery.ExtensionFileLoader(name, str(path))
            spec = importlib.util.spec_from_file_location(name, path, loader=loader)
            module = importlib.util.module_from_spec(spec)
            loader.exec_module(module)
            function = module.run
        except (ImportError, OSError, AttributeError) as error:
            warnings.warn(
                f"the built sample loop {path} could not be loaded ({error}); the run uses "
                "the JIT-compiled loop (delete the file, or build it again with "
                "hpdob.simulation.build_loop_extension)",
                AheadOfTimeWarning,
                stacklevel=2,
            )
            function = None
        _LOADED[path] = function
        return function


class Captured(Exception):  # not an error: it ends a run build_loop_extension watches
    """Raised by :func:`simulate_loop` while :data:`CAPTURE` watches: the run's loop is known."""


#: Set ``CAPTURE.target`` to a dict and :func:`simulate_loop` stores the run's structure,
#: source and argument types in it and raises :class:`Captured` (``build_loop_extension``).
CAPTURE = threading.local()


def simulate_loop(k_stop, substeps, Ts, plant, ctl, sen, act, obs, sig, out, work, limit,
                  midpoint=None):  # fmt: skip
    """The built loop of this run, as ``run(k_start, k_stop)`` (the number of samples
    completed, as ``run_samples``), or None: no built loop matches the run's structure and
    argument types, loading it failed, or ``HPDOB_AOT=0``. ``k_stop`` is the run's length (an
    ``int`` as every chunk's bounds, so the types hold for every call)."""
    capture = getattr(CAPTURE, "target", None)
    if capture is None:
        folder = _route_folder()
        names = frozenset() if folder is None else _listing(folder)
        if not names:
            return None
    structure = run_structure(plant, ctl, sen, act, obs, sig, work, midpoint)
    source, fields = _source(structure)
    records = {"plant": plant, "ctl": ctl, "sen": sen, "act": act, "obs": obs, "sig": sig,
               "out": out, "work": work}  # fmt: skip
    arguments = [getattr(records[record], field) for record, field in fields]
    leading = (0, k_stop, substeps, Ts, limit)
    types = argument_types((*leading, *arguments))
    if capture is not None:
        capture.update(structure=structure, source=source, types=types)
        raise Captured
    if types is None:
        return None
    name = extension_name(source, types)
    if name + SUFFIX not in names:
        return None
    function = load_extension(folder / (name + SUFFIX))
    if function is None:
        return None

    def run(k_start: int, k_stop: int) -> int:
        return function(k_start, k_stop, substeps, Ts, limit, *arguments)

    return run
