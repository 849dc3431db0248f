"""The uncertainty ranges of ``hpdob tune``: ``--J-range`` takes ratios of the true to the
nominal inertia, ``--b-range`` absolute viscous frictions (docs/naming.md says why). Values that
look like the other kind are refused with the converted option, instead of a search that
finds "no candidate stable"."""

from __future__ import annotations

from ._errors import CLIError

__all__ = ["check_uncertainty_ranges"]

#: A true/nominal inertia ratio this small (J 90 % below J_n) is taken for an absolute inertia.
SMALLEST_RATIO = 0.1
#: A viscous friction with b / J_n above this [1/s] (a mechanical time constant below 1 ms) in
#: a range of numbers near 1 is taken for a ratio.
LARGEST_DAMPING = 1e3


def check_uncertainty_ranges(J_range, b_range, *, J_n: float, b_n: float) -> None:
    """Refuse a ``--J-range`` of absolute inertias or a ``--b-range`` of ratios, saying what
    the option should read."""
    if J_range is not None and J_n > 0 and max(J_range) < SMALLEST_RATIO:
        low, high = (v / J_n for v in J_range)
        raise CLIError(
            f"--J-range takes ratios of the true to the nominal inertia (e.g. 0.8,1.25); "
            f"{J_range[0]:g},{J_range[1]:g} look like absolute inertias [kg m^2]: with --J-n "
            f"{J_n:g} that is --J-range {low:.4g},{high:.4g}"
        )
    if b_range is None or not all(0.1 <= v <= 10.0 for v in b_range):
        return
    looks_ratio = min(b_range) > 100.0 * b_n if b_n > 0 else min(b_range) / J_n > LARGEST_DAMPING
    if looks_ratio:
        hint = (
            f": with --b-n {b_n:g} that is --b-range {b_range[0] * b_n:.4g},{b_range[1] * b_n:.4g}"
            if b_n > 0
            else " (--b-n is 0, so give them as values)"
        )
        raise CLIError(
            f"--b-range takes absolute viscous frictions [N m s/rad] (b_n may be 0, so not "
            f"ratios); {b_range[0]:g},{b_range[1]:g} look like ratios{hint}"
        )
