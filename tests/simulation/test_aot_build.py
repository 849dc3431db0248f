"""The ahead-of-time built sample loop (issue 25): built with numba.pycc through the test
extra's ``zig cc``, run by a later process's ``simulate`` without numba, bit for bit the JIT's.

The module's fixture builds two loops once (~5-12 s each on the shared 2-core machine: numba
compiles the loop, zig compiles and links numba's C runtime; the second build reuses the
first's object files); every other test is a subprocess or an in-process run.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

from hpdob import Actuator, Encoder, ServoLoop, paper, simulate
from hpdob.simulation import AheadOfTimeWarning, LoopBuildError, build_loop_extension
from hpdob.simulation._aot import argument_types

FIELDS = ("theta", "omega", "theta_measured", "omega_measured", "u", "tau_hat", "tau_dn")

#: The canonical run (10 s, HPDOb-100) and one with an encoder (noise), a delay and a limit.
RUNS = {
    "canonical": "{}",
    "encoder": (
        "dict(duration=0.6, sensor=Encoder(4096, noise_std=2e-4, seed=1), substeps=4, "
        "actuator=Actuator(torque_limit=0.06, delay_samples=1))"
    ),
    "pd": "dict(observer=None, duration=1.0)",
}

RUN = """
import sys, numpy as np
from hpdob import Actuator, Encoder, paper, simulate
kw = paper.scenario()
kw["observer"] = paper.observer("HPDOb-100").design
kw.update({changes})
r = simulate(**kw)
np.savez(sys.argv[1], **{{k: getattr(r, k) for k in {fields}}})
print("numba" in sys.modules)
"""


def _settings(name: str) -> dict:
    kw = paper.scenario()
    kw["observer"] = paper.observer("HPDOb-100").design
    kw.update(eval(RUNS[name], {"Encoder": Encoder, "Actuator": Actuator}))
    return kw


def _in_subprocess(name: str, folder, path, **env) -> bool:
    """Run ``name`` in a fresh process looking in ``folder``; whether it imported numba."""
    code = RUN.format(changes=RUNS[name], fields=FIELDS)
    environment = {k: v for k, v in os.environ.items() if k != "HPDOB_AOT"}
    environment.update(HPDOB_AOT_DIR=str(folder), **env)
    done = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True,
                          text=True, check=True, env=environment)  # fmt: skip
    return done.stdout.split()[-1] == "True"


def _jit(name: str, monkeypatch):
    monkeypatch.setenv("HPDOB_AOT", "0")
    return simulate(**_settings(name))


def _same(saved, result) -> bool:
    return all(
        saved[k].dtype == getattr(result, k).dtype
        and saved[k].tobytes() == getattr(result, k).tobytes()
        for k in FIELDS
    )


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """A folder with the canonical and the encoder run's loops, built once."""
    folder = tmp_path_factory.mktemp("aot")
    paths = {name: build_loop_extension(**_settings(name), folder=folder, compiler="zig")
             for name in ("canonical", "encoder")}  # fmt: skip
    return folder, paths


@pytest.mark.parametrize("name", ["canonical", "encoder"])
def test_a_later_process_runs_the_built_loop_without_numba_bit_for_bit(
    name, built, tmp_path, monkeypatch
):
    folder, paths = built
    assert paths[name].parent == folder and paths[name].is_file()
    imported = _in_subprocess(name, folder, tmp_path / "r.npz")
    assert not imported  # the built loop ran: numba was never imported
    saved = np.load(tmp_path / "r.npz")
    assert saved["theta"].size == round(_settings(name)["duration"] / 1e-3)
    assert _same(saved, _jit(name, monkeypatch))


def test_a_run_of_another_structure_or_disabled_runs_the_jit_loop(built, tmp_path, monkeypatch):
    folder, _ = built
    assert _in_subprocess("pd", folder, tmp_path / "pd.npz")  # no PD loop built: the JIT's
    assert _same(np.load(tmp_path / "pd.npz"), _jit("pd", monkeypatch))
    assert _in_subprocess("canonical", folder, tmp_path / "off.npz", HPDOB_AOT="0")
    assert _same(np.load(tmp_path / "off.npz"), _jit("canonical", monkeypatch))


def test_building_again_keeps_the_built_file(built):
    folder, paths = built
    before = paths["canonical"].stat()
    again = build_loop_extension(**_settings("canonical"), folder=folder, compiler="zig")
    after = again.stat()
    assert again == paths["canonical"]  # the same file, not replaced by a new build
    assert (after.st_ino, after.st_mtime_ns) == (before.st_ino, before.st_mtime_ns)


