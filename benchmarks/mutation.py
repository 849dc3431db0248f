"""Mutation testing of the numerical core with cosmic-ray (docs/testing.md).

Run with (the ``mutation`` extra installs cosmic-ray)

    python benchmarks/mutation.py --modules observers.synthesis identification.regression \
        --sample 20 --seed 1
    python benchmarks/mutation.py --report

Each module of the numerical core is paired with the FEW test files that exercise it, so one
mutant costs one short pytest run, not the suite. cosmic-ray mutates the source on disk; this
script never lets it touch the checkout: the tracked and untracked-but-not-ignored files are
copied to ``<workdir>/tree`` (default ``.mutation/``, git-ignored) at the start of every run,
which also undoes a mutant left behind by an interrupted run. Because the mutant is written to
the file, numba's on-disk cache sees a new source stamp and recompiles the mutated kernel; this
is why cosmic-ray, not mutmut 3, is used (mutmut's trampolines cannot run inside numba-jitted
functions).

The full set is thousands of mutants at seconds each, so ``--sample N --seed S`` runs the first
N mutants of a seeded random permutation of each module's mutants (a larger N with the same seed
extends the same sample), less those inside annotations (never evaluated: every module has
``from __future__ import annotations``, so they are equivalent by construction). One cosmic-ray
session (config + sqlite) per module and source hash lives in ``<workdir>/sessions``; a
changed module starts a new session, an unchanged one resumes. The jobs run one after another
under ``nice -n 19`` (the machine is shared).

``--report`` prints, and writes as JSON and Markdown to ``<workdir>/report.{json,md}``, the kill
rate per module and every survivor with file:line, operator and the mutated line. Survivors
classified in ``benchmarks/mutation_survivors.toml`` (equivalent, or accepted, with the reason)
are counted apart: the target is >= 90 % of the non-equivalent mutants killed.
``--rerun-survivors`` runs the surviving mutants again (after a test was added to kill them).
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import fcntl
import hashlib
import json
import math
import os
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

ROOT = Path(__file__).resolve().parent.parent
CLASSIFIED = ROOT / "benchmarks" / "mutation_survivors.toml"
ANNOTATION = "inside an annotation, never evaluated (from __future__ import annotations)"
# -n 0: one process (the suite's addopts spread it over workers; a mutant's run stays short)
PYTEST = "-m pytest -n 0 -x -q -p no:cacheprovider --hypothesis-seed=0 --timeout={timeout}"


@dataclasses.dataclass(frozen=True)
class Target:
    """One module of the numerical core and the fast tests that exercise it."""

    path: str
    tests: tuple[str, ...]
    select: str = ""  # a pytest -k expression that leaves out the slow, unrelated tests


# The files of each command are the fewest fast ones that exercise the module, fastest first:
# with -x a killed mutant stops at the first failing test (unmutated run times on the shared
# machine in docs/testing.md). tests/<subpackage>/test_<module>_mutants.py runs first.
TARGETS = {
    "analysis.describing": Target(
        "src/hpdob/analysis/_describing.py",
        (
            "tests/analysis/test_describing_mutants.py",
            "tests/analysis/test_describing.py",
            "tests/analysis/test_contact_limit_cycle.py",
        ),
    ),
    "observers.synthesis": Target(
        "src/hpdob/observers/_synthesis.py",
        ("tests/observers/test_core.py", "tests/observers/test_synthesis.py"),
    ),
    "observers.position": Target(
        "src/hpdob/observers/_position.py", ("tests/observers/test_position.py",)
    ),
    "observers.eso": Target(
        "src/hpdob/observers/_eso.py",
        ("tests/observers/test_eso.py", "tests/observers/test_peers.py"),
        "eso or ESO or Eso",
    ),
    "observers.kalman": Target(
        "src/hpdob/observers/_kalman.py",
        ("tests/observers/test_kalman.py", "tests/observers/test_peers.py"),
        "kalman or Kalman",
    ),
    "observers.program": Target(
        "src/hpdob/observers/_program.py",
        (
            "tests/observers/test_core.py",
            "tests/observers/test_program.py",
            "tests/observers/test_system.py",
        ),
    ),
    "observers.system": Target(
        "src/hpdob/observers/_system.py",
        ("tests/observers/test_core.py", "tests/observers/test_system.py"),
    ),
    "observers.core": Target(
        "src/hpdob/observers/_core.py",
        ("tests/observers/test_core.py", "tests/observers/test_runtime.py"),
    ),
    "observers.runtime": Target(
        "src/hpdob/observers/_runtime.py",
        ("tests/observers/test_runtime.py", "tests/observers/test_core.py"),
    ),
    "observers.realised": Target(
        # test_synthesis.py: the state-measuring order-m designs check their realised poles too
        "src/hpdob/observers/_realised.py",
        ("tests/observers/test_realised.py", "tests/observers/test_synthesis.py"),
    ),
    "observers.error_dynamics": Target(
        "src/hpdob/observers/_error_dynamics.py",
        ("tests/observers/test_synthesis.py", "tests/observers/test_realised.py"),
    ),
    "observers.poles": Target(
        "src/hpdob/observers/_poles.py",
        ("tests/observers/test_synthesis.py", "tests/observers/test_realised.py"),
    ),
    "observers.response": Target(
        "src/hpdob/observers/_response.py",
        # test_position.py: the factored response with zeros (position-only designs)
        (
            "tests/observers/test_statespace.py",
            "tests/observers/test_system.py",
            "tests/observers/test_position.py",
        ),
    ),
    "observers.reaction": Target(
        # the composition as a design (test_reaction_design.py) and its Coulomb term with the
        # velocity filter (test_friction.py), then the force loop's RTOB tests
        "src/hpdob/observers/_reaction.py",
        (
            "tests/observers/test_reaction_design.py",
            "tests/observers/test_friction.py",
            "tests/controllers/test_force.py",
        ),
        "rtob or reac or bad_inputs or friction or design or replace_pickle",
    ),
    "observers.external": Target(
        "src/hpdob/observers/_external.py",
        ("tests/models/test_lti.py", "tests/robots/test_external.py"),
        "derived_reset or pyadrc or place_design or test_external",
    ),
    "observers.friction": Target(
        "src/hpdob/observers/_friction.py",
        (
            "tests/observers/test_friction_mutants.py",
            "tests/observers/test_friction.py",
            "tests/observers/test_friction_deadband.py",
        ),
    ),
    "models.servo": Target("src/hpdob/models/_servo.py", ("tests/models/test_servo.py",)),
    "models.two_mass": Target("src/hpdob/models/_two_mass.py", ("tests/models/test_two_mass.py",)),
    "models.plant": Target(
        "src/hpdob/models/_plant.py",
        (
            "tests/models/test_plant.py",
            "tests/models/test_servo.py",
            "tests/models/test_two_mass.py",
        ),
    ),
    "models.lti": Target("src/hpdob/models/_lti.py", ("tests/models/test_lti.py",)),
    "models.environment": Target(
        "src/hpdob/models/_environment.py", ("tests/models/test_environment.py",)
    ),
    "models.contact": Target(
        "src/hpdob/models/_contact.py",
        ("tests/models/test_environment.py", "tests/controllers/test_force.py"),
    ),
    "simulation.kernel": Target(
        "src/hpdob/simulation/_loop_source.py",
        # the generator of the sample loop (issue 25; numba-free since the ahead-of-time
        # route, its helpers stay in _kernel.py): its Python is mutated (which lines it
        # writes for which structure); the loop's arithmetic is text in it, which cosmic-ray
        # does not mutate (the planted bugs below edit that text). A rigid, a two-mass and a
        # generic sub-step path: tests for each (test_plant.py reaches the generic one), the
        # contact force (rigid and two-mass load) and the force loop (issue 21). A mutant
        # changes the generated source, so numba compiles it anew (docs/testing.md).
        (
            "tests/simulation/test_signal_table.py",
            "tests/models/test_plant.py",
            "tests/models/test_environment.py",
            "tests/models/test_two_mass.py",
            "tests/simulation/test_kernel.py",
            "tests/simulation/test_simulate.py",
            "tests/controllers/test_force.py",
        ),
    ),
    "simulation.signal_table": Target(
        "src/hpdob/simulation/_signal_table.py",
        ("tests/simulation/test_signal_table.py", "tests/simulation/test_kernel.py"),
    ),
    "signals": Target(
        # the built-in signals and their sums (a Sum skips terms silent over the grid: the
        # bit-for-bit comparison with every term added catches a wrong silence)
        "src/hpdob/_signals.py",
        ("tests/simulation/test_signals.py", "tests/simulation/test_signal_table.py"),
    ),
    "analysis.noise": Target(
        # the noise gains' Lyapunov solve (scipy's numbers bit for bit) and the gains
        "src/hpdob/analysis/_noise.py",
        ("tests/analysis/test_noise.py",),
    ),
    "identification.regression": Target(
        "src/hpdob/identification/_regression.py",
        (
            # the block-wise paths (several blocks only on logs longer than _lean.BLOCK)
            "tests/identification/test_lean.py",
            "tests/identification/test_regression.py",
            "tests/identification/test_identify.py",
            "tests/identification/test_identify_defaults.py",
        ),
        "not example_prints and not plot_labels and not result_exports",
    ),
    "identification.design": Target(
        # the check's own tests (block-wise condition and VIF), then the refusals it makes
        # through identify (one-way logs, one speed, several logs)
        "src/hpdob/identification/_design.py",
        (
            "tests/identification/test_design_check.py",
            "tests/identification/test_identify_logs.py",
            "tests/identification/test_identify.py",
        ),
        "not example_prints and not plot_labels and not result_exports",
    ),
    "identification.solve": Target(
        # the covariance's closed forms, then least squares and the IV iteration (through
        # the logged loop and input-driven) via identify
        "src/hpdob/identification/_solve.py",
        (
            "tests/identification/test_solve.py",
            "tests/identification/test_identify.py",
            "tests/identification/test_identify_logs.py",
        ),
        "not example_prints and not plot_labels and not result_exports",
    ),
    "identification.lean": Target(
        # the kernels' own tests (block-wise filtfilt, gradient, decimation, Welch), then the
        # regression and the solver that call them
        "src/hpdob/identification/_lean.py",
        (
            "tests/identification/test_lean.py",
            "tests/identification/test_regression.py",
            "tests/identification/test_solve.py",
        ),
    ),
    "identification.sos_kernel": Target(
        # scipy's sosfilt recurrence compiled in place (issue 25): its bit-for-bit tests
        # against sosfilt/sosfiltfilt and its shape refusals, then the filters that call it
        "src/hpdob/identification/_sos_kernel.py",
        ("tests/identification/test_lean.py", "tests/identification/test_regression.py"),
    ),
    "identification.estimate_kernel": Target(
        # the offline loop's generator: the estimate against the runtime object and the
        # closed loop, the streamed estimate, the program's rows written out
        "src/hpdob/identification/_estimate_kernel.py",
        (
            "tests/identification/test_estimate.py",
            "tests/identification/test_stream.py",
            "tests/observers/test_program.py",
        ),
    ),
    "simulation.row_kernel": Target(
        # a sweep row's metrics in numpy's pairwise-sum order, then the sweep's rows
        "src/hpdob/simulation/_row_kernel.py",
        ("tests/simulation/test_row_kernel.py", "tests/simulation/test_sweep_rows.py"),
    ),
    "identification.checks": Target(
        # the log's checks (time steps, lengths, read-only arrays), then the readers' and
        # identify's refusals that go through them
        "src/hpdob/identification/_checks.py",
        (
            "tests/identification/test_log.py",
            "tests/identification/test_log_file.py",
            "tests/identification/test_stream.py",
        ),
    ),
    "identification.readers": Target(
        # the log files' readers (.mat, Parquet, CSV), then the streaming reader
        "src/hpdob/identification/_readers.py",
        (
            "tests/identification/test_log_file.py",
            "tests/identification/test_log.py",
            "tests/identification/test_stream.py",
        ),
    ),
}


@dataclasses.dataclass(frozen=True)
class Planted:
    """A bug planted by hand (issue 20): one source line replaced, the tests that must fail."""

    target: str  # the TARGETS entry whose tests also run
    original: str
    mutated: str
    tests: tuple[str, ...]  # the tests written to catch it


#: The two bugs that survived the whole suite when issue 20 was filed.
PLANTED = {
    "kernel-generic-friction-doubled": Planted(
        "simulation.kernel",
        "force = applied - c * math.tanh(x[v] / c_scale)",
        "force = applied - 2.0 * c * math.tanh(x[v] / c_scale)",
        ("tests/models/test_plant.py",),
    ),
    "eso-reset-without-b_n": Planted(
        "observers.eso",
        "N[2, 1], N[2, 2] = -b_n / J_n, -1.0 / J_n",
        "N[2, 1], N[2, 2] = 0.0, -1.0 / J_n",
        ("tests/observers/test_family_invariants.py",),
    ),
}


def run_planted(name: str, tree: Path) -> dict:
    """Plant one bug in the tree, run its tests and the module's, put the source back."""
    planted = PLANTED[name]
    target = TARGETS[planted.target]
    path = tree / target.path
    source = path.read_text()
    if source.count(planted.original) != 1:
        return {"bug": name, "outcome": f"not applicable: the line is not once in {target.path}"}
    # the tests written for the bug once they are in the tree, else the module's own tests
    tests = tuple(t for t in planted.tests if (tree / t).is_file())
    chosen = dataclasses.replace(target, tests=tests, select="") if tests else target
    command = shlex.split(test_command(chosen, 600))
    try:
        path.write_text(source.replace(planted.original, planted.mutated))
        run = subprocess.run(command, cwd=tree, env=_env(tree), capture_output=True, text=True)
    finally:
        path.write_text(source)
    failed = [line for line in run.stdout.splitlines() if line.startswith("FAILED")]
    return {
        "bug": name,
        "where": target.path,
        "mutated": planted.mutated,
        "tests": " ".join(t for t in chosen.tests if (tree / t).is_file()),
        "outcome": "killed" if run.returncode != 0 else "survived",
        "failed": failed,
    }


