"""The traces of one N-joint run, per joint, with the ground truth of eq. (3) per joint."""

from __future__ import annotations

from dataclasses import KW_ONLY, dataclass

import numpy as np

from .._validation import ParameterValueError

__all__ = ["ArmResult"]

#: Traces of shape (samples, joints) and their units.
TRACES = {
    "q": "rad", "qd": "rad/s", "q_measured": "rad", "qd_measured": "rad/s", "r": "rad",
    "r_dot": "rad/s", "r_ddot": "rad/s^2", "u": "N m", "tau_hat": "N m", "tau_dn": "N m",
    "tau_external": "N m",
}  # fmt: skip


def _rms(x, axis=0):
    return np.sqrt(np.mean(np.square(x), axis=axis)) if len(x) else np.full(x.shape[1], np.nan)


@dataclass(frozen=True)
class ArmResult:
    """Sampled traces of one N-joint run: arrays of shape ``(samples, joints)``.

    Attributes
    ----------
    t : ndarray, shape (samples,)
        Sampling instants [s].
    q, qd : ndarray
        True joint angles [rad] and velocities [rad/s].
    q_measured, qd_measured : ndarray
        What each joint's sensor delivered.
    r, r_dot, r_ddot : ndarray
        Joint references [rad, rad/s, rad/s^2].
    u : ndarray
        Torque commands after each joint's limit [N m].
    tau_hat : ndarray
        Each joint's disturbance estimate [N m] (0 without an observer).
    tau_dn : ndarray
        Ground truth of each joint's nominal disturbance, eq. (3) per joint:
        ``u_i - b_n,i qd_i - J_n,i qdd_i(t_k+)`` [N m].
    tau_external : ndarray
        The joint torques external forces exert on the arm [N m] (``J^T F`` for an
        end-effector force; robotics sign: ``M qdd + ... = u + tau_external``).
    Ts : float
        Sampling period [s].
    joint_names : tuple of str
    label : str
    diverged : bool
        True if the run stopped early (the arrays end there).
    force : ndarray or None, shape (samples, 3) or (samples, 6)
        The end-effector force [N] (and moment [N m]) applied, world frame, where one was.
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    q_measured: np.ndarray
    qd_measured: np.ndarray
    r: np.ndarray
    r_dot: np.ndarray
    r_ddot: np.ndarray
    u: np.ndarray
    tau_hat: np.ndarray
    tau_dn: np.ndarray
    tau_external: np.ndarray
    Ts: float
    _: KW_ONLY
    joint_names: tuple = ()
    label: str = ""
    diverged: bool = False
    force: np.ndarray | None = None

    def __post_init__(self):
        n = len(self.t)
        joints = len(self.joint_names)
        for name in TRACES:
            array = np.array(getattr(self, name), dtype=float)
            if array.shape != (n, joints):
                raise ParameterValueError(
                    f"{name} must have shape ({n}, {joints}), got {array.shape}"
                )
            array.setflags(write=False)
            object.__setattr__(self, name, array)

    def __len__(self) -> int:
        return len(self.t)

    @property
    def position_error(self) -> np.ndarray:
        """``q - r`` [rad] per joint."""
        return self.q - self.r

    @property
    def estimation_error(self) -> np.ndarray:
        """``tau_hat - tau_dn`` [N m] per joint."""
        return self.tau_hat - self.tau_dn

    def metrics(self, *, start: float = 0.0) -> dict:
        """Per-joint RMS and peak errors over ``t >= start``.

        Parameters
        ----------
        start : float, optional
            First instant of the window [s]. Default 0.

        Returns
        -------
        dict
            ``rms_position_error``, ``max_position_error`` [rad] and ``rms_estimation_error``
            [N m]: a list of one float per joint each (in ``joint_names`` order).
        """
        mask = self.t >= start
        e = self.position_error[mask]
        return {
            "rms_position_error": _rms(e).tolist(),
            "max_position_error": (np.max(np.abs(e), axis=0) if len(e) else _rms(e)).tolist(),
            "rms_estimation_error": _rms(self.estimation_error[mask]).tolist(),
        }

    def _columns(self) -> dict:
        columns = {"t": self.t}
        for name in TRACES:
            values = getattr(self, name)
            for j, joint in enumerate(self.joint_names):
                columns[f"{name}[{joint}]"] = values[:, j]
        return columns

    def to_csv(self, path):
        """Write the traces to ``path`` as CSV, atomically (the columns of :meth:`to_pandas`).

        Parameters
        ----------
        path : str or os.PathLike

        Returns
        -------
        pathlib.Path
        """
        from .._table import columns_to_csv

        return columns_to_csv(self._columns(), path)

    def to_pandas(self):
        """The traces as a ``pandas.DataFrame``: ``t`` and one column ``<trace>[<joint>]`` per
        trace and joint (``q[shoulder]``, ...), SI units.

        Returns
        -------
        pandas.DataFrame
        """
        import pandas as pd

        return pd.DataFrame(self._columns())

    def plot(self, *, title: str | None = None):
        """Per joint, one row of three panels: position error, torque command, and the
        estimate drawn over the ground truth of its disturbance (eq. 3 per joint).

        One row per joint keeps a 7-joint arm legible (each joint on its own scale); the
        ground truth ``tau_dn`` is a wide light line, the estimate ``tau_hat`` a thin dark
        dashed one on top; the legend sits below the panels, off the data.

        Parameters
        ----------
        title : str, optional
            Figure title (default the label).

        Returns
        -------
        matplotlib.figure.Figure
        """
        import matplotlib.pyplot as plt

        from .._plotting import style_axes

        n = len(self.joint_names)
        fig, axes = plt.subplots(n, 3, figsize=(9.0, 1.45 * n + 1.3), sharex=True,
                                 squeeze=False, layout="constrained")  # fmt: skip
        for j, joint in enumerate(self.joint_names):
            row = axes[j]
            row[0].plot(self.t, 1e3 * self.position_error[:, j], color="C0", linewidth=1.0)
            row[1].plot(self.t, self.u[:, j], color="C1", linewidth=1.0)
            truth = row[2].plot(self.t, self.tau_dn[:, j], color="C2", linewidth=3.0, alpha=0.45,
                                label="tau_dn: ground truth, eq. (3) per joint")  # fmt: skip
            estimate = row[2].plot(self.t, self.tau_hat[:, j], color="k", linewidth=0.9,
                                   linestyle="--", label="tau_hat: its estimate")  # fmt: skip
            xlabel = "time [s]" if j == n - 1 else None
            style_axes(row[0], xlabel=xlabel, ylabel=f"{joint}\nq - r [mrad]")
            style_axes(row[1], xlabel=xlabel, ylabel="u [N m]")
            style_axes(row[2], xlabel=xlabel, ylabel="disturbance [N m]")
        axes[0, 0].set_title("position error", fontsize="medium")
        axes[0, 1].set_title("torque command", fontsize="medium")
        axes[0, 2].set_title("disturbance", fontsize="medium")
        fig.legend(handles=[truth[0], estimate[0]], loc="outside lower center", ncol=2,
                   fontsize="small", frameon=False)  # fmt: skip
        fig.suptitle(title if title is not None else (self.label or "N-joint run"))
        return fig
