"""A minimal reader of 32-bit little-endian ELF files (ARM objects and executables).

Enough to load an executable's segments into an emulator, to find its functions, and to list
an object file's symbols (defined and undefined) and section sizes, without binutils.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

__all__ = ["ElfFile", "ElfSymbol", "read_elf"]

_PT_LOAD = 1
_SHT_SYMTAB = 2
_SHF_ALLOC = 0x2


@dataclass(frozen=True)
class ElfSymbol:
    """One symbol of an ELF file.

    Parameters
    ----------
    name : str
    value : int
        Address (executables) or offset in its section (objects).
    size : int
        Size [bytes].
    kind : int
        ``STT_*`` type: 0 none, 1 object, 2 function.
    defined : bool
        False for a reference to a symbol of another file.
    """

    name: str
    value: int
    size: int
    kind: int
    defined: bool


@dataclass(frozen=True)
class ElfFile:
    """The parts of an ELF32 file an emulator and a symbol check need.

    Parameters
    ----------
    segments : tuple of (int, bytes, int)
        Loadable segments: address, contents, size in memory.
    sections : dict
        ``{name: (size, flags)}``.
    symbols : tuple of ElfSymbol
    """

    segments: tuple
    sections: dict
    symbols: tuple

    def symbol(self, name: str) -> ElfSymbol:
        """The defined symbol ``name``.

        Parameters
        ----------
        name : str

        Returns
        -------
        ElfSymbol

        Raises
        ------
        KeyError
            If the file defines no such symbol.
        """
        for s in self.symbols:
            if s.name == name and s.defined:
                return s
        raise KeyError(name)

    def undefined(self) -> list[str]:
        """Names of the symbols the file uses but does not define.

        Returns
        -------
        list of str
            Sorted.
        """
        return sorted({s.name for s in self.symbols if not s.defined and s.name})

    def allocated_size(self, prefixes=(".text", ".rodata", ".data")) -> int:
        """Bytes of the loaded sections whose name starts with one of ``prefixes``.

        Parameters
        ----------
        prefixes : tuple of str, optional
            Default code, constants and data (``.text``, ``.rodata``, ``.data``).

        Returns
        -------
        int
        """
        return sum(size for name, (size, flags) in self.sections.items()
                   if flags & _SHF_ALLOC and name.startswith(tuple(prefixes)))  # fmt: skip


def read_elf(path) -> ElfFile:
    """Read ``path`` (an ELF32 little-endian file).

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    ElfFile

    Raises
    ------
    ValueError
        If the file is not a 32-bit little-endian ELF file.
    """
    data = Path(path).read_bytes()
    if data[:4] != b"\x7fELF" or data[4] != 1 or data[5] != 1:
        raise ValueError(f"{str(path)!r} is not a 32-bit little-endian ELF file")
    phoff, shoff = struct.unpack_from("<II", data, 28)
    phentsize, phnum, shentsize, shnum, shstrndx = struct.unpack_from("<HHHHH", data, 42)
    segments = []
    for i in range(phnum):
        kind, offset, vaddr, _, filesz, memsz, _, _ = struct.unpack_from(
            "<8I", data, phoff + i * phentsize
        )
        if kind == _PT_LOAD:
            segments.append((vaddr, data[offset : offset + filesz], memsz))
    headers = [struct.unpack_from("<10I", data, shoff + i * shentsize) for i in range(shnum)]

    def string(table: int, offset: int) -> str:
        start = headers[table][4] + offset
        return data[start : data.index(b"\0", start)].decode("ascii", "replace")

    sections, symbols = {}, []
    for h in headers:
        if shnum and shstrndx < shnum:
            sections[string(shstrndx, h[0])] = (h[5], h[2])
        if h[1] == _SHT_SYMTAB:
            for j in range(h[5] // 16):
                name, value, size, info, _, shndx = struct.unpack_from(
                    "<IIIBBH", data, h[4] + j * 16
                )
                symbols.append(ElfSymbol(string(h[6], name), value, size, info & 15, shndx != 0))
    return ElfFile(tuple(segments), sections, tuple(symbols))
