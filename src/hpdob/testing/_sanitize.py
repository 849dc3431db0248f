"""Run an exported C observer under AddressSanitizer and UndefinedBehaviorSanitizer.

:func:`sanitized_run` builds the drive loop of :class:`hpdob.testing.CObserver` with a
``main`` that reads the trace from a file, under ``-fsanitize=address,undefined``, and runs
it as a subprocess: any out-of-bounds access, use of uninitialised memory the sanitizers see,
signed overflow or leak fails the run.
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import numpy as np

from ._c_harness import (
    STRICT_FLAGS,
    CBuildError,
    _as_trace,
    _shape,
    _write_drive,
    compile_c,
    find_compiler,
)

__all__ = ["SANITIZE_FLAGS", "sanitized_run", "sanitizer_available"]

SANITIZE_FLAGS = (
    "-O2",
    "-g",
    "-fsanitize=address,undefined",
    "-fno-sanitize-recover=all",
    "-fno-omit-frame-pointer",
)

_MAIN = """\
#include <stdio.h>
#include <stdlib.h>

void {prefix}_drive(long n, const double *init, const double *theta, const double *omega,
                    const double *u, double *tau_hat, double *z);

/* usage: drive IN OUT. IN: n (int64), init[3], theta[n], omega[n], u[n] (float64);
   OUT: tau_hat[n], z[n * {n}] (float64). */
int main(int argc, char **argv)
{{
    FILE *in;
    FILE *out;
    long long count = 0;
    size_t n, ok;
    double init[3];
    double *buf;
    if (argc != 3 || (in = fopen(argv[1], "rb")) == NULL) {{
        return 2;
    }}
    if (fread(&count, sizeof count, 1, in) != 1 || count <= 0
        || fread(init, sizeof(double), 3, in) != 3) {{
        fclose(in);
        return 3;
    }}
    n = (size_t)count;
    buf = (double *)malloc(sizeof(double) * n * (4 + {n}));
    if (buf == NULL) {{
        fclose(in);
        return 4;
    }}
    ok = fread(buf, sizeof(double), 3 * n, in);
    fclose(in);
    if (ok != 3 * n) {{
        free(buf);
        return 5;
    }}
    {prefix}_drive((long)n, init, buf, buf + n, buf + 2 * n, buf + 3 * n, buf + 4 * n);
    out = fopen(argv[2], "wb");
    if (out == NULL) {{
        free(buf);
        return 6;
    }}
    ok = fwrite(buf + 3 * n, sizeof(double), n * (1 + {n}), out);
    fclose(out);
    free(buf);
    return ok == n * (1 + {n}) ? 0 : 7;
}}
"""


def sanitizer_available(directory: Path) -> str | None:
    """Whether :func:`sanitized_run` can work here: a probe program is built and run.

    Parameters
    ----------
    directory : str or Path
        Where the probe is written (created if missing).

    Returns
    -------
    str or None
        None if a ``-fsanitize=address,undefined`` build links and runs, else the reason it
        does not (no compiler, no sanitizer runtime, ...): a message to skip a test with.

    Examples
    --------
    >>> import tempfile
    >>> from hpdob.testing import sanitizer_available
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     reason = sanitizer_available(tmp)
    >>> reason is None or isinstance(reason, str)
    True
    """
    if find_compiler() is None:
        return "no C compiler found"
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    probe = directory / "probe.c"
    probe.write_text("int main(void) { return 0; }\n")
    try:
        exe = compile_c([probe], directory / "probe", flags=SANITIZE_FLAGS)
    except CBuildError as err:
        return f"the sanitizer runtime cannot be linked: {err}"
    done = subprocess.run([str(exe)], capture_output=True, text=True, check=False)
    if done.returncode != 0:
        return f"a sanitized program cannot run here: {done.stderr.strip()[:200]}"
    return None


def sanitized_run(
    source,
    *,
    prefix,
    dtype,
    build_dir,
    theta,
    omega,
    u,
    order=None,
    observer=None,
    init=(0.0, 0.0, 0.0),
):
    """Build the drive loop under ASan + UBSan (``-O2``) and run a trace through it.

    The exported ``source`` is compiled with :data:`STRICT_FLAGS` and :data:`SANITIZE_FLAGS`
    together with the drive loop of :meth:`CObserver.drive` and a ``main`` that reads the
    trace from a file; the program runs as a subprocess, with leak detection on.

    Parameters
    ----------
    source : str or Path
        The ``<prefix>.c`` written by :func:`hpdob.export_c` (its header next to it).
    prefix, dtype : str
        As given to :func:`hpdob.export_c`.
    build_dir : str or Path
        Where the program and the trace files are written (created if missing).
    theta, omega, u : array_like
        The trace, as for :meth:`CObserver.drive`.
    order : int, optional
        The design's truncation order (an order-m observer measuring the state).
    observer : observer-like, optional
        The exported observer (gives its states and measurements); give ``observer`` or
        ``order``.
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
    CBuildError
        If the build fails or the program exits non-zero or prints anything (every sanitizer
        finding is fatal: ``-fno-sanitize-recover=all``).
    ValueError
        If neither ``observer`` nor ``order`` is given, or the traces differ in length.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from hpdob import design_observer, export_c, paper
    >>> from hpdob.testing import sanitized_run, sanitizer_available
    >>> design = design_observer(paper.NOMINAL.discretize(paper.TS), order=1, bandwidth=100.0)
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     _, source = export_c(design, tmp, prefix="dob")
    ...     if sanitizer_available(Path(tmp, "probe")) is None:  # else nothing is checked
    ...         tau_hat, z = sanitized_run(source, prefix="dob", dtype="double",
    ...                                    build_dir=Path(tmp, "build"), theta=[0.0] * 5,
    ...                                    omega=[0.0] * 5, u=[1e-3] * 5, observer=design)
    ...         assert tau_hat.shape == (5,) and z.shape == (5, 2)
    """
    build_dir = Path(build_dir)
    build_dir.mkdir(parents=True, exist_ok=True)
    theta, omega, u = _as_trace(theta, omega, u)
    n = theta.size
    states, measures = _shape(order, observer)
    drive = _write_drive(Path(source).parent, prefix, dtype, states, measures)
    main = build_dir / f"{prefix}_main.c"
    main.write_text(_MAIN.format(prefix=prefix, n=states))
    exe = compile_c(
        [source, drive, main],
        build_dir / f"{prefix}_sanitized",
        flags=(*STRICT_FLAGS, *SANITIZE_FLAGS),
    )
    inputs, outputs = build_dir / "trace.bin", build_dir / "result.bin"
    with open(inputs, "wb") as f:
        f.write(np.int64(n).tobytes())
        f.write(np.ascontiguousarray(init, dtype=np.float64).tobytes())
        for a in (theta, omega, u):
            f.write(a.tobytes())
    env = dict(os.environ)
    env["ASAN_OPTIONS"] = "detect_leaks=1:abort_on_error=0:halt_on_error=1"
    env["UBSAN_OPTIONS"] = "print_stacktrace=1:halt_on_error=1"
    done = subprocess.run(
        [str(exe), str(inputs), str(outputs)], capture_output=True, text=True, env=env, check=False
    )
    if done.returncode != 0 or done.stdout or done.stderr:
        raise CBuildError(
            f"sanitized drive of {prefix} exited with {done.returncode}:\n"
            f"{done.stdout}{done.stderr}"
        )
    data = np.fromfile(outputs, dtype=np.float64)
    return data[:n], data[n:].reshape(n, states)
