"""The observer as an FMI 2.0 co-simulation FMU (for Simulink, OpenModelica, Dymola, fmpy).

:func:`export_fmu` writes ``<model_identifier>.fmu``: a zip with ``modelDescription.xml`` (the
inputs, outputs, the design's parameters as constants and its provenance), the generated
double C of :func:`hpdob.export_c` with a small FMI wrapper under ``sources/``, and that code
built for the host platform under ``binaries/<platform>/``. The library is compiled with
``zig cc`` (the ``ziglang`` package) when it is installed, else with ``$CC``/``cc``, always
without floating-point contraction so that it reproduces the Python observer bit for bit.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import uuid
import zipfile
from pathlib import Path
from xml.sax.saxutils import escape, quoteattr

from .._files import atomic_path
from .._validation import ParameterTypeError, ParameterValueError
from .._version import __version__
from ..observers import as_system
from ._c import check_prefix, render_c
from ._fmu_wrapper import fmi2_wrapper

__all__ = ["FMUBuildError", "export_fmu", "fmu_platform"]

#: Flags of the FMU's library build: exact IEEE double arithmetic (no contraction).
FMU_FLAGS = ("-std=c99", "-O2", "-ffp-contract=off", "-fPIC", "-shared")


class FMUBuildError(RuntimeError):
    """The C compiler for the FMU's binary is missing or failed (one-line message)."""


def fmu_platform() -> str:
    """The FMI 2.0 platform folder of this machine (``linux64``, ``darwin64``, ``win64``...).

    Returns
    -------
    str

    Raises
    ------
    FMUBuildError
        On a platform FMI 2.0 has no folder name for.
    """
    bits = "64" if sys.maxsize > 2**32 else "32"
    system = platform.system()
    names = {"Linux": "linux", "Darwin": "darwin", "Windows": "win"}
    if system not in names:
        raise FMUBuildError(f"compiler: FMI 2.0 names no binaries folder for {system!r}")
    return names[system] + bits


def _compiler(compiler) -> list[str]:
    if compiler is not None:
        if not isinstance(compiler, (list, tuple)) or not all(isinstance(c, str) for c in compiler):
            raise ParameterTypeError(
                f"compiler must be None or a list of str (a command, e.g. ['gcc']), got "
                f"{compiler!r}"
            )
        if not compiler or shutil.which(compiler[0]) is None:
            raise FMUBuildError(f"compiler {list(compiler)!r} was not found on PATH")
        return list(compiler)
    if importlib.util.find_spec("ziglang") is not None:
        return [sys.executable, "-m", "ziglang", "cc"]
    cc = shutil.which(os.environ.get("CC", "cc"))
    if cc is None:
        raise FMUBuildError(
            "compiler: no C compiler to build the FMU's binary: pip install ziglang (or "
            "'hpdob[test]'), or set CC"
        )
    return [cc]


def _variables(system) -> list[dict]:
    """The model variables with their value references (FMI: 1-based index in the list)."""
    variables = [
        {"name": "theta", "causality": "input", "unit": "rad", "description": "angle",
         "start": 0.0},
    ]  # fmt: skip
    if len(system.measures) == 2:
        variables.append({"name": "omega", "causality": "input", "unit": "rad/s",
                          "description": "measured velocity", "start": 0.0})  # fmt: skip
    variables.append({"name": "u", "causality": "input", "unit": "N.m",
                      "description": "torque applied at this sample", "start": 0.0})  # fmt: skip
    variables.append({"name": "tau_hat", "causality": "output", "unit": "N.m",
                      "description": "disturbance estimate"})  # fmt: skip
    if system.has_velocity:
        variables.append({"name": "omega_hat", "causality": "output", "unit": "rad/s",
                          "description": "velocity estimate"})  # fmt: skip
    if "tau_reac" in system.outputs:
        variables.append({"name": "tau_reac", "causality": "output", "unit": "N.m",
                          "description": "reaction-torque estimate"})  # fmt: skip
    variables.append({"name": "tau0", "causality": "parameter", "unit": "N.m", "start": 0.0,
                      "description": "disturbance the observer is initialised with (at rest "
                      "at the first theta, omega)"})  # fmt: skip
    constants = [("Ts", system.Ts, "s", "sampling period the observer was designed for")]
    model = system.model
    if model is not None:
        constants += [("J_n", model.J, "kg.m2", "nominal inertia"),
                      ("b_n", model.b, "N.m.s/rad", "nominal viscous friction")]  # fmt: skip
    if system.truncation_order is not None:
        constants.append(("order", float(system.truncation_order), "1", "truncation order m"))
    for name, value, unit, note in constants:
        variables.append({"name": name, "causality": "local", "variability": "constant",
                          "unit": unit, "start": float(value), "description": note})  # fmt: skip
    for i, v in enumerate(variables):
        v["vr"] = i
    return variables