def _tracked_files() -> list[str]:
    out = subprocess.run(
        ["git", "ls-files", "-co", "--exclude-standard", "-z"],
        cwd=ROOT, check=True, capture_output=True,
    ).stdout  # fmt: skip
    return [name for name in out.decode().split("\0") if name]


def sync_tree(tree: Path) -> None:
    """Copy the checkout's files into ``tree`` (restoring any mutated file)."""
    for name in _tracked_files():
        source = ROOT / name
        if not source.is_file():
            continue
        target = tree / name
        if target.is_file() and target.read_bytes() == source.read_bytes():
            continue
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(source, target)


def test_command(target: Target, timeout: float) -> str:
    # tests/<subpackage>/test_<module>_mutants.py hold the tests written to kill survivors
    stem = Path(target.path)
    extra = f"tests/{stem.parent.name}/test_{stem.stem.lstrip('_')}_mutants.py"
    # (a file not in this checkout yet, e.g. one another branch adds, is left out)
    tests = [t for t in (extra, *target.tests) if (ROOT / t).is_file()]
    command = f"{sys.executable} {PYTEST.format(timeout=int(timeout))} {' '.join(tests)}"
    if target.select:
        # cosmic-ray splits the command with shlex: quote the -k expression
        command += f" -k '{target.select}'"
    return command