@pytest.mark.parametrize("damage", ["garbage", "truncated", "no record", "another module"])
def test_a_corrupt_extension_is_reported_and_the_jit_loop_runs(
    damage, built, tmp_path, monkeypatch
):
    """A file under a run's extension name that is not what its build wrote (its size and
    SHA-256 are recorded beside it: loading a truncated shared object can crash the process)
    or that is a valid extension of another loop: a warning, and the JIT loop's result."""
    _, paths = built
    target = tmp_path / "aot"
    target.mkdir()
    canonical, other = paths["canonical"], paths["encoder"]
    copy = target / canonical.name
    record = canonical.with_suffix("").with_suffix(".sha256")
    shutil.copyfile(record, target / record.name)
    if damage == "garbage":
        copy.write_bytes(b"not an extension" * 100)
    elif damage == "truncated":
        copy.write_bytes(canonical.read_bytes()[:20000])
    elif damage == "no record":
        shutil.copyfile(canonical, copy)
        (target / record.name).unlink()
    else:  # recorded as it is, but its init function has the other loop's name
        shutil.copyfile(other, copy)
        shutil.copyfile(other.with_suffix("").with_suffix(".sha256"), target / record.name)
    expected = _jit("canonical", monkeypatch)
    monkeypatch.delenv("HPDOB_AOT")
    monkeypatch.setenv("HPDOB_AOT_DIR", str(target))
    with pytest.warns(AheadOfTimeWarning, match="could not be loaded"):
        result = simulate(**_settings("canonical"))
    assert all(getattr(result, k).tobytes() == getattr(expected, k).tobytes() for k in FIELDS)


def test_a_failed_or_interrupted_build_leaves_no_extension(tmp_path):
    failing = [sys.executable, "-c", "raise SystemExit(1)"]
    with pytest.raises(LoopBuildError, match=r"numba\.pycc failed"):
        build_loop_extension(**_settings("pd"), folder=tmp_path / "a", compiler=failing)
    left = [p.name for p in (tmp_path / "a").iterdir()]
    assert not [n for n in left if n.startswith(("hpdob_aot_", ".build-"))], left
    # killed while numba compiles: the temporary folder may stay, no extension appears
    folder = tmp_path / "b"
    code = ("import sys; from hpdob import paper; from hpdob.simulation import "
            "build_loop_extension; kw = paper.scenario(); kw['observer'] = None; "
            "build_loop_extension(**kw, folder=sys.argv[1], compiler='zig')")  # fmt: skip
    process = subprocess.Popen([sys.executable, "-c", code, str(folder)],
                               start_new_session=True)  # fmt: skip
    try:
        deadline = time.monotonic() + 120
        while not (folder.is_dir() and any(folder.glob(".build-*"))):
            assert process.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
    finally:  # the caller; its build process (a session of its own) runs on: killed too
        os.killpg(process.pid, signal.SIGKILL)
        process.wait()
        _kill_builds_in(folder)
    assert not any(p.name.startswith("hpdob_aot_") for p in folder.iterdir())


