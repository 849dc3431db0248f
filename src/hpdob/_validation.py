"""Argument validation shared by every public entry point.

Every check raises :class:`TypeError` (wrong kind of object) or :class:`ValueError`
(right kind, wrong value) with a message that names the parameter, shows the value that
was given and says what was expected, e.g.
``J must be a positive finite inertia [kg m^2], got -1.0``.
Checks never modify their input; callers validate everything before changing state.
"""

from __future__ import annotations

import math
import numbers
import operator
from collections.abc import Iterable

import numpy as np

__all__ = [
    "ParameterTypeError",
    "ParameterValueError",
    "as_grid",
    "as_int",
    "as_real",
    "as_real_vector",
    "check_choice",
    "check_keys",
    "nonnegative",
    "numeric_array",
    "positive",
    "readonly",
    "require_instance",
    "shaped_matrix",
]


class _OneLine:
    """Messages on one line: a value's multi-line repr (a 2-D array) is joined."""

    def __init__(self, *args):
        if len(args) == 1 and isinstance(args[0], str) and "\n" in args[0]:
            args = (" ".join(part.strip() for part in args[0].splitlines() if part.strip()),)
        super().__init__(*args)


class ParameterValueError(_OneLine, ValueError):
    """A parameter has an acceptable type but an invalid value (message says which)."""


class ParameterTypeError(_OneLine, TypeError):
    """A parameter has the wrong type (message says which and what was expected)."""


def _show(value: object) -> str:
    """Short repr of ``value`` for error messages (arrays are abbreviated)."""
    if isinstance(value, np.ndarray):
        # one line: messages are printed on one line by the CLI
        text = np.array2string(value, threshold=8, precision=6, max_line_width=1_000_000)
        return " ".join(text.split())  # 2-D arrays print a row per line
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 10**30:
        return _show_int(value)
    try:
        text = " ".join(repr(value).split()) if isinstance(value, (list, tuple)) else repr(value)
    except (ValueError, RecursionError):  # an int over 4300 digits, a very deep nesting
        return f"a {type(value).__name__} that cannot be shown"
    if "\n" in text:  # e.g. the repr of a 2-D array inside a list
        text = " ".join(text.split())
    return text if len(text) <= 80 else text[:77] + "..."


def _show_int(value) -> str:
    """A huge integer in a few characters: its leading digits and its number of digits."""
    digits = str(abs(int(value))) if int(value).bit_length() < 13000 else None
    if digits is None:
        return f"about 2**{int(value).bit_length()}"
    sign = "-" if value < 0 else ""
    if len(digits) <= 30:
        return str(int(value))
    return f"{sign}{digits[0]}.{digits[1:4]}e{len(digits) - 1}"


def as_real(value: object, name: str, what: str = "a real number") -> float:
    """Return ``value`` as a finite Python float.

    Raises
    ------
    TypeError
        If ``value`` is not a real number (``bool`` and strings are rejected).
    ValueError
        If ``value`` is NaN or infinite.
    """
    if isinstance(value, np.ma.MaskedArray) and np.ma.is_masked(value):  # np.ma.masked: no value
        raise ParameterTypeError(f"{name} must be {what}, got a masked value (numpy.ma.masked)")
    # bool is an int, numpy.timedelta64 a numpy integer: neither is a number of hpdob's units
    if isinstance(value, (bool, np.bool_, np.timedelta64)) or not isinstance(value, numbers.Real):
        if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iuf":
            value = value.item()
        else:
            raise ParameterTypeError(
                f"{name} must be {what}, got {_show(value)} of type {type(value).__name__}"
            )
    try:
        result = float(value)
    except OverflowError:  # an integer beyond the float range, e.g. 10**400
        raise ParameterValueError(
            f"{name} must be {what}, got an integer beyond the float range ({_show_int(value)})"
        ) from None
    if not math.isfinite(result):
        raise ParameterValueError(f"{name} must be {what}, got {_show(value)}")
    return result


