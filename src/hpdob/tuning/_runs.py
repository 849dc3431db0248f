"""The verification runs of ``tune``: the scenario sampled once, the centre runs on two threads,
started while the analysis of the later candidates goes on."""

from __future__ import annotations

import threading
import warnings
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..models import ServoModel
from ..simulation import ServoLoop, run_loop, sample_count, sample_signals

__all__ = ["CentreRuns", "VerificationRuns"]


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
        self.plants: dict = {}

    def plant(self, J_ratio, b) -> ServoModel:
        """The true plant ``(J_ratio J_n, b)`` with the Coulomb friction: one object per plant,
        so that its runs share the sub-step matrices it keeps (``simulate`` makes the same)."""
        key = repr((J_ratio, b))  # repr: -0.0 is not 0.0 here
        if key not in self.plants:
            self.plants[key] = ServoModel(J_ratio * self.nominal.J, b, coulomb=self.coulomb)
        return self.plants[key]

    def loop(self, r, J_ratio, b):
        """Candidate ``r``'s loop on the true plant ``(J_ratio J_n, b)`` and its signals."""
        loop = ServoLoop(plant=self.plant(J_ratio, b), nominal=self.nominal, Ts=self.Ts,
                         controller=r["_controller"], observer=r["_design"],
                         **self.devices)  # fmt: skip
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

    def started(self, J_ratio, b) -> CentreRuns:
        """A :class:`CentreRuns` on that plant: runs started as the candidates are found."""
        return CentreRuns(self, J_ratio, b)

    def _quiet_run(self, r, J_ratio, b):
        """``(diverged, metrics, worst RMS position error)``: the figures only, so that the
        finished runs waiting for the analysis do not hold their traces."""
        # np.errstate is the thread's own (a context variable): numpy's warnings of a diverging
        # run are silenced in this thread only, not in the caller's analysis meanwhile
        with np.errstate(all="ignore"):
            result, metrics, position = self._run(r, J_ratio, b)
        return result.diverged, metrics, position

    def _run(self, r, J_ratio, b):
        result = run_loop(*self.loop(r, J_ratio, b), np.zeros(2))
        metrics = result.metrics()
        position = max(metrics["rms_position_error_regulation"],
                       metrics["rms_position_error_tracking"])  # fmt: skip
        return result, metrics, position


class CentreRuns:
    """:meth:`VerificationRuns.simulate` of candidates on one plant, each started as soon as
    it is submitted, so that the runs overlap the caller's analysis of the next candidates
    (the compiled kernel releases the GIL). One run at a time while the caller works (a
    second core is all that is free then), two once it waits in :meth:`results`. A context
    manager that cancels what has not started when it exits. Each run is bit for bit the
    serial one."""

    def __init__(self, runs: VerificationRuns, J_ratio, b):
        self._runs, self._plant = runs, (J_ratio, b)
        self._pool = ThreadPoolExecutor(2)
        self._gate = threading.Semaphore(1)  # a second run once the caller waits
        self._futures: list = []

    def __enter__(self) -> CentreRuns:
        return self

    def __exit__(self, *exc) -> None:
        self._gate.release()  # a run waiting at the gate is not cancelled: let it through
        self._pool.shutdown(wait=True, cancel_futures=True)

    def submit(self, r) -> None:
        """Start candidate ``r``'s run."""
        if not self._futures:  # the scenario sampled here, before the threads share it
            self._runs.loop(r, *self._plant)
        self._futures.append(self._pool.submit(self._gated, r))

    def _gated(self, r):
        with self._gate:
            return self._runs._quiet_run(r, *self._plant)

    def results(self, report):
        """``(diverged, metrics, worst RMS position error)`` of each submitted run, in order;
        ``report("simulation", done, total)`` before each, as a serial loop would call it."""
        self._gate.release()  # the caller waits from here on: two runs at a time
        for done, future in enumerate(self._futures):
            report("simulation", done, len(self._futures))
            yield future.result()
