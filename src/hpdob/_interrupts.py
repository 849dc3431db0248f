"""Signals of the ``hpdob`` command: Ctrl-C (SIGINT), SIGTERM and SIGHUP end a run the same way.

Standard library only, so that the command installs its handlers before it imports numpy and
the rest (an interrupt during start-up then exits 130 with one line, not a traceback).

- :func:`handling_signals` (used by :func:`hpdob.cli.main`) installs a handler that records the
  signal and raises :class:`Interrupted` (a ``KeyboardInterrupt``), so every ``finally`` and
  staged output set cleans up as for Ctrl-C. The record matters: Python *ignores* an exception
  raised inside a ``__del__`` method or a weakref callback (it prints ``Exception ignored in
  ...``), so a signal that arrives there would be lost; :func:`check` re-raises a recorded
  signal, and is called in long loops, before every commit of outputs and after the command.
- :func:`interrupts_deferred` holds the signals back during the renames of a commit.
- :func:`checkpoint` is a test hook: with ``HPDOB_TEST_PAUSE=<name>:<file>`` in the
  environment the process, on reaching checkpoint ``<name>``, creates ``<file>`` and waits
  (up to 60 s) for a signal. A test waits for the file, then signals the process, so the signal
  arrives at a known point whatever the machine's load (no sleeps).
"""

from __future__ import annotations

import atexit
import contextlib
import os
import signal
import sys
import threading
import time

__all__ = [
    "EXIT_CODES",
    "Interrupted",
    "acknowledge",
    "check",
    "checkpoint",
    "handling_signals",
    "interruptible",
    "interrupts_deferred",
    "received",
]

#: The signals handled like Ctrl-C (those the platform has).
SIGNALS = tuple(
    getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name)
)

#: Exit code per signal: 128 + its number (SIGINT 130, SIGHUP 129, SIGTERM 143), as a shell
#: reports a process killed by it.
EXIT_CODES = {int(s): 128 + int(s) for s in SIGNALS}


class Interrupted(KeyboardInterrupt):
    """Raised by the handler of :func:`handling_signals`; ``signum`` is the signal.

    ``detail`` (re-raised by a command that kept finished work) is appended to the one line
    ``hpdob <command>: interrupted`` the command line prints, e.g. where that work went.
    """

    def __init__(self, signum: int = signal.SIGINT, detail: str = ""):
        super().__init__(signum)
        self.signum = int(signum)
        self.detail = detail

    @property
    def name(self) -> str:
        """The signal's name, e.g. ``"SIGTERM"``."""
        return signal.Signals(self.signum).name


#: Signals received (and not yet cleared) by the handler of :func:`handling_signals`.
_received: list[int] = []


def received() -> int | None:
    """The first signal received under :func:`handling_signals` since it started, or None."""
    return _received[0] if _received else None


def check() -> None:
    """Raise :class:`Interrupted` if a signal was received (even if its exception was lost)."""
    if _received:
        raise Interrupted(_received[0])


def acknowledge() -> None:
    """Forget the signals received so far: the caller has handled them and writes what it
    keeps (e.g. an interrupted sweep's finished rows), which :func:`check` would otherwise
    refuse to commit. A signal received after this call interrupts that writing as usual."""
    _received.clear()


def _handler(signum, frame):
    _received.append(int(signum))
    raise Interrupted(signum)


@contextlib.contextmanager
def _handled_by(handler, *, keep_ignored: bool):
    """``handler`` for :data:`SIGNALS` inside the block (not for a signal ignored with
    ``SIG_IGN`` if ``keep_ignored``), the previous handlers restored on leaving: every one of
    them, also when a signal comes while they change (each old handler is recorded before its
    replacement goes in; a ``KeyboardInterrupt`` during the restoring is raised once all are
    back)."""
    previous = {}
    try:
        for signum in SIGNALS:
            old = signal.getsignal(signum)
            if keep_ignored and old is signal.SIG_IGN:
                continue
            previous[signum] = old
            signal.signal(signum, handler)
        yield
    finally:
        pending = None
        for signum, old in previous.items():
            while True:
                try:
                    signal.signal(signum, old)
                    break
                except KeyboardInterrupt as err:
                    pending = err
        if pending is not None:
            raise pending


