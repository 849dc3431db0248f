"""Compact tables for notebooks: what Jupyter shows for a design or a result
(``_repr_markdown_``, as python-control's systems show theirs)."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["fmt", "markdown_table"]


def fmt(value) -> str:
    """A value as a table shows it: 4 significant digits, arrays abbreviated."""
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return "–" if not math.isfinite(value) and math.isnan(value) else f"{float(value):.4g}"
    if isinstance(value, (complex, np.complexfloating)):
        return f"{complex(value):.4g}".strip("()")
    if isinstance(value, (tuple, list, np.ndarray)):
        items = [fmt(v) for v in list(np.asarray(value, dtype=object).ravel())]
        shown = items if len(items) <= 6 else [*items[:5], "…"]
        return "[" + ", ".join(shown) + "]"
    return str(value)


def markdown_table(title: str, rows) -> str:
    """``title`` in bold over a two-column table of ``(name, value)`` rows; None values left out."""
    lines = [f"**{title}**", "", "| | |", "|---|---|"]
    for name, value in rows:
        if value is None:
            continue
        text = fmt(value).replace("|", "\\|")
        lines.append(f"| {name} | {text} |")
    return "\n".join(lines) + "\n"
