"""The first ``simulate`` of a later process, split into what it waits for (issue 25).

Each round starts a fresh interpreter (numba's on-disk cache already filled by an earlier
process) and times, in order: ``import numba``; ``import hpdob`` with ``hpdob.simulate``
looked up; numba's one-time initialisation (its typing and lowering registries, loaded by the
first compiled function any package calls: here a trivial cached ``njit`` function, which also
makes numba's BLAS check import ``scipy.linalg``); building the canonical ``ServoLoop``; the
first canonical ``simulate`` (10 s, HPDOb-100): loading hpdob's cached kernel and running it;
and a second ``simulate``, for comparison. Printed: the median and the best over ``--runs``
of each, wall and CPU.

``--no-warm`` leaves out the trivial function, so that the first ``simulate`` pays numba's
initialisation itself (the figure a user sees). ``--breakdown`` splits numba's initialisation
into the ``scipy.linalg`` import of its BLAS check, its typing registries
(``typing_context.refresh()``) and its lowering registries (``target_context.refresh()``,
which imports about 60 ``numba.*`` modules: every implementation numba has, whatever the
function uses), each timed by calling it directly (numba's internals, here only to measure).
``--fresh`` gives every measured process an empty ``NUMBA_CACHE_DIR``, so that its first
``simulate`` compiles hpdob's loop (target <= 1.0 s). ``--bytecode`` lets the processes
cache hpdob's bytecode (a private ``PYTHONPYCACHEPREFIX``, written by a warm-up process) where
the environment sets ``PYTHONDONTWRITEBYTECODE``: an installed package has its ``.pyc`` files,
a checkout run with that variable compiles every module of hpdob on each import.

``--aot`` measures the library's ahead-of-time route instead: it builds the canonical loop
with :func:`hpdob.simulation.build_loop_extension` (``--compiler``, default ``zig``: the
``ziglang`` package) into a temporary folder, then times fresh processes alternating between
the two routes, each with its caches filled by earlier processes: ``HPDOB_AOT_DIR`` set to
that folder (the built loop, no numba) and ``HPDOB_AOT=0`` (the JIT loop from numba's cache).
Each times ``import hpdob`` with ``hpdob.simulate`` looked up, building the canonical loop
(the paper's set-up and the observer's design), the first and the second ``simulate``; "in
all" is the sum of the three steps up to the first ``simulate`` (the interpreter's own start
not counted); it prints whether numba was imported and the ratio of the routes' medians.

Target (issue 25): the first ``simulate`` of a later process <= 0.2 s, with "import alone" its
own row; of a fresh environment <= 1.0 s.

    python benchmarks/bench_first_call.py [--runs 7] [--no-warm] [--breakdown] [--fresh]
                                          [--bytecode]
    python benchmarks/bench_first_call.py --aot [--runs 7] [--bytecode] [--compiler zig]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

#: The start of both children: the clock marks.
_MARKS = r"""
import json, sys, time
marks = []
def mark(name):
    marks.append((name, time.perf_counter(), time.process_time()))
mark("start")
"""
#: The canonical loop and its first simulate, timed (after the imports).
_FIRST_SIMULATE = r"""from hpdob import ServoLoop, paper, simulate
kw = paper.scenario()
loop = ServoLoop(plant=kw["plant"], nominal=kw["nominal"], Ts=kw["Ts"],
                 controller=kw["controller"], observer=paper.observer("HPDOb-100").design)
mark("the loop")
run = dict(reference=kw["reference"], disturbance=kw["disturbance"], duration=kw["duration"])
simulate(loop, **run)
mark("first simulate")
"""
_IMPORT_HPDOB = r"""import hpdob
hpdob.simulate
mark("import hpdob")
"""

CHILD = (
    _MARKS
    + r"""import numba
mark("import numba")
"""
    + _IMPORT_HPDOB
    + r"""if BREAKDOWN:
    import scipy.linalg
    mark("scipy.linalg (BLAS check)")
    from numba.core.registry import cpu_target
    cpu_target.typing_context.refresh()
    mark("typing registries")
    cpu_target.target_context.refresh()
    mark("lowering registries")
if WARM:
    @numba.njit(cache=True)
    def _trivial(x):
        return x + 1.0
    _trivial(1.0)
    mark("rest of numba's init" if BREAKDOWN else "numba's initialisation")
"""
    + _FIRST_SIMULATE
    + r"""simulate(loop, **run)
mark("second simulate")
json.dump([(b[0], b[1] - a[1], b[2] - a[2]) for a, b in zip(marks, marks[1:])], sys.stdout)
"""
)

AOT_CHILD = (
    _MARKS
    + _IMPORT_HPDOB
    + _FIRST_SIMULATE
    + r"""numba = "numba" in sys.modules