def _model_description(system, identifier: str, variables, guid: str, sources) -> str:
    units = sorted({v["unit"] for v in variables})
    unit_defs = "\n".join(f"    <Unit name={quoteattr(u)}/>" for u in units)
    lines = []
    for v in variables:
        attrs = [f"name={quoteattr(v['name'])}", f'valueReference="{v["vr"]}"',
                 f"description={quoteattr(v['description'])}",
                 f'causality="{v["causality"]}"']  # fmt: skip
        if v["causality"] == "input":
            attrs.append('variability="continuous"')
            real = f'<Real unit={quoteattr(v["unit"])} start="{v["start"]!r}"/>'
        elif v["causality"] == "output":
            attrs += ['variability="continuous"', 'initial="calculated"']
            real = f"<Real unit={quoteattr(v['unit'])}/>"
        elif v["causality"] == "parameter":
            attrs += ['variability="fixed"', 'initial="exact"']
            real = f'<Real unit={quoteattr(v["unit"])} start="{v["start"]!r}"/>'
        else:
            attrs += ['variability="constant"', 'initial="exact"']
            real = f'<Real unit={quoteattr(v["unit"])} start="{v["start"]!r}"/>'
        lines.append(f"    <ScalarVariable {' '.join(attrs)}>\n      {real}\n    </ScalarVariable>")
    inputs = [v for v in variables if v["causality"] == "input" and v["name"] != "u"]
    deps = " ".join(str(v["vr"] + 1) for v in inputs)  # outputs feed through from measures
    outputs = "\n".join(
        f'      <Unknown index="{v["vr"] + 1}" dependencies="{deps}"/>'
        for v in variables if v["causality"] == "output")  # fmt: skip
    info = list(system.info) or [("observer", system.name)]
    annotations = "\n".join(f"        <Design key={quoteattr(k)} value={quoteattr(str(val))}/>"
                            for k, val in info)  # fmt: skip
    source_list = "\n".join(f'        <File name="{name}"/>' for name in sources)
    description = f"{system.name} exported by hpdob {__version__}: " + "; ".join(
        f"{k}: {val}" for k, val in info)  # fmt: skip
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription
  fmiVersion="2.0"
  modelName={quoteattr(identifier)}
  guid="{guid}"
  description={quoteattr(description)}
  generationTool="hpdob {escape(__version__)}"
  variableNamingConvention="flat"
  numberOfEventIndicators="0">
  <CoSimulation
    modelIdentifier={quoteattr(identifier)}
    canHandleVariableCommunicationStepSize="true"
    canInterpolateInputs="false"
    canBeInstantiatedOnlyOncePerProcess="false"
    canNotUseMemoryManagementFunctions="false"
    canGetAndSetFMUstate="false"
    canSerializeFMUstate="false">
    <SourceFiles>
{source_list}
    </SourceFiles>
  </CoSimulation>
  <UnitDefinitions>
{unit_defs}
  </UnitDefinitions>
  <DefaultExperiment startTime="0.0" stepSize="{system.Ts!r}"/>
  <VendorAnnotations>
    <Tool name="hpdob">
      <Observer name={quoteattr(system.name)} version={quoteattr(__version__)}>
{annotations}
      </Observer>
    </Tool>
  </VendorAnnotations>
  <ModelVariables>
{chr(10).join(lines)}
  </ModelVariables>
  <ModelStructure>
    <Outputs>
{outputs}
    </Outputs>
    <InitialUnknowns>
{outputs}
    </InitialUnknowns>
  </ModelStructure>
