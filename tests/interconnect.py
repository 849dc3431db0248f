"""The linear closed loop assembled independently of hpdob's analysis, by python-control.

The plant is sampled by ``control.c2d`` (zero-order hold) from its continuous state space
``J theta'' = u - b omega``; the observer and the controller enter as the python-control
systems of their published matrices (``F, G, H, E``); ``control.interconnect`` wires them by
name: the plant's ``theta``/``omega`` (plus the measurement noise ``n_theta``/``n_omega``) to
the observer and the controller, the observer's outputs to the controller's inputs of the same
name, the command ``u`` to the plant, the observer and the controller's ``u_bar`` (no torque
limit). Nothing here uses ``hpdob.analysis`` (the checked code: ``loop_matrices``).
"""

from __future__ import annotations

import numpy as np


def _ss(F, G, H, E, Ts, inputs, outputs, name):
    import control

    F, G, H, E = (np.atleast_2d(np.asarray(m, dtype=float)) for m in (F, G, H, E))
    n = 0 if F.size == 0 else F.shape[0]
    F = F.reshape(n, n)
    G = G.reshape(n, len(inputs))
    H = H.reshape(len(outputs), n)
    E = E.reshape(len(outputs), len(inputs))
    return control.ss(F, G, H, E, Ts, inputs=list(inputs), outputs=list(outputs), name=name)


def closed_loop(*, J: float, b: float, Ts: float, controller, observer=None):
    """The closed loop from ``r, r_dot, r_ddot, n_theta, n_omega`` to ``theta, u`` (a
    python-control ``StateSpace``). ``controller`` a :class:`hpdob.controllers.LinearController`,
    ``observer`` a :class:`hpdob.LinearObserver` (or None: ``tau_hat = 0``)."""
    import control

    plant = control.c2d(
        control.ss([[0.0, 1.0], [0.0, -b / J]], [[0.0], [1.0 / J]], np.eye(2), np.zeros((2, 1))),
        Ts,
        method="zoh",
    )
    plant = control.ss(plant.A, plant.B, plant.C, plant.D, Ts, inputs=["u"],
                       outputs=["theta_true", "omega_true"], name="plant")  # fmt: skip
    sensor = control.ss(
        np.zeros((0, 0)), np.zeros((0, 4)), np.zeros((2, 0)),
        [[1.0, 0.0, 1.0, 0.0], [0.0, 1.0, 0.0, 1.0]], Ts,
        inputs=["theta_true", "omega_true", "n_theta", "n_omega"], outputs=["theta", "omega"],
        name="sensor",
    )  # fmt: skip
    systems = [plant, sensor]
    connections = [
        ["sensor.theta_true", "plant.theta_true"],
        ["sensor.omega_true", "plant.omega_true"],
        ["plant.u", "controller.u"],
        ["controller.u_bar", "controller.u"],
    ]
    sources = {"theta": "sensor.theta", "omega": "sensor.omega"}
    if observer is not None:
        G = np.asarray(observer.G)
        systems.append(_ss(observer.F, G, observer.H, observer.E, Ts,
                           [*observer.measures, "u"], observer.outputs, "observer"))  # fmt: skip
        connections += [[f"observer.{m}", sources[m]] for m in observer.measures]
        connections.append(["observer.u", "controller.u"])
        sources.update({name: f"observer.{name}" for name in observer.outputs})
    c = controller
    E = np.hstack([np.asarray(c.E, dtype=float).reshape(1, -1), [[0.0]]])
    systems.append(_ss(c.F, c.G, c.H, E, Ts, [*c.inputs, "u_bar"], ["u"], "controller"))
    references = [name for name in c.inputs if name in ("r", "r_dot", "r_ddot")]
    for name in c.inputs:
        if name in references:
            continue
        if name in sources:
            connections.append([f"controller.{name}", sources[name]])
        elif name != "tau_hat":  # tau_hat without an observer: 0, an input left open
            raise ValueError(f"cannot wire controller input {name!r}")
    inputs = [*references, "n_theta", "n_omega"]
    inplist = [*(f"controller.{name}" for name in references), "sensor.n_theta",
               "sensor.n_omega"]  # fmt: skip
    # every controller input is wired above or raised on; unused *outputs* (an observer's
    # omega_hat a PD does not read) are what check_unused would warn about
    return control.interconnect(
        systems,
        connections=connections,
        inplist=inplist,
        inputs=inputs,
        outlist=["plant.theta_true", "controller.u"],
        outputs=["theta", "u"],
        dt=Ts,
        check_unused=False,
    )


def poles(**loop) -> np.ndarray:
    """Eigenvalues of :func:`closed_loop`."""
    return np.linalg.eigvals(closed_loop(**loop).A)


def radius(**loop) -> float:
    """Spectral radius of :func:`closed_loop`."""
    return float(np.abs(poles(**loop)).max())


def h2(system, input_name: str, output_name: str) -> float:
    """RMS of ``output_name`` per unit white noise on ``input_name``: the Gramian
    ``X = sum_k A^k B B^T (A^k)^T`` by doubling (``X <- X + A X A^T``, ``A <- A^2``: 2^40
    terms; no Lyapunov solver, which the checked code uses)."""
    j = system.input_labels.index(input_name)
    i = system.output_labels.index(output_name)
    A, B, C, D = system.A, system.B[:, [j]], system.C[[i]], system.D[[i]][:, [j]]
    X = B @ B.T
    for _ in range(40):
        X = X + A @ X @ A.T
        A = A @ A
    return float(np.sqrt((C @ X @ C.T + D @ D.T)[0, 0]))
