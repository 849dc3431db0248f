r"""The linear sampled-data closed loop of :func:`hpdob.simulate` as an LTI system.

Per sample ``k`` (the order of :func:`hpdob.simulate`, Coulomb friction and saturation left out):

.. math::

    \theta_{m,k} &= \theta_k + n_{\theta,k}, \qquad
    \omega_{m,k} = \omega_k + n_{\omega,k}
    \ \ (\text{or } (\theta_{m,k} - \theta_{m,k-1})/T_s + n_{\omega,k}), \\
    y_k &= H s_k + E [x_{m,k}], \qquad s_{k+1} = F s_k + G [x_{m,k}, u_k]
    \quad (\text{the observer: } y = \hat\tau(, \hat\omega)), \\
    u_k &= H_c c_k + E_c v_k, \qquad c_{k+1} = F_c c_k + G_c [v_k, u_k]
    \quad (\text{the controller, } \bar u_k = u_k), \\
    x_{k+1} &= A x_k + B\,(u_{k-d} - \tau_{ext,k}),

with ``A, B`` the exact ZOH discretisation of the *true* plant, the external torque held over
the sample and :math:`v_k` the controller's inputs wired by name (reference, measurement,
observer outputs); for the PD :math:`u_k = J_n(\ddot r_k + k_p(r_k - \theta_{m,k}) + k_d(\dot
r_k - \omega_{m,k})) + \hat\tau_k`. The state is
``[theta, omega, (theta_prev), (u_delay1..d), (z1..z{m+1}), (controller states)]``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._validation import ParameterTypeError, ParameterValueError, as_real
from ..controllers import LinearController
from ..observers import LinearObserver
from ..simulation import ServoLoop

__all__ = [
    "INPUTS",
    "OUTPUTS",
    "LoopSpec",
    "delay_state",
    "delayed_state_matrix",
    "loop_matrices",
    "loop_spec",
    "state_names",
]

#: Inputs of :func:`hpdob.closed_loop`: reference and its derivatives [rad, rad/s, rad/s^2],
#: external torque [N m] (opposing the motor, as in :func:`hpdob.simulate`), measurement noise
#: on position [rad] and on velocity [rad/s].
INPUTS = ("r", "r_dot", "r_ddot", "tau_ext", "n_theta", "n_omega")
#: Outputs: true position [rad] and velocity [rad/s], command [N m], estimate [N m].
OUTPUTS = ("theta", "omega", "u", "tau_hat")


#: Longest actuator delay [samples] of the linear loop: each sample adds a state.
MAX_DELAY_SAMPLES = 1000


@dataclass(frozen=True, eq=False)
class LoopSpec:
    """Validated ingredients of the linear loop (internal).

    ``plant`` is the true plant's linear ZOH model (``A, B, D, C, state_names``). ``system``
    is a checked :class:`~hpdob.observers.LinearObserver`, or anything with its ``F, G, H, E,
    measures, outputs, n_states`` (the describing-function scan's changed copies of one).
    """

    plant: object
    controller: LinearController
    system: LinearObserver | None
    backward_difference: bool
    delay: int

    @property
    def Ts(self) -> float:
        return self.plant.Ts


def loop_spec(loop: ServoLoop) -> LoopSpec:
    """The linear ingredients of a :class:`~hpdob.ServoLoop` (raises for what is not linear)."""
    actuator = loop.actuator
    if actuator.torque_limit is not None:
        raise ParameterValueError(
            "actuator.torque_limit must be None for the linear loop (saturation is not "
            f"linear), got {actuator.torque_limit!r}"
        )
    if actuator.delay_samples > MAX_DELAY_SAMPLES:
        raise ParameterValueError(
            f"actuator.delay_samples must be at most {MAX_DELAY_SAMPLES} for the linear loop "
            f"(each sample of delay adds a state), got {actuator.delay_samples}"
        )
    sensor = loop.sensor
    return LoopSpec(
        plant=loop.plant.discretize(loop.Ts),
        controller=loop.controller_system,
        system=loop.system,
        backward_difference=sensor is not None and sensor.velocity == "backward-difference",
        delay=actuator.delay_samples,
    )


def state_names(spec: LoopSpec) -> list[str]:
    names = list(spec.plant.state_names)
    if spec.backward_difference:
        names.append("theta_prev")
    names += [f"u_delay{i + 1}" for i in range(spec.delay)]
    if spec.system is not None:
        letter = "z" if spec.system.truncation_order is not None else "s"
        names += [f"{letter}{i + 1}" for i in range(spec.system.n_states)]
    controller = spec.controller
    given = controller.program.state_names
    names += [f"controller_{given[i] if i < len(given) else f'c{i + 1}'}"
              for i in range(controller.n_states)]  # fmt: skip
    return names


def loop_matrices(
    spec: LoopSpec,
    *,
    broken: bool = False,
    measurement_gain: float = 1.0,
    command_gain: float = 1.0,
    signals: tuple = (),
):
    r"""``(A, B, C, D, inputs, outputs)`` of the loop as numpy arrays.

    With ``broken=False`` the inputs are :data:`INPUTS` and the outputs :data:`OUTPUTS` plus
    ``"a"``, the torque the plant receives (``u`` delayed). With ``broken=True`` the loop is
    cut at the plant input: the plant is driven by an extra last input ``"a_in"`` instead of
    ``"a"``, so the loop gain is :math:`L = -a/a_{in}`.

    ``measurement_gain`` and ``command_gain`` are the quasi-linear gains of the describing-
    function analysis (:mod:`hpdob.analysis._describing`): the measured angle is
    ``measurement_gain * theta + n_theta`` (the encoder's quantiser), and the command the
    observer, the controller and the actuator receive is ``command_gain * u`` (the torque
    limit; the output ``"u"`` stays the command before it). At 1.0 (the default) they leave
    every entry as it was, bit for bit. ``signals`` appends outputs: the measured ``"theta_m"``
    and ``"omega_m"`` and observer outputs by name (e.g. ``"omega_hat"``).
    """
    # a NaN or a string gain would give NaN matrices, and a bare string iterates by letters
    measurement_gain = as_real(measurement_gain, "measurement_gain", "a finite real gain")
    command_gain = as_real(command_gain, "command_gain", "a finite real gain")
    if not isinstance(signals, (tuple, list)) or not all(isinstance(n, str) for n in signals):
        raise ParameterTypeError(
            f"signals must be a tuple of signal names, got {signals!r} of type "
            f"{type(signals).__name__}"
        )
    Ts = spec.Ts
    system = spec.system
    nd = spec.delay
    nx = np.asarray(spec.plant.A).shape[0]
    i_prev = nx
    i_delay = i_prev + int(spec.backward_difference)
    i_z = i_delay + nd
    nz = 0 if system is None else system.n_states
    i_c = i_z + nz
    controller = spec.controller
    nc = controller.n_states
    ns = i_c + nc
    inputs = [*INPUTS, "a_in"] if broken else list(INPUTS)
    nv = len(inputs)
    col = {name: ns + j for j, name in enumerate(inputs)}
    Cp = np.asarray(spec.plant.C)

    def row():
        return np.zeros(ns + nv)

    # Measurement rows over [state, input].
    theta_m = row()
    theta_m[:nx] = Cp[0] if measurement_gain == 1.0 else measurement_gain * Cp[0]
    theta_m[col["n_theta"]] = 1.0
    omega_m = row()
    if spec.backward_difference:
        omega_m += theta_m / Ts
        omega_m[i_prev] -= 1.0 / Ts
    else:
        omega_m[:nx] = Cp[1]
    omega_m[col["n_omega"]] += 1.0
    Y = np.vstack([theta_m, omega_m])

    # the observer's outputs, then the controller's inputs, as rows over [state, inputs]
    signals_of = {"theta": theta_m, "omega": omega_m, "tau_hat": row()}
    for name in ("r", "r_dot", "r_ddot"):
        signals_of[name] = row()
        signals_of[name][col[name]] = 1.0
    if system is not None:
        p = len(system.measures)
        Ym = Y[:p]
        H, E = np.asarray(system.H), np.asarray(system.E)
        for j, name in enumerate(system.outputs):
            signals_of[name] = row()
            signals_of[name][i_z:i_c] = H[j]
            signals_of[name] += E[j, :p] @ Ym
    tau_hat = signals_of["tau_hat"]
    V = np.vstack([signals_of[name] for name in controller.inputs]) if controller.inputs else (
        np.zeros((0, ns + nv)))  # fmt: skip
    u = controller.E[0] @ V
    u[i_c:ns] += controller.H[0]
    command = u
    if command_gain != 1.0:  # the command really given, after the torque limit
        u = command_gain * command
    if nd == 0:
        a = u.copy()
    else:
        a = row()
        a[i_delay] = 1.0

    nxt = np.zeros((ns, ns + nv))
    drive = a.copy()
    if broken:
        drive = row()
        drive[col["a_in"]] = 1.0
    A = np.asarray(spec.plant.A)
    B = np.asarray(spec.plant.B)
    D = np.asarray(spec.plant.D)
    nxt[:nx, :nx] = A
    nxt[:nx] += np.outer(B, drive)
    nxt[:nx, col["tau_ext"]] -= D
    if spec.backward_difference:
        nxt[i_prev] = theta_m
    for i in range(nd - 1):
        nxt[i_delay + i, i_delay + i + 1] = 1.0
    if nd:
        nxt[i_delay + nd - 1] = u
    if system is not None:
        G = np.asarray(system.G)
        nxt[i_z:i_c, i_z:i_c] = system.F
        nxt[i_z:i_c] += G[:, :p] @ Ym + np.outer(G[:, p], u)
    if nc:
        pc = len(controller.inputs)
        nxt[i_c:, i_c:ns] = controller.F
        nxt[i_c:] += controller.G[:, :pc] @ V + np.outer(controller.G[:, pc], u)

    theta_row, omega_row = row(), row()
    theta_row[:nx], omega_row[:nx] = Cp[0], Cp[1]
    rows = {"theta": theta_row, "omega": omega_row, "u": command, "tau_hat": tau_hat, "a": a}
    measured = {"theta_m": theta_m, "omega_m": omega_m}
    for name in signals:
        rows[name] = measured.get(name, signals_of.get(name))
        if rows[name] is None:
            raise ParameterValueError(
                f"signals must name theta_m, omega_m or observer outputs "
                f"{list(signals_of)}, got {name!r}"
            )
    names = [*OUTPUTS, "a", *signals]
    out = np.vstack([rows[name] for name in names])
    return (
        nxt[:, :ns],
        nxt[:, ns:],
        out[:, :ns],
        out[:, ns:],
        inputs,
        names,
    )


def delay_state(spec: LoopSpec) -> int:
    """Index of the first delay-line state: after the plant's states and ``theta_prev``."""
    return np.asarray(spec.plant.A).shape[0] + int(spec.backward_difference)


def delayed_state_matrix(
    template: np.ndarray, spec: LoopSpec | None, delay: int, *, state: int | None = None
) -> np.ndarray:
    """The state matrix of ``loop_matrices(spec with delay)`` from the one with one sample.

    ``template`` is ``loop_matrices(dataclasses.replace(spec, delay=1))[0]``, or a stack of
    such matrices (shape ``(k, n, n)``) whose delay state is at one index, given as ``state``
    instead of ``spec``. With ``d >= 1`` samples of delay the loop's rows are the one-sample
    rows with the ``d - 1`` extra delay-line states inserted: the plant reads the oldest
    command (the template's delay column), the newest is the template's delay row, and the
    line shifts by ones. The same numbers at shifted places, so the result equals
    ``loop_matrices`` bit for bit (``tests/analysis/test_closed_loop_radii.py`` checks);
    building it this way costs four block copies instead of the whole assembly (``tune``
    scans up to 20 delays per candidate and corner).
    """
    if delay < 1:
        raise ValueError(f"delay must be at least 1 sample here, got {delay}")
    i = delay_state(spec) if state is None else state
    extra = delay - 1
    n = template.shape[-1] + extra
    out = np.zeros((*template.shape[:-2], n, n))
    # old index j -> j before the delay state, j + extra after it; the delay state's row (the
    # newest command, u) moves to the end of the line, its column (the oldest) stays at i
    top, low = slice(None, i), slice(i + extra, None)  # rows: before / from the delay state
    left, right = slice(None, i + 1), slice(i + 1 + extra, None)  # columns: up to / after it
    out[..., top, left] = template[..., :i, : i + 1]
    out[..., top, right] = template[..., :i, i + 1 :]
    out[..., low, left] = template[..., i:, : i + 1]
    out[..., low, right] = template[..., i:, i + 1 :]
    line = np.arange(i, i + extra)
    out[..., line, line + 1] = 1.0
    return out
