"""Mutation testing of the GENERATED closed-loop sample loop with cosmic-ray (docs/testing.md).

The sample loop is Python source written per run structure by ``hpdob.simulation._kernel``
(``loop_source``); its arithmetic is text in the generator's string templates, which
``benchmarks/mutation.py`` (mutating the generator's own AST) never mutates. This script
mutates the generated loops themselves:

1. ``--materialise`` runs the kernel's tests once with a recording plugin (this module, loaded
   with ``pytest -p mutation_kernel``) that notes every structure ``sample_loop`` is asked for,
   its source and the tests that ran it; one structure per kind below (the one most tests run)
   is written as a real module ``<workdir>/loops/<loop_key>.py``.
2. cosmic-ray mutates those files in place; each mutant's test command is the pytest node ids
   that ran that structure, with ``HPDOB_MUTATION_LOOPS=<workdir>/loops`` (the test-only
   override of ``sample_loop``: a structure with a file there runs that file's loop, compiled
   from memory, so numba never loads machine code of an older mutant from its disk cache).

Run with (the ``mutation`` extra installs cosmic-ray)

    python benchmarks/mutation_kernel.py --materialise
    python benchmarks/mutation_kernel.py --total 90 --seed 1   # stratified over the structures
    python benchmarks/mutation_kernel.py --planted             # issue 20's generic-friction bug
    python benchmarks/mutation_kernel.py --rerun-survivors     # after a test was added
    python benchmarks/mutation_kernel.py --report

The sample of each structure is the first N of a seeded permutation of its mutants (a larger
``--total`` with the same seed extends it), N in proportion to its mutant count
(``mutation.allocate``). Survivors are classified in ``benchmarks/mutation_survivors.toml`` with
``path = "loop:<kind>"``. Sessions live in ``<workdir>/sessions`` named by the kind and the hash
of the materialised source (a changed generator gives a new session).
"""

from __future__ import annotations

import argparse
import fcntl
import hashlib
import json
import os
import shlex
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RECORD_VARIABLE = "HPDOB_RECORD_LOOPS"
OVERRIDE_VARIABLE = "HPDOB_MUTATION_LOOPS"  # hpdob.simulation._kernel.OVERRIDE_VARIABLE

#: The test files that run the kernel's structures (fast ones; the recording picks, per
#: structure, the node ids among them that ran it).
TESTS = (
    "tests/simulation/test_kernel_mutants.py",
    "tests/simulation/test_kernel.py",
    "tests/models/test_plant.py",
    "tests/models/test_environment.py",
    "tests/models/test_two_mass.py",
    "tests/simulation/test_simulate.py",
    "tests/controllers/test_force.py",
    "tests/controllers/test_switching.py",
)

#: Tests of the cache, not of the loop, that fail by design under the override (its loop is
#: compiled from memory): never in a structure's command.
EXCLUDE = (
    "tests/simulation/test_kernel.py::test_kernel_is_numba_compiled_with_cache",
    "tests/simulation/test_kernel.py::test_generated_source_is_kept_under_the_cache_directory",
)

#: At most this many other structures tried per survivor (``--siblings``).
SIBLINGS = 5

#: At most this many node ids per structure: a surviving mutant runs them all.
MAX_TESTS = 12


def _describe(structure) -> dict:
    from hpdob.simulation import _kernel

    path, nx, _, _, wall, mode, noisy, observer, controller, midpoint = structure
    names = {
        _kernel.PATH_RIGID: "rigid", _kernel.PATH_TWO_MASS: "two-mass",
        _kernel.PATH_GENERIC: "generic", _kernel.PATH_PYTHON: "python",
    }  # fmt: skip
    return {
        "path": names.get(path, str(path)),
        "nx": int(nx),
        "wall": bool(wall),
        "sensor": int(mode),
        "noise": bool(noisy),
        "observer": None if observer is None else int(observer[0]),
        "rtob": observer is not None and bool(observer[5] or observer[4] > 0),
        "switch": controller[6] is not None,
        "table": midpoint is not None,
    }