def positive(value: object, name: str, what: str) -> float:
    """Return ``value`` as a float after checking that it is finite and > 0."""
    result = as_real(value, name, what)
    if result <= 0.0:
        raise ParameterValueError(f"{name} must be {what}, got {_show(value)}")
    return result


def nonnegative(value: object, name: str, what: str) -> float:
    """Return ``value`` as a float after checking that it is finite and >= 0."""
    result = as_real(value, name, what)
    if result < 0.0:
        raise ParameterValueError(f"{name} must be {what}, got {_show(value)}")
    return result


def as_int(
    value: object, name: str, what: str, *, minimum: int | None = None, maximum: int | None = None
) -> int:
    """Return ``value`` as a Python int (``bool`` and floats are rejected).

    ``minimum``/``maximum`` bound it (inclusive); the message of ``maximum`` states the limit.
    """
    if isinstance(value, (bool, np.bool_, np.timedelta64)):
        raise ParameterTypeError(
            f"{name} must be {what}, got {_show(value)} of type {type(value).__name__}"
        )
    try:
        result = operator.index(value)
    except TypeError:
        raise ParameterTypeError(
            f"{name} must be {what}, got {_show(value)} of type {type(value).__name__}"
        ) from None
    if minimum is not None and result < minimum:
        raise ParameterValueError(f"{name} must be {what}, got {_show(result)}")
    if maximum is not None and result > maximum:
        raise ParameterValueError(
            f"{name} must be {what} of at most {maximum}, got {_show(result)}"
        )
    return result


def as_real_vector(
    value: object,
    name: str,
    what: str,
    *,
    length: int | None = None,
) -> np.ndarray:
    """Return ``value`` as a new 1-D float array with finite entries.

    Raises
    ------
    TypeError
        If ``value`` cannot be read as an array of real numbers.
    ValueError
        If it has the wrong shape or a non-finite entry.
    """
    array = numeric_array(value, name, what, dtype=float)
    if array.ndim != 1 or (length is not None and array.shape[0] != length):
        expected = f"shape ({length},)" if length is not None else "a 1-D sequence"
        raise ParameterValueError(
            f"{name} must be {what}: expected {expected}, got shape {array.shape} ({_show(value)})"
        )
    if not np.all(np.isfinite(array)):
        raise ParameterValueError(f"{name} must be {what} with finite entries, got {_show(value)}")
    return array


def _refuse_masked(value: object, name: str, what: str) -> None:
    """A ParameterTypeError for masked entries (numpy would read them as 0.0 or NaN)."""
    if np.ma.is_masked(value) or (
        isinstance(value, (list, tuple)) and any(np.ma.is_masked(v) for v in value)
    ):
        raise ParameterTypeError(f"{name} must be {what}, got masked entries (numpy.ma.masked)")


def numeric_array(value: object, name: str, what: str, *, dtype=float) -> np.ndarray:
    """``value`` as a new numeric array of ``dtype`` (float or complex).

    Strings, bytes, booleans and (for ``dtype=float``) complex numbers are rejected rather
    than parsed or silently truncated.
    """
    if type(value) is np.ndarray and value.dtype == dtype:  # e.g. a matrix hpdob computed:
        return np.array(value, dtype=dtype)  # none of the checks below can refuse it
    if value is None or isinstance(value, (str, bytes)):
        raise ParameterTypeError(
            f"{name} must be {what}, got {_show(value)} of type {type(value).__name__}"
        )
    if isinstance(value, (list, tuple)) and any(isinstance(v, (bool, np.bool_)) for v in value):
        raise ParameterTypeError(f"{name} must be {what}, got {_show(value)} with a bool entry")
    _refuse_masked(value, name, what)
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError):
        raise ParameterTypeError(f"{name} must be {what}, got {_show(value)}") from None
    forbidden = "USVbmM" + ("c" if np.dtype(dtype).kind == "f" else "")  # mM: dates, durations
    if raw.dtype.kind == "O" and any(
        isinstance(v, (np.datetime64, np.timedelta64)) for v in raw.flat
    ):  # a mixed list: numpy would cast the date to a count of days
        raise ParameterTypeError(f"{name} must be {what}, got {_show(value)} with a date entry")
    if raw.dtype.kind in forbidden:
        raise ParameterTypeError(
            f"{name} must be {what}, got {_show(value)} with {raw.dtype.name} entries"
        )
    try:
        return np.array(raw, dtype=dtype)
    except OverflowError:  # an object array holding an integer beyond the float range
        raise ParameterValueError(
            f"{name} must be {what}, got an entry beyond the float range ({_show(value)})"
        ) from None
    except (TypeError, ValueError):
        raise ParameterTypeError(f"{name} must be {what}, got {_show(value)}") from None