@contextlib.contextmanager
def handling_signals():
    """Handle SIGINT, SIGTERM and SIGHUP by raising :class:`Interrupted` inside the block.

    The previous handlers are restored on leaving (so an in-process caller, e.g. a test calling
    :func:`hpdob.cli.main`, is unaffected). Only the main thread can install handlers; elsewhere
    the block runs as is. A signal the parent process ignores (``SIG_IGN``, e.g. SIGHUP under
    ``nohup``) stays ignored, as Python itself leaves an ignored SIGINT.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _received.clear()
    try:
        with _handled_by(_handler, keep_ignored=True):
            yield
    finally:
        _received.clear()


@contextlib.contextmanager
def interrupts_deferred():
    """Hold back SIGINT, SIGTERM and SIGHUP inside the block; deliver them when it ends.

    Only the main thread can install signal handlers; elsewhere the block runs as is.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held = []
    try:
        with _handled_by(lambda s, frame: held.append(s), keep_ignored=False):
            yield
    finally:
        if held:
            signal.raise_signal(held[0])  # now handled as it would have been


def interruptible(function, /, *args, **kwargs):
    """``function(*args, **kwargs)``, with the main thread free to handle a signal meanwhile.

    Python runs a signal's handler only between bytecodes of the main thread, so one long call
    into LAPACK (``eigvals`` of a 1000-state loop: 0.3 s idle, tens of seconds on a loaded
    machine) would hold back Ctrl-C for as long. In the main thread the call runs in a daemon
    thread (abandoned, not waited for, if the signal ends the process) while the main thread
    waits interruptibly; elsewhere it runs directly. Use it for calls that may take seconds.
    """
    if threading.current_thread() is not threading.main_thread():
        return function(*args, **kwargs)
    outcome = {}
    # Our own flag, not Thread.is_alive(): a join() interrupted by a signal marks the thread
    # stopped although it still runs (CPython's bpo-45274 handling).
    done = threading.Event()

    def run():
        try:
            outcome["value"] = function(*args, **kwargs)
        except BaseException as err:  # handed to the caller below
            outcome["error"] = err
        finally:
            done.set()

    threading.Thread(target=run, name="hpdob-interruptible", daemon=True).start()
    try:
        while not done.wait(0.1):  # a signal's handler runs here (and raises) within 0.1 s
            check()
    except BaseException as err:
        if isinstance(err, KeyboardInterrupt):
            _abandon(done, EXIT_CODES.get(getattr(err, "signum", signal.SIGINT), 130))
        raise
    if "error" in outcome:
        raise outcome["error"]
    return outcome["value"]


#: Workers of :func:`interruptible` left running by a signal (their "done" events), and the
#: exit code the signal implies.
_abandoned: list[threading.Event] = []
_abandoned_code = [130]


def _abandon(worker: threading.Event, code: int) -> None:
    """Remember ``worker``: at exit, a process whose LAPACK call still runs must not wait for
    it (the BLAS library joins its threads when the process exits: minutes)."""
    if not _abandoned:
        atexit.register(_exit_now)
    _abandoned.append(worker)
    _abandoned_code[0] = code


def _exit_now() -> None:
    """At exit: if an abandoned worker still computes, flush and end the process at once (the
    remaining exit handlers are skipped; hpdob's outputs were already cleaned up)."""
    if not all(done.is_set() for done in _abandoned):
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(Exception):
                stream.flush()
        os._exit(_abandoned_code[0])


def checkpoint(name: str) -> None:
    """A point where a long run notices a signal (:func:`check`), and a test hook.

    The hook pauses at ``name`` for a signal if ``HPDOB_TEST_PAUSE=<name>:<file>`` asks for
    it (unset in normal use: then this is one dictionary look-up). The file is created when
    the checkpoint is first reached (a process pauses at a checkpoint once); the process then
    waits up to 60 s for the signal the test sends, and goes on if none comes or as soon as
    the test removes the file (so that a test can act elsewhere, e.g. stop a dask scheduler,
    while the command waits at a known point).
    """
    check()
    spec = os.environ.get("HPDOB_TEST_PAUSE")
    if not spec:
        return
    wanted, _, path = spec.partition(":")
    if wanted != name or not path or name in _paused:
        return
    _paused.add(name)
    partial = f"{path}.{os.getpid()}.partial"  # renamed: the test may read it once it exists
    with open(partial, "w", encoding="utf-8") as flag:
        flag.write(f"{os.getpid()} {name}\n")
    os.replace(partial, path)
    deadline = time.monotonic() + 60.0
    while time.monotonic() < deadline:
        time.sleep(0.01)  # a signal's handler runs here and raises
        check()
        if not os.path.exists(path):  # the test removed the file: go on
            return


#: Checkpoints this process has paused at: it pauses at each at most once.
_paused: set[str] = set()
