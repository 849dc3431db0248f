r"""Describing functions and the harmonic balance of the force loop in contact.

The contact map (:func:`hpdob.analysis.contact_stability_map`) is linear: it leaves out the
plant's Coulomb friction, the RTOB's Coulomb term, the encoder's quantiser and the torque
limit. Here each of them is replaced by its describing function (DF), the gain of its first
harmonic for a sinusoid of amplitude :math:`A` at its input (Gelb & Vander Velde 1968;
Slotine & Li 1991, ch. 5):

.. math::

    N(A) = \frac{1}{\pi A}\int_0^{2\pi} f(x_0 + A\sin\phi)\,\sin\phi\,d\phi,

and the loop with these gains (quasi-linear: the library's own sampled-data loop,
:func:`hpdob.analysis._linear_loop.loop_matrices`, with the gains put in) is searched for a
pole on the unit circle, :math:`z = e^{j\omega T_s}` (the harmonic balance). Single-valued
nonlinearities have real DFs (no quadrature part):

- Coulomb friction :math:`c\tanh(\omega/v)`: :func:`tanh_friction_df`, an extra viscous
  friction in the continuous plant (its relay limit :math:`4c/(\pi A)`: :func:`relay_df`);
- the encoder's rounding quantiser of step :math:`q` (mid-tread: ``q round(x/q)``, as the
  simulation's encoder), around an equilibrium ``offset`` from a level:
  :func:`quantiser_df`, :math:`N = \frac{2q}{\pi A}\sum_k \sqrt{1 - (t_k/A)^2}` over the
  thresholds :math:`t_k` (relative to the equilibrium) within the amplitude;
- the torque limit :math:`\pm L` around the equilibrium command :math:`u_0`:
  :func:`saturation_df`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .._blas import one_blas_thread
from .._validation import (
    ParameterTypeError,
    ParameterValueError,
    as_int,
    as_real,
    nonnegative,
    numeric_array,
    positive,
    require_instance,
)
from ..models import InContact, ServoModel
from ..observers import LinearObserver
from ..simulation import ServoLoop
from ._linear_loop import LoopSpec, loop_matrices
from ._noise import h2_gains

__all__ = [
    "ContactLimitCycle",
    "contact_limit_cycle",
    "quantiser_df",
    "relay_df",
    "saturation_df",
    "tanh_friction_df",
]

#: Verdicts of :func:`contact_limit_cycle`.
VERDICTS = ("stable", "limit cycle", "unstable")

# Gauss-Legendre nodes on [0, pi/2] for the tanh DF's quarter-period integral
_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(400)
_PHI = (_NODES + 1.0) * (np.pi / 4.0)
_W = _WEIGHTS * (np.pi / 4.0)
# Gauss-Hermite nodes for a mean over Gaussian noise: E[g(n)] = sum w_i g(sqrt(2) sigma x_i)
_HERMITE_X, _HERMITE_W = np.polynomial.hermite.hermgauss(40)
_HERMITE_W = _HERMITE_W / np.sqrt(np.pi)
# Gauss-Legendre on [0, 20] (units of v) for the remainder sign(u) - tanh(u) ~ 2 exp(-2u)
_TAIL_U, _TAIL_W = np.polynomial.legendre.leggauss(200)
_TAIL_U, _TAIL_W = (_TAIL_U + 1.0) * 10.0, _TAIL_W * 10.0
# Gauss-Legendre on [-1, 1], mapped per phase onto the noise's half-lines beyond the dead band
_BAND_X, _BAND_W = np.polynomial.legendre.leggauss(120)
_BAND_T = 8.0  # the Gaussian noise truncated at 8 sigma (its tail beyond: 1e-15)
# per-call constants of the tanh DF, computed once by the same expressions (the same bits)
_SIN = np.sin(_PHI)
_SIN_W = _SIN * _W
_GAP = (1.0 - np.tanh(_TAIL_U)) * _TAIL_W  # sign - tanh on u > 0 (odd), weighted
_SQRT_2PI = np.sqrt(2.0 * np.pi)


#: Beyond this many quantisation steps of amplitude the quantiser's DF is 1: the exact sum
#: would need ~2 * A/q thresholds per amplitude (memory), and its deviation from 1 is of the
#: order (q/A)^(3/2) (the Euler-Maclaurin remainder of the sqrt end points), below 1e-9 here.
QUANTISER_EXACT_STEPS = 2**20

# above this the tanh's argument A/v (and the friction's DF) is saturated: tanh(1e150) is 1
_X_MAX = 1e150


def _amplitude(amplitude) -> np.ndarray:
    what = "positive finite amplitudes (a number or an array of them)"
    a = numeric_array(amplitude, "amplitude", what)  # strings, bools, complex: TypeError
    # subnormal amplitudes refused too: 1/A overflows there (a gain beyond the float range)
    if a.size == 0 or not np.all(np.isfinite(a)) or np.any(a < np.finfo(float).tiny):
        raise ParameterValueError(f"amplitude must be {what}, got {amplitude!r}")
    return a


def _centre(value, name: str, what: str, half_width: float, *, closed: bool) -> float:
    """``value`` as a finite float within ``half_width`` of 0 (``closed``: inclusive, with a
    relative 1e-12 of slack for a centre computed on the boundary)."""
    x0 = as_real(value, name, f"a finite {what}")  # numpy scalars too; str, bool: TypeError
    bound = half_width * (1 + 1e-12) if closed else half_width
    if abs(x0) > bound or (not closed and abs(x0) == bound):
        sign = "<=" if closed else "<"
        raise ParameterValueError(
            f"{name} must be a finite {what} (|{name}| {sign} {half_width!r}), got {value!r}"
        )
    return x0


def _out(value: np.ndarray, amplitude):
    return float(value) if np.ndim(amplitude) == 0 else value


_TINY = float(np.finfo(float).tiny)


def _one(core, amplitude: float, *arguments) -> float:
    """``core`` (a DF's computation after its checks) at one amplitude, a float: what the
    public function gives for it, without checking the other, already checked, arguments
    at each of the harmonic balance's thousands of calls. An amplitude the public
    functions refuse is refused the same way."""
    if not _TINY <= amplitude < math.inf:  # NaN too
        _amplitude(amplitude)
    return float(core(np.array(amplitude, dtype=float), *arguments))


def relay_df(amplitude, *, level: float):
    r"""The ideal relay's describing function, :math:`N(A) = 4h/(\pi A)`.

    Parameters
    ----------
    amplitude : float or array_like
        Input amplitude :math:`A` [input units], positive.
    level : float
        Relay output level :math:`h` (e.g. the Coulomb torque [N m]), non-negative.

    Returns
    -------
    float or ndarray
        :math:`N(A)` [output units / input units].

    Raises
    ------
    ParameterTypeError
        For an argument that is not a real number (amplitudes: a number or an array
        of them; strings, booleans and complex numbers are refused).
    ParameterValueError
        For a non-positive amplitude or a negative level.

    Examples
    --------
    >>> from hpdob.analysis import relay_df
    >>> round(relay_df(0.1, level=0.01), 6)   # 4 * 0.01 / (pi * 0.1) [N m s/rad]
    0.127324
    """
    h = nonnegative(level, "level", "a non-negative relay level")
    a = _amplitude(amplitude)
    return _out(4.0 * h / (np.pi * a), amplitude)


def tanh_friction_df(
    amplitude, *, coulomb: float, velocity: float, sigma: float = 0.0, deadband: float = 0.0
):
    r"""Describing function of the smooth Coulomb friction :math:`c\tanh(\omega/v)`.

    .. math:: N(A) = \frac{4c}{\pi A}\int_0^{\pi/2}\tanh\left(\frac{A\sin\phi}{v}\right)
              \sin\phi\,d\phi

    (400-point Gauss-Legendre): :math:`c/v` (the slope) for :math:`A \ll v`, the relay's
    :math:`4c/(\pi A)` for :math:`A \gg v`. As an equivalent viscous friction [N m s/rad].
    With ``sigma > 0`` the input also carries zero-mean Gaussian noise of that standard
    deviation, and :math:`\tanh` is replaced by its mean over the noise (40-point
    Gauss-Hermite): the sinusoid's gain of the dual-input (sinusoid + Gaussian) describing
    function (Gelb & Vander Velde 1968, ch. 6). Noise lowers it: for :math:`A \to 0` it
    tends to the mean slope :math:`E[c/v\,\mathrm{sech}^2(n/v)]`, about
    :math:`c\sqrt{2/\pi}/\sigma` for :math:`\sigma \gg v`.

    With ``deadband`` :math:`d > 0` the nonlinearity is the RTOB's dead-banded term
    :math:`c\tanh(\operatorname{dz}_d(\omega)/v)` (:func:`hpdob.observers.coulomb_torque`):
    :math:`\tanh` is replaced by :math:`\tanh(\operatorname{dz}_d(\cdot)/v)`, 0 for
    :math:`|\omega| \le d` (so :math:`N = 0` for :math:`A \le d` without noise); with noise
    its mean is the sum of two integrals over the noise's half-lines beyond :math:`\pm d`,
    where it is smooth (120-point Gauss-Legendre each, the noise truncated at
    :math:`8\sigma`).

    Parameters
    ----------
    amplitude : float or array_like
        Velocity amplitude :math:`A` [rad/s], positive.
    coulomb : float
        :math:`c` [N m], non-negative.
    velocity : float
        :math:`v` [rad/s], positive.
    sigma : float, optional
        Standard deviation [rad/s] of Gaussian noise added to the sinusoid, non-negative.
        Default 0.
    deadband : float, optional
        :math:`d` [rad/s], the dead band on the input, non-negative. Default 0 (none: the
        computation above, unchanged).

    Returns
    -------
    float or ndarray
        :math:`N(A)` [N m s/rad].

    Raises
    ------
    ParameterTypeError
        For an argument that is not a real number (amplitudes: a number or an array
        of them; strings, booleans and complex numbers are refused).
    ParameterValueError
        For a non-positive amplitude or velocity, or a negative Coulomb torque.

    Examples
    --------
    >>> from hpdob.analysis import tanh_friction_df
    >>> round(tanh_friction_df(1e-6, coulomb=0.01, velocity=0.01), 6)   # the slope c/v
    1.0
    """
    c, v, sigma, d = _tanh_arguments(coulomb, velocity, sigma, deadband)
    a = _amplitude(amplitude)
    return _out(_tanh_df(a, c, v, sigma, d), amplitude)


def _tanh_arguments(coulomb, velocity, sigma, deadband) -> tuple[float, float, float, float]:
    c = nonnegative(coulomb, "coulomb", "a non-negative Coulomb torque [N m]")
    v = positive(velocity, "velocity", "a positive velocity scale [rad/s]")
    sigma = nonnegative(sigma, "sigma", "a non-negative noise standard deviation [rad/s]")
    d = nonnegative(deadband, "deadband", "a non-negative dead band [rad/s]")
    return c, v, sigma, d


def _tanh_df(a: np.ndarray, c: float, v: float, sigma: float, d: float) -> np.ndarray:
    """:func:`tanh_friction_df` of validated arguments (``a`` as :func:`_amplitude` gives it):
    the harmonic balance's inner loop calls it directly."""
    with np.errstate(over="ignore"):  # A/v beyond the float range: tanh is 1 long before
        ratio = np.minimum(a / v, _X_MAX)
    x = np.multiply.outer(ratio, _SIN)
    if d > 0.0:
        f = _deadband_mean(x, d / v, sigma / v)
    elif sigma == 0.0:
        f = np.tanh(x)
    elif sigma <= v:  # E[tanh((x + n)/v)], n ~ N(0, sigma^2): smooth on the noise's scale
        shift = np.sqrt(2.0) * sigma / v * _HERMITE_X
        small = ratio < 1e-6  # the nodes' mean of tanh(shift) is 0 only to rounding (~1e-17),
        if np.any(small):  # nonsense over a tiny A: there its linear term (relative error x^2)
            slope = np.cosh(shift) ** -2.0 @ _HERMITE_W
        if np.all(small):  # every row's linear term: the tanh sum would be replaced whole
            f = x * slope
        else:
            f = np.tanh(x[..., None] + shift) @ _HERMITE_W
            if np.any(small):
                f[small] = x[small] * slope
    else:  # a step on the noise's scale: E[sign] = erf exactly, minus the smooth remainder
        from scipy.special import erf

        s = sigma / v  # in units of v: E[sign(x + n)] - E[sign(u) - tanh(u)] over u = x + n
        xu = x[..., None]
        top = np.max(x)
        if np.array_equal(_TAIL_U - top, _TAIL_U + top):
            # u - x and u + x round to one number (u itself) at the largest x >= 0, so at
            # every x (rounding is monotone): the tiny amplitudes the scan visits, where the
            # two exps are one number and their difference 0
            pdf = np.zeros(x.shape + _TAIL_U.shape)
        else:  # one expression: numpy reuses its temporaries (named ones: twice the time)
            pdf = (np.exp(-0.5 * ((_TAIL_U - xu) / s) ** 2)
                   - np.exp(-0.5 * ((_TAIL_U + xu) / s) ** 2))  # fmt: skip
        f = erf(x / (np.sqrt(2.0) * s)) - (pdf @ _GAP) / (s * np.sqrt(2 * np.pi))
    return 4.0 * c / (np.pi * a) * (f @ _SIN_W)


def _deadband_mean(x: np.ndarray, d: float, s: float) -> np.ndarray:
    """E[tanh(dz_d(x + n))] with n ~ N(0, s^2), all in units of v (s = 0: no noise): beyond
    +d the integrand is tanh(u - d), below -d tanh(u + d), between 0; each half-line's part
    is a Gauss-Legendre integral over the standard normal's t (u = x + s t), truncated at
    +-8, on which the integrand is smooth."""
    if s == 0.0:
        return np.sign(x) * np.tanh(np.maximum(np.abs(x) - d, 0.0))
    upper = np.clip((d - x) / s, -_BAND_T, _BAND_T)  # u > d from t > upper
    lower = np.clip((-d - x) / s, -_BAND_T, _BAND_T)  # u < -d from t < lower
    total = np.zeros_like(x)
    for lo, hi, shift in ((upper, np.full_like(x, _BAND_T), -d),
                          (np.full_like(x, -_BAND_T), lower, d)):  # fmt: skip
        half = 0.5 * (hi - lo)
        # a half-line beyond the truncation (half = 0) adds 0 times its (finite) integral:
        # nothing, so its integrand is left at 0 (the product's shape, and so each row's
        # sum in the matrix product, unchanged)
        keep = half != 0.0
        if np.all(keep):
            part = _band_integrand(x, lo, half, s, shift)
        elif np.any(keep):
            part = np.zeros(x.shape + _BAND_X.shape)
            part[keep] = _band_integrand(x[keep], lo[keep], half[keep], s, shift)
        else:
            continue
        total += half * (part @ _BAND_W)
    return total


def _band_integrand(x, lo, half, s: float, shift: float) -> np.ndarray:
    """``tanh(x + s t + shift)`` times the standard normal's density at the Gauss-Legendre
    nodes ``t`` of ``[lo, lo + 2 half]``: the operations of ``t = (lo + half) + half x_k``,
    ``exp(-0.5 t**2) / sqrt(2 pi)`` and ``tanh(x + s * t + shift) * pdf`` in that order."""
    t = np.multiply(half[..., None], _BAND_X)
    np.add((lo + half)[..., None], t, out=t)
    y = np.multiply(s, t)
    np.add(x[..., None], y, out=y)
    # a sinusoid far inside the band (the tiny amplitudes the scan visits): if every phase's
    # nodes and arguments round to the same numbers, so does its integrand (the first and
    # last phases compared first: the cheap test that fails at any other amplitude)
    if (x.ndim == 1 and np.array_equal(t[-1], t[0]) and np.array_equal(y[-1], y[0])
            and np.all(t == t[0]) and np.all(y == y[0])):  # fmt: skip
        out = np.empty_like(t)
        out[:] = _band_product(t[0], y[0], shift)
        return out
    return _band_product(t, y, shift)


def _band_product(t: np.ndarray, y: np.ndarray, shift: float) -> np.ndarray:
    """``tanh(y + shift) * exp(-0.5 t**2) / sqrt(2 pi)``, in the buffers of ``t`` and ``y``."""
    np.square(t, out=t)
    np.multiply(-0.5, t, out=t)
    np.exp(t, out=t)
    np.divide(t, _SQRT_2PI, out=t)
    np.add(y, shift, out=y)
    np.tanh(y, out=y)
    return np.multiply(y, t, out=y)


def quantiser_df(amplitude, *, step: float, offset: float = 0.0):
    r"""Describing function of the rounding quantiser ``step * round(x / step)``.

    For :math:`x = x_0 + A\sin\phi`, with the thresholds :math:`(k + 1/2) q` at
    :math:`t_k = (k + 1/2) q - x_0` from the centre :math:`x_0`:

    .. math:: N(A) = \frac{2q}{\pi A}\sum_{|t_k| < A}\sqrt{1 - (t_k/A)^2},

    at ``offset = 0`` (centred on a level, the mid-tread case) the textbook
    :math:`\frac{4q}{\pi A}\sum_{i \ge 1}\sqrt{1 - ((2i-1)q/(2A))^2}`: zero below
    :math:`A = q/2`, tending to 1 for :math:`A \gg q`. Beyond
    :data:`QUANTISER_EXACT_STEPS` (:math:`2^{20}`) steps of amplitude it is 1 (the sum's
    deviation from 1 is of the order :math:`(q/A)^{3/2}`, below 1e-9 there).

    Parameters
    ----------
    amplitude : float or array_like
        Input amplitude :math:`A` [rad], positive.
    step : float
        Quantisation step :math:`q` [rad] (``2 pi / counts_per_rev``), positive.
    offset : float, optional
        The centre :math:`x_0` from the nearest level [rad], in ``[-q/2, q/2]``. Default 0.

    Returns
    -------
    float or ndarray
        :math:`N(A)` [-].

    Raises
    ------
    ParameterTypeError
        For an argument that is not a real number (amplitudes: a number or an array
        of them; strings, booleans and complex numbers are refused).
    ParameterValueError
        For a non-positive amplitude or step, or an offset beyond half a step.

    Examples
    --------
    >>> from hpdob.analysis import quantiser_df
    >>> quantiser_df(0.4, step=1.0)                   # below half a step: no output
    0.0
    >>> round(quantiser_df(0.4, step=1.0, offset=0.5), 4)   # on a threshold: 2q/(pi A)
    1.5915
    """
    q, x0 = _quantiser_arguments(step, offset)
    a = _amplitude(amplitude)
    return _out(_quantiser_df(a, q, x0), amplitude)


def _quantiser_arguments(step, offset) -> tuple[float, float]:
    q = positive(step, "step", "a positive quantisation step [rad]")
    x0 = _centre(offset, "offset", "centre within half a step of a level [rad]", 0.5 * q,
                 closed=True)  # fmt: skip
    return q, x0


def _quantiser_df(a: np.ndarray, q: float, x0: float) -> np.ndarray:
    """:func:`quantiser_df` of validated arguments."""
    with np.errstate(over="ignore"):
        large = a / q > QUANTISER_EXACT_STEPS  # N = 1 - O((q/A)^1.5): 1 to < 1e-9
    if np.all(large):
        return np.ones_like(a)
    exact = np.where(large, q, a)  # the exact sum's thresholds: those of the smaller amplitudes
    k_max = int(np.ceil(np.max(exact) / q)) + 1
    t = (np.arange(-k_max, k_max) + 0.5) * q - x0  # thresholds relative to the centre
    with np.errstate(over="ignore"):  # a tiny A: (t/A)^2 = inf is a threshold beyond it
        r = np.clip(1.0 - np.square(np.divide.outer(t, exact)), 0.0, None)
    n = 2.0 * q / (np.pi * exact) * np.sqrt(r).sum(axis=0)
    if np.any(large):
        n = np.where(large, 1.0, n)
    return n


def _g(r: np.ndarray) -> np.ndarray:
    inside = np.clip(r, 0.0, 1.0)
    return np.where(r >= 1.0, np.pi / 2, np.arcsin(inside) + inside * np.sqrt(1 - inside**2))


def saturation_df(amplitude, *, limit: float, bias: float = 0.0):
    r"""Describing function of the saturation :math:`\mathrm{clip}(x, -L, L)` around a bias.

    For :math:`x = x_0 + A\sin\phi` with :math:`|x_0| < L`, :math:`\delta_1 = L - x_0`,
    :math:`\delta_2 = L + x_0`:

    .. math:: N(A) = \frac{1}{\pi}\left[g(\delta_1/A) + g(\delta_2/A)\right],\quad
              g(r) = \arcsin r + r\sqrt{1 - r^2}\ (r < 1),\ \pi/2\ (r \ge 1),

    at ``bias = 0`` the textbook :math:`\frac{2}{\pi}(\arcsin\frac{L}{A} + \frac{L}{A}
    \sqrt{1 - L^2/A^2})` (1 for :math:`A \le L`).

    Parameters
    ----------
    amplitude : float or array_like
        Input amplitude :math:`A` [N m], positive.
    limit : float
        :math:`L` [N m], positive.
    bias : float, optional
        The centre :math:`x_0` [N m] (the equilibrium command), :math:`|x_0| < L`. Default 0.

    Returns
    -------
    float or ndarray
        :math:`N(A)` [-], in (0, 1].

    Raises
    ------
    ParameterTypeError
        For an argument that is not a real number (amplitudes: a number or an array
        of them; strings, booleans and complex numbers are refused).
    ParameterValueError
        For a non-positive amplitude or limit, or a bias not inside the limits.

    Examples
    --------
    >>> from hpdob.analysis import saturation_df
    >>> saturation_df(0.3, limit=0.444)
    1.0
    >>> round(saturation_df(2.0, limit=1.0), 4)   # (2/pi)(pi/6 + sqrt(3)/4)
    0.609
    """
    L, x0 = _saturation_arguments(limit, bias)
    a = _amplitude(amplitude)
    return _out(_saturation_df(a, L, x0), amplitude)


def _saturation_arguments(limit, bias) -> tuple[float, float]:
    L = positive(limit, "limit", "a positive torque limit [N m]")
    return L, _centre(bias, "bias", "centre inside the limits [N m]", L, closed=False)


def _saturation_df(a: np.ndarray, L: float, x0: float) -> np.ndarray:
    """:func:`saturation_df` of validated arguments."""
    with np.errstate(over="ignore"):  # a tiny A: delta/A = inf, g = pi/2 (no clipping)
        return (_g((L - x0) / a) + _g((L + x0) / a)) / np.pi


def _candidates(A: np.ndarray, min_angle: float, count: int):
    """``(spectral radius, [(eigenvalue, eigenvector), ...])``: the ``count`` largest
    oscillatory eigenvalues of ``A`` (angle above ``min_angle`` [rad/sample], one of each
    conjugate pair), largest first."""
    w, v = np.linalg.eig(A)
    osc = np.flatnonzero((np.angle(w) > min_angle) | (np.angle(w) >= np.pi - 1e-12))
    order = osc[np.argsort(-np.abs(w[osc]))][:count]
    return float(np.abs(w).max()), [(w[i], v[:, i]) for i in order]


def harmonic_balance(build, gains, amplitudes, *, reference: str, min_angle=1e-3, modes=3,
                     iterations=30, tolerance=1e-4):  # fmt: skip
    """The quasi-linear loop's oscillations at each amplitude of ``reference`` (internal).

    ``build(gains) -> (A, rows)``: the loop's state matrix with the DF gains put in and the
    output rows (name -> row over the state) whose amplitudes the gains read. ``gains`` maps
    a row's name to its DF ``N(amplitude, amplitudes, angle)``: the row's amplitude, every
    row's, and the oscillation's angle per sample [rad]. An oscillation in one mode at
    amplitude ``X`` of ``reference`` gives the other rows the amplitudes of that mode's
    eigenvector; they set the gains, which move the mode. Per mode a fixed point, iterated
    (geometric mean of old and new amplitudes, to damp it), following the eigenvalue
    nearest the last one. The ``modes`` largest oscillatory modes are followed, seeded from
    the previous amplitude's (``amplitudes`` in the order given). Returns ``(modulus, omega
    [rad/sample], converged)``: the largest self-consistent modulus at each amplitude, its
    angle, and whether its fixed point was reached; where no oscillatory mode remains, the
    spectral radius if it exceeds 1 (a real mode that grows) and 0 otherwise.
    """
    n = len(amplitudes)
    modulus, angle = np.full(n, np.nan), np.full(n, np.nan)
    converged = np.zeros(n, dtype=bool)

    def gains_at(amp, theta):
        if amp is None:
            return dict.fromkeys(gains, 1.0)
        amp = {k: max(a, 1e-200) for k, a in amp.items()}
        return {k: f(amp[k], amp, theta) for k, f in gains.items()}

    seeds = [(None, 0.0)]  # amplitude ratios (row / reference) and angle of the modes followed
    for i, level in enumerate(amplitudes):
        found = []  # (modulus, angle, converged, ratios)
        starts, spectral = [], 0.0
        for ratios, theta in seeds:
            amp = None if ratios is None else {k: level * r for k, r in ratios.items()}
            radius, pairs = _candidates(build(gains_at(amp, theta))[0], min_angle, modes)
            starts += [(lam, ratios) for lam, _ in pairs]
            spectral = max(spectral, radius)
        for lam, ratios in starts[: 2 * modes]:
            amp = None if ratios is None else {k: level * ratios[k] for k in gains}
            done = False
            for _ in range(iterations):
                A, rows = build(gains_at(amp, abs(np.angle(lam))))
                w, v = np.linalg.eig(A)
                j = int(np.argmin(np.abs(w - lam)))
                lam, vec = w[j], v[:, j]
                size = {k: float(abs(rows[k] @ vec)) for k in (*gains, reference)}
                if size[reference] == 0.0:
                    break
                new = {k: min(max(level * size[k] / size[reference], 1e-200), 1e100)
                       for k in gains}  # fmt: skip
                done = amp is not None and all(
                    abs(math.log(new[k] / amp[k])) < tolerance for k in gains)  # fmt: skip
                amp = new if amp is None else {
                    k: math.sqrt(amp[k]) * math.sqrt(new[k]) for k in gains}  # fmt: skip
                if done:
                    break
            if amp is not None and abs(np.angle(lam)) > min_angle:
                found.append((abs(lam), abs(np.angle(lam)), done,
                              {k: max(amp[k] / level, 1e-100) for k in gains}))  # fmt: skip
        if not found:  # no oscillatory mode: a real one decides (growth only beyond 1)
            modulus[i], converged[i] = (spectral if spectral > 1.0 + 1e-9 else 0.0), True
            continue
        # the same mode reached from two seeds: keep one (moduli and angles within 1e-6)
        unique = []
        for f in sorted(found, key=lambda f: -f[0]):
            if all(abs(f[0] - u[0]) > 1e-6 or abs(f[1] - u[1]) > 1e-6 for u in unique):
                unique.append(f)
        best = unique[0]  # the largest: the one that decides growth or decay
        modulus[i], angle[i], converged[i] = best[0], best[1], best[2]
        seeds = [(f[3], f[1]) for f in unique[:modes]]
    return modulus, angle, converged


@dataclass(frozen=True, eq=False)
class ContactLimitCycle:
    r"""The describing-function verdict of one force loop in contact.

    Built by :func:`contact_limit_cycle`. The scan: at each amplitude :math:`X` of the
    contact-torque oscillation [N m] the quasi-linear loop (every nonlinearity by its DF at the
    amplitude its input sees) has a largest oscillatory pole of modulus ``radius[i]`` at
    ``frequency[i]``; a harmonic balance (a predicted limit cycle) is where it crosses 1.

    Attributes
    ----------
    verdict : str
        ``"stable"`` (the oscillation started by the step decays to rest: the radius is below
        1 from the start amplitude down to the smallest scanned), ``"limit cycle"`` (it decays
        or grows to a stable harmonic balance below the start amplitude) or ``"unstable"``
        (it grows at the start amplitude, ``tau_ref``: the contact torque would reach 0, the
        contact is lost).
    amplitude : float
        The predicted limit cycle's contact-torque amplitude over ``tau_ref`` [-] (0 for
        ``"stable"``, ``inf`` for ``"unstable"``).
    frequency : float
        Its frequency [Hz] (NaN for ``"stable"``; the growing mode's for ``"unstable"``).
    tau_ref : float
        The force reference [N m]: the equilibrium, and the start amplitude of the scan's top.
    levels : ndarray
        The scanned contact-torque amplitudes [N m], increasing.
    radius : ndarray
        The quasi-linear loop's largest oscillatory pole modulus at each level.
    frequencies : ndarray
        Its frequency [Hz] at each level.
    converged : ndarray of bool
        Whether the amplitude ratios reached their fixed point at each level.
    limit_cycles : tuple of dict
        Every crossing of ``radius = 1``: ``{"amplitude": X / tau_ref, "frequency": Hz,
        "stable": bool}``; stable (Loeb's criterion in its amplitude form) where the radius
        falls through 1 as the amplitude grows.
    nonlinearities : tuple of str
        Which were modelled: ``"friction"``, ``"reaction_friction"``, ``"quantiser"``,
        ``"saturation"``.
    """

    verdict: str
    amplitude: float
    frequency: float
    tau_ref: float
    levels: np.ndarray = field(repr=False)
    radius: np.ndarray = field(repr=False)
    frequencies: np.ndarray = field(repr=False)
    converged: np.ndarray = field(repr=False)
    limit_cycles: tuple = field(repr=False)
    nonlinearities: tuple = ()

    def to_pandas(self):
        """The scan as a DataFrame: ``amplitude_N_m``, ``amplitude_ratio`` (over ``tau_ref``),
        ``radius``, ``frequency_hz``, ``converged``.

        Returns
        -------
        pandas.DataFrame
            One row per scanned amplitude, increasing.

        Examples
        --------
        >>> from hpdob import Environment, ServoLoop, paper
        >>> from hpdob.analysis import contact_limit_cycle
        >>> from hpdob.controllers import ForceControl
        >>> from hpdob.observers import design_observer, reaction_torque_observer
        >>> dob = design_observer(paper.NOMINAL.discretize(1e-3), order=1, bandwidth=100.0)
        >>> loop = ServoLoop(plant=paper.PLANT.replace(environment=Environment(10.0)),
        ...                  nominal=paper.NOMINAL, Ts=1e-3,
        ...                  controller=ForceControl(1000.0, kv=40.0),
        ...                  observer=reaction_torque_observer(dob, friction=paper.PLANT,
        ...                                                    velocity_filter=100.0),
        ...                  sensor=paper.VIRTUAL_SENSOR, actuator=paper.VIRTUAL_ACTUATOR)
        >>> cycle = contact_limit_cycle(loop, tau_ref=0.05, levels=8)
        >>> frame = cycle.to_pandas()
        >>> len(frame), float(frame["amplitude_ratio"].iloc[-1])   # the scan's top: tau_ref
        (8, 1.0)
        """
        import pandas as pd

        return pd.DataFrame(
            {
                "amplitude_N_m": self.levels,
                "amplitude_ratio": self.levels / self.tau_ref,
                "radius": self.radius,
                "frequency_hz": self.frequencies,
                "converged": self.converged,
            }
        )

    def plot(self, ax=None):
        """The scan: radius against the contact-torque amplitude over ``tau_ref``.

        Parameters
        ----------
        ax : matplotlib Axes, optional
            Where to draw; default a new figure.

        Returns
        -------
        matplotlib.figure.Figure
            The radius over the amplitude [%], the line ``|z| = 1``, the balances (``o``
            stable, ``x`` unstable) and a legend right of the axes.

        Examples
        --------
        >>> import matplotlib
        >>> matplotlib.use("Agg")
        >>> import matplotlib.pyplot as plt
        >>> from hpdob import Environment, ServoLoop, paper
        >>> from hpdob.analysis import contact_limit_cycle
        >>> from hpdob.controllers import ForceControl
        >>> from hpdob.observers import design_observer, reaction_torque_observer
        >>> dob = design_observer(paper.NOMINAL.discretize(1e-3), order=1, bandwidth=100.0)
        >>> loop = ServoLoop(plant=paper.PLANT.replace(environment=Environment(10.0)),
        ...                  nominal=paper.NOMINAL, Ts=1e-3,
        ...                  controller=ForceControl(1000.0, kv=40.0),
        ...                  observer=reaction_torque_observer(dob, friction=paper.PLANT,
        ...                                                    velocity_filter=100.0),
        ...                  sensor=paper.VIRTUAL_SENSOR, actuator=paper.VIRTUAL_ACTUATOR)
        >>> cycle = contact_limit_cycle(loop, tau_ref=0.05, levels=8)
        >>> fig = cycle.plot()
        >>> fig.axes[0].get_ylabel()
        'largest oscillatory pole modulus [-]'
        >>> plt.close(fig)
        """
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(figsize=(6.0, 4.0), layout="constrained")
        ax.semilogx(100 * self.levels / self.tau_ref, self.radius, label="quasi-linear loop")
        ax.axhline(1.0, color="k", lw=0.8, label="|z| = 1")
        labels = {True: "stable balance", False: "unstable balance"}  # each labelled once
        for cycle in self.limit_cycles:
            ax.plot(100 * cycle["amplitude"], 1.0, "o" if cycle["stable"] else "x", color="C3",
                    label=labels.pop(cycle["stable"], None))  # fmt: skip
        ax.set_xlabel("contact-torque amplitude X / tau_ref [%]")
        ax.set_ylabel("largest oscillatory pole modulus [-]")
        # right of the axes: the curve and the balances on |z| = 1 stay uncovered
        ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize="small")
        ax.set_title(f"{self.verdict}" + (f": {100 * self.amplitude:.3g} %"
                                          if self.verdict == "limit cycle" else ""))  # fmt: skip
        return ax.figure


