"""One-line progress with an estimate of the time left, on stderr (docs/reliability.md).

The library calls back with counts only (``progress(done, total)``); the clock lives here,
in the command layer, so no algorithm reads the wall clock.
"""

from __future__ import annotations

import sys
import time


def show_progress(flag) -> bool:
    """``--progress/--no-progress``, or (not given) whether stderr is a terminal."""
    return sys.stderr.isatty() if flag is None else bool(flag)


def format_seconds(seconds: float) -> str:
    """``"42 s"``, ``"3 min 05 s"``, ``"2 h 07 min"``: a time left, rounded to the second."""
    s = max(0, round(seconds))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


class ProgressLine:
    """``label done/total (p%), about T left`` rewritten in place; a newline when done.

    The time left is the elapsed time scaled by the share still to do (items of equal cost);
    ``clock`` is injectable so that tests check the lines, not the speed.
    """

    def __init__(self, label: str, stream=None, clock=time.monotonic, *, unit: str = "",
                 scale: float = 1.0):  # fmt: skip
        self.label = label
        self.unit, self.scale = unit, scale  # counts shown as done/scale, e.g. bytes as MiB
        self.stream = sys.stderr if stream is None else stream
        self.clock = clock
        self.start = clock()
        self.open = False  # a line written but not yet ended

    def __call__(self, done: int, total: int, *, detail: str = "") -> None:
        now = self.clock()
        if done == 0:
            self.start = now
        if self.scale == 1.0:
            counts = f"{done}/{total}"
        else:
            counts = f"{done / self.scale:.1f}/{total / self.scale:.1f}"
        line = f"{self.label}{' ' + detail if detail else ''} {counts}"
        if self.unit:
            line += f" {self.unit}"
        if total > 0:
            line += f" ({100 * done // total}%)"
        if 0 < done < total:
            left = (now - self.start) * (total - done) / done
            line += f", about {format_seconds(left)} left"
        self.open = done < total
        self.stream.write(f"\r\x1b[K{line}{'' if self.open else chr(10)}")
        self.stream.flush()

    def end(self) -> None:
        """End a line left open (the work failed or was interrupted), so that the next
        message starts on its own line."""
        if self.open:
            self.stream.write("\n")
            self.stream.flush()
            self.open = False


class StagedProgress:
    """Progress of work in named stages (``progress(stage, done, total)`` of the library):
    a :class:`ProgressLine` per stage, with its own clock, so each stage's time left is
    estimated from that stage alone. ``names`` maps a stage to its words on the line."""

    def __init__(self, prefix: str, names: dict, stream=None, clock=time.monotonic):
        self.prefix, self.names, self.stream, self.clock = prefix, names, stream, clock
        self.stage, self.line = None, None

    def __call__(self, stage: str, done: int, total: int) -> None:
        if stage != self.stage:  # a new stage: its own clock and line
            self.end()
            label = f"{self.prefix} {self.names.get(stage, stage)}"
            self.line = ProgressLine(label, self.stream, self.clock)
            self.stage = stage
        self.line(done, total)

    def end(self) -> None:
        """End the current stage's line if it is left open."""
        if self.line is not None:
            self.line.end()
