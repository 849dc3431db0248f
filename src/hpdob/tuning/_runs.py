"""The verification runs of ``tune``: the scenario sampled once, the centre runs on two threads."""

from __future__ import annotations

import warnings
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..models import ServoModel
from ..simulation import ServoLoop, run_loop, sample_count, sample_signals

__all__ = ["VerificationRuns"]


class VerificationRuns:
    """``simulate()`` of candidates on the verification scenario, without re-evaluating it.

    The scenario is sampled once per sub-step count (each true inertia may need its own), not
    once per simulation; the runs are :func:`~hpdob.simulation._simulate.run_loop`'s, so each
    is bit for bit what ``simulate`` gives. A diverged run is marked, not warned.
    """

    def __init__(self, *, nominal, Ts, sensor, actuator, coulomb, run):
        self.nominal, self.Ts, self.coulomb, self.run = nominal, Ts, coulomb, run
        self.devices = {"sensor": sensor, "actuator": actuator}
        self.n = sample_count(Ts, run["duration"])
        self.sampled: dict = {}

    def loop(self, r, J_ratio, b):
        """Candidate ``r``'s loop on the true plant ``(J_ratio J_n, b)`` and its signals."""
        loop = ServoLoop(plant=ServoModel(J_ratio * self.nominal.J, b, coulomb=self.coulomb),
                         nominal=self.nominal, Ts=self.Ts, controller=r["_controller"],
                         observer=r["_design"], **self.devices)  # fmt: skip
        S = loop.plant.substeps(self.Ts, None)
        if S not in self.sampled:
            self.sampled[S] = sample_signals(self.run["reference"], self.run.get("disturbance"),
                                             Ts=self.Ts, n=self.n, substeps=S)  # fmt: skip
        return loop, self.sampled[S]

    def simulate(self, r, J_ratio, b):
        """``(result, metrics, worst RMS position error)`` of candidate ``r`` on that plant."""
        with warnings.catch_warnings():  # numpy's warnings of a diverging run
            warnings.simplefilter("ignore", RuntimeWarning)
            return self._run(r, J_ratio, b)

    def at(self, candidates, J_ratio, b, report):
        """:meth:`simulate` of every candidate on one plant, in order, on two threads (the
        compiled kernel releases the GIL; the next run starts while this one is collected);
        ``report("simulation", done, total)`` before each, as a serial loop would call it."""
        self.loop(candidates[0], J_ratio, b)  # sampled before the threads share it
        # catch_warnings is process-wide: set once here, for both threads
        with warnings.catch_warnings(), ThreadPoolExecutor(2) as pool:
            warnings.simplefilter("ignore", RuntimeWarning)
            runs = [pool.submit(self._run, candidates[0], J_ratio, b)]
            for done in range(len(candidates)):
                report("simulation", done, len(candidates))
                if done + 1 < len(candidates):
                    runs.append(pool.submit(self._run, candidates[done + 1], J_ratio, b))
                yield runs[done].result()

    def _run(self, r, J_ratio, b):
        result = run_loop(*self.loop(r, J_ratio, b), np.zeros(2))
        metrics = result.metrics()
        position = max(metrics["rms_position_error_regulation"],
                       metrics["rms_position_error_tracking"])  # fmt: skip
        return result, metrics, position
