"""Memory of every command that reads a measured log (issue 25: "no command holds more than
two copies of a log"), measured by tracemalloc, which traces numpy's allocations.

Counting rule (docs/performance.md, "Memory of the commands that read a log"): one *copy* is
the log's columns that the command reads, as float64: samples x columns x 8 bytes (with
several logs, all of them). Everything the command allocates counts by its bytes, the log as
read included: a derived array of the log's length is 1/columns of a copy, a regressor of k
columns decimated by d is k/(columns d) of one. The figure is the *slope*: the tracemalloc
peak of the command on a log of N1 samples minus its peak on N0 samples, over the difference
of their copies, so that what does not grow with the log (the modules a warm-up imported,
parsers, buffers of a fixed size) cancels. The block-wise filters of identify
(``hpdob.identification._lean``) run with small blocks here so that their buffers are fixed
below N0 (the arithmetic does not depend on the block size: tests/identification/test_lean.py
checks it bit for bit at several sizes); buffers that are not yet at their fixed size at N0
(the CSV writer's chunks) only make the slope larger: the bound is conservative.

Every log here is SYNTHETIC (a PD loop around a rigid axis with Coulomb friction, seeded).
"""

from __future__ import annotations

import contextlib
import functools
import gc
import io
import tracemalloc

import numpy as np
import pytest

from hpdob.cli import main
from hpdob.identification import FeedbackLoop, simulate_loop

pa = pytest.importorskip("pyarrow")
pq = pytest.importorskip("pyarrow.parquet")

#: The logs' lengths: the estimate's (its figure's envelopes reach their fixed size at 20 000
#: samples) and identify's (slower: its iterations and diagnostics run over the whole log;
#: from 48 000 samples, as shorter logs' fixed buffers, still a good part of their peak,
#: make the slope low: docs/performance.md, "The IDIM-LS path cut").
N0, N1 = 20_000, 100_000
N0_IDENTIFY, N1_IDENTIFY = 48_000, 96_000
#: The bound: two copies, and a small allowance for the decimated regression and its
#: instruments (identify: 4 columns / decimation of each, 0.1 or less at the defaults).
TWO_COPIES = 2.0 + 0.1
TS, J, B, COULOMB = 1e-3, 1.2e-3, 2e-3, 0.03


@pytest.fixture(autouse=True)
def small_blocks(monkeypatch):
    """Blocks well below N0: identify's filters, the estimate's blocks of a log, a Parquet
    file's batches and the CSV writer's chunks (the same numbers at any size). 4096 samples
    (8192 for the readers): 1024 measured a slope up to 0.5 higher (more blocks: more small
    per-block arrays alive) at four times the traced time (tracemalloc hooks every
    allocation): docs/performance.md, "The memory tests' blocks"."""
    from hpdob import _csv_floats
    from hpdob.identification import _lean, _log_file, _readers

    monkeypatch.setattr(_lean, "BLOCK", 4096)
    monkeypatch.setattr(_log_file, "BLOCK", 8192)
    monkeypatch.setattr(_readers, "PARQUET_BLOCK", 8192)
    monkeypatch.setattr(_csv_floats, "CHUNK", 4096)