#: Where a kind's structure is chosen by the tests of one file (or node id prefix) first, then
#: by the number of tests that run it: the generic path's own checks (tests/models/test_plant.py)
#: against the rigid servo's path near rest (where ``tanh`` is not saturated: issue 20's planted
#: bug) and against the exact ZOH recurrence of a three-state plant.
PREFERRED = {
    "generic": "tests/models/test_plant.py::test_generic_path_runs_the_rigid",
    "generic-3-states": "tests/models/test_plant.py::test_generic_path_is_exact_zoh",
}


#: Tests added by hand to a kind's recorded ones: a structure first run while a shared fixture
#: was set up is recorded for the test that requested the fixture first, not for the tests that
#: check its result (``canonical_results`` of test_simulate.py runs every canonical run).
EXTRA = {
    "rigid-encoder-observer": (
        "tests/simulation/test_simulate.py::test_agrees_with_reference_loop",
        "tests/simulation/test_simulate.py::test_agrees_with_reference_loop_noise_delay_saturation",
    ),
}


#: The representative structures: a kind and what its structure must be.
def _kinds() -> dict:
    return {
        "rigid-encoder-observer": lambda d: d["path"] == "rigid" and not d["wall"]
        and d["sensor"] != 0 and d["observer"] is not None and not d["rtob"]
        and not d["switch"],
        "two-mass": lambda d: d["path"] == "two-mass" and not d["switch"],
        "generic": lambda d: d["path"] == "generic" and d["nx"] == 2 and not d["switch"],
        "generic-3-states": lambda d: d["path"] == "generic" and d["nx"] == 3,
        "wall-rtob": lambda d: d["wall"] and d["rtob"] and not d["switch"],
        "switch": lambda d: d["switch"],
    }  # fmt: skip


# ---------------------------------------------------------------------------------------------
# The recording plugin (pytest -p mutation_kernel, with HPDOB_RECORD_LOOPS set)


def pytest_configure(config):
    directory = os.environ.get(RECORD_VARIABLE)
    if not directory:
        return
    from hpdob.simulation import _kernel

    original = _kernel.sample_loop
    seen: dict = {}

    def recording(structure):
        key = _kernel.loop_key(structure)
        if key not in seen:
            seen[key] = {
                "describe": _describe(structure), "source": _kernel.loop_source(structure),
                "tests": [],
            }  # fmt: skip
        test = os.environ.get("PYTEST_CURRENT_TEST", "").rsplit(" ", 1)[0]
        if test and test not in seen[key]["tests"] and test not in EXCLUDE:
            seen[key]["tests"].append(test)
        return original(structure)

    recording.cache_clear = original.cache_clear
    recording.cache_info = original.cache_info
    _kernel.sample_loop = recording
    config._hpdob_recorded = (Path(directory), seen)


def pytest_unconfigure(config):
    recorded = getattr(config, "_hpdob_recorded", None)
    if recorded is not None:
        directory, seen = recorded
        (directory / "recorded.json").write_text(json.dumps(seen, indent=1))


# ---------------------------------------------------------------------------------------------


def _env(workdir: Path, **extra) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src"), str(ROOT / "benchmarks")])
    env[OVERRIDE_VARIABLE] = str(workdir / "loops")
    env.update(extra)
    return env