def _contact_parts(loop: ServoLoop, tau_ref: float):
    require_instance(loop, ServoLoop, "loop")
    plant = loop.plant
    if isinstance(plant, InContact):  # bonded (loop_at(..., bonded=True)): the same analysis
        plant = plant.plant
    if not isinstance(plant, ServoModel) or plant.environment is None:
        raise ParameterValueError(
            "loop.plant must be a ServoModel with an environment, or InContact of one (the "
            f"describing-function analysis is of the rigid axis pressing its wall), got "
            f"{loop.plant!r}"
        )
    wall = plant.environment
    if wall.damping != 0.0:
        raise ParameterValueError(
            "loop.plant.environment.damping must be 0 for the describing-function analysis "
            f"(the contact torque is k_e theta), got {wall.damping!r}"
        )
    limit = loop.actuator.torque_limit
    if limit is not None and tau_ref >= limit:
        raise ParameterValueError(
            f"tau_ref must be below the torque limit {limit!r} N m (the equilibrium command), "
            f"got {tau_ref!r}"
        )
    return plant, wall, limit


@one_blas_thread  # thousands of eigenvalue problems of size ~12: BLAS threads only cost
def contact_limit_cycle(
    loop: ServoLoop,
    /,
    *,
    tau_ref: float,
    friction: bool = True,
    reaction_friction: bool = True,
    quantiser: bool = True,
    saturation: bool = True,
    levels: int = 48,
    smallest: float = 1e-3,
) -> ContactLimitCycle:
    r"""Describing-function verdict of the force loop in contact: stable, limit cycle, unstable.

    The loop of :func:`hpdob.analysis.contact_stability_map` (plant + spring, exact ZOH, DOb,
    RTOB, controller, delay; ``loop`` is one of its points, ``cmap.loop_at(k_e, g)``) with its
    nonlinearities as describing functions at the amplitudes their inputs see when the contact
    torque oscillates with amplitude :math:`X` about :math:`\tau_{ref}`:

    - the plant's Coulomb friction :math:`c\tanh(\omega/v)` (:func:`tanh_friction_df` of the
      velocity amplitude) as extra viscous friction of the continuous plant;
    - the RTOB's Coulomb term :math:`c_n\tanh(w/v_n)` (its velocity ``w``: the measured or
      low-passed one) as a viscous term subtracted from ``tau_reac``;
    - the encoder's quantiser (:func:`quantiser_df` of the angle amplitude, centred on the
      equilibrium angle :math:`\theta_e + \tau_{ref}/k_e`);
    - the torque limit (:func:`saturation_df` of the command amplitude around the
      equilibrium command :math:`\tau_{ref}`).

    The amplitudes at the nonlinearities follow from :math:`X` by the oscillating mode's
    eigenvector (iterated with the gains to a fixed point). Scanning :math:`X` from
    ``smallest * tau_ref`` to :math:`\tau_{ref}` (where the contact torque would touch 0), the
    largest oscillatory pole modulus :math:`\rho(X)` of the quasi-linear loop says whether an
    oscillation of that amplitude grows (> 1) or decays (< 1); a crossing of 1 is a harmonic
    balance, stable (Loeb's criterion, amplitude form) where :math:`\rho` falls through 1 as
    :math:`X` grows. The step from rest at the wall starts the oscillation at
    :math:`X = \tau_{ref}`: if :math:`\rho(\tau_{ref}) > 1` the verdict is ``"unstable"``
    (contact lost); else the oscillation decays to the largest stable balance below
    :math:`\tau_{ref}` (``"limit cycle"``) or, if there is none, to rest (``"stable"``).

    Parameters
    ----------
    loop : ServoLoop
        A rigid ServoModel plant with a (damping-free) environment, its unilateral form (as
        :meth:`ContactStabilityMap.loop_at` gives it) or bonded; the sensor (an
        :class:`~hpdob.Encoder` quantises), the actuator's delay and torque limit, the
        composed observer (its Coulomb term, ``LinearObserver.coulomb``) are read from it.
    tau_ref : float
        The force reference [N m] the loop holds, positive, below the torque limit.
    friction, reaction_friction, quantiser, saturation : bool, optional
        Model the plant's Coulomb friction, the RTOB's Coulomb term, the encoder's quantiser,
        the torque limit. Default True each; False leaves it out (frictionless, the RTOB's
        term as if absent, unquantised, unlimited).
    levels : int, optional
        Amplitudes scanned (log-spaced), at least 8. Default 48.
    smallest : float, optional
        The smallest scanned amplitude over ``tau_ref``, in (0, 1). Default 1e-3.

    Returns
    -------
    ContactLimitCycle
        ``.verdict``, ``.amplitude`` (over ``tau_ref``), ``.frequency`` [Hz], the scan and
        ``.limit_cycles``; ``.to_pandas()`` and ``.plot()``.

    Raises
    ------
    ParameterTypeError, ParameterValueError
        Naming the parameter: a loop that is not a rigid plant with a damping-free
        environment, a non-positive ``tau_ref`` or one at or above the torque limit, a flag
        that is not a bool, a bad ``levels`` or ``smallest``.

    Notes
    -----
    The DFs assume a sinusoid at each input (the loop filters the harmonics) and the
    equilibrium as the sinusoid's centre (the bias of the dual-input DF is not solved for:
    the loop's integral action holds the mean contact torque at :math:`\tau_{ref}`). The
    sampled sinusoid is taken to cover its phases (an oscillation frequency not a rational
    fraction of the sampling rate). The Coulomb-friction DF of the plant reads the sampled
    velocity's amplitude.

    References
    ----------
    A. Gelb, W. E. Vander Velde, *Multiple-Input Describing Functions and Nonlinear System
    Design*, 1968; J.-J. E. Slotine, W. Li, *Applied Nonlinear Control*, 1991, ch. 5; issue
    21 section 5; ``docs/force-control.md``.

    Examples
    --------
    >>> import numpy as np
    >>> from hpdob import Environment, ServoLoop, paper
    >>> from hpdob.analysis import contact_limit_cycle
    >>> from hpdob.controllers import ForceControl
    >>> from hpdob.observers import design_observer, reaction_torque_observer
    >>> dob = design_observer(paper.NOMINAL.discretize(1e-3), order=1, bandwidth=100.0)
    >>> loop = ServoLoop(plant=paper.PLANT.replace(environment=Environment(10.0)),
    ...                  nominal=paper.NOMINAL, Ts=1e-3, controller=ForceControl(1000.0, kv=40.0),
    ...                  observer=reaction_torque_observer(dob, friction=paper.PLANT,
    ...                                                    velocity_filter=100.0),
    ...                  sensor=paper.VIRTUAL_SENSOR, actuator=paper.VIRTUAL_ACTUATOR)
    >>> contact_limit_cycle(loop, tau_ref=0.05).verdict
    'stable'
    """
    tau_ref = positive(tau_ref, "tau_ref", "a positive force reference [N m]")
    plant, wall, limit = _contact_parts(loop, tau_ref)
    levels = as_int(levels, "levels", "an integer number of amplitudes, at least 8", minimum=8)
    smallest = positive(smallest, "smallest", "an amplitude ratio in (0, 1)")
    if smallest >= 1.0:
        raise ParameterValueError(
            f"smallest must be an amplitude ratio in (0, 1), got {smallest!r}"
        )
    flags = {"friction": friction, "reaction_friction": reaction_friction,
             "quantiser": quantiser, "saturation": saturation}  # fmt: skip
    for name, flag in flags.items():  # bool("no") is True: a flag must be a bool
        if not isinstance(flag, (bool, np.bool_)):
            raise ParameterTypeError(
                f"{name} must be True or False, got {flag!r} of type {type(flag).__name__}"
            )
    friction, quantiser, saturation = bool(friction), bool(quantiser), bool(saturation)
    reaction_friction = bool(reaction_friction)
    Ts = loop.Ts
    k_e = wall.stiffness
    system = loop.system
    sensor = loop.sensor
    base = plant.replace(coulomb=0.0)
    controller = loop.controller_system
    backward = sensor is not None and sensor.velocity == "backward-difference"
    coulomb = None if system is None or not reaction_friction else system.coulomb
    signals, gains, used = (), {}, []
    quantised = quantiser and sensor is not None and hasattr(sensor, "counts_per_rev")
    q = 2.0 * np.pi / sensor.counts_per_rev if quantised else 0.0
    # the DFs' cores (each public function's own computation, its checks done once here)
    if friction and plant.coulomb > 0.0:
        c_p, v_p, _, _ = _tanh_arguments(plant.coulomb, plant.coulomb_velocity, 0.0, 0.0)
        gains["omega"] = lambda a, amp, angle: _one(_tanh_df, a, c_p, v_p, 0.0, 0.0)
        used.append("friction")
    if coulomb is not None and coulomb.c > 0.0:
        source = "omega_m" if coulomb.velocity == "omega" else "omega_hat"
        signals = (source,)
        dither = _velocity_dither(system, source, Ts) if quantised and backward else 0.0
        c_r, v_r, _, d_r = _tanh_arguments(coulomb.c, coulomb.v, 0.0, coulomb.deadband)

        def reaction_gain(a, amp, angle):
            # the encoder's count changes as noise on the term's velocity: crossings per
            # sample of a sinusoid of amp["theta"] / q counts, each an impulse q / Ts of the
            # backward difference (white q^2/12 at one and more per sample)
            rate = 2.0 / np.pi * amp["theta"] / q * angle if dither else 0.0
            sigma = dither * q / Ts * math.sqrt(min(rate, 1.0 / 6.0))
            if not 0.0 <= sigma < math.inf:
                _tanh_arguments(c_r, v_r, sigma, d_r)  # refused as tanh_friction_df does
            return _one(_tanh_df, a, c_r, v_r, float(sigma), d_r)

        gains[source] = reaction_gain
        used.append("reaction_friction")
    if quantised:
        centre = wall.position + tau_ref / k_e
        offset = centre - q * round(centre / q)
        step, x0 = _quantiser_arguments(q, offset)
        gains["theta"] = lambda a, amp, angle: _one(_quantiser_df, a, step, x0)
        used.append("quantiser")
    if saturation and limit is not None:
        L, bias = _saturation_arguments(limit, tau_ref)
        gains["u"] = lambda a, amp, angle: _one(_saturation_df, a, L, bias)
        used.append("saturation")
    plants = {}
    delay = loop.actuator.delay_samples

    def build(values):
        # the plant's ZOH with the friction's equivalent viscous term, to 5 digits (each ZOH
        # is an expm: the fixed-point iterations revisit the same few values)
        extra = float(f"{values.get('omega', 0.0):.5g}")
        if extra not in plants:
            plants[extra] = InContact(base.replace(b=base.b + extra)).discretize(Ts)
        observer = system
        if coulomb is not None and coulomb.c > 0.0:
            observer = _with_viscous_reaction(system, coulomb.velocity, values[signals[0]])
        spec = LoopSpec(plant=plants[extra], controller=controller, system=observer,
                        backward_difference=backward, delay=delay)  # fmt: skip
        A, _, C, _, _, names = loop_matrices(spec, measurement_gain=values.get("theta", 1.0),
                                             command_gain=values.get("u", 1.0),
                                             signals=signals)  # fmt: skip
        rows = dict(zip(names, C, strict=True))
        rows["tau_env"] = k_e * rows["theta"]
        return A, rows

    top = tau_ref
    grid = np.geomspace(smallest * top, top, levels)
    # scanned from the top down: the start amplitude's mode seeds the next level's ratios
    rho, angle, converged = harmonic_balance(build, gains, grid[::-1], reference="tau_env")
    rho, angle, converged = rho[::-1], angle[::-1], converged[::-1]
    hz = angle / (2 * np.pi * Ts)
    cycles = []
    for i in range(levels - 1):
        lo, hi = rho[i] - 1.0, rho[i + 1] - 1.0
        if np.isfinite(lo) and np.isfinite(hi) and lo * hi < 0:
            t = lo / (lo - hi)  # linear in log amplitude
            x = float(np.exp((1 - t) * np.log(grid[i]) + t * np.log(grid[i + 1])))
            cycles.append({"amplitude": x / tau_ref,
                           "frequency": float((1 - t) * hz[i] + t * hz[i + 1]),
                           "stable": bool(lo > 0)})  # fmt: skip
    if not rho[-1] < 1.0:
        verdict, amplitude, frequency = "unstable", math.inf, float(hz[-1])
    else:
        below = [c for c in cycles if c["stable"]]
        if below:
            best = max(below, key=lambda c: c["amplitude"])
            verdict, amplitude, frequency = "limit cycle", best["amplitude"], best["frequency"]
        else:
            verdict, amplitude, frequency = "stable", 0.0, math.nan
    for array in (grid, rho, hz, converged):
        array.setflags(write=False)
    return ContactLimitCycle(verdict=verdict, amplitude=amplitude, frequency=frequency,
                             tau_ref=tau_ref, levels=grid, radius=rho, frequencies=hz,
                             converged=converged, limit_cycles=tuple(cycles),
                             nonlinearities=tuple(used))  # fmt: skip