def _env(tree: Path) -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(tree / "src")
    return env


def _source_hash(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()[:12]


def _session_paths(workdir: Path, name: str) -> tuple[Path, Path]:
    # the checkout's source, not the tree's: the tree holds a mutant while a job runs
    digest = _source_hash(ROOT / TARGETS[name].path)
    stem = f"{name}-{digest}"  # not Path.with_suffix: the name has a dot
    return workdir / "sessions" / f"{stem}.toml", workdir / "sessions" / f"{stem}.sqlite"


def _annotation_spans(path: Path) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    """Source spans of the annotations, if the module never evaluates them.

    With ``from __future__ import annotations`` an annotation is a string nobody reads at run
    time (the dataclasses here do not), so a mutant inside one is equivalent by construction.
    """
    tree = ast.parse(path.read_text())
    future = any(
        isinstance(node, ast.ImportFrom)
        and node.module == "__future__"
        and any(alias.name == "annotations" for alias in node.names)
        for node in tree.body
    )
    if not future:
        return []
    spans = []
    for node in ast.walk(tree):
        annotations = []
        if isinstance(node, ast.arg | ast.AnnAssign) and node.annotation is not None:
            annotations.append(node.annotation)
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and node.returns is not None:
            annotations.append(node.returns)
        spans += [((a.lineno, a.col_offset), (a.end_lineno, a.end_col_offset)) for a in annotations]
    return spans


def _in_annotation(item, spans) -> bool:
    start = tuple(item.mutations[0].start_pos)
    return any(first <= start < last for first, last in spans)


def _ordered(items):
    """Work items in a stable order (cosmic-ray's job ids are random)."""
    return sorted(items, key=lambda w: (w.mutations[0].operator_name, w.mutations[0].occurrence))


def prepare(
    name: str, *, workdir: Path, tree: Path, sample: int | None, seed: int, add: bool = True
) -> tuple:
    """Write the config, enumerate the mutants and put the sampled ones in the session.

    ``add=False`` (re-running survivors) leaves the session's mutants as they are.
    """
    from cosmic_ray.config import load_config
    from cosmic_ray.work_db import WorkDB, use_db

    target = TARGETS[name]
    config_path, session = _session_paths(workdir, name)
    config_path.parent.mkdir(parents=True, exist_ok=True)
    sidecar = session.with_suffix(".json")
    seconds = json.loads(sidecar.read_text()).get("baseline_s") if sidecar.exists() else None
    if config_path.exists():
        timeout = load_config(str(config_path)).timeout
    else:
        start = time.perf_counter()
        baseline = subprocess.run(
            shlex.split(test_command(target, 600)), cwd=tree, env=_env(tree),
            capture_output=True, text=True,
        )  # fmt: skip
        seconds = time.perf_counter() - start
        if baseline.returncode != 0:
            raise SystemExit(
                f"{name}: the unmutated tests fail, so no mutant can be judged:\n"
                f"{baseline.stdout[-3000:]}"
            )
        # Generous: a mutant that makes the tests 3x slower still counts as a timeout (killed).
        timeout = round(3.0 * seconds + 30.0)
        print(f"{name}: baseline passed in {seconds:.1f} s, timeout {timeout} s")
    # Rewritten each run: the test command picks up test files added since the session began.
    config_path.write_text(
        "[cosmic-ray]\n"
        f'module-path = "{target.path}"\n'
        f"timeout = {timeout}\n"
        "excluded-modules = []\n"
        f"test-command = {json.dumps(test_command(target, timeout))}\n"
        "\n[cosmic-ray.distributor]\n"
        'name = "local"\n'
    )
    items, spans = enumerate_mutants(name, tree, load_config(str(config_path)).operators_config)
    annotations = sum(_in_annotation(w, spans) for w in items)
    chosen = sample_mutants(items, spans, sample=sample, seed=seed)
    sidecar.write_text(
        json.dumps({
            "mutants": len(items) - annotations, "in_annotations": annotations, "seed": seed,
            "baseline_s": None if seconds is None else round(seconds, 1),
        })
    )  # fmt: skip
    with use_db(str(session), WorkDB.Mode.create) as db:
        known = {_key(w) for w in db.work_items}
        if add:
            db.add_work_items([w for w in chosen if _key(w) not in known])
        pending = db.num_work_items - db.num_results
    print(
        f"{name}: {len(items) - annotations} mutants (and {annotations} inside annotations), "
        + (f"{len(chosen)} sampled (seed {seed}), {pending} to run" if add else "")
    )
    return config_path, session, len(items)


def enumerate_mutants(name: str, tree: Path, operators_config=None) -> tuple[list, list]:
    """Every mutant cosmic-ray makes of a module (in a stable order) and its annotation spans."""
    from cosmic_ray.commands.init import init
    from cosmic_ray.work_db import WorkDB, use_db

    target = TARGETS[name]
    with tempfile.TemporaryDirectory() as scratch:
        everything = Path(scratch) / "all.sqlite"
        with use_db(str(everything), WorkDB.Mode.create) as db:
            cwd = os.getcwd()
            os.chdir(tree)
            try:
                init([Path(target.path)], db, operators_config or {})
            finally:
                os.chdir(cwd)
            items = _ordered(db.work_items)
    return items, _annotation_spans(tree / target.path)


def sample_mutants(items: list, spans: list, *, sample: int | None, seed: int) -> list:
    """The first ``sample`` mutants of a seeded permutation, those inside annotations left out.

    A larger ``sample`` with the same seed extends the same sample: it is a prefix of one
    permutation (a sample drawn before annotations were left out, as the first N of the
    permutation less those in annotations, is a prefix of it too).
    """
    order = np.random.default_rng(seed).permutation(len(items))
    kept = [items[i] for i in order if not _in_annotation(items[i], spans)]
    return kept if sample is None else kept[:sample]


def allocate(total: int, sizes: dict[str, int]) -> dict[str, int]:
    """A stratified sample of about ``total`` mutants, in proportion to each module's count.

    Each module's share ``total * size / population`` is rounded up (so every module gets at
    least one, and the counts add up to a little more than ``total``): rounding up is monotone,
    so a larger ``total`` never takes a module's count down and the samples extend.
    """
    population = sum(sizes.values())
    return {name: math.ceil(total * size / population) for name, size in sizes.items()}


def _key(item) -> tuple[str, int]:
    mutation = item.mutations[0]
    return (mutation.operator_name, mutation.occurrence)


def execute(config_path: Path, session: Path, tree: Path) -> None:
    """Run the pending mutants of one session with cosmic-ray, niced."""
    subprocess.run(
        ["nice", "-n", "19", str(Path(sys.executable).with_name("cosmic-ray")), "exec",
         str(config_path), str(session)],
        cwd=tree, env=_env(tree), check=True,
    )  # fmt: skip


def rerun_survivors(config_path: Path, session: Path, tree: Path, target: Target) -> None:
    """Run the unclassified survivors of a session again (after new tests were added)."""
    from cosmic_ray.config import load_config
    from cosmic_ray.mutating import mutate_and_test
    from cosmic_ray.work_db import use_db
    from cosmic_ray.work_item import TestOutcome

    config = load_config(str(config_path))
    os.environ["PYTHONPATH"] = str(tree / "src")
    os.chdir(tree)
    with use_db(str(session)) as db:
        survivors = [
            item for item, result in db.completed_work_items
            if result.test_outcome == TestOutcome.SURVIVED
            and _verdict(target, item, result) is None
        ]  # fmt: skip
        # the first pass's survivors are remembered: the report shows both passes
        first = _first_pass_survivors(session)
        first |= {_key_text(item) for item in survivors}
        session.with_suffix(".first-pass.json").write_text(json.dumps(sorted(first), indent=1))
        for item in survivors:
            result = mutate_and_test(item.mutations, config.test_command, config.timeout)
            db.set_result(item.job_id, result)
            print(f"  {_where(item)}: {result.test_outcome}")


def _key_text(item) -> str:
    operator, occurrence = _key(item)
    return f"{operator}#{occurrence}"


def _first_pass_survivors(session: Path) -> set[str]:
    path = session.with_suffix(".first-pass.json")
    return set(json.loads(path.read_text())) if path.exists() else set()


def _where(item) -> str:
    mutation = item.mutations[0]
    return f"{mutation.module_path}:{mutation.start_pos[0]} {mutation.operator_name}"


def _changed_lines(diff: str) -> tuple[str, str]:
    """The original and mutated line of a one-mutation unified diff."""
    lines = diff.splitlines()
    old = [line[1:] for line in lines if line.startswith("-") and not line.startswith("---")]
    new = [line[1:] for line in lines if line.startswith("+") and not line.startswith("+++")]
    return " / ".join(s.strip() for s in old), " / ".join(s.strip() for s in new)


def _verdict(target: Target, item, result) -> dict | None:
    """The hand classification of a survivor, or None."""
    old, new = _changed_lines(result.diff or "")
    operator = item.mutations[0].operator_name
    for entry in _classified():
        if (entry["path"], entry["operator"], entry["original"], entry["mutated"]) == (
            target.path, operator, old, new,
        ):  # fmt: skip
            return entry
    if _in_annotation(item, _annotation_spans(ROOT / target.path)):
        return {"class": "equivalent", "reason": ANNOTATION}
    return None


def _classified() -> list[dict]:
    if not CLASSIFIED.exists():
        return []
    return tomllib.loads(CLASSIFIED.read_text())["survivor"]


def report(workdir: Path) -> dict:
    """Kill rates per module and the survivors of the current sources' sessions."""
    from cosmic_ray.work_db import WorkDB, use_db
    from cosmic_ray.work_item import TestOutcome, WorkerOutcome

    commit = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True
    ).stdout.strip()
    modules = {}
    for name, target in TARGETS.items():
        _, session = _session_paths(workdir, name)
        if not session.exists():
            continue
        sidecar = session.with_suffix(".json")
        counts = dict.fromkeys(
            ["killed", "survived", "incompetent", "timeout", "no-test", "killed_on_rerun"], 0
        )
        first_pass = _first_pass_survivors(session)
        survivors = []
        with use_db(str(session), WorkDB.Mode.open) as db:
            for item, result in _ordered_pairs(db.completed_work_items):
                if result.worker_outcome == WorkerOutcome.NO_TEST:
                    counts["no-test"] += 1
                elif result.test_outcome == TestOutcome.INCOMPETENT:
                    counts["incompetent"] += 1
                elif result.test_outcome == TestOutcome.SURVIVED:
                    counts["survived"] += 1
                    old, new = _changed_lines(result.diff or "")
                    mutation = item.mutations[0]
                    verdict = _verdict(target, item, result)
                    survivors.append({
                        "where": f"{target.path}:{mutation.start_pos[0]}",
                        "operator": mutation.operator_name,
                        "occurrence": mutation.occurrence,
                        "original": old,
                        "mutated": new,
                        "class": verdict["class"] if verdict else "unclassified",
                        "reason": verdict["reason"] if verdict else "",
                    })  # fmt: skip
                elif result.output == "timeout":
                    counts["timeout"] += 1
                else:
                    counts["killed"] += 1
                if result.test_outcome == TestOutcome.KILLED and _key_text(item) in first_pass:
                    counts["killed_on_rerun"] += 1
                    mutation = item.mutations[0]
                    survivors.append({
                        "where": f"{target.path}:{mutation.start_pos[0]}",
                        "operator": mutation.operator_name,
                        "occurrence": mutation.occurrence,
                        "original": _changed_lines(result.diff or "")[0],
                        "mutated": _changed_lines(result.diff or "")[1],
                        "class": "killed on re-run",
                        "reason": "a test added after the first pass",
                    })  # fmt: skip
            total = db.num_work_items
        judged = counts["killed"] + counts["timeout"] + counts["survived"]
        equivalent = sum(s["class"] == "equivalent" for s in survivors)
        killed = counts["killed"] + counts["timeout"]
        low, high = jeffreys_interval(killed, judged - equivalent)
        modules[name] = {
            "path": target.path,
            "tests": " ".join(target.tests) + (f" -k '{target.select}'" if target.select else ""),
            "mutants": None,
            **(json.loads(sidecar.read_text()) if sidecar.exists() else {}),
            "sampled": total,
            "run": judged + counts["incompetent"] + counts["no-test"],
            **counts,
            "equivalent": equivalent,
            "kill_rate": killed / judged if judged else None,
            "kill_rate_non_equivalent": (
                killed / (judged - equivalent) if judged - equivalent else None
            ),
            "interval_95": [low, high],
            "survivors": survivors,
        }
    result = {"commit": commit, "modules": modules}
    killed = sum(m["killed"] + m["timeout"] for m in modules.values())
    judged = sum(m["killed"] + m["timeout"] + m["survived"] for m in modules.values())
    equivalent = sum(m["equivalent"] for m in modules.values())
    first = killed - sum(m["killed_on_rerun"] for m in modules.values())
    result["total"] = {
        "killed": killed, "killed_first_pass": first, "judged": judged, "equivalent": equivalent,
        "kill_rate_non_equivalent": killed / (judged - equivalent) if judged > equivalent else None,
        "mutants": sum(m["mutants"] or 0 for m in modules.values()),
        "stratified": stratified_estimate(modules),
        "stratified_first_pass": stratified_estimate(modules, first_pass=True),
    }  # fmt: skip
    return result


