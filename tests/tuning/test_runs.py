"""tune()'s centre runs (``hpdob.tuning._runs.CentreRuns``): one run at a time while the caller
still analyses candidates, two once it waits for the results, the results in submission order.
The runs here are stand-ins that meet at a barrier, so the test asserts no timing: two runs
at once is the only way both get past it."""

from __future__ import annotations

import threading
import time

from hpdob.tuning import _runs


class Stand:
    """A stand-in for VerificationRuns: each run records that it started, and the runs wait
    for each other at a barrier of ``parties`` once ``together`` is set."""

    def __init__(self, parties: int = 2):
        self.started: list = []
        self.first = threading.Event()
        self.barrier = threading.Barrier(parties, timeout=60.0)
        self.lock = threading.Lock()

    def loop(self, r, *plant):  # the scenario sampled before the threads share it
        return None

    def _quiet_run(self, r, *plant):
        with self.lock:
            self.started.append(r)
        self.first.set()
        self.barrier.wait()  # BrokenBarrierError (after 60 s) unless a second run comes
        return (False, {"r": r}, float(r))


def test_one_run_while_the_caller_works_two_once_it_waits():
    stand = Stand()
    events = []
    with _runs.CentreRuns(stand, 1.0, 0.0) as runs:
        for r in (1, 2, 3, 4):
            runs.submit(r)
        assert stand.first.wait(60.0)
        time.sleep(0.05)  # room for a second run to start, were the gate open (no timing asserted)
        assert stand.started == [1]  # the gate holds the second run while the caller works
        out = list(runs.results(lambda *a: events.append(a)))
    # past the barrier in pairs (1 with 2, 3 with 4): two runs at once after results()
    assert [o[2] for o in out] == [1.0, 2.0, 3.0, 4.0]  # in submission order
    assert sorted(stand.started[:2]) == [1, 2] and sorted(stand.started[2:]) == [3, 4]
    assert events == [("simulation", k, 4) for k in range(4)]
