"""Build a run structure's sample loop ahead of time: :func:`build_loop_extension`."""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import math
import numbers
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from .._files import check_output
from .._validation import ParameterTypeError, ParameterValueError
from . import _aot
from ._loop import ServoLoop, accepts_loop
from ._simulate import AT_REST, simulate

__all__ = ["LoopBuildError", "build_loop_extension"]


class LoopBuildError(RuntimeError):
    """``numba.pycc`` or the C compiler failed to build a loop; nothing was written."""


def _command(compiler, name: str) -> str:
    if isinstance(compiler, (str, os.PathLike)):
        try:
            parts = shlex.split(os.fspath(compiler))
        except ValueError as error:  # an unclosed quotation, a trailing escape
            raise ParameterValueError(
                f"{name} must be a command line shlex can split, got {compiler!r} ({error})"
            ) from None
    elif isinstance(compiler, (list, tuple)) and all(isinstance(p, str) for p in compiler):
        parts = list(compiler)
    else:
        raise ParameterTypeError(
            f"{name} must be a command line (a str such as 'clang', or a list of str), "
            f"got {compiler!r}"
        )
    if not parts or not all(parts):
        raise ParameterValueError(f"{name} must name a compiler command, got {compiler!r}")
    return shlex.join(parts)


def _compiler_commands(compiler, cxx_compiler) -> tuple | None:
    """``(C command, C++ command)`` for the build, or None: the one setuptools finds."""
    if compiler is None:
        if cxx_compiler is not None:
            raise ParameterValueError(
                f"cxx_compiler needs a compiler as well, got cxx_compiler={cxx_compiler!r} "
                "and compiler=None"
            )
        return None
    if compiler == "zig":  # the ziglang package (the test extra's)
        if cxx_compiler is not None:  # zig c++ compiles numba's runtime: no other is run
            raise ParameterValueError(
                f"cxx_compiler must be None with compiler='zig' (it runs zig c++), got "
                f"cxx_compiler={cxx_compiler!r}"
            )
        zig = [sys.executable, "-m", "ziglang"]
        # -nostdlib for the link: an extension's C library calls are bound by the Python
        # process that loads it, and without the flag zig first builds its own C runtime and
        # glibc stubs (~40 s on the first build of a machine, against ~0.1 s)
        return shlex.join([*zig, "cc", "-nostdlib"]), shlex.join([*zig, "c++"])
    c = _command(compiler, "compiler")
    return c, c if cxx_compiler is None else _command(cxx_compiler, "cxx_compiler")


