"""Compile exported C observers on the host and drive them from Python.

Used by the tests and benchmarks of :func:`hpdob.export_c`, and by anyone who wants to check
an export on their own machine. It needs a C compiler (``gcc`` or ``$CC``); nothing here is
imported by ``import hpdob``.

Two ways to drive a build:

* :class:`CObserver` calls the exported ``_init``/``_estimate``/``_update`` through ctypes, one
  call per sample, exactly as firmware would (use it when Python closes the loop);
* :meth:`CObserver.drive` runs a whole input trace in a C loop (``<prefix>_drive`` from
  :func:`drive_source`) and returns the estimates and the states.

:func:`hpdob.testing.sanitized_run` (``_sanitize.py``) builds the same drive loop under
AddressSanitizer and UndefinedBehaviorSanitizer.
"""

from __future__ import annotations

import ctypes
import os
import shutil
import subprocess
from collections.abc import Sequence
from pathlib import Path

import numpy as np

__all__ = [
    "STRICT_FLAGS",
    "CBuildError",
    "CObserver",
    "compile_c",
    "drive_source",
    "find_compiler",
]

#: The warning set of the issue, plus the checks that matter on a microcontroller.
STRICT_FLAGS = (
    "-std=c99",
    "-Wall",
    "-Wextra",
    "-Wpedantic",
    "-Wconversion",
    "-Wdouble-promotion",
    "-Wshadow",
    "-Werror",
)
#: No fused multiply-add contraction: the double build then reproduces hpdob.update exactly.
#: (GCC's default under -std=c99 already; spelt out for other compilers and modes.)
EXACT_FLAGS = ("-ffp-contract=off",)


class CBuildError(RuntimeError):
    """The C compiler or a compiled program failed (the message holds its output).

    Raised by :func:`compile_c`, :class:`CObserver` and :func:`sanitized_run`.
    """


def find_compiler() -> str | None:
    """The C compiler :func:`compile_c` uses: ``$CC``, default ``gcc``, found on ``PATH``.

    Returns
    -------
    str or None
        Its full path, or None if it is not installed (skip C tests then).

    Examples
    --------
    >>> from hpdob.testing import find_compiler
    >>> cc = find_compiler()
    >>> cc is None or isinstance(cc, str)
    True
    """
    return shutil.which(os.environ.get("CC", "gcc"))


def compile_c(
    sources: Sequence[Path | str],
    output: Path | str,
    *,
    flags: Sequence[str] = (),
    shared: bool = False,
    libraries: Sequence[str] = (),
) -> Path:
    """Compile ``sources`` into ``output`` (an executable, or a shared library if ``shared``).

    Any output of the compiler on stderr counts as a failure, so a build with
    :data:`STRICT_FLAGS` is warning-free.

    Parameters
    ----------
    sources : sequence of str or Path
        The C files to compile and link together.
    output : str or Path
        The file to write.
    flags : sequence of str, optional
        Compiler flags, e.g. :data:`STRICT_FLAGS`. Default none.
    shared : bool, optional
        Build a shared library (``-shared -fPIC``) to load with ctypes. Default False.
    libraries : sequence of str, optional
        Libraries to link, without ``-l`` (e.g. ``["m"]``). Default none.

    Returns
    -------
    pathlib.Path
        ``output``.

    Raises
    ------
    CBuildError
        If no compiler is found or it reports an error or a warning (the message holds the
        command and its output).

    Examples
    --------
    >>> import ctypes, tempfile
    >>> from pathlib import Path
    >>> from hpdob.testing import STRICT_FLAGS, compile_c, find_compiler
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     source = Path(tmp, "answer.c")
    ...     _ = source.write_text("int answer(void);\\nint answer(void) { return 42; }\\n")
    ...     if find_compiler():  # needs gcc or $CC; without one nothing is checked
    ...         lib = compile_c([source], Path(tmp, "libanswer.so"), flags=STRICT_FLAGS,
    ...                         shared=True)
    ...         assert ctypes.CDLL(str(lib)).answer() == 42
    """
    cc = find_compiler()
    if cc is None:
        raise CBuildError("no C compiler found (set CC or install gcc)")
    output = Path(output)
    cmd = [cc, *flags, *(["-shared", "-fPIC"] if shared else [])]
    cmd += [str(s) for s in sources] + ["-o", str(output)] + [f"-l{lib}" for lib in libraries]
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if done.returncode != 0 or done.stderr.strip():
        raise CBuildError(f"{' '.join(cmd)} failed:\n{done.stdout}{done.stderr}")
    return output