def check_choice(value: object, name: str, choices: Iterable[str]) -> str:
    """Return ``value`` if it is one of ``choices``; otherwise list the valid ones."""
    options = list(choices)
    if not isinstance(value, str) or value not in options:
        listed = ", ".join(repr(c) for c in options)
        raise ParameterValueError(f"{name} must be one of {listed}; got {_show(value)}")
    return value


def check_keys(mapping, valid, where: str = "") -> None:
    """Raise if ``mapping`` has a key outside ``valid``, naming it, its value and the valid keys.

    ``where`` qualifies the key (``plant`` gives ``unknown key plant.inertia = 1.0; valid keys
    of plant: J, b, ...``).
    """
    unknown = sorted((k for k in mapping if k not in valid), key=str)
    if unknown:
        key = unknown[0]
        name = f"{where}.{key}" if where else str(key)
        of = f" of {where}" if where else ""
        raise ParameterValueError(
            f"unknown key {name} = {_show(mapping[key])}; valid keys{of}: {', '.join(valid)}"
        )


def require_instance(value, cls, name: str, *, optional: bool = False):
    """Return ``value`` if it is an instance of ``cls`` (a class or tuple of classes).

    ``optional=True`` also accepts None. The error names the accepted classes.
    """
    if value is None and optional:
        return None
    if not isinstance(value, cls):
        names = [c.__name__ for c in (cls if isinstance(cls, tuple) else (cls,))]
        listed = " or ".join(f"{'an' if n[0].lower() in 'aeiou' else 'a'} {n}" for n in names)
        suffix = " or None" if optional else ""
        raise ParameterTypeError(f"{name} must be {listed}{suffix}, got {type(value).__name__}")
    return value


def readonly(array: np.ndarray) -> np.ndarray:
    """Mark ``array`` read-only and return it (immutable results hold read-only arrays)."""
    array.setflags(write=False)
    return array


def shaped_matrix(value, name: str, shape: tuple, *, empty: bool = False) -> np.ndarray:
    """A finite real matrix of ``shape`` as a new read-only array (a 1-D row or column is
    reshaped; with ``empty``, an empty value for a shape with a zero dimension too)."""
    array = numeric_array(value, name, f"a real matrix of shape {shape}", dtype=float)
    if (empty and array.size == 0 and 0 in shape) or (
        array.ndim == 1 and len(shape) == 2 and 1 in shape
    ):
        array = array.reshape(shape)
    if array.shape != shape:
        raise ParameterValueError(f"{name} must have shape {shape}, got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ParameterValueError(f"{name} must have finite entries, got {_show(array)}")
    return readonly(array)


def as_grid(
    values, name: str, what: str, *, allow_zero: bool = False, increasing: bool = False
) -> np.ndarray:
    """A non-empty 1-D grid of finite values > 0 (>= 0 with ``allow_zero``), as a new array.

    With ``increasing=True`` the grid must also be strictly increasing (maps and boundaries
    are drawn along it).
    """
    _refuse_masked(values, name, what)
    grid = as_real_vector(np.atleast_1d(values), name, what)
    if grid.size == 0:
        raise ParameterValueError(f"{name} must hold at least one value ({what}), got []")
    bad = grid[grid < 0] if allow_zero else grid[grid <= 0]
    if bad.size:
        raise ParameterValueError(f"{name} must be {what}, got {float(bad[0])!r} in {name}")
    if increasing and np.any(np.diff(grid) <= 0):
        raise ParameterValueError(f"{name} must be strictly increasing, got {_show(grid)}")
    return grid
