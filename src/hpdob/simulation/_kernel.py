r"""The compiled sample loop: one generator writes it per run structure, for every plant.

:func:`loop_source` writes the loop's source for a run's *structure* (:func:`loop_structure`:
the plant's sub-step path, its state size and contact, the sensor mode and whether it has
noise, the observer's and the controller's program structure and wiring, a latching switch,
the outputs recorded, the disturbance's form), with only the steps the run uses, the programs'
rows as straight-line sums over local variables (:func:`hpdob._generated.sum_source`: the
sums :func:`program_row` computes, term by term left to right, so the results are bit for bit
those of one generic loop, the runtime objects and the exported C) and the states in locals;
the generator is :mod:`hpdob.simulation._loop_source`, which imports no numba (an
ahead-of-time built loop, :mod:`hpdob.simulation._aot`, is recognised without numba).
:func:`sample_loop` compiles it once per structure and process with numba (``cache=True``,
the source kept under the numba cache directory as ``hpdob._generated`` does for the offline
estimation loops, so only the first process on a machine compiles a structure); the
coefficients are read from the run's records, so a sweep over bandwidths or inertias compiles
nothing after its first scenario. ``NUMBA_DISABLE_JIT=1`` runs the same source as plain
Python. This module is imported on the first simulation, never by ``import hpdob``.

Per sample ``k`` (``t_k = k Ts``) the loop runs, for every plant:

1. measure: ideal, or encoder (quantised angle with optional noise, backward-difference or
   exact velocity);
2. estimate: the observer's outputs :math:`\hat\tau_k (, \hat\omega_k) = H s_k + E v_k`
   (0 without observer), from its program (:class:`hpdob.observers.Program`), in exactly the
   operation order of the Python observer and the exported C; then an RTOB's Coulomb term
   (``LinearObserver.coulomb``) is subtracted from ``tau_reac``;
3. control: the controller's signal rows in order (:class:`hpdob.controllers.ControllerProgram`),
   from its state and its inputs wired by name (reference, measurement, observer outputs); the
   last signal is the command :math:`u_k` (or, for a controller with a latching
   :class:`~hpdob.controllers.Switch` that is on, its ``after`` signal plus ``offset``; the PD:
   :math:`J_n(k_p(r_k-\theta_{m,k}) + k_d(\dot r_k-\omega_{m,k}) + \ddot r_k) + \hat\tau_k`),
   clipped to the actuator limit;
4. observer update :math:`s_{k+1} = F s_k + G [v_k, u_k]` and controller update
   :math:`c_{k+1} = F_c c_k + G_c [v_k, \bar u_k]` with the clipped command;
5. the plant receives :math:`u_{k-d}` (``d`` samples of delay; 0 before the first command);
6. ground truth (eq. 3) just after :math:`u_{k-d}` is applied:
   :math:`\tau_{dn,k} = u_k - b_n\omega_k - J_n\ddot\theta(t_k^+)` (:func:`ground_truth`);
7. the plant's advance over :math:`[t_k, t_{k+1})`, with the external torque at the sub-step
   midpoints evaluated in the loop from the disturbance's coefficient table
   (:mod:`hpdob.simulation._signal_table`: hpdob's constants, steps, ramps, sines and their
   sums, numpy's operations in numpy's order) or read from the array sampled in numpy.

A plant with an :class:`~hpdob.Environment` records the contact torque and the in-contact flag
at :math:`t_k` with step 1 (``Outputs.tau_contact``, ``in_contact``); the contact torque is part
of the external torque :math:`F` below, evaluated like the Coulomb friction at the start and the
exponential midpoint of each sub-step (the angle and velocity of the contacting body there),
so a contact onset inside a sub-step is resolved to second order
(``tests/models/test_environment.py``: halving the default sub-step changes the contact torque by
< 1 % of its peak, measured 0.2 % on a 0.014 N m impact).

Only the plant's part (the acceleration of step 6 and step 7) differs per plant. For plants with
a linear part (:class:`~hpdob.ServoModel`, :class:`~hpdob.TwoMassServo`;
``plant.linear``) the loop does it in sub-steps of ``h = Ts/S``: the linear part exactly (ZOH
over the sub-step), the Coulomb friction and the external disturbance by an exponential
midpoint rule. With :math:`F(\omega, t) = c\tanh(\omega/v) + \tau_{ext}(t)` and
:math:`t_{j+1/2}` the sub-step midpoint:

.. math::

    x_{j+1/2} = A_{h/2} x_j + B_{h/2}\,(u - F(\omega_j, t_{j+1/2})),\qquad
    x_{j+1} = A_h x_j + B_h\,(u - F(\omega_{j+1/2}, t_{j+1/2})),

second order in ``h`` for smooth forcing, and exact for disturbance steps on sub-step
boundaries (the canonical ones are at half samples, so any even ``S`` aligns them). The plant's
sampler names the path that advances it (``ExactSubsteps.path``): ``"rigid"`` and
``"two-mass"`` hold the state in registers, ``"generic"`` loops over any state size
(``tests/models/test_plant.py`` checks it against the exact ZOH recurrence). A plant
advanced from Python (MuJoCo) calls :func:`run_samples` for one sample at a time, whose loop
(path ``PATH_PYTHON``) stops after step 5 and leaves steps 6-7 to the plant
(``hpdob.simulation._python_plant``).

The step is generated inline in the loop: a per-sample call of a numba function taking the
run's records costs more than the step itself (their arrays are reference-counted at every call
boundary). The generated module carries a hash of the generator, of this module and of the
Coulomb term's definition, so a change of any gives new sources and numba never loads machine
code compiled from older ones.
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

import numba

from .._generated import compiled_function
from ..observers import coulomb_torque as _coulomb_torque
from ._loop_source import (
    PARAMETERS,
    PATH_PYTHON,
    loop_key,
    loop_source,
    loop_structure,
    run_structure,
    signature_fields,
)
from ._loop_source import digest as _digest
from ._records import PATH_GENERIC, PATH_RIGID, PATH_TWO_MASS
from ._signal_table import midpoint_source

__all__ = [
    "PARAMETERS",
    "PATH_GENERIC",
    "PATH_PYTHON",
    "PATH_RIGID",
    "PATH_TWO_MASS",
    "contact_torque",
    "ground_truth",
    "loop_key",
    "loop_source",
    "loop_structure",
    "midpoint_filler",
    "program_row",
    "run_samples",
    "sample_loop",
]

_jit = numba.njit(cache=True, nogil=True)

#: The RTOB's Coulomb term, compiled from its one definition (``hpdob.observers._friction``).
coulomb_torque = _jit(_coulomb_torque)


@_jit
def program_row(pointer, coefficient, operand, w, row):
    """Row ``row`` of an observer's program: the left-to-right sum of
    ``coefficient[t] * w[operand[t]]`` over its terms (0 for an empty row)."""
    start, stop = pointer[row], pointer[row + 1]
    if start == stop:
        return 0.0
    acc = coefficient[start] * w[operand[start]]
    for t in range(start + 1, stop):
        acc += coefficient[t] * w[operand[t]]
    return acc


@_jit
def ground_truth(uk, om, accel, J_n, b_n):
    r"""Eq. (3) at :math:`t_k^+`: :math:`\tau_{dn,k} = u_k - b_n\omega_k - J_n\ddot\theta`."""
    return uk - b_n * om - J_n * accel


@_jit
def contact_torque(th, om, k_e, c_e, th_e):
    r"""The unilateral environment's torque: :math:`k_e(\theta-\theta_e) + c_e\omega` where
    :math:`\theta > \theta_e` and that pushes, else 0 (:class:`hpdob.Environment`)."""
    if th <= th_e:
        return 0.0
    push = k_e * (th - th_e) + c_e * om
    return push if push > 0.0 else 0.0


#: For mutation testing only (``benchmarks/mutation_kernel.py``): a directory of loop sources
#: named ``<loop_key(structure)>.py``; a structure with a file there runs that file's loop,
#: compiled from memory (no on-disk cache, so a mutated file is always compiled anew). Unset,
#: or without a file for the structure, nothing changes.
OVERRIDE_VARIABLE = "HPDOB_MUTATION_LOOPS"


@functools.lru_cache(maxsize=256)
def sample_loop(structure: tuple):
    """The compiled sample loop of ``structure`` (:func:`loop_structure`) and the record
    fields it takes after ``k_start, k_stop, substeps, Ts, limit`` (``(record, field)`` pairs,
    :data:`PARAMETERS`): generated and compiled once per structure and process, its machine
    code cached on disk by numba (or read from :data:`OVERRIDE_VARIABLE`'s directory)."""
    directory = os.environ.get(OVERRIDE_VARIABLE)
    override = Path(directory, f"{loop_key(structure)}.py") if directory else None
    if override is not None and override.is_file():
        source = override.read_text(encoding="utf-8")
    else:
        override, source = None, loop_source(structure)
    kernel = compiled_function(
        source, kind="sample-loops", prefix="hpdob_loop_", cache=override is None
    )
    return kernel, signature_fields(source)


def run_samples(
    k_start, k_stop, substeps, Ts, plant, ctl, sen, act, obs, sig, out, work, limit, midpoint=None,
    errors=False,
):  # fmt: skip
    """Run samples ``k_start <= k < k_stop``; return the number of samples completed.

    With a linear plant the plant is advanced here and a return value below ``k_stop`` means
    its state left ``|x| <= limit`` (or became non-finite) at the end of the last completed
    sample. Otherwise one sample's steps 1-5 run (the plant's state ``work.x`` set by the
    caller) and ``work.applied[0]`` holds the torque to apply. The loop is the one compiled
    for the run's structure (:func:`sample_loop`); ``errors``: the loop that records only the
    error traces (``out.estimation_error``, ``out.position_error``; see :func:`loop_source`).
    """
    structure = run_structure(plant, ctl, sen, act, obs, sig, work, midpoint, errors)
    kernel, fields = sample_loop(structure)
    records = {"plant": plant, "ctl": ctl, "sen": sen, "act": act, "obs": obs, "sig": sig,
               "out": out, "work": work}  # fmt: skip
    arguments = [getattr(records[record], field) for record, field in fields]
    return kernel(k_start, k_stop, substeps, Ts, limit, *arguments)


@functools.lru_cache(maxsize=64)
def midpoint_filler(form):
    """A compiled ``run(n, substeps, Ts, table, out)`` that writes the disturbance of ``form``
    (:func:`~hpdob.simulation._signal_table.midpoint_table`) at every sub-step midpoint,
    ``out[k substeps + j]`` at ``t = k Ts + (j + 1/2) Ts/substeps``, with the statements the
    sample loop evaluates it by (:func:`loop_source`: the same ``t`` and ``h``, the same
    operations in the same order, the factor ``table[0]`` last), so a loop that reads ``out``
    computes what the loop evaluating the table inline computes, bit for bit: a sweep fills
    one array per time grid instead of evaluating the signal in every scenario's loop."""
    loads, evaluate = midpoint_source(form, "t_mid", "table", "tau_e")
    lines = [
        f"# hpdob sub-step midpoints of a disturbance table (generator {_digest()})",
        "import math",
        "",
        "",
        "def run(n, substeps, Ts, table, out):",
        "    factor = table[0]",
        "    h = Ts / substeps",
        *("    " + line for line in loads),
        "    for k in range(n):",
        "        t_k = k * Ts",
        "        for j in range(substeps):",
        "            t_mid = t_k + (j + 0.5) * h",
        *("            " + line for line in evaluate),
        "            out[k * substeps + j] = factor * tau_e",
    ]
    return compiled_function("\n".join(lines) + "\n", kind="sample-loops", prefix="hpdob_mid_")
