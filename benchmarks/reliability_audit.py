"""Reliability audit (issue 16): feed bad inputs to the API, the CLI and log files; count outcomes.

Run with

    python benchmarks/reliability_audit.py [--verbose]

Every case is a call that should either work or fail cleanly. The outcome is classified as

- ``clean``: a ParameterValueError/ParameterTypeError (CLI: exit code 2 with one line
  ``hpdob <command>: error: ...``) whose message is one line;
- ``accepted``: the call returned (listed with ``--verbose``: each is a deliberate acceptance,
  e.g. NaN samples in a Parquet float column are rejected later, by ``identify``);
- ``escape``: any other exception, a traceback, a multi-line message, or a rejected call that
  changed the state of the object it was called on. The audit exits non-zero on any escape.

The counts printed at the end are the ones quoted in docs/reliability.md. The surfaces that
issues 12-15 added (position-only, ESO, Kalman, two-mass plant, estimate, tune, compare, the
stability map of any family, ``hpdob design --type``) are in reliability_audit_families.py;
``--part core`` or ``--part families`` runs one half.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import sys
import tempfile
import warnings
from collections import Counter
from pathlib import Path

import numpy as np

from hpdob import (
    PD,
    Actuator,
    DisturbanceObserver,
    Encoder,
    LinearObserver,
    Observer,
    ParameterTypeError,
    ParameterValueError,
    ServoLoop,
    ServoModel,
    design_observer,
    estimate,
    initial_state,
    update,
)
from hpdob.cli import main as cli_main
from hpdob.identification import emps, identify, read_log
from hpdob.observers import outputs

HUGE = 10**400
NAN, INF = math.nan, math.inf
CLEAN = (ParameterTypeError, ParameterValueError)


class Audit:
    def __init__(self, verbose: bool):
        self.verbose = verbose
        self.counts: Counter = Counter()
        self.escapes: list[str] = []
        self.accepted: list[str] = []

    def _record(self, surface: str, name: str, outcome: str, detail: str = "") -> None:
        self.counts[surface, outcome] += 1
        if outcome == "escape":
            self.escapes.append(f"[{surface}] {name}: {detail}")
        elif outcome == "accepted":
            self.accepted.append(f"[{surface}] {name}")
        if self.verbose:
            print(f"{outcome:>8}  [{surface}] {name} {detail}"[:220])

    def api(self, surface: str, name: str, call, *, state=None, check=None) -> None:
        """Run ``call()``; ``state()`` (optional) must be unchanged when it raises, and
        ``check(result)`` (optional) true when it returns (else a silently wrong result)."""
        before = None if state is None else state()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error")  # a warning instead of an error is an escape
                result = call()
        except CLEAN as err:
            text = str(err)
            if "\n" in text:
                self._record(surface, name, "escape", f"multi-line message: {text!r}")
            elif state is not None and not _same(before, state()):
                self._record(surface, name, "escape", "a rejected call changed the state")
            else:
                self._record(surface, name, "clean", text[:120])
        except TypeError as err:  # Python's own signature check names the argument: clean
            signature = (
                "unexpected keyword argument",
                "required positional argument",
                "required keyword-only argument",
                "were given",
            )
            outcome = "clean" if any(s in str(err) for s in signature) else "escape"
            self._record(surface, name, outcome, f"{type(err).__name__}: {err}"[:200])
        except Exception as err:
            self._record(surface, name, "escape", f"{type(err).__name__}: {err}"[:200])
        else:
            if check is not None and not check(result):
                self._record(surface, name, "escape", "accepted with a wrong (non-finite) result")
            else:
                self._record(surface, name, "accepted")

    def cli(self, surface: str, name: str, argv, *, cwd: Path) -> None:
        out, err = io.StringIO(), io.StringIO()
        with (
            contextlib.chdir(cwd),
            contextlib.redirect_stdout(out),
            contextlib.redirect_stderr(err),
        ):
            try:
                code = cli_main([str(a) for a in argv])
            except SystemExit as exit_:
                code = exit_.code
            except BaseException as exc:
                self._record(surface, name, "escape", f"{type(exc).__name__}: {exc}")
                return
        text = err.getvalue()
        if code == 0 or (
            code == 1
            and out.getvalue().rstrip().splitlines()[-1:] != []
            and "warning:" in out.getvalue()
            and text == ""
        ):
            self._record(surface, name, "accepted")  # 1: done, with a warning (diverged)
        elif code == 2 and text.count("\n") == 1 and ": error: " in text:
            self._record(surface, name, "clean", text.strip()[:120])
        else:
            self._record(surface, name, "escape", f"exit {code}: {text!r}"[:200])

    def report(self) -> int:
        surfaces = sorted({s for s, _ in self.counts})
        print(f"{'surface':<22}{'tried':>7}{'clean':>7}{'accepted':>10}{'escapes':>9}")
        for s in surfaces:
            row = [self.counts[s, k] for k in ("clean", "accepted", "escape")]
            print(f"{s:<22}{sum(row):>7}{row[0]:>7}{row[1]:>10}{row[2]:>9}")
        total = [sum(self.counts[s, k] for s in surfaces) for k in ("clean", "accepted", "escape")]
        print(f"{'total':<22}{sum(total):>7}{total[0]:>7}{total[1]:>10}{total[2]:>9}")
        for line in self.escapes:
            print("ESCAPE", line)
        return 1 if self.escapes else 0


def _same(a, b) -> bool:
    return all(np.array_equal(x, y, equal_nan=True) for x, y in zip(a, b, strict=True))


# -- logs and identification ------------------------------------------------------------------
def _log_columns():
    log = emps()
    n = 6000  # a part of the EMPS run: enough motion in both directions, fast to identify
    return {
        "t": log.t[:n],
        "qm": log.theta[:n],
        "vir": log.u[:n] / log.input_gain,
        "qg": log.reference[:n],
    }, log.input_gain


def _write_csv(path: Path, columns: dict, *, header=None, rows=None, encoding="utf-8") -> Path:
    names = header or list(columns)
    lines = [",".join(names)]
    data = rows if rows is not None else zip(*columns.values(), strict=True)
    lines += [",".join(str(v) for v in row) for row in data]
    path.write_bytes(("\n".join(lines) + "\n").encode(encoding))
    return path


def audit_logs(audit: Audit, tmp: Path) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq
    import scipy.io

    columns, gain = _log_columns()
    good = {"time": "t", "position": "qm", "input": "vir", "input_gain": gain}
    n = len(columns["t"])

    def case(name, path, **overrides):
        kwargs = {**good, **overrides}
        audit.api("read_log", name, lambda: read_log(path, **kwargs).identify())

    # CSV
    csv_ok = _write_csv(tmp / "ok.csv", columns)
    case("valid CSV", csv_ok)
    case("missing column", csv_ok, position="theta")
    case("renamed time column", csv_ok, time="time")
    case("time and Ts both", csv_ok, Ts=1e-3)
    case("neither time nor Ts", csv_ok, time=None)
    case("input_gain variable missing from CSV", csv_ok, input_gain="gtau")
    case("input_gain nan", csv_ok, input_gain=NAN)
    case("input_gain huge int", csv_ok, input_gain=HUGE)
    case("input_gain bool", csv_ok, input_gain=True)
    case("position None", csv_ok, position=None)
    case("position int", csv_ok, position=3)
    case("axis bad", csv_ok, axis="angular")
    case("time_tolerance -1", csv_ok, time_tolerance=-1.0)
    case("Ts nan without time", csv_ok, time=None, Ts=NAN)
    case("Ts huge int without time", csv_ok, time=None, Ts=HUGE)
    case("unknown suffix", csv_ok.rename(tmp / "ok.dat"))
    csv_ok = _write_csv(tmp / "ok.csv", columns)
    case("directory named x.csv", (tmp / "dir.csv").mkdir() or tmp / "dir.csv")
    case("missing file", tmp / "nope.csv")
    rows = [list(r) for r in zip(*columns.values(), strict=True)]
    for label, cell in [
        ("text", "abc"),
        ("empty", ""),
        ("nan", "nan"),
        ("inf", "inf"),
        ("1e400", "1e400"),
        ("0x10", "0x10"),
        ("comma decimal", "1,5"),
    ]:
        bad = [r[:] for r in rows]
        bad[10][1] = cell
        case(f"CSV position cell {label}", _write_csv(tmp / f"cell_{label}.csv", columns, rows=bad))
    ragged = [r[:] for r in rows]
    ragged[5] = ragged[5][:2]
    case("ragged row", _write_csv(tmp / "ragged.csv", columns, rows=ragged))
    case("header only", _write_csv(tmp / "header.csv", columns, rows=[]))
    case("one row", _write_csv(tmp / "one.csv", columns, rows=rows[:1]))
    case("ten rows", _write_csv(tmp / "ten.csv", columns, rows=rows[:10]))
    (tmp / "empty.csv").write_bytes(b"")
    case("empty file", tmp / "empty.csv")
    case(
        "latin-1 bytes",
        _write_csv(
            tmp / "latin.csv", columns, header=["t", "qm", "vir", "qg\xe9"], encoding="latin-1"
        ),
    )
    case("UTF-16 file", _write_csv(tmp / "utf16.csv", columns, encoding="utf-16"))
    (tmp / "nul.csv").write_bytes(b"t,qm,vir,qg\n0,0\x00,0,0\n")
    case("NUL byte", tmp / "nul.csv")
    (tmp / "long.csv").write_text("t,qm,vir,qg\n" + "1" * 200_000 + ",0,0,0\n")
    case("200k-character field", tmp / "long.csv")
    (tmp / "binary.csv").write_bytes(bytes(range(256)) * 40)
    case("binary garbage", tmp / "binary.csv")
    dup = _write_csv(tmp / "dup.csv", columns, header=["t", "qm", "qm", "qg"])
    case("duplicated column names", dup)
    back = [r[:] for r in rows]
    back[100][0] = back[99][0]
    case("repeated time", _write_csv(tmp / "repeat.csv", columns, rows=back))
    shuffled = [r[:] for r in rows]
    shuffled[200], shuffled[201] = shuffled[201], shuffled[200]
    case("time not increasing", _write_csv(tmp / "swap.csv", columns, rows=shuffled))
    jitter = [r[:] for r in rows]
    jitter[300][0] += 4e-4
    case("non-uniform time", _write_csv(tmp / "jitter.csv", columns, rows=jitter))
    still = {**columns, "qm": np.zeros(n)}
    case("no motion", _write_csv(tmp / "still.csv", still))
    flat = {**columns, "vir": np.ones(n)}
    case("constant input", _write_csv(tmp / "flat.csv", flat))
    semi = tmp / "semi.csv"
    semi.write_text(csv_ok.read_text().replace(",", ";"))
    case("semicolon separated", semi)

    # Parquet
    def parquet(name, table):
        path = tmp / name
        pq.write_table(table, path)
        return path

    base = {k: pa.array(v) for k, v in columns.items()}
    case("valid Parquet", parquet("ok.parquet", pa.table(base)))
    case(
        "Parquet string column",
        parquet("str.parquet", pa.table({**base, "qm": pa.array([str(v) for v in columns["qm"]])})),
    )
    case(
        "Parquet bool column",
        parquet("bool.parquet", pa.table({**base, "qm": pa.array(columns["qm"] > 0)})),
    )
    case(
        "Parquet list column",
        parquet("list.parquet", pa.table({**base, "qm": pa.array([[v] for v in columns["qm"]])})),
    )
    case(
        "Parquet timestamp time",
        parquet(
            "ts.parquet",
            pa.table(
                {
                    **base,
                    "t": pa.array((columns["t"] * 1e6).astype("int64")).cast(pa.timestamp("us")),
                }
            ),
        ),
    )
    nulls = pa.array([None if i == 50 else v for i, v in enumerate(columns["qm"])])
    case("Parquet null value", parquet("null.parquet", pa.table({**base, "qm": nulls})))
    ints = pa.array([None if i == 50 else int(i) for i in range(n)], type=pa.int64())
    case(
        "Parquet int column with null", parquet("intnull.parquet", pa.table({**base, "vir": ints}))
    )
    case(
        "Parquet struct column",
        parquet(
            "struct.parquet", pa.table({**base, "qm": pa.array([{"a": v} for v in columns["qm"]])})
        ),
    )
    case(
        "Parquet dictionary column",
        parquet(
            "dict.parquet", pa.table({**base, "qm": pa.array(columns["qm"]).dictionary_encode()})
        ),
    )
    case(
        "Parquet decimal column",
        parquet(
            "dec.parquet", pa.table({**base, "qm": pa.array([0] * n).cast(pa.decimal128(30, 3))})
        ),
    )
    case(
        "Parquet empty table",
        parquet("empty.parquet", pa.table({k: v[:0] for k, v in base.items()})),
    )
    case(
        "Parquet missing column",
        parquet("miss.parquet", pa.table({k: v for k, v in base.items() if k != "vir"})),
    )
    (tmp / "corrupt.parquet").write_bytes(b"PAR1" + bytes(500) + b"PAR1")
    case("corrupt Parquet", tmp / "corrupt.parquet")
    (tmp / "text.parquet").write_text("t,qm\n1,2\n")
    case("CSV named .parquet", tmp / "text.parquet")

    # MAT
    def mat(name, **variables):
        path = tmp / name
        scipy.io.savemat(path, {**columns, "gtau": gain, **variables})
        return path

    case("valid MAT", mat("ok.mat"), input_gain="gtau")
    case("MAT string variable", mat("s.mat", qm="abc"), input_gain="gtau")
    case("MAT complex variable", mat("c.mat", qm=columns["qm"] + 1j), input_gain="gtau")
    case("MAT bool variable", mat("b.mat", qm=columns["qm"] > 0), input_gain="gtau")
    case("MAT matrix", mat("m.mat", qm=np.ones((3, 4))), input_gain="gtau")
    case("MAT 3-D array", mat("3d.mat", qm=np.ones((2, 2, 2))), input_gain="gtau")
    case("MAT struct", mat("st.mat", qm={"a": 1.0}), input_gain="gtau")
    case("MAT cell array", mat("cell.mat", qm=np.array([1, "a"], dtype=object)), input_gain="gtau")
    case("MAT empty variable", mat("e.mat", qm=np.zeros(0)), input_gain="gtau")
    case("MAT gain vector", mat("gv.mat", gtau=np.arange(3.0)), input_gain="gtau")
    case("MAT gain zero", mat("g0.mat", gtau=0.0), input_gain="gtau")
    case("MAT gain nan", mat("gn.mat", gtau=NAN), input_gain="gtau")
    case(
        "MAT int16 column",
        mat("i16.mat", vir=(columns["vir"] * 1000).astype(np.int16)),
        input_gain="gtau",
    )
    case("MAT missing gain variable", mat("ok2.mat"), input_gain="gain")
    (tmp / "corrupt.mat").write_bytes(b"MATLAB 5.0 MAT-file" + bytes(200))
    case("corrupt MAT", tmp / "corrupt.mat", input_gain="gtau")
    (tmp / "h5.mat").write_bytes(b"\x89HDF\r\n\x1a\n" + bytes(600))
    case("HDF5 bytes named .mat", tmp / "h5.mat", input_gain="gtau")
    # identify() settings
    log = read_log(csv_ok, **good)
    for name, kwargs in {
        "method bad": {"method": "ls"},
        "bandwidth 0": {"bandwidth": 0.0},
        "bandwidth nan": {"bandwidth": NAN},
        "bandwidth huge int": {"bandwidth": HUGE},
        "cutoff above Nyquist": {"cutoff": 600.0},
        "cutoff negative": {"cutoff": -1.0},
        "order 0": {"order": 0},
        "order 100": {"order": 100},
        "order float": {"order": 4.0},
        "decimation 0": {"decimation": 0},
        "decimation huge": {"decimation": 10**6},
        "border negative": {"border": -1},
        "border beyond the log": {"border": 10**6},
        "min_speed negative": {"min_speed": -1.0},
        "min_speed above every speed": {"min_speed": 1e6},
        "max_iterations 0": {"max_iterations": 0},
        "tolerance nan": {"tolerance": NAN},
        "idim-iv without loop": {"method": "idim-iv"},
        "loop of the wrong type": {"loop": object()},
        "axis bad": {"axis": "x"},
    }.items():
        audit.api("identify", name, lambda kw=kwargs: log.identify(**kw))
    for name, args in {
        "t shorter": (log.t[:-1], log.theta, log.u),
        "theta with nan": (log.t, np.where(np.arange(len(log)) == 9, NAN, log.theta), log.u),
        "u complex": (log.t, log.theta, log.u + 0j),
        "u strings": (log.t, log.theta, log.u.astype(str)),
        "t 2-D": (log.t[:, None], log.theta, log.u),
        "empty": (np.zeros(0), np.zeros(0), np.zeros(0)),
        "scalars": (1.0, 2.0, 3.0),
        "None": (None, None, None),
        "huge ints": ([HUGE] * 3, [0, 1, 2], [0, 1, 2]),
    }.items():
        audit.api("identify", name, lambda a=args: identify(*a))


def audit_identify_cli(audit: Audit, tmp: Path) -> None:
    columns, gain = _log_columns()
    path = _write_csv(tmp / "log.csv", columns)
    ok = [
        "identify",
        path,
        "--time",
        "t",
        "--position",
        "qm",
        "--input",
        "vir",
        "--input-gain",
        str(gain),
        "--out",
        tmp / "id",
        "--no-plot",
    ]
    audit.cli("hpdob identify", "valid", ok, cwd=tmp)
    for name, argv in {
        "no log, no --emps": ["identify"],
        "log and --emps": ["identify", path, "--emps"],
        "--emps with --time": ["identify", "--emps", "--time", "t"],
        "missing --position": ["identify", path, "--input", "vir", "--time", "t"],
        "renamed column": [*ok[:5], "pos", *ok[6:]],
        "--input-gain nan": [*ok[:9], "nan", *ok[10:]],
        "--input-gain unknown variable": [*ok[:9], "gtau", *ok[10:]],
        "--Ts with --time": [*ok, "--Ts", "1e-3"],
        "--Ts 0 without time": [ok[0], ok[1], *ok[4:], "--Ts", "0"],
        "--method idim-iv without loop": [*ok, "--method", "idim-iv"],
        "--kp nan": [*ok, "--method", "idim-iv", "--reference", "qg", "--kp", "nan", "--kd", "1"],
        "--velocity-filter text": [*ok, "--velocity-filter", "a,b"],
        "--order -1": [*ok, "--order", "-1"],
        "--decimation 0": [*ok, "--decimation", "0"],
        "--out ''": [*ok[:-3], "--out", "", "--no-plot"],
        "log is a directory": ["identify", tmp, *ok[2:]],
        "log missing": ["identify", tmp / "nope.csv", *ok[2:]],
        "Parquet named csv": [
            "identify",
            (tmp / "x.csv").write_bytes(b"PAR1\0\0PAR1") or tmp / "x.csv",
            *ok[2:],
        ],
    }.items():
        audit.cli("hpdob identify", name, argv, cwd=tmp)


# -- ServoLoop, LinearObserver, the functional core, the runtime observer -------------------------
def audit_servo_loop(audit: Audit) -> None:
    model = ServoModel(2.8e-4).discretize(1e-3)
    design = design_observer(model, order=1, bandwidth=100.0)
    good = {
        "plant": ServoModel(3.06e-4),
        "nominal": ServoModel(2.8e-4),
        "Ts": 1e-3,
        "controller": PD(50.0, 5.0),
    }
    audit.api("ServoLoop", "valid", lambda: ServoLoop(**good, observer=design))
    bad = {
        "plant None": {"plant": None},
        "plant a design": {"plant": design},
        "plant discrete": {"plant": model},
        "nominal str": {"nominal": "2.8e-4"},
        "Ts 0": {"Ts": 0.0},
        "Ts nan": {"Ts": NAN},
        "Ts huge int": {"Ts": HUGE},
        "Ts bool": {"Ts": True},
        "Ts array": {"Ts": np.array([1e-3, 2e-3])},
        "controller dict": {"controller": {"kp": 50}},
        "observer str": {"observer": "HPDOb"},
        "observer of another Ts": {
            "observer": design_observer(
                ServoModel(2.8e-4).discretize(2e-3), order=1, bandwidth=100.0
            )
        },
        "observer of another J_n": {
            "observer": design_observer(ServoModel(3e-4).discretize(1e-3), order=1, bandwidth=100.0)
        },
        "sensor a PD": {"sensor": PD(1.0, 1.0)},
        "actuator int": {"actuator": 3},
        "actuator delay huge": {"actuator": lambda: Actuator(delay_samples=10**7)},
        "encoder huge": {"sensor": lambda: Encoder(2**60)},
        "unknown key": {"plnt": ServoModel(3e-4)},
    }
    for name, change in bad.items():

        def call(change=change):
            args = dict(good)
            args.update(
                {
                    k: v() if callable(v) and not isinstance(v, type) else v
                    for k, v in change.items()
                }
            )
            return ServoLoop(**args)

        audit.api("ServoLoop", name, call)
    loop = ServoLoop(**good, observer=design)
    for name, changes in {
        "replace Ts string": {"Ts": "1e-3"},
        "replace unknown": {"gain": 1.0},
        "replace plant None": {"plant": None},
    }.items():
        audit.api(
            "ServoLoop",
            name,
            lambda c=changes: loop.replace(**c),
            state=lambda: (np.array(loop.Ts),),
        )


def audit_linear_observer(audit: Audit) -> None:
    dob = design_observer(ServoModel(2.8e-4).discretize(1e-3), order=0, bandwidth=200.0).system
    good = {"F": dob.F, "G": dob.G, "H": dob.H, "E": dob.E, "N": dob.N, "Ts": 1e-3}
    audit.api("LinearObserver", "valid", lambda: LinearObserver(**good))
    for name, change in {
        "F 0x0": {"F": np.zeros((0, 0))},
        "F not square": {"F": np.zeros((1, 2))},
        "F 3-D": {"F": np.zeros((1, 1, 1))},
        "F nan": {"F": [[NAN]]},
        "F inf": {"F": [[INF]]},
        "F huge int": {"F": [[HUGE]]},
        "F complex": {"F": [[0.5j]]},
        "F strings": {"F": [["a"]]},
        "F bool": {"F": [[True]]},
        "F None": {"F": None},
        "F ragged": {"F": [[1.0], [1.0, 2.0]]},
        "F scalar": {"F": 0.5},
        "G wrong shape": {"G": np.zeros((1, 2))},
        "G nan": {"G": np.full((1, 3), NAN)},
        "H wrong shape": {"H": np.zeros((2, 2))},
        "E feed-through from u": {"E": [[-1.0, -1.0, 1.0]]},
        "E wrong shape": {"E": np.zeros((1, 4))},
        "N wrong shape": {"N": np.zeros((1, 2))},
        "N inf": {"N": np.full((1, 3), INF)},
        "Ts 0": {"Ts": 0.0},
        "Ts huge int": {"Ts": HUGE},
        "measures unknown": {"measures": ("theta", "accel")},
        "measures str": {"measures": "theta"},
        "outputs unknown": {"outputs": ("omega_hat",)},
        "model wrong type": {"model": ServoModel(2.8e-4)},
        "model of another Ts": {"model": ServoModel(2.8e-4).discretize(2e-3)},
        "name int": {"name": 3},
        "program wrong type": {"program": "x"},
        "error_dynamics wrong type": {"error_dynamics": 1},
        "position-only with state G": {"measures": ("theta",)},
        "huge F": {"F": [[1e308]], "G": np.full((1, 3), 1e308)},
    }.items():
        audit.api("LinearObserver", name, lambda c=change: LinearObserver(**{**good, **c}))


def audit_core(audit: Audit) -> None:
    design = design_observer(ServoModel(2.8e-4).discretize(1e-3), order=1, bandwidth=100.0)
    state = initial_state(design)
    xs = {
        "x nan": (NAN, 0.0),
        "x inf": (0.0, INF),
        "x huge int": (HUGE, 0),
        "x str": "ab",
        "x bytes": b"ab",
        "x dict": {0: 1.0, 1: 2.0},
        "x set": {1.0, 2.0},
        "x 3 values": (1, 2, 3),
        "x None": None,
        "x complex": (1j, 0.0),
        "x bool": (True, False),
        "x 2-D": np.zeros((2, 1)),
        "x object array": np.array([1, "a"], dtype=object),
        "x list of lists": [[1.0], [2.0]],
    }
    for fn in (estimate, outputs):
        for name, x in xs.items():
            audit.api(
                "functional core", f"{fn.__name__} {name}", lambda f=fn, x=x: f(design, state, x)
            )
    for name, x in xs.items():
        audit.api("functional core", f"update {name}", lambda x=x: update(design, state, x, 0.0))
    for name, u in {
        "u nan": NAN,
        "u huge int": HUGE,
        "u str": "1",
        "u complex": 1j,
        "u array": np.zeros(2),
        "u None": None,
    }.items():
        audit.api("functional core", f"update {name}", lambda u=u: update(design, state, (0, 0), u))
    for name, s in {
        "state nan": (NAN, NAN),
        "state list": [0.0, 0.0],
        "state short": (0.0,),
        "state ints": (0, 0),
        "state str": "ab",
        "state None": None,
        "state numpy": np.zeros(2),
    }.items():
        audit.api("functional core", f"estimate {name}", lambda s=s: estimate(design, s, (0, 0)))
        audit.api("functional core", f"update {name}", lambda s=s: update(design, s, (0, 0), 0))
    for name, obs in {
        "observer str": "x",
        "observer None": None,
        "observer model": ServoModel(1),
        "observer int": 3,
    }.items():
        audit.api("functional core", f"estimate {name}", lambda o=obs: estimate(o, state, (0, 0)))
        audit.api("functional core", f"initial_state {name}", lambda o=obs: initial_state(o))
    for name, kw in {
        "x0 nan": {"x0": (NAN, 0)},
        "tau0 inf": {"tau0": INF},
        "tau0 huge": {"tau0": HUGE},
        "x0 short": {"x0": (0.0,)},
    }.items():
        audit.api(
            "functional core", f"initial_state {name}", lambda kw=kw: initial_state(design, **kw)
        )


def audit_runtime(audit: Audit) -> None:
    model = ServoModel(2.8e-4).discretize(1e-3)
    dob = DisturbanceObserver(model, order=1, bandwidth=100.0)
    dob.update((0.1, 0.2), 0.01)
    generic = Observer.of(design_observer(model, order=2, bandwidth=150.0))
    for label, obs in (("DisturbanceObserver", dob), ("Observer.of", generic)):

        def state(o=obs):
            return (np.array(o.state),)

        for name, args in {
            "x nan": ((NAN, 0.0), 0.0),
            "u inf": ((0.0, 0.0), INF),
            "x dict": ({0: 1.0, 1: 2.0}, 0.0),
            "u huge": ((0, 0), HUGE),
            "x set": ({1.0, 2.0}, 0.0),
            "u str": ((0, 0), "1"),
        }.items():
            audit.api(
                "runtime observer",
                f"{label}.update {name}",
                lambda o=obs, a=args: o.update(*a),
                state=state,
            )
            if name.startswith("x"):
                audit.api(
                    "runtime observer",
                    f"{label}.estimate {name}",
                    lambda o=obs, a=args: o.estimate(a[0]),
                    state=state,
                )
        for name, args in {
            "reset x0 nan": ((NAN, 0.0), 0.0),
            "reset tau0 huge": ((0, 0), HUGE),
            "reset x0 str": ("ab", 0.0),
        }.items():
            audit.api(
                "runtime observer",
                f"{label}.{name}",
                lambda o=obs, a=args: o.reset(*a),
                state=state,
            )


# -- scenario files, through the API and the CLI ------------------------------------------------
SUBSTITUTES = {
    "huge int": "1" + "0" * 400,
    "nan": "nan",
    "inf": "-inf",
    "string": '"1.0"',
    "bool": "true",
    "array": "[1.0, 2.0]",
    "table": "{ a = 1.0 }",
    "zero": "0",
    "negative": "-1.0",
    "tiny": "1e-320",
    "huge": "1e308",
}


def audit_scenarios(audit: Audit, tmp: Path) -> None:
    import re

    root = Path(__file__).resolve().parents[1]
    text = (root / "examples" / "canonical_hpdob.toml").read_text()
    text = text.replace("duration = 10.0", "duration = 0.1")
    lines = text.splitlines()
    numeric = [i for i, line in enumerate(lines) if re.search(r"=\s*-?[0-9]", line.split("#")[0])]
    count = 0
    for i in numeric:
        key = lines[i].split("=")[0].strip()
        for label, value in SUBSTITUTES.items():
            changed = [*lines[:i], f"{key} = {value}", *lines[i + 1 :]]
            path = tmp / f"case{count}.toml"
            path.write_text("\n".join(changed) + "\n")
            count += 1
            audit.cli(
                "scenario TOML",
                f"{key} = {label} (line {i + 1})",
                ["simulate", path, "--out", tmp / "o", "--no-plot"],
                cwd=tmp,
            )
    for label, payload in {
        "not TOML": b"Ts = = 1\n",
        "UTF-16": "Ts = 1e-3\n".encode("utf-16"),
        "latin-1": "# caf\xe9\nTs = 1e-3\n".encode("latin-1"),
        "empty": b"",
        "500 nested tables": ("x = " + "{a = " * 500 + "1" + "}" * 500 + "\n").encode(),
        "binary": bytes(range(256)),
        "unknown top-level key": b"Tss = 1e-3\n",
    }.items():
        path = tmp / f"raw_{count}.toml"
        path.write_bytes(payload)
        count += 1
        audit.cli(
            "hpdob simulate", label, ["simulate", path, "--out", tmp / "o", "--no-plot"], cwd=tmp
        )
    for label, replacement in {
        "label ../escaped": 'label = "../escaped"',
        "label NUL": 'label = "a\\u0000b"',
        "label empty": 'label = ""',
        "label hidden": 'label = ".x"',
    }.items():
        path = tmp / f"label_{count}.toml"
        path.write_text(text.replace('label = "HPDOb-100"', replacement))
        count += 1
        audit.cli(
            "hpdob simulate", label, ["simulate", path, "--out", tmp / "o", "--no-plot"], cwd=tmp
        )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--verbose", action="store_true", help="print every case")
    parser.add_argument(
        "--part",
        choices=("all", "core", "families", "second"),
        default="all",
        help="core: the surfaces of the first audit; families: those of issues 12-15 "
        "(reliability_audit_families.py); second: the cases of the second audit, issue 27 "
        "(reliability_audit_second.py); default all three",
    )
    args = parser.parse_args()
    audit = Audit(args.verbose)
    with tempfile.TemporaryDirectory() as directory:
        tmp = Path(directory)
        if args.part in ("all", "core"):
            audit_logs(audit, tmp)
            audit_identify_cli(audit, tmp)
            audit_scenarios(audit, tmp)
            audit_servo_loop(audit)
            audit_linear_observer(audit)
            audit_core(audit)
            audit_runtime(audit)
        if args.part in ("all", "families"):
            import reliability_audit_families

            reliability_audit_families.run(audit, tmp)
        if args.part in ("all", "second"):
            import reliability_audit_second

            reliability_audit_second.run(audit, tmp)
    code = audit.report()
    if args.verbose:
        print("accepted:", *audit.accepted, sep="\n  ")
    return code


if __name__ == "__main__":
    sys.exit(main())