def _kill_builds_in(folder: Path) -> None:
    """Kill the build processes (and their compilers: each build is a session of its own)
    whose command line names a folder in ``folder``."""
    for entry in Path("/proc").glob("[0-9]*"):
        try:
            command = (entry / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if any(part.startswith(os.fsencode(folder)) for part in command):
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(int(entry.name), signal.SIGKILL)


def test_bad_input_is_rejected_and_writes_nothing(tmp_path):
    kw = _settings("pd")
    folder = tmp_path / "none"
    loop = ServoLoop(**{k: kw.pop(k) for k in ("plant", "nominal", "Ts", "controller",
                                               "observer")})  # fmt: skip
    cases = [
        (TypeError, "takes a ServoLoop as its first argument", 3, {}),
        (TypeError, "folder must be a path", loop, {"folder": 3}),
        (TypeError, "compiler must be a command line", loop, {"compiler": 5}),
        (ValueError, "compiler must name a compiler", loop, {"compiler": ""}),
        (ValueError, "cxx_compiler needs a compiler", loop, {"cxx_compiler": "clang++"}),
        (ValueError, "timeout must be a positive", loop, {"timeout": 0}),
        (ValueError, "duration", loop, {"duration": -1.0}),
        (ValueError, r"folder must name a folder, got ''", loop, {"folder": ""}),
        (
            ValueError,
            r"compiler must be a command line shlex can split, got 'gcc \"-O2'",
            loop,
            {"compiler": 'gcc "-O2'},
        ),
        (
            ValueError,
            "cxx_compiler must be None with compiler='zig'",
            loop,
            {"compiler": "zig", "cxx_compiler": "clang++"},
        ),
        (
            ValueError,
            "timeout must be a positive finite number of seconds, got inf",
            loop,
            {"timeout": float("inf")},
        ),
        (
            ValueError,
            "timeout must be a positive finite number of seconds, got nan",
            loop,
            {"timeout": float("nan")},
        ),
        (
            TypeError,
            "timeout must be a positive finite number of seconds, got '5' of type str",
            loop,
            {"timeout": "5"},
        ),
        (TypeError, "timeout .* got None of type NoneType", loop, {"timeout": None}),
        (TypeError, "timeout .* got True of type bool", loop, {"timeout": True}),
    ]
    for error, message, first, change in cases:
        arguments = {**kw, "folder": folder, **change}
        with pytest.raises(error, match=message):
            build_loop_extension(first, **arguments)
        assert not folder.exists()


@pytest.fixture
def no_build(monkeypatch):
    """The build step replaced by a failure: a refused call never reaches it."""
    import hpdob.simulation._aot_build as aot_build

    def compile_(work, command, timeout):
        raise AssertionError(f"the build started in {work}")

    monkeypatch.setattr(aot_build, "_compile", compile_)


def test_a_folder_that_cannot_be_written_is_refused_before_the_build(tmp_path, no_build):
    kw = _settings("pd")
    taken = tmp_path / "taken"
    taken.write_text("a file")
    for folder in (taken, taken / "below"):
        with pytest.raises(OSError, match=f"folder '{folder}' cannot be written"):
            build_loop_extension(**kw, folder=folder, compiler="zig")
    assert [p.name for p in tmp_path.iterdir()] == ["taken"]
    assert taken.read_text() == "a file"


@pytest.fixture
def read_only_folder(tmp_path):
    """A folder in which no file can be created: one of mode 0o500 for a user; for root,
    whom permissions do not bind, ``/sys`` (sysfs creates no file on request, root's
    either: the probe's own check that it refuses)."""
    if not hasattr(os, "geteuid") or os.geteuid() != 0:
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o500)
        try:
            yield locked
        finally:
            locked.chmod(0o700)
        return
    sysfs = Path("/sys")
    if not sysfs.is_dir():
        pytest.skip("no folder refuses root here: no /sys")
    try:
        handle, probe = tempfile.mkstemp(dir=sysfs)
    except OSError:
        yield sysfs
        return
    os.close(handle)
    os.unlink(probe)
    pytest.skip("no folder refuses root here: /sys accepted a file")


def test_a_read_only_folder_is_refused_before_the_build(read_only_folder, no_build):
    locked = read_only_folder
    before = sorted(os.listdir(locked))
    for folder in (locked, locked / "below"):
        with pytest.raises(OSError, match=f"folder '{folder}' cannot be written"):
            build_loop_extension(**_settings("pd"), folder=folder, compiler="zig")
    assert sorted(os.listdir(locked)) == before


def test_numpy_numbers_are_timeouts(tmp_path, monkeypatch):
    import hpdob.simulation._aot_build as aot_build

    seen = []

    def compile_(work, command, timeout):
        seen.append(timeout)
        raise LoopBuildError("stopped here")

    monkeypatch.setattr(aot_build, "_compile", compile_)
    for timeout in (np.int64(5), np.float64(2.5), 7):
        with pytest.raises(LoopBuildError, match="stopped here"):
            build_loop_extension(**_settings("pd"), folder=tmp_path, timeout=timeout)
    assert seen == [5.0, 2.5, 7.0] and all(type(t) is float for t in seen)


#: A build whose compile step writes bytes of its own process, after waiting up to 1 s in
#: ``sys.argv[2]`` for the other process's build to arrive there too.
FAKE_BUILD = """
import json, os, sys, time
from pathlib import Path
from hpdob import paper
from hpdob.simulation import build_loop_extension
import hpdob.simulation._aot_build as aot_build

def compile_(work, command, timeout):
    meeting = Path(sys.argv[2])
    (meeting / str(os.getpid())).touch()
    deadline = time.monotonic() + 1.0
    while len(list(meeting.iterdir())) < 2 and time.monotonic() < deadline:
        time.sleep(0.01)
    spec = json.loads((work / "spec.json").read_text())
    (work / spec["file"]).write_bytes(str(os.getpid()).encode() * 1000)

aot_build._compile = compile_
kw = paper.scenario()
kw["observer"] = None
print(build_loop_extension(**kw, folder=sys.argv[1]))
"""


