r"""Linear ADRC: state feedback on its own extended state observer, with b0 = 1/J_n."""

from __future__ import annotations

import math
from dataclasses import KW_ONLY, dataclass

import numpy as np

from .._validation import ParameterTypeError, positive
from ._base import Controller
from ._system import LinearController, ProgramBuilder

__all__ = ["ADRC"]


@dataclass(frozen=True)
class ADRC(Controller):
    r"""Second-order linear ADRC in the discrete state-space form of pyadrc (Herbst 2019).

    The plant is modelled as :math:`\ddot y = f + b_0 u` with :math:`b_0 = 1/J_n` and the
    total disturbance :math:`f` an extra state. Its discrete extended state observer (ESO)
    is the *current* observer of the ZOH model
    :math:`A_d = \begin{bmatrix}1 & T_s & T_s^2/2\\ 0 & 1 & T_s\\ 0 & 0 & 1\end{bmatrix}`,
    :math:`B_d = b_0 [T_s^2/2,\ T_s,\ 0]^T`, :math:`C_d = [1, 0, 0]`:

    .. math::

        \hat x_k &= (A_d - L C_d A_d)\,\hat x_{k-1} + (B_d - L C_d B_d)\,\bar u_{k-1}
                    + L\,\theta_k, \\
        u_k &= \frac{1}{b_0}\left(k_p (r_k - \hat x_{1,k}) - k_d \hat x_{2,k}
               - \hat x_{3,k}\right)
               \quad\left[+ \frac{1}{b_0}(k_d \dot r_k + \ddot r_k)
               \text{ with feedforward}\right],

    with the controller gains :math:`k_p = \omega_c^2`, :math:`k_d = 2\omega_c` (both
    closed-loop poles at :math:`-\omega_c`) and the observer gains that put the three ESO
    poles at :math:`z_o = e^{-\omega_o T_s}`:
    :math:`L = [1 - z_o^3,\ \tfrac{3}{2T_s}(1 - z_o)^2(1 + z_o),\ \tfrac{1}{T_s^2}(1 - z_o)^3]^T`.
    The ESO is fed the command after the torque limit, :math:`\bar u` (the usual anti-windup
    of ADRC: the observer sees what the plant got). It measures the angle only and needs no
    separate observer in the loop (a loop observer's outputs are not used).

    As a :class:`~hpdob.controllers.LinearController` its state is the ESO's prediction
    :math:`c_k = (A_d - L C_d A_d)\hat x_{k-1} + (B_d - L C_d B_d)\bar u_{k-1}`, so that
    :math:`\hat x_k = c_k + L\theta_k`; a run starts with
    :math:`\hat x_0 = [\theta_0, \omega_0, -\tau_0/J_n]` (at rest: zero, as pyadrc).

    Parameters
    ----------
    bandwidth : float
        Closed-loop bandwidth :math:`\omega_c` [rad/s], positive (pyadrc's ``w_cl``).
    observer_bandwidth : float, optional
        ESO bandwidth :math:`\omega_o` [rad/s], positive; default :math:`5\omega_c`
        (pyadrc's ``k_eso = omega_o / omega_c``).
    feedforward : bool, optional
        Add the reference's velocity and acceleration (Gao 2003's tracking form); default
        False, pyadrc's form (reference angle only).

    References
    ----------
    Z. Gao, "Scaling and bandwidth-parameterization based controller tuning", ACC 2003.
    G. Herbst, "Practical active disturbance rejection control: bumpless transfer, rate
    limitation, and incremental algorithm", arXiv:1908.04610, 2019 (the discrete form,
    as implemented by pyadrc's ``StateSpace``).

    Examples
    --------
    >>> from hpdob import ADRC, ServoModel
    >>> c = ADRC(50.0).design(ServoModel(2.8e-4), 1e-3)
    >>> c.n_states, c.inputs
    (3, ('r', 'theta'))
    """

    bandwidth: float
    _: KW_ONLY
    observer_bandwidth: float | None = None
    feedforward: bool = False

    def __post_init__(self):
        object.__setattr__(
            self,
            "bandwidth",
            positive(self.bandwidth, "bandwidth", "a positive closed-loop bandwidth [rad/s]"),
        )
        if self.observer_bandwidth is not None:
            object.__setattr__(
                self,
                "observer_bandwidth",
                positive(self.observer_bandwidth, "observer_bandwidth",
                         "a positive ESO bandwidth [rad/s]"),
            )  # fmt: skip
        if not isinstance(self.feedforward, bool):
            raise ParameterTypeError(f"feedforward must be True or False, got {self.feedforward!r}")

    def matrices(self, nominal, Ts: float) -> dict:
        r"""The literal matrices of the class docstring.

        Parameters
        ----------
        nominal : ServoModel
            Its ``J`` is :math:`J_n = 1/b_0`.
        Ts : float
            Sampling period [s].

        Returns
        -------
        dict
            ``Ad, Bd, Cd, L, Ao, Bo`` (``Ao = Ad - L Cd Ad``, ``Bo = Bd - L Cd Bd``),
            ``kp, kd, b0``.
        """
        wc = self.bandwidth
        wo = 5.0 * wc if self.observer_bandwidth is None else self.observer_bandwidth
        b0 = 1.0 / nominal.J
        Ad = np.array([[1.0, Ts, Ts**2 / 2], [0.0, 1.0, Ts], [0.0, 0.0, 1.0]])
        Bd = b0 * np.array([Ts**2 / 2, Ts, 0.0])
        Cd = np.array([1.0, 0.0, 0.0])
        z = math.exp(-wo * Ts)
        L = np.array([1 - z**3, 3 / (2 * Ts) * (1 - z) ** 2 * (1 + z), (1 - z) ** 3 / Ts**2])
        Ao = Ad - np.outer(L, Cd @ Ad)
        Bo = Bd - L * (Cd @ Bd)
        return {"Ad": Ad, "Bd": Bd, "Cd": Cd, "L": L, "Ao": Ao, "Bo": Bo,
                "kp": wc**2, "kd": 2 * wc, "b0": b0}  # fmt: skip

    def design(self, nominal, Ts: float) -> LinearController:
        r"""The ADRC as a linear system: three states (the ESO's prediction), the signals
        :math:`\hat x_{i,k} = c_{i,k} + L_i\theta_k` and the command.

        Parameters
        ----------
        nominal : ServoModel
            Its ``J`` is :math:`J_n = 1/b_0`.
        Ts : float
            Sampling period [s].

        Returns
        -------
        LinearController
            Inputs ``r, (r_dot, r_ddot), theta``.
        """
        m = self.matrices(nominal, Ts)
        L, Ao, Bo, kp, kd = m["L"], m["Ao"], m["Bo"], m["kp"], m["kd"]
        J_n = nominal.J  # 1 / b0
        inputs = ("r", *(("r_dot", "r_ddot") if self.feedforward else ()), "theta")
        states = ("p1", "p2", "p3")
        b = ProgramBuilder(inputs, states)
        for i in range(3):
            b.signal(f"x{i + 1}", (1.0, states[i]), (L[i], "theta", f"L{i + 1}"))
        terms = [(kp * J_n, "r", "KP_B0"), (-kp * J_n, "x1", "KP_B0", True),
                 (-kd * J_n, "x2", "KD_B0", True), (-J_n, "x3", "INV_B0", True)]  # fmt: skip
        if self.feedforward:
            terms += [(kd * J_n, "r_dot", "KD_B0"), (J_n, "r_ddot", "INV_B0")]
        b.signal("u", *terms)
        for i in range(3):
            row = [(Ao[i, j], f"x{j + 1}", f"AO{i + 1}_{j + 1}") for j in range(3)
                   if Ao[i, j] != 0.0]  # fmt: skip
            if Bo[i] != 0.0:
                row.append((Bo[i], "u_bar", f"BO{i + 1}"))
            b.update(states[i], *row)
        b.reset("p1", (1.0 - L[0], "theta0"))
        b.reset("p2", (-L[1], "theta0"), (1.0, "omega0"))
        b.reset("p3", (-L[2], "theta0"), (-1.0 / J_n, "tau0"))
        b.describe("KP_B0", "kp / b0 = wc^2 J_n [N m/rad]")
        b.describe("KD_B0", "kd / b0 = 2 wc J_n [N m s/rad]")
        b.describe("INV_B0", "1 / b0 = J_n [kg m^2]")
        wo = 5.0 * self.bandwidth if self.observer_bandwidth is None else self.observer_bandwidth
        return b.build(Ts=Ts, name=f"ADRC(wc={self.bandwidth:g}, wo={wo:g})",
                       info=(("controller", "linear ADRC (pyadrc StateSpace form)"),
                             ("bandwidth", f"{self.bandwidth!r} rad/s"),
                             ("observer bandwidth", f"{wo!r} rad/s")))  # fmt: skip
