"""The result of an identification: parameters, their standard deviations, the fit."""

from __future__ import annotations

import math
import types
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from .._files import write_json_atomic
from .._table import columns_to_csv, columns_to_pandas
from .._validation import ParameterValueError, positive, readonly
from ._checks import shareable, units
from ._regression import PARAMETERS

__all__ = ["Identification"]

#: What each parameter is called on a rotary and a linear axis (for reports).
_LABELS = {
    "J": ("inertia J", "mass M"),
    "b": ("viscous friction b", "viscous friction Fv"),
    "coulomb": ("Coulomb friction c", "Coulomb friction Fc"),
    "offset": ("offset", "offset"),
}


def _relative(value: float, std: float, fixed: bool) -> str:
    """The relative uncertainty, or why none is printed: a near-zero value (below 2 standard
    deviations) has only its absolute one (a relative 2232 % says nothing)."""
    if fixed:
        return "fixed"
    if std == 0.0 and value == 0.0:
        return "-"
    if abs(value) < 2.0 * std:
        return "within 2 std of 0"
    return f"{100 * std / abs(value):.2f} %"


def _loop_errors(simulation) -> str:
    """The errors of the loop simulated with the identified parameters, in words: the input's
    in the band the regression uses, since above it the logged input is mostly the controller's
    response to the encoder's quantisation and noise, which the noise-free simulation lacks
    (86 % unfiltered but 1 % in band on a 4096-count PD log at 0.5 ms)."""
    text = f"position error {simulation['position_error_percent']:.4g} %"
    raw = simulation["input_error_percent"]
    band = simulation.get("input_error_band_percent")
    if band is None:
        return f"{text}, input error {raw:.4g} %"
    text += f", input error {band:.3g} % below {simulation['band_hz']:.3g} Hz (the band identified)"
    if raw > 2.0 * band + 1.0:
        text += (
            f"; {raw:.3g} % unfiltered: the logged input also carries the controller's response "
            "to the encoder's quantisation and noise, which the simulation does not"
        )
    else:
        text += f", {raw:.3g} % unfiltered"
    return text


def _json_ready(value):
    if isinstance(value, Mapping):
        return {str(k): _json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_ready(v) for v in value]
    if isinstance(value, np.ndarray):
        return _json_ready(value.tolist())
    if isinstance(value, (np.integer, np.bool_)):
        return value.item()
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    return value