def test_two_processes_building_one_loop_leave_one_intact_extension(tmp_path):
    """Two processes building the same loop at once (fake builds whose files differ, as two
    real builds' can): the second waits on the first's lock and finds its extension, instead
    of building too and renaming its record and file over the first's (one's record beside
    the other's file would be loaded by no run)."""
    from hpdob.simulation import _aot

    folder, meeting = tmp_path / "aot", tmp_path / "meeting"
    meeting.mkdir()
    processes = [subprocess.Popen([sys.executable, "-c", FAKE_BUILD, str(folder), str(meeting)],
                                  stdout=subprocess.PIPE, text=True) for _ in range(2)]  # fmt: skip
    paths = {process.communicate(timeout=60)[0].strip() for process in processes}
    assert [process.returncode for process in processes] == [0, 0]
    assert len(paths) == 1 and _aot.intact(Path(paths.pop()))
    assert len(list(meeting.iterdir())) == 1  # one build; the other found its extension


@pytest.mark.skipif(sys.platform == "win32", reason="holds the lock with fcntl")
def test_a_build_waits_for_another_at_most_timeout(tmp_path, monkeypatch):
    """Another build of the loop holding its lock (here the test): a LoopBuildError after
    ``timeout`` seconds, not a wait without end; nothing built."""
    import fcntl

    import hpdob.simulation._aot_build as aot_build

    names = []

    def compile_(work, command, timeout):
        names.append(json.loads((work / "spec.json").read_text())["name"])
        raise LoopBuildError("the build started")

    monkeypatch.setattr(aot_build, "_compile", compile_)
    folder = tmp_path / "aot"
    with pytest.raises(LoopBuildError, match="the build started"):  # the lock's name
        build_loop_extension(**_settings("pd"), folder=folder)
    with open(folder / f".{names[0]}.lock", "ab") as held:
        fcntl.flock(held.fileno(), fcntl.LOCK_EX)
        with pytest.raises(LoopBuildError, match=r"another build of this loop held .* "
                           r"for longer than timeout=0\.2 s"):  # fmt: skip
            build_loop_extension(**_settings("pd"), folder=folder, timeout=0.2)
    assert len(names) == 1
    assert not [p for p in folder.iterdir() if p.name.startswith("hpdob_aot_")]


@pytest.fixture
def fake_build(tmp_path, monkeypatch):
    """A folder holding a file under the PD run's extension name (a fake build: no compiler)
    and the paths ``simulate`` tries to load, recorded (none is loaded: the JIT loop runs)."""
    import hpdob.simulation._aot_build as aot_build
    from hpdob.simulation import _aot

    def compile_(work, command, timeout):
        spec = json.loads((work / "spec.json").read_text())
        (work / spec["file"]).write_bytes(b"not loaded")

    monkeypatch.setattr(aot_build, "_compile", compile_)
    folder = tmp_path / "aot"
    path = build_loop_extension(**_settings("pd"), folder=folder)
    tried = []
    monkeypatch.setattr(_aot, "load_extension", lambda p: tried.append(p))
    monkeypatch.setenv("HPDOB_AOT_DIR", str(folder))
    return path, tried


@pytest.mark.parametrize(
    ("value", "on"),
    [
        ("0", False),
        ("false", False),
        ("OFF", False),
        (" no ", False),
        ("", True),
        ("1", True),
        ("true", True),
        ("garbage", True),
    ],
)
def test_hpdob_aot_turns_the_route_off_with_0_false_no_off(value, on, fake_build, monkeypatch):
    path, tried = fake_build
    monkeypatch.setenv("HPDOB_AOT", value)
    simulate(**_settings("pd"))
    assert tried == ([path] if on else [])


def test_a_folder_of_built_loops_that_is_not_one_runs_the_jit_loop(tmp_path, monkeypatch):
    """``HPDOB_AOT_DIR`` naming a file, a missing or an unreadable folder: no warning (the
    suite's warnings are errors), the JIT loop's result."""
    expected = _jit("pd", monkeypatch)
    monkeypatch.delenv("HPDOB_AOT")
    (tmp_path / "file").write_text("a file")
    unreadable = tmp_path / "unreadable"
    unreadable.mkdir(mode=0o000)
    try:
        for named in (tmp_path / "file", tmp_path / "missing", unreadable):
            monkeypatch.setenv("HPDOB_AOT_DIR", str(named))
            assert _same({k: getattr(expected, k) for k in FIELDS}, simulate(**_settings("pd")))
    finally:
        unreadable.chmod(0o700)


