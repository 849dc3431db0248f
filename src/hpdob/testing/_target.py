"""Build exported C for a Cortex-M with ``zig cc`` and run it on an emulated CPU (``unicorn``).

Both tools install from PyPI (``ziglang``, ``unicorn``; the ``test`` extra of hpdob), so the
check that generated fixed-point code computes, on the target's instruction set, exactly what
:class:`hpdob.export.FixedPointObserver` computes runs on any machine. Also here: the host
build of the same drive loop (ctypes), the one the long traces use.

The drive loop's interface is the same on every build::

    void <prefix>_drive(int32_t n, const int32_t *in, int32_t *out);
    void <prefix>_step(<prefix>_state *s, const <T> *in, <T> *out);

``in`` holds ``init[3]`` followed by ``count, omega, u`` for each of ``n`` samples; ``out``
receives, per sample, the outputs and then the state the sample started from. ``_step`` runs
one ``estimate`` (+ ``velocity``) and ``update``: what the instruction count measures; for a
reaction-torque observer composition ``estimates`` (``tau_hat`` and ``tau_reac`` in one call)
replaces ``estimate``.
"""

from __future__ import annotations

import ctypes
import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np

from ._c_harness import CBuildError, compile_c, find_compiler
from ._elf import read_elf

__all__ = [
    "CPUS",
    "EmulatedCortexM",
    "HostFixedObserver",
    "cross_compile",
    "fixed_drive_source",
    "float_step_source",
    "zig_cc",
]

#: Cortex-M cores: name -> (zig -mcpu, unicorn CPU model name). The Cortex-M0+ shares the
#: ARMv6-M instruction set with the M0, which is the model unicorn offers.
CPUS = {
    "cortex-m0plus": ("cortex_m0plus", "UC_CPU_ARM_CORTEX_M0"),
    "cortex-m3": ("cortex_m3", "UC_CPU_ARM_CORTEX_M3"),
}
TARGET = "thumb-freestanding-eabi"  # soft float: no FPU instructions, helpers from compiler-rt
FLASH, RAM, DATA = 0x0000_0000, 0x2000_0000, 0x3000_0000
_SIZE = 1 << 20
_RETURN = 0x000F_FF00  # an address in flash that no code occupies: emulation stops there
_LINKER_SCRIPT = f"""\
MEMORY {{ FLASH (rx) : ORIGIN = {FLASH:#x}, LENGTH = 1M
         RAM (rwx) : ORIGIN = {RAM:#x}, LENGTH = 512K }}
SECTIONS {{
  .text : {{ *(.text*) *(.rodata*) }} > FLASH
  .data : {{ *(.data*) }} > RAM
  .bss : {{ *(.bss*) *(COMMON) }} > RAM
}}
"""
TARGET_FLAGS = ("-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Wconversion", "-Wshadow",
                "-Werror", "-ffreestanding", "-fno-unwind-tables",
                "-fno-asynchronous-unwind-tables")  # fmt: skip


def zig_cc() -> list[str]:
    """The command of ``zig cc`` from the ``ziglang`` package.

    Returns
    -------
    list of str
        ``[python, "-m", "ziglang", "cc"]``.

    Raises
    ------
    CBuildError
        If ``ziglang`` is not installed (one line saying how to install it).
    """
    if importlib.util.find_spec("ziglang") is None:
        raise CBuildError(
            "the zig compiler is missing: pip install ziglang (or pip install 'hpdob[test]')"
        )
    return [sys.executable, "-m", "ziglang", "cc"]


def _run(cmd: list[str]) -> None:
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if done.returncode != 0 or done.stderr.strip():
        raise CBuildError(f"{' '.join(cmd)} failed:\n{done.stdout}{done.stderr}")