simulate(loop, **run)
mark("second simulate")
steps = [(b[0], b[1] - a[1], b[2] - a[2]) for a, b in zip(marks, marks[1:])]
json.dump([steps, numba], sys.stdout)
"""
)


def aot(args, env: dict, folder: str) -> None:
    """The ``--aot`` mode: the built loop against the JIT loop, fresh processes interleaved."""
    from hpdob import ServoLoop, paper
    from hpdob.simulation import build_loop_extension

    kw = paper.scenario()
    loop = ServoLoop(plant=kw["plant"], nominal=kw["nominal"], Ts=kw["Ts"],
                     controller=kw["controller"],
                     observer=paper.observer("HPDOb-100").design)  # fmt: skip
    built = Path(folder, "aot")
    path = build_loop_extension(loop, reference=kw["reference"], disturbance=kw["disturbance"],
                                folder=built, compiler=args.compiler)  # fmt: skip
    script = Path(folder) / "first_call_aot.py"
    script.write_text(AOT_CHILD)
    routes = {
        "built loop": {**env, "HPDOB_AOT_DIR": str(built)},
        "JIT loop": {**{k: v for k, v in env.items() if k != "HPDOB_AOT_DIR"}, "HPDOB_AOT": "0",
                     "HPDOB_AOT_DIR": str(Path(folder, "none"))},
    }  # fmt: skip
    for route in routes.values():  # fills numba's cache and the bytecode
        one(script, route)
    rounds: dict = {name: [] for name in routes}
    for _ in range(args.runs):
        for name, route in routes.items():
            rounds[name].append(one(script, route))
    print(f"built {path.name} ({path.stat().st_size // 1024} kB) with compiler={args.compiler!r}")
    print(f"load average {os.getloadavg()[0]:.2f}; {args.runs} fresh processes per route, "
          "interleaved, caches filled; medians")  # fmt: skip
    medians: dict = {}
    print(f"{'step':>18}  " + "  ".join(f"{name + ' wall':>15}  {name + ' CPU':>14}"
                                         for name in routes))  # fmt: skip
    steps = [step[0] for step in rounds["built loop"][0][0]] + ["in all (to 1st)"]
    for i, step in enumerate(steps):
        cells = []
        for name in routes:
            if i < len(steps) - 1:
                wall = [r[0][i][1] for r in rounds[name]]
                cpu = [r[0][i][2] for r in rounds[name]]
            else:  # import hpdob + the loop + the first simulate
                wall = [sum(s[1] for s in r[0][:3]) for r in rounds[name]]
                cpu = [sum(s[2] for s in r[0][:3]) for r in rounds[name]]
            medians[name, step] = statistics.median(wall), statistics.median(cpu)
            cells.append(f"{medians[name, step][0] * 1e3:>13.1f}ms  "
                         f"{medians[name, step][1] * 1e3:>12.1f}ms")  # fmt: skip
        print(f"{step:>18}  " + "  ".join(cells))
    for name in routes:
        print(f"{name}: numba imported in {sum(r[1] for r in rounds[name])} of {args.runs}")
    for step in ("first simulate", "in all (to 1st)"):
        (aw, ac), (jw, jc) = medians["built loop", step], medians["JIT loop", step]
        print(f"{step}: built / JIT loop = {aw / jw:.3f} wall, {ac / jc:.3f} CPU")


def one(script: Path, env: dict) -> list:
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          check=True, env=env)  # fmt: skip
    return json.loads(done.stdout)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=7)
    parser.add_argument("--no-warm", dest="warm", action="store_false")
    parser.add_argument("--breakdown", action="store_true",
                        help="split numba's initialisation into its parts")  # fmt: skip
    parser.add_argument("--fresh", action="store_true",
                        help="an empty numba cache for every measured process")  # fmt: skip
    parser.add_argument("--bytecode", action="store_true",
                        help="let the processes cache hpdob's bytecode")  # fmt: skip
    parser.add_argument("--aot", action="store_true",
                        help="the ahead-of-time built loop against the JIT loop")  # fmt: skip
    parser.add_argument("--compiler", default="zig",
                        help="--aot's C compiler (default: zig, the ziglang package)")  # fmt: skip
    args = parser.parse_args()
    env = dict(os.environ)
    with tempfile.TemporaryDirectory() as folder:
        if args.aot:
            if args.bytecode:
                env.pop("PYTHONDONTWRITEBYTECODE", None)
                env["PYTHONPYCACHEPREFIX"] = str(Path(folder, "bytecode"))
            env.setdefault("NUMBA_CACHE_DIR", folder)  # not the user's cache
            return aot(args, env, folder)
        script = Path(folder) / "first_call.py"  # a file: numba caches only those
        child = CHILD.replace("WARM", repr(args.warm)).replace("BREAKDOWN", repr(args.breakdown))
        script.write_text(child)
        if args.bytecode:
            env.pop("PYTHONDONTWRITEBYTECODE", None)
            env["PYTHONPYCACHEPREFIX"] = str(Path(folder, "bytecode"))
        bytecode = "cached" if "PYTHONDONTWRITEBYTECODE" not in env else "compiled on import"
        if "NUMBA_CACHE_DIR" not in env or args.fresh:  # not the user's cache
            env["NUMBA_CACHE_DIR"] = folder
            print(f"NUMBA_CACHE_DIR={folder} (hpdob's kernels compiled once below)")
        one(script, env)  # fills the caches: every later process loads from disk
        rounds = []
        for i in range(args.runs):
            if args.fresh:  # an empty numba cache: this process compiles what it runs
                env["NUMBA_CACHE_DIR"] = str(Path(folder, f"fresh-{i}"))
            rounds.append(one(script, env))
    kind = "an empty numba cache each" if args.fresh else "numba's cache filled"
    print(f"load average {os.getloadavg()[0]:.2f}; {args.runs} fresh processes, {kind}; "
          f"hpdob's bytecode {bytecode}")  # fmt: skip
    print(f"{'step':>26}  {'wall median':>11}  {'wall best':>9}  {'CPU median':>10}")
    for i, (name, _, _) in enumerate(rounds[0]):
        wall = [r[i][1] for r in rounds]
        cpu = [r[i][2] for r in rounds]
        print(f"{name:>26}  {statistics.median(wall) * 1e3:>9.0f}ms  "
              f"{min(wall) * 1e3:>7.0f}ms  {statistics.median(cpu) * 1e3:>8.0f}ms")  # fmt: skip


if __name__ == "__main__":
    main()