def drive_source(prefix: str, dtype: str, states: int, measures=("theta", "omega")) -> str:
    """C source of ``void <prefix>_drive(...)``: run a trace through the exported observer.

    ``theta, omega, u`` hold ``n`` doubles, converted to the observer's type as firmware
    would (``omega`` is ignored by a position-only observer); ``tau_hat[k]`` receives the
    estimate at sample ``k`` and ``z[k*states + i]`` the state the estimate and update of
    sample ``k`` started from.
    """
    args = "th, om" if len(measures) == 2 else "th"
    unused = "" if len(measures) == 2 else "        (void)om;\n"
    return f"""\
#include "{prefix}.h"

void {prefix}_drive(long n, const double *init, const double *theta, const double *omega,
                    const double *u, double *tau_hat, double *z);

void {prefix}_drive(long n, const double *init, const double *theta, const double *omega,
                    const double *u, double *tau_hat, double *z)
{{
    {prefix}_state s;
    long k;
    int i;
    {prefix}_init(&s, ({dtype})init[0], ({dtype})init[1], ({dtype})init[2]);
    for (k = 0; k < n; ++k) {{
        const {dtype} th = ({dtype})theta[k];
        const {dtype} om = ({dtype})omega[k];
{unused}        for (i = 0; i < {states}; ++i) {{
            z[k * {states} + i] = (double)s.z[i];
        }}
        tau_hat[k] = (double){prefix}_estimate(&s, {args});
        {prefix}_update(&s, {args}, ({dtype})u[k]);
    }}
}}
"""


def _write_drive(directory: Path, prefix: str, dtype: str, states: int, measures) -> Path:
    path = directory / f"{prefix}_drive.c"
    path.write_text(drive_source(prefix, dtype, states, measures))
    return path


def _as_trace(theta, omega, u) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    arrays = [np.ascontiguousarray(a, dtype=np.float64) for a in (theta, omega, u)]
    if len({a.shape for a in arrays}) != 1 or arrays[0].ndim != 1:
        raise ValueError("theta, omega and u must be 1-D arrays of the same length")
    return arrays[0], arrays[1], arrays[2]


def _outputs(observer) -> tuple:
    from ..observers import as_system

    return as_system(observer).outputs


def _shape(order, observer) -> tuple[int, tuple]:
    """``(states, measures)`` of the exported observer, from ``observer`` or ``order``."""
    if observer is not None:
        from ..observers import as_system

        system = as_system(observer)
        return system.n_states, system.measures
    if order is None:
        raise ValueError("give observer= or order=")
    return order + 1, ("theta", "omega")