def jeffreys_interval(killed: int, n: int, level: float = 0.95) -> tuple[float, float] | None:
    """The Jeffreys interval of a binomial proportion (Brown, Cai & DasGupta 2001).

    The quantiles of Beta(k + 1/2, n - k + 1/2); it stays inside [0, 1] and is not empty at
    k = n, where the normal approximation's interval collapses to a point.
    """
    from scipy.stats import beta

    if n == 0:
        return None, None
    tail = (1.0 - level) / 2.0
    low = 0.0 if killed == 0 else float(beta.ppf(tail, killed + 0.5, n - killed + 0.5))
    high = 1.0 if killed == n else float(beta.ppf(1 - tail, killed + 0.5, n - killed + 0.5))
    return low, high


def stratified_estimate(modules: dict, *, first_pass: bool = False) -> dict:
    """The pooled kill rate of the non-equivalent mutants, estimated from a stratified sample.

    Each module ``h`` (a stratum of ``M_h`` mutants) was sampled at random, ``n_h`` mutants:
    ``k_h`` killed, ``s_h`` survived, ``e_h`` equivalent. The pooled rate is a ratio of
    population totals, estimated by

        R = sum_h M_h k_h / n_h  /  sum_h M_h (k_h + s_h) / n_h

    (killed over non-equivalent mutants; unbiased for each stratum's totals whatever the
    allocation). With the allocation in proportion to ``M_h`` (``allocate``) R is close to the
    plain count ``sum k / sum (k + s)``, and the stratified sample is at least as precise as a
    simple random sample of the same size (Cochran, *Sampling Techniques*, 3rd ed., 1977,
    sec. 5.6): the Jeffreys interval of the plain count is then a conservative 95 % interval.
    (A per-stratum posterior would be dominated by its prior in the modules of one or two
    sampled mutants.) The sample is about 1 % of each module, so the finite-population
    correction, which would narrow it, is left out.
    """
    num = den = 0.0
    killed_all = judged_all = 0
    used = []
    for name, m in modules.items():
        size = m.get("mutants")
        killed = m["killed"] + m["timeout"] - (m["killed_on_rerun"] if first_pass else 0)
        equivalent = m["equivalent"]
        survived = m["killed"] + m["timeout"] + m["survived"] - killed - equivalent
        n = killed + survived + equivalent
        if not size or n == 0:
            continue
        used.append(name)
        num += size * killed / n
        den += size * (killed + survived) / n
        killed_all += killed
        judged_all += killed + survived
    if not used or den == 0.0:
        return {"rate": None, "pooled": None, "interval_95": [None, None], "modules": used}
    return {
        "rate": num / den,
        "pooled": killed_all / judged_all,
        "killed": killed_all,
        "non_equivalent": judged_all,
        "interval_95": list(jeffreys_interval(killed_all, judged_all)),
        "modules": used,
    }


