"""Build one sample loop with ``numba.pycc`` (run as ``python -m hpdob.simulation._aot_compile
FOLDER`` by :func:`hpdob.simulation.build_loop_extension`, in a process of its own).

``FOLDER`` holds ``spec.json`` (the extension's module name, the source module's name and the
argument types, :func:`hpdob.simulation._aot.argument_types`) and the loop's source module;
the extension is written there as ``<name>.so`` (``.pyd`` on Windows). The C compiler is the
one ``setuptools`` finds (``CC``, else the platform's); ``build_loop_extension(compiler=...)``
sets ``CC`` to this file run as a script with ``--driver``, which runs ``$HPDOB_AOT_CC`` on C
sources and for the link and ``$HPDOB_AOT_CXX`` on C++ sources (numba's runtime, ``nrt.cpp``:
``zig cc`` finds no C++ headers, ``zig c++`` does). ``numba.pycc`` is pending deprecation
(numba's deprecation notices, since 0.57): its ``NumbaPendingDeprecationWarning`` is expected
here and silenced, the build itself is unchanged.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib
import json
import os
import shlex
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

#: The C and C++ compiler commands the ``--driver`` runs, the folder of object files it keeps
#: and the environment they were compiled in.
C_VARIABLE, CXX_VARIABLE = "HPDOB_AOT_CC", "HPDOB_AOT_CXX"
OBJECTS_VARIABLE, ENVIRONMENT_VARIABLE = "HPDOB_AOT_OBJECTS", "HPDOB_AOT_ENVIRONMENT"


def driver(arguments) -> int:
    """Run the C++ compiler on a C++ source, the C compiler on a C source and for the link
    (numba's runtime uses only header-only parts of the C++ library: linking it, which
    ``zig c++`` builds from source on its first use, is not needed).

    With ``$HPDOB_AOT_OBJECTS`` set, a compile of one source reuses the object file of an
    earlier compile of the same text with the same command and flags in the same environment
    (``$HPDOB_AOT_ENVIRONMENT``: numba's, numpy's and Python's versions, whose headers the
    sources include): numba's own C sources are the same in every build, and compiling them is
    most of a build's time.
    """
    cxx = "-c" in arguments and any(a.endswith((".cpp", ".cxx", ".cc")) for a in arguments)
    command = shlex.split(os.environ[CXX_VARIABLE if cxx else C_VARIABLE])
    objects = os.environ.get(OBJECTS_VARIABLE)
    sources = [a for a in arguments if a.endswith((".c", ".cpp", ".cxx", ".cc"))]
    if not objects or "-c" not in arguments or "-o" not in arguments or len(sources) != 1:
        return subprocess.run([*command, *arguments], check=False).returncode
    at = arguments.index("-o")
    output, source = Path(arguments[at + 1]), Path(sources[0])
    body = source.read_bytes()
    # pycc defines the module's name for every source; only its module mixin reads it (a
    # wrong object would name the module wrongly: its import fails, simulate runs the JIT)
    flags = [
        a
        for i, a in enumerate(arguments)
        if i not in (at, at + 1)
        and a != sources[0]
        and not (a.startswith("-DPYCC_MODULE_NAME=") and b"PYCC_MODULE_NAME" not in body)
    ]
    text = json.dumps([command, flags, source.name, os.environ.get(ENVIRONMENT_VARIABLE, "")])
    key = hashlib.sha256(text.encode() + b"\0" + body).hexdigest()[:32]
    kept = Path(objects, f"{key}.o")
    try:
        shutil.copyfile(kept, output)
        return 0
    except OSError:  # not kept (or removed meanwhile: another environment's build pruned it)
        pass
    code = subprocess.run([*command, *arguments], check=False).returncode
    if code == 0:  # kept atomically: a reader sees a whole object file or none
        temporary = kept.with_name(f"{key}.{os.getpid()}.tmp")
        try:  # a cache: a failure to keep it fails no build
            kept.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(output, temporary)
            os.replace(temporary, kept)
        except OSError:
            with contextlib.suppress(OSError):
                temporary.unlink()
    return code


def numba_type(described):
    """The numba type of one entry of :func:`hpdob.simulation._aot.argument_types`."""
    import numba
    import numpy as np

    if isinstance(described, str):
        return {"int64": numba.types.int64, "int32": numba.types.int32,
                "float64": numba.types.float64, "bool": numba.types.boolean}[described]  # fmt: skip
    _, dtype, ndim, layout, readonly = described
    return numba.types.Array(
        numba.from_dtype(np.dtype(dtype)), ndim, layout, readonly=bool(readonly)
    )


def main(folder: str) -> None:
    import numba
    from numba.core.errors import NumbaPendingDeprecationWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumbaPendingDeprecationWarning)
        from numba.pycc import CC

    spec = json.loads(Path(folder, "spec.json").read_text(encoding="utf-8"))
    sys.path.insert(0, folder)
    module = importlib.import_module(spec["source_module"])
    types = [numba_type(t) for t in spec["types"]]
    cc = CC(spec["name"], source_module=module)
    cc.output_dir = folder
    cc.output_file = spec["file"]
    cc.export("run", numba.types.int64(*types))(module.run)
    cc.compile()


if __name__ == "__main__":
    if sys.argv[1] == "--driver":
        sys.exit(driver(sys.argv[2:]))
    main(sys.argv[1])
