"""The bit-exact Python model of the fixed-point C, and its error bound along a trace.

:class:`FixedPointObserver` runs the integer rows of a :class:`FixedPointDesign` exactly as the
generated C does; :func:`fixed_point_error_bound` bounds its distance to the exact observer
(``docs/deployment.md``, "Fixed point").
"""

from __future__ import annotations

import numpy as np

from .._validation import ParameterTypeError, ParameterValueError
from ._fixed import FixedPointDesign

__all__ = ["FixedPointObserver", "fixed_point_error_bound"]


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
        if omega is not None:
            raise ParameterValueError(
                f"omega must be None for an observer that measures only the angle (pass u by "
                f"name: update(count, u=...)), got {omega!r}"
            )
        return (count,)

    def outputs(self, count: int, omega: int | None = None) -> tuple:
        """All outputs (``tau_hat`` [, ``omega_hat``] [, ``tau_reac``]) of the held state, as
        integers.

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

    def reaction(self, count: int, omega: int | None = None) -> int:
        """The reaction-torque estimate of a reaction-torque observer composition (integer in
        the ``tau_reac`` format), as ``<prefix>_reaction`` of the C.

        Parameters
        ----------
        count, omega : int
            As for :meth:`outputs`.

        Returns
        -------
        int

        Raises
        ------
        ParameterValueError
            If the observer has no ``tau_reac`` output.

        Examples
        --------
        >>> from hpdob import ServoModel, design_observer
        >>> from hpdob.export import FixedPointObserver, fixed_point_design
        >>> from hpdob.observers import reaction_torque_observer
        >>> dob = design_observer(ServoModel(J=2.8e-4).discretize(1e-3), order=1,
        ...                       bandwidth=100.0)
        >>> fx = fixed_point_design(reaction_torque_observer(dob, viscous=5e-5),
        ...                         counts_per_rev=16384, omega_max=50.0, u_max=0.5, tau_max=0.5)
        >>> obs = FixedPointObserver(fx)
        >>> obs.reaction(0, 0)                # at rest, no torque
        0
        >>> obs.reaction(0, 0) == obs.estimates(0, 0)[1]
        True
        """
        return self.estimates(count, omega)[1]

    def estimates(self, count: int, omega: int | None = None) -> tuple[int, int]:
        """``(tau_hat, tau_reac)`` in one call, as ``<prefix>_estimates`` of the C (issue 21):
        the DOb's disturbance estimate (``tau_hat`` format) and the reaction-torque estimate
        (``tau_reac`` format).

        Parameters
        ----------
        count, omega : int
            As for :meth:`outputs`.

        Returns
        -------
        tuple of int

        Raises
        ------
        ParameterValueError
            If the observer has no ``tau_reac`` output (not a reaction-torque observer
            composition).

        Examples
        --------
        >>> from hpdob import ServoModel, design_observer
        >>> from hpdob.export import FixedPointObserver, fixed_point_design
        >>> from hpdob.observers import reaction_torque_observer
        >>> dob = design_observer(ServoModel(J=2.8e-4).discretize(1e-3), order=1,
        ...                       bandwidth=100.0)
        >>> fx = fixed_point_design(reaction_torque_observer(dob, viscous=5e-5),
        ...                         counts_per_rev=16384, omega_max=50.0, u_max=0.5, tau_max=0.5)
        >>> obs = FixedPointObserver(fx)
        >>> obs.estimates(0, 0)               # at rest, no torque: both zero
        (0, 0)
        """
        outputs = self.design.system.outputs
        if "tau_reac" not in outputs:
            raise ParameterValueError(
                f"observer {self.design.system.name!r} has no reaction-torque output tau_reac "
                f"(its outputs: {', '.join(outputs)}); a reaction-torque observer composition "
                "(hpdob.observers.reaction_torque_observer) has one"
            )
        y = self.outputs(count, omega)
        return y[0], y[outputs.index("tau_reac")]

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