</fmiModelDescription>
"""


def export_fmu(obs, path, *, model_identifier: str = "dob", compiler=None) -> Path:
    r"""Write the observer as an FMI 2.0 co-simulation FMU built for this machine.

    Inputs ``theta`` [rad] (and ``omega`` [rad/s] for an observer measuring it) and ``u``
    [N m]; outputs ``tau_hat`` [N m] (and ``omega_hat`` [rad/s] for observers estimating
    it, ``tau_reac`` [N m] for a reaction-torque observer,
    :func:`hpdob.observers.reaction_torque_observer`); parameter ``tau0`` [N m]; the
    design's ``Ts``, ``J_n``, ``b_n`` and order as constants, its summary in
    ``VendorAnnotations`` and the description. Use a communication step equal to ``Ts``: at
    each communication point set the inputs, read the outputs (the estimate of that sample),
    then ``doStep`` applies the observer's update.

    Parameters
    ----------
    obs : observer-like
        Any hpdob observer (design or runtime object); only its design is exported.
    path : str or os.PathLike
        The ``.fmu`` file to write (replaced atomically; its directory must exist).
    model_identifier : str, optional
        The FMU's model identifier and the C prefix: a C identifier as for
        :func:`hpdob.export_c`. Default ``"dob"``.
    compiler : list of str, optional
        C compiler command for the binary. Default: ``zig cc`` of the ``ziglang`` package if
        installed, else ``$CC`` or ``cc``.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    TypeError, ValueError
        For a bad observer, ``path`` (not ending in ``.fmu``, a directory, a missing parent)
        or ``model_identifier``. Nothing is written then.
    FMUBuildError
        If no compiler is found or the build fails (one line; nothing is written).

    Examples
    --------
    >>> import tempfile, zipfile
    >>> from pathlib import Path
    >>> from hpdob import ServoModel, design_observer
    >>> from hpdob.export import export_fmu
    >>> design = design_observer(ServoModel(J=2.8e-4).discretize(1e-3), order=1,
    ...                          bandwidth=100.0)
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     fmu = export_fmu(design, Path(tmp, "hpdob.fmu"), model_identifier="hpdob1")
    ...     names = zipfile.ZipFile(fmu).namelist()
    >>> "modelDescription.xml" in names and "sources/hpdob1.c" in names
    True
    """
    system = as_system(obs, "obs")
    identifier = check_prefix(model_identifier)
    if not isinstance(path, (str, os.PathLike)):
        raise ParameterTypeError(f"path must be a path (str or os.PathLike), got {path!r}")
    path = Path(path)
    if path.suffix != ".fmu":
        raise ParameterValueError(f"path must end in .fmu, got {str(path)!r}")
    if path.is_dir():
        raise ParameterValueError(f"path {str(path)!r} is an existing directory")
    if not path.parent.is_dir():
        raise ParameterValueError(f"path's directory {str(path.parent)!r} does not exist")
    cc = _compiler(compiler)
    plat = fmu_platform()
    header, source = render_c(system, prefix=identifier, dtype="double")
    digest = hashlib.sha256((header + source).encode("ascii")).hexdigest()
    guid = "{" + str(uuid.uuid5(uuid.NAMESPACE_URL, f"hpdob:{digest}")) + "}"
    variables = _variables(system)
    wrapper = fmi2_wrapper(system, identifier, variables, guid)
    files = {f"{identifier}.h": header, f"{identifier}.c": source,
             f"fmi2_{identifier}.c": wrapper}  # fmt: skip
    suffix = {"linux": ".so", "darwin": ".dylib", "win": ".dll"}[plat.rstrip("0123456789")]
    with tempfile.TemporaryDirectory() as tmp:
        for name, text in files.items():
            Path(tmp, name).write_text(text, encoding="ascii")
        library = Path(tmp, identifier + suffix)
        sources = [str(Path(tmp, f"{identifier}.c")), str(Path(tmp, f"fmi2_{identifier}.c"))]
        libm = ["-lm"] if system.coulomb is not None else []  # the Coulomb term's tanh
        cmd = [*cc, *FMU_FLAGS, "-o", str(library), *sources, *libm]
        try:
            done = subprocess.run(cmd, capture_output=True, text=True, check=False)
        except OSError as err:
            raise FMUBuildError(f"compiler {cc[0]!r} could not be run: {err}") from None
        if done.returncode != 0:
            first = (done.stderr or done.stdout).strip().splitlines()[:1]
            raise FMUBuildError(
                f"compiler {' '.join(cc)} failed to build the FMU binary: "
                f"{first[0] if first else 'exit code ' + str(done.returncode)}"
            )
        description = _model_description(system, identifier, variables, guid, list(files)[1:])
        with (
            atomic_path(path) as temporary,
            zipfile.ZipFile(temporary, "w", zipfile.ZIP_DEFLATED) as fmu,
        ):
            fmu.writestr("modelDescription.xml", description)
            for name, text in files.items():
                fmu.writestr(f"sources/{name}", text)
            fmu.write(library, f"binaries/{plat}/{identifier}{suffix}")
    return path