@dataclass(frozen=True, eq=False)
class Identification:
    r"""Identified rigid-axis model :math:`u = J\ddot q + b\dot q + c\,\mathrm{sign}(\dot q)
    + \mathrm{offset}` with the fit it came from.

    Made by :func:`hpdob.identify`. Units follow ``axis`` (``units`` lists them): on a linear
    axis ``J`` is the mass [kg], ``b`` [N s/m], ``coulomb`` and ``offset`` [N].

    Attributes
    ----------
    method : str
        ``"idim-ls"`` or ``"idim-iv"``.
    J, b, coulomb, offset : float
        Inertia (or mass), viscous and Coulomb friction, and the constant offset of the
        input (a constant load, or a bias of the torque/force measurement).
    J_std, b_std, coulomb_std, offset_std : float
        Standard deviations, square roots of the diagonal of ``covariance``.
    std_iid : dict
        The textbook standard deviations, from ``covariance_iid``.
    covariance : ndarray, shape (4, 4)
        :math:`A \hat S A^T`, :math:`A = (Z^T X)^{-1}` (:math:`Z = X` for least squares),
        with :math:`\hat S` the batch-means covariance of the scores :math:`z_k e_k` over 20
        contiguous batches of each log's rows: it holds for the decimated residual, which is
        correlated over neighbouring rows (Bester, Conley and Hansen 2011; docs/real-data.md).
        0 for fixed parameters.
    covariance_iid : ndarray, shape (4, 4)
        The textbook :math:`\hat\sigma^2 (Z^T X)^{-1} Z^T Z (X^T Z)^{-1}`,
        :math:`\hat\sigma^2 = \lVert y - X\hat\theta\rVert^2 / (N - 4)`, right for a white
        residual only; for least squares it is :math:`\hat\sigma^2 (X^T X)^{-1}`, the EMPS
        benchmark's (compare its published standard deviations with :attr:`std_iid`).
    t : ndarray
        Time [s] of each regression row (the decimated samples used).
    u : ndarray
        Measured input after the parallel filter and decimation [N m or N].
    u_model : ndarray
        The model's input :math:`X\hat\theta` on the same rows.
    axis : str or None
        ``"rotary"``, ``"linear"`` or None (units not stated).
    settings : mapping
        Everything needed to repeat the identification (filters, method options), and
        ``rests``, ``rest_rows``, ``rest_speed``: whether the log's rests were dropped, how
        many rows, and the speed below which it rests [rad/s or m/s].
    n_samples : int
        Samples of the log.
    condition_number : float
        Of the observation matrix ``X`` as it is (as the EMPS script reports it; it depends
        on the units).
    max_speed : float
        Largest filtered speed of the log [rad/s or m/s].
    iterations : int
        IDIM-IV iterations (0 for IDIM-LS).
    converged : bool
        Whether IDIM-IV met its tolerance (always True for IDIM-LS).
    simulation : mapping or None
        With a loop: relative errors [%] of the loop simulated with the identified
        parameters against the log (``position_error_percent``, ``input_error_percent``,
        as eq. 11 of the EMPS description), and ``input_error_band_percent``, the input's
        with both low-passed to ``band_hz`` [Hz], the decimation filter's cut-off (above it
        the logged input is mostly the controller's response to the encoder's quantisation
        and noise, which the simulation lacks).
    t_log, theta_log, theta_simulated : ndarray or None
        With a loop: the log's time and position and the simulated position, for the plot.
    offsets, offsets_std : tuple of float
        The offset of each log and its standard deviation (one log: ``(offset,)``). With
        one offset per log, ``offset`` is their mean.
    sources : tuple of str
        The name of each log.
    run : ndarray of int
        The log each regression row comes from (index into ``sources``).
    fits : tuple of (mapping or None)
        Per log: the identified model simulated on it (through its loop, or open loop from
        its input) and the NRMSE fits [%] of position and velocity (MATLAB ``compare``);
        None without ``diagnostics`` (but for a first log with a loop: ``simulation``).
    sensitivity : mapping or None
        ``{"x2": {...}, "/2": {...}}``: how far each estimated parameter moves, in standard
        deviations, with the filters' bandwidth doubled and halved.
    warnings : tuple of str
        The :class:`IdentificationWarning` messages of the identification.
    systematic : mapping or None
        With ``diagnostics``: a systematic uncertainty of each parameter beside the statistical
        ``std``: the largest move of the estimate when the filters' bandwidth is doubled or
        halved (the method's bias under the filters, which ``std`` does not contain; 0 for a
        fixed parameter). Report ``std`` and ``systematic`` side by side (docs/real-data.md).
    notes : tuple of str
        What the diagnostics could not check (e.g. a log too short for the filters' bandwidth
        halved), printed by :meth:`summary`.
    """

    method: str
    J: float
    b: float
    coulomb: float
    offset: float
    covariance: np.ndarray = field(repr=False)
    t: np.ndarray = field(repr=False)
    u: np.ndarray = field(repr=False)
    u_model: np.ndarray = field(repr=False)
    axis: str | None
    settings: Mapping
    n_samples: int
    condition_number: float
    max_speed: float
    iterations: int = 0
    converged: bool = True
    simulation: Mapping | None = None
    t_log: np.ndarray | None = field(default=None, repr=False)
    theta_log: np.ndarray | None = field(default=None, repr=False)
    theta_simulated: np.ndarray | None = field(default=None, repr=False)
    offsets: tuple = ()
    offsets_std: tuple = ()
    sources: tuple = ()
    run: np.ndarray | None = field(default=None, repr=False)
    fits: tuple = ()
    sensitivity: Mapping | None = None
    warnings: tuple = ()
    covariance_iid: np.ndarray | None = field(default=None, repr=False)
    notes: tuple = ()
    systematic: Mapping | None = None

    def __post_init__(self) -> None:
        if not self.offsets:
            object.__setattr__(self, "offsets", (float(self.offset),))
            object.__setattr__(self, "offsets_std", (float(np.sqrt(self.covariance[3, 3])),))
        if self.run is None:
            object.__setattr__(self, "run", np.zeros(np.shape(self.t), dtype=int))
        object.__setattr__(self, "run", readonly(np.array(self.run, dtype=int)))
        if self.covariance_iid is None:
            object.__setattr__(self, "covariance_iid", self.covariance)
        for name in ("covariance", "covariance_iid", "t", "u", "u_model", "t_log", "theta_log",
                     "theta_simulated"):  # fmt: skip
            value = getattr(self, name)
            # an immutable float64 array (the log's columns, a simulated trace) is shared:
            # nobody can change it, and a log's traces are not held twice
            if value is not None and not shareable(value):
                object.__setattr__(self, name, readonly(np.array(value, dtype=float)))
        object.__setattr__(self, "settings", types.MappingProxyType(dict(self.settings)))
        if self.simulation is not None:
            object.__setattr__(self, "simulation", types.MappingProxyType(dict(self.simulation)))

    # -- derived quantities ------------------------------------------------------------------
    @property
    def parameters(self) -> dict[str, float]:
        """``{"J": ..., "b": ..., "coulomb": ..., "offset": ...}``."""
        return {name: float(getattr(self, name)) for name in PARAMETERS}

    @property
    def std(self) -> dict[str, float]:
        """Standard deviation of each parameter (same keys as :attr:`parameters`)."""
        return dict(zip(PARAMETERS, np.sqrt(np.diag(self.covariance)).tolist(), strict=True))

    @property
    def std_iid(self) -> dict[str, float]:
        """The textbook standard deviations (white residual; see ``covariance_iid``)."""
        return dict(zip(PARAMETERS, np.sqrt(np.diag(self.covariance_iid)).tolist(), strict=True))

    @property
    def J_std(self) -> float:
        """Standard deviation of ``J`` [kg m^2, or kg on a linear axis]."""
        return self.std["J"]

    @property
    def b_std(self) -> float:
        """Standard deviation of ``b`` [N m s/rad, or N s/m on a linear axis]."""
        return self.std["b"]

    @property
    def coulomb_std(self) -> float:
        """Standard deviation of ``coulomb`` [N m, or N on a linear axis]."""
        return self.std["coulomb"]

    @property
    def offset_std(self) -> float:
        """Standard deviation of ``offset`` [N m, or N on a linear axis]."""
        return self.std["offset"]

    @property
    def residual(self) -> np.ndarray:
        """``u - u_model`` [N m or N] on the regression rows."""
        return self.u - self.u_model

    @property
    def relative_error(self) -> float:
        """``100 ||u - u_model|| / ||u||`` [%] (EMPS description, eq. 11)."""
        return 100.0 * float(np.linalg.norm(self.residual) / np.linalg.norm(self.u))

    @property
    def residual_std(self) -> float:
        r""":math:`\hat\sigma = \lVert u - u_{model}\rVert / \sqrt{N - 4}` [N m or N]."""
        return float(np.linalg.norm(self.residual) / math.sqrt(self.u.size - len(PARAMETERS)))

    @property
    def units(self) -> dict:
        """Unit of each quantity on this axis (neutral "N m or N" if the axis is not stated)."""
        return dict(units(self.axis))

    # -- model -------------------------------------------------------------------------------
    def model(self, *, coulomb_velocity: float | None = None):
        """The identified model as a :class:`hpdob.ServoModel` (the offset is not part of it).

        Parameters
        ----------
        coulomb_velocity : float, optional
            Velocity scale [rad/s or m/s] of the model's ``tanh`` Coulomb friction (the
            identification uses ``sign``). Default: 1 % of the log's largest speed.

        Returns
        -------
        ServoModel
            ``ServoModel(J, b, coulomb=coulomb, coulomb_velocity=...)``.

        Raises
        ------
        ParameterValueError
            If the identified ``J`` is not positive or ``b`` or ``coulomb`` is negative
            (a ServoModel cannot hold them; the message says which).
        """
        from ..models import ServoModel

        for name, value in self.parameters.items():
            if name == "offset":
                continue
            if value < 0.0 or (name == "J" and value == 0.0):
                raise ParameterValueError(
                    f"the identified {name} = {value:.6g} {self.units[name]} is "
                    f"{'not positive' if name == 'J' else 'negative'}: no ServoModel has it; "
                    "check the log's excitation and the identification settings"
                )
        if coulomb_velocity is None:
            coulomb_velocity = 0.01 * self.max_speed if self.max_speed > 0 else 0.01
        velocity = positive(
            coulomb_velocity, "coulomb_velocity", "a positive finite velocity [rad/s or m/s]"
        )
        return ServoModel(self.J, self.b, coulomb=self.coulomb, coulomb_velocity=velocity)

    def validate(self, log, *, loop=None, offset: float | None = None):
        """Simulate the identified model on another log and measure how well it fits.

        Open loop from the log's input, or through ``loop`` (the controller and reference
        that produced it) if given; from the log's first position and filtered velocity.
        Position and velocity (the identification's filtered differentiation, at the log's
        own sampling period) are compared by MATLAB ``compare``'s NRMSE fit.

        Parameters
        ----------
        log : Log
            A log the model was not fitted to (identify on one part, validate on another).
        loop : FeedbackLoop, optional
            The logged loop; None simulates open loop from the logged input.
        offset : float, optional
            The input offset to simulate [N m or N]. Default: the identified one (with one
            offset per log, their mean).

        Returns
        -------
        Validation
            ``position_fit``, ``velocity_fit`` [%], the traces, ``summary()``, ``to_dict()``
            and ``plot()``.

        Raises
        ------
        ParameterTypeError
            If ``log`` is not a :class:`Log` or ``loop`` not a :class:`FeedbackLoop`.
        ParameterValueError
            If the identified ``J`` is not positive, or ``loop`` does not have one sample
            per logged sample, or the simulation diverges.

        Examples
        --------
        >>> from hpdob.identification import emps
        >>> log = emps()
        >>> first = log.slice(0.0, 12.4)
        >>> fit = first.identify(method="idim-ls")
        >>> check = fit.validate(log.slice(12.4, None))
        >>> bool(check.velocity_fit > 80.0)
        True
        """
        from ._simfit import validate

        return validate(self, log, loop=loop, offset=offset)

    # -- reports -----------------------------------------------------------------------------
    def _repr_markdown_(self) -> str:
        """A compact table for Jupyter: each parameter with its standard deviation and unit."""
        from .._repr import markdown_table

        u, i = self.units, int(self.axis == "linear")
        rows = [(f"{_LABELS[n][i]} [{u[n]}]", f"{v:.4g} ± {self.std[n]:.2g}")
                for n, v in self.parameters.items()]  # fmt: skip
        rows += [("method", f"{self.method} ({self.n_samples} samples)"),
                 ("relative error [%]", self.relative_error)]  # fmt: skip
        return markdown_table("IdentificationResult", rows)  # fmt: skip

    def summary(self) -> str:
        """A report of the identification.

        Returns
        -------
        str
            A few lines: the method and rows, each parameter with its standard deviation
            (the batch-means one; absolute and relative) and unit, the relative error,
            residual std and condition number, IDIM-IV's iterations, with a loop the errors
            of the loop simulated with the identified parameters, and with diagnostics the
            fits and how far the parameters move when the filters change.
        """
        u = self.units
        linear = self.axis == "linear"
        periods = sorted({log["Ts"] for log in self.settings.get("logs", ())}) or [
            self.settings["Ts"]
        ]
        ts = ", ".join(f"{value:g}" for value in periods)
        lines = [f"{self.method.upper()}: {self.t.size} regression rows from "
                 f"{self.n_samples} samples (Ts = {ts} s)"]  # fmt: skip
        fixed = self.settings.get("fixed", {})
        several = len(self.offsets) > 1
        for name, value in self.parameters.items():
            std = self.std[name]
            label = _LABELS[name][1 if linear else 0]
            if several and name == "offset":
                label = "mean offset"
            relative = _relative(value, std, name in fixed)
            if name == "coulomb" and self.settings.get("friction") == "viscous":
                relative = "0: friction='viscous' lumps it into the offset"
            systematic = (self.systematic or {}).get(name)
            extra = "" if not systematic else f", systematic +- {systematic:.3g}"
            lines.append(f"  {label:<22}{value:>14.6g} +- {std:<11.4g} {u[name]:<16} "
                         f"({relative}{extra})")  # fmt: skip
        if several:
            for source, value, std in zip(self.sources, self.offsets, self.offsets_std,
                                          strict=True):  # fmt: skip
                lines.append(f"    offset of {source}: {value:.6g} +- {std:.4g} {u['offset']} "
                             f"({_relative(value, std, False)})")  # fmt: skip
        lines.append(
            f"  relative error {self.relative_error:.3f} %, residual std "
            f"{self.residual_std:.4g} {u['input']}, condition number {self.condition_number:.1f}"
        )
        if self.method == "idim-iv":
            state = "converged" if self.converged else "NOT converged"
            lines.append(f"  {self.iterations} IV iterations, {state}")
        if self.simulation is not None:
            lines.append(f"  loop simulated with these parameters: {_loop_errors(self.simulation)}")
        for source, fit in zip(self.sources, self.fits, strict=False):
            if fit is not None:
                lines.append(
                    f"  simulated on {source} ({fit['mode']}): position fit "
                    f"{fit['position_fit_percent']:.2f} %, velocity fit "
                    f"{fit['velocity_fit_percent']:.2f} % (MATLAB compare)"
                )
        adaptive = bool(self.settings.get("adaptive", False))
        for key, which in (("/2", "halved"), ("x2", "doubled")):
            moves = (self.sensitivity or {}).get(key)
            if moves:
                listed = ", ".join(f"{name} {move:+.2g}" for name, move in moves.items()
                                   if not name.startswith("offset"))  # fmt: skip
                why = (
                    "for information only: with the filters read from the log only halving "
                    "can warn" if adaptive and key == "x2" else
                    "a change of bias; a warning needs its target's allowance too: 2 % of J, "
                    "b 10 % or 0.02 J 2 pi B, Coulomb 5 % or 2 % of the input's RMS"
                )  # fmt: skip
                lines.append(
                    f"  filters' bandwidth {which}: moves in standard deviations: {listed} ({why})"
                )
        for message in self.notes:
            lines.append(f"  note: {message}")
        for message in self.warnings:
            lines.append(f"  warning: {message}")
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """The identification as plain Python data.

        Returns
        -------
        dict
            JSON-ready (non-finite values as None): ``method``, ``axis``, ``parameters``,
            ``std``, ``std_iid``, ``units``, ``covariance``, ``relative_error_percent``,
            ``residual_std``, ``rows``, ``n_samples``, ``condition_number``, ``max_speed``,
            ``iterations``, ``converged``, ``simulation``, ``offsets``, ``offsets_std``,
            ``fits``, ``sensitivity``, ``systematic``, ``warnings``, ``notes`` and
            ``settings``.
        """
        return _json_ready(
            {
                "method": self.method,
                "axis": self.axis,
                "parameters": self.parameters,
                "std": self.std,
                "units": {name: self.units[name] for name in PARAMETERS},
                "covariance": self.covariance,
                "std_iid": self.std_iid,
                "relative_error_percent": self.relative_error,
                "residual_std": self.residual_std,
                "rows": int(self.t.size),
                "n_samples": int(self.n_samples),
                "condition_number": self.condition_number,
                "max_speed": self.max_speed,
                "iterations": self.iterations,
                "converged": self.converged,
                "simulation": None if self.simulation is None else dict(self.simulation),
                "offsets": dict(zip(self.sources or ("log",), self.offsets, strict=False)),
                "offsets_std": dict(zip(self.sources or ("log",), self.offsets_std, strict=False)),
                "fits": list(self.fits),
                "sensitivity": None if self.sensitivity is None else dict(self.sensitivity),
                "warnings": list(self.warnings),
                "notes": list(self.notes),
                "systematic": None if self.systematic is None else dict(self.systematic),
                "settings": dict(self.settings),
            }
        )

    def to_json(self, path):
        """Write :meth:`to_dict` to ``path`` as JSON (atomically).

        Parameters
        ----------
        path : str or os.PathLike
            The file to write (replaced if it exists).

        Returns
        -------
        str or os.PathLike
            ``path``, as given.
        """
        write_json_atomic(path, self.to_dict())
        return path

    def _columns(self) -> dict:
        columns = {"t": self.t, "u": self.u, "u_model": self.u_model, "residual": self.residual}
        if len(self.offsets) > 1:
            columns["run"] = self.run.astype(float)
        return columns

    def to_csv(self, path):
        """Write the fit as CSV (atomically).

        Parameters
        ----------
        path : str or os.PathLike
            The file to write (replaced if it exists): columns ``t``, ``u``, ``u_model``,
            ``residual`` on the regression rows (and ``run``, the log's index, with several).

        Returns
        -------
        pathlib.Path
            ``path``.
        """
        return columns_to_csv(self._columns(), path)  # atomic

    def to_pandas(self):
        """The fit as a table.

        Returns
        -------
        pandas.DataFrame
            Columns ``t``, ``u``, ``u_model``, ``residual`` on the regression rows.

        Raises
        ------
        ImportError
            If pandas is not installed (``pip install hpdob[pandas]``).
        """
        return columns_to_pandas(self._columns(), caller="Identification.to_pandas()")

    def plot(self, *, title: str | None = None):
        """Measured vs model torque/force, the residual and (with a loop) the position error of
        the loop simulated with the identified model.

        Parameters
        ----------
        title : str, optional
            The figure's title. Default: the method and its relative error.

        Returns
        -------
        matplotlib.figure.Figure
        """
        import matplotlib.pyplot as plt

        from .._plotting import PAPER_WIDTH, style_axes

        u = self.units
        effort = {"rotary": "torque", "linear": "force"}.get(self.axis, "torque/force")
        panels = 3 if self.theta_simulated is not None else 2
        fig, axes = plt.subplots(
            panels, 1, figsize=(PAPER_WIDTH, 2.2 * panels + 0.6), sharex=True,
            layout="constrained",
        )  # fmt: skip
        ax = axes[0]
        ax.plot(self.t, self.u, color="0.35", linewidth=1.2, label="measured (filtered)")
        ax.plot(self.t, self.u_model, "--", linewidth=1.0, label=f"model ({self.method})")
        style_axes(ax, xlabel=None, ylabel=f"{effort} [{u['input']}]")
        ax.legend(loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=2, fontsize="small")
        ax = axes[1]
        ax.plot(self.t, self.residual, linewidth=0.8)
        style_axes(ax, xlabel=None if panels == 3 else "time [s]",
                   ylabel=f"residual [{u['input']}]")  # fmt: skip
        if panels == 3:
            ax = axes[2]
            ax.plot(self.t_log, self.theta_log - self.theta_simulated, linewidth=0.8)
            style_axes(ax, xlabel="time [s]", ylabel=f"position error [{u['position']}]")
            ax.set_title("measured minus loop simulated with the identified model",
                         fontsize="small", loc="right")  # fmt: skip
        fig.suptitle(title or f"{self.method.upper()}: relative error {self.relative_error:.2f} %")
        return fig
