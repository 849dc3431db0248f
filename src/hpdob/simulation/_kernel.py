r"""The compiled sample loop: one generator writes it per run structure, for every plant.

:func:`loop_source` writes the loop's source for a run's *structure* (:func:`loop_structure`:
the plant's sub-step path, its state size and contact, the sensor mode and whether it has
noise, the observer's and the controller's program structure and wiring, a latching switch,
the outputs recorded, the disturbance's form), with only the steps the run uses, the programs'
rows as straight-line sums over local variables (:func:`hpdob._generated.sum_source`: the
sums :func:`program_row` computes, term by term left to right, so the results are bit for bit
those of one generic loop, the runtime objects and the exported C) and the states in locals.
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
boundary). The generated module carries a hash of this module and of the Coulomb term's
definition, so a change of either gives new sources and numba never loads machine code compiled
from older ones.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import os
import re
import sys
from pathlib import Path

import numba
import numpy as np

from .._generated import compiled_function, sum_source
from ..observers import coulomb_torque as _coulomb_torque
from ._records import (
    PATH_GENERIC,
    PATH_RIGID,
    PATH_TWO_MASS,
    SENSOR_ENCODER_DIFFERENCE,
    SENSOR_ENCODER_EXACT,
    SENSOR_IDEAL,
)
from ._signal_table import midpoint_source

__all__ = [
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


# ---------------------------------------------------------------------------------------------
# The structure of a run and the loop generated for it

#: The path of a plant advanced from Python (the loop stops after step 5).
PATH_PYTHON = -1


def _shape(pointer, coefficient, operand) -> tuple:
    """What the generated code depends on in a program's rows (as
    :func:`hpdob.observers.program_structure`), read from the arrays the loop reads: the row
    pointers, each term's operand and +1/-1 for a unit term (written without a factor), 0 for a
    term with a factor; as bytes (hashed without a Python loop over the terms, see
    :func:`_rows`)."""
    unit = tuple([1 if c == 1.0 else -1 if c == -1.0 else 0 for c in coefficient.tolist()])
    return pointer.tobytes(), operand.tobytes(), unit


def _rows(shape) -> tuple:
    """``shape`` (:func:`_shape`) as rows of ``(operand, unit)`` terms."""
    p = np.frombuffer(shape[0], dtype=np.int64).tolist()
    o = np.frombuffer(shape[1], dtype=np.int64).tolist()
    u = shape[2]
    return tuple(tuple((o[t], u[t]) for t in range(p[i], p[i + 1])) for i in range(len(p) - 1))


def loop_structure(
    plant, ctl, sen, obs, sig, nx: int, midpoint=None, errors=False, delayed=True
) -> tuple:
    """What the generated sample loop depends on, apart from the values it reads: the plant's
    path (and state size, velocity and contact indices, whether it has a contact), the sensor
    mode and whether it has noise, the observer's and the controller's program structure and
    wiring, whether the actuator delays the command (``delayed``: else the plant receives
    ``u_k`` itself, not read back from ``u``), and what it records (``errors``: only the two
    error traces a sweep's metrics read, :func:`loop_source`). Two runs of one structure run
    one compiled function (a sweep over bandwidths or inertias compiles nothing after its first
    scenario)."""
    observer = None
    if obs.present:
        observer = (
            obs.n,
            obs.p,
            obs.q,
            obs.velocity_row,
            obs.reaction_row,
            obs.coulomb_source,
            _shape(obs.update_pointer, obs.update_coefficient, obs.update_operand),
            _shape(obs.output_pointer, obs.output_coefficient, obs.output_operand),
        )
    switch = (
        None if ctl.switch_latch < 0 else (ctl.switch_latch, ctl.switch_trigger, ctl.switch_after)
    )
    controller = (
        ctl.n,
        ctl.p,
        ctl.q,
        ctl.source.tobytes(),
        _shape(ctl.signal_pointer, ctl.signal_coefficient, ctl.signal_operand),
        _shape(ctl.update_pointer, ctl.update_coefficient, ctl.update_operand),
        switch,
    )
    path = plant.path if plant.linear else PATH_PYTHON
    wall = bool(plant.contact) and plant.linear
    return (
        path,
        nx,
        plant.velocity_index,
        plant.contact_index if wall else 0,
        wall,
        sen.mode,
        sig.noise.shape[0] > 0,
        observer,
        controller,
        midpoint if plant.linear else None,
        bool(errors) and plant.linear,
        bool(delayed),
    )


def _names(prefix: str, shape) -> list:
    """The local names of the non-unit coefficients of ``shape``'s rows: ``prefix`` and the
    term's index in the flat coefficient array."""
    names, t = [], 0
    for row in shape:
        for _, unit in row:
            if not unit:
                names.append(f"{prefix}{t}")
            t += 1
    return names


def _loads(array: str, names) -> list:
    return [f"{name} = {array}[{name.lstrip('abcdefghijklmnopqrstuvwxyz_')}]" for name in names]


#: The signals a controller input may read (``ControllerRecord.source``): the reference, the
#: measurement, the observer's outputs.
_SIGNALS = ("r_k", "r_dot_k", "r_ddot_k", "thm", "omm", "est")


def loop_source(structure: tuple) -> str:
    """The source of the sample loop ``run(k_start, k_stop, substeps, Ts, limit, ...)`` for
    ``structure`` (:func:`loop_structure`), whose further parameters are the record fields its
    body reads (:data:`PARAMETERS`).

    The observer's and the controller's rows are written as straight-line sums
    (:func:`hpdob._generated.sum_source`) over local variables, their coefficients read once
    from the records' arrays; the states are kept in locals and written back to ``work``'s
    arrays on return.

    With ``errors`` (a sweep's loop: its rows read nothing else) the loop records, instead of
    ``theta``, ``omega``, ``theta_m``, ``omega_m``, ``tau_hat``, ``tau_dn`` and the plant's
    states, only ``estimation_error[k] = tau_hat_k - tau_dn_k`` and ``position_error[k] =
    theta_k - r_k``: the one IEEE subtraction numpy's ``result.tau_hat - result.tau_dn`` and
    ``result.theta - result.r`` perform on the recorded values, so the metrics computed from
    them are bit for bit those of a full run; ``u`` (the delay line) and the optional outputs
    are recorded as in a full run.
    """
    path, nx, v, ci, wall, mode, noisy, observer, controller, midpoint, errors, delayed = structure
    nc, _, qc, source, c_signals, c_update, switch = controller
    source = np.frombuffer(source, dtype=np.int64).tolist()
    c_signals, c_update = _rows(c_signals), _rows(c_update)
    rigid, two_mass, generic, python = (
        path == p for p in (PATH_RIGID, PATH_TWO_MASS, PATH_GENERIC, PATH_PYTHON)
    )
    lines: list = []

    def put(depth: int, *texts: str) -> None:
        lines.extend("    " * depth + text for text in texts)

    put(
        0,
        f"# hpdob closed-loop sample loop (generator {_digest()})",
        "import math",
        "",
        "from hpdob.simulation._kernel import contact_torque, coulomb_torque, ground_truth",
        "",
        "",
        "SIGNATURE",
    )
    store = []  # the state written back to ``work`` before every return
    signals = list(_SIGNALS)
    if observer is not None:
        n, p, q, velocity_row, reaction_row, coulomb_source, o_update, o_output = observer
        o_update, o_output = _rows(o_update), _rows(o_output)
        signals += [f"y{j}" for j in range(1, q)]
        o_update_names, o_output_names = _names("ou", o_update), _names("oo", o_output)
        put(1, *_loads("ou", o_update_names), *_loads("oo", o_output_names))
        put(1, *(f"s{i} = s_[{i}]" for i in range(n)))
        store += [f"s_[{i}] = s{i}" for i in range(n)]
    c_signal_names, c_update_names = _names("cs", c_signals), _names("cu", c_update)
    put(1, *_loads("cs", c_signal_names), *_loads("cu", c_update_names))
    put(1, *(f"c{i} = c_[{i}]" for i in range(nc)))
    store += [f"c_[{i}] = c{i}" for i in range(nc)]
    if mode == SENSOR_ENCODER_DIFFERENCE:
        put(1, "prev = previous[0]")
        store.append("previous[0] = prev")
    if python:
        put(1, "record = states.shape[0] > 0")
    else:
        if midpoint is not None:  # the disturbance's table: [factor, coefficients]
            loads, evaluate = midpoint_source(midpoint, "t_mid", "table", "tau_e")
            put(1, "factor = table[0]", "h = Ts / substeps", *loads)
    if rigid:
        put(
            1,
            "a00, a01, a10, a11 = A_h[0, 0], A_h[0, 1], A_h[1, 0], A_h[1, 1]",
            "h10, h11, b0, b1, g1 = A_half[1, 0], A_half[1, 1], B_h[0], B_h[1], B_half[1]",
            "h00, h01, g0 = A_half[0, 0], A_half[0, 1], B_half[0]",
            "i0, i1 = internal[0], internal[1]",
            "th, om = x[0], x[1]",
        )
        store += ["x[0] = th", "x[1] = om"]
        state = ["th", "om"]
    elif two_mass:
        put(
            1,
            "h0, h1, h2, h3 = A_half[1, 0], A_half[1, 1], A_half[1, 2], A_half[1, 3]",
            "gb, gd = B_half[1], D_half[1]",
            "i0, i1, i2, i3 = internal[0], internal[1], internal[2], internal[3]",
            "x0, x1, x2, x3 = x[0], x[1], x[2], x[3]",
        )
        store.append("x[0], x[1], x[2], x[3] = x0, x1, x2, x3")
        state = ["x0", "x1", "x2", "x3"]
    elif generic:
        put(1, "nx = x.shape[0]", *(() if errors else ("record = states.shape[0] > 0",)))
    put(1, "for k in range(k_start, k_stop):")
    if rigid:
        pass
    elif two_mass:
        put(2, "th = x0", f"om = x{v}")
    else:
        put(2, "th = x[0]", f"om = x[{v}]")
    if errors:  # theta_k - r_k, as numpy subtracts the recorded traces
        put(2, "position_error[k] = th - r_in[k]")
    else:
        put(2, "theta[k] = th", "omega[k] = om")
    if errors:
        pass
    elif two_mass:
        put(2, *(f"states[k, {i}] = x{i}" for i in range(nx)))
    elif generic or python:
        put(2, "if record:", "    for i in range(x.shape[0]):", "        states[k, i] = x[i]")
    if wall:
        at = (
            (f"x{ci}", f"x{ci + 1}")
            if two_mass
            else state[ci : ci + 2]
            if rigid
            else (f"x[{ci}]", f"x[{ci + 1}]")
        )
        put(
            2,
            f"f_env = contact_torque({at[0]}, {at[1]}, k_e, c_e, th_e)",
            "tau_contact[k] = f_env",
            "in_contact[k] = 1.0 if f_env > 0.0 else 0.0",
        )
    else:
        put(2, "f_env = 0.0")
    put(2, "# 1. measurement")
    if mode == SENSOR_IDEAL:
        put(2, "thm = th", "omm = om")
    else:
        put(
            2,
            "thm = resolution * math.floor("
            + ("(th + noise[k])" if noisy else "th")
            + " / resolution + 0.5)",
        )  # th + 0.0 rounds to th: the same count
        if mode == SENSOR_ENCODER_EXACT:
            put(2, "omm = om")
        else:
            put(
                2,
                "if k == 0:",
                "    omm = 0.0",
                "else:",
                "    omm = (thm - prev) / Ts",
                "prev = thm",
            )
    if not errors:
        put(2, "theta_m[k] = thm", "omega_m[k] = omm")
    put(2, "# 2. estimate: the observer's output rows, left to right")
    if observer is not None:
        operands = [*(f"s{i}" for i in range(n)), "thm", *(("omm",) if p == 2 else ()), "uk"]
        names = iter(o_output_names)
        rows = [sum_source(row, operands, names) for row in o_output]
        put(2, f"est = {rows[0]}", *(f"y{j} = {rows[j]}" for j in range(1, q)))
        if coulomb_source:  # the RTOB's Coulomb term, after the linear rows
            speed = "omm" if coulomb_source == 1 else f"y{velocity_row}"
            put(2, f"y{reaction_row} = y{reaction_row} - coulomb_torque(c_n, v_n, {speed}, d_n)")
        if velocity_row > 0:
            put(2, f"omega_hat[k] = y{velocity_row}")
        if reaction_row > 0:
            put(2, f"tau_reac[k] = y{reaction_row}")
    else:
        put(2, "est = 0.0")
    if not errors:
        put(2, "tau_hat[k] = est")
    for j, name in enumerate(("r_in", "r_dot_in", "r_ddot_in")):
        if j in source:
            put(2, f"{_SIGNALS[j]} = {name}[k]")
    put(2, "# 3. control: the controller's signal rows in order, the last is the command")
    c_operands = [
        *(f"c{i}" for i in range(nc)),
        *(signals[j] for j in source),
        "uk",
        *(f"q{j}" for j in range(qc)),
    ]
    names = iter(c_signal_names)
    put(2, *(f"q{j} = {sum_source(row, c_operands, names)}" for j, row in enumerate(c_signals)))
    put(2, f"uk = q{qc - 1}")
    if switch is not None:  # a latching switch (hpdob.controllers.Switch), after the signals
        latch, trigger, after = switch
        put(
            2,
            f"on = c{latch} != 0.0 or {c_operands[trigger]} >= threshold",
            "if on:",
            f"    uk = q{after} + offset",
        )
    put(
        2,
        "if uk > torque_limit:",
        "    uk = torque_limit",
        "elif uk < -torque_limit:",
        "    uk = -torque_limit",
        "u[k] = uk",
    )
    put(2, "# 4. observer and controller updates with the command really given")
    if observer is not None:
        names = iter(o_update_names)
        put(2, *(f"n{i} = {sum_source(row, operands, names)}" for i, row in enumerate(o_update)))
        put(2, *(f"s{i} = n{i}" for i in range(n)))
    if nc:
        names = iter(c_update_names)
        put(2, *(f"d{i} = {sum_source(row, c_operands, names)}" for i, row in enumerate(c_update)))
        if switch is not None:
            put(2, f"d{switch[0]} = 1.0 if on else 0.0")
        put(2, *(f"c{i} = d{i}" for i in range(nc)))
    # without a delay the command itself: u[k - 0] read back from memory is uk, but the
    # store-to-load round trip sits on the loop's critical path (6 % of a canonical run)
    applied = "u[k - delay] if k >= delay else 0.0" if delayed else "uk"
    put(2, "# 5. actuator delay", f"applied = {applied}")
    if python:
        put(2, "applied_out[0] = applied", *store, "return k + 1")
        put(1, *store, "return k_stop")
        return _with_signature(lines)
    put(
        2,
        "# 6. ground truth just after u is applied: the motor's acceleration",
        "tau = tau_sample[k]",
        "accel = applied",
    )
    if rigid or two_mass:
        for i, name in enumerate(state):
            put(2, f"if i{i} != 0.0:", f"    accel -= i{i} * {name}")
    else:
        put(
            2,
            "for i in range(nx):",
            "    if internal[i] != 0.0:",
            "        accel -= internal[i] * x[i]",
        )
    put(
        2,
        "accel -= c * math.tanh(om / c_scale)",
        "if shared:",
        "    accel -= tau + f_env",
        (
            "estimation_error[k] = est - ground_truth(uk, om, accel / J_motor, J_n, b_n)"
            if errors
            else "tau_dn[k] = ground_truth(uk, om, accel / J_motor, J_n, b_n)"
        ),
        "# 7. the plant over [t_k, t_{k+1}): exponential midpoint sub-steps",
    )
    if midpoint is None:
        put(2, "base = k * substeps", "for j in range(substeps):", "    tau_e = tau_mid[base + j]")
    else:  # the disturbance at t_k + (j + 1/2) h, as sample_signals' numpy would give it
        put(2, "t_k = k * Ts", "for j in range(substeps):", "    t_mid = t_k + (j + 0.5) * h")
        put(3, *evaluate, "tau_e = factor * tau_e")
    put(3, "start = tau_e")
    for text in _substep(path, wall):
        put(3, text)
    if rigid or two_mass:
        test = " or ".join(f"not abs({name}) <= limit" for name in state)
        put(2, f"if {test}:", *("    " + line for line in store), "    return k + 1")
    else:
        put(
            2,
            "for i in range(nx):",
            "    if not abs(x[i]) <= limit:",
            *("        " + line for line in store),
            "        return k + 1",
        )
    put(1, *store, "return k_stop")
    return _with_signature(lines)


#: The loop's parameters after ``k_start, k_stop, substeps, Ts, limit``: its local name, the
#: record and the field it is read from; a loop takes those its body uses, in this order (flat
#: arguments: numba compiles and calls a function of records' fields far faster than one of
#: the records).
PARAMETERS = (
    ("r_in", "sig", "r"), ("r_dot_in", "sig", "r_dot"), ("r_ddot_in", "sig", "r_ddot"),
    ("tau_sample", "sig", "tau_sample"), ("tau_mid", "sig", "tau_mid"), ("noise", "sig", "noise"),
    ("table", "sig", "table"),
    *((name, "out", name) for name in ("theta", "omega", "theta_m", "omega_m", "u", "tau_hat",
                                       "tau_dn", "omega_hat", "states", "tau_contact",
                                       "in_contact", "tau_reac", "estimation_error",
                                       "position_error")),
    ("x", "work", "x"), ("x_next", "work", "x_next"), ("s_", "work", "s"), ("c_", "work", "c"),
    ("previous", "work", "previous"), ("applied_out", "work", "applied"),
    ("resolution", "sen", "resolution"),
    ("torque_limit", "act", "torque_limit"), ("delay", "act", "delay"),
    ("J_n", "ctl", "J_n"), ("b_n", "ctl", "b_n"), ("cs", "ctl", "signal_coefficient"),
    ("cu", "ctl", "update_coefficient"), ("threshold", "ctl", "switch_threshold"),
    ("offset", "ctl", "switch_offset"),
    ("ou", "obs", "update_coefficient"), ("oo", "obs", "output_coefficient"),
    ("c_n", "obs", "coulomb"), ("v_n", "obs", "coulomb_velocity"),
    ("d_n", "obs", "coulomb_deadband"),
    *((name, "plant", name) for name in ("A_h", "B_h", "D_h", "A_half", "B_half", "D_half",
                                         "internal", "shared")),
    ("c", "plant", "coulomb"), ("c_scale", "plant", "coulomb_velocity"),
    ("J_motor", "plant", "J_motor"), ("k_e", "plant", "contact_stiffness"),
    ("c_e", "plant", "contact_damping"), ("th_e", "plant", "contact_position"),
    ("v", "plant", "velocity_index"), ("ci", "plant", "contact_index"),
)  # fmt: skip


def _used(lines) -> tuple:
    """The :data:`PARAMETERS` the body ``lines`` reads."""
    words = set(re.findall(r"[A-Za-z_][A-Za-z_0-9]*", "\n".join(lines)))
    return tuple(p for p in PARAMETERS if p[0] in words)


def _with_signature(lines) -> str:
    body = [line for line in lines if line != "SIGNATURE"]
    names = ", ".join(p[0] for p in _used(body))
    signature = f"def run(k_start, k_stop, substeps, Ts, limit, {names}):"
    return "\n".join(signature if line == "SIGNATURE" else line for line in lines) + "\n"


def _substep(path: int, wall: bool) -> list:
    """The body of one sub-step (after ``tau_e``, ``start`` = the disturbance at its midpoint)
    of the plant's path: the exponential midpoint rule, the contact torque only with a wall."""
    if path == PATH_RIGID:  # the rigid servo, kept in registers
        return [
            *(["start += contact_torque(th, om, k_e, c_e, th_e)"] if wall else []),
            "force = applied - c * math.tanh(om / c_scale) - start",
            "om_half = h10 * th + h11 * om + g1 * force",
            *(
                [
                    "th_half = h00 * th + h01 * om + g0 * force",
                    "tau_e += contact_torque(th_half, om_half, k_e, c_e, th_e)",
                ]
                if wall
                else []
            ),
            "force = applied - c * math.tanh(om_half / c_scale) - tau_e",
            "th, om = a00 * th + a01 * om + b0 * force, a10 * th + a11 * om + b1 * force",
        ]
    if path == PATH_TWO_MASS:  # the two-mass drive, kept in registers

        def load(row):
            return (
                " + ".join(f"A_half[{row}, {i}] * x{i}" for i in range(4))
                + f" + B_half[{row}] * force - D_half[{row}] * start"
            )

        def advance(row):
            return " + ".join(f"A_h[{row}, {i}] * x{i}" for i in range(4))

        return [
            *(["start += contact_torque(x2, x3, k_e, c_e, th_e)"] if wall else []),
            "force = applied - c * math.tanh(x1 / c_scale)",
            "om_half = h0 * x0 + h1 * x1 + h2 * x2 + h3 * x3 + gb * force - gd * start",
            *(
                [
                    f"load_th = {load(2)}",
                    f"load_om = {load(3)}",
                    "tau_e += contact_torque(load_th, load_om, k_e, c_e, th_e)",
                ]
                if wall
                else []
            ),
            "force = applied - c * math.tanh(om_half / c_scale)",
            *(f"y{row} = {advance(row)}" for row in range(4)),
            *(f"x{row} = y{row} + B_h[{row}] * force - D_h[{row}] * tau_e" for row in range(4)),
        ]
    # any plant (the path its sampler names): the motor's velocity row (and the contacting
    # body's rows) at the midpoint, then every row
    return [
        *(["start += contact_torque(x[ci], x[ci + 1], k_e, c_e, th_e)"] if wall else []),
        "force = applied - c * math.tanh(x[v] / c_scale)",
        "for row in range(nx):",
        "    if row != v" + (" and row != ci and row != ci + 1" if wall else "") + ":",
        "        continue",
        "    acc = A_half[row, 0] * x[0]",
        "    for i in range(1, nx):",
        "        acc += A_half[row, i] * x[i]",
        "    if shared:",
        "        acc += B_half[row] * (force - start)",
        "    else:",
        "        acc += B_half[row] * force",
        "        acc -= D_half[row] * start",
        "    x_next[row] = acc",
        "om_half = x_next[v]",
        *(["tau_e += contact_torque(x_next[ci], x_next[ci + 1], k_e, c_e, th_e)"] if wall else []),
        "force = applied - c * math.tanh(om_half / c_scale)",
        "for row in range(nx):",
        "    acc = A_h[row, 0] * x[0]",
        "    for i in range(1, nx):",
        "        acc += A_h[row, i] * x[i]",
        "    if shared:",
        "        acc += B_h[row] * (force - tau_e)",
        "    else:",
        "        acc += B_h[row] * force",
        "        acc -= D_h[row] * tau_e",
        "    x_next[row] = acc",
        "for row in range(nx):",
        "    x[row] = x_next[row]",
    ]


@functools.cache
def _digest() -> str:
    """A hash of the generator and the helpers the loop calls: a change of either gives new
    sources (new modules), so numba never loads machine code compiled from older ones."""
    files = (sys.modules[__name__].__file__, inspect.getsourcefile(_coulomb_torque))
    text = b"".join(Path(name).read_bytes() for name in files)
    return hashlib.sha256(text).hexdigest()[:16]


#: For mutation testing only (``benchmarks/mutation_kernel.py``): a directory of loop sources
#: named ``<loop_key(structure)>.py``; a structure with a file there runs that file's loop,
#: compiled from memory (no on-disk cache, so a mutated file is always compiled anew). Unset,
#: or without a file for the structure, nothing changes.
OVERRIDE_VARIABLE = "HPDOB_MUTATION_LOOPS"


def loop_key(structure: tuple) -> str:
    """A name for ``structure`` (:func:`loop_structure`) stable across processes."""
    return hashlib.sha256(repr(structure).encode()).hexdigest()[:16]


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
    signature = next(line for line in source.splitlines() if line.startswith("def run("))
    names = signature[len("def run(") : -len("):")].split(", ")[5:]
    where = {name: (record, field) for name, record, field in PARAMETERS}
    kernel = compiled_function(
        source, kind="sample-loops", prefix="hpdob_loop_", cache=override is None
    )
    return kernel, tuple(where[name] for name in names)


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
    structure = loop_structure(
        plant, ctl, sen, obs, sig, work.x.shape[0], midpoint, errors, act.delay != 0
    )
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
