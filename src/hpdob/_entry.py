"""The ``hpdob`` console script and ``python -m hpdob``: signals are handled from the start.

:func:`main` installs, as its first statement and before anything else is imported, a
handler for SIGINT, SIGTERM and SIGHUP that prints ``hpdob: interrupted`` and exits with
128 + the signal's number (130 for Ctrl-C) by raising ``SystemExit``, which Python never
reports with a traceback. It covers the import of the command modules, numpy and the rest;
:func:`hpdob.cli.main` then installs the command's own handlers
(``hpdob._interrupts.handling_signals``: outputs cleaned up, ``hpdob <command>:
interrupted``). Once the command has returned, a signal ends the process at once with the
same code, stdout flushed (a ``SystemExit`` raised while Python exits would be printed as
"Exception ignored in atexit callback"). An interrupted command (exit 128 + signal) ends
the same way once the exit handlers have run, without the interpreter's finalisation.

Importing the module changes nothing (the doctests import every module); only the entry
points call :func:`main`. What runs before it: the interpreter's own start-up and ``site``
(with the environment's ``.pth`` files), ``runpy`` for ``python -m`` or the wrapper script
pip generates (it imports ``re``), ``hpdob/__init__`` (a few assignments: the package
imports its subpackages lazily) and this module (which imports no ``signal``/``enum``: it
uses the C module ``_signal``). A Ctrl-C there is Python's own: a ``KeyboardInterrupt``
traceback; the window is measured by ``benchmarks/bench_startup_window.py``
(docs/reliability.md, section 3).
"""

# The C module under ``signal``: ``signal`` itself imports ``enum`` (1-10 ms before the
# handler is in place, under load); the handlers and SIG_IGN are the same objects.
import _signal
import sys

__all__ = ["main"]

#: signal number -> name, of the signals handled here
_SIGNALS = {getattr(_signal, n): n for n in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(_signal, n)}


def _line(signum: int) -> str:
    name = _SIGNALS.get(signum, str(signum))
    return "hpdob: interrupted\n" if name == "SIGINT" else f"hpdob: interrupted ({name})\n"


#: Signals the early handler received (its SystemExit may be lost in a ``__del__``).
_received: list[int] = []


def _early(signum, frame):
    """Until the command's handlers are in place: one line, exit 128 + signum."""
    if not _received:
        sys.stderr.write(_line(signum))
    _received.append(signum)
    raise SystemExit(128 + signum)


def _unraisable(info, previous=sys.unraisablehook):
    """Python prints an exception raised in a ``__del__`` or a weakref callback ("Exception
    ignored in ...") and goes on; for a signal's exception that is a traceback after the one
    line. The signal was recorded (here or in ``hpdob._interrupts``) and still ends the run."""
    if isinstance(info.exc_value, (KeyboardInterrupt, SystemExit)):
        return
    previous(info)


def _late(signum, frame):
    """After the command: end at once (its outputs are complete, or were cleaned up)."""
    import contextlib
    import os

    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):  # e.g. a closed pipe: nothing more to say
            stream.flush()
    with contextlib.suppress(OSError):
        os.write(2, _line(signum).encode())
    os._exit(128 + signum)


def _install(handler) -> None:
    for signum in _SIGNALS:
        if _signal.getsignal(signum) != _signal.SIG_IGN:  # e.g. SIGHUP under nohup
            _signal.signal(signum, handler)


def main() -> int:
    """Run the ``hpdob`` command (:func:`hpdob.cli.main`) and return its exit code."""
    _install(_early)  # first, before the imports below (numpy and the rest follow)
    sys.unraisablehook = _unraisable
    try:
        from ._interrupts import checkpoint

        checkpoint("entry")  # a test hook (hpdob._interrupts); a no-op otherwise
        from .cli import main as run
    except Exception:
        if not _received:
            raise
        # else the signal's SystemExit, turned into another error by the C code it hit
    if _received:  # (or lost in a __del__ during the imports)
        raise SystemExit(128 + _received[0])
    code = run()
    _install(_late)
    if code in {128 + signum for signum in _SIGNALS}:
        _end_interrupted(code)
    return code


def _end_interrupted(code: int) -> None:
    """An interrupted command (its outputs cleaned up, its line printed): the exit handlers,
    then end the process without the interpreter's finalisation, which tears down numpy,
    numba and matplotlib for 0.5-1 s after the line (measured in ``hpdob reproduce``)."""
    import atexit
    import contextlib
    import os

    # atexit's own runner (CPython): e.g. coverage of subprocesses saves its data there.
    with contextlib.suppress(Exception):
        getattr(atexit, "_run_exitfuncs", lambda: None)()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):  # e.g. a closed pipe: nothing more to say
            stream.flush()
    os._exit(code)
