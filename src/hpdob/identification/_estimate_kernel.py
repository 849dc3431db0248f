r"""The offline estimation loop, generated from the observer's program and compiled by numba.

:func:`offline_kernel` writes the program's rows as straight-line code (as
:func:`hpdob.export_c` prints them), with the state in local variables and the coefficients
read once into locals, and compiles it with numba. The code depends only on the program's
structure (:func:`~hpdob.observers._program.program_structure`: which operand each term reads,
which terms are unit terms) and on where the velocity comes from, so it is generated and
compiled once per structure and process, and reused for every design of that structure. Per
sample it evaluates exactly the sums of :func:`hpdob.simulation._kernel.program_row`, term by
term left to right (numba does not reassociate or fuse floating-point operations unless asked
to), so it reproduces the runtime object and the closed-loop kernel bit for bit.

The generated source is saved as a small module under ``~/.cache/hpdob`` (or
``NUMBA_CACHE_DIR``) so that numba caches its machine code on disk like the package's own
kernels (``hpdob._generated``, shared with the closed-loop kernel): only the first process to
run a structure compiles it. This module is imported on the first offline estimation only.
"""

from __future__ import annotations

import functools
import threading

import numpy as np

from .._generated import compiled_function, read_only_view, sum_source
from ..observers import program_coefficients, program_structure
from ._checks import immutable

__all__ = [
    "VELOCITY_DERIVED",
    "VELOCITY_GIVEN",
    "VELOCITY_NONE",
    "offline_kernel",
    "run",
    "run_block",
]

#: From this many samples on, :func:`run`'s check and the copies of the inputs it keeps are
#: made on a second thread while the loop runs (the loop is ``nogil``; numpy's steps and
#: copies release the GIL), instead of before it and by the loop: the time check and the
#: copies' fresh memory then take the other core. Below it a thread's start is not worth it
#: (~0.1 ms against ~0.4 ms of copies at this size).
PARALLEL_SAMPLES = 1 << 18

#: Where the observer's second measured signal comes from: none (position-only observer), the
#: log's velocity, or the backward difference of the position computed in the loop.
VELOCITY_NONE, VELOCITY_GIVEN, VELOCITY_DERIVED = 0, 1, 2


def kernel_source(structure: tuple, n: int, velocity: int) -> str:
    """Source of ``run(c, s_init, theta_in, omega_in, u_in, t_in, theta, omega, u, tau_hat,
    omega_hat, t, Ts)`` for a program of ``structure`` with ``n`` states; ``velocity`` is one of
    the ``VELOCITY_*`` modes.

    The loop copies the inputs ``*_in`` into non-empty ``theta``, ``omega`` (or writes the
    backward difference there), ``u`` and ``t`` while it reads them (one pass over the log
    instead of a copy and a run; an empty output is not written: the input is shared, or the
    array derived when it is read); with an empty ``t_in`` it fills a non-empty ``t`` with
    ``k * Ts`` (what ``np.arange(n) * Ts`` gives). At the end ``s_init`` holds the state after
    the last sample (a next piece of the log starts there).
    """
    update, output, _ = structure
    p = 1 if velocity == VELOCITY_NONE else 2
    state = [f"s{i}" for i in range(n)]
    operands = [*state, "v0", "v1", "uk"] if p == 2 else [*state, "v0", "uk"]
    count = sum(1 for rows in (update, output) for r in rows for _, unit in r if not unit)
    names = [f"c{i}" for i in range(count)]
    coefficient = iter(names)
    update_rows = [sum_source(r, operands, coefficient) for r in update]
    output_rows = [sum_source(r, operands, coefficient) for r in output]
    lines = ["def run(c, s_init, theta_in, omega_in, u_in, t_in, theta, omega, u, tau_hat, "
             "omega_hat, t, Ts):"]  # fmt: skip
    lines += [f"    {name} = c[{i}]" for i, name in enumerate(names)]
    lines += [f"    s{i} = s_init[{i}]" for i in range(n)]
    lines += [f"    write_{x} = {x}.shape[0] > 0" for x in ("theta", "omega", "u", "t")]
    lines.append("    copy_time = t_in.shape[0] > 0")
    if velocity == VELOCITY_DERIVED:
        lines.append("    previous = theta_in[0] if theta_in.shape[0] > 0 else 0.0")
    lines.append("    for k in range(theta_in.shape[0]):")
    lines += ["        if write_t:", "            t[k] = t_in[k] if copy_time else k * Ts"]
    lines.append("        v0 = theta_in[k]")
    lines += ["        if write_theta:", "            theta[k] = v0"]
    if velocity == VELOCITY_GIVEN:
        lines += [
            "        v1 = omega_in[k]",
            "        if write_omega:",
            "            omega[k] = v1",
        ]
    elif velocity == VELOCITY_DERIVED:  # 0 at k = 0: (theta[0] - theta[0]) / Ts
        lines += ["        v1 = (v0 - previous) / Ts", "        previous = v0",
                  "        if write_omega:", "            omega[k] = v1"]  # fmt: skip
    lines.append(f"        tau_hat[k] = {output_rows[0]}")
    if len(output_rows) > 1:
        lines.append(f"        omega_hat[k] = {output_rows[1]}")
    lines += ["        uk = u_in[k]", "        if write_u:", "            u[k] = uk"]
    lines += [f"        n{i} = {row}" for i, row in enumerate(update_rows)]
    lines += [f"        s{i} = n{i}" for i in range(n)]
    lines += [f"    s_init[{i}] = s{i}" for i in range(n)]  # the state after the last sample
    return "\n".join(lines) + "\n"


