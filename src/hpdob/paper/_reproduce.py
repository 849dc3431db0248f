"""``hpdob reproduce``: the paper's Figs. 2-5 from the canonical scenario, in one call."""

from __future__ import annotations

from pathlib import Path

from ..simulation._result import metrics_json
from ._scenario import RUNS, run

__all__ = ["reproduce", "summary_table"]

METRIC_UNITS = {
    "rms_estimation_error": "N m",
    "rms_position_error_regulation": "rad",
    "rms_position_error_tracking": "rad",
}


def summary_table(metrics: dict) -> str:
    """Fixed-width table of ``{run: metrics}``."""
    names = list(METRIC_UNITS)
    width = max(20, *(len(name) + 1 for name in metrics))
    header = f"{'run':<{width}}" + "".join(f"{n + ' [' + METRIC_UNITS[n] + ']':>36}" for n in names)
    lines = [header, "-" * len(header)]
    for name, values in metrics.items():
        lines.append(f"{name:<{width}}" + "".join(f"{values[n]:>36.4e}" for n in names))
    return "\n".join(lines)


def reproduce(out_dir="hpdob-results", *, figures: bool = True) -> dict:
    """Run the canonical runs and write figures, traces and metrics into ``out_dir``.

    Writes ``fig2.png`` ... ``fig5.png`` (and ``.pdf``), ``traces/<run>.csv`` and
    ``metrics.json`` ``{"PD": {...}, "DOb-50": {...}, ..., "virtual-experiment": {...},
    "virtual-experiment-position": {...}}``.

    Returns
    -------
    dict
        ``{run name: SimulationResult}``.
    """
    out = Path(out_dir)
    (out / "traces").mkdir(parents=True, exist_ok=True)
    results = {name: run(name) for name in RUNS}
    metrics = {name: res.metrics() for name, res in results.items()}
    for name, res in results.items():
        res.to_csv(out / "traces" / f"{name}.csv")
    (out / "metrics.json").write_text(metrics_json(metrics))
    if figures:
        import matplotlib

        matplotlib.use("Agg")  # files only; never needs a display
        import matplotlib.pyplot as plt

        from ._figures import paper_figures

        for name, fig in paper_figures(results).items():
            fig.savefig(out / f"{name}.png", dpi=200)
            fig.savefig(out / f"{name}.pdf")
            plt.close(fig)
    return results
