"""Atomic file writes: every file is written to a temporary name in its directory, then renamed.

One helper for every writer of hpdob:

- :func:`atomic_path` / :func:`write_text_atomic` / :func:`save_figure`: one file. A reader never
  sees a half-written file; a failed or interrupted write leaves the previous file (if any)
  untouched and no temporary file behind.
- :func:`staged_outputs`: the files of one command run (figures, traces, metrics). All are
  written to temporary names first; only when every one is complete are they renamed, the
  *marker* files (``metrics.json``, the summary JSON) last, after the old markers were removed.
  A run that fails or is interrupted therefore leaves the previous complete outputs, or files
  without their marker, never a marker beside missing or truncated files. Ctrl-C (and SIGTERM,
  SIGHUP) during the renames is deferred until they are done; a signal received before the
  commit (even one whose exception Python ignored) cancels it.
- :func:`check_output`: an output location, checked before the work that fills it.

Temporary names are ``.<name>.~hpdob<pid>-<random><suffix>``: hidden, recognisable, and
carrying the writer's process id. A temporary left by a process that is gone (killed by
SIGKILL, or a power loss) is removed the next time its target is written; a temporary is never
itself written through a temporary (no ``..a.csv.X.csv.Y.csv`` chains).
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import re
import sys
import tempfile
import threading
from pathlib import Path

from . import _interrupts
from ._interrupts import interrupts_deferred

__all__ = [
    "OutputSet",
    "atomic_path",
    "check_file_stem",
    "check_output",
    "interrupts_deferred",
    "save_figure",
    "staged_outputs",
    "write_text_atomic",
]

#: Prefix of temporary files: hidden, and recognisable as unfinished.
TEMPORARY_PREFIX = "."


def _check_target(path: Path) -> Path:
    """``path`` as a Path, refused (OSError naming it) if it is an existing directory."""
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(f"cannot write {str(path)!r}: it is an existing directory")
    return path


def _umask() -> int:
    """The process's file-creation mask (read without changing it, where the OS allows)."""
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    with _UMASK_LOCK:  # portable fallback: set and restore at once
        mask = os.umask(0o022)
        os.umask(mask)
    return mask


_UMASK_LOCK = threading.Lock()


#: The marker between a target's name and the random part of its temporary's name.
_TEMPORARY_TAG = "~hpdob"


def _temporary_pattern(name: str, suffix: str) -> re.Pattern:
    """Temporary names of target ``name``: this module's (group 1: the writer's process id) and
    those of hpdob before 2026-12 (``.<name>.<8 random characters><suffix>``, possibly nested)."""
    name, suffix = re.escape(name), re.escape(suffix)
    return re.compile(
        rf"\.{name}\.{_TEMPORARY_TAG}(\d+)-[\w]+{suffix}"
        rf"|\.+{name}(?:\.[a-z0-9_]{{8}}{suffix})+"
    )


def is_temporary(path) -> bool:
    """Whether ``path`` names a temporary file of this module (``.<name>.~hpdob<pid>-...``)."""
    return re.fullmatch(rf"\..+\.{_TEMPORARY_TAG}\d+-\w+(\.\w+)?", Path(path).name) is not None


def _process_gone(pid: int) -> bool:
    """True only if no process ``pid`` exists (POSIX; elsewhere: never sure, so False)."""
    if sys.platform == "win32" or pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except OSError:  # e.g. another user's process: it exists
        return False
    return False


def remove_stale_temporaries(path) -> list[Path]:
    """Delete the temporaries of target ``path`` whose writer process is gone; return them.

    A temporary of a live process (another run writing the same directory) is kept; so is
    anything that does not match the temporary names exactly.
    """
    path = Path(path)
    pattern = _temporary_pattern(path.name, path.suffix)
    removed = []
    try:
        candidates = list(path.parent.glob(f".*{glob_escape(path.name)}.*"))
    except OSError:
        return removed
    for candidate in candidates:
        match = pattern.fullmatch(candidate.name)
        if match is None or not candidate.is_file() or candidate.is_symlink():
            continue
        pid = match.group(1)
        if pid is not None and (int(pid) == os.getpid() or not _process_gone(int(pid))):
            continue
        with contextlib.suppress(OSError):
            candidate.unlink()
            removed.append(candidate)
    return removed


