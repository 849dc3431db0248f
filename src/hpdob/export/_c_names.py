"""Names and places of exported C: the prefix (a C identifier, not a standard header) and
the output directory."""

from __future__ import annotations

import os
import re
from pathlib import Path

from .._validation import ParameterTypeError, ParameterValueError

__all__ = ["MAX_PREFIX", "STANDARD_HEADERS"]

#: Longest prefix: ``<prefix>_estimate`` then stays within the 31 significant characters
#: C99 (5.2.4.1) guarantees for external identifiers.
MAX_PREFIX = 31 - len("_estimate")
_IDENTIFIER = re.compile(r"[A-Za-z][A-Za-z0-9_]*\Z")
#: The standard headers of C99 (7.1.2) and C11: a prefix equal to one of them (in any case, for
#: case-insensitive file systems) would write e.g. ``math.h`` and shadow the system header for
#: every file of the firmware compiled with ``-I`` on the output directory.
STANDARD_HEADERS = (
    "assert", "complex", "ctype", "errno", "fenv", "float", "inttypes", "iso646", "limits",
    "locale", "math", "setjmp", "signal", "stdarg", "stdbool", "stddef", "stdint", "stdio",
    "stdlib", "string", "tgmath", "time", "wchar", "wctype",
    "stdalign", "stdatomic", "stdnoreturn", "threads", "uchar",
)  # fmt: skip


def check_prefix(prefix) -> str:
    if not isinstance(prefix, str):
        raise ParameterTypeError(
            f"prefix must be a str (a C identifier such as 'dob'), got {prefix!r} of type "
            f"{type(prefix).__name__}"
        )
    if not _IDENTIFIER.match(prefix):
        raise ParameterValueError(
            "prefix must be a C identifier starting with a letter (letters, digits and "
            f"underscores only, e.g. 'dob' or 'axis1_dob'), got {prefix!r}"
        )
    if prefix.lower() in STANDARD_HEADERS:
        raise ParameterValueError(
            f"prefix {prefix!r} would write {prefix}.h, which shadows the C standard header "
            f"<{prefix.lower()}.h>; choose another prefix, e.g. 'dob' or '{prefix}_dob'"
        )
    if len(prefix) > MAX_PREFIX:
        raise ParameterValueError(
            f"prefix must have at most {MAX_PREFIX} characters so that "
            f"'{prefix}_estimate' stays within C99's 31 significant characters, "
            f"got {prefix!r} ({len(prefix)} characters)"
        )
    return prefix


def check_directory(directory) -> Path:
    if not isinstance(directory, (str, os.PathLike)):
        raise ParameterTypeError(
            f"directory must be a path (str or os.PathLike), got {type(directory).__name__}"
        )
    path = Path(directory)
    if path.exists() and not path.is_dir():
        raise ParameterValueError(f"directory must be a directory, got the file {str(path)!r}")
    return path
