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

from .._validation import ParameterValueError, check_choice
from ..observers import LinearObserver, as_system
from ._fixed_tables import (
    _check_ranges,
    _frac_bits,
    _frame,
    _l1_gain,
    _peak_gain,
    _powers,
    _quantise_row,
)

__all__ = ["WORDS", "FixedPointDesign", "fixed_point_design"]

#: Word formats: name -> word length W [bits] (states, coefficients, signals; accumulators 2W).
WORDS = {"q31": 32, "q15": 16}
#: One bit of headroom on every derived bound (covers the truncated series and float rounding
#: of the bound's own evaluation, which are many orders of magnitude smaller).
_MARGIN = 2.0


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
        from ._fixed_python import compile_fixed

        return compile_fixed(self)

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
        if "tau_reac" in q:
            r = self.system.outputs.index("tau_reac")
            lines.append(("tau_reac", f"{q['tau_reac']}, |tau_reac| <= "
                                      f"{self.output_bound[r]:.6g} N m"))  # fmt: skip
        for i in range(self.system.n_states):
            lines.append((f"q{i + 1}", f"{q[f'q{i + 1}']}, |q{i + 1}| <= "
                                       f"{self.state_bound[i]:.6g}"))  # fmt: skip
        lines.append(("error bound", ", ".join(
            f"{name} {b:.3g}" for name, b in zip(self.system.outputs, self.error_bound,
                                                  strict=True))))  # fmt: skip
        return lines


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
    if system.coulomb is not None:
        raise ParameterValueError(
            f"observer {system.name!r} has a Coulomb term (tanh) in tau_reac, which fixed point "
            "does not implement; export it with dtype 'double' or 'float'"
        )
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
