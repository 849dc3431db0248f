r"""The force loop's response in contact: :math:`\tau_{env}/\tau_{ref}`, its poles, zeros and
-3 dB bandwidth.

In contact (:class:`hpdob.models.InContact`, angles from the contact position) the contact
torque is :math:`\tau_{env} = k_e\theta + c_e\omega`, so from the linear closed loop of
:func:`hpdob.closed_loop` with the force reference as its reference ``r``:

.. math:: T(z) = \frac{\tau_{env}}{\tau_{ref}}(z) = k_e\,G_{\theta r}(z) + c_e\,G_{\omega r}(z).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .._validation import ParameterValueError, require_instance
from ..models import InContact, ServoModel, TwoMassServo
from ..simulation import Actuator, ServoLoop
from ._linear_loop import LoopSpec, loop_matrices

__all__ = ["ForceResponse", "force_response"]

#: Frequency points per decade of the search for the -3 dB crossing (refined by Brent).
POINTS_PER_DECADE = 400


@dataclass(frozen=True, eq=False)
class ForceResponse:
    r"""The linear force loop in contact, :math:`T = \tau_{env}/\tau_{ref}`.

    Built by :func:`force_response`.

    Attributes
    ----------
    system : control.StateSpace
        :math:`T(z)`, discrete (``dt = Ts``), input ``tau_ref`` [N m], output ``tau_env``
        [N m]; the whole closed loop's states (not reduced).
    poles : ndarray of complex
        Its minimal realisation's poles, by decreasing magnitude.
    zeros : ndarray of complex
        Its minimal realisation's zeros, by decreasing magnitude.
    dc_gain : float
        :math:`T(1)`: the steady-state contact torque per unit step of :math:`\tau_{ref}`.
    bandwidth : float
        The -3 dB bandwidth [rad/s]: the lowest frequency where :math:`|T(e^{j\omega T_s})|`
        falls below :math:`|T(1)|/\sqrt 2` (``inf`` if it never does below Nyquist).
    peak : float
        :math:`\max_\omega |T(e^{j\omega T_s})| / |T(1)|` on the grid to Nyquist (1: no
        resonance).
    peak_frequency : float
        Where the peak is [rad/s].
    """

    system: object = field(repr=False)
    poles: np.ndarray = field(repr=False)
    zeros: np.ndarray = field(repr=False)
    dc_gain: float
    bandwidth: float
    peak: float
    peak_frequency: float

    @property
    def bandwidth_hz(self) -> float:
        """The -3 dB bandwidth [Hz]."""
        return self.bandwidth / (2.0 * math.pi)


def _contact_plant(plant):
    if isinstance(plant, InContact):
        return plant
    if isinstance(plant, (ServoModel, TwoMassServo)) and plant.environment is not None:
        return InContact(plant)
    raise ParameterValueError(
        "loop.plant must be in contact: an InContact plant, or a ServoModel or TwoMassServo "
        f"with an environment, got {plant!r}"
    )


def force_response(loop: ServoLoop, /) -> ForceResponse:
    r"""The force loop's transfer function in contact, :math:`\tau_{env}/\tau_{ref}`.

    The loop is made linear as for :func:`hpdob.closed_loop`, with its plant held in contact
    (:class:`~hpdob.models.InContact`: plant + spring-damper, exact ZOH) and the actuator's
    torque limit left out (its delay kept; quantisation and Coulomb friction left out too).
    The force reference is the loop's reference ``r``
    (:class:`~hpdob.controllers.ForceControl`).

    Parameters
    ----------
    loop : ServoLoop
        A force loop: its observer has a ``tau_reac`` output
        (:func:`hpdob.observers.reaction_torque_observer`), its plant an environment (or it is
        an :class:`~hpdob.models.InContact`).

    Returns
    -------
    ForceResponse
        The transfer function, its poles and zeros, DC gain, -3 dB bandwidth and peak.

    Raises
    ------
    ParameterTypeError
        If ``loop`` is not a ServoLoop.
    ParameterValueError
        If the plant has no environment, or the loop in contact is not asymptotically stable
        (no bandwidth then).

    References
    ----------
    Issue 21, section 4; ``docs/force-control.md``.

    Examples
    --------
    >>> from hpdob import Environment, ServoLoop, paper
    >>> from hpdob.analysis import force_response
    >>> from hpdob.controllers import ForceControl
    >>> from hpdob.observers import design_observer, reaction_torque_observer
    >>> dob = design_observer(paper.NOMINAL.discretize(1e-3), order=1, bandwidth=100.0)
    >>> loop = ServoLoop(plant=paper.PLANT.replace(environment=Environment(10.0)),
    ...                  nominal=paper.NOMINAL, Ts=1e-3, controller=ForceControl(1000.0, kv=40.0),
    ...                  observer=reaction_torque_observer(dob, viscous=5e-5))
    >>> response = force_response(loop)
    >>> round(response.dc_gain, 6)       # the contact torque settles on tau_ref
    1.0
    """
    import control
    from scipy.optimize import brentq

    require_instance(loop, ServoLoop, "loop")
    plant = _contact_plant(loop.plant)
    wall = plant.plant.environment
    linear = loop.replace(plant=plant, actuator=Actuator(delay_samples=loop.actuator.delay_samples))
    sensor = linear.sensor
    spec = LoopSpec(
        plant=plant.discretize(linear.Ts),
        controller=linear.controller_system,
        system=linear.system,
        backward_difference=sensor is not None and sensor.velocity == "backward-difference",
        delay=linear.actuator.delay_samples,
    )
    A, B, C, D, inputs, outputs = loop_matrices(spec)
    rho = float(np.abs(np.linalg.eigvals(A)).max())
    if rho >= 1.0:
        raise ParameterValueError(
            f"the loop in contact must be asymptotically stable for a force response, got "
            f"spectral radius {rho:.6g} (see hpdob.analysis.contact_stability_map)"
        )
    j_r = inputs.index("r")
    row = wall.stiffness * C[outputs.index("theta")] + wall.damping * C[outputs.index("omega")]
    feed = wall.stiffness * D[outputs.index("theta"), j_r] + wall.damping * D[
        outputs.index("omega"), j_r]  # fmt: skip
    Ts = linear.Ts
    system = control.ss(A, B[:, [j_r]], row[None, :], [[feed]], Ts, inputs=["tau_ref"],
                        outputs=["tau_env"])  # fmt: skip
    poles, zeros = _cancel(np.linalg.eigvals(A), _zeros(A, B[:, j_r], row, feed))

    def magnitude(w):
        z = np.exp(1j * np.atleast_1d(np.asarray(w, dtype=float)) * Ts)
        return np.abs(_evaluate(A, B[:, j_r], row, feed, z))

    dc = float(np.real(_evaluate(A, B[:, j_r], row, feed, np.ones(1))[0]))
    nyquist = math.pi / Ts
    w = np.geomspace(nyquist * 1e-6, nyquist, int(6 * POINTS_PER_DECADE) + 1)
    mag = magnitude(w) / abs(dc)
    below = np.nonzero(mag < 1.0 / math.sqrt(2.0))[0]
    if below.size == 0:
        bandwidth = math.inf
    else:
        k = int(below[0])
        if k == 0:
            raise ParameterValueError(
                "the force response is below -3 dB at the lowest frequency searched "
                f"({w[0]:.3g} rad/s): no bandwidth"
            )

        def f(x):
            return float(magnitude(math.exp(x))[0]) / abs(dc) - 1.0 / math.sqrt(2.0)

        bandwidth = math.exp(brentq(f, math.log(w[k - 1]), math.log(w[k]), xtol=1e-12))
    i_peak = int(np.argmax(mag))
    return ForceResponse(
        system=system,
        poles=poles,
        zeros=zeros,
        dc_gain=dc,
        bandwidth=float(bandwidth),
        peak=float(mag[i_peak]),
        peak_frequency=float(w[i_peak]),
    )


#: A pole and a zero closer than this cancel (modes the force reference does not excite or
#: the contact torque does not see); well above the ~1e-8 split of a double observer pole.
CANCEL_TOLERANCE = 1e-6


def _zeros(A, b, c, d) -> np.ndarray:
    """The transmission zeros of a SISO ``(A, b, c, d)``: the finite generalised eigenvalues
    of the Rosenbrock pencil ``[[A, b], [c, d]] - z [[I, 0], [0, 0]]``."""
    from scipy.linalg import eigvals

    n = A.shape[0]
    M = np.block([[A, b[:, None]], [c[None, :], np.array([[d]])]])
    N = np.zeros((n + 1, n + 1))
    N[:n, :n] = np.eye(n)
    z = eigvals(M, N)
    return z[np.isfinite(z) & (np.abs(z) < 1e12)]


def _cancel(poles, zeros) -> tuple[np.ndarray, np.ndarray]:
    """Poles and zeros of the minimal realisation: cancel each zero against the nearest pole
    within :data:`CANCEL_TOLERANCE`; both sorted by decreasing magnitude."""
    poles, kept = list(poles), []
    for z in zeros:
        distance = [abs(p - z) for p in poles]
        if distance and min(distance) < CANCEL_TOLERANCE:
            poles.pop(int(np.argmin(distance)))
        else:
            kept.append(z)
    poles, zeros = np.asarray(poles), np.asarray(kept, dtype=complex)
    return (poles[np.argsort(-np.abs(poles), kind="stable")],
            zeros[np.argsort(-np.abs(zeros), kind="stable")])  # fmt: skip


def _evaluate(A, b, c, d, z) -> np.ndarray:
    """:math:`c (zI - A)^{-1} b + d` at the points ``z`` (one batched solve)."""
    M = z[:, None, None] * np.eye(A.shape[0]) - A
    x = np.linalg.solve(M, np.broadcast_to(b.astype(complex), (z.size, b.size))[..., None])
    return x[..., 0] @ c + d
