r"""Noise gains: RMS of the estimate and of the command per unit white measurement noise.

For an asymptotically stable discrete system :math:`s_{k+1} = A s_k + B n_k`,
:math:`y_k = C s_k + D n_k` driven by white noise of unit variance, the stationary state
covariance solves the discrete Lyapunov equation :math:`X = A X A^T + B B^T` and the output
variance is :math:`C X C^T + D D^T` (exactly; no simulation).

The equation is solved in the real Schur basis of ``A`` (an orthogonal change of
coordinates): the observer's ``m + 1`` poles at one place form a near-defective cluster, and
the Kronecker solve of :func:`scipy.linalg.solve_discrete_lyapunov` is accurate on the
(quasi-)triangular Schur form where, on the companion form, it loses up to 3 digits for
``m = 3`` and bandwidths below ~10 rad/s (measured against frequency-domain quadrature in
``tests/analysis/test_noise.py``). scipy's condition warning refers to the Kronecker matrix's
norm-wise condition number, which is pessimistic for this triangular system: the solve
(:func:`discrete_lyapunov`, scipy's numbers bit for bit) does not estimate it, so nothing
needs silencing (a thread-safe matter: ``tune()`` analyses while its runs compile).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .._validation import ParameterValueError, check_choice
from ..observers import as_system
from ..simulation import ServoLoop, accepts_loop
from ._estimation import observer_matrices
from ._linear_loop import INPUTS, OUTPUTS, loop_matrices, loop_spec

__all__ = ["NoiseGains", "noise_gains", "observer_noise_gain"]

#: Noise channels: measurement noise on position [rad] or on velocity [rad/s].
CHANNELS = ("position", "velocity")
#: Noise channels of :func:`observer_noise_gain`: also angle noise reaching a differenced
#: velocity (``"encoder"``).
OBSERVER_CHANNELS = ("velocity", "position", "encoder")


#: Below this size :func:`scipy.linalg.solve_discrete_lyapunov` solves the Kronecker system
#: directly (its ``method=None``); from it on, by its bilinear method.
DIRECT_LYAPUNOV = 10


def discrete_lyapunov(a: np.ndarray, q: np.ndarray) -> np.ndarray:
    """:func:`scipy.linalg.solve_discrete_lyapunov` ``(a, q)``, bit for bit, without its
    condition warning.

    Below :data:`DIRECT_LYAPUNOV` states it solves ``(I - kron(a, a)) vec(X) = vec(q)`` by
    LAPACK's ``getrf``/``getrs``, the routines ``scipy.linalg.solve`` runs for it, without the
    condition estimate that warns (:class:`scipy.linalg.LinAlgWarning`): that estimate is the
    Kronecker matrix's, pessimistic on a Schur form (module docstring), and silencing it with
    :func:`warnings.catch_warnings` is not thread-safe: ``tune()`` analyses while its runs
    compile in another thread, whose own ``catch_warnings`` (numba's) could drop or keep the
    filter for the whole process. From :data:`DIRECT_LYAPUNOV` on, scipy's bilinear method
    (which does not warn) as it is.

    Raises
    ------
    numpy.linalg.LinAlgError
        If the Kronecker matrix is exactly singular (as ``scipy.linalg.solve``).
    """
    from scipy.linalg import LinAlgError, get_lapack_funcs, solve_discrete_lyapunov

    a, q = np.asarray(a, dtype=float), np.asarray(q, dtype=float)
    if a.shape[0] >= DIRECT_LYAPUNOV:
        return solve_discrete_lyapunov(a, q)
    lhs = np.eye(a.shape[0] ** 2) - np.kron(a, a.conj())
    if not (np.all(np.isfinite(lhs)) and np.all(np.isfinite(q))):
        raise ValueError("array must not contain infs or NaNs")
    getrf, getrs = get_lapack_funcs(("getrf", "getrs"), (lhs,))
    lu, pivots, info = getrf(lhs)
    if info > 0:
        raise LinAlgError("A singular matrix detected.")
    x, info = getrs(lu, pivots, q.flatten())
    return np.reshape(x, q.shape)


def h2_gains(A, B, C, D) -> np.ndarray:
    """RMS of each output per unit-variance white noise on the (single) input column of ``B``.

    ``A`` must be asymptotically stable (checked by the callers).
    """
    from scipy.linalg import matrix_balance, schur

    # Diagonal balancing first: a state in physical units (the ESO's [theta, omega, f, f', ...]
    # spans ~1e11) makes C X C^T a difference of huge terms that cancel to garbage or a
    # negative variance. The scaling is by powers of 2, an exact similarity.
    _, (scale, _) = matrix_balance(A, permute=False, separate=True)
    A = A * scale[None, :] / scale[:, None]
    B = B / scale[:, None]
    C = C * scale[None, :]
    T, U = schur(A, output="real")
    Bs = U.T @ B
    X = discrete_lyapunov(T, Bs @ Bs.T)
    Cs = C @ U
    variance = np.einsum("ij,jk,ik->i", Cs, X, Cs) + np.einsum("ij,ij->i", D, D)
    # A variance below zero is a failed solve, not a noiseless output: never report it as 0.
    scale_of_terms = np.einsum("ij,ik->i", np.abs(Cs), np.abs(Cs)) * np.abs(X).max()
    if np.any(variance < -1e-8 * scale_of_terms):
        raise ArithmeticError(
            f"the Lyapunov solve of the noise gain lost its accuracy (variance {variance!r})"
        )
    return np.sqrt(np.maximum(variance, 0.0))


@dataclass(frozen=True)
class NoiseGains:
    r"""Noise gains of a closed loop (see :func:`noise_gains`).

    Each value is the RMS of a signal per unit RMS of a white measurement noise, in the
    stationary state.

    Attributes
    ----------
    tau_hat_position : float
        RMS of :math:`\hat\tau` [N m] per rad of position noise.
    tau_hat_velocity : float
        RMS of :math:`\hat\tau` [N m] per rad/s of velocity noise.
    u_position : float
        RMS of ``u`` [N m] per rad of position noise.
    u_velocity : float
        RMS of ``u`` [N m] per rad/s of velocity noise.
    theta_position : float
        RMS of the true position [rad] per rad of position noise.
    theta_velocity : float
        RMS of the true position [rad] per rad/s of velocity noise.
    """

    tau_hat_position: float
    tau_hat_velocity: float
    u_position: float
    u_velocity: float
    theta_position: float
    theta_velocity: float

    def to_dict(self) -> dict:
        """The gains as a plain ``dict`` (e.g. for JSON).

        Returns
        -------
        dict
            ``{field name: value}`` of every gain (floats, in the units of the attributes).
        """
        return asdict(self)


@accepts_loop
def noise_gains(loop: ServoLoop) -> NoiseGains:
    r"""Exact noise gains of the linear closed loop, from the discrete Lyapunov equation.

    For white measurement noise of standard deviation :math:`\sigma` on the position (the
    input ``n_theta`` of :func:`hpdob.closed_loop`) the stationary RMS of the estimate is
    ``tau_hat_position * sigma``, and so on; noise on position and on velocity add in
    quadrature when they are independent.

    Parameters
    ----------
    loop : ServoLoop
        The loop (see :class:`~hpdob.ServoLoop`), or its parts as keyword arguments
        (the loop functions' one alias rule, :data:`hpdob.simulation.LOOP_KEYS`).
        With ``Encoder(velocity="backward-difference")`` the
        position noise also reaches the differenced velocity.

    Returns
    -------
    NoiseGains

    Raises
    ------
    TypeError, ValueError
        As for :func:`hpdob.closed_loop`; ValueError if the closed loop is not asymptotically
        stable (the stationary variance is then infinite).

    Notes
    -----
    On the nominal plant the estimate's noise gains do not depend on the controller: the
    observer reconstructs the command's effect exactly, so :math:`\hat\tau` responds to the
    noise only through its own measurement input (:func:`observer_noise_gain`).

    References
    ----------
    ``docs/analysis.md``, section 4 (method, accuracy, Monte-Carlo confirmation).

    Examples
    --------
    >>> from hpdob import PD, ServoModel, design_observer, noise_gains, observer_noise_gain
    >>> nominal = ServoModel(2.8e-4)
    >>> obs = design_observer(nominal.discretize(1e-3), order=1, bandwidth=100.0)
    >>> g = noise_gains(plant=ServoModel(3.06e-4, 5e-5), nominal=nominal, Ts=1e-3,
    ...                 controller=PD(50, 5), observer=obs)
    >>> sorted(g.to_dict())  # doctest: +NORMALIZE_WHITESPACE
    ['tau_hat_position', 'tau_hat_velocity', 'theta_position', 'theta_velocity',
     'u_position', 'u_velocity']
    >>> g0 = noise_gains(plant=nominal, nominal=nominal, Ts=1e-3, controller=PD(50, 5),
    ...                  observer=obs)       # nominal plant: the observer's own noise gain
    >>> abs(g0.tau_hat_velocity - observer_noise_gain(obs)) < 1e-12 * g0.tau_hat_velocity
    True
    """
    system = _stable_loop(loop)
    values = {channel: _channel_gains(*system, channel) for channel in CHANNELS}
    return NoiseGains(
        tau_hat_position=float(values["position"][0]),
        tau_hat_velocity=float(values["velocity"][0]),
        u_position=float(values["position"][1]),
        u_velocity=float(values["velocity"][1]),
        theta_position=float(values["position"][2]),
        theta_velocity=float(values["velocity"][2]),
    )


def channel_noise_gains(loop: ServoLoop, channel: str) -> np.ndarray:
    """``[tau_hat, u, theta]`` gains of :func:`noise_gains` for one noise channel (internal).

    Each channel has its own Lyapunov solve, so these are :func:`noise_gains`'s figures bit for
    bit at half the cost; ``tune`` needs the position channel only.
    """
    return _channel_gains(*_stable_loop(loop), check_choice(channel, "channel", CHANNELS))


def _stable_loop(loop: ServoLoop):
    """The loop's ``A, B, C, D``; ValueError if it is not asymptotically stable."""
    spec = loop_spec(loop)
    A, B, C, D, _, _ = loop_matrices(spec)
    radius = float(np.abs(np.linalg.eigvals(A)).max())
    if not radius < 1.0:
        raise ParameterValueError(
            f"the closed loop must be asymptotically stable for finite noise gains, got "
            f"spectral radius {radius:.6g} >= 1 (plant {loop.plant!r})"
        )
    return A, B, C, D


def _channel_gains(A, B, C, D, channel: str) -> np.ndarray:
    j = INPUTS.index({"position": "n_theta", "velocity": "n_omega"}[channel])
    rows = [OUTPUTS.index(name) for name in ("tau_hat", "u", "theta")]
    return h2_gains(A, B[:, [j]], C[rows], D[rows][:, [j]])


def observer_noise_gain(observer, *, noise: str = "velocity") -> float:
    r"""RMS of the observer's estimate per unit white measurement noise, observer alone.

    The H2 norm of the observer's transfer function from ``theta`` (``noise="position"``,
    [N m/rad]) or ``omega`` (``noise="velocity"``, [N m/(rad/s)]) to ``tau_hat``. It is the
    estimate's noise gain in any closed loop on the nominal plant (:func:`noise_gains`), and it
    depends on the observer only. ``noise="encoder"`` [N m/rad] is white noise on the angle
    that also reaches the velocity through a backward difference,
    :math:`\omega_{m,k} = (\theta_{m,k} - \theta_{m,k-1})/T_s` (an
    ``Encoder(velocity="backward-difference")``): the one noise source that observers
    measuring the state and position-only observers share, for comparing them. For a
    position-only observer it equals ``"position"``. An encoder's quantisation step ``q``
    acts as white noise of standard deviation :math:`q/\sqrt{12}` while the shaft moves
    (``docs/analysis.md``, section 8).

    Parameters
    ----------
    observer : LinearObserver, design or runtime observer
    noise : {"velocity", "position", "encoder"}, optional
        Which measurement carries the noise. Default ``"velocity"``; a position-only observer
        has the ``"position"`` (= ``"encoder"``) channel only.

    Returns
    -------
    float

    Raises
    ------
    TypeError, ValueError
        For a wrong observer or noise channel.

    Examples
    --------
    >>> from hpdob import ServoModel, design_observer, observer_noise_gain
    >>> model = ServoModel(2.8e-4).discretize(1e-3)
    >>> dob, hpdob = (design_observer(model, order=m, bandwidth=100.0) for m in (0, 1))
    >>> observer_noise_gain(hpdob) > observer_noise_gain(dob)    # at equal bandwidth
    True
    >>> pos = design_observer(model, order=1, bandwidth=100.0, measurement="position")
    >>> encoder = [observer_noise_gain(o, noise="encoder") for o in (hpdob, pos)]
    >>> bool(encoder[1] < encoder[0] / 10)        # same angle noise, far less in the estimate
    True
    """
    system = as_system(observer)
    check_choice(noise, "noise", OBSERVER_CHANNELS)
    p = len(system.measures)
    if noise == "velocity" and p == 1:
        raise ParameterValueError(
            "noise must be 'position' or 'encoder' for an observer that measures the angle only, "
            f"got {noise!r}"
        )
    A, B, C, D = observer_matrices(system)
    radius = float(np.abs(np.linalg.eigvals(A)).max()) if system.error_dynamics is None else 0.0
    if not radius < 1.0:  # the order-m families are stable by construction (exact Schur-Cohn)
        raise ParameterValueError(
            f"the observer must be asymptotically stable for a finite noise gain, got spectral "
            f"radius {radius:.6g} >= 1"
        )
    if noise == "encoder" and p == 2:
        # state [s, n_{k-1}]: theta = n_k, omega = (n_k - n_{k-1}) / Ts
        Ts, n = system.Ts, A.shape[0]
        A = np.block([[A, -B[:, [1]] / Ts], [np.zeros((1, n)), np.zeros((1, 1))]])
        B = np.vstack([B[:, [0]] + B[:, [1]] / Ts, [[1.0]]])
        C = np.hstack([C[:1], -D[:1, [1]] / Ts])
        D = D[:1, [0]] + D[:1, [1]] / Ts
        return float(h2_gains(A, B, C, D)[0])
    j = 0 if noise in ("position", "encoder") else 1
    return float(h2_gains(A, B[:, [j]], C[:1], D[:1, [j]])[0])