@accepts_loop
def build_loop_extension(
    loop: ServoLoop,
    *,
    reference,
    disturbance=None,
    duration: float | None = None,
    substeps: int | None = None,
    x0=AT_REST,
    folder=None,
    compiler=None,
    cxx_compiler=None,
    timeout: float = 600.0,
) -> Path:
    r"""Build the sample loop of ``loop``'s runs ahead of time, so that :func:`~hpdob.simulate`
    runs it in a later process without numba.

    :func:`~hpdob.simulate` compiles a loop per run *structure* with numba and caches its
    machine code, but every process that loads it first initialises numba (~0.3 s with its
    import, docs/performance.md). This function generates the same loop source the JIT path
    compiles, for the structure and argument types of ``simulate(loop, reference=reference,
    disturbance=disturbance, duration=duration, substeps=substeps, x0=x0)``, and builds it with
    ``numba.pycc`` into a C extension in ``folder``. A later :func:`~hpdob.simulate` of a run
    of the same structure (the same loop parts and sensor mode, the same kind of disturbance
    and any ``duration``, ``x0``, gains or bandwidths that keep the program's shape) finds it
    there, checks that every argument has the type it was built for and calls it, without
    importing numba; its results are bit for bit the JIT loop's. Any other run, sweeps and
    ``tune()`` (whose threads need the JIT loop's ``nogil``) run the JIT loop.

    The extension's name is a hash of the generated source, the argument types, the numba,
    numpy and Python versions and the platform, and numba's settings that change the code it
    generates (``NUMBA_OPT``, ``NUMBA_LOOP_VECTORIZE``, ``NUMBA_BOUNDSCHECK``, ... from the
    environment or a ``.numba_config.yaml`` in the working folder, read by the build and by
    every run): a change of any (a new hpdob or numba,
    another ``NUMBA_OPT``) builds and uses a new one. The compiler commands and the flags
    setuptools takes from the environment (``CFLAGS``, ``LDFLAGS``, ...) are recorded beside
    it: a build with other ones replaces it, one with the same returns it. It is built in a
    temporary folder inside ``folder``, by a process of its own (on POSIX in a session of its
    own: a timeout or a ``KeyboardInterrupt`` kills it and the compilers it started), and
    renamed into place, its size and SHA-256 recorded beside it (a run checks both before
    loading it), so an interrupted or failed build leaves no file a run would load; a second
    build of the same loop at once (another process) waits for the first on a lock file
    (``fcntl.flock``, on Windows ``msvcrt.locking``; removed when the build ends) and returns
    its file. A build removes what killed builds of its loop left (their lock file and
    temporary folder) and the object files ``folder/.objects`` keeps for other numba, numpy
    or Python versions; those of this environment stay for later builds. Set
    ``HPDOB_AOT=0`` (or ``false``, ``no``, ``off``) to have :func:`~hpdob.simulate` ignore
    built loops.

    ``numba.pycc`` is *pending deprecation* in numba (since 0.57; numba's deprecation notices
    promise deprecation warnings and two releases before removal). Where it is gone the build
    raises :class:`~hpdob.simulation.LoopBuildError` and :func:`~hpdob.simulate` runs the JIT
    loop, as before.

    Parameters
    ----------
    loop : ServoLoop
        The loop (plant, nominal model, ``Ts``, controller, observer, sensor, actuator); or its
        parts as keyword arguments (:data:`hpdob.simulation.LOOP_KEYS`). A plant advanced from
        Python (MuJoCo) runs no compiled loop and is rejected.
    reference : Signal or callable
        The runs' reference, as for :func:`~hpdob.simulate`.
    disturbance : callable, optional
        The runs' disturbance, as for :func:`~hpdob.simulate` (its kind decides how the loop
        evaluates it).
    duration : float, optional
        A duration of the runs [s] (it does not change the loop); default ``10 Ts``.
    substeps : int, optional
        Plant sub-steps per sample, as for :func:`~hpdob.simulate`.
    x0 : sequence of 2 floats, optional
        Initial motor state ``[theta (rad), omega (rad/s)]``, as for :func:`~hpdob.simulate`.
    folder : str or path-like, optional
        Where the extension is written and where :func:`~hpdob.simulate` looks: default
        ``$HPDOB_AOT_DIR``, else ``~/.cache/hpdob/aot`` (``$XDG_CACHE_HOME/hpdob/aot``).
        :func:`~hpdob.simulate` looks only in that default, so a build into another folder is
        used by processes that set ``HPDOB_AOT_DIR`` to it.
    compiler : str or list of str, optional
        The C compiler command (``"clang"``, ``["gcc", "-O2"]``), also used for numba's C++
        runtime and the link unless ``cxx_compiler`` is given; ``"zig"``: the ``ziglang``
        package's ``zig cc`` and ``zig c++`` (no compiler installed on the machine needed).
        Default: ``$CC``, else the one ``setuptools`` finds.
    cxx_compiler : str or list of str, optional
        The C++ compiler command, for numba's runtime and the link (with ``compiler``, not
        ``"zig"``).
    timeout : float, optional
        Seconds the build may take before it is stopped, its process and compilers killed
        (positive and finite; default 600); also the longest wait for another build of the
        same loop.

    Returns
    -------
    pathlib.Path
        The extension's file (already there and not rebuilt if the same loop was built).

    Raises
    ------
    TypeError, ValueError
        For arguments of the wrong type or value, with the parameter named (the run's
        arguments are checked as :func:`~hpdob.simulate` checks them).
    OSError
        If the folder cannot be written (a file where it should be, no permission): checked
        before the build, nothing written.
    LoopBuildError
        If ``numba.pycc`` (it needs numba, ``setuptools``: the ``aot`` extra, and a C compiler)
        or the compiler fails, the build times out or waits longer than ``timeout`` for
        another build of the loop, or an extension built with other compiler settings
        cannot be replaced (Windows: a process has it loaded); no extension is written.

    Examples
    --------
    Build the canonical loop once (a few seconds), then a later process's first
    ``simulate(**kw)`` of that structure runs it without importing numba:

    >>> from hpdob import paper
    >>> from hpdob.simulation import build_loop_extension
    >>> kw = paper.scenario()
    >>> kw["observer"] = paper.observer("HPDOb-100").design
    >>> path = build_loop_extension(**kw, compiler="zig")  # doctest: +SKIP
    """
    if not isinstance(loop, ServoLoop):
        raise ParameterTypeError(f"loop must be a ServoLoop, got {type(loop).__name__}")
    if folder is not None and not isinstance(folder, (str, os.PathLike)):
        raise ParameterTypeError(f"folder must be a path (str or os.PathLike), got {folder!r}")
    if folder is not None and not os.fspath(folder):  # Path("") is the working folder
        raise ParameterValueError(f"folder must name a folder, got {folder!r}")
    command = _compiler_commands(compiler, cxx_compiler)
    if isinstance(timeout, bool) or not isinstance(timeout, numbers.Real):
        raise ParameterTypeError(
            f"timeout must be a positive finite number of seconds, got {timeout!r} of type "
            f"{type(timeout).__name__}"
        )
    if not (math.isfinite(timeout) and timeout > 0):  # subprocess cannot wait for inf
        raise ParameterValueError(
            f"timeout must be a positive finite number of seconds, got {timeout!r}"
        )
    timeout = float(timeout)
    if duration is None:
        duration = 10 * loop.Ts
    seen: dict = {}
    _aot.CAPTURE.target = seen
    try:
        simulate(loop, reference=reference, disturbance=disturbance, duration=duration,
                 substeps=substeps, x0=x0)  # fmt: skip
    except _aot.Captured:
        pass
    finally:
        _aot.CAPTURE.target = None
    if not seen:
        raise ParameterValueError(
            f"loop's plant ({type(loop.plant).__name__}) is advanced from Python, not by the "
            "compiled sample loop: there is no loop to build"
        )
    if seen["types"] is None:  # the records hold only typed arrays and scalars
        raise LoopBuildError("the run's arguments have types the built loop cannot take")
    target = _aot.extension_folder(folder)
    name = _aot.extension_name(seen["source"], seen["types"])
    path = target / (name + _aot.SUFFIX)
    settings = _compiler_settings(command)
    if _built(path, settings):
        return path
    # before the build, not after it: a file where the folder should be, a read-only folder
    where = "folder" if folder is not None else f"folder (${_aot.FOLDER_VARIABLE} or the cache)"
    check_output(target, name=where)
    target.mkdir(parents=True, exist_ok=True)
    with _exclusive(target / f".{name}.lock", timeout):
        if _built(path, settings):  # built meanwhile by another process
            return path
        _build(target, path, name, seen, command, timeout, settings)
    return path


