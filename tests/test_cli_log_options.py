"""The log options' messages are in the command's terms (``--time``, ``--Ts``), not the
library's keyword arguments (``time='column'``, ``Ts=...``)."""

from __future__ import annotations

import pytest

from hpdob.cli import main


@pytest.fixture
def log(tmp_path):
    path = tmp_path / "log.csv"
    path.write_text("t,q,u\n" + "".join(f"{k * 1e-3!r},0.0,0.0\n" for k in range(50)))
    return path


@pytest.mark.parametrize("command", ["estimate", "identify"])
@pytest.mark.parametrize(
    ("extra", "detail"),
    [([], ""), (["--time", "t", "--Ts", "0.001"], " (not both: got --time t and --Ts 0.001)")],
)
def test_missing_or_double_time_names_the_cli_options(command, extra, detail, log, tmp_path,
                                                      capsys):  # fmt: skip
    argv = [command, str(log), "--position", "q", "--input", "u", *extra,
            "--out", str(tmp_path / "out")]  # fmt: skip
    if command == "estimate":
        argv += ["--J-n", "2.8e-4", "--order", "1", "--bandwidth", "100"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err == (
        f"hpdob {command}: error: give the log's time column as --time NAME or, for a log "
        f"without one, its sampling period as --Ts SECONDS{detail}"
    )
    assert "time=" not in err and "Ts=" not in err