def test_the_name_follows_what_is_baked_into_the_source_not_the_numbers(tmp_path, monkeypatch):
    """Numbers the loop takes as arguments (gains, bandwidths, duration, the initial state)
    keep the extension's name: the loop built for one runs the other, its numbers passed in;
    what the generated source is made of (the observer's order, a sensor, a delay line)
    changes the name, so an extension is never called with another structure's arguments."""
    import hpdob.simulation._aot_build as aot_build
    from hpdob import PD
    from hpdob.observers import DisturbanceObserver

    def compile_(work, command, timeout):
        spec = json.loads((work / "spec.json").read_text())
        (work / spec["file"]).write_bytes(spec["name"].encode())

    monkeypatch.setattr(aot_build, "_compile", compile_)

    def name(**changes) -> str:
        kw = {**_settings("canonical"), **changes}
        return build_loop_extension(**kw, folder=tmp_path).name

    discrete = paper.NOMINAL.discretize(paper.TS)
    base = name()
    same = {
        "gains": name(controller=PD(kp=80.0, kd=3.0)),
        "bandwidth": name(observer=DisturbanceObserver(discrete, order=1, bandwidth=170.0).design),
        "duration": name(duration=0.25),
        "x0": name(x0=(0.1, -2.0)),
    }
    assert same == dict.fromkeys(same, base)
    other = {
        "order": name(observer=DisturbanceObserver(discrete, order=2, bandwidth=100.0).design),
        "no observer": name(observer=None),
        "encoder": name(sensor=Encoder(4096)),
        "delay": name(actuator=Actuator(delay_samples=1)),
    }
    assert len({base, *other.values()}) == 1 + len(other), other


def test_without_numba_pycc_the_build_fails_and_writes_no_extension(tmp_path, monkeypatch):
    """What the docs promise for numba releases without ``numba.pycc`` (pending deprecation):
    the build raises LoopBuildError naming it; nothing a run would load is written."""
    shadow = tmp_path / "shadow"
    shadow.mkdir()  # the build process's numba.pycc made unimportable
    (shadow / "sitecustomize.py").write_text('import sys\nsys.modules["numba.pycc"] = None\n')
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(shadow), *sys.path]))
    with pytest.raises(LoopBuildError, match=r"ModuleNotFoundError: import of numba\.pycc"):
        build_loop_extension(**_settings("pd"), folder=tmp_path / "aot", compiler="zig")
    assert not [p for p in (tmp_path / "aot").iterdir() if p.name.startswith("hpdob_aot_")]


class Subclass(np.ndarray):
    """An array subclass (numba's typeof would not type it as an array of its own)."""


def test_argument_types_are_numba_s():
    """Each argument's type as numba's dispatcher types it (``numba.typeof``); arguments it
    cannot check (the JIT loop runs them) have none."""
    import numba

    from hpdob.simulation._aot_compile import numba_type

    a = np.zeros((4, 3))
    read_only = np.zeros(5)
    read_only.flags.writeable = False
    values = [3, -(2**62), 0.5, True, np.float64(2.0), np.int64(7), np.bool_(False), a, a.T,
              a[:, 1], a[::2], read_only, np.zeros(0), np.zeros((0, 2)),
              np.zeros(3, dtype=np.int64), np.zeros(2, dtype=bool)]  # fmt: skip
    types = argument_types(values)
    assert [numba_type(t) for t in types] == [numba.typeof(v) for v in values]
    assert types[8][3] == "F" and types[9][3] == "A" and types[11][4] is True
    unaligned = np.frombuffer(bytes(33), dtype=np.uint8)[1:].view(np.float64)
    for value in (np.zeros(3, dtype=np.float32), np.zeros(3, dtype=">f8"), unaligned,
                  np.ma.zeros(3), np.zeros(3).view(Subclass), 2**63, "x", None, [1.0]):  # fmt: skip
        assert argument_types([1.0, value]) is None, value


#: A build process that starts a "compiler" of its own (a child that would run on), notes its
#: pid and waits: the stage at which a timeout or a Ctrl-C used to leave the compiler running.
HANGING_BUILD = """
import os, subprocess, sys, time
child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"])
with open(os.environ["HPDOB_TEST_PID_FILE"] + ".tmp", "w") as f:
    f.write(str(child.pid))
os.replace(os.environ["HPDOB_TEST_PID_FILE"] + ".tmp", os.environ["HPDOB_TEST_PID_FILE"])
time.sleep(600)
"""