def materialise(workdir: Path) -> dict:
    """Record the structures the kernel's tests run; write one per kind as a module."""
    workdir.mkdir(parents=True, exist_ok=True)
    tests = [t for t in TESTS if (ROOT / t).is_file()]
    env = _env(workdir, **{RECORD_VARIABLE: str(workdir)})
    env.pop(OVERRIDE_VARIABLE)
    command = [sys.executable, "-m", "pytest", "-n", "0", "-q", "-p", "no:cacheprovider",
               "-p", "mutation_kernel", *tests]  # fmt: skip
    run = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True)
    if run.returncode != 0:
        raise SystemExit(f"the unmutated tests fail:\n{run.stdout[-3000:]}")
    seen = json.loads((workdir / "recorded.json").read_text())
    loops = workdir / "loops"
    loops.mkdir(exist_ok=True)
    for old in loops.glob("*.py"):
        old.unlink()
    chosen = {}
    for kind, wanted in _kinds().items():
        preferred = PREFERRED.get(kind, "\0")
        matching = [
            (sum(t.startswith(preferred) for t in v["tests"]), len(v["tests"]), k)
            for k, v in seen.items()
            if wanted(v["describe"])
        ]
        if not matching:
            print(f"{kind}: no test runs such a structure")
            continue
        *_, key = max(matching)
        entry = seen[key]
        (loops / f"{key}.py").write_text(entry["source"])
        chosen[kind] = {
            "key": key, "sha": hashlib.sha256(entry["source"].encode()).hexdigest()[:12],
            "describe": entry["describe"], "all_tests": len(entry["tests"]),
            "tests": list(dict.fromkeys([*entry["tests"][:MAX_TESTS], *EXTRA.get(kind, ())])),
        }  # fmt: skip
        print(f"{kind}: {key} {entry['describe']}, {len(entry['tests'])} tests")
    # Kinds whose structures generate the same text (the generic path's source does not depend
    # on the state size) are one file: the later ones' files link to it, so a mutant is run by
    # the tests of both structures.
    for kind, entry in list(chosen.items()):
        first = next(k for k, e in chosen.items() if e["sha"] == entry["sha"])
        if first != kind:
            (loops / f"{entry['key']}.py").unlink()
            (loops / f"{entry['key']}.py").symlink_to(f"{chosen[first]['key']}.py")
            chosen[first]["tests"] = list(dict.fromkeys([*chosen[first]["tests"], *entry["tests"]]))
            chosen[first].setdefault("also", []).append(entry["key"])
            del chosen[kind]
    (workdir / "structures.json").write_text(json.dumps(chosen, indent=1))
    return chosen


def _structures(workdir: Path) -> dict:
    path = workdir / "structures.json"
    if not path.exists():
        raise SystemExit("no structures: run with --materialise first")
    return json.loads(path.read_text())


def test_command(tests, timeout: float) -> str:
    return shlex.join([sys.executable, "-m", "pytest", "-n", "0", "-x", "-q", "-p",
                       "no:cacheprovider", f"--timeout={int(timeout)}", *tests])  # fmt: skip


def _session(workdir: Path, kind: str, entry: dict) -> tuple[Path, Path]:
    # the recorded source's hash, not the file's: the file holds a mutant while a job runs
    stem = f"{kind}-{entry['sha']}"
    return workdir / "sessions" / f"{stem}.toml", workdir / "sessions" / f"{stem}.sqlite"


def _mutants(path: Path) -> list:
    import tempfile

    from cosmic_ray.commands.init import init
    from cosmic_ray.work_db import WorkDB, use_db
    from mutation import _ordered

    with (
        tempfile.TemporaryDirectory() as scratch,
        use_db(str(Path(scratch) / "all.sqlite"), WorkDB.Mode.create) as db,
    ):
        init([path], db, {})
        return _ordered(db.work_items)


def prepare(workdir: Path, kind: str, entry: dict, *, sample: int | None, seed: int,
            add: bool = True) -> tuple[Path, Path]:  # fmt: skip
    from cosmic_ray.work_db import WorkDB, use_db
    from mutation import _key, sample_mutants

    config_path, session = _session(workdir, kind, entry)
    config_path.parent.mkdir(parents=True, exist_ok=True)
    sidecar = session.with_suffix(".json")
    path = workdir / "loops" / f"{entry['key']}.py"
    if sidecar.exists():
        timeout = json.loads(sidecar.read_text())["timeout"]
    else:
        start = time.perf_counter()
        baseline = subprocess.run(shlex.split(test_command(entry["tests"], 600)), cwd=ROOT,
                                  env=_env(workdir), capture_output=True, text=True)  # fmt: skip
        seconds = time.perf_counter() - start
        if baseline.returncode != 0:
            raise SystemExit(f"{kind}: the unmutated tests fail:\n{baseline.stdout[-3000:]}")
        timeout = round(3.0 * seconds + 30.0)
        print(f"{kind}: baseline passed in {seconds:.1f} s, timeout {timeout} s")
    config_path.write_text(
        "[cosmic-ray]\n"
        f"module-path = {json.dumps(str(path))}\n"
        f"timeout = {timeout}\n"
        "excluded-modules = []\n"
        f"test-command = {json.dumps(test_command(entry['tests'], timeout))}\n"
        "\n[cosmic-ray.distributor]\n"
        'name = "local"\n'
    )
    items = _mutants(path)
    sidecar.write_text(json.dumps({"mutants": len(items), "seed": seed, "timeout": timeout}))
    chosen = sample_mutants(items, [], sample=sample, seed=seed)
    with use_db(str(session), WorkDB.Mode.create) as db:
        known = {_key(w) for w in db.work_items}
        if add:
            db.add_work_items([w for w in chosen if _key(w) not in known])
        pending = db.num_work_items - db.num_results
    print(f"{kind}: {len(items)} mutants, {len(chosen)} sampled (seed {seed}), {pending} to run")
    return config_path, session


