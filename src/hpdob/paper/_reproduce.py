"""``hpdob reproduce``: the paper's Figs. 2-5 from the canonical scenario, in one call."""

from __future__ import annotations

from .._files import check_output, staged_outputs
from .._interrupts import checkpoint
from ..simulation import metrics_json
from ._scenario import RUNS, run

__all__ = ["reproduce", "summary_table"]

METRIC_UNITS = {
    "rms_estimation_error": "N m",
    "rms_position_error_regulation": "rad",
    "rms_position_error_tracking": "rad",
}


def summary_table(metrics: dict) -> str:
    """Fixed-width text table of the metrics of several runs.

    Parameters
    ----------
    metrics : dict
        ``{run name: SimulationResult.metrics()}``: each value has the keys
        ``rms_estimation_error``, ``rms_position_error_regulation`` and
        ``rms_position_error_tracking``.

    Returns
    -------
    str
        A header naming each metric with its unit, a rule, and one line per run (values in
        ``%.4e``), what ``hpdob reproduce`` prints.

    Raises
    ------
    KeyError
        If a run's metrics lack one of the three keys.

    Examples
    --------
    >>> from hpdob import paper
    >>> metrics = paper.run("HPDOb-100", duration=2.0).metrics()
    >>> header, rule, row = paper.summary_table({"HPDOb-100": metrics}).splitlines()
    >>> header.split()[:4], row.split()[0]
    (['run', 'rms_estimation_error', '[N', 'm]'], 'HPDOb-100')
    """
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
    "virtual-experiment-position": {...}}``. The files are written to temporary names and
    renamed when all are complete, ``metrics.json`` last: a failed or interrupted call leaves
    the previous complete set, or files without ``metrics.json`` (``docs/reliability.md``).

    Parameters
    ----------
    out_dir : str or os.PathLike, optional
        Output directory, created if missing. Default ``"hpdob-results"``.
    figures : bool, optional
        Draw and write Figs. 2-5 (matplotlib, ~5 s). Default True.

    Returns
    -------
    dict
        ``{run name: SimulationResult}``.

    Raises
    ------
    OSError
        If ``out_dir`` cannot be created or written (the previous files are kept).

    Examples
    --------
    >>> import json, tempfile
    >>> from pathlib import Path
    >>> from hpdob import paper
    >>> with tempfile.TemporaryDirectory() as out:
    ...     results = paper.reproduce(out, figures=False)
    ...     metrics = json.loads(Path(out, "metrics.json").read_text())
    >>> list(metrics) == list(paper.RUNS) == list(results)
    True
    """
    out = check_output(out_dir, name="out_dir")  # before the runs, not after them
    results = {name: run(name) for name in RUNS}
    metrics = {name: res.metrics() for name, res in results.items()}
    # Every file is staged and renamed when all are complete, metrics.json last: an
    # interrupted or failed run leaves the previous complete set or no metrics.json.
    with staged_outputs(out, markers=["metrics.json"]) as files:
        for name, res in results.items():
            res.to_csv(files.path(f"traces/{name}.csv"))
        checkpoint("reproduce-staged")  # a test hook (traces staged, not committed); no-op
        if figures:
            import matplotlib

            matplotlib.use("Agg")  # files only; never needs a display
            import matplotlib.pyplot as plt

            from ._figures import paper_figures

            for name, fig in paper_figures(results).items():
                try:
                    files.save_figure(f"{name}.png", fig, dpi=200)
                    # the PDF keeps the PNG's constrained layout instead of solving it again
                    # (its positions differ by < 0.2 % of the figure; the data are the same)
                    fig.set_layout_engine("none")
                    files.save_figure(f"{name}.pdf", fig)
                finally:
                    plt.close(fig)
        files.write_text("metrics.json", metrics_json(metrics))
    return results
