"""Memory of ``hpdob identify --emps`` (issue 25: "no command holds more than two copies of a
log"): one file of fixed length, so no slope (``test_cli_memory.py``) but the absolute
tracemalloc peak of a second call in the process, everything it allocates counted (fixed
buffers, the parser, the result), over the EMPS log's 24 841 samples x 4 columns x 8 bytes,
with the library's own blocks: ``benchmarks/bench_identify_ab.py --memory``'s measure
(docs/performance.md, "`--emps` in two copies"). The log is the measured EMPS run hpdob
ships."""

from __future__ import annotations

import contextlib
import gc
import io
import tracemalloc

import pytest

from hpdob.cli import main

#: One copy of the EMPS log [bytes].
EMPS_COPY = 24_841 * 4 * 8


def _call(tmp_path, words, name) -> int:
    quiet = contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO())
    with quiet[0], quiet[1]:
        return main([*words, "--out", str(tmp_path / name), "--no-plot"])


@pytest.mark.parametrize("method", ["auto", "idim-ls", "idim-iv"])
def test_identify_emps_holds_at_most_two_copies(tmp_path, method):
    words = ["identify", "--emps", "--method", method]
    assert _call(tmp_path, words, "warm-up") == 0  # imports, numba's caches, first-call state
    gc.collect()
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        code = _call(tmp_path, words, "traced")
        peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
    print(f"identify --emps --method {method}: {peak / EMPS_COPY:.3f} copies")  # with -s
    assert code == 0
    assert peak <= 2.0 * EMPS_COPY