def _ordered_pairs(pairs):
    return sorted(pairs, key=lambda p: _key(p[0]))


def _percent(x) -> str:
    return "-" if x is None else f"{100 * x:.0f} %"


def _percent1(x) -> str:
    return "-" if x is None else f"{100 * x:.1f} %"


def _interval(pair) -> str:
    low, high = pair
    return "-" if low is None else f"{100 * low:.1f}-{100 * high:.1f} %"


def markdown(result: dict) -> str:
    lines = [
        f"Measured on commit {result['commit']}.",
        "",
        "| module | mutants | sampled | killed (first pass; timeouts) | survived | equivalent "
        "| incompetent | non-equivalent killed | 95 % interval | unmutated run [s] |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, m in result["modules"].items():
        killed = m["killed"] + m["timeout"]
        lines.append(
            f"| {name} | {m['mutants']} | {m['run']} "
            f"| {killed} ({killed - m['killed_on_rerun']}; {m['timeout']}) "
            f"| {m['survived']} | {m['equivalent']} | {m['incompetent']} "
            f"| {_percent(m['kill_rate_non_equivalent'])} | {_interval(m['interval_95'])} "
            f"| {m.get('baseline_s') or '-'} |"
        )
    total = result["total"]
    pooled, first = total["stratified"], total["stratified_first_pass"]
    lines += [
        "",
        f"All modules: {total['killed']} of {total['judged'] - total['equivalent']} "
        f"non-equivalent mutants killed ({_percent(total['kill_rate_non_equivalent'])}; "
        f"{total['killed_first_pass']} on the first pass).",
        "",
        f"Stratified estimate over the {len(pooled['modules'])} modules' {total['mutants']} "
        f"mutants: {_percent1(pooled['rate'])} of the non-equivalent mutants killed "
        f"(95 % interval {_interval(pooled['interval_95'])}); on the first pass "
        f"{_percent1(first['rate'])} ({_interval(first['interval_95'])}).",
        "",
        "| survivor | operator | mutated line | class | reason |",
        "|---|---|---|---|---|",
    ]
    for m in result["modules"].values():
        for s in m["survivors"]:
            mutated = s["mutated"].replace("|", "\\|")
            lines.append(
                f"| {s['where']} | {s['operator'].removeprefix('core/')} | `{mutated}` "
                f"| {s['class']} | {s['reason']} |"
            )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--modules", nargs="+", choices=sorted(TARGETS), default=[])
    parser.add_argument("--sample", type=int, default=None, help="mutants per module")
    parser.add_argument(
        "--total", type=int, default=None,
        help="a stratified sample of about this many mutants over all modules, in proportion "
        "to each module's mutant count (runs --modules, or every module)",
    )  # fmt: skip
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--workdir", type=Path, default=ROOT / ".mutation")
    parser.add_argument("--report", action="store_true")
    parser.add_argument("--rerun-survivors", action="store_true")
    parser.add_argument("--list", action="store_true", help="print each module's test command")
    parser.add_argument(
        "--planted", action="store_true", help="check that the tests kill issue 20's planted bugs"
    )
    args = parser.parse_args(argv)
    if args.sample is not None and args.sample < 1:
        parser.error(f"--sample must be a positive number of mutants, got {args.sample}")
    if args.total is not None and (args.total < 1 or args.sample is not None):
        parser.error(
            f"--total must be a positive number of mutants without --sample, got {args.total}"
        )
    if args.list:
        for name, target in TARGETS.items():
            print(f"{name}: {target.path}\n    {test_command(target, 600)}")
        return
    tree = args.workdir / "tree"
    tree.mkdir(parents=True, exist_ok=True)
    lock = (args.workdir / "lock").open("w")
    if args.total is not None and not args.modules:
        args.modules = list(TARGETS)
    if args.modules or args.planted:
        try:  # one run at a time: a second one would restore the first one's mutant
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            parser.error(f"another mutation run holds {args.workdir / 'lock'}")
        sync_tree(tree)
        os.nice(19)  # the machine is shared; the jobs inherit the niceness
    samples = dict.fromkeys(args.modules, args.sample)
    if args.total is not None:
        sizes = {}
        for name in TARGETS:
            items, spans = enumerate_mutants(name, tree)
            sizes[name] = sum(not _in_annotation(w, spans) for w in items)
        allocation = allocate(args.total, sizes)
        samples = {name: allocation[name] for name in args.modules}
        print("stratified sample:", ", ".join(f"{k} {v}/{sizes[k]}" for k, v in samples.items()))
    for name in args.modules:
        config_path, session, _ = prepare(
            name, workdir=args.workdir, tree=tree, sample=samples[name], seed=args.seed,
            add=not args.rerun_survivors,
        )  # fmt: skip
        if args.rerun_survivors:
            rerun_survivors(config_path, session, tree, TARGETS[name])
        else:
            execute(config_path, session, tree)
    if args.planted:
        results = [run_planted(name, tree) for name in PLANTED]
        (args.workdir / "planted.json").write_text(json.dumps(results, indent=2))
        for result in results:
            print(f"{result['bug']}: {result['outcome']} {' '.join(result.get('failed', []))}")
    if args.report or not (args.modules or args.planted):
        result = report(args.workdir)
        (args.workdir / "report.json").write_text(json.dumps(result, indent=2))
        text = markdown(result)
        (args.workdir / "report.md").write_text(text)
        print(text)


if __name__ == "__main__":
    main()