class CObserver:
    """An exported observer compiled into a shared library and loaded with ctypes.

    Parameters
    ----------
    header, source : Path
        The files written by :func:`hpdob.export_c`.
    prefix, dtype : str
        As given to :func:`hpdob.export_c`.
    order : int, optional
        The design's truncation order (an order-m observer measuring the state).
    observer : observer-like, optional
        The exported observer; gives the number of states and what it measures. Give
        ``observer`` or ``order``.
    nan_guard : bool, optional
        Whether the export has the NaN guard (``export_c(..., nan_guard=True)``): its state
        struct then also holds ``last``, ``skipped`` and ``fault`` (see :attr:`skipped`,
        :attr:`fault`).
    build_dir : Path
        Where the drive loop and the library are written (use a fresh directory per build:
        the dynamic loader caches libraries by path).
    flags : sequence of str
        Compiler flags; default :data:`STRICT_FLAGS`, ``-O2`` and :data:`EXACT_FLAGS`.
    """

    def __init__(
        self,
        header,
        source,
        *,
        prefix,
        dtype,
        build_dir,
        order=None,
        observer=None,
        flags=None,
        nan_guard=False,
    ):
        states, measures = _shape(order, observer)
        build_dir = Path(build_dir)
        build_dir.mkdir(parents=True, exist_ok=True)
        flags = (*STRICT_FLAGS, "-O2", *EXACT_FLAGS) if flags is None else tuple(flags)
        drive = _write_drive(Path(source).parent, prefix, dtype, states, measures)
        self.library_path = compile_c(
            [source, drive], build_dir / f"lib{prefix}_{dtype}.so", flags=flags, shared=True
        )
        self.order, self.dtype, self.states, self.measures = order, dtype, states, measures
        scalar = ctypes.c_double if dtype == "double" else ctypes.c_float
        self._scalar = scalar
        p = len(measures)

        outputs = 1 if observer is None else len(_outputs(observer))
        guard_fields = [
            ("last", scalar * outputs),
            ("skipped", ctypes.c_uint),
            ("fault", ctypes.c_int),
        ]

        class State(ctypes.Structure):
            _fields_ = [("z", scalar * states), *(guard_fields if nan_guard else [])]

        self._state = State()
        lib = ctypes.CDLL(str(self.library_path))
        pointer = ctypes.POINTER(State)
        self._init = lib[f"{prefix}_init"]
        self._init.argtypes, self._init.restype = [pointer, scalar, scalar, scalar], None
        self._estimate = lib[f"{prefix}_estimate"]
        self._estimate.argtypes, self._estimate.restype = [pointer, *[scalar] * p], scalar
        self._update = lib[f"{prefix}_update"]
        self._update.argtypes, self._update.restype = [pointer, *[scalar] * (p + 1)], None
        self._velocity = None
        if hasattr(lib, f"{prefix}_velocity"):
            self._velocity = lib[f"{prefix}_velocity"]
            self._velocity.argtypes, self._velocity.restype = [pointer, *[scalar] * p], scalar
        double_p = ctypes.POINTER(ctypes.c_double)
        self._drive = lib[f"{prefix}_drive"]
        self._drive.argtypes = [ctypes.c_long, *([double_p] * 6)]
        self._drive.restype = None
        self._ref = ctypes.byref(self._state)

    def init(self, theta0: float, omega0: float, tau0: float) -> None:
        """``<prefix>_init`` on the held state (arguments rounded to the C type).

        Parameters
        ----------
        theta0, omega0 : float
            Initial angle [rad] and velocity [rad/s] of the loop.
        tau0 : float
            Initial disturbance estimate [N m].
        """
        self._init(self._ref, theta0, omega0, tau0)

    def estimate(self, *measurement: float) -> float:
        """``<prefix>_estimate`` of the held state.

        Parameters
        ----------
        *measurement : float
            ``theta`` [rad] and ``omega`` [rad/s], or ``theta`` alone for a position-only
            observer.

        Returns
        -------
        float
            The disturbance estimate [N m], computed in the export's ``dtype``.
        """
        return self._estimate(self._ref, *measurement)

    def velocity(self, *measurement: float) -> float:
        """``<prefix>_velocity`` of the held state (observers that estimate the velocity).

        Parameters
        ----------
        *measurement : float
            As for :meth:`estimate`.

        Returns
        -------
        float
            The velocity estimate [rad/s].

        Raises
        ------
        AttributeError
            If the export has no ``<prefix>_velocity``.
        """
        if self._velocity is None:
            raise AttributeError("this observer exports no velocity estimate")
        return self._velocity(self._ref, *measurement)

    def update(self, *measurement_and_u: float) -> None:
        """``<prefix>_update`` of the held state: advance it by one sample.

        Parameters
        ----------
        *measurement_and_u : float
            ``theta`` [rad], ``omega`` [rad/s] and the torque applied ``u`` [N m], or
            ``theta, u`` for a position-only observer.
        """
        self._update(self._ref, *measurement_and_u)

    @property
    def state(self) -> tuple:
        """The C state ``z`` as Python floats."""
        return tuple(self._state.z)

    @property
    def skipped(self) -> int:
        """``s.skipped`` of a NaN-guarded export: updates skipped since ``init``."""
        return int(self._state.skipped)

    @property
    def fault(self) -> int:
        """``s.fault`` of a NaN-guarded export: 1 if the latest call got a non-finite input."""
        return int(self._state.fault)

    def drive(self, theta, omega, u, *, init=(0.0, 0.0, 0.0)):
        """Run a whole trace through the C observer in a C loop, from ``<prefix>_init(*init)``.

        Parameters
        ----------
        theta, omega, u : array_like
            Angle [rad], velocity [rad/s] and torque applied [N m] at each sample, 1-D of the
            same length ``n`` (``omega`` is ignored by a position-only observer).
        init : tuple of 3 floats, optional
            ``(theta0, omega0, tau0)`` of ``<prefix>_init``. Default zeros.

        Returns
        -------
        tau_hat : ndarray, shape (n,)
            The estimate at each sample [N m].
        z : ndarray, shape (n, states)
            The state each sample started from.

        Raises
        ------
        ValueError
            If the three traces are not 1-D arrays of the same length.
        """
        theta, omega, u = _as_trace(theta, omega, u)
        n = theta.size
        start = np.ascontiguousarray(init, dtype=np.float64)
        tau_hat, z = np.empty(n), np.empty((n, self.states))

        def ptr(a):
            return a.ctypes.data_as(ctypes.POINTER(ctypes.c_double))

        self._drive(n, ptr(start), ptr(theta), ptr(omega), ptr(u), ptr(tau_hat), ptr(z))
        return tau_hat, z