def _running(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie no longer does: a container's init may not reap)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state not in ("Z", "X")


@pytest.mark.skipif(not Path("/proc/self/stat").exists() or os.name != "posix",
                    reason="reads process states from /proc")  # fmt: skip
@pytest.mark.parametrize("stop", ["timeout", "interrupt"])
def test_a_stopped_build_kills_its_compilers_and_leaves_no_extension(stop, tmp_path,
                                                                     monkeypatch):  # fmt: skip
    """A build stopped by its timeout or by Ctrl-C while its compiler runs: the compiler (a
    child of the build process) is killed with it, and the folder holds no extension and no
    temporary folder. The stop comes once the compiler runs (the wait for it is not timed)."""
    import hpdob.simulation._aot_build as aot_build

    (tmp_path / "hanging_build.py").write_text(HANGING_BUILD)
    pid_file = tmp_path / "compiler.pid"
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(tmp_path), *sys.path]))
    monkeypatch.setenv("HPDOB_TEST_PID_FILE", str(pid_file))
    monkeypatch.setattr(aot_build, "_BUILDER", "hanging_build")

    class Popen(subprocess.Popen):
        def communicate(self, input=None, timeout=None):
            while not pid_file.exists():
                assert self.poll() is None, "the build process ended"
                time.sleep(0.01)
            if stop == "interrupt":
                raise KeyboardInterrupt
            return super().communicate(input, timeout=0.01)

    monkeypatch.setattr(subprocess, "Popen", Popen)
    folder = tmp_path / "aot"
    expected = LoopBuildError if stop == "timeout" else KeyboardInterrupt
    with pytest.raises(expected, match="longer than timeout=30 s" if stop == "timeout" else None):
        build_loop_extension(**_settings("pd"), folder=folder, timeout=30)
    compiler = int(pid_file.read_text())
    deadline = time.monotonic() + 10  # a killed process is gone in ms; an unkilled one runs
    while _running(compiler) and time.monotonic() < deadline:
        time.sleep(0.01)
    try:
        assert not _running(compiler), "the compiler still runs"
    finally:
        if _running(compiler):
            os.kill(compiler, signal.SIGKILL)
    assert not [p.name for p in folder.iterdir() if p.name.startswith(("hpdob_aot_", ".build-"))]


@pytest.mark.parametrize(
    ("variable", "value", "matches"),
    [
        ("NUMBA_OPT", "0", False),
        ("NUMBA_LOOP_VECTORIZE", "0", False),
        ("NUMBA_BOUNDSCHECK", "1", False),
        # read by the JIT only: pycc compiles for the generic CPU (AOTCPUCodegen)
        ("NUMBA_CPU_NAME", "generic", True),
        ("NUMBA_CACHE_DIR", "elsewhere", True),
    ],
)
def test_numba_s_code_settings_are_in_the_name(variable, value, matches, fake_build,
                                               monkeypatch):  # fmt: skip
    """A run with a numba setting that changes the generated machine code (set in its
    environment) does not take a loop built without it, and a build with it gets another
    name; the settings that do not change pycc's code keep the name."""
    path, tried = fake_build
    monkeypatch.setenv(variable, value)
    if variable != "NUMBA_OPT":  # the JIT loop at another level is compiled anew (seconds)
        simulate(**_settings("pd"))
        assert tried == ([path] if matches else [])
    again = build_loop_extension(**_settings("pd"), folder=path.parent)
    assert (again == path) is matches


@pytest.mark.parametrize(
    ("text", "matches"),
    [
        ("opt: 0\n", False),
        ("boundscheck: 1\n", False),
        ("cache_dir: elsewhere\n", True),  # not a code setting
        ("", True),
        ("opt: [0\n", False),  # numba cannot read it: no build made without it is taken
    ],
)
def test_numba_s_settings_file_is_in_the_name(text, matches, tmp_path, monkeypatch):
    """numba also reads its settings from ``.numba_config.yaml`` in the working folder (under
    the environment's, which win): a loop built without the file's code settings has another
    name, and the file's ``opt: 0`` names it as ``NUMBA_OPT=0`` does."""
    pytest.importorskip("yaml")  # numba reads the file only with PyYAML
    from hpdob.simulation import _aot

    for name in _aot.CODE_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    source, types = "def loop(): pass", ("float64",)
    plain = _aot.extension_name(source, types)
    monkeypatch.chdir(tmp_path)
    (tmp_path / _aot.CONFIG_FILE).write_text(text)
    assert (_aot.extension_name(source, types) == plain) is matches


