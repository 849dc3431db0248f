"""One run of the N-joint loop (:class:`ArmLoop`)."""

from __future__ import annotations

import math
import warnings

import numpy as np

from .._validation import ParameterTypeError, ParameterValueError, as_int, positive
from ..simulation import SimulationDivergedWarning
from ._arm_loop import ArmLoop
from ._computed_torque import ComputedTorque
from ._result import ArmResult
from ._two_link import TwoLinkArm

__all__ = ["simulate_arm"]

_LIMIT = 1e9
_SENSOR_MODES = {"backward-difference": 1, "exact": 2}


def _samples(values, shape, name):
    array = np.asarray(values, dtype=float)
    if array.shape != shape:
        array = (
            np.broadcast_to(array, shape)
            if array.ndim <= 1 and array.size in (1, shape[-1])
            else array
        )
    if array.shape != shape:
        raise ParameterValueError(f"{name} must give an array of shape {shape}, got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ParameterValueError(f"{name} must be finite")
    return np.ascontiguousarray(array, dtype=float)


def simulate_arm(loop: ArmLoop, *, duration: float, reference, external=None, substeps=None,
                 tau0=None, label: str = "") -> ArmResult:  # fmt: skip
    r"""Simulate the N-joint loop (``docs/robots.md``).

    Parameters
    ----------
    loop : ArmLoop
        The loop.
    duration : float
        Length of the run [s].
    reference : callable
        ``t -> (r, r_dot, r_ddot)``, each of shape ``(len(t), N)`` (e.g. :class:`JointSines`).
    external : callable, optional
        For a :class:`TwoLinkArm`: ``t -> `` joint torques ``(len(t), 2)`` [N m] the environment
        exerts on the arm. For a :class:`MujocoArm`: ``t -> `` a force ``(len(t), 3)`` [N], or
        a wrench ``(len(t), 6)`` (force [N], then moment [N m]), world frame, at the
        end-effector site (MuJoCo's ``xfrc_applied``). Evaluated at the sampling instants and
        at each sub-step's midpoint.
    substeps : int, optional
        Integration steps per sample (RK4 of the written-out dynamics, or MuJoCo steps of
        ``Ts/substeps``). Default 8 for a :class:`TwoLinkArm`, 1 for a :class:`MujocoArm`.
    tau0 : None, "gravity" or sequence of float, optional
        The disturbance each joint's observer starts converged on [N m]: zeros (None), the
        nominal model's gravity torque at ``q0`` (``"gravity"``), or given.
    label : str, optional

    Returns
    -------
    ArmResult

    Raises
    ------
    ParameterTypeError, ParameterValueError
        Naming the argument.
    """
    from ._kernel import PLANT_PYTHON, PLANT_TWO_LINK, run_arm

    if not isinstance(loop, ArmLoop):
        raise ParameterTypeError(f"loop must be an ArmLoop, got {type(loop).__name__}")
    plant, Ts, N = loop.plant, loop.Ts, loop.n_joints
    duration = positive(duration, "duration", "a positive finite duration [s]")
    two_link = isinstance(plant, TwoLinkArm)
    if substeps is None:
        substeps = 8 if two_link else 1
    substeps = as_int(substeps, "substeps", "a positive integer", minimum=1, maximum=10_000)
    K = math.floor(duration / Ts + 1e-9) + 1
    t = np.arange(K) * Ts
    if not callable(reference):
        raise ParameterTypeError(f"reference must be a callable t -> (r, r_dot, r_ddot), got "
                                 f"{type(reference).__name__}")  # fmt: skip
    parts = reference(t)
    if not isinstance(parts, (tuple, list)) or len(parts) != 3:
        raise ParameterValueError("reference must return a tuple (r, r_dot, r_ddot)")
    ref = np.stack([_samples(p, (K, N), f"reference's {n}")
                    for p, n in zip(parts, ("r", "r_dot", "r_ddot"), strict=True)])  # fmt: skip
    t_mid = (np.arange(K * substeps) + 0.5) * (Ts / substeps)
    width = N if two_link else 3
    if external is None:
        ext_sample = np.zeros((K, width))
        ext_mid = np.zeros((K * substeps, width))
    elif callable(external):
        values = np.asarray(external(t), dtype=float)
        if not two_link and values.shape == (K, 6):
            width = 6  # a wrench: force and moment
        ext_sample = _samples(values, (K, width), "external")
        ext_mid = _samples(external(t_mid), (K * substeps, width), "external")
    else:
        raise ParameterTypeError(f"external must be a callable of t or None, got "
                                 f"{type(external).__name__}")  # fmt: skip
    # per-joint parameters
    ct = isinstance(loop.controller, ComputedTorque)
    fpar = np.zeros((7, N))
    ipar = np.zeros((4, N), dtype=np.int64)
    noise = np.zeros((K, N))
    for i in range(N):
        kp = kd = ff = 0.0
        if ct:  # computed torque's PD on the error, in the kernel
            kp, kd = loop.controller.kp[i], loop.controller.kd[i]
            ff = float(loop.controller.feedforward)
        act = loop.actuators[i]
        sensor = loop.sensors[i]
        fpar[:, i] = (kp, kd, loop.nominal_inertia[i], loop.nominal_friction[i],
                      math.inf if act.torque_limit is None else act.torque_limit,
                      1.0 if sensor is None else sensor.resolution, ff)  # fmt: skip
        ipar[0, i] = 0 if sensor is None else _SENSOR_MODES[sensor.velocity]
        ipar[1, i] = act.delay_samples
        if sensor is not None and sensor.noise_std > 0:
            seed = 0 if sensor.seed is None else sensor.seed
            noise[:, i] = sensor.noise_std * np.random.default_rng([seed, i]).standard_normal(K)
    from ._controllers import stack_controllers
    from ._stack import stack_programs

    stacked = stack_programs(loop.systems)
    controllers = stack_controllers(loop.controller_rows)
    (cs_ptr, cs_c, cs_i), (cu_ptr, cu_c, cu_i) = controllers.signals, controllers.update
    cwork = np.zeros(2 * controllers.n_states + 8 * N + controllers.n_signals)
    ipar[2], ipar[3] = stacked.tau_row, stacked.omega_row
    S = stacked.n_states
    if tau0 is None:
        tau0 = np.zeros(N)
    elif isinstance(tau0, str) and tau0 == "gravity":
        tau0 = loop.nominal.gravity_torque(np.array(loop.q0))
    else:
        try:
            values = np.asarray(tau0, dtype=float)
        except (TypeError, ValueError):
            raise ParameterValueError(
                f'tau0 must be None, "gravity" or one torque [N m] per joint, got {tau0!r}'
            ) from None
        if values.ndim == 1 and values.size != N:
            raise ParameterValueError(
                f"tau0 must have one entry per joint ({N}), got {values.size}"
            )
        tau0 = _samples(values, (N,), "tau0")
    work = np.zeros(3 * S + 3 * N + 4 * N)
    for i, s0 in enumerate(loop.initial_observer_states(tau0)):
        if s0 is not None:
            off = stacked.offsets[i]
            work[off : off + len(s0)] = s0
    for i, ctl in enumerate(loop.controller_rows):  # c_0 = N [theta0, omega0, tau0]
        start = (loop.q0[i], 0.0, float(tau0[i]))
        for j, row in enumerate(ctl.reset):
            total = 0.0
            for term in row:
                total += term.coefficient * start[term.operand]
            cwork[controllers.offsets[i] + j] = total
    rec = np.zeros((8, K, N))
    tau_external = np.zeros((K, N))
    x = np.concatenate([np.array(loop.q0), np.zeros(N)])
    (up_ptr, up_c, up_i), (out_ptr, out_c, out_i) = stacked.update, stacked.output
    base = 3 * S + 3 * N
    acc, model_torque, applied = (work[base + N : base + 2 * N], work[base + 2 * N : base + 3 * N],
                                  work[base + 3 * N :])  # fmt: skip
    J_n, b_n = fpar[2], fpar[3]

    def step(k, phases, kind, par, tau_s, tau_m):
        return run_arm(k, k + 1 if kind == PLANT_PYTHON or ct else K, phases, ct, kind, par,
                       substeps, Ts, fpar, ipar, ref, rec, noise, up_ptr, up_i, up_c, out_ptr,
                       out_i, out_c, work, x, tau_s, tau_m, _LIMIT, cs_ptr, cs_i, cs_c, cu_ptr,
                       cu_i, cu_c, controllers.command, cwork)  # fmt: skip

    def control(k, kind, par, tau_s, tau_m):
        if not ct:
            return step(k, 3, kind, par, tau_s, tau_m)
        if step(k, 1, kind, par, tau_s, tau_m) != k + 1:
            return k
        model_torque[:] = loop.controller.model.inverse_dynamics(rec[2, k], rec[3, k], acc)
        return step(k, 2, kind, par, tau_s, tau_m)

    completed = K
    force = None
    if two_link:
        par = plant.packed()
        load_s, load_m = -ext_sample, -ext_mid  # the kernel takes loads (sign of eq. 1)
        tau_external[:] = ext_sample
        if ct:
            for k in range(K):
                if control(k, PLANT_TWO_LINK, par, load_s, load_m) != k + 1:
                    completed = k + 1
                    break
        else:
            completed = control(0, PLANT_TWO_LINK, par, load_s, load_m)
    else:
        session = plant.start(np.array(loop.q0), Ts, substeps)
        q, qd = session.state()
        dummy = np.zeros((1, N))
        has_force = external is not None
        if has_force:
            force = ext_sample
        qdd = np.zeros((K, N))  # the accelerations just after each command
        for k in range(K):
            x[:N] = q
            x[N:] = qd
            if control(k, PLANT_PYTHON, dummy[0], dummy, dummy) != k + 1:
                completed = k  # the state left |x| <= limit at the end of sample k - 1
                break
            tau_e = session.sample(
                applied,
                ext_sample[k] if has_force else None,
                ext_mid[k * substeps : (k + 1) * substeps] if has_force else None,
                qdd[k],
            )
            if has_force:
                tau_external[k] = tau_e
            if session.diverged():
                completed = k + 1
                break
        # eq. (3) per joint, elementwise as the two-link kernel computes it
        n = completed
        rec[7, :n] = rec[4, :n] - b_n * rec[1, :n] - J_n * qdd[:n]
    diverged = completed < K
    if diverged:
        message = f"the N-joint run diverged at t = {(completed - 1) * Ts:.6g} s"
        warnings.warn(SimulationDivergedWarning(message), stacklevel=2)
    n = completed
    return ArmResult(
        t[:n],
        rec[0, :n],
        rec[1, :n],
        rec[2, :n],
        rec[3, :n],
        ref[0, :n],
        ref[1, :n],
        ref[2, :n],
        rec[4, :n],
        rec[5, :n],
        rec[7, :n],
        tau_external[:n],
        Ts,
        joint_names=plant.joint_names,
        label=label,
        diverged=diverged,
        force=None if force is None else force[:n],
    )
