"""How long a signal at start-up meets Python's default handler (a traceback), not hpdob's.

Issue 27 item 5 (docs/reliability.md, section 3). Two measurements, under whatever load the
machine has (printed):

1. the time from spawning ``python -m hpdob design`` to the entry point's handler being in
   place (the ``entry`` checkpoint, right after it, creates a file: its mtime, an upper
   bound), against the same spawn of ``python -c pass`` (the interpreter's own start-up,
   which no package can shorten), both as medians over ``--runs``;
2. SIGINT sent after a range of delays: how many runs ended with hpdob's one line, how many
   with a traceback or a ``Fatal Python error`` (Python's own start-up).

Run: ``PYTHONPATH=src python benchmarks/bench_startup_window.py [--runs 15]`` (about 20 s).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def _spawn_to_entry(env: dict, folder: Path) -> float:
    flag = folder / "entry.flag"
    flag.unlink(missing_ok=True)
    env = {**env, "HPDOB_TEST_PAUSE": f"entry:{flag}"}
    start = time.time()
    process = subprocess.Popen([sys.executable, "-m", "hpdob", "design"], env=env,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
    while not flag.exists():
        time.sleep(0.001)
    reached = flag.stat().st_mtime
    process.send_signal(signal.SIGINT)
    process.wait(timeout=60)
    return reached - start


def _bare_start(env: dict) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-c", "pass"], env=env, check=True)
    return time.perf_counter() - start


def _outcome(env: dict, delay: float) -> str:
    process = subprocess.Popen([sys.executable, "-m", "hpdob", "design"], env=env,
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                               text=True)  # fmt: skip
    time.sleep(delay)
    with contextlib.suppress(ProcessLookupError):
        process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=60)
    if "Traceback" in err:
        return "traceback"
    if "Fatal Python error" in err:
        return "fatal"
    if process.returncode == 0:
        return "finished"
    if process.returncode == -signal.SIGINT and not err:
        return "killed silently (before Python's handler)"
    if process.returncode == 130 and err.endswith("interrupted\n") and err.count("\n") == 1:
        return "hpdob's one line"
    return f"other (exit {process.returncode})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=15)
    args = parser.parse_args()
    env = dict(os.environ)
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    with tempfile.TemporaryDirectory() as folder:
        entry = [_spawn_to_entry(env, Path(folder)) for _ in range(args.runs)]
    bare = [_bare_start(env) for _ in range(args.runs)]
    print(f"spawn -> hpdob's handler in place: median {1e3 * statistics.median(entry):.0f} ms, "
          f"max {1e3 * max(entry):.0f} ms ({args.runs} runs)")  # fmt: skip
    print(f"python -c pass, whole run:          median {1e3 * statistics.median(bare):.0f} ms, "
          f"max {1e3 * max(bare):.0f} ms")  # fmt: skip
    ratio = statistics.median(entry) / statistics.median(bare)
    print(f"ratio (window / bare interpreter): {ratio:.2f}")
    for delay in (0.005, 0.01, 0.02, 0.03, 0.05, 0.08, 0.12, 0.15, 0.3):
        outcomes = [_outcome(env, delay) for _ in range(max(1, args.runs // 5))]
        counts = {k: outcomes.count(k) for k in sorted(set(outcomes))}
        print(f"SIGINT after {1e3 * delay:4.0f} ms: {counts}")


if __name__ == "__main__":
    main()
