"""Deployment: an observer as dependency-free C99 for a microcontroller.

export_c, render_c
    Write (or return the text of) ``<prefix>.h`` and ``<prefix>.c``.
"""

from ._c import export_c, render_c

__all__ = ["export_c", "render_c"]
