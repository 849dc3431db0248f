"""Atomic file writes: every file is written to a temporary name in its directory, then renamed.

One helper for every writer of hpdob:

- :func:`atomic_path` / :func:`write_text_atomic` / :func:`save_figure`: one file. A reader never
  sees a half-written file; a failed or interrupted write leaves the previous file (if any)
  untouched and no temporary file behind.
- :func:`staged_outputs`: the files of one command run (figures, traces, metrics). All are
  written to temporary names first; only when every one is complete are they renamed, the
  *marker* files (``metrics.json``, the summary JSON) last, after the old markers were removed.
  A run that fails or is interrupted therefore leaves the previous complete outputs, or files
  without their marker, never a marker beside missing or truncated files. Ctrl-C during the
  renames is deferred until they are done.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import tempfile
import threading
from pathlib import Path

__all__ = [
    "OutputSet",
    "atomic_path",
    "check_file_stem",
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


def _temporary_beside(path: Path) -> Path:
    handle, name = tempfile.mkstemp(
        prefix=f"{TEMPORARY_PREFIX}{path.name}.", suffix=path.suffix, dir=path.parent
    )
    try:
        # mkstemp creates 0600; the renamed file must have the mode an open() would give it
        os.fchmod(handle, 0o666 & ~_umask())
    except (OSError, AttributeError):  # pragma: no cover - no fchmod (Windows)
        pass
    finally:
        os.close(handle)
    return Path(name)


#: Characters a file stem made from a user's label may not contain (path separators, NUL and
#: the characters Windows forbids), besides control characters.
_FORBIDDEN_IN_STEM = set('/\\:*?"<>|')


def check_file_stem(stem, name: str = "label") -> str:
    """``stem`` if it can name a file inside the output directory, else a ParameterValueError.

    Refused: non-strings, the empty string, ``.`` and ``..``, a leading ``.`` (hidden files,
    and the temporary names of :func:`atomic_path`), path separators, NUL and other control
    characters, ``:*?"<>|``, and more than 200 characters. So a scenario's ``label`` can never
    write outside ``--out``.
    """
    from ._validation import ParameterTypeError, ParameterValueError, _show

    if not isinstance(stem, str):
        raise ParameterTypeError(f"{name} must be a str, got {type(stem).__name__}")
    bad = sorted({c for c in stem if c in _FORBIDDEN_IN_STEM or ord(c) < 32 or ord(c) == 127})
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
    temporary = _temporary_beside(path)
    try:
        yield temporary
        os.replace(temporary, path)
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


@contextlib.contextmanager
def interrupts_deferred():
    """Hold back SIGINT (Ctrl-C) inside the block and deliver it when the block ends.

    Only the main thread can install signal handlers; elsewhere the block runs as is.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: received.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if received:
            signal.raise_signal(signal.SIGINT)  # now handled as it would have been


class OutputSet:
    """The files of one run, staged under temporary names and renamed together.

    Use :func:`staged_outputs`. :meth:`path` returns the temporary path to write for a file
    name relative to the output directory; :meth:`commit` renames them all, ``markers`` last.
    """

    def __init__(self, directory, *, markers=()):
        self.directory = Path(directory)
        self.markers = tuple(markers)
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

        Old markers are removed first, so that an error between two renames leaves files
        without a marker (not complete-looking), never a marker beside a mix of old and new
        files. Ctrl-C is deferred until the renames are done.
        """
        order = self.targets
        with interrupts_deferred():
            try:
                for target in order:  # re-check: a directory may have appeared meanwhile
                    _check_target(target)
                for name in self.markers:
                    with contextlib.suppress(FileNotFoundError):
                        (self.directory / name).unlink()
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
def staged_outputs(directory, *, markers=()):
    """Context manager yielding an :class:`OutputSet` committed when the block succeeds.

    On an exception (including KeyboardInterrupt) every staged file is deleted and the
    previous outputs stay as they were.

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
    outputs = OutputSet(directory, markers=markers)
    try:
        yield outputs
    except BaseException:
        outputs.discard()
        raise
    outputs.commit()