def _file_locks():
    """``(acquire, release, kind)`` for an exclusive lock on an open file: ``fcntl.flock``
    (POSIX) or ``msvcrt.locking`` of its first byte (Windows); None where neither exists.
    ``acquire(handle)`` is False while another process holds the lock."""
    try:
        import fcntl
    except ImportError:
        fcntl = None
    if fcntl is not None:

        def acquire(handle) -> bool:
            try:
                fcntl.flock(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                return False
            return True

        return acquire, lambda handle: fcntl.flock(handle.fileno(), fcntl.LOCK_UN), "flock"
    try:
        import msvcrt
    except ImportError:
        return None

    def acquire(handle) -> bool:  # the other platform's
        handle.seek(0)  # a region of the file: its first byte (beyond its end is allowed)
        try:
            msvcrt.locking(handle.fileno(), msvcrt.LK_NBLCK, 1)
        except OSError as error:  # EACCES, or EDEADLOCK: held by another process
            if error.errno in (errno.EACCES, errno.EDEADLOCK):
                return False
            raise
        return True

    def release(handle) -> None:
        handle.seek(0)
        msvcrt.locking(handle.fileno(), msvcrt.LK_UNLCK, 1)

    return acquire, release, "msvcrt"


def _same_file(handle, path: Path) -> bool:
    """Whether ``path`` still names the file open as ``handle`` (not removed or replaced)."""
    try:
        here, there = os.fstat(handle.fileno()), os.stat(path)
    except OSError:
        return False
    return (here.st_dev, here.st_ino) == (there.st_dev, there.st_ino)


@contextlib.contextmanager
def _exclusive(lock: Path, timeout: float):
    """Hold an exclusive lock on the file ``lock`` (:func:`_file_locks`): a second build of
    the same loop, in any process, waits and then finds the first's, not building it again.
    Two builds' files can differ (debug information naming the temporary folder, a compiler's
    time stamps), and two builds renaming their record and extension at once could leave one's
    record beside the other's extension, which no run would load. Waiting longer than
    ``timeout`` seconds raises :class:`LoopBuildError`.

    The lock file is created for the build and removed at its end (POSIX: while still held,
    so that a process waiting on it finds, once it holds it, that it is no longer the file
    of that name and locks the new one instead; Windows: after the release, and only if no
    other process has it open). A killed build leaves it; the next build takes and removes it.
    Without either lock (no ``fcntl``, no ``msvcrt``) builds do not wait for one another;
    each file is still renamed whole."""
    locks = _file_locks()
    if locks is None:
        yield
        return
    acquire, release, kind = locks
    deadline = time.monotonic() + timeout
    while True:
        handle = open(lock, "ab")  # noqa: SIM115  # closed below, on every path
        try:
            while not acquire(handle):
                if time.monotonic() > deadline:
                    raise LoopBuildError(
                        f"another build of this loop held {lock} for longer than "
                        f"timeout={timeout:g} s"
                    )
                time.sleep(0.05)
        except BaseException:
            handle.close()
            raise
        if _same_file(handle, lock):
            break
        handle.close()  # its holder removed it on its way out: lock the file now there
    try:
        yield
    finally:
        if kind == "msvcrt":  # an open file cannot be removed there
            with contextlib.suppress(OSError):
                release(handle)
            handle.close()
            with contextlib.suppress(OSError):
                lock.unlink()
        else:
            with contextlib.suppress(OSError):
                lock.unlink()
            handle.close()  # the lock is released when the file is closed


#: The environment variables with which setuptools changes the compiler commands and flags
#: (``customize_compiler``); ``CC`` and ``LDSHARED`` only without ``compiler=``, which
#: replaces them.
COMPILER_VARIABLES = ("CC", "CXX", "LDSHARED", "CPP", "CFLAGS", "CPPFLAGS", "LDFLAGS", "AR",
                      "ARFLAGS")  # fmt: skip


def _compiler_settings(command: tuple | None) -> str:
    """The compiler commands and the flags from the environment a build would use, as one
    line of JSON recorded beside the extension (:func:`_aot.recorded_build`)."""
    replaced = () if command is None else ("CC", "LDSHARED")
    variables = {k: os.environ.get(k) for k in COMPILER_VARIABLES if k not in replaced}
    return json.dumps({"commands": command, "environment": variables}, sort_keys=True)


def _built(path: Path, settings: str) -> bool:
    """Whether ``path`` holds the extension as a build with these compiler ``settings``
    writes it (intact, built with the same compiler and flags): a build with other settings
    is replaced, since its machine code (numba's C runtime, the module's wrapper) can differ.
    The settings are not in the name: a run cannot know the compiler, and any build of the
    name runs the loop's numba-generated code."""
    return path.is_file() and _aot.intact(path) and _aot.recorded_build(path) == settings


def _build(target: Path, path: Path, name: str, seen: dict, command, timeout: float,
           settings: str) -> None:  # fmt: skip
    """Build the extension ``path`` in a temporary folder in ``target`` and rename it there
    (with the loop's lock held: the temporary folders of its earlier builds are stale, left by
    a killed build, and removed first; after the build, :func:`_prune_objects`)."""
    for stale in target.glob(f".build-{name}-*"):
        shutil.rmtree(stale, ignore_errors=True)
    work = Path(tempfile.mkdtemp(prefix=f".build-{name}-", dir=target))  # same file system
    try:
        source_module = f"hpdob_aot_source_{name[len(_aot.PREFIX) :]}"
        (work / f"{source_module}.py").write_text(seen["source"], encoding="utf-8")
        spec = {"name": name, "file": name + _aot.SUFFIX, "source_module": source_module,
                "types": seen["types"]}  # fmt: skip
        (work / "spec.json").write_text(json.dumps(spec), encoding="utf-8")
        _compile(work, command, timeout)
        built = work / spec["file"]
        if not built.is_file():
            raise LoopBuildError(f"numba.pycc wrote no {spec['file']} in {work}")
        record = work / "record.sha256"  # in place before the extension: never one without
        record.write_text(f"{_aot.file_record(built)}\n{settings}\n", encoding="ascii")
        if path.exists():  # another build's (other compiler settings): gone before its record
            try:  # is replaced, so a run finds no extension rather than a mismatched one
                path.unlink()
            except OSError as error:  # Windows: a process has it loaded
                raise LoopBuildError(
                    f"the extension {path}, built with other compiler settings, could not be "
                    f"replaced ({error})"
                ) from error
        os.replace(record, _aot.record_path(path))
        os.replace(built, path)
        _aot.forget(path)  # a file this process could not load before: try the new one
    finally:
        shutil.rmtree(work, ignore_errors=True)
    _prune_objects(target)


def _objects_folder(target: Path) -> Path:
    """The folder of the object files kept for builds in ``target`` in this environment
    (numba's, numpy's, Python's versions: the headers numba's C sources include)."""
    tag = hashlib.sha256(_aot.environment().encode()).hexdigest()[:16]
    return target / ".objects" / tag


def _prune_objects(target: Path) -> None:
    """Remove the kept object files of other environments from ``target/.objects``: no build
    here can use them again (their key holds the environment). This environment's stay, one
    per source, compiler command and flags (~2 MB for numba's runtime with ``zig cc``), since
    reusing them saves about a third of every later build."""
    keep = _objects_folder(target)
    try:
        entries = list(keep.parent.iterdir())
    except OSError:
        return
    for entry in entries:
        if entry == keep:
            continue
        if entry.is_dir() and not entry.is_symlink():
            shutil.rmtree(entry, ignore_errors=True)
        else:
            with contextlib.suppress(OSError):
                entry.unlink()


#: The module the build process runs (``python -m``; a test runs another in its place).
_BUILDER = "hpdob.simulation._aot_compile"


def _stop(process: subprocess.Popen, *, group: bool) -> None:
    """Kill ``process`` and, with ``group``, every process of its process group (the C
    compilers it runs: they would go on writing into the folder being removed), and reap it.
    A temporary folder a dying compiler still wrote into is removed by the loop's next build
    (:func:`_build` removes its stale ``.build-<name>-*`` folders first)."""
    if group:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(process.pid, signal.SIGKILL)  # its group id is its pid (a new session)
    with contextlib.suppress(ProcessLookupError):
        process.kill()
    process.wait()


def _compile(work: Path, command: tuple | None, timeout: float) -> None:
    """Run ``_aot_compile`` on ``work`` in a process of its own (numba, its pending-deprecation
    warning and the compiler's environment stay there)."""
    import hpdob

    env = dict(os.environ)
    root = str(Path(hpdob.__file__).resolve().parent.parent)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (root, env.get("PYTHONPATH")) if p)
    if command is not None:  # setuptools links with CC too (LDSHARED follows it)
        script = Path(__file__).with_name("_aot_compile.py")
        env["CC"] = shlex.join([sys.executable, str(script), "--driver"])
        env["HPDOB_AOT_CC"], env["HPDOB_AOT_CXX"] = command
        env["HPDOB_AOT_OBJECTS"] = str(_objects_folder(work.parent))  # numba's C, once
        env["HPDOB_AOT_ENVIRONMENT"] = _aot.environment()
        env.pop("LDSHARED", None)
    # its own session (POSIX): a timeout or an interrupt kills the compilers it started too,
    # and a Ctrl-C at the terminal reaches this process only, which then stops the group
    posix = os.name == "posix"
    with subprocess.Popen(
        [sys.executable, "-m", _BUILDER, str(work)], stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True, env=env, start_new_session=posix,
    ) as process:  # fmt: skip
        try:
            stdout, stderr = process.communicate(timeout=timeout)
        except BaseException as error:  # the timeout, KeyboardInterrupt, anything
            _stop(process, group=posix)
            if isinstance(error, subprocess.TimeoutExpired):
                raise LoopBuildError(f"the build took longer than timeout={timeout:g} s") from error
            raise
    done = subprocess.CompletedProcess(process.args, process.returncode, stdout, stderr)
    if done.returncode != 0:
        lines = (done.stderr or done.stdout).strip().splitlines()
        errors = [line for line in lines if re.match(r"[\w.]+(Error|Exception): ", line)]
        reason = errors[-1] if errors else lines[-1] if lines else "no output"
        tail = "\n".join(lines[-60:])
        raise LoopBuildError(
            f"numba.pycc failed to build the loop (exit {done.returncode}): {reason}\n{tail}"
        )
