r"""The sample loop's source, generated per run structure without numba.

:func:`loop_structure` says what a run's loop depends on, :func:`loop_source` writes its
source (the steps are described in :mod:`hpdob.simulation._kernel`, which compiles it with
numba) and :func:`loop_key` names a structure. Nothing here imports numba, so a process that
runs an ahead-of-time built loop (:mod:`hpdob.simulation._aot`) generates and recognises its
source without initialising numba.
"""

from __future__ import annotations

import functools
import hashlib
import re
from pathlib import Path

import numpy as np

from .._generated import sum_source
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
    "PARAMETERS",
    "PATH_PYTHON",
    "digest",
    "loop_key",
    "loop_source",
    "loop_structure",
]


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
        f"# hpdob closed-loop sample loop (generator {digest()})",
        "import math",
        "",
        "from hpdob.simulation._kernel import contact_torque, coulomb_torque",
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
        # eq. (3), _kernel.ground_truth's expression written inline: a call of it costs a
        # compile of its own in a fresh environment (~50 ms)
        (
            "estimation_error[k] = est - (uk - b_n * om - J_n * (accel / J_motor))"
            if errors
            else "tau_dn[k] = uk - b_n * om - J_n * (accel / J_motor)"
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
def digest() -> str:
    """A hash of the generator, of the module defining the helpers the loop calls
    (``hpdob.simulation._kernel``, read as a file, not imported) and of the Coulomb term's
    definition: a change of any gives new sources (new modules), so numba never loads machine
    code, and no ahead-of-time built loop is used, compiled from older ones."""
    here = Path(__file__)
    files = (here, here.with_name("_kernel.py"), Path(_coulomb_torque.__code__.co_filename))
    text = b"".join(name.read_bytes() for name in files)
    return hashlib.sha256(text).hexdigest()[:16]


def loop_key(structure: tuple) -> str:
    """A name for ``structure`` (:func:`loop_structure`) stable across processes."""
    return hashlib.sha256(repr(structure).encode()).hexdigest()[:16]


def run_structure(plant, ctl, sen, act, obs, sig, work, midpoint=None, errors=False) -> tuple:
    """:func:`loop_structure` of a run from its records (as ``run_samples`` computes it)."""
    return loop_structure(
        plant, ctl, sen, obs, sig, work.x.shape[0], midpoint, errors, act.delay != 0
    )


def signature_fields(source: str) -> tuple:
    """The ``(record, field)`` pairs a loop's source takes after ``k_start, k_stop, substeps,
    Ts, limit``, read from its ``def run(...)`` line (:data:`PARAMETERS`)."""
    signature = next(line for line in source.splitlines() if line.startswith("def run("))
    names = signature[len("def run(") : -len("):")].split(", ")[5:]
    where = {name: (record, field) for name, record, field in PARAMETERS}
    return tuple(where[name] for name in names)
