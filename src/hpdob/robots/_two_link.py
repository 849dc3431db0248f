r"""The built-in two-link planar arm: its dynamics written out (``docs/robots.md``).

Both joints turn about the horizontal y axis; link ``i`` has length ``l_i``, mass ``m_i`` with its
centre of mass at ``lc_i`` along the link and inertia ``I_i`` about it; ``J_i`` is the rotor
inertia (armature) and ``b_i`` the viscous friction of joint ``i``. Angles are measured from the
downward vertical (the arm hangs at ``q = 0``), ``q_2`` relative to link 1. With
``c_2 = cos q_2``, ``s_2 = sin q_2``, ``h = m_2 l_1 lc_2 s_2``:

.. math::

    M(q) = \begin{bmatrix}
        m_1 lc_1^2 + I_1 + J_1 + m_2 (l_1^2 + lc_2^2 + 2 l_1 lc_2 c_2) + I_2 &
        m_2 (lc_2^2 + l_1 lc_2 c_2) + I_2 \\
        m_2 (lc_2^2 + l_1 lc_2 c_2) + I_2 & m_2 lc_2^2 + I_2 + J_2 \end{bmatrix},

    C(q,\dot q)\dot q = \begin{bmatrix} -h (2\dot q_1 \dot q_2 + \dot q_2^2) \\
        h \dot q_1^2 \end{bmatrix},\qquad
    g(q) = \begin{bmatrix} (m_1 lc_1 + m_2 l_1) g_0 \sin q_1 + m_2 lc_2 g_0 \sin(q_1 + q_2) \\
        m_2 lc_2 g_0 \sin(q_1 + q_2) \end{bmatrix},

and the arm moves by :math:`M(q)\ddot q + C(q,\dot q)\dot q + g(q) + B\dot q = u - \tau_{ext}`
(``B = diag(b)``; the external torque enters with the sign of the paper's eq. 1, as a load).
"""

from __future__ import annotations

import math
from dataclasses import KW_ONLY, dataclass, field

import numba
import numpy as np

from .._validation import ParameterValueError, as_real, nonnegative, positive

__all__ = ["TwoLinkArm", "two_link_derivative", "two_link_rk4"]

_jit = numba.njit(cache=True, nogil=True)


@_jit
def two_link_derivative(p, q1, q2, w1, w2, u1, u2):
    """``(q1', q2', w1', w2')`` of the written-out dynamics; ``p`` the packed parameters
    ``(a1, a2, a3, J1, J2, I2 + m2 lc2^2, G1, G2, b1, b2)`` (see :meth:`TwoLinkArm.packed`)."""
    c2 = math.cos(q2)
    h = p[2] * math.sin(q2)
    m11 = p[0] + 2.0 * p[2] * c2 + p[3]
    m12 = p[1] + p[2] * c2
    m22 = p[1] + p[4]
    s12 = math.sin(q1 + q2)
    f1 = u1 - (-h * (2.0 * w1 * w2 + w2 * w2)) - (p[6] * math.sin(q1) + p[7] * s12) - p[8] * w1
    f2 = u2 - h * w1 * w1 - p[7] * s12 - p[9] * w2
    det = m11 * m22 - m12 * m12
    return w1, w2, (m22 * f1 - m12 * f2) / det, (m11 * f2 - m12 * f1) / det


@_jit
def two_link_rk4(p, x, u1, u2, tau_mid, h, steps):
    """Advance ``x = (q1, q2, w1, w2)`` in place by ``steps`` classical RK4 steps of ``h`` [s]
    with the joint torques ``u - tau_mid[j]`` held over step ``j``."""
    q1, q2, w1, w2 = x[0], x[1], x[2], x[3]
    for j in range(steps):
        a1, a2 = u1 - tau_mid[j, 0], u2 - tau_mid[j, 1]
        k1 = two_link_derivative(p, q1, q2, w1, w2, a1, a2)
        k2 = two_link_derivative(
            p, q1 + 0.5 * h * k1[0], q2 + 0.5 * h * k1[1], w1 + 0.5 * h * k1[2],
            w2 + 0.5 * h * k1[3], a1, a2,
        )  # fmt: skip
        k3 = two_link_derivative(
            p, q1 + 0.5 * h * k2[0], q2 + 0.5 * h * k2[1], w1 + 0.5 * h * k2[2],
            w2 + 0.5 * h * k2[3], a1, a2,
        )  # fmt: skip
        k4 = two_link_derivative(
            p, q1 + h * k3[0], q2 + h * k3[1], w1 + h * k3[2], w2 + h * k3[3], a1, a2
        )
        q1 += h / 6.0 * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0])
        q2 += h / 6.0 * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1])
        w1 += h / 6.0 * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2])
        w2 += h / 6.0 * (k1[3] + 2.0 * k2[3] + 2.0 * k3[3] + k4[3])
    x[0], x[1], x[2], x[3] = q1, q2, w1, w2