def cross_compile(sources, output, *, cpu: str, optimize: str = "-O2", link: bool = True,
                  flags=TARGET_FLAGS) -> Path:  # fmt: skip
    """Compile ``sources`` for a Cortex-M with ``zig cc`` (soft float, freestanding).

    Parameters
    ----------
    sources : sequence of path
    output : path
        An executable ELF image linked for flash at 0 and RAM at 0x20000000 (no start-up
        code: the emulator calls functions); with ``link=False`` the object file of one
        source, or the existing directory that receives ``<source stem>.o`` for each of
        several sources.
    cpu : {"cortex-m0plus", "cortex-m3"}
    optimize : str, optional
        Optimisation flag, default ``-O2``.
    link : bool, optional
        Link an executable (default) or only compile.
    flags : sequence of str, optional
        Warning and language flags; default :data:`TARGET_FLAGS` (warnings are errors).

    Returns
    -------
    pathlib.Path

    Raises
    ------
    CBuildError
        If zig is missing or the build reports an error or a warning.
    """
    if cpu not in CPUS:
        raise ValueError(f"cpu must be one of {', '.join(CPUS)}, got {cpu!r}")
    output = Path(output)
    cmd = [*zig_cc(), "-target", TARGET, f"-mcpu={CPUS[cpu][0]}", optimize, *flags]
    if link:
        script = output.with_suffix(".ld")
        script.write_text(_LINKER_SCRIPT)
        # zig links compiler-rt (64-bit and soft-float helpers) and no libc for freestanding;
        # every function is kept (the emulator calls them, nothing references them)
        cmd += ["-Wl,-e,0", "-Wl,--no-gc-sections", f"-Wl,-T,{script}"]
        _run(cmd + [str(s) for s in sources] + ["-o", str(output)])
    elif len(sources) == 1:
        _run([*cmd, "-c", str(sources[0]), "-o", str(output)])
    else:  # one run per file: zig cc -c writes only the first of several objects
        for source in sources:
            _run([*cmd, "-c", str(source), "-o", str(output / (Path(source).stem + ".o"))])
    return output


def fixed_drive_source(design, prefix: str) -> str:
    """C source of ``<prefix>_drive`` and ``<prefix>_step`` for a fixed-point export.

    Parameters
    ----------
    design : FixedPointDesign
        The exported design.
    prefix : str
        The export's prefix.

    Returns
    -------
    str
        C99 (the interface is in the module docstring).
    """
    system = design.system
    n, q = system.n_states, len(system.outputs)
    word = f"int{design.bits}_t"
    args = "c, w" if design.measures_omega else "c"
    outs = [f"{prefix}_estimate(s, {args})"]
    if system.has_velocity:
        outs.append(f"{prefix}_velocity(s, {args})")
    step_outs = "".join(f"    out[{r}] = {e};\n" for r, e in enumerate(outs))
    if "tau_reac" in system.outputs:  # both estimates through the one call
        r = system.outputs.index("tau_reac")
        step_outs = step_outs.replace(
            f"    out[0] = {outs[0]};\n",
            f"    {prefix}_estimates(s, {args}, &out[0], &out[{r}]);\n")  # fmt: skip
    unused = "" if design.measures_omega else "    (void)w;\n"
    return f"""\
#include <stdint.h>
#include "{prefix}.h"

void {prefix}_step({prefix}_state *s, const int32_t *in, int32_t *out);
void {prefix}_drive(int32_t n, const int32_t *in, int32_t *out);

void {prefix}_step({prefix}_state *s, const int32_t *in, int32_t *out)
{{
    const int32_t c = in[0], w = in[1], u = in[2];
{unused}{step_outs}    {prefix}_update(s, {args}, u);
}}

void {prefix}_drive(int32_t n, const int32_t *in, int32_t *out)
{{
    {prefix}_state state;
    {prefix}_state *s = &state;
    int32_t k;
    int i;
    {prefix}_init(s, in[0], in[1], in[2]);
    for (k = 0; k < n; ++k) {{
        int32_t *o = out + k * {q + n};
        for (i = 0; i < {n}; ++i) {{
            o[{q} + i] = ({word})s->q[i];
        }}
        {prefix}_step(s, in + 3 + 3 * k, o);
    }}
}}
"""


def float_step_source(prefix: str, dtype: str, measures, *, velocity: bool = False) -> str:
    """C source of ``<prefix>_step`` for a float/double export (for instruction counts).

    Parameters
    ----------
    prefix : str
        The export's prefix.
    dtype : {"float", "double"}
    measures : tuple of str
        The observer's measures: ``in`` holds them followed by ``u``.
    velocity : bool, optional
        Also call ``<prefix>_velocity`` (into ``out[1]``). Default False.

    Returns
    -------
    str
    """
    args = "in[0], in[1]" if len(measures) == 2 else "in[0]"
    u = "in[2]" if len(measures) == 2 else "in[1]"
    extra = f"    out[1] = {prefix}_velocity(s, {args});\n" if velocity else ""
    return f"""\
#include "{prefix}.h"

void {prefix}_step({prefix}_state *s, const {dtype} *in, {dtype} *out);

void {prefix}_step({prefix}_state *s, const {dtype} *in, {dtype} *out)
{{
    out[0] = {prefix}_estimate(s, {args});
{extra}    {prefix}_update(s, {args}, {u});
}}
"""


