r"""Fixed-point observers: integer arithmetic for FPU-less microcontrollers.

``docs/deployment.md`` ("Fixed point") derives the formats and bounds used here.

:func:`fixed_point_design` turns any observer (a :class:`~hpdob.LinearObserver`
:math:`s_{k+1} = F s_k + G v_k`, :math:`y_k = H s_k + E v_k`) and the ranges the user declares
into integer tables: Q formats per signal and per state, ``W``-bit coefficients, ``2W``-bit
accumulation, one rounding per row (round half up) and saturation. :class:`FixedPointObserver`
runs those tables in Python exactly as the generated C does (``export_c(..., dtype="q31")``),
and :func:`fixed_point_error_bound` bounds its distance to the exact observer along a trace.

**The angle enters only through count differences.** With
:math:`d = (I - F)^{-1} G_\theta` (the state of the observer at rest at a constant unit angle)
and :math:`q_k = s_k - d\,\theta_{k-1}`, the recurrence becomes

.. math::

    q_{k+1} = F q_k + (G_\theta - d)\,\Delta_k + G_r r_k,\qquad
    y_k = H q_k + E_\theta \Delta_k + E_r r_k,\qquad \Delta_k = \theta_k - \theta_{k-1},

with :math:`r = (\omega, u)` the other inputs, exactly when :math:`H d + E_\theta = 0`: the
zero DC gain from the angle to every output (a constant angle offset changes no estimate).
Every family of hpdob satisfies it to rounding (the residual is part of the error bound);
the encoder counts then pass through a wrap-around difference and multi-turn axes keep
working past the int32 range of counts.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from .._validation import (
    ParameterTypeError,
    ParameterValueError,
    as_int,
    check_choice,
    positive,
)
from ..observers._system import LinearObserver, as_system

__all__ = [
    "WORDS",
    "FixedPointDesign",
    "FixedPointObserver",
    "FixedPointRow",
    "fixed_point_design",
    "fixed_point_error_bound",
]

#: Word formats: name -> word length W [bits] (states, coefficients, signals; accumulators 2W).
WORDS = {"q31": 32, "q15": 16}
#: One bit of headroom on every derived bound (covers the truncated series and float rounding
#: of the bound's own evaluation, which are many orders of magnitude smaller).
_MARGIN = 2.0
#: The series of the l1 norms are summed until ||F^J||_inf falls below this (tail bounded).
_TAIL = 1e-13


@dataclass(frozen=True)
class FixedPointRow:
    """One row of integer arithmetic: ``sat(round(sum_j C_j V_j 2^k_j / 2^shift), limit)``.

    Attributes
    ----------
    target : str
        What the row computes (``"q1"``, ``"tau_hat"``, ...).
    terms : tuple of (int, int, int)
        ``(C_j, j, k_j)``: the term ``C_j V_j 2^k_j`` with ``|C_j| <= 2^(W-1) - 1`` and operand
        ``j`` of the row's operand vector (:attr:`FixedPointDesign.operands` or
        :attr:`FixedPointDesign.reset_operands`).
    shift : int
        Right shift from the accumulator to the target's Q format (``0 <= shift <= 2W - 2``).
    limit : int
        Saturation limit: the result is clamped to ``[-limit, limit]``.
    frac_bits : int
        Fractional bits ``a`` of the accumulator: ``acc * 2^-a`` is the row's value [SI].
    """

    target: str
    terms: tuple
    shift: int
    limit: int
    frac_bits: int


def _check_ranges(counts_per_rev, omega_max, u_max, tau_max):
    cpr = as_int(counts_per_rev, "counts_per_rev", "a positive integer number of encoder "
                 "counts per revolution", minimum=1, maximum=2**53)  # fmt: skip
    omega_max = positive(omega_max, "omega_max", "a positive finite velocity range [rad/s]")
    u_max = positive(u_max, "u_max", "a positive finite torque command range [N m]")
    tau_max = positive(tau_max, "tau_max", "a positive finite estimate range [N m]")
    return cpr, omega_max, u_max, tau_max


def _frac_bits(bound: float, word: int, name: str, value_name: str) -> int:
    """Largest fractional bit count whose range ``(2^(W-1) - 1) 2^-f`` holds ``bound``."""
    top = 2 ** (word - 1) - 1
    f = math.floor(math.log2(top) - math.log2(bound))
    while top * 2.0**-f < bound:  # log2 rounding
        f -= 1
    if f < -(word - 1) or f > 4 * word:
        raise ParameterValueError(
            f"{name} cannot be scaled into a {word}-bit word: {value_name} = {bound!r} needs "
            f"2^{-f} per bit (the formats allow 2^{-4 * word} to 2^{word - 1})"
        )
    return f


def _powers(F: np.ndarray):
    """``F^j`` for ``j = 0 .. J-1`` with ``||F^J||_inf < _TAIL``, and ``||F^J||_inf``."""
    n = F.shape[0]
    out, X = [], np.eye(n)
    for _ in range(200_000):
        out.append(X)
        X = X @ F
        norm = float(np.abs(X).sum(axis=1).max())
        if norm < _TAIL:
            return np.array(out), norm
        if not np.isfinite(norm) or norm > 1e30:
            break
    raise ParameterValueError(
        "observer must be stable in fixed point: the quantised state matrix F has a pole on "
        "or outside the unit circle (the design's coefficients cannot be represented)"
    )


def _l1_gain(powers, tail, B, C=None):
    """Entry-wise ``sum_j |C F^j B|`` (C = I by default), with the tail bound added."""
    terms = np.abs(powers @ B) if C is None else np.abs(C @ powers @ B)
    total = terms.sum(axis=0)
    # sum_{j>=J} |C F^j B| <= (tail / (1 - tail)) * max over entries of the first J terms
    return total + tail / (1.0 - tail) * float(terms.sum(axis=0).max())


def _peak_gain(powers, tail):
    """Entry-wise ``sup_k |F^k|`` (for the free response of the initial state)."""
    return np.abs(powers).max(axis=0) + tail


@dataclass(frozen=True, eq=False)
class FixedPointDesign:
    r"""Integer tables of a fixed-point observer, from :func:`fixed_point_design`.

    Signals are integers: ``count`` (encoder counts, 1 count = ``2 pi / counts_per_rev`` rad),
    ``omega`` = :math:`\omega\,2^{f_\omega}`, ``u`` = :math:`u\,2^{f_u}`, ``tau_hat`` =
    :math:`\hat\tau\,2^{f_\tau}` (and ``omega_hat`` = :math:`\hat\omega\,2^{f_{\hat\omega}}`);
    state ``i`` holds :math:`q_i 2^{f_i}`.

    Attributes
    ----------
    system : LinearObserver
        The observer.
    word : {"q31", "q15"}
        Word format: ``W = 32`` (int32 values, int64 accumulation) or ``W = 16``.
    counts_per_rev : int
        Encoder counts per revolution.
    omega_max, u_max, tau_max : float
        Declared ranges [rad/s, N m, N m]: inputs beyond them are saturated.
    delta_max : int
        Largest count difference per sample, ``floor(omega_max Ts counts_per_rev / 2 pi) + 1``;
        differences beyond it are saturated.
    frac_bits : dict
        Fractional bits of every signal (``"omega"``, ``"u"``, ``"tau_hat"``,
        ``"omega_hat"``) and state (``"q1"``, ...).
    update, output, reset : tuple of FixedPointRow
        The rows: state ``i`` from the operands ``[q_1..q_n, delta, (omega,) u]``, outputs from
        the same operands, reset state ``i`` from ``[omega0, tau0]``.
    state_bound : ndarray
        Proven bound on ``|q_i|`` [SI] for every input sequence (inputs are saturated to the
        ranges), including the initial state and the rounding.
    output_bound : ndarray
        The same for every output before its saturation.
    error_bound : ndarray
        A-priori bound on ``|y_fixed - y_exact|`` for every output [SI] while no output
        saturates (``docs/deployment.md``).
    shift_residual : ndarray
        Bound on ``|H d + E_theta|`` [output per rad]: how much a constant angle offset
        still moves each output of the double design (rounding level).
    update_residual : ndarray
        Bound on ``|(F - I) d + G_theta|`` [state per rad] (rounding level).
    reset_residual : ndarray
        Bound on ``|N_theta - d|`` [state per rad] (rounding level).
    real : dict
        The real matrices of the count-difference frame (``F``, ``G``, ``H``, ``E``, ``N``),
        their quantised values (``Fh``, ...) and the inputs' LSBs (for the error bounds).
    """

    system: LinearObserver
    word: str
    counts_per_rev: int
    omega_max: float
    u_max: float
    tau_max: float
    delta_max: int
    frac_bits: dict
    update: tuple
    output: tuple
    reset: tuple
    state_bound: np.ndarray
    output_bound: np.ndarray
    error_bound: np.ndarray
    shift_residual: np.ndarray
    update_residual: np.ndarray = field(repr=False)
    reset_residual: np.ndarray = field(repr=False)
    real: dict = field(repr=False)

    @property
    def bits(self) -> int:
        """Word length ``W`` [bits]."""
        return WORDS[self.word]

    @property
    def measures_omega(self) -> bool:
        """Whether the observer takes the measured velocity as an input."""
        return len(self.system.measures) == 2

    @property
    def operands(self) -> tuple:
        """Names of the operands of update and output rows."""
        n = self.system.n_states
        return (*(f"q{i + 1}" for i in range(n)), "delta",
                *(("omega",) if self.measures_omega else ()), "u")  # fmt: skip

    @property
    def reset_operands(self) -> tuple:
        """Names of the operands of reset rows."""
        return ("omega0", "tau0")

    @property
    def radians_per_count(self) -> float:
        """One encoder count [rad]."""
        return 2.0 * math.pi / self.counts_per_rev

    def lsb(self, signal: str) -> float:
        """Value of one integer step of ``signal`` [SI].

        Parameters
        ----------
        signal : str
            ``"count"``, ``"omega"``, ``"omega0"``, ``"u"``, ``"tau_hat"``, ``"tau0"``,
            ``"omega_hat"`` or a state ``"q1"``, ...

        Returns
        -------
        float
        """
        if signal in ("count", "delta"):
            return self.radians_per_count
        return 2.0 ** -self.frac_bits["tau_hat" if signal == "tau0" else signal]

    def to_int(self, signal: str, values) -> np.ndarray:
        """``values`` [SI] as the integers of ``signal``: rounded to nearest, saturated.

        Parameters
        ----------
        signal : str
            As for :meth:`lsb`. ``"count"`` converts an angle [rad] to the encoder count,
            wrapped to int32 as a 32-bit counter does; every other signal is clamped to its
            range.
        values : array_like
            Values [SI].

        Returns
        -------
        ndarray of int64
        """
        values = np.asarray(values, dtype=float)
        scaled = np.rint(values / self.lsb(signal))
        if signal == "count":
            return ((scaled.astype(np.int64) + 2**31) % 2**32 - 2**31).astype(np.int64)
        limit = self.limit(signal)
        return np.clip(scaled, -limit, limit).astype(np.int64)

    def to_real(self, signal: str, values) -> np.ndarray:
        """Integers of ``signal`` as values [SI] (exact in binary64).

        Parameters
        ----------
        signal : str
            As for :meth:`lsb`.
        values : array_like of int

        Returns
        -------
        ndarray of float
        """
        return np.asarray(values, dtype=np.int64).astype(float) * self.lsb(signal)

    def limit(self, signal: str) -> int:
        """Saturation limit of an input or output signal.

        Parameters
        ----------
        signal : str
            ``"delta"``, ``"omega"``, ``"omega0"``, ``"u"``, ``"tau_hat"``/``"tau0"``; any
            other name gives the word limit ``2^(W-1) - 1``.

        Returns
        -------
        int
        """
        if signal == "delta":
            return self.delta_max
        if signal == "omega":
            return math.floor(self.omega_max * 2.0 ** self.frac_bits["omega"])
        if signal == "u":
            return math.floor(self.u_max * 2.0 ** self.frac_bits["u"])
        if signal in ("tau_hat", "tau0"):
            return math.floor(self.tau_max * 2.0 ** self.frac_bits["tau_hat"])
        if signal == "omega0":
            return math.floor(self.omega_max * 2.0 ** self.frac_bits["omega0"])
        return 2 ** (self.bits - 1) - 1

    @functools.cached_property
    def python(self):
        """Generated Python functions ``(init, outputs, update)`` on integer tuples."""
        return _compile(self)

    def describe(self) -> list[tuple[str, str]]:
        """The formats and bounds as text (for headers of generated code).

        Returns
        -------
        list of (str, str)
            ``(key, value)`` lines.
        """
        w = self.bits
        q = {k: f"Q{w - 1 - f}.{f}" if f >= 0 else f"2^{-f} per bit" for k, f in
             self.frac_bits.items() if k != "omega0"}  # fmt: skip
        lines = [
            (
                "word",
                f"{self.word}: int{w} values, int{2 * w} accumulation, round half up, saturation",
            ),
            (
                "encoder",
                f"{self.counts_per_rev} counts/rev, |delta| <= {self.delta_max} counts per sample",
            ),
        ]
        if self.measures_omega:
            lines.append(("omega", f"{q['omega']}, |omega| <= {self.omega_max!r} rad/s"))
        lines.append(("u", f"{q['u']}, |u| <= {self.u_max!r} N m"))
        lines.append(("tau_hat", f"{q['tau_hat']}, saturated at {self.tau_max!r} N m"))
        if "omega_hat" in q:
            lines.append(("omega_hat", f"{q['omega_hat']}, |omega_hat| <= "
                                       f"{self.output_bound[1]:.6g} rad/s"))  # fmt: skip
        for i in range(self.system.n_states):
            lines.append((f"q{i + 1}", f"{q[f'q{i + 1}']}, |q{i + 1}| <= "
                                       f"{self.state_bound[i]:.6g}"))  # fmt: skip
        lines.append(("error bound", ", ".join(
            f"{name} {b:.3g}" for name, b in zip(self.system.outputs, self.error_bound,
                                                  strict=True))))  # fmt: skip
        return lines


def _frame(system: LinearObserver):
    """The observer in the count-difference frame (real coefficients per operand)."""
    F, G, H, E, N = (np.asarray(a, dtype=float) for a in (system.F, system.G, system.H,
                                                         system.E, system.N))  # fmt: skip
    n = F.shape[0]
    try:
        d = np.linalg.solve(np.eye(n) - F, G[:, 0])
    except np.linalg.LinAlgError:
        raise ParameterValueError(
            "observer must have no pole at z = 1 (I - F singular): its state does not settle "
            "at a constant angle, so it cannot be written in count differences"
        ) from None
    eps = np.finfo(float).eps
    scale = np.abs(H) @ np.abs(d) + np.abs(E[:, 0])
    # residuals of the frame change, plus a bound on their own evaluation in binary64
    residual = np.abs(H @ d + E[:, 0]) + 4 * n * eps * scale
    update_residual = np.abs((F - np.eye(n)) @ d + G[:, 0]) + 4 * n * eps * (
        (np.abs(F) + np.eye(n)) @ np.abs(d) + np.abs(G[:, 0])
    )
    if np.any(residual > 1e-6 * np.maximum(scale, 1e-300)):
        raise ParameterValueError(
            "observer's outputs must not depend on a constant angle offset (zero DC gain from "
            f"theta, |H d + E_theta| = {residual.max():.3g}); it cannot run on count "
            "differences"
        )
    # per rad of count difference; the count's LSB (2 pi / cpr) is applied with the others
    Gq = np.column_stack([G[:, 0] - d, G[:, 1:-1], G[:, -1]])
    Eq = E
    Nq = N[:, 1:]  # (omega0, tau0): N_theta theta0 = d theta0 up to reset_residual
    reset_residual = np.abs(N[:, 0] - d) + 4 * eps * (np.abs(N[:, 0]) + np.abs(d))
    return F, Gq, H, Eq, Nq, (residual, update_residual, reset_residual)


def _quantise_row(target, coeffs, scales, vmax, f_target, limit, word, what, reach=None):
    """Integer row for real ``coeffs`` on operands of LSB ``scales`` and bound ``vmax``
    (``reach``: the operands' proven bounds, for the test that no term that matters is lost).

    Every coefficient gets a full word (``|C_j| <= 2^(W-1) - 1``) at its own exponent
    ``a_j <= a``; its product is scaled to the accumulator by the exact factor ``2^(a - a_j)``.
    ``a`` is the finest accumulator whose worst-case sum fits ``2W - 2`` bits.
    """
    top = 2 ** (word - 1) - 1
    acc_top = 2 ** (2 * word - 2) - 1
    real = np.asarray(coeffs, dtype=float) * np.asarray(scales, dtype=float)
    nonzero = real != 0.0
    if not nonzero.any():
        return FixedPointRow(target, (), 0, limit, f_target), real

    def exponent(c, a):
        e = min(a, math.floor(math.log2(top / abs(c))))
        while abs(round(c * 2.0**e)) > top:
            e -= 1
        return e

    a = f_target + 2 * word - 2
    while True:
        terms = []
        for j, c in enumerate(real):
            if c != 0.0:
                e = exponent(c, a)
                terms.append((round(c * 2.0**e), j, a - e))
        shift = a - f_target
        half = 2 ** (shift - 1) if shift > 0 else 0
        total = sum(abs(C) * 2**k * vmax[j] for C, j, k in terms) + half
        if total <= acc_top or shift < 0:
            break
        a -= 1
    if shift < 0:
        raise ParameterValueError(
            f"{what}: the coefficients of {target} cannot be represented: they need an "
            f"accumulator coarser than {target}'s Q format (largest |c| = "
            f"{np.abs(real).max():.3g} per bit); widen the declared ranges or use dtype 'double'"
        )
    quantised = np.zeros_like(real)
    for C, j, k in terms:
        quantised[j] = C * 2.0 ** (k - a)
    lsb_target = 2.0**-f_target
    for c, C, v in zip(real, quantised, vmax if reach is None else reach, strict=True):
        if c != 0.0 and C == 0.0 and abs(c) * v > lsb_target:
            raise ParameterValueError(
                f"{what}: a coefficient of {target} ({c:.3g} per bit) rounds to zero in the "
                f"{2 * word}-bit accumulator although it can move {target} by "
                f"{abs(c) * v / lsb_target:.3g} bits; the design's coefficients cannot be "
                "represented (its gains span too many orders of magnitude)"
            )
    terms = tuple(t for t in terms if t[0] != 0)
    return FixedPointRow(target, terms, shift, limit, a), quantised


def fixed_point_design(
    observer,
    *,
    counts_per_rev: int,
    omega_max: float,
    u_max: float,
    tau_max: float,
    word: str = "q31",
) -> FixedPointDesign:
    r"""Q formats and integer tables of an observer in fixed point, from declared ranges.

    Scales are chosen so that no intermediate overflows for any input: inputs are saturated
    to the declared ranges, and for such inputs every state stays within a bound computed
    from the quantised coefficients (the l1 norm of the impulse response from the inputs and
    from the rounding to the state, plus the peak of the free response of the initial
    state; proof in ``docs/deployment.md``). Each state then gets the finest Q format that
    holds its bound with one bit to spare, each row the finest accumulator in which every
    coefficient fits a ``W``-bit word and the sum of ``|C_j| max|V_j|`` (states at their full
    word range) fits ``2W - 2`` bits.

    Parameters
    ----------
    observer : observer-like
        Any hpdob observer (design, runtime object or :class:`~hpdob.LinearObserver`) whose
        outputs do not depend on a constant angle offset (all of hpdob's families).
    counts_per_rev : int
        Encoder counts per revolution (the angle input is an integer count).
    omega_max : float
        Velocity range [rad/s]: bounds the measured velocity input and the count difference
        per sample.
    u_max : float
        Torque command range [N m].
    tau_max : float
        Estimate range [N m]: the format of ``tau_hat`` (and of ``tau0`` of the reset); the
        estimate saturates there.
    word : {"q31", "q15"}, optional
        ``"q31"`` (int32 words, int64 accumulation; default) or ``"q15"`` (int16, int32).

    Returns
    -------
    FixedPointDesign

    Raises
    ------
    ParameterTypeError
        If ``observer`` is not an observer, or a range is not a number.
    ParameterValueError
        Naming the parameter: a range that is not positive and finite, an encoder resolution
        whose count difference per sample does not fit the word, a design whose coefficients
        cannot be represented, or an observer whose estimate depends on the absolute angle.

    Examples
    --------
    >>> from hpdob import ServoModel, design_observer
    >>> from hpdob.export import fixed_point_design
    >>> design = design_observer(ServoModel(J=2.8e-4).discretize(1e-3), order=1,
    ...                          bandwidth=100.0)
    >>> fx = fixed_point_design(design, counts_per_rev=16384, omega_max=50.0, u_max=0.5,
    ...                         tau_max=0.5)
    >>> fx.delta_max, fx.frac_bits["tau_hat"], fx.frac_bits["u"]     # Q0.31: |x| < 1
    (131, 31, 31)
    >>> bool(fx.error_bound[0] < 1e-4)                               # [N m], a priori
    True
    """
    system = as_system(observer, "observer")
    word_name = check_choice(word, "word", WORDS)
    w = WORDS[word_name]
    cpr, omega_max, u_max, tau_max = _check_ranges(counts_per_rev, omega_max, u_max, tau_max)
    delta_max = math.floor(omega_max * system.Ts * cpr / (2.0 * math.pi)) + 1
    if delta_max > 2 ** (w - 1) - 1:
        raise ParameterValueError(
            f"counts_per_rev = {cpr} cannot be scaled into {word_name}: at omega_max = "
            f"{omega_max!r} rad/s the count difference per sample reaches {delta_max}, more "
            f"than {2 ** (w - 1) - 1}; use fewer counts per revolution (drop low bits)"
        )
    F, Gq, H, Eq, Nq, residuals = _frame(system)
    n, _q = F.shape[0], H.shape[0]
    top = 2 ** (w - 1) - 1
    frac = {}
    if len(system.measures) == 2:
        frac["omega"] = _frac_bits(omega_max, w, "omega_max", "omega_max")
    # omega0 of the reset uses the omega format even for a position-only observer
    omega_bits = frac.get("omega", _frac_bits(omega_max, w, "omega_max", "omega_max"))
    frac["u"] = _frac_bits(u_max, w, "u_max", "u_max")
    frac["tau_hat"] = _frac_bits(tau_max, w, "tau_max", "tau_max")
    inputs_lsb = [2.0 * math.pi / cpr] + ([2.0 ** -frac["omega"]] if "omega" in frac else [])
    inputs_lsb.append(2.0 ** -frac["u"])
    vmax_in = np.array([delta_max] + ([math.floor(omega_max * 2.0 ** frac["omega"])]
                                      if "omega" in frac else [])
                       + [math.floor(u_max * 2.0 ** frac["u"])], dtype=float)  # fmt: skip
    reset_lsb = [2.0**-omega_bits, 2.0 ** -frac["tau_hat"]]
    reset_vmax = [math.floor(omega_max * 2.0**omega_bits),
                  math.floor(tau_max * 2.0 ** frac["tau_hat"])]  # fmt: skip
    what = f"observer {system.name!r} in {word_name}"

    # exact-coefficient bounds give the first formats; then verify with the quantised ones
    powers, tail = _powers(F)
    in_real = vmax_in * np.array(inputs_lsb)
    bound = _l1_gain(powers, tail, Gq) @ in_real + _peak_gain(powers, tail) @ (
        np.abs(Nq) @ np.array([omega_max, tau_max])
    )
    bound = np.maximum(bound, 1e-300)
    state_bits = [_frac_bits(_MARGIN * b, w, "observer", f"the bound of state q{i + 1}")
                  for i, b in enumerate(bound)]  # fmt: skip
    for _attempt in range(8):
        lsb = np.array([2.0**-f for f in state_bits])
        scales = np.concatenate([lsb, inputs_lsb])
        vmax = np.concatenate([np.full(n, float(top)), vmax_in])
        reach = np.concatenate([np.minimum(bound / lsb, top), vmax_in])
        rows, Fh, Gh = [], np.zeros_like(F), np.zeros_like(Gq)
        for i in range(n):
            row, quant = _quantise_row(f"q{i + 1}", np.concatenate([F[i], Gq[i]]), scales, vmax,
                                       state_bits[i], top, w, what, reach)  # fmt: skip
            rows.append(row)
            Fh[i], Gh[i] = quant[:n] / lsb, quant[n:] / np.array(inputs_lsb)
        resets, Nh = [], np.zeros_like(Nq)
        for i in range(n):
            row, quant = _quantise_row(f"q{i + 1}", Nq[i], reset_lsb, reset_vmax, state_bits[i],
                                       top, w, what)  # fmt: skip
            resets.append(row)
            Nh[i] = quant / np.array(reset_lsb)
        powers_h, tail_h = _powers(Fh)
        rho = np.array([0.5 * lsb[i] if rows[i].shift > 0 else 0.0 for i in range(n)])
        rho0 = np.array([0.5 * lsb[i] if resets[i].shift > 0 else 0.0 for i in range(n)])
        q0 = np.abs(Nh) @ np.array([reset_vmax[0] * reset_lsb[0], reset_vmax[1] * reset_lsb[1]])
        q0 += rho0
        bound = (_l1_gain(powers_h, tail_h, Gh) @ in_real
                 + _l1_gain(powers_h, tail_h, np.eye(n)) @ rho
                 + _peak_gain(powers_h, tail_h) @ q0)  # fmt: skip
        fits = [bound[i] * _MARGIN <= top * lsb[i] for i in range(n)]
        if all(fits):
            break
        state_bits = [
            f if ok else _frac_bits(_MARGIN * b, w, "observer", f"state q{i + 1}")
            for i, (f, ok, b) in enumerate(zip(state_bits, fits, bound, strict=True))
        ]
    else:  # pragma: no cover - the bound converges within two rounds for every family
        raise ParameterValueError(f"{what}: no Q formats satisfy the state bounds")
    for i, f in enumerate(state_bits):
        frac[f"q{i + 1}"] = f
    # outputs: tau_hat in the declared range; omega_hat in the format of its proven bound
    out_bound = _l1_gain(powers_h, tail_h, Gh, H) @ in_real + np.abs(Eq) @ in_real
    out_bound = (out_bound + _l1_gain(powers_h, tail_h, np.eye(n), H) @ rho
                 + np.abs(H) @ (_peak_gain(powers_h, tail_h) @ q0))  # fmt: skip
    out_rows, Hh, Eh, out_bits = [], np.zeros_like(H), np.zeros_like(Eq), []
    for r, name in enumerate(system.outputs):
        if name == "tau_hat":
            bits, lim = frac["tau_hat"], math.floor(tau_max * 2.0 ** frac["tau_hat"])
        else:
            bits = _frac_bits(_MARGIN * out_bound[r], w, "observer", f"the bound of {name}")
            frac[name], lim = bits, top
        row, quant = _quantise_row(name, np.concatenate([H[r], Eq[r]]), scales, vmax, bits, lim,
                                   w, what, reach)  # fmt: skip
        out_rows.append(row)
        out_bits.append(bits)
        Hh[r], Eh[r] = quant[:n] / lsb, quant[n:] / np.array(inputs_lsb)
    # a-priori error bound (docs/deployment.md): local errors |dF| B + |dG| vmax + rho
    local = np.abs(Fh - F) @ bound + np.abs(Gh - Gq) @ in_real + rho
    e0 = np.abs(Nh - Nq) @ np.array([omega_max, tau_max]) + rho0
    error = _l1_gain(powers, tail, np.eye(n), H) @ local
    error = error + np.abs(H) @ (_peak_gain(powers, tail) @ e0)
    error = error + np.abs(Hh - H) @ bound + np.abs(Eh - Eq) @ in_real
    error = error + np.array([0.5 * 2.0**-b if row.shift > 0 else 0.0
                              for b, row in zip(out_bits, out_rows, strict=True)])  # fmt: skip
    real = {
        "F": F,
        "G": Gq,
        "H": H,
        "E": Eq,
        "N": Nq,
        "Fh": Fh,
        "Gh": Gh,
        "Hh": Hh,
        "Eh": Eh,
        "Nh": Nh,
        "inputs_lsb": np.array(inputs_lsb),
        "reset_lsb": np.array(reset_lsb),
    }
    frac.setdefault("omega0", omega_bits)
    return FixedPointDesign(
        system=system, word=word_name, counts_per_rev=cpr, omega_max=omega_max, u_max=u_max,
        tau_max=tau_max, delta_max=delta_max, frac_bits=frac, update=tuple(rows),
        output=tuple(out_rows), reset=tuple(resets), state_bound=bound, output_bound=out_bound,
        error_bound=error, shift_residual=residuals[0], update_residual=residuals[1],
        reset_residual=residuals[2], real=real,
    )  # fmt: skip


# -- the integer arithmetic, generated once for Python (and printed as C by _c_fixed) --------
def _py_row(row: FixedPointRow, operands) -> str:
    total = (
        " + ".join(f"({c}) * {operands[j]}" + (f" * {2**k}" if k else "") for c, j, k in row.terms)
        or "0"
    )
    if row.shift > 0:
        total = f"(({total}) + {2 ** (row.shift - 1)}) >> {row.shift}"
    return f"_sat({total}, {row.limit})"


def _compile(design: FixedPointDesign):
    n = design.system.n_states
    state = [f"q{i}" for i in range(n)]
    names = [*state, "d", *(("w",) if design.measures_omega else ()), "u"]
    mask = 2**32
    wrap = f"    d = (count - c + {2**31}) % {mask} - {2**31}\n"
    wrap += f"    d = -{design.delta_max} if d < -{design.delta_max} else " \
            f"({design.delta_max} if d > {design.delta_max} else d)\n"  # fmt: skip
    clamp = ""
    if design.measures_omega:
        lim = design.limit("omega")
        clamp += f"    w = -{lim} if w < -{lim} else ({lim} if w > {lim} else w)\n"
    unpack = f"    ({', '.join(state)},), c = s\n"
    args = "count, w" if design.measures_omega else "count"
    lim_u = design.limit("u")
    clamp_u = f"    u = -{lim_u} if u < -{lim_u} else ({lim_u} if u > {lim_u} else u)\n"
    lim_w0, lim_t0 = math.floor(design.omega_max * 2.0 ** design.frac_bits["omega0"]), \
        design.limit("tau_hat")  # fmt: skip
    src = [
        "def _sat(x, limit):\n    return -limit if x < -limit else (limit if x > limit else x)\n",
        "def init(count0, omega0, tau0):\n"
        f"    omega0 = _sat(omega0, {lim_w0})\n    tau0 = _sat(tau0, {lim_t0})\n"
        f"    return ({', '.join(_py_row(r, ('omega0', 'tau0')) for r in design.reset)},), "
        "count0\n",
        f"def outputs(s, {args}):\n{unpack}{wrap}{clamp}"
        f"    return ({', '.join(_py_row(r, names) for r in design.output)},)\n",
        f"def update(s, {args}, u):\n{unpack}{wrap}{clamp}{clamp_u}"
        f"    return ({', '.join(_py_row(r, names) for r in design.update)},), count\n",
    ]
    namespace: dict = {}
    exec(compile("\n".join(src), "<hpdob fixed-point observer>", "exec"), namespace)
    return namespace["init"], namespace["outputs"], namespace["update"]


def _int(value, name: str) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise ParameterTypeError(f"{name} must be an integer, got {value!r}")
    if not -(2**31) <= int(value) < 2**31:
        raise ParameterValueError(f"{name} must fit int32, got {int(value)}")
    return int(value)


class FixedPointObserver:
    """Bit-exact Python model of the fixed-point C (``export_c(..., dtype="q31")``).

    Every value is an integer in the Q format of :class:`FixedPointDesign`; the arithmetic
    (products, ``2W``-bit sums, rounding, saturation, wrap-around count difference) is what
    the C evaluates, so both return the same integers for the same inputs.

    Parameters
    ----------
    design : FixedPointDesign
        From :func:`fixed_point_design`.
    count0, omega0, tau0 : int, optional
        As for :meth:`init`. Default zeros.

    Examples
    --------
    >>> from hpdob import ServoModel, design_observer
    >>> from hpdob.export import FixedPointObserver, fixed_point_design
    >>> fx = fixed_point_design(design_observer(ServoModel(J=2.8e-4).discretize(1e-3),
    ...                                         order=0, bandwidth=100.0),
    ...                         counts_per_rev=4096, omega_max=20.0, u_max=1.0, tau_max=1.0)
    >>> obs = FixedPointObserver(fx)
    >>> tau0 = int(fx.to_int("tau_hat", 0.1)[()])
    >>> obs.init(7, 0, tau0)                # at rest at count 7 under 0.1 N m
    >>> tau_hat = obs.estimate(7, 0)        # integer, 2^-30 N m per bit
    >>> abs(tau_hat - tau0) <= 4, round(float(fx.to_real("tau_hat", tau_hat)), 6)
    (True, 0.1)
    """

    def __init__(self, design: FixedPointDesign, count0: int = 0, omega0: int = 0,
                 tau0: int = 0):  # fmt: skip
        if not isinstance(design, FixedPointDesign):
            raise ParameterTypeError(
                f"design must be a FixedPointDesign (from fixed_point_design), got "
                f"{type(design).__name__}"
            )
        self.design = design
        self._init, self._outputs, self._update = design.python
        self.init(count0, omega0, tau0)

    def init(self, count0: int, omega0: int, tau0: int) -> None:
        """Reset to rest at ``count0`` [counts] with velocity ``omega0`` and disturbance
        ``tau0`` (integers in the formats of ``omega`` and ``tau_hat``).

        Parameters
        ----------
        count0, omega0, tau0 : int
            Encoder count, velocity and disturbance (int32 values).
        """
        args = (_int(count0, "count0"), _int(omega0, "omega0"), _int(tau0, "tau0"))
        self.state = self._init(*args)

    def _args(self, count, omega):
        count = _int(count, "count")
        if self.design.measures_omega:
            if omega is None:
                raise ParameterTypeError("omega must be given for an observer measuring it")
            return (count, _int(omega, "omega"))
        return (count,)

    def outputs(self, count: int, omega: int | None = None) -> tuple:
        """All outputs (``tau_hat`` [, ``omega_hat``]) of the held state, as integers.

        Parameters
        ----------
        count : int
            Encoder count (int32, wraps around).
        omega : int, optional
            Measured velocity, for observers that measure it.

        Returns
        -------
        tuple of int
        """
        return self._outputs(self.state, *self._args(count, omega))

    def estimate(self, count: int, omega: int | None = None) -> int:
        """The disturbance estimate (integer in the ``tau_hat`` format).

        Parameters
        ----------
        count, omega : int
            As for :meth:`outputs`.

        Returns
        -------
        int
        """
        return self.outputs(count, omega)[0]

    def update(self, count: int, omega: int | None = None, u: int = 0) -> None:
        """Advance by one sample with the measurement and the torque applied (integers).

        Parameters
        ----------
        count, omega : int
            As for :meth:`outputs`.
        u : int
            Torque applied (``u`` format).
        """
        self.state = self._update(self.state, *self._args(count, omega), _int(u, "u"))

    def run(self, counts, omega, u):
        """Drive a whole trace from the held state (``estimate`` then ``update`` per sample).

        Parameters
        ----------
        counts, omega, u : array_like of int, shape (n,)
            Inputs per sample (``omega`` is ignored by an observer that does not measure it).

        Returns
        -------
        outputs : ndarray of int64, shape (n, n_outputs)
            The outputs at each sample.
        states : ndarray of int64, shape (n, n_states)
            The state ``q`` each sample started from.
        """
        counts, omega, u = (np.asarray(a, dtype=np.int64).tolist() for a in (counts, omega, u))
        if not len(counts) == len(omega) == len(u):
            raise ParameterValueError("counts, omega and u must have the same length")
        outs, states = [], []
        s, fo, fu = self.state, self._outputs, self._update
        if self.design.measures_omega:
            for c, w, v in zip(counts, omega, u, strict=True):
                states.append(s[0])
                outs.append(fo(s, c, w))
                s = fu(s, c, w, v)
        else:
            for c, v in zip(counts, u, strict=True):
                states.append(s[0])
                outs.append(fo(s, c))
                s = fu(s, c, v)
        self.state = s
        n = self.design.system.n_states
        return (np.array(outs, dtype=np.int64).reshape(-1, len(self.design.system.outputs)),
                np.array(states, dtype=np.int64).reshape(-1, n))  # fmt: skip


def fixed_point_error_bound(design: FixedPointDesign, counts, omega, u, states, *,
                            init=(0, 0, 0), output: int = 0, theta=None):  # fmt: skip
    r"""Bound on ``|y_fixed - y_exact|`` at every sample of a trace [SI].

    ``y_exact`` is the observer in exact arithmetic with the design's (double) coefficients,
    driven by the same quantised inputs (``counts`` as angles, ``omega`` and ``u`` as the
    values their integers stand for) from the reset at ``init``. The derivation is in
    ``docs/deployment.md``: the fixed-point state obeys the exact recursion plus a local error
    :math:`\delta_k = (\hat F - F)\hat q_k + (\hat G - G) v_k + \rho_k`, propagated by ``F``.

    Parameters
    ----------
    design : FixedPointDesign
    counts, omega, u : array_like of int, shape (n,)
        The integer inputs the fixed-point observer was driven with.
    states : array_like of int, shape (n, n_states)
        Its states at the start of every sample (:meth:`FixedPointObserver.run`).
    init : tuple of 3 int, optional
        ``(count0, omega0, tau0)`` of the reset.
    output : int, optional
        Which output (0: ``tau_hat``, 1: ``omega_hat``). Default 0.
    theta : array_like, shape (n,), optional
        The absolute angle [rad] the exact observer is driven with (the counts unwrapped, as
        radians); default ``counts * 2 pi / counts_per_rev``. It enters only through the
        rounding-level residuals of the frame change.

    Returns
    -------
    ndarray, shape (n,)
        The bound at each sample (valid while the output is not saturated).
    """
    real = design.real
    n = design.system.n_states
    lsb = np.array([2.0 ** -design.frac_bits[f"q{i + 1}"] for i in range(n)])
    q = np.abs(np.asarray(states, dtype=float)) * lsb
    ins = [np.asarray(counts, dtype=np.int64), np.asarray(omega, dtype=np.int64),
           np.asarray(u, dtype=np.int64)]  # fmt: skip
    delta = np.diff(np.concatenate([[int(init[0])], ins[0]]))
    delta = (delta + 2**31) % 2**32 - 2**31
    columns = [np.abs(delta) * design.radians_per_count]
    if design.measures_omega:
        columns.append(np.abs(ins[1]) * design.lsb("omega"))
    columns.append(np.abs(ins[2]) * design.lsb("u"))
    v = np.column_stack(columns)
    rho = np.array([0.5 * lsb[i] if row.shift > 0 else 0.0 for i, row in enumerate(design.update)])
    if theta is None:
        theta = ins[0] * design.radians_per_count
    theta = np.abs(np.asarray(theta, dtype=float))
    previous = np.concatenate([[abs(int(init[0])) * design.radians_per_count], theta[:-1]])
    local = q @ np.abs(real["Fh"] - real["F"]).T + v @ np.abs(real["Gh"] - real["G"]).T + rho
    local = local + previous[:, None] * design.update_residual[None, :]
    start = np.array([abs(init[1]) * design.lsb("omega0"), abs(init[2]) * design.lsb("tau_hat")])
    rho0 = np.array([0.5 * lsb[i] if row.shift > 0 else 0.0 for i, row in enumerate(design.reset)])
    e0 = np.abs(real["Nh"] - real["N"]) @ start + rho0
    e0 = e0 + design.reset_residual * abs(int(init[0])) * design.radians_per_count
    F, H = real["F"], real["H"]
    h, row = [], np.abs(H[output])
    row = H[output].copy()
    peak = 0.0
    while True:
        size = float(np.abs(row).sum())
        peak = max(peak, size)
        h.append(np.abs(row))
        if size < 1e-20 * peak and len(h) > 10 * n:
            break
        row = row @ F
    h = np.array(h)
    k = q.shape[0]
    bound = np.zeros(k)
    for i in range(n):
        bound[1:] += np.convolve(local[:, i], h[:, i])[: k - 1]
        reach = np.zeros(k)
        reach[: min(k, h.shape[0])] = h[:k, i]
        bound += reach * e0[i]
    out = design.output[output]
    bound += q @ np.abs(real["Hh"][output] - H[output]) + v @ np.abs(
        real["Eh"][output] - real["E"][output]
    )
    bound += 0.5 * 2.0 ** -design.frac_bits[design.system.outputs[output]] if out.shift else 0.0
    bound += design.shift_residual[output] * previous
    return bound * (1.0 + 1e-9)
