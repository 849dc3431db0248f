"""The result of :func:`hpdob.tune`: the recommendation, the candidates and the evidence."""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

from .._table import columns_to_pandas

__all__ = ["TuningResult"]

#: Columns of :attr:`TuningResult.table`, with their units.
COLUMNS = {
    "family": "",
    "order": "",
    "name": "",
    "parameter": "",
    "value": "rad/s, or the Kalman process noise",
    "accuracy": "|1 - Q| at the disturbance frequency (RMS over a band)",
    "tau_noise": "N m RMS",
    "u_noise": "N m RMS",
    "radius": "worst closed-loop spectral radius over the corners",
    "radius_margin": "the same with one extra sample of delay",
    "delay_margin_samples": "extra samples of delay the loop stays stable with at every corner "
    "(-1 unstable, capped at 20)",
    "robust": "",
    "within_noise": "",
    "pareto": "",
    "simulated": "objective of the simulation at the centre (N m or rad)",
}


@dataclass(frozen=True, eq=False)
class TuningResult:
    """What :func:`hpdob.tune` found (see there and ``docs/tuning.md``).

    Attributes
    ----------
    design
        The recommended design (a :class:`~hpdob.ObserverDesign`, an ESO or a Kalman design).
    observer
        Its runtime object, reset at rest: ready for the sample loop.
    recommendation : dict
        The recommended candidate's figures (family, order, tuned parameter and value,
        accuracy, noise, spectral radii, ``delay_margin_samples``: the extra samples of delay
        it stays stable with at every corner, simulated objective).
    verification : list of dict
        The nonlinear simulation at every corner of the uncertainty set: ``J_ratio``, ``b``,
        ``diverged``, ``tracks`` (RMS position error below the reference's RMS), ``radius``,
        ``rms_estimation_error`` [N m], ``rms_position_error`` [rad]
        and ``delay_margin`` [s].
    settings : dict
        The arguments the search ran with.
    scenario : dict
        The verification run (``reference``, ``disturbance``, ``duration``: keyword arguments
        of :func:`hpdob.simulate`).
    notes : tuple of str
        What was left out and why.
    rows : list of dict
        Every candidate with its figures (what :attr:`table` shows).
    recommended : dict
        The recommended row, with its design and controller (what :attr:`recommendation`
        shows, and more).
    """

    rows: list = field(repr=False)
    recommended: dict = field(repr=False)
    verification: list = field(repr=False)
    settings: dict = field(repr=False)
    notes: tuple = ()
    scenario: dict = field(default_factory=dict, repr=False)

    @property
    def design(self):
        """The recommended design."""
        return self.recommended["_design"]

    @property
    def observer(self):
        """A runtime object of the recommended design, reset at rest."""
        from ..observers import Observer

        return Observer.of(self.design)

    @property
    def controller(self):
        """The PD the recommendation was verified with (its velocity source included)."""
        return self.recommended["_controller"]

    def _repr_markdown_(self) -> str:
        """A compact table for Jupyter: the recommendation and its figures."""
        from .._repr import markdown_table

        r = self.recommended
        return markdown_table(f"TuningResult: {r['name']}", [
            (r["parameter"], r["value"]), ("candidates", len(self.rows)),
            ("accuracy abs(1 - Q)", r["accuracy"]), ("noise in the estimate [N m RMS]",
                                                 r["tau_noise"]),
            ("worst spectral radius", r["radius"]),
            ("PD velocity", getattr(self.controller, "velocity", "-")),
            ("simulated estimation error [N m RMS]", r.get("simulated_estimation")),
        ])  # fmt: skip

    def loop(self):
        """The loop the recommendation was simulated in, at the centre of the uncertainty set.

        Returns
        -------
        ServoLoop
            The true plant at the centre (``J_n`` times the middle of ``J_range``, the middle of
            ``b_range``, the Coulomb friction simulated), the nominal model, ``Ts``,
            :attr:`controller`, :attr:`design`, the sensor and the actuator (torque limit and
            delay): ``simulate(result.loop(), **result.scenario)`` repeats the run that ranked
            it. The corners are ``loop.replace(plant=...)``.
        """
        from ..simulation import Actuator

        base, s = self.recommended["_base"], self.settings  # the linear figures' loop
        actuator = Actuator(torque_limit=s["torque_limit"], delay_samples=s["delay_samples"])
        return base.replace(plant=base.plant.replace(coulomb=s["coulomb"]), actuator=actuator)

    @property
    def recommendation(self) -> dict:
        """The recommended candidate's figures (JSON-ready)."""
        return {k: v for k, v in self.recommended.items() if not k.startswith("_")}

    @property
    def table(self):
        """Every candidate with its figures, as a :class:`pandas.DataFrame`."""
        columns = {name: [row.get(name) for row in self.rows] for name in COLUMNS}
        return columns_to_pandas(columns, caller="TuningResult.table")

    def pareto(self):
        """The Pareto front of (accuracy, noise) among the qualified candidates.

        Returns
        -------
        pandas.DataFrame
            The rows of :attr:`table` on the front (no qualified candidate is both more
            accurate and less noisy), renumbered from 0.

        Raises
        ------
        ImportError
            If pandas is not installed (``pip install hpdob[pandas]``).
        """
        frame = self.table
        return frame[frame["pareto"]].reset_index(drop=True)

    def report(self) -> str:
        """The recommendation and why, as text.

        Returns
        -------
        str
            The recommended observer and parameter, how many candidates qualified and on what
            grounds, its accuracy, noise, spectral radius and simulated errors, the
            nonlinear simulations at every corner of the uncertainty set, and notes.
        """
        r, s = self.recommended, self.settings
        unit = "rad/s" if r["parameter"] == "bandwidth" else ""
        margin = str(r["delay_margin_samples"])
        if r["delay_margin_samples"] >= s["max_extra_delay"]:
            margin = f"at least {margin}"
        qualified = sum(row["robust"] and row["within_noise"] for row in self.rows)
        lines = [
            f"Recommended: {r['name']}, {r['parameter']} = {r['value']:.4g} {unit}".rstrip(),
            f"  searched {len(self.rows)} candidates ({', '.join(s['families'])}); "
            f"{qualified} robustly stable over J/J_n in [{s['J_range'][0]:g}, "
            f"{s['J_range'][1]:g}] with {s['delay_samples']} + 1 samples of delay"
            + ("" if s["noise_limit"] is None else f" and within {s['noise_limit']:g} N m noise")
            + "; all of these simulated at the centre of the set",
            f"  accuracy |1 - Q| {r['accuracy']:.3g}; sensor noise in the estimate "
            f"{r['tau_noise']:.3g} N m, in u {r['u_noise']:.3g} N m RMS",
            f"  worst spectral radius {r['radius']:.5f} (with one more sample of delay "
            f"{r['radius_margin']:.5f}); stable at every corner with up to {margin} extra "
            "samples of delay",
            f"  {self._velocity_text()}",
            f"  simulated at the centre: RMS estimation error {r['simulated_estimation']:.3g} N m, "
            f"RMS position error {r['simulated_position']:.3g} rad",
            "  verified by nonlinear simulation at every corner:",
        ]
        for c in self.verification:
            lines.append(
                f"    J/J_n = {c['J_ratio']:g}, b = {c['b']:g}: bounded and tracking, spectral "
                f"radius {c['radius']:.5f}, delay margin {c['delay_margin'] * 1e3:.2f} ms, RMS "
                f"estimation error {c['rms_estimation_error']:.3g} N m, position "
                f"{c['rms_position_error']:.3g} rad"
            )
        return "\n".join(lines + [f"  note: {n}" for n in self.notes[:5]])

    def _velocity_text(self) -> str:
        """Which velocity the verified loop's controller takes, named by its type (the loop
        that ran: a controller asked for the observer's estimate takes the measured velocity
        with an observer that gives none)."""
        ran = getattr(self.controller, "velocity", None)
        if ran is None:  # ADRC: state feedback on its own ESO's estimates
            return f"the {type(self.controller).__name__} controller uses its own estimates"
        name = {"FilteredPD": "filtered PD"}.get(type(self.controller).__name__,
                                                 type(self.controller).__name__)  # fmt: skip
        if ran == "observer":
            return f"the {name}'s derivative uses the observer's velocity estimate omega_hat"
        text = f"the {name}'s derivative uses the measured velocity"
        if (self.settings.get("controller") or {}).get("velocity") == "observer":
            text += (f" (velocity 'observer' was asked for; {self.recommended['name']} gives no "
                     "velocity estimate)")  # fmt: skip
        return text

    def to_dict(self) -> dict:
        """The tuning run as plain Python data.

        Returns
        -------
        dict
            JSON-ready (non-finite values as None): ``settings``, ``recommendation``,
            ``verification``, ``candidates`` (every row) and ``notes``.
        """
        from ..simulation import json_ready

        rows = [{k: v for k, v in row.items() if not k.startswith("_")} for row in self.rows]
        return json_ready({
            "settings": self.settings,
            "recommendation": {**self.recommendation,  # the velocity the verified loop took
                               "velocity": getattr(self.controller, "velocity", None)},
            "verification": self.verification, "candidates": rows, "notes": list(self.notes),
        })  # fmt: skip

    def to_json(self, path):
        """Write :meth:`to_dict` as JSON (atomically: a temporary file, then renamed).

        Parameters
        ----------
        path : str or os.PathLike
            The file to write (replaced if it exists).

        Returns
        -------
        pathlib.Path
            ``path``.
        """
        from .._files import write_json_atomic

        return write_json_atomic(path, self.to_dict())

    def plot(self):
        """Accuracy against noise of every candidate: the robust set marked, the Pareto front
        and the recommendation.

        Returns
        -------
        matplotlib.figure.Figure
        """
        import matplotlib.pyplot as plt

        from .._plotting import PAPER_WIDTH

        fig, ax = plt.subplots(figsize=(PAPER_WIDTH, 4.2), layout="constrained")
        names = list(dict.fromkeys(r["family"] for r in self.rows))  # the searched variants
        markers = dict(zip(names, itertools.cycle("os^DvP<>X"), strict=False))
        colors = {0: "tab:blue", 1: "tab:red", 2: "tab:green", 3: "tab:purple", 4: "tab:brown"}
        quiet = min((r["tau_noise"] for r in self.rows if r["tau_noise"] > 0), default=1e-12)
        for family, marker in markers.items():
            for m, color in colors.items():
                rows = [r for r in self.rows if r["family"] == family and r["order"] == m
                        and math.isfinite(r["tau_noise"])]  # fmt: skip
                if not rows:
                    continue
                noise = [max(r["tau_noise"], quiet / 10) for r in rows]
                ax.scatter(noise, [r["accuracy"] for r in rows], marker=marker, s=18,
                           facecolors=[color if r["robust"] else "none" for r in rows],
                           edgecolors=color, linewidths=0.8, label=f"{family}, m={m}")  # fmt: skip
        r = self.recommended
        ax.scatter([max(r["tau_noise"], quiet / 10)], [r["accuracy"]], marker="*", s=220,
                   color="gold", edgecolors="black", zorder=5, label="recommended")  # fmt: skip
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("sensor noise in the estimate [N m RMS]")
        ax.set_ylabel("estimation error $|1-Q|$ [-]")
        band = self.settings["frequencies_Hz"]
        at = f"{band[0]:g} Hz" if len(band) == 1 else f"{band[0]:g}-{band[-1]:g} Hz (RMS)"
        ax.set_title(f"candidates at {at}; filled: robustly stable; star: best in simulation",
                     fontsize="medium")  # fmt: skip
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize="x-small", ncols=1)
        return fig