def _pack(design, counts, omega, u, init) -> tuple[np.ndarray, int]:
    arrays = [np.asarray(a, dtype=np.int64) for a in (counts, omega, u)]
    if len({a.shape for a in arrays}) != 1 or arrays[0].ndim != 1:
        raise ValueError("counts, omega and u must be 1-D arrays of the same length")
    if any(a.size and (a.min() < -(2**31) or a.max() >= 2**31) for a in arrays):
        raise ValueError("counts, omega and u must be int32 values")
    data = np.concatenate([np.asarray(init, dtype=np.int64), np.column_stack(arrays).ravel()])
    return np.ascontiguousarray(data, dtype=np.int32), arrays[0].size


def _unpack(design, out: np.ndarray, n: int):
    q, ns = len(design.system.outputs), design.system.n_states
    out = out.reshape(n, q + ns).astype(np.int64)
    return out[:, :q], out[:, q:]


class HostFixedObserver:
    """A fixed-point export built for the host (``gcc``/``$CC``, else ``zig cc``) and
    driven through ctypes.

    Parameters
    ----------
    design : FixedPointDesign
    source : Path
        ``<prefix>.c`` written by :func:`hpdob.export_c` (its header beside it).
    prefix : str
    build_dir : Path
        Fresh directory for the drive loop and the library.
    flags : sequence of str, optional
        Compiler flags; default strict warnings as errors and ``-O2``.
    """

    def __init__(self, design, source, *, prefix: str, build_dir, flags=None):
        build_dir = Path(build_dir)
        build_dir.mkdir(parents=True, exist_ok=True)
        drive = Path(source).parent / f"{prefix}_drive.c"
        drive.write_text(fixed_drive_source(design, prefix))
        flags = ("-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Wconversion", "-Wshadow",
                 "-Werror", "-O2") if flags is None else tuple(flags)  # fmt: skip
        library = build_dir / f"lib{prefix}_fixed.so"
        if find_compiler() is not None:
            compile_c([source, drive], library, flags=flags, shared=True)
        else:
            _run([*zig_cc(), *flags, "-shared", "-fPIC", str(source), str(drive), "-o",
                  str(library)])  # fmt: skip
        self.design = design
        lib = ctypes.CDLL(str(library))
        self._drive = lib[f"{prefix}_drive"]
        pointer = ctypes.POINTER(ctypes.c_int32)
        self._drive.argtypes = [ctypes.c_int32, pointer, pointer]
        self._drive.restype = None

    def drive(self, counts, omega, u, *, init=(0, 0, 0)):
        """Run a trace in C from ``<prefix>_init(*init)``.

        Parameters
        ----------
        counts, omega, u : array_like of int, shape (n,)
            The integer inputs (int32).
        init : tuple of 3 int, optional
            ``(count0, omega0, tau0)``.

        Returns
        -------
        outputs : ndarray, shape (n, n_outputs)
        states : ndarray, shape (n, n_states)
        """
        data, n = _pack(self.design, counts, omega, u, init)
        out = np.zeros(n * (len(self.design.system.outputs) + self.design.system.n_states),
                       dtype=np.int32)  # fmt: skip
        pointer = ctypes.POINTER(ctypes.c_int32)
        self._drive(n, data.ctypes.data_as(pointer), out.ctypes.data_as(pointer))
        return _unpack(self.design, out, n)