def _pair(value, name: str, what: str, check) -> tuple[float, float]:
    if np.ndim(value) == 0:
        raise ParameterValueError(
            f"{name} must be a pair (joint 1, joint 2) of {what}, got {value!r}"
        )
    values = tuple(value)
    if len(values) != 2:
        raise ParameterValueError(
            f"{name} must have one entry per joint (2), got {len(values)}: {values!r}"
        )
    return tuple(check(v, f"{name}[{i}]", what) for i, v in enumerate(values))


@dataclass(frozen=True)
class TwoLinkArm:
    r"""A two-link planar arm in a vertical plane, its dynamics written out (module docstring).

    Parameters
    ----------
    m : (float, float)
        Link masses [kg], positive.
    l : (float, float)
        Link lengths [m], positive (``l[1]`` places the end effector).
    lc : (float, float)
        Distance of each link's centre of mass from its joint [m], non-negative.
    I : (float, float)
        Link inertia about its centre of mass, about the joint axis [kg m^2], positive.
    J : (float, float), optional
        Rotor inertia of each joint (MuJoCo's ``armature``) [kg m^2], non-negative. Default 0.
    b : (float, float), optional
        Viscous friction of each joint [N m s/rad], non-negative. Default 0.
    gravity : float, optional
        Gravitational acceleration [m/s^2], non-negative. Default 9.81 (MuJoCo's).

    Examples
    --------
    >>> from hpdob.robots import TwoLinkArm
    >>> arm = TwoLinkArm(m=(1.0, 1.0), l=(0.5, 0.5), lc=(0.25, 0.25), I=(0.02, 0.02))
    >>> # stretched out (q2 = 0): M11 = m1 lc1^2 + I1 + m2 (l1 + lc2)^2 + I2 = 0.665
    >>> arm.mass_matrix((0.0, 0.0)).round(6).tolist()
    [[0.665, 0.2075], [0.2075, 0.0825]]
    """

    m: tuple
    l: tuple  # noqa: E741 -- the link lengths, as in the equations
    lc: tuple
    I: tuple  # noqa: E741
    _: KW_ONLY
    J: tuple = (0.0, 0.0)
    b: tuple = (0.0, 0.0)
    gravity: float = 9.81
    _packed: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        set_ = object.__setattr__
        set_(self, "m", _pair(self.m, "m", "positive finite masses [kg]", positive))
        set_(self, "l", _pair(self.l, "l", "positive finite lengths [m]", positive))
        set_(self, "lc", _pair(self.lc, "lc", "non-negative finite distances [m]", nonnegative))
        set_(self, "I", _pair(self.I, "I", "positive finite inertias [kg m^2]", positive))
        set_(
            self,
            "J",
            _pair(self.J, "J", "non-negative finite rotor inertias [kg m^2]", nonnegative),
        )
        set_(
            self, "b", _pair(self.b, "b", "non-negative finite frictions [N m s/rad]", nonnegative)
        )
        set_(self, "gravity", nonnegative(self.gravity, "gravity", "a non-negative finite "
                                          "gravitational acceleration [m/s^2]"))  # fmt: skip
        (m1, m2), (l1, _), (c1, c2), (I1, I2) = self.m, self.l, self.lc, self.I
        g0 = self.gravity
        packed = np.array([
            m1 * c1**2 + I1 + m2 * (l1**2 + c2**2) + I2,  # a1: M11 without 2 a3 cos q2 and J1
            m2 * c2**2 + I2,  # a2
            m2 * l1 * c2,  # a3
            self.J[0], self.J[1], m2 * c2**2 + I2,
            (m1 * c1 + m2 * l1) * g0, m2 * c2 * g0,  # G1, G2
            self.b[0], self.b[1],
        ])  # fmt: skip
        packed.setflags(write=False)
        set_(self, "_packed", packed)

    n_joints = 2
    joint_names = ("shoulder", "elbow")

    def packed(self) -> np.ndarray:
        """The parameters as the compiled integrator reads them.

        Returns
        -------
        ndarray
            ``(a1, a2, a3, J1, J2, I2 + m2 lc2^2, G1, G2, b1, b2)``, read-only.
        """
        return self._packed

    def _q(self, q, name="q"):
        values = _pair(q, name, "finite joint values", as_real)
        return values

    def mass_matrix(self, q) -> np.ndarray:
        """:math:`M(q)` [kg m^2] (module docstring).

        Parameters
        ----------
        q : (float, float)
            Joint angles [rad].

        Returns
        -------
        ndarray, shape (2, 2)
        """
        _, q2 = self._q(q)
        p = self._packed
        m12 = p[1] + p[2] * math.cos(q2)
        return np.array([[p[0] + 2.0 * p[2] * math.cos(q2) + p[3], m12], [m12, p[1] + p[4]]])

    def coriolis(self, q, qd) -> np.ndarray:
        r""":math:`C(q, \dot q)\dot q` [N m].

        Parameters
        ----------
        q, qd : (float, float)
            Joint angles [rad] and velocities [rad/s].

        Returns
        -------
        ndarray, shape (2,)
        """
        _, q2 = self._q(q)
        w1, w2 = self._q(qd, "qd")
        h = self._packed[2] * math.sin(q2)
        return np.array([-h * (2.0 * w1 * w2 + w2 * w2), h * w1 * w1])

    def coriolis_transpose(self, q, qd) -> np.ndarray:
        r""":math:`C(q, \dot q)^T \dot q` [N m] with the Christoffel ``C`` (``Ṁ = C + Cᵀ``),
        the term of the momentum observer: :math:`(0,\ -h\,\dot q_1 (\dot q_1 + \dot q_2))`.

        Parameters
        ----------
        q, qd : (float, float)
            Joint angles [rad] and velocities [rad/s].

        Returns
        -------
        ndarray, shape (2,)
        """
        _, q2 = self._q(q)
        w1, w2 = self._q(qd, "qd")
        h = self._packed[2] * math.sin(q2)
        return np.array([0.0, -h * w1 * (w1 + w2)])

    def gravity_torque(self, q) -> np.ndarray:
        """:math:`g(q)` [N m].

        Parameters
        ----------
        q : (float, float)
            Joint angles [rad].

        Returns
        -------
        ndarray, shape (2,)
        """
        q1, q2 = self._q(q)
        p = self._packed
        s12 = math.sin(q1 + q2)
        return np.array([p[6] * math.sin(q1) + p[7] * s12, p[7] * s12])

    def friction(self, qd) -> np.ndarray:
        """Viscous friction torques :math:`B \\dot q` [N m].

        Parameters
        ----------
        qd : (float, float)
            Joint velocities [rad/s].

        Returns
        -------
        ndarray, shape (2,)
        """
        w = self._q(qd, "qd")
        return np.array([self.b[0] * w[0], self.b[1] * w[1]])

    def acceleration(self, q, qd, u, tau_ext=(0.0, 0.0)) -> np.ndarray:
        r""":math:`\ddot q = M^{-1}(u - \tau_{ext} - C\dot q - g - B\dot q)` [rad/s^2].

        Parameters
        ----------
        q, qd : (float, float)
            Joint angles [rad] and velocities [rad/s].
        u : (float, float)
            Joint torques [N m].
        tau_ext : (float, float), optional
            External load torques [N m] (sign of eq. 1).

        Returns
        -------
        ndarray, shape (2,)
        """
        q1, q2 = self._q(q)
        w1, w2 = self._q(qd, "qd")
        u1, u2 = self._q(u, "u")
        t1, t2 = self._q(tau_ext, "tau_ext")
        d = two_link_derivative(self._packed, q1, q2, w1, w2, u1 - t1, u2 - t2)
        return np.array([d[2], d[3]])

    def inverse_dynamics(self, q, qd, qdd) -> np.ndarray:
        r""":math:`M(q)\ddot q + C(q,\dot q)\dot q + g(q) + B\dot q` [N m].

        Parameters
        ----------
        q, qd, qdd : (float, float)
            Joint angles [rad], velocities [rad/s], accelerations [rad/s^2].

        Returns
        -------
        ndarray, shape (2,)
        """
        qdd = np.array(self._q(qdd, "qdd"))
        return (self.mass_matrix(q) @ qdd + self.coriolis(q, qd) + self.gravity_torque(q)
                + self.friction(qd))  # fmt: skip

    def end_effector(self, q) -> np.ndarray:
        """Position of the end effector (tip of link 2) in the x-z plane [m], ``(x, z)``.

        Parameters
        ----------
        q : (float, float)
            Joint angles [rad].

        Returns
        -------
        ndarray, shape (2,)
        """
        q1, q2 = self._q(q)
        l1, l2 = self.l
        return np.array(
            [
                -l1 * math.sin(q1) - l2 * math.sin(q1 + q2),
                -l1 * math.cos(q1) - l2 * math.cos(q1 + q2),
            ]
        )

    def jacobian(self, q) -> np.ndarray:
        """The end effector's translational Jacobian ``d(x, z)/dq`` [m/rad].

        Parameters
        ----------
        q : (float, float)
            Joint angles [rad].

        Returns
        -------
        ndarray, shape (2, 2)
        """
        q1, q2 = self._q(q)
        l1, l2 = self.l
        c1, s1 = math.cos(q1), math.sin(q1)
        c12, s12 = math.cos(q1 + q2), math.sin(q1 + q2)
        return np.array([[-l1 * c1 - l2 * c12, -l2 * c12], [l1 * s1 + l2 * s12, l2 * s12]])

    def to_mjcf(self, *, integrator: str = "RK4", timestep: float = 1e-3) -> str:
        """The same arm as an MJCF model (hinges ``shoulder`` and ``elbow`` about y, ``<motor>``
        actuators of gear 1, an end-effector site ``tip``), for the cross-check with MuJoCo.

        Parameters
        ----------
        integrator : str, optional
            MuJoCo's integrator. Default ``"RK4"``.
        timestep : float, optional
            MuJoCo's time step [s]. Default 1e-3.

        Returns
        -------
        str
        """
        timestep = positive(timestep, "timestep", "a positive finite MuJoCo time step [s]")
        (m1, m2), (l1, l2), (c1, c2), (I1, I2) = self.m, self.l, self.lc, self.I

        def link(i, mass, com, inertia):
            return (f'<inertial pos="0 0 {-com!r}" mass="{mass!r}" '
                    f'diaginertia="{inertia!r} {inertia!r} {inertia!r}"/>')  # fmt: skip

        return f"""<mujoco model="hpdob_two_link_arm">
  <compiler angle="radian" inertiafromgeom="false"/>
  <option timestep="{timestep!r}" integrator="{integrator}" gravity="0 0 {-self.gravity!r}"/>
  <worldbody>
    <body name="link1">
      <joint name="shoulder" type="hinge" axis="0 1 0" armature="{self.J[0]!r}"
             damping="{self.b[0]!r}"/>
      {link(1, m1, c1, I1)}
      <body name="link2" pos="0 0 {-l1!r}">
        <joint name="elbow" type="hinge" axis="0 1 0" armature="{self.J[1]!r}"
               damping="{self.b[1]!r}"/>
        {link(2, m2, c2, I2)}
        <site name="tip" pos="0 0 {-l2!r}"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="shoulder_motor" joint="shoulder" gear="1"/>
    <motor name="elbow_motor" joint="elbow" gear="1"/>
  </actuator>
</mujoco>
"""
