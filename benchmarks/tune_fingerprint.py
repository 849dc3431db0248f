"""Digests of everything ``tune`` returns, on seven settings: compare two checkouts bit for bit.

For each setting: the report, every row's figures (``repr``: floats round-trip), each
candidate's ``F, G, H, E`` (their bytes), the verification, the notes and the settings, as one
sha256; the sequence of ``progress`` calls and the warnings seen, or the error raised. Run it
with each checkout's sources first and compare the outputs (issue 25: no figure may move):

    PYTHONPATH=../main/src python benchmarks/tune_fingerprint.py > main.txt
    PYTHONPATH=src python benchmarks/tune_fingerprint.py > this.txt
    diff main.txt this.txt
"""

from __future__ import annotations

import hashlib
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_tune import SETTINGS

from hpdob import PID, Actuator, Encoder, ServoModel, tune

CASES = {
    "paper": dict(SETTINGS),
    "b_range_position": {**SETTINGS, "b_range": (0.0, 2e-3), "objective": "position",
                         "J_range": (0.8, 1.2)},
    "backward_difference_noise_limit": {
        "nominal": ServoModel(2.8e-4), "Ts": 1e-3,
        "sensor": Encoder(4096, velocity="backward-difference"),
        "actuator": Actuator(delay_samples=2), "J_range": (0.9, 1.1),
        "families": ["state", "kalman", "position"], "noise_limit": 2e-3,
        "disturbance_frequency": (0.5, 5.0)},
    "ideal_sensor": {"nominal": ServoModel(2.8e-4, 1e-4), "Ts": 5e-4,
                     "families": ["state", "eso"], "J_range": (0.8, 1.25)},
    "pid": {"nominal": ServoModel(2.8e-4), "Ts": 1e-3, "sensor": Encoder(16384),
            "controller": PID(50.0, 5.0, 100.0), "J_range": (0.9, 1.1),
            "families": ["position", "eso"]},
    "wide_no_answer": {**SETTINGS, "J_range": (0.4, 2.5),
                       "actuator": Actuator(delay_samples=1, torque_limit=0.05)},
    "wide": {**SETTINGS, "J_range": (0.5, 2.0),
             "actuator": Actuator(delay_samples=1, torque_limit=0.3)},
}  # fmt: skip


def _bytes(x) -> str:
    return hashlib.sha256(np.ascontiguousarray(x).tobytes()).hexdigest()[:16]


def digest(result) -> str:
    parts = [result.report()]
    for row in result.rows:
        parts.append(repr({k: v for k, v in row.items() if not k.startswith("_")}))
        system = row["_design"].system
        parts.append("".join(_bytes(np.asarray(getattr(system, m))) for m in "FGHE"))
    parts += [repr(result.verification), repr(result.notes), repr(result.settings)]
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()


def main(names=None) -> None:
    for name in names or CASES:
        calls: list = []
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            try:
                out = digest(tune(**CASES[name], progress=lambda *a, c=calls: c.append(a)))
            except ValueError as err:
                out = f"raised {type(err).__name__}: {err}"
        steps = hashlib.sha256(repr(calls).encode()).hexdigest()[:12]
        kinds = sorted({f"{w.category.__name__}: {str(w.message)[:60]}" for w in seen})
        print(name, out, "progress", len(calls), steps, "warnings", len(seen), kinds,
              flush=True)  # fmt: skip


if __name__ == "__main__":
    main(sys.argv[1:])