@functools.cache  # the same logs in every test: made once (read-only arrays)
def _columns(n: int, seed: int = 0, way: float = 1.0) -> dict:
    """A synthetic closed-loop log: a PD at 5 Hz tracking three sines, an encoder of 4096
    counts, 1 % noise on the logged input."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * TS
    r = way * (0.5 * np.sin(2 * np.pi * 0.3 * t) + 0.2 * np.sin(2 * np.pi * 1.7 * t + 1.0)
               + 0.05 * np.sin(2 * np.pi * 4.1 * t))  # fmt: skip
    w = 2 * np.pi * 5.0
    theta, u = simulate_loop(FeedbackLoop(r, kp=J * w * w, kd=J * 2 * w), (J, B, COULOMB, 0.0),
                             Ts=TS)  # fmt: skip
    q = 2 * np.pi / 4096
    columns = {"t": t, "q": np.round(theta / q) * q,
               "u": u + 0.01 * np.std(u) * rng.standard_normal(n), "r": r}  # fmt: skip
    for column in columns.values():
        column.flags.writeable = False
    return columns


def _write(path, columns: dict) -> None:
    if path.suffix == ".parquet":
        pq.write_table(pa.table(columns), path)
    elif path.suffix == ".mat":
        import scipy.io

        scipy.io.savemat(path, columns)
    else:
        names = list(columns)
        np.savetxt(path, np.column_stack([columns[k] for k in names]), fmt="%.17g",
                   delimiter=",", header=",".join(names), comments="")  # fmt: skip


def _peak(args: list, out, *, traced: bool = True) -> int:
    """tracemalloc's peak [bytes] while ``hpdob ARGS --out OUT --no-plot`` runs (0 if not
    ``traced``: a warm-up, several times faster untraced)."""
    gc.collect()
    if traced:
        tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        errors = io.StringIO()
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(errors):
            code = main([*args, "--out", str(out), "--no-plot"])
        peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
    # 1: an identification warning, as the command's exit code
    assert code in (0, 1), (args, errors.getvalue())
    return peak


def copies(
    tmp_path, command: list, files: dict, read: int, *, n0=N0_IDENTIFY, n1=N1_IDENTIFY
) -> float:
    """The slope of the command's peak against its log, in copies (module docstring).

    ``files``: name -> (suffix, seed, way) of the logs the command's ``command`` words name
    as ``{name}``; ``read``: the columns the command reads from each log."""
    peaks = []
    for n in (10_000, n0, n1):  # the first run is a warm-up: imports and compilations
        paths = {}
        for name, (suffix, seed, way) in files.items():
            paths[name] = tmp_path / f"{name}-{n}{suffix}"
            if not paths[name].exists():
                columns = _columns(n, seed, way)
                if name.startswith("runs"):  # one file, two runs: a run column
                    half = n // 2
                    columns = {"run": np.repeat([1.0, 2.0], [half, n - half]),
                               **{k: np.concatenate([v[:half], v[:n - half]])
                                  for k, v in columns.items()}}  # fmt: skip
                _write(paths[name], columns)
        args = [word.format(**paths) for word in command]
        peaks.append(_peak(args, tmp_path / f"out-{n}", traced=n != 10_000))
    copy0, copy1 = (n * read * 8 * len(files) for n in (n0, n1))
    slope = (peaks[2] - peaks[1]) / (copy1 - copy0)
    print(f"{' '.join(command[:1] + command[2:])}: {slope:.3f} copies")  # with pytest -s
    return slope


ESTIMATE = ["estimate", "{log}", "--time", "t", "--position", "q", "--input", "u",
            "--J-n", "1.2e-3"]  # fmt: skip
IDENTIFY = ["identify", "{log}", "--time", "t", "--position", "q", "--input", "u"]


@pytest.mark.parametrize("suffix", [".parquet", ".csv"])
def test_estimate_holds_at_most_two_copies(tmp_path, suffix):
    """A Parquet log is read block by block (none held); a CSV log is read whole (one) and
    the estimate (a third) kept."""
    measured = copies(tmp_path, ESTIMATE, {"log": (suffix, 0, 1.0)}, 3, n0=N0, n1=N1)
    assert measured <= TWO_COPIES


def test_identify_least_squares_holds_at_most_two_copies(tmp_path):
    """--method idim-ls: the benchmark's filters and rules (decimation 10 at 1 kHz)."""
    command = [*IDENTIFY, "--method", "idim-ls"]
    assert copies(tmp_path, command, {"log": (".parquet", 0, 1.0)}, 3) <= TWO_COPIES


def test_identify_auto_holds_at_most_two_copies(tmp_path):
    """The default: filters read from the log, instruments from the input-driven model, the
    simulation fit and the sensitivity check."""
    assert copies(tmp_path, IDENTIFY, {"log": (".parquet", 0, 1.0)}, 3) <= TWO_COPIES


@pytest.mark.parametrize("suffix", [".mat", ".csv"])
def test_identify_of_a_log_read_whole_holds_at_most_two_copies(tmp_path, suffix):
    """A MATLAB or CSV log (the default method), read whole: its columns are the log's, not
    copied again; of a MATLAB file only the variables asked for are loaded (the file holds
    the reference as well; three columns read)."""
    assert copies(tmp_path, IDENTIFY, {"log": (suffix, 0, 1.0)}, 3) <= TWO_COPIES
