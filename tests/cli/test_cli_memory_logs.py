"""Memory of identify on logs through their loop, several logs, a file of several runs and a
validation log (issue 25: "no command holds more than two copies of a log"): the counting
rule, the helper and the small blocks of ``test_cli_memory.py`` (a file of its own so that
the two run on two workers). Every log here is SYNTHETIC (seeded)."""

from __future__ import annotations

import numpy as np
from test_cli_memory import (  # the helper and its autouse fixture
    IDENTIFY,
    N0_IDENTIFY,
    N1_IDENTIFY,
    TWO_COPIES,
    J,
    copies,
    small_blocks,  # noqa: F401
)

#: Two logs: each half as long, so that both hold the single-log tests' samples.
N0_EACH, N1_EACH = N0_IDENTIFY // 2, N1_IDENTIFY // 2


def test_identify_through_the_loop_holds_at_most_two_copies(tmp_path):
    """--method idim-iv through the logged loop, a PD in torque units with velocity feedback
    only (as the EMPS controller of --emps): four columns read."""
    w = 2 * np.pi * 5.0
    command = [*IDENTIFY, "--reference", "r", "--method", "idim-iv",
               "--loop-kp", f"{J * w * w!r}", "--loop-kd", f"{J * 2 * w!r}"]  # fmt: skip
    assert copies(tmp_path, command, {"log": (".parquet", 0, 1.0)}, 4) <= TWO_COPIES


def test_identify_several_logs_holds_at_most_two_copies(tmp_path):
    """Two logs, one moving each way, with a shared offset: copies of both logs."""
    command = ["identify", "{log}", "{other}", "--time", "t", "--position", "q", "--input", "u",
               "--offsets", "shared"]  # fmt: skip
    files = {"log": (".parquet", 0, 1.0), "other": (".parquet", 1, -1.0)}
    assert copies(tmp_path, command, files, 3, n0=N0_EACH, n1=N1_EACH) <= TWO_COPIES


def test_identify_runs_of_one_file_holds_at_most_two_copies(tmp_path):
    """--run: one file holding two runs, split by its run column (four columns read)."""
    command = [*IDENTIFY, "--run", "run"]
    command[1] = "{runs}"
    assert copies(tmp_path, command, {"runs": (".parquet", 0, 1.0)}, 4) <= TWO_COPIES


def test_identify_with_validation_holds_at_most_two_copies(tmp_path):
    """--validate OTHER: the identified model simulated on a second log (both logs count)."""
    command = [*IDENTIFY, "--method", "idim-ls", "--validate", "{other}"]
    files = {"log": (".parquet", 0, 1.0), "other": (".parquet", 1, 1.0)}
    assert copies(tmp_path, command, files, 3, n0=N0_EACH, n1=N1_EACH) <= TWO_COPIES
