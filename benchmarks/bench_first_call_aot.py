"""What an ahead-of-time compiled sample loop would give the first ``simulate`` (issue 25).

numba's ``cache=True`` saves machine code, but every process that loads it first initialises
numba (its typing and lowering registries and, for its BLAS check, ``scipy.linalg``: about
0.3 s, ``bench_first_call.py --breakdown``). ``numba.pycc`` (pending deprecation since numba
0.57, still in 0.68; it needs setuptools and a C compiler) writes a C extension instead,
which a later process imports without numba. This benchmark measures that route for the
canonical loop (10 s, HPDOb-100), outside the library:

1. one process runs the canonical ``simulate``, keeps the generated loop's source and the
   arguments it was called with (a copy before the call and the arrays after it), and builds
   the same source with ``numba.pycc`` for the argument types numba saw (the build's wall and
   CPU time, its compiler processes included, are printed);
2. ``--runs`` fresh processes import numpy and the extension only, call it with the saved
   arguments and compare every array it writes, bit for bit, with the JIT's; ``numba`` must
   not be imported (printed: the import, the first and the second call, CPU);
3. the extension's call on two threads against one: pycc's wrapper holds the GIL (a sweep on
   threads, which the JIT loop's ``nogil`` runs in parallel, would run one at a time).

    python benchmarks/bench_first_call_aot.py [--runs 5]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile

BUILD = r"""
import os, pickle, resource, sys, time, warnings
import numba
from hpdob import ServoLoop, paper, simulate
from hpdob.simulation import _kernel

folder = sys.argv[1]
kw = paper.scenario()
loop = ServoLoop(plant=kw["plant"], nominal=kw["nominal"], Ts=kw["Ts"],
                 controller=kw["controller"], observer=paper.observer("HPDOb-100").design)
seen = {}
original = _kernel.run_samples


def spy(k_start, k_stop, substeps, Ts, plant, ctl, sen, act, obs, sig, out, work, limit,
        midpoint=None, errors=False):
    structure = _kernel.run_structure(plant, ctl, sen, act, obs, sig, work, midpoint, errors)
    kernel, fields = _kernel.sample_loop(structure)
    records = {"plant": plant, "ctl": ctl, "sen": sen, "act": act, "obs": obs, "sig": sig,
               "out": out, "work": work}
    arguments = [k_start, k_stop, substeps, Ts, limit,
                 *(getattr(records[r], f) for r, f in fields)]
    seen["source"] = _kernel.loop_source(structure)
    seen["before"] = pickle.dumps(arguments)
    seen["types"] = [numba.typeof(a) for a in arguments]
    done = kernel(*arguments)
    seen["after"], seen["done"] = pickle.dumps(arguments), done
    return done


_kernel.run_samples = spy
os.environ["HPDOB_AOT"] = "0"  # the JIT loop (not one built by hpdob.simulation)
simulate(loop, reference=kw["reference"], disturbance=kw["disturbance"],
         duration=kw["duration"])
from pathlib import Path
Path(folder, "aot_loop_source.py").write_text(seen["source"])
with open(Path(folder, "arguments.pkl"), "wb") as f:
    pickle.dump({k: seen[k] for k in ("before", "after", "done")}, f)
sys.path.insert(0, folder)
import aot_loop_source
with warnings.catch_warnings():  # pycc warns that it is pending deprecation
    warnings.simplefilter("ignore")
    from numba.pycc import CC
wall, cpu = time.perf_counter(), time.process_time()
children = resource.getrusage(resource.RUSAGE_CHILDREN)
cc = CC("hpdob_aot_loop", source_module=aot_loop_source)
cc.output_dir = folder
cc.export("run", numba.types.int64(*seen["types"]))(aot_loop_source.run)
cc.compile()
after = resource.getrusage(resource.RUSAGE_CHILDREN)
child_cpu = (after.ru_utime + after.ru_stime) - (children.ru_utime + children.ru_stime)
print(f"{time.perf_counter() - wall:.2f} {time.process_time() - cpu:.2f} {child_cpu:.2f} "
      f"{len(seen['types'])}")
"""

LOAD = r"""
import pickle, sys, time
c0 = time.process_time()
import numpy as np
c1 = time.process_time()
sys.path.insert(0, sys.argv[1])
import hpdob_aot_loop
c2 = time.process_time()
with open(sys.argv[1] + "/arguments.pkl", "rb") as f:
    saved = pickle.load(f)
arguments, expected = pickle.loads(saved["before"]), pickle.loads(saved["after"])
again = pickle.loads(saved["before"])
c3 = time.process_time()
done = hpdob_aot_loop.run(*arguments)
c4 = time.process_time()
hpdob_aot_loop.run(*again)
c5 = time.process_time()
same = done == saved["done"] and all(
    a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
    if isinstance(a, np.ndarray) else a == b
    for a, b in zip(arguments, expected))
print(f"{c1 - c0:.4f} {c2 - c1:.4f} {c4 - c3:.4f} {c5 - c4:.4f} {int(same)} "
      f"{int('numba' in sys.modules)}")
"""

THREADS = r"""
import pickle, sys, threading, time
sys.path.insert(0, sys.argv[1])
import hpdob_aot_loop
with open(sys.argv[1] + "/arguments.pkl", "rb") as f:
    before = pickle.load(f)["before"]
calls = [pickle.loads(before) for _ in range(40)]
def work(part):
    for arguments in part:
        hpdob_aot_loop.run(*arguments)
wall = time.perf_counter(); work(calls[:20]); one = time.perf_counter() - wall
threads = [threading.Thread(target=work, args=(calls[20 + 10 * i:30 + 10 * i],))
           for i in range(2)]
wall = time.perf_counter()
for t in threads:
    t.start()
for t in threads:
    t.join()
print(f"{one:.4f} {time.perf_counter() - wall:.4f}")
"""


def run(code: str, *arguments: str, env: dict | None = None) -> list[str]:
    done = subprocess.run([sys.executable, "-c", code, *arguments], capture_output=True,
                          text=True, check=True, env=env)  # fmt: skip
    return done.stdout.split()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        env = {**os.environ, "NUMBA_CACHE_DIR": folder}
        wall, cpu, child_cpu, count = run(BUILD, folder, env=env)
        print(f"build with numba.pycc: {float(wall):.2f} s wall, {float(cpu):.2f} s CPU in the "
              f"process and {float(child_cpu):.2f} s in its compiler processes; "
              f"{count} arguments")  # fmt: skip
        rounds = [[float(x) for x in run(LOAD, folder)] for _ in range(args.runs)]
        one, two = (float(x) for x in run(THREADS, folder))
    print(f"load average {os.getloadavg()[0]:.2f}; {args.runs} fresh processes, CPU median")
    for i, name in enumerate(("import numpy", "import the extension", "first call",
                              "second call")):  # fmt: skip
        print(f"{name:>22}  {statistics.median(r[i] for r in rounds) * 1e3:8.1f} ms")
    print("every array bit for bit the JIT's:", all(r[4] for r in rounds),
          "| numba imported:", any(r[5] for r in rounds))  # fmt: skip
    print(
        f"20 calls: {one * 1e3:.0f} ms on one thread, {two * 1e3:.0f} ms on two threads "
        f"(10 each): {'the GIL is held' if two > 0.75 * one else 'in parallel'}"
    )


if __name__ == "__main__":
    main()