def glob_escape(text: str) -> str:
    """``text`` with glob's special characters escaped."""
    return re.sub(r"([*?[])", r"[\1]", text)


def _renamed(err: OSError, target, temporaries=()) -> OSError:
    """``err`` naming ``target`` instead of a hidden temporary (or nothing)."""
    names = {None, *(str(t) for t in temporaries)}
    if err.filename not in names and str(err.filename) not in names:
        return err
    renamed = type(err)(err.errno, err.strerror or str(err), str(target))
    renamed.__cause__ = None
    return renamed


def _temporary_beside(path: Path) -> Path:
    remove_stale_temporaries(path)
    try:
        handle, name = tempfile.mkstemp(
            prefix=f"{TEMPORARY_PREFIX}{path.name}.{_TEMPORARY_TAG}{os.getpid()}-",
            suffix=path.suffix,
            dir=path.parent,
        )
    except OSError as err:  # name the target, not the temporary (EROFS, EACCES, ENOSPC, ...)
        raise _renamed(err, path, [err.filename]) from None
    try:
        # mkstemp creates 0600; the renamed file must have the mode an open() would give it
        os.fchmod(handle, 0o666 & ~_umask())
    except (OSError, AttributeError):  # pragma: no cover - no fchmod (Windows)
        pass
    finally:
        os.close(handle)
    return Path(name)


class OutputLocationError(OSError):
    """An output location that cannot be written, found before any work (one-line message)."""

    def __str__(self) -> str:
        return self.strerror


def check_output(path, *, kind: str = "directory", name: str = "--out") -> Path:
    """``path`` as a Path if a ``kind`` (``"directory"`` or ``"file"``) can be written there.

    Checked before the work that fills it, so that a run is not lost at its end: an existing
    file where a directory is wanted (or the reverse), a file among the parent directories,
    and a directory that cannot be created or written (read-only, permissions; probed by
    creating and deleting a temporary file) raise :class:`OutputLocationError`, an OSError
    whose message names ``name`` and ``path``. Nothing is created.
    """
    path = Path(path)

    def refuse(code: int, why: str) -> OutputLocationError:
        return OutputLocationError(code, f"{name} {str(path)!r} cannot be written: {why}")

    if kind == "directory":
        if path.exists() and not path.is_dir():
            raise refuse(errno.ENOTDIR, "it is an existing file; it must be a directory")
    elif path.is_dir():
        raise refuse(errno.EISDIR, "it is an existing directory; it must be a file")
    directory = path if kind == "directory" else path.parent
    existing = directory
    while not existing.exists() and existing != existing.parent:
        if existing.is_symlink():
            raise refuse(errno.ENOENT, f"{str(existing)!r} is a broken symbolic link")
        existing = existing.parent
    if not existing.is_dir():
        raise refuse(errno.ENOTDIR, f"{str(existing)!r} is a file, not a directory")
    try:  # the real test of a read-only mount, permissions, ACLs
        handle, probe = tempfile.mkstemp(
            prefix=f"{TEMPORARY_PREFIX}hpdob-probe.{_TEMPORARY_TAG}{os.getpid()}-", dir=existing
        )
    except OSError as err:
        where = "" if existing == directory else f" (in {str(existing)!r})"
        raise refuse(err.errno or errno.EACCES, f"{err.strerror or err}{where}") from None
    os.close(handle)
    with contextlib.suppress(OSError):
        os.unlink(probe)
    return path


#: Characters a file stem made from a user's label may not contain (path separators, NUL and
#: the characters Windows forbids), besides control characters.
_FORBIDDEN_IN_STEM = set('/\\:*?"<>|')


def _invisible(c: str) -> bool:
    """Control and format characters: NUL, newlines, and the bidirectional controls (U+202E
    makes ``"x\u202egnp.exe"`` display as ``xexe.png``) and zero-width characters."""
    import unicodedata

    return ord(c) < 32 or unicodedata.category(c) in ("Cc", "Cf", "Cs", "Co", "Zl", "Zp")