def test_the_environment_wins_over_numba_s_settings_file(tmp_path, monkeypatch):
    pytest.importorskip("yaml")
    from hpdob.simulation import _aot

    for name in _aot.CODE_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    monkeypatch.chdir(tmp_path)
    (tmp_path / _aot.CONFIG_FILE).write_text("opt: 0\nloop_vectorize: 0\n")
    settings = dict(zip(_aot.CODE_VARIABLES, _aot.code_settings(), strict=True))
    assert (settings["NUMBA_OPT"], settings["NUMBA_LOOP_VECTORIZE"]) == ("0", "0")
    monkeypatch.setenv("NUMBA_LOOP_VECTORIZE", "1")
    settings = dict(zip(_aot.CODE_VARIABLES, _aot.code_settings(), strict=True))
    assert (settings["NUMBA_OPT"], settings["NUMBA_LOOP_VECTORIZE"]) == ("0", "1")


def test_a_build_with_other_compiler_settings_replaces_the_extension(tmp_path, monkeypatch):
    """The compiler commands and setuptools' flags from the environment (``CFLAGS``, ...) are
    recorded beside the extension: building again with the same reuses it, with others
    builds it again in its place (a run finds the loop by its source and types, whatever
    compiled numba's runtime)."""
    import hpdob.simulation._aot_build as aot_build
    from hpdob.simulation import _aot

    builds = []

    def compile_(work, command, timeout):
        builds.append(command)
        spec = json.loads((work / "spec.json").read_text())
        (work / spec["file"]).write_bytes(b"built %d" % len(builds))

    monkeypatch.setattr(aot_build, "_compile", compile_)
    monkeypatch.delenv("CFLAGS", raising=False)
    folder = tmp_path / "aot"

    def build(**options):
        return build_loop_extension(**_settings("pd"), folder=folder, **options)

    first = build(compiler="gcc")
    assert build(compiler="gcc") == first and len(builds) == 1
    assert build(compiler=["gcc", "-O1"]) == first and len(builds) == 2
    assert first.read_bytes() == b"built 2" and _aot.intact(first)
    assert json.loads(_aot.recorded_build(first))["commands"] == ["gcc -O1", "gcc -O1"]
    monkeypatch.setenv("CFLAGS", "-ffast-math")
    assert build(compiler=["gcc", "-O1"]) == first and len(builds) == 3
    assert build(compiler=["gcc", "-O1"]) == first and len(builds) == 3
    assert sorted(p.name for p in folder.iterdir() if not p.name.startswith(".")) == [
        first.name,
        _aot.record_path(first).name,
    ]


def test_a_build_cleans_up_after_itself_and_after_killed_builds(tmp_path, monkeypatch):
    """What a build leaves in the folder: the extension and its record. Its lock file is
    removed (after a failed build too); a killed build's lock file and temporary folder are
    removed by the loop's next build; the kept object files of other environments (numba,
    numpy, Python versions) are removed, this environment's kept."""
    import hpdob.simulation._aot_build as aot_build
    from hpdob.simulation import _aot

    outcome = {"fail": True}

    def compile_(work, command, timeout):
        if outcome["fail"]:
            raise LoopBuildError("failed")
        spec = json.loads((work / "spec.json").read_text())
        (work / spec["file"]).write_bytes(b"built")

    monkeypatch.setattr(aot_build, "_compile", compile_)
    folder = tmp_path / "aot"
    with pytest.raises(LoopBuildError, match="failed"):
        build_loop_extension(**_settings("pd"), folder=folder)
    assert list(folder.iterdir()) == []  # no lock file, no temporary folder
    objects = aot_build._objects_folder(folder)
    (objects / "kept.o").parent.mkdir(parents=True)
    (objects / "kept.o").write_bytes(b"this environment's")
    (objects.parent / "0123456789abcdef").mkdir()
    (objects.parent / "0123456789abcdef" / "old.o").write_bytes(b"another environment's")
    (objects.parent / "loose.o").write_bytes(b"the flat layout's")
    name = _aot.extension_name(*_captured("pd"))
    killed = folder / f".build-{name}-killed"
    killed.mkdir()
    (killed / "spec.json").write_text("{}")
    (folder / f".{name}.lock").write_text("")
    other_loop = folder / ".build-hpdob_aot_000000000000000000000000-x"  # not this loop's
    other_loop.mkdir()
    outcome["fail"] = False
    path = build_loop_extension(**_settings("pd"), folder=folder)
    assert path.name == name + _aot.SUFFIX
    assert sorted(p.name for p in folder.iterdir()) == sorted(
        [path.name, _aot.record_path(path).name, ".objects", other_loop.name]
    )
    assert [p.name for p in objects.parent.iterdir()] == [objects.name]
    assert [p.name for p in objects.iterdir()] == ["kept.o"]


