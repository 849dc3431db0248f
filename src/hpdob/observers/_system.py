r"""The observer protocol: every observer is a linear discrete-time system.

An observer reads, at sample ``k``, the signals it measures (``measures``: the angle
:math:`\theta_k`, and the velocity :math:`\omega_k` for the paper's observers) and the torque
:math:`u_k` that was applied, and returns its estimate :math:`\hat\tau_k` (and, where it has one,
a velocity estimate :math:`\hat\omega_k`):

.. math::

    y_k = H s_k + E v_k, \qquad s_{k+1} = F s_k + G v_k, \qquad s_0 = N\,[\theta_0, \omega_0,
    \tau_0]^T,

with :math:`v_k = [\text{measured signals}, u_k]` and :math:`y_k = [\hat\tau_k(, \hat\omega_k)]`.
The last column of ``E`` is zero: the estimate of sample ``k`` is computed before ``u_k`` (which
uses it) exists. :class:`LinearObserver` holds these matrices; it is what the runtime object, the
functional core, the compiled simulation kernel, the MuJoCo loop, :func:`hpdob.export_c` and the
analysis functions consume. A new observer family is one design function that returns one.

Every executable form is derived from one definition, the :class:`Program`: for each row of
``[F G]``, ``[H E]`` and ``N`` an ordered list of terms ``coefficient * operand``. Python code is
generated from it (:func:`compile_python`), the numba kernel interprets its arrays
(:meth:`Program.arrays`) and the C exporter prints it, all summing the terms in the same order,
so the three agree bit for bit. By default the program is read off the dense matrices (non-zero
entries, column order). A structured family may give its own: the order-m observer keeps its
companion form's unit shifts and integer extrapolation weights as separate exact terms instead
of rounded sums such as :math:`p_{m+1} - k_{m+1}`.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from .._validation import (
    ParameterTypeError,
    ParameterValueError,
    _show,
    numeric_array,
    positive,
    shaped_matrix,
)
from ._error_dynamics import ErrorDynamics
from ._friction import CoulombFriction, coulomb_torque
from ._program import (
    RESET_OPERANDS,
    Program,
    Term,
    check_program,
    compile_checked_update,
    compile_python,
)
from ._signals import MEASUREMENTS, OUTPUTS, UNITS

__all__ = [
    "MEASUREMENTS",
    "OUTPUTS",
    "RESET_OPERANDS",
    "UNITS",
    "ErrorDynamics",
    "LinearObserver",
    "Program",
    "Term",
    "as_system",
    "check_designed_on",
]


class _Designed:
    """What every family's frozen design shares: its ``model`` and ``system`` give ``Ts`` and
    ``to_statespace``."""

    __slots__ = ()

    @property
    def Ts(self) -> float:
        """Sampling period [s]."""
        return self.model.Ts

    def to_statespace(self):
        """The observer as a discrete python-control ``StateSpace`` (``dt = Ts``).

        Returns
        -------
        control.StateSpace
            Inputs the measured signals (``theta``, and ``omega`` for a state-measuring
            observer) and ``u``; outputs ``tau_hat`` (and ``omega_hat`` where the observer has
            one): :meth:`LinearObserver.to_statespace`.
        """
        return self.system.to_statespace()

    def _repr_markdown_(self) -> str:
        """A compact table for Jupyter: family, nominal model, poles, signals."""
        from .._repr import markdown_table

        system, model = self.system, self.model
        return markdown_table(system.name, [
            ("nominal model", f"J_n = {model.J:.4g} kg m², b_n = {model.b:.4g} N m s/rad"),
            ("Ts [s]", model.Ts), ("bandwidth [rad/s]", getattr(self, "bandwidth", None)),
            ("poles", getattr(self, "poles", None)), ("states", system.n_states),
            ("measures", ", ".join(system.measures)), ("outputs", ", ".join(system.outputs)),
        ])  # fmt: skip


@dataclass(frozen=True, eq=False)
class LinearObserver:
    r"""An observer as a linear discrete-time system: the protocol every observer implements.

    .. math::

        y_k = H s_k + E v_k,\qquad s_{k+1} = F s_k + G v_k,\qquad
        s_0 = N\,[\theta_0,\ \omega_0,\ \tau_0]^T,

    with inputs :math:`v_k = [\text{measures}\dots, u_k]` and outputs
    :math:`y_k = [\hat\tau_k, (\hat\omega_k)]`. At every sample the loop calls ``estimate``
    (outputs from :math:`s_k` and the measurement), computes and applies :math:`u_k`, then
    ``update`` (:math:`s_{k+1}`). All arrays are read-only.

    Parameters
    ----------
    F : array_like, shape (n, n)
        State matrix.
    G : array_like, shape (n, p + 1)
        Input matrix; columns follow ``measures`` then ``u`` [N m].
    H : array_like, shape (q, n)
        Output matrix; rows follow ``outputs``.
    E : array_like, shape (q, p + 1)
        Feed-through; its last column (from ``u``) must be zero.
    N : array_like, shape (n, 3)
        Reset matrix: :math:`s_0 = N [\theta_0, \omega_0, \tau_0]` is the state of an observer
        that has converged on a constant disturbance :math:`\tau_0` [N m] at
        :math:`(\theta_0, \omega_0)` (what ``reset(x0, tau0)`` sets).
    Ts : float
        Sampling period [s].
    measures : {("theta", "omega"), ("theta",)}
        Measured signals, in the order of the first columns of ``G`` and ``E``.
    outputs : tuple of str, optional
        Output signals: ``("tau_hat",)`` (default), ``("tau_hat", "omega_hat")``, or either
        followed by ``"tau_reac"``, a reaction-torque estimate [N m]
        (:func:`hpdob.observers.reaction_torque_observer`).
    model : DiscreteServoModel, optional
        The nominal model the observer was designed on; loops check it against their nominal
        model and ``Ts``. None: only ``Ts`` is checked.
    name : str, optional
        Short description (used in messages and generated code).
    program : Program, optional
        Evaluation order of the recurrence; default :meth:`Program.from_matrices`. A given
        program must sum to the matrices (each entry to rounding).
    error_dynamics : ErrorDynamics, optional
        Closed form of the estimation error on the nominal plant, where the family has one
        (the order-m family: :math:`1 - Q(z) = (z-1)^{m+1}/\prod_i (z - p_i)`), used by
        :func:`hpdob.estimation_response`. None: ``Q`` is computed from the matrices.
    info : tuple of (str, str), optional
        Design summary lines (key, value) for headers of generated code.
    coulomb : CoulombFriction, optional
        The one nonlinear term an observer may have: the Coulomb part
        :math:`c_n\tanh(\omega/v_n)` of a reaction-torque observer's friction model, subtracted
        from the linear ``tau_reac`` row after the outputs of the sample are computed (the Python
        runtime, the compiled kernel and exported C alike;
        :func:`hpdob.observers.reaction_torque_observer`). The matrices, ``to_statespace`` and
        the (linear) analysis views hold the linear part only. Needs a ``tau_reac`` output and
        the velocity it reads. Default None.

    Raises
    ------
    TypeError, ValueError
        Naming the argument: wrong shapes, non-finite entries, an unknown ``measures`` or
        ``outputs``, a feed-through from ``u``, a program that does not match the matrices.

    See Also
    --------
    hpdob.design_observer : the order-m family (``ObserverDesign.system``).

    Examples
    --------
    The conventional DOb (eqs. 11, 13) followed by a first-order low-pass, from scratch:

    >>> import numpy as np
    >>> from hpdob import LinearObserver, ServoModel, design_observer
    >>> model = ServoModel(2.8e-4).discretize(1e-3)
    >>> dob = design_observer(model, order=0, bandwidth=200.0).system
    >>> a = 0.9                                         # low-pass pole
    >>> F = np.block([[dob.F, np.zeros((1, 1))], [(1 - a) * dob.H, np.array([[a]])]])
    >>> G = np.vstack([dob.G, (1 - a) * dob.E])
    >>> filtered = LinearObserver(F=F, G=G, H=[[0.0, 1.0]], E=np.zeros((1, 3)),
    ...                           N=np.vstack([dob.N, [0.0, 0.0, 1.0]]), Ts=1e-3,
    ...                           measures=("theta", "omega"), model=model)
    >>> filtered.F.shape, filtered.measures
    ((2, 2), ('theta', 'omega'))
    """

    F: np.ndarray
    G: np.ndarray
    H: np.ndarray
    E: np.ndarray
    N: np.ndarray
    Ts: float
    measures: tuple = ("theta", "omega")
    outputs: tuple = ("tau_hat",)
    model: object = None
    name: str = "observer"
    program: Program | None = field(default=None, repr=False)
    error_dynamics: ErrorDynamics | None = field(default=None, repr=False)
    info: tuple = field(default=(), repr=False)
    coulomb: CoulombFriction | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        measures = tuple(self.measures) if isinstance(self.measures, (tuple, list)) else None
        if measures not in MEASUREMENTS.values():
            raise ParameterValueError(
                f"measures must be one of {list(MEASUREMENTS.values())}, got {self.measures!r}"
            )
        outputs = tuple(self.outputs) if isinstance(self.outputs, (tuple, list)) else None
        if outputs not in OUTPUTS:
            raise ParameterValueError(
                f"outputs must be one of {list(OUTPUTS)}, got {self.outputs!r}"
            )
        F = numeric_array(self.F, "F", "a square real matrix", dtype=float)
        if F.ndim != 2 or F.shape[0] != F.shape[1] or F.shape[0] == 0:
            raise ParameterValueError(f"F must be a non-empty square matrix, got shape {F.shape}")
        n, p, q = F.shape[0], len(measures), len(outputs)
        F = shaped_matrix(F, "F", (n, n))
        G = shaped_matrix(self.G, "G", (n, p + 1))
        H = shaped_matrix(self.H, "H", (q, n))
        E = shaped_matrix(self.E, "E", (q, p + 1))
        N = shaped_matrix(self.N, "N", (n, 3))
        if np.any(E[:, -1] != 0.0):
            raise ParameterValueError(
                "E's last column (feed-through from u) must be zero: the estimate of sample k "
                f"is needed to compute u_k, got {_show(E[:, -1])}"
            )
        Ts = positive(self.Ts, "Ts", "a positive finite sampling period [s]")
        model = self.model
        if model is not None:
            from ..models import DiscreteServoModel

            if not isinstance(model, DiscreteServoModel):
                raise ParameterTypeError(
                    f"model must be a DiscreteServoModel or None, got {type(model).__name__}"
                )
            if model.Ts != Ts:
                raise ParameterValueError(f"model.Ts = {model.Ts!r} must equal Ts = {Ts!r}")
        if not isinstance(self.name, str):
            raise ParameterTypeError(f"name must be a str, got {type(self.name).__name__}")
        program = self.program
        if program is None:
            program = Program.from_matrices(F, G, H, E, N, measures)
        else:
            check_program(
                program,
                {"update": np.hstack([F, G]), "output": np.hstack([H, E]), "reset": N},
                n,
                p,
                q,
            )
        if any(t.operand == n + p for terms in program.output for t in terms):
            raise ParameterValueError("program.output must not use u (operand n + p)")
        program.constant_table()  # each constant name has one value
        if self.error_dynamics is not None and not isinstance(self.error_dynamics, ErrorDynamics):
            raise ParameterTypeError(
                "error_dynamics must be an ErrorDynamics or None, got "
                f"{type(self.error_dynamics).__name__}"
            )
        _check_coulomb(self.coulomb, measures, outputs)
        object.__setattr__(self, "measures", measures)
        object.__setattr__(self, "outputs", outputs)
        for name, value in (("F", F), ("G", G), ("H", H), ("E", E), ("N", N)):
            object.__setattr__(self, name, value)
        object.__setattr__(self, "Ts", Ts)
        object.__setattr__(self, "program", program)
        object.__setattr__(self, "info", tuple(self.info))

    # -- shape -----------------------------------------------------------------------------
    @property
    def n_states(self) -> int:
        """Number of states ``n``."""
        return self.F.shape[0]

    @property
    def system(self) -> LinearObserver:
        """The observer itself (every observer-like object has ``.system``)."""
        return self

    @property
    def input_names(self) -> tuple:
        """``measures`` followed by ``"u"``."""
        return (*self.measures, "u")

    @property
    def measurement(self) -> str:
        """``"state"`` (angle and velocity measured) or ``"position"`` (angle only)."""
        return "state" if self.measures == MEASUREMENTS["state"] else "position"

    @property
    def truncation_order(self) -> int | None:
        """Truncation order ``m`` of the error dynamics, where the family has one."""
        return None if self.error_dynamics is None else self.error_dynamics.order

    @property
    def has_velocity(self) -> bool:
        """Whether the observer outputs a velocity estimate ``omega_hat``."""
        return "omega_hat" in self.outputs

    # -- derived ---------------------------------------------------------------------------
    @functools.cached_property
    def python(self):
        """Generated Python functions ``(reset, outputs, estimate, update)`` (see
        :func:`compile_python`); with a :attr:`coulomb` term, ``outputs`` subtracts it from
        ``tau_reac``."""
        functions = compile_python(self)
        if self.coulomb is None:
            return functions
        return (functions[0], _with_coulomb(self, functions[1]), *functions[2:])

    @functools.cached_property
    def checked_update(self):
        """The generated ``update`` that returns None instead of a next state that is not
        finite (:func:`compile_checked_update`): the overflow refusal of the sample loop."""
        return compile_checked_update(self)

    @functools.cached_property
    def kernel_arrays(self):
        """The program as arrays for the compiled kernel (:meth:`Program.arrays`)."""
        return self.program.arrays()

    def to_statespace(self):
        r"""The observer as a discrete python-control ``StateSpace`` (``dt = Ts``).

        Run from a zero initial state on the sequences of measurements and ``u`` it returns,
        sample by sample, what the runtime observer returns after ``reset()``.

        Returns
        -------
        control.StateSpace
            ``A, B, C, D = F, G, H, E``: inputs :attr:`measures` (``theta`` [rad], and
            ``omega`` [rad/s] for a state-measuring observer) and ``u`` [N m], outputs
            :attr:`outputs` (``tau_hat`` [N m], and ``omega_hat`` [rad/s] where the observer
            has one). For the order-m family :math:`A = M`, :math:`B = [K_x, K_u]`,
            :math:`C = e_{m+1}^T`, :math:`D = [-L_{m+1}^T, 0]`.

        References
        ----------
        Eqs. (11), (13) (DOb) and (20), (21), (23) (HPDOb), in matrix form.

        Examples
        --------
        >>> import control, numpy as np
        >>> from hpdob import ServoModel, design_observer
        >>> design = design_observer(ServoModel(J=2.8e-4).discretize(1e-3), order=1,
        ...                          bandwidth=100.0)
        >>> ss = design.system.to_statespace()
        >>> ss.input_labels, ss.output_labels, ss.dt
        (['theta', 'omega', 'u'], ['tau_hat'], 0.001)
        >>> np.abs(control.poles(ss)).round(6)   # both at exp(-100 Ts)
        array([0.904837, 0.904837])
        """
        from ._response import statespace

        return statespace(self)

    @classmethod
    def from_statespace(
        cls, sys, *, measures=None, outputs=None, model=None, N=None, name: str | None = None
    ) -> LinearObserver:
        r"""An estimator designed elsewhere, from a discrete python-control ``StateSpace``.

        The inverse of :meth:`to_statespace` (``F, G, H, E = A, B, C, D``, ``Ts = dt``): the
        outputs of sample ``k`` use the state and measurements of ``k``, not ``u_k``. (A
        *current* estimator ``x_k = A' x_{k-1} + B' u_{k-1} + L y_k``, output ``C x_k``, takes
        the prediction as state: ``F = A'``, ``G = [A' L, B']``, ``H = C``, ``E = [C L, 0]``.)

        Parameters
        ----------
        sys : control.StateSpace
            Discrete (``dt > 0``); inputs the measured signals then ``u`` [N m], outputs
            ``tau_hat`` [N m] (and ``omega_hat`` [rad/s]).
        measures, outputs : tuple of str, optional
            As in the constructor. Default: read from ``sys``'s labels where they are these
            names (as :meth:`to_statespace` writes them); one output is ``("tau_hat",)``.
        model : DiscreteServoModel or sampled python-control servo, optional
            The nominal model it was designed on (loops check it).
        N : array_like, shape (n, 3), optional
            Default: derived, where the system allows it, as the state the observer holds once
            converged on a constant :math:`\tau_0` while the axis turns at a constant
            :math:`\omega_0` from :math:`\theta_0`. Where it does not (``F`` has an eigenvalue
            at 1, or the estimate does not settle at a constant disturbance) the error says so
            and ``N`` must be given.
        name : str, optional
            Short description. Default: the system's name.

        Returns
        -------
        LinearObserver

        Raises
        ------
        ParameterTypeError, ParameterValueError
            For a continuous system, labels or shapes that do not fit, a feed-through from
            ``u``, or an ``N`` that cannot be derived.

        Examples
        --------
        >>> import numpy as np
        >>> from hpdob import LinearObserver, ServoModel, design_observer
        >>> model = ServoModel(2.8e-4).discretize(1e-3)
        >>> dob = design_observer(model, order=1, bandwidth=100.0).system
        >>> back = LinearObserver.from_statespace(dob.to_statespace(), model=model)
        >>> back.measures, bool(np.allclose(back.N, dob.N))
        (('theta', 'omega'), True)
        """
        from ._external import observer_from_statespace

        return observer_from_statespace(
            cls, sys, measures=measures, outputs=outputs, model=model, N=N, name=name
        )

    def __getstate__(self) -> dict:
        # generated code is rebuilt on demand, not pickled (e.g. for dask workers)
        state = dict(self.__dict__)
        # (and not the simulation's values kept on the design: hpdob.simulation._derived)
        for derived in ("python", "checked_update", "kernel_arrays", "_hpdob_derived"):
            state.pop(derived, None)
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)

    def __repr__(self) -> str:
        return (
            f"LinearObserver(name={self.name!r}, states={self.n_states}, "
            f"measures={self.measures}, outputs={self.outputs}, Ts={self.Ts:g})"
        )


def _check_coulomb(coulomb, measures: tuple, outputs: tuple) -> None:
    if coulomb is None:
        return
    if not isinstance(coulomb, CoulombFriction):
        raise ParameterTypeError(
            f"coulomb must be a CoulombFriction or None, got {type(coulomb).__name__}"
        )
    if "tau_reac" not in outputs:
        raise ParameterValueError(
            f"coulomb needs a tau_reac output to subtract from, got outputs {outputs}"
        )
    available = measures if coulomb.velocity == "omega" else outputs
    if coulomb.velocity not in available:
        raise ParameterValueError(
            f"coulomb reads {coulomb.velocity!r}, which the observer (measures {measures}, "
            f"outputs {outputs}) does not have"
        )


def _with_coulomb(system: LinearObserver, linear):
    """``outputs`` of ``system`` with its Coulomb term subtracted from ``tau_reac``: the linear
    row first, then ``- c tanh(omega / v)`` (the kernel's and the C's order)."""
    c, v, d = system.coulomb.c, system.coulomb.v, system.coulomb.deadband
    r = system.outputs.index("tau_reac")
    if system.coulomb.velocity == "omega":
        j = system.measures.index("omega")

        def outputs(s, *values):
            y = linear(s, *values)
            return (*y[:r], y[r] - coulomb_torque(c, v, values[j], d), *y[r + 1 :])
    else:
        j = system.outputs.index("omega_hat")

        def outputs(s, *values):
            y = linear(s, *values)
            return (*y[:r], y[r] - coulomb_torque(c, v, y[j], d), *y[r + 1 :])

    return outputs


def as_system(observer, name: str = "observer") -> LinearObserver:
    """The :class:`LinearObserver` of an observer-like object.

    Parameters
    ----------
    observer : LinearObserver or observer-like
        A :class:`LinearObserver`, or anything with a ``system`` attribute that is one
        (designs such as :class:`~hpdob.ObserverDesign`, runtime objects such as
        :class:`~hpdob.DisturbanceObserver`, your own observer classes), or a discrete
        python-control ``StateSpace`` labelled as :meth:`LinearObserver.to_statespace` labels
        (read by :meth:`LinearObserver.from_statespace`, ``N`` derived).
    name : str, optional
        The parameter name the error message uses. Default ``"observer"``.

    Returns
    -------
    LinearObserver
        ``observer`` itself, or its ``system``.

    Raises
    ------
    ParameterTypeError
        If ``observer`` is neither.

    Examples
    --------
    >>> from hpdob import DisturbanceObserver, ServoModel
    >>> from hpdob.observers import as_system
    >>> obs = DisturbanceObserver(ServoModel(J=2.8e-4).discretize(1e-3), order=1,
    ...                           bandwidth=100.0)
    >>> system = as_system(obs)
    >>> system.n_states, system.measures, system.outputs
    (2, ('theta', 'omega'), ('tau_hat',))
    """
    if isinstance(observer, LinearObserver):
        return observer
    system = getattr(observer, "system", None)
    if isinstance(system, LinearObserver):
        return system
    from ..models import is_lti

    if is_lti(observer):
        return LinearObserver.from_statespace(observer, name=name)
    raise ParameterTypeError(
        f"{name} must be a DisturbanceObserver, an ObserverDesign or another observer (a "
        f"LinearObserver, or an object whose .system is one), got {type(observer).__name__}"
    )


def check_designed_on(system, nominal, Ts: float, name: str = "observer") -> None:
    """Raise unless ``system`` was synthesised on ``nominal.discretize(Ts)`` (same J, b, Ts;
    J and ``b Ts/J`` to 1e-9 relative).

    ``system`` is a :class:`LinearObserver` or anything with one (``.system``); an observer
    without a nominal model (``model=None``) is checked for ``Ts`` only.
    """
    system = as_system(system, name)
    model = system.model
    if model is None:
        if system.Ts != Ts:
            raise ParameterValueError(
                f"{name} must run at the loop's sampling period: its Ts={system.Ts} but the "
                f"loop has Ts={Ts}"
            )
        return
    # to 1e-9 relative: a model read back from python-control (ServoModel.from_lti,
    # DiscreteServoModel.from_lti) is the same nominal model to its last digits, not to all
    same_J = math.isclose(model.J, nominal.J, rel_tol=1e-9)
    same_b = math.isclose(model.b * Ts / model.J, nominal.b * Ts / nominal.J, rel_tol=1e-9,
                          abs_tol=1e-12)  # fmt: skip
    if not (same_J and same_b and model.Ts == Ts):
        raise ParameterValueError(
            f"{name} must be designed on nominal.discretize(Ts): its model has J={model.J}, "
            f"b={model.b}, Ts={model.Ts} but nominal has J={nominal.J}, b={nominal.b} and Ts={Ts}"
        )