def execute(workdir: Path, config_path: Path, session: Path) -> None:
    cosmic_ray = str(Path(sys.executable).with_name("cosmic-ray"))
    subprocess.run(["nice", "-n", "19", cosmic_ray, "exec", str(config_path), str(session)],
                   cwd=ROOT, env=_env(workdir), check=True)  # fmt: skip


def _verdict(kind: str, result) -> dict | None:
    from mutation import _changed_lines, _classified

    old, new = _changed_lines(result.diff or "")
    for entry in _classified():
        if (entry["path"], entry["original"], entry["mutated"]) == (f"loop:{kind}", old, new):
            return entry
    return None


def rerun_survivors(workdir: Path, kind: str, config_path: Path, session: Path) -> None:
    from cosmic_ray.config import load_config
    from cosmic_ray.mutating import mutate_and_test
    from cosmic_ray.work_db import use_db
    from cosmic_ray.work_item import TestOutcome
    from mutation import _key_text

    config = load_config(str(config_path))
    os.environ.update(_env(workdir))
    os.chdir(ROOT)
    with use_db(str(session)) as db:
        survivors = [item for item, result in db.completed_work_items
                     if result.test_outcome == TestOutcome.SURVIVED
                     and _verdict(kind, result) is None]  # fmt: skip
        first_path = session.with_suffix(".first-pass.json")
        first = set(json.loads(first_path.read_text())) if first_path.exists() else set()
        first |= {_key_text(item) for item in survivors}
        first_path.write_text(json.dumps(sorted(first), indent=1))
        for item in survivors:
            result = mutate_and_test(item.mutations, config.test_command, config.timeout)
            db.set_result(item.job_id, result)
            print(f"  {kind}:{item.mutations[0].start_pos[0]}: {result.test_outcome}")