def _velocity_dither(system: LinearObserver, source: str, Ts: float) -> float:
    """The RMS of the Coulomb term's velocity per unit white noise on the measured velocity
    (the observer alone: 1 for the measured velocity, the H2 norm to ``omega_hat`` for its
    own); 0 for an observer that does not read the measured velocity."""
    if source == "omega_m":
        return 1.0
    if "omega" not in system.measures:
        return 0.0
    col = system.measures.index("omega")
    w = system.outputs.index("omega_hat")
    F, G, H, E = (np.asarray(m, dtype=float) for m in (system.F, system.G, system.H, system.E))
    return float(h2_gains(F, G[:, col : col + 1], H[w : w + 1], E[w : w + 1, col : col + 1])[0])


@dataclass(frozen=True, eq=False)
class _LoopObserver:
    """What :func:`~hpdob.analysis._linear_loop.loop_matrices` reads of an observer: the
    matrices of one already checked, with its ``tau_reac`` row changed (internal)."""

    F: np.ndarray
    G: np.ndarray
    H: np.ndarray
    E: np.ndarray
    measures: tuple
    outputs: tuple

    @property
    def n_states(self) -> int:
        return self.F.shape[0]


def _with_viscous_reaction(system: LinearObserver, velocity: str, gain: float):
    """The composed observer with its Coulomb term as the viscous ``gain`` [N m s/rad] on its
    velocity: ``tau_reac`` row minus ``gain`` times the velocity's row (measured or
    ``omega_hat``). For the loop's matrices only: a LinearObserver of these matrices would
    check them again at each of the harmonic balance's thousands of builds."""
    H, E = np.array(system.H), np.array(system.E)
    r = system.outputs.index("tau_reac")
    if velocity == "omega":
        E[r, system.measures.index("omega")] -= gain
    else:
        w = system.outputs.index("omega_hat")
        H[r] -= gain * H[w]
        E[r] -= gain * E[w]
    return _LoopObserver(F=system.F, G=system.G, H=H, E=E, measures=system.measures,
                         outputs=system.outputs)  # fmt: skip
