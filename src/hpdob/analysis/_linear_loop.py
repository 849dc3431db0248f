r"""The linear sampled-data closed loop of :func:`hpdob.simulate` as an LTI system.

Per sample ``k`` (the order of :func:`hpdob.simulate`, Coulomb friction and saturation left out):

.. math::

    \theta_{m,k} &= \theta_k + n_{\theta,k}, \qquad
    \omega_{m,k} = \omega_k + n_{\omega,k}
    \ \ (\text{or } (\theta_{m,k} - \theta_{m,k-1})/T_s + n_{\omega,k}), \\
    \hat\tau_k &= \hat z_{m+1,k} - L_{m+1}^T x_{m,k}, \\
    u_k &= J_n(\ddot r_k + k_p(r_k - \theta_{m,k}) + k_d(\dot r_k - \omega_{m,k})) + \hat\tau_k, \\
    \hat z_{k+1} &= M \hat z_k + K_x x_{m,k} + K_u u_k, \\
    x_{k+1} &= A x_k + B\,(u_{k-d} - \tau_{ext,k}),

with ``A, B`` the exact ZOH discretisation of the *true* plant and the external torque held
over the sample. The state is ``[theta, omega, (theta_prev), (u_delay1..d), (z1..z{m+1})]``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._validation import ParameterValueError, positive, require_instance
from ..models._servo import DiscreteServoModel, ServoModel
from ..observers._runtime import as_design, check_designed_on
from ..observers._synthesis import ObserverDesign
from ..simulation._controller import PD
from ..simulation._devices import Actuator, Encoder

__all__ = ["INPUTS", "OUTPUTS", "LoopSpec", "loop_matrices", "loop_spec"]

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
    """Validated ingredients of the linear loop (internal)."""

    plant: DiscreteServoModel
    J_n: float
    kp: float
    kd: float
    feedforward: bool
    design: ObserverDesign | None
    backward_difference: bool
    delay: int


def loop_spec(*, plant, nominal, Ts, controller, observer=None, sensor=None, actuator=None):
    """Validate the arguments shared by the closed-loop functions; return a :class:`LoopSpec`."""
    plant = require_instance(plant, ServoModel, "plant")
    nominal = require_instance(nominal, ServoModel, "nominal")
    Ts = positive(Ts, "Ts", "a positive finite sampling period [s]")
    controller = require_instance(controller, PD, "controller")
    sensor = require_instance(sensor, Encoder, "sensor", optional=True)
    actuator = require_instance(actuator, Actuator, "actuator", optional=True) or Actuator()
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
    design = None
    if observer is not None:
        design = as_design(observer, "observer")
        check_designed_on(design, nominal, Ts)
    return LoopSpec(
        plant=plant.discretize(Ts),
        J_n=nominal.J,
        kp=controller.kp,
        kd=controller.kd,
        feedforward=controller.feedforward,
        design=design,
        backward_difference=sensor is not None and sensor.velocity == "backward-difference",
        delay=actuator.delay_samples,
    )


def state_names(spec: LoopSpec) -> list[str]:
    names = ["theta", "omega"]
    if spec.backward_difference:
        names.append("theta_prev")
    names += [f"u_delay{i + 1}" for i in range(spec.delay)]
    if spec.design is not None:
        names += [f"z{i + 1}" for i in range(spec.design.order + 1)]
    return names


def loop_matrices(spec: LoopSpec, *, broken: bool = False):
    r"""``(A, B, C, D, inputs, outputs)`` of the loop as numpy arrays.

    With ``broken=False`` the inputs are :data:`INPUTS` and the outputs :data:`OUTPUTS` plus
    ``"a"``, the torque the plant receives (``u`` delayed). With ``broken=True`` the loop is
    cut at the plant input: the plant is driven by an extra last input ``"a_in"`` instead of
    ``"a"``, so the loop gain is :math:`L = -a/a_{in}`.
    """
    Ts = spec.plant.Ts
    design = spec.design
    nd = spec.delay
    i_prev = 2
    i_delay = i_prev + int(spec.backward_difference)
    i_z = i_delay + nd
    nz = 0 if design is None else design.order + 1
    ns = i_z + nz
    inputs = [*INPUTS, "a_in"] if broken else list(INPUTS)
    nv = len(inputs)
    col = {name: ns + j for j, name in enumerate(inputs)}

    def row():
        return np.zeros(ns + nv)

    # Measurement rows over [state, input].
    theta_m = row()
    theta_m[0] = 1.0
    theta_m[col["n_theta"]] = 1.0
    omega_m = row()
    if spec.backward_difference:
        omega_m += theta_m / Ts
        omega_m[i_prev] -= 1.0 / Ts
    else:
        omega_m[1] = 1.0
    omega_m[col["n_omega"]] += 1.0
    Y = np.vstack([theta_m, omega_m])

    tau_hat = row()
    if design is not None:
        tau_hat[i_z + nz - 1] = 1.0
        tau_hat -= design.gains[-1] @ Y
    u = tau_hat.copy()
    u[col["r"]] += spec.J_n * spec.kp
    u[col["r_dot"]] += spec.J_n * spec.kd
    if spec.feedforward:
        u[col["r_ddot"]] += spec.J_n
    u -= spec.J_n * (spec.kp * theta_m + spec.kd * omega_m)
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
    drive[col["tau_ext"]] -= 1.0
    A = np.asarray(spec.plant.A)
    B = np.asarray(spec.plant.B)
    nxt[0:2, 0:2] = A
    nxt[0:2] += np.outer(B, drive)
    if spec.backward_difference:
        nxt[i_prev] = theta_m
    for i in range(nd - 1):
        nxt[i_delay + i, i_delay + i + 1] = 1.0
    if nd:
        nxt[i_delay + nd - 1] = u
    if design is not None:
        nxt[i_z:, i_z:ns] = design.error_matrix
        nxt[i_z:] += design.state_input @ Y + np.outer(design.control_input, u)

    out_rows = []
    for name in (*OUTPUTS, "a"):
        if name == "theta":
            r = row()
            r[0] = 1.0
        elif name == "omega":
            r = row()
            r[1] = 1.0
        else:
            r = {"u": u, "tau_hat": tau_hat, "a": a}[name]
        out_rows.append(r)
    out = np.vstack(out_rows)
    return (
        nxt[:, :ns],
        nxt[:, ns:],
        out[:, :ns],
        out[:, ns:],
        inputs,
        [*OUTPUTS, "a"],
    )