def _captured(name: str) -> tuple:
    """The source and argument types of run ``name``'s loop (as the build sees them)."""
    from hpdob.simulation import _aot

    seen: dict = {}
    _aot.CAPTURE.target = seen
    try:
        simulate(**_settings(name))
    except _aot.Captured:
        pass
    finally:
        _aot.CAPTURE.target = None
    return seen["source"], seen["types"]


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX: a lock file removed while held")
def test_a_lock_file_its_holder_removed_is_not_taken(tmp_path, monkeypatch):
    """A build waiting on a lock file that its holder removes on the way out (and a third
    build then creates and holds anew) must not take the removed file's lock: it locks the
    file now under the name, so the third build still excludes it."""
    import fcntl
    import threading

    import hpdob.simulation._aot_build as aot_build

    lock = tmp_path / ".loop.lock"
    first = open(lock, "ab")  # noqa: SIM115  # closed below
    fcntl.flock(first.fileno(), fcntl.LOCK_EX)
    waiting = threading.Event()

    class Clock:  # the module's time, its first sleep telling that the waiter waits
        monotonic = staticmethod(time.monotonic)

        @staticmethod
        def sleep(seconds):
            waiting.set()
            time.sleep(seconds)

    monkeypatch.setattr(aot_build, "time", Clock)
    outcome = []

    def wait_for_the_lock():
        try:
            with aot_build._exclusive(lock, timeout=1.0):
                outcome.append("held")
        except LoopBuildError as error:
            outcome.append(str(error))

    waiter = threading.Thread(target=wait_for_the_lock)
    waiter.start()
    try:
        assert waiting.wait(60)
        lock.unlink()  # the first build ends: removes its lock file while holding it ...
        third = open(lock, "ab")  # noqa: SIM115  # ... a third creates a new one and holds it
        fcntl.flock(third.fileno(), fcntl.LOCK_EX)
        first.close()  # ... and the first's lock is released
        waiter.join(60)
    finally:
        first.close()
    assert len(outcome) == 1 and "for longer than timeout=1 s" in outcome[0], outcome
    third.close()


@pytest.mark.skipif(sys.platform == "win32", reason="the stand-in locks with fcntl")
def test_without_fcntl_builds_take_turns_on_msvcrt_locking(tmp_path, monkeypatch):
    """Where there is no ``fcntl`` (Windows), a build locks its lock file's first byte with
    ``msvcrt.locking`` (here a stand-in doing the same with ``flock``): it waits for another
    holder at most ``timeout``, and unlocks and removes the file after its build."""
    import fcntl
    import types

    import hpdob.simulation._aot_build as aot_build

    calls = []

    def locking(fd, mode, nbytes):
        calls.append((mode, nbytes, os.lseek(fd, 0, os.SEEK_CUR)))
        if mode == 2:  # LK_NBLCK: OSError(EACCES) if held elsewhere, as msvcrt's
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                raise PermissionError(13, "Permission denied") from None
        else:
            fcntl.flock(fd, fcntl.LOCK_UN)

    msvcrt = types.SimpleNamespace(locking=locking, LK_NBLCK=2, LK_UNLCK=0)
    monkeypatch.setitem(sys.modules, "fcntl", None)  # import fcntl: ImportError
    monkeypatch.setitem(sys.modules, "msvcrt", msvcrt)
    names = []

    def compile_(work, command, timeout):
        spec = json.loads((work / "spec.json").read_text())
        names.append(spec["name"])
        (work / spec["file"]).write_bytes(b"built")

    monkeypatch.setattr(aot_build, "_compile", compile_)
    folder = tmp_path / "aot"
    name = _aot_name("pd")
    folder.mkdir()
    with open(folder / f".{name}.lock", "ab") as held:  # another build holds the lock
        fcntl.flock(held.fileno(), fcntl.LOCK_EX)
        with pytest.raises(LoopBuildError, match=r"held .* for longer than timeout=0\.2 s"):
            build_loop_extension(**_settings("pd"), folder=folder, timeout=0.2)
    assert names == [] and {mode for mode, _, _ in calls} == {2}
    calls.clear()
    path = build_loop_extension(**_settings("pd"), folder=folder)
    assert names == [name] and path.is_file()
    assert calls == [(2, 1, 0), (0, 1, 0)]  # the first byte locked, then unlocked
    assert not (folder / f".{name}.lock").exists()


def _aot_name(name: str) -> str:
    from hpdob.simulation import _aot

    return _aot.extension_name(*_captured(name))
