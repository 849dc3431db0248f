"""Errors of a nested argument re-raised naming it where the user wrote it (a TOML table's key,
a per-joint entry): ``payload must be ...`` raised inside ``[plant]`` becomes
``plant.payload must be ...``."""

from __future__ import annotations

import re
from contextlib import contextmanager

from .._validation import ParameterTypeError, ParameterValueError

__all__ = ["qualified"]

_NAME = re.compile(r"([A-Za-z_]\w*)((?:\[\d+\])*)(?=[ .])")


@contextmanager
def qualified(where: str, keys=(), renames=None):
    """Re-raise a parameter error from the block with its parameter named inside ``where``.

    A message that starts with one of ``keys`` (or a key of ``renames``, written as its value)
    gets ``where.`` in front of that name; one that already starts with ``where`` is kept; any
    other gets ``where: `` in front. The error keeps its class.
    """
    renames = dict(renames or {})
    try:
        yield
    except (ParameterTypeError, ParameterValueError) as err:
        message = str(err)
        match = _NAME.match(message)
        if message.startswith(where) and (len(message) == len(where)
                                          or message[len(where)] in " .[:"):  # fmt: skip
            raise
        if match and (match[1] in keys or match[1] in renames):
            name = renames.get(match[1], match[1])
            text = f"{where}.{name}{match[2]}{message[match.end() :]}"
        else:
            text = f"{where}: {message}"
        raise type(err)(text) from None
