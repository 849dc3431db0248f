"""The sample loop for plants advanced from Python (a :class:`~hpdob.models.PlantSession`,
e.g. MuJoCo), around the compiled sample step.

Per sample ``k``: the motor's angle and velocity from the plant; steps 1-5 of the compiled
:func:`~hpdob.simulation._kernel.run_samples` for this one sample (measure, estimate, control,
limit, observer update, delay) -- the same code the compiled loop runs for hpdob's own plants;
the ground truth (eq. 3, :func:`~hpdob.simulation._kernel.ground_truth`) from the plant's
acceleration just after the command, and there the contact torque of a plant that presses a wall
(``PlantSession.contact``); the plant's advance over the sample with the external
torque at its sub-steps' midpoints. The run stops after a sample whose end state the plant
reports as diverged.
"""

from __future__ import annotations

import numpy as np

from ._records import PATH_GENERIC, LinearPlantRecord

__all__ = ["run_python_plant"]

_EMPTY = np.zeros((1, 1))
#: The plant record of a plant advanced from Python: the kernel stops after step 5.
_PYTHON_PLANT = LinearPlantRecord(
    False, PATH_GENERIC, 1, _EMPTY, _EMPTY[0], _EMPTY[0], _EMPTY, _EMPTY[0], _EMPTY[0], True,
    np.zeros(2), 1.0, 0.0, 1.0, False, 0, 1.0, 0.0, 0.0,
)  # fmt: skip


def run_python_plant(session, n_samples, substeps, Ts, records, out, work, limit, *,
                     progress=None, every=None) -> int:  # fmt: skip
    """Simulate ``n_samples`` samples on ``session``; fill ``out``; return the samples
    completed (as :func:`~hpdob.simulation._kernel.run_samples`). ``progress(done, total)``
    is called at the start, every ``every`` samples and at the end."""
    if progress is not None:
        progress(0, n_samples)
    from ._kernel import ground_truth, run_samples

    ctl, sig = records["ctl"], records["sig"]
    tau_mid, tau_sample, u, tau_dn = sig.tau_mid, sig.tau_sample, out.u, out.tau_dn
    x, applied = work.x, work.applied
    for k in range(n_samples):
        x[0], x[1] = session.motor()
        states = session.states()
        if states is not None:
            x[:] = states
        run_samples(k, k + 1, substeps, Ts, _PYTHON_PLANT, **records, out=out, work=work,
                    limit=limit)  # fmt: skip
        a = float(applied[0])
        accel = session.acceleration(a, float(tau_sample[k]))
        contact = session.contact()
        if contact is not None:
            out.tau_contact[k], out.in_contact[k] = contact
        tau_dn[k] = ground_truth(float(u[k]), float(x[1]), accel, ctl.J_n, ctl.b_n)
        base = k * substeps
        session.advance(a, tau_mid[base : base + substeps])
        if session.diverged(limit):
            if progress is not None:
                progress(k + 1, n_samples)
            return k + 1
        if progress is not None and ((k + 1) % every == 0 or k + 1 == n_samples):
            progress(k + 1, n_samples)
    return n_samples