def check_file_stem(stem, name: str = "label") -> str:
    """``stem`` if it can name a file inside the output directory, else a ParameterValueError.

    Refused: non-strings, the empty string, ``.`` and ``..``, a leading ``.`` (hidden files,
    and the temporary names of :func:`atomic_path`), path separators, NUL and other control
    characters, format characters (bidirectional overrides such as U+202E, zero-width
    spaces), ``:*?"<>|``, and more than 200 characters. So a scenario's ``label`` can never
    write outside ``--out``.
    """
    from ._validation import ParameterTypeError, ParameterValueError, _show

    if not isinstance(stem, str):
        raise ParameterTypeError(f"{name} must be a str, got {type(stem).__name__}")
    bad = sorted({c for c in stem if c in _FORBIDDEN_IN_STEM or _invisible(c)})
    if not stem or stem.startswith(".") or bad or len(stem) > 200 or stem != stem.strip():
        why = (
            f"it contains {', '.join(repr(c) for c in bad)}"
            if bad
            else "it is empty, starts with '.', has surrounding spaces or is over 200 characters"
        )
        raise ParameterValueError(
            f"{name} {_show(stem)} cannot name an output file: {why}; use letters, digits, "
            f"spaces, '-', '_' and '.' (not first)"
        )
    return stem


@contextlib.contextmanager
def atomic_path(path):
    """Context manager yielding a temporary path beside ``path``; moved onto ``path`` on success.

    The caller writes the temporary path (its name keeps the suffix of ``path``, so tools that
    infer the format from it, like matplotlib's ``savefig``, still do); on leaving the block
    without an exception it replaces ``path`` atomically, otherwise it is deleted. An existing
    directory at ``path`` is refused before anything is written.
    """
    path = _check_target(path)
    if is_temporary(path):  # already a staged temporary: renamed by its owner
        yield path
        return
    temporary = _temporary_beside(path)
    try:
        try:
            yield temporary
            _interrupts.check()  # a signal whose exception was lost: do not replace
            os.replace(temporary, path)
        except OSError as err:
            raise _renamed(err, path, [temporary]) from None
    except BaseException:
        with contextlib.suppress(OSError):
            temporary.unlink()
        raise


