r"""Sensitivity functions (gang of four) and stability margins of the loop at the plant input.

The loop is cut where the DOb closes it and where inertia, friction and actuator errors enter:
at the plant input. Let :math:`a` be the torque the actuator delivers (the command ``u``,
delayed by the actuator's delay if any); the plant is driven by :math:`a - \tau_{ext}`. For the
loop gain the connection from :math:`a` to the plant is broken: the plant is driven by an
external :math:`a_{in}` instead (PD and observer in place, the observer still reading ``u``;
references, noise and :math:`\tau_{ext}` zero), and :math:`L = -a/a_{in}`. Closing
:math:`a_{in} = a` restores the loop. With the input disturbance :math:`d = -\tau_{ext}`, so
that the plant receives :math:`a + d`:

.. math::

    S = \frac{1}{1 + L} = \frac{a + d}{d},\quad
    T = \frac{L}{1 + L} = 1 - S = -\frac{a}{d} = \frac{a}{\tau_{ext}},\quad
    PS = \frac{\theta}{d},\quad CS = -\frac{u}{n_\theta}.

With a position-only measurement these are the usual gang of four of Åström & Murray (input
disturbance added to the control signal, :math:`T = -a/d`); here the controller also reads the
velocity, so ``CS`` is the response of the command to position noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..simulation import ServoLoop, accepts_loop
from ._linear_loop import INPUTS, loop_matrices, loop_spec

__all__ = ["GangOfFour", "LoopMargins", "gang_of_four", "loop_margins"]

_OUT = {"theta": 0, "omega": 1, "u": 2, "tau_hat": 3, "a": 4}


class GangOfFour(NamedTuple):
    """The four closed-loop transfer functions of :func:`gang_of_four` (SISO ``StateSpace``).

    Attributes
    ----------
    S : control.StateSpace
        Input sensitivity :math:`1/(1+L)` (dimensionless).
    T : control.StateSpace
        Complementary sensitivity :math:`L/(1+L) = 1 - S` (dimensionless).
    PS : control.StateSpace
        Load sensitivity: position per input disturbance [rad/(N m)].
    CS : control.StateSpace
        Noise sensitivity: command per position-measurement noise [N m/rad].
    """

    S: object
    T: object
    PS: object
    CS: object


@accepts_loop
def gang_of_four(loop: ServoLoop) -> GangOfFour:
    r"""Gang of four of the linear loop, cut at the plant input.

    Parameters
    ----------
    loop : ServoLoop
        The loop (see :class:`~hpdob.ServoLoop`), or its parts as keyword arguments
        (the loop functions' one alias rule, :data:`hpdob.simulation.LOOP_KEYS`).

    Returns
    -------
    GangOfFour
        Named tuple of discrete SISO python-control systems (``dt = Ts``):

        - ``S`` input sensitivity :math:`1/(1+L)`: total plant torque per input disturbance
          :math:`d = -\tau_{ext}` (dimensionless);
        - ``T`` complementary sensitivity :math:`L/(1+L) = 1 - S`: torque the actuator
          delivers per external torque, :math:`a/\tau_{ext} = -a/d` (dimensionless; where
          ``T = 1`` the actuator cancels the external torque);
        - ``PS`` load sensitivity: position per input disturbance [rad/(N m)];
        - ``CS`` noise sensitivity: command per position-measurement noise, with the sign of
          :math:`C/(1+PC)` [N m/rad].

    Raises
    ------
    TypeError, ValueError
        As for :func:`hpdob.closed_loop`.

    Notes
    -----
    On the nominal plant a DOb of estimation response ``Q`` (:func:`estimation_transfer`) makes
    the input sensitivity :math:`S = (1 - Q)\,S_{PD}`, with :math:`S_{PD}` that of the PD loop
    alone: the observer removes disturbances where :math:`|1-Q|` is small.

    References
    ----------
    K. J. Åström and R. M. Murray, *Feedback Systems*, chapter "Frequency Domain Design"
    (sensitivity functions, the gang of four);
    ``docs/analysis.md``, section 3.

    Examples
    --------
    >>> from hpdob import PD, ServoModel, design_observer, gang_of_four
    >>> nominal = ServoModel(2.8e-4)
    >>> obs = design_observer(nominal.discretize(1e-3), order=1, bandwidth=100.0)
    >>> g4 = gang_of_four(plant=nominal, nominal=nominal, Ts=1e-3, controller=PD(50, 5),
    ...                   observer=obs)
    >>> abs(complex(g4.S(1.0))) < 1e-9      # S(z=1) = 0: constant load torques are rejected
    True
    """
    import control

    spec = loop_spec(loop)
    A, B, C, D, _, _ = loop_matrices(spec)
    j_tau, j_noise = INPUTS.index("tau_ext"), INPUTS.index("n_theta")
    dt = spec.Ts

    def siso(out, j, sign, offset, name, output):
        i = _OUT[out]
        return control.ss(
            A,
            B[:, [j]],
            sign * C[[i]],
            sign * D[[i]][:, [j]] + offset,
            dt,
            inputs=[name],
            outputs=[output],
        )

    return GangOfFour(
        S=siso("a", j_tau, -1.0, 1.0, "d", "S"),
        T=siso("a", j_tau, 1.0, 0.0, "d", "T"),
        PS=siso("theta", j_tau, -1.0, 0.0, "d", "PS"),
        CS=siso("u", j_noise, -1.0, 0.0, "n_theta", "CS"),
    )


@accepts_loop
def loop_transfer(loop: ServoLoop):
    r"""Loop gain :math:`L = -a/a_{in}` of the loop cut at the plant input.

    The plant is driven by :math:`a_{in}` instead of the torque :math:`a` the actuator delivers
    (the PD and the observer stay in place, the observer still sees the command ``u``); with
    negative unit feedback :math:`a_{in} = a` this closes the loop of :func:`hpdob.closed_loop`.

    Parameters
    ----------
    loop : ServoLoop
        The loop (see :class:`~hpdob.ServoLoop`), or its parts as keyword arguments
        (the loop functions' one alias rule, :data:`hpdob.simulation.LOOP_KEYS`).

    Returns
    -------
    control.StateSpace
        SISO, ``dt = Ts``, input ``a_in`` [N m], output ``L`` (dimensionless).

    Raises
    ------
    TypeError, ValueError
        As for :func:`hpdob.closed_loop`.

    References
    ----------
    Section IV of the paper (DOb inner loop); ``docs/analysis.md``, section 3.

    Examples
    --------
    >>> from hpdob import PD, ServoModel, loop_transfer
    >>> motor = ServoModel(2.8e-4)
    >>> L = loop_transfer(plant=motor, nominal=motor, Ts=1e-3, controller=PD(50, 5))
    >>> L.ninputs, L.noutputs, L.dt
    (1, 1, 0.001)
    """
    import control

    spec = loop_spec(loop)
    return control.ss(*_broken_loop(spec), spec.Ts, inputs=["a_in"], outputs=["L"])


def _broken_loop(spec):
    """``(A, B, C, D)`` of the loop transfer ``L = -a / a_in`` (loop broken at the actuator)."""
    A, B, C, D, inputs, _ = loop_matrices(spec, broken=True)
    j, i = inputs.index("a_in"), _OUT["a"]
    return A, B[:, [j]], -C[[i]], -D[[i]][:, [j]]


@dataclass(frozen=True)
class LoopMargins:
    """Stability margins of the loop cut at the plant input (see :func:`loop_margins`).

    Attributes
    ----------
    gain_margin : float
        Factor > 1 by which the loop gain can grow before the closed loop becomes unstable
        (``inf`` if never).
    gain_margin_lower : float
        Factor < 1 to which the loop gain can shrink before the closed loop becomes unstable
        (0 if never).
    phase_margin : float
        Phase margin [deg], :math:`180° + \\angle L` at the gain crossover where it is smallest in
        magnitude, wrapped to (-180°, 180°] (``inf`` if ``|L|`` never crosses 1). With the
        integrators of the observer in the loop the Nyquist curve winds around -1, so a stable
        loop may show a negative value here; the delay margin is the unambiguous measure.
    crossover_frequency : float
        Gain crossover frequency [Hz] of ``phase_margin`` (NaN if none).
    delay_margin : float
        Smallest extra loop delay [s] that puts a closed-loop pole on the unit circle:
        the minimum over the gain crossovers of the phase lag still available (wrapped to
        [0°, 360°)) divided by the crossover frequency. One more sample of actuator delay keeps
        the loop stable if ``delay_margin > Ts``.
    stability_margin : float
        Smallest distance of the Nyquist curve to -1, ``1 / max|S|``.
    stable : bool
        Whether the closed loop is stable as given. If not, the gain margins are NaN.
    """

    gain_margin: float
    gain_margin_lower: float
    phase_margin: float
    crossover_frequency: float
    delay_margin: float
    stability_margin: float
    stable: bool

    @property
    def inertia_factor_range(self) -> tuple[float, float]:
        """Factors by which the plant's inertia may be multiplied and the loop stay stable.

        With ``b = 0`` the plant's input gain is exactly ``1/J``, so a factor ``c`` on ``J``
        divides the loop gain by ``c``: the range is ``(1/gain_margin, 1/gain_margin_lower)``.
        With friction it is an approximation (the friction pole moves with ``J`` too).
        """
        low = 1.0 / self.gain_margin if self.gain_margin > 0 else math.nan
        high = 1.0 / self.gain_margin_lower if self.gain_margin_lower > 0 else math.inf
        return low, high


#: Frequency grid of the margin search: points per decade and lowest frequency [rad/s].
_GRID_PER_DECADE = 2000
_W_MIN = 1e-3
#: Loop gains |L| outside [1/_L_RANGE, _L_RANGE] are not searched for phase crossovers.
_L_RANGE = 1e6


def _response(A, B, C, D, w, Ts):
    """``C (zI - A)^-1 B + D`` at ``z = exp(j w Ts)`` for a SISO system, vectorised in ``w``."""
    z = np.exp(1j * np.atleast_1d(w) * Ts)
    n = A.shape[0]
    M = z[:, None, None] * np.eye(n) - A
    x = np.linalg.solve(M, np.broadcast_to(B.astype(complex), (z.size, n, 1)))
    return (C @ x)[:, 0, 0] + D[0, 0]


def _roots(f, w, values):
    """Refined roots of ``f`` between consecutive grid points where ``values`` changes sign."""
    from scipy.optimize import brentq

    with np.errstate(invalid="ignore"):
        idx = np.nonzero(np.sign(values[:-1]) * np.sign(values[1:]) < 0)[0]
    return [brentq(f, w[i], w[i + 1], xtol=1e-12 * w[i], rtol=1e-14) for i in idx]


def _closed_radius(A, B, C, D, c: float) -> float:
    """Spectral radius of the loop closed as ``a_in = c a`` (``L`` scaled by ``c``)."""
    gain = c / (1.0 - c * D[0, 0])
    return float(np.abs(np.linalg.eigvals(A + gain * (B @ C))).max())


@accepts_loop
def loop_margins(loop: ServoLoop) -> LoopMargins:
    r"""Gain, phase, delay and stability margins of the loop cut at the plant input.

    The loop gain :math:`L` (see :func:`gang_of_four`) includes the PD and the observer: this
    is the inner loop where the DOb closes and where an inertia error scales the loop gain.

    Parameters
    ----------
    loop : ServoLoop
        The loop (see :class:`~hpdob.ServoLoop`), or its parts as keyword arguments
        (the loop functions' one alias rule, :data:`hpdob.simulation.LOOP_KEYS`).

    Returns
    -------
    LoopMargins

    Raises
    ------
    TypeError, ValueError
        As for :func:`hpdob.closed_loop`.

    Notes
    -----
    A DOb puts ``m + 1`` integrators into the controller, so :math:`L` has ``m + 3`` poles at
    ``z = 1`` with the plant's two; the transfer-function polynomials are then too
    ill-conditioned for root-based margin finders (:func:`control.stability_margins` reports
    spurious crossovers here). The margins are therefore computed from the state-space
    frequency response on a logarithmic grid (2000 points per decade from 1e-3 rad/s to the
    Nyquist frequency), every crossover refined by Brent's method. The gain margins are checked
    against the closed-loop eigenvalues: they bound the interval of loop-gain factors around
    1 for which the closed loop is stable.

    References
    ----------
    ``docs/analysis.md``, section 3 (definitions, and the checks against the closed-loop
    eigenvalues and against a one-sample delay).

    Examples
    --------
    >>> from hpdob import PD, ServoModel, design_observer, loop_margins
    >>> nominal = ServoModel(2.8e-4)
    >>> obs = design_observer(nominal.discretize(1e-3), order=1, bandwidth=100.0)
    >>> lm = loop_margins(plant=nominal, nominal=nominal, Ts=1e-3, controller=PD(50, 5),
    ...                   observer=obs)
    >>> lm.stable, lm.delay_margin > 1e-3      # tolerates one more sample of delay
    (True, True)
    """
    spec = loop_spec(loop)
    Ab, Bb, Cb, Db = _broken_loop(spec)
    dt = spec.Ts
    w_nyq = math.pi / dt
    # Below w Ts ~ 1e-6, z = exp(j w Ts) rounds so close to the loop's poles at z = 1 that
    # zI - A is singular in double precision (a short Ts); |L| is far outside _L_RANGE there.
    w_min = max(_W_MIN, 1e-6 / dt)
    n = int(_GRID_PER_DECADE * math.log10(w_nyq / w_min)) + 1
    w = np.geomspace(w_min, w_nyq, n)
    w[-1] = w_nyq
    L = _response(Ab, Bb, Cb, Db, w, dt)

    def resp(x):
        return complex(_response(Ab, Bb, Cb, Db, x, dt)[0])

    # Gain crossovers |L| = 1.
    crossings = _roots(lambda x: math.log(abs(resp(x))), w, np.log(np.abs(L)))
    phases = [math.degrees(np.angle(-resp(x))) for x in crossings]  # 180 + angle(L)
    if crossings:
        k = int(np.argmin(np.abs(phases)))
        phase_margin, f_c = phases[k], crossings[k] / (2 * math.pi)
        lags = [math.radians(p % 360.0) / x for p, x in zip(phases, crossings, strict=True)]
        delay_margin = min(lags)
    else:
        phase_margin, f_c, delay_margin = math.inf, math.nan, math.inf
    # Phase crossovers: L real and negative; candidate gain factors c = -1/L. Only where
    # 1e-6 < |L| < 1e6: near z = 1 the m + 3 integrators make |L| reach 1e16 and its phase
    # numerical noise, and loop-gain factors beyond 1e6 are of no interest.
    sane = (np.abs(L) < _L_RANGE) & (np.abs(L) > 1.0 / _L_RANGE) & (L.real < 0)
    imag = np.where(sane, L.imag, np.nan)
    pcs = _roots(lambda x: resp(x).imag, w, imag)
    factors = [-1.0 / resp(x).real for x in pcs if resp(x).real < 0]
    if L[-1].real < 0:  # z = -1: L is real there
        factors.append(-1.0 / L[-1].real)
    stable = _closed_radius(Ab, Bb, -Cb, -Db, 1.0) < 1.0  # a_in = a closes the true loop
    upper, lower = math.nan, math.nan
    if stable:
        upper, lower = math.inf, 0.0
        ups = sorted(c for c in factors if c > 1.0)
        downs = sorted((c for c in factors if c < 1.0), reverse=True)
        for a_, b_ in zip(ups, [*ups[1:], 2 * ups[-1]] if ups else [], strict=True):
            if _closed_radius(Ab, Bb, -Cb, -Db, math.sqrt(a_ * b_)) >= 1.0:
                upper = a_
                break
        for a_, b_ in zip(downs, [*downs[1:], downs[-1] / 2] if downs else [], strict=True):
            if _closed_radius(Ab, Bb, -Cb, -Db, math.sqrt(a_ * b_)) >= 1.0:
                lower = a_
                break
    return LoopMargins(
        gain_margin=float(upper),
        gain_margin_lower=float(lower),
        phase_margin=float(phase_margin),
        crossover_frequency=float(f_c),
        delay_margin=float(delay_margin),
        stability_margin=float(np.abs(1.0 + L).min()),
        stable=stable,
    )
