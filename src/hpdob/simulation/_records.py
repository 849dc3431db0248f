"""Typed records the compiled sample loop reads (numba-compatible named tuples).

Built once per run from validated, frozen values (:class:`~hpdob.ServoLoop`, the plant, the
sampled signals); the kernel in :mod:`hpdob.simulation._kernel` only reads them, except the
``Work`` arrays and the ``Outputs`` it fills. This module imports no numba, so building the
records costs nothing at ``import hpdob``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = [
    "PATH_GENERIC",
    "PATH_RIGID",
    "PATH_TWO_MASS",
    "SENSOR_ENCODER_DIFFERENCE",
    "SENSOR_ENCODER_EXACT",
    "SENSOR_IDEAL",
    "ActuatorRecord",
    "ControllerRecord",
    "LinearPlantRecord",
    "ObserverRecord",
    "Outputs",
    "SensorRecord",
    "SignalRecord",
    "Work",
]

SENSOR_IDEAL = 0
SENSOR_ENCODER_DIFFERENCE = 1
SENSOR_ENCODER_EXACT = 2

#: The kernel's sub-step paths (indices into ``hpdob.models._plant.SUBSTEP_PATHS``).
PATH_RIGID = 0
PATH_TWO_MASS = 1
PATH_GENERIC = 2


class ControllerRecord(NamedTuple):
    """A controller's program as arrays (:meth:`hpdob.controllers.ControllerProgram.arrays`),
    the wiring of its inputs and the nominal model of the ground truth (eq. 3)."""

    J_n: float
    b_n: float
    n: int  # states
    p: int  # inputs
    q: int  # signals (the last is the command)
    source: np.ndarray  # input j is entry source[j] of [r, r_dot, r_ddot, theta_m, omega_m, y_obs]
    signal_pointer: np.ndarray
    signal_coefficient: np.ndarray
    signal_operand: np.ndarray
    update_pointer: np.ndarray
    update_coefficient: np.ndarray
    update_operand: np.ndarray
    switch_latch: int  # the Switch's latch state, -1 without a switch
    switch_trigger: int  # its trigger's operand index in [c, v]
    switch_threshold: float
    switch_after: int  # the signal that is the command once switched
    switch_offset: float  # [N m]


class SensorRecord(NamedTuple):
    mode: int  # SENSOR_*
    resolution: float  # rad per count (1.0 for the ideal sensor)


class ActuatorRecord(NamedTuple):
    torque_limit: float  # inf: no limit
    delay: int  # samples


class ObserverRecord(NamedTuple):
    """An observer's program as arrays (:meth:`hpdob.observers.Program.arrays`)."""

    present: bool
    n: int  # states
    p: int  # measured signals (1 or 2)
    q: int  # outputs: tau_hat first, then others by name (wired to controller inputs)
    velocity_row: int  # the row of omega_hat (recorded), -1 without one
    reaction_row: int  # the row of tau_reac (recorded), -1 without one
    coulomb_source: int  # the Coulomb term's velocity: 0 none, 1 measured omega, 2 omega_hat
    coulomb: float  # its c_n [N m]
    coulomb_velocity: float  # its v_n [rad/s]
    coulomb_deadband: float  # its dead band d [rad/s] (0: none)
    update_pointer: np.ndarray
    update_coefficient: np.ndarray
    update_operand: np.ndarray
    output_pointer: np.ndarray
    output_coefficient: np.ndarray
    output_operand: np.ndarray


class SignalRecord(NamedTuple):
    r: np.ndarray
    r_dot: np.ndarray
    r_ddot: np.ndarray
    tau_sample: np.ndarray  # external torque at the sampling instants [N m]
    tau_mid: np.ndarray  # ... at the sub-step midpoints (n * substeps), empty with a table
    noise: np.ndarray  # position noise of the sensor [rad] (empty: none)
    table: np.ndarray  # [factor, coefficients]: tau_mid evaluated by the loop (empty: sampled)


class Outputs(NamedTuple):
    theta: np.ndarray
    omega: np.ndarray
    theta_m: np.ndarray
    omega_m: np.ndarray
    u: np.ndarray
    tau_hat: np.ndarray
    tau_dn: np.ndarray
    omega_hat: np.ndarray
    states: np.ndarray  # (n, nx) full plant state, or (0, nx) when not recorded
    tau_contact: np.ndarray  # the environment's contact torque at t_k [N m] (0 without one)
    in_contact: np.ndarray  # 1.0 where the environment pushes at t_k, else 0.0
    tau_reac: np.ndarray  # the observer's reaction-torque estimate (0 without one) [N m]


class Work(NamedTuple):
    """Mutable state of a run, kept between calls of the kernel."""

    s: np.ndarray  # observer state s_k
    s_new: np.ndarray
    w: np.ndarray  # operands [s_k, measurement, u_k]
    c: np.ndarray  # controller state c_k
    c_new: np.ndarray
    cw: np.ndarray  # controller operands [c_k, inputs, u_bar_k, signals]
    sv: np.ndarray  # the loop's signals [r, r_dot, r_ddot, theta_m, omega_m, observer outputs]
    previous: np.ndarray  # [theta_m of the previous sample]
    x: np.ndarray  # plant state (set by the caller for a plant advanced from Python)
    x_next: np.ndarray
    applied: np.ndarray  # [torque the plant receives over the last sample run]


class LinearPlantRecord(NamedTuple):
    r"""A plant whose linear part is integrated exactly over each sub-step of ``h = Ts/S``.

    :math:`x_{j+1} = A_h x_j + B_h (a - F_c(\omega_m)) - D_h \tau_{ext}` (``shared``: ``D = B``,
    the external torque acts on the motor and the forces are summed first), with the Coulomb
    friction :math:`F_c = c \tanh(\omega_m / v)` of the motor evaluated at the exponential
    midpoint (``_half`` matrices: ``h/2``).
    """

    linear: bool  # False: a plant advanced from Python (the other fields are unused)
    path: int  # the sub-step path: an index into hpdob.models._plant.SUBSTEP_PATHS
    velocity_index: int  # index of the motor velocity in x
    A_h: np.ndarray
    B_h: np.ndarray
    D_h: np.ndarray
    A_half: np.ndarray
    B_half: np.ndarray
    D_half: np.ndarray
    shared: bool
    internal: np.ndarray  # motor acceleration = (a - internal @ x - F_c - [tau]) / J_motor
    J_motor: float
    coulomb: float
    coulomb_velocity: float
    contact: bool  # a unilateral environment on x[contact_index], x[contact_index + 1]
    contact_index: int
    contact_stiffness: float  # k_e [N m/rad]
    contact_damping: float  # c_e [N m s/rad]
    contact_position: float  # theta_e [rad]