class EmulatedCortexM:
    """An executable ELF image (from :func:`cross_compile`) on unicorn's Cortex-M model.

    Parameters
    ----------
    elf : Path
        The linked image.
    cpu : {"cortex-m0plus", "cortex-m3"}
        The core to emulate (the M0+ runs on unicorn's Cortex-M0 model: same ISA).

    Raises
    ------
    CBuildError
        If ``unicorn`` is not installed (one line saying how to install it).
    """

    def __init__(self, elf, *, cpu: str):
        if importlib.util.find_spec("unicorn") is None:
            raise CBuildError(
                "the unicorn emulator is missing: pip install unicorn (or pip install "
                "'hpdob[test]')"
            )
        import unicorn
        from unicorn import arm_const

        if cpu not in CPUS:
            raise ValueError(f"cpu must be one of {', '.join(CPUS)}, got {cpu!r}")
        self.image = read_elf(elf)
        self._uc = unicorn
        self._arm = arm_const
        mu = unicorn.Uc(unicorn.UC_ARCH_ARM, unicorn.UC_MODE_THUMB | unicorn.UC_MODE_MCLASS)
        mu.ctl_set_cpu_model(getattr(arm_const, CPUS[cpu][1]))
        for base in (FLASH, RAM, DATA):
            mu.mem_map(base, _SIZE)
        for address, data, _ in self.image.segments:
            mu.mem_write(address, data)
        self.mu = mu
        self.cpu = cpu
        self.instructions = 0

    def call(self, function: str, *args: int, count: bool = False) -> int:
        """Call ``function`` with up to four integer/pointer arguments.

        Parameters
        ----------
        function : str
            A function of the image.
        *args : int
            Its arguments (in ``r0``-``r3``).
        count : bool, optional
            Set ``self.instructions`` to the number of instructions executed: the call's own
            and those of every helper it calls (e.g. ``__aeabi_lmul``). Default False.

        Returns
        -------
        int
            ``r0`` on return.
        """
        mu, arm = self.mu, self._arm
        registers = (arm.UC_ARM_REG_R0, arm.UC_ARM_REG_R1, arm.UC_ARM_REG_R2, arm.UC_ARM_REG_R3)
        for reg, value in zip(registers, args, strict=False):
            mu.reg_write(reg, value & 0xFFFFFFFF)
        mu.reg_write(arm.UC_ARM_REG_SP, RAM + _SIZE - 64)
        mu.reg_write(arm.UC_ARM_REG_LR, _RETURN | 1)
        hook = None
        executed = [0]
        if count:

            def tick(*_):
                executed[0] += 1

            hook = mu.hook_add(self._uc.UC_HOOK_CODE, tick)
            mu.ctl_flush_tb()  # blocks translated before the hook existed would not count
        try:
            mu.emu_start(self.image.symbol(function).value | 1, _RETURN)
        finally:
            if hook is not None:
                mu.hook_del(hook)
                mu.ctl_flush_tb()
        self.instructions = executed[0]
        return mu.reg_read(arm.UC_ARM_REG_R0)

    def write(self, address: int, array: np.ndarray) -> None:
        """Copy ``array``'s bytes to emulated memory.

        Parameters
        ----------
        address : int
        array : ndarray
        """
        self.mu.mem_write(address, np.ascontiguousarray(array).tobytes())

    def read(self, address: int, count: int, dtype) -> np.ndarray:
        """Values from emulated memory.

        Parameters
        ----------
        address : int
        count : int
            Number of values.
        dtype : numpy dtype

        Returns
        -------
        ndarray
        """
        size = np.dtype(dtype).itemsize * count
        return np.frombuffer(bytes(self.mu.mem_read(address, size)), dtype=dtype).copy()

    def drive_fixed(self, design, prefix: str, counts, omega, u, *, init=(0, 0, 0)):
        """``<prefix>_drive`` of a fixed-point image over a trace.

        Parameters
        ----------
        design : FixedPointDesign
        prefix : str
        counts, omega, u, init
            As for :meth:`HostFixedObserver.drive`.

        Returns
        -------
        outputs : ndarray, shape (n, n_outputs)
        states : ndarray, shape (n, n_states)
        """
        data, n = _pack(design, counts, omega, u, init)
        width = len(design.system.outputs) + design.system.n_states
        if data.nbytes + 4 * n * width > _SIZE:
            raise ValueError(f"trace too long for the emulated memory ({n} samples)")
        self.write(DATA, data)
        out_address = DATA + ((data.nbytes + 7) // 8) * 8
        self.call(f"{prefix}_drive", n, DATA, out_address)
        return _unpack(design, self.read(out_address, n * width, np.int32), n)

    def step_instructions(self, prefix: str, samples, *, state_size: int, dtype) -> np.ndarray:
        """Instructions executed by ``<prefix>_step`` for each sample.

        Parameters
        ----------
        prefix : str
        samples : sequence of tuples
            The ``in`` array of each call.
        state_size : int
            Bytes of ``<prefix>_state`` (zeroed once; the arithmetic branches only in the
            saturation tests, so the count hardly varies with the values).
        dtype : numpy dtype
            Type of ``in`` (int32 for fixed point, float32 for a float export).

        Returns
        -------
        ndarray of int
            Instructions per call.
        """
        state, buffer, out = DATA, DATA + 1024, DATA + 2048
        self.write(state, np.zeros(state_size, dtype=np.uint8))
        counts = []
        for sample in samples:
            self.write(buffer, np.asarray(sample, dtype=dtype))
            self.call(f"{prefix}_step", state, buffer, out, count=True)
            counts.append(self.instructions)
        return np.array(counts)