def report(workdir: Path) -> dict:
    from cosmic_ray.work_db import WorkDB, use_db
    from cosmic_ray.work_item import TestOutcome, WorkerOutcome
    from mutation import _changed_lines, _key_text, jeffreys_interval, stratified_estimate

    sibling_path = workdir / "siblings.json"
    sibling = json.loads(sibling_path.read_text()) if sibling_path.exists() else {}
    modules = {}
    for kind, entry in _structures(workdir).items():
        _, session = _session(workdir, kind, entry)
        if not session.exists():
            continue
        sidecar = json.loads(session.with_suffix(".json").read_text())
        first_path = session.with_suffix(".first-pass.json")
        first = set(json.loads(first_path.read_text())) if first_path.exists() else set()
        counts = dict.fromkeys(
            ["killed", "survived", "incompetent", "timeout", "no-test", "killed_on_rerun"], 0
        )
        survivors = []
        with use_db(str(session), WorkDB.Mode.open) as db:
            for item, result in db.completed_work_items:
                line = item.mutations[0].start_pos[0]
                old, new = _changed_lines(result.diff or "")
                if result.worker_outcome == WorkerOutcome.NO_TEST:
                    counts["no-test"] += 1
                elif result.test_outcome == TestOutcome.INCOMPETENT:
                    counts["incompetent"] += 1
                elif result.test_outcome == TestOutcome.SURVIVED:
                    counts["survived"] += 1
                    verdict = _verdict(kind, result)
                    other = sibling.get(f"loop:{kind}:{line}|{new}", {})
                    if verdict is None and other.get("outcome") == "killed":
                        reason = f"{other['structure']}: {other['failed']}"
                        verdict = {"class": "killed in another structure", "reason": reason}
                    survivors.append({
                        "where": f"loop:{kind}:{line}", "operator": item.mutations[0].operator_name,
                        "original": old, "mutated": new,
                        "class": verdict["class"] if verdict else "unclassified",
                        "reason": verdict["reason"] if verdict else "",
                    })  # fmt: skip
                elif result.output == "timeout":
                    counts["timeout"] += 1
                else:
                    counts["killed"] += 1
                    if _key_text(item) in first:
                        counts["killed_on_rerun"] += 1
                        survivors.append({
                            "where": f"loop:{kind}:{line}",
                            "operator": item.mutations[0].operator_name,
                            "original": old, "mutated": new, "class": "killed on re-run",
                            "reason": "a test added after the first pass",
                        })  # fmt: skip
            sampled = db.num_work_items
        judged = counts["killed"] + counts["timeout"] + counts["survived"]
        equivalent = sum(s["class"] == "equivalent" for s in survivors)
        killed = counts["killed"] + counts["timeout"]
        elsewhere = sum(s["class"] == "killed in another structure" for s in survivors)
        modules[kind] = {
            "key": entry["key"], "tests": len(entry["tests"]), "mutants": sidecar["mutants"],
            "sampled": sampled, **counts, "equivalent": equivalent,
            "killed_in_another_structure": elsewhere,
            "kill_rate_with_other_structures": (killed + elsewhere) / (judged - equivalent)
            if judged > equivalent else None,
            "kill_rate_non_equivalent": killed / (judged - equivalent) if judged > equivalent
            else None,
            "interval_95": list(jeffreys_interval(killed, judged - equivalent)),
            "survivors": survivors,
        }  # fmt: skip
    return {"modules": modules, "total": stratified_estimate(modules),
            "first_pass": stratified_estimate(modules, first_pass=True)}  # fmt: skip


def siblings(workdir: Path) -> dict:
    """Try each unclassified survivor's change in the other recorded structures.

    The generator writes one line into many structures' loops, and a structure's own tests are
    few: a survivor's line is replaced the same way in every other recorded structure whose
    loop has it once, and that structure's tests are run with it. Killed there means the suite
    catches the change of the generator's text (counted apart in the report).
    """
    import tempfile

    recorded = json.loads((workdir / "recorded.json").read_text())
    found, passes = {}, {}

    def run_tests(key, source):
        with tempfile.TemporaryDirectory() as scratch:
            (Path(scratch) / f"{key}.py").write_text(source)
            tests = [t for t in recorded[key]["tests"] if t not in EXCLUDE][:MAX_TESTS]
            return subprocess.run(
                shlex.split(test_command(tests, 600)), cwd=ROOT,
                env=_env(workdir, **{OVERRIDE_VARIABLE: scratch}), capture_output=True, text=True,
            )  # fmt: skip

    for kind, module in report(workdir)["modules"].items():
        own = {module["key"], *_structures(workdir)[kind].get("also", ())}
        for survivor in module["survivors"]:
            if survivor["class"] != "unclassified" or " / " in survivor["original"]:
                continue
            verdict = {"outcome": "survived", "tried": 0}
            # the structures most tests run first, at most SIBLINGS of them
            for key, entry in sorted(recorded.items(), key=lambda e: -len(e[1]["tests"])):
                if verdict["tried"] == SIBLINGS:
                    break
                lines = entry["source"].splitlines(keepends=True)
                at = [i for i, line in enumerate(lines) if line.strip() == survivor["original"]]
                usable = [t for t in entry["tests"] if t not in EXCLUDE]
                if key in own or len(at) != 1 or not usable:
                    continue
                indent = lines[at[0]][: len(lines[at[0]]) - len(lines[at[0]].lstrip())]
                lines[at[0]] = indent + survivor["mutated"] + "\n"
                verdict["tried"] += 1
                run = run_tests(key, "".join(lines))
                if run.returncode != 0 and key not in passes:  # the unmutated loop passes?
                    passes[key] = run_tests(key, entry["source"]).returncode == 0
                if run.returncode != 0 and passes[key]:
                    failed = [x for x in run.stdout.splitlines() if x.startswith("FAILED")]
                    verdict = {"outcome": "killed", "structure": key, "failed": failed[:1]}
                    break
            found[f"{survivor['where']}|{survivor['mutated']}"] = verdict
            print(f"  {survivor['where']} {survivor['mutated']}: {verdict}")
    (workdir / "siblings.json").write_text(json.dumps(found, indent=1))
    return found