@functools.lru_cache(maxsize=64)
def offline_kernel(structure: tuple, n: int, velocity: int):
    """The compiled loop for ``structure``: generated once per process, its machine code cached
    on disk by numba where the cache directory is writable (else compiled once per process)."""
    return compiled_function(
        kernel_source(structure, n, velocity), kind="estimate-loops", prefix="hpdob_estimate_"
    )


def run(system, s_init, theta, omega, u, t, velocity: int, *, check=None):
    """Run ``system`` over the samples (finite float64 vectors of one length; ``omega`` None
    unless ``velocity`` is ``VELOCITY_GIVEN``, ``t`` None for ``k Ts``).

    ``check``, if given, is called without arguments before the result is returned (on a long
    log while the loop runs, which only reads the inputs and writes new arrays): an error it
    raises is raised instead of a result.

    Returns
    -------
    tuple
        Arrays ``(theta, omega, u, tau_hat, omega_hat, t, state)``: the inputs, copied unless
        they are immutable (:func:`~hpdob.identification._checks.immutable`: then shared; the
        copies are made by the loop, or from :data:`PARALLEL_SAMPLES` samples on by a
        second thread while the loop runs), ``omega`` None for ``VELOCITY_NONE`` and for
        ``VELOCITY_DERIVED``, whose backward difference the loop computes but does not write
        (the caller derives it from ``theta`` when needed), the outputs (``omega_hat`` None
        where the observer has none), the time (``t`` or a copy; None for ``k Ts``, not
        written either) and the state after the last sample.
    """
    program = system.program
    kernel = offline_kernel(program_structure(program), system.n_states, velocity)
    coefficients = np.array(program_coefficients(program)[: _count(program)], dtype=np.float64)
    n = theta.shape[0]
    empty = np.empty(0)

    def new(given):  # a new output unless the input can be shared
        return empty if given is not None and immutable(given) else np.empty(n)

    out = {
        "theta": new(theta),
        "omega": empty if velocity != VELOCITY_GIVEN else new(omega),
        "u": new(u),
        "tau_hat": np.empty(n),
        "omega_hat": np.empty(n) if system.has_velocity else empty,
        "t": empty if t is None else new(t),
    }
    state = np.array(s_init, dtype=np.float64)  # the kernel leaves the final state in it
    given = {"theta": theta, "omega": omega, "u": u, "tau_hat": None, "omega_hat": None, "t": t}
    inputs = [
        read_only_view(x)
        for x in (theta, empty if omega is None else omega, u, empty if t is None else t)
    ]  # one signature (read_only_view)
    copies = [(out[name], given[name]) for name in ("theta", "omega", "u", "t")
              if out[name].shape[0] > 0]  # fmt: skip
    if n >= PARALLEL_SAMPLES and (copies or check is not None):
        loop_outputs = {**out, "theta": empty, "omega": empty, "u": empty, "t": empty}
        failed: list = []
        worker = threading.Thread(
            target=_alongside, args=(check, copies, failed), name="hpdob-estimate-copy"
        )
        worker.start()
        try:
            kernel(coefficients, state, *inputs, *loop_outputs.values(), float(system.Ts))
        finally:
            worker.join()
        if failed:  # the check's error (a copy of arrays of one length and dtype cannot fail)
            raise failed[0]
    else:
        if check is not None:
            check()
        kernel(coefficients, state, *inputs, *out.values(), float(system.Ts))
    return (*(
        given[name] if array is empty and given[name] is not None
        else None if array is empty else array
        for name, array in out.items()
    ), state)  # fmt: skip


def _alongside(check, pairs, failed: list) -> None:
    """The work of :func:`run`'s second thread: the check, then the copies."""
    try:
        if check is not None:
            check()
        for destination, source in pairs:
            np.copyto(destination, source)
    except BaseException as error:  # re-raised by the caller's thread
        failed.append(error)


def run_block(system, state, theta, omega, u, tau_hat, omega_hat) -> None:
    """Run ``system`` from ``state`` (float64, updated in place to the state after the last
    sample) over one block of a log, writing only the estimates into ``tau_hat`` and
    ``omega_hat`` (None where the observer has none): the inputs are neither copied nor
    derived (``omega`` is the velocity, or None for a position-only observer)."""
    velocity = VELOCITY_NONE if omega is None else VELOCITY_GIVEN
    program = system.program
    kernel = offline_kernel(program_structure(program), system.n_states, velocity)
    coefficients = np.array(program_coefficients(program)[: _count(program)], dtype=np.float64)
    empty = np.empty(0)
    inputs = [read_only_view(x) for x in (theta, empty if omega is None else omega, u, empty)]
    kernel(coefficients, state, *inputs, empty, empty, empty, tau_hat,
           empty if omega_hat is None else omega_hat, empty, float(system.Ts))  # fmt: skip


def _count(program) -> int:
    """Number of non-unit coefficients of the update and output rows (the reset's follow)."""
    return sum(1 for rows in (program.update, program.output) for terms in rows for t in terms
               if abs(t.coefficient) != 1.0)  # fmt: skip