def write_text_atomic(path, text: str, *, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` atomically and return ``path`` as a Path."""
    path = Path(path)
    with atomic_path(path) as temporary:
        temporary.write_text(text, encoding=encoding)
    return path


def json_text(data) -> str:
    """``data`` as strict JSON text (NaN and infinity refused), indented, newline-terminated:
    the form of every JSON file hpdob writes."""
    return json.dumps(data, indent=2, allow_nan=False) + "\n"


def write_json_atomic(path, data) -> Path:
    """Write :func:`json_text` of ``data`` to ``path`` atomically; return ``path`` as a Path."""
    return write_text_atomic(path, json_text(data))


def save_figure(fig, path, **kwargs) -> Path:
    """``fig.savefig`` to ``path`` atomically (the format from the suffix of ``path``)."""
    path = Path(path)
    kwargs.setdefault("format", path.suffix.lstrip(".") or None)
    with atomic_path(path) as temporary:
        fig.savefig(temporary, **kwargs)
    return path


class OutputSet:
    """The files of one run, staged under temporary names and renamed together.

    Use :func:`staged_outputs`. :meth:`path` returns the temporary path to write for a file
    name relative to the output directory; :meth:`commit` renames them all, ``markers`` last,
    and deletes the files named in ``replaces`` that this run did not write (e.g. the figure
    of a previous run when this one has ``--no-plot``), so the directory holds one set.
    """

    def __init__(self, directory, *, markers=(), replaces=()):
        self.directory = Path(directory)
        self.markers = tuple(markers)
        self.replaces = tuple(replaces)
        self._staged: dict[Path, Path] = {}  # target -> temporary

    def path(self, name) -> Path:
        """A temporary path for ``directory/name`` (subdirectories are created)."""
        target = _check_target(self.directory / name)
        if target in self._staged:
            raise ValueError(f"{str(target)!r} is staged twice in one run")
        target.parent.mkdir(parents=True, exist_ok=True)
        temporary = _temporary_beside(target)
        self._staged[target] = temporary
        return temporary

    def write_text(self, name, text: str, *, encoding: str = "utf-8") -> None:
        """Stage ``text`` as ``directory/name``."""
        self.path(name).write_text(text, encoding=encoding)

    def write_json(self, name, data) -> None:
        """Stage :func:`json_text` of ``data`` as ``directory/name``."""
        self.write_text(name, json_text(data))

    def save_figure(self, name, fig, **kwargs) -> None:
        """Stage ``fig.savefig`` as ``directory/name`` (format from its suffix)."""
        kwargs.setdefault("format", Path(name).suffix.lstrip(".") or None)
        fig.savefig(self.path(name), **kwargs)

    def plot(self, name, draw, *, dpi: int = 150) -> None:
        """Stage the figure ``draw()`` returns as ``directory/name``, drawn off-screen (Agg)
        and closed even if saving fails."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig = draw()
        try:
            self.save_figure(name, fig, dpi=dpi)
        finally:
            plt.close(fig)

    @property
    def targets(self) -> list[Path]:
        """The final paths, in commit order."""
        markers = [self.directory / name for name in self.markers]
        ordered = [t for t in self._staged if t not in markers]
        return ordered + [t for t in markers if t in self._staged]

    def commit(self) -> list[Path]:
        """Rename every staged file onto its target, the markers last; return the targets.

        Old markers are removed first, then the files of ``replaces`` this run did not write,
        so that an error between two renames leaves files without a marker (not
        complete-looking), never a marker beside a mix of old and new files. Signals are
        deferred until the renames are done.
        """
        order = self.targets
        obsolete = [self.directory / name for name in self.replaces]
        obsolete = [p for p in obsolete if p not in self._staged]
        with interrupts_deferred():
            try:
                _interrupts.check()  # a signal whose exception was lost cancels the commit
                for target in order:  # re-check: a directory may have appeared meanwhile
                    _check_target(target)
                for name in self.markers:
                    with contextlib.suppress(FileNotFoundError):
                        (self.directory / name).unlink()
                for stale in obsolete:  # files of the previous set this run does not write
                    if stale.is_file() or stale.is_symlink():
                        stale.unlink()
                for target in order:
                    os.replace(self._staged[target], target)
                    del self._staged[target]  # only now: a failed rename is cleaned up
            finally:
                self.discard()
        return order

    def discard(self) -> None:
        """Delete every staged temporary file that was not committed."""
        for temporary in self._staged.values():
            with contextlib.suppress(OSError):
                temporary.unlink()
        self._staged.clear()


@contextlib.contextmanager
def staged_outputs(directory, *, markers=(), replaces=()):
    """Context manager yielding an :class:`OutputSet` committed when the block succeeds.

    On an exception (including KeyboardInterrupt) every staged file is deleted and the
    previous outputs stay as they were. An OSError while writing a staged file names its
    target, not the hidden temporary. ``replaces``: names of files of the set this run may
    not write; the commit deletes those it did not write.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> with tempfile.TemporaryDirectory() as out:
    ...     with staged_outputs(out, markers=["metrics.json"]) as files:
    ...         files.write_text("traces/a.csv", "t\\n0\\n")
    ...         files.write_text("metrics.json", "{}\\n")
    ...     sorted(p.name for p in pathlib.Path(out).rglob("*"))
    ['a.csv', 'metrics.json', 'traces']
    """
    outputs = OutputSet(directory, markers=markers, replaces=replaces)
    try:
        try:
            yield outputs
        except OSError as err:
            temporaries = {str(t): target for target, t in outputs._staged.items()}
            target = temporaries.get(str(err.filename), outputs.directory)
            raise _renamed(err, target, temporaries) from None
    except BaseException:
        outputs.discard()
        raise
    outputs.commit()