def run_planted(workdir: Path) -> dict:
    """Issue 20's planted bug (the generic path's friction doubled) in the generic loop."""
    from mutation import PLANTED

    planted = PLANTED["kernel-generic-friction-doubled"]
    entry = _structures(workdir)["generic"]
    path = workdir / "loops" / f"{entry['key']}.py"
    source = path.read_text()
    if source.count(planted.original) != 1:
        return {"outcome": "not applicable: the line is not once in the generic loop"}
    try:
        path.write_text(source.replace(planted.original, planted.mutated))
        run = subprocess.run(shlex.split(test_command(entry["tests"], 600)), cwd=ROOT,
                             env=_env(workdir), capture_output=True, text=True)  # fmt: skip
    finally:
        path.write_text(source)
    failed = [line for line in run.stdout.splitlines() if line.startswith("FAILED")]
    return {"outcome": "killed" if run.returncode else "survived", "failed": failed}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--materialise", action="store_true")
    parser.add_argument("--kinds", nargs="+", default=None, help="structures to run (default all)")
    parser.add_argument("--total", type=int, default=None, help="mutants over all structures")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--workdir", type=Path, default=ROOT / ".mutation" / "kernel")
    parser.add_argument("--planted", action="store_true")
    parser.add_argument("--rerun-survivors", action="store_true")
    parser.add_argument(
        "--siblings",
        action="store_true",
        help="try each survivor's change in the other recorded structures",
    )
    parser.add_argument("--report", action="store_true")
    args = parser.parse_args(argv)
    sys.path.insert(0, str(ROOT / "benchmarks"))
    sys.path.insert(0, str(ROOT / "src"))
    args.workdir.mkdir(parents=True, exist_ok=True)
    lock = (args.workdir / "lock").open("w")
    try:  # one run at a time: a second one would restore the first one's mutant
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        parser.error(f"another run holds {args.workdir / 'lock'}")
    os.nice(19)
    if args.materialise:
        materialise(args.workdir)
    structures = _structures(args.workdir)
    kinds = args.kinds or list(structures)
    if args.total is not None or args.rerun_survivors:
        from mutation import allocate

        sizes = {k: len(_mutants(args.workdir / "loops" / f"{structures[k]['key']}.py"))
                 for k in kinds}  # fmt: skip
        samples = allocate(args.total, sizes) if args.total else dict.fromkeys(kinds)
        for kind in kinds:
            config_path, session = prepare(args.workdir, kind, structures[kind],
                                           sample=samples[kind], seed=args.seed,
                                           add=not args.rerun_survivors)  # fmt: skip
            if args.rerun_survivors:
                rerun_survivors(args.workdir, kind, config_path, session)
            else:
                execute(args.workdir, config_path, session)
    if args.planted:
        result = run_planted(args.workdir)
        (args.workdir / "planted.json").write_text(json.dumps(result, indent=2))
        print("kernel-generic-friction-doubled (generated generic loop):", result["outcome"],
              *result.get("failed", []))  # fmt: skip
    if args.siblings:
        siblings(args.workdir)
    if args.report:
        result = report(args.workdir)
        (args.workdir / "report.json").write_text(json.dumps(result, indent=2))
        print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
