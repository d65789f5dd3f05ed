"""The figure of a held-out prediction (:class:`bmr.identification.prediction.Prediction`): per run, the measured
and predicted output against the input with the single-valued baseline, and the residuals along the run."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from bmr import plot

__all__ = ["prediction_figure"]

MAX_RUNS = 8


def prediction_figure(prediction: Any, path: Path) -> Path:
    """Write the PNG to ``path``: one row per run (at most ``MAX_RUNS``), loop on the left, residual on the
    right, in the declared units."""
    q = prediction.quantities
    runs = prediction.runs[:MAX_RUNS]
    with plot.style():
        fig, axes = plot.figure("panel3", nrows=len(runs), ncols=2, height=2.6 * len(runs) + 0.6, squeeze=False)
        for row, r in zip(axes, runs):
            ax, ax_r = row
            ev = r.evaluated
            u, y, yhat, base = plot.thin(r.input, r.output, r.predicted, r.baseline)
            few = r.input.size <= 400
            # Measured drawn wide underneath: where the prediction is right it shows as a grey halo.
            ax.plot(u, y, "o-" if few else "-", ms=4, color=plot.COLORS["measured"], lw=2.0, label="measured")
            ax.plot(u, base, "--", color=plot.COLORS["alternative"], label="single-valued baseline")
            ax.plot(u, yhat, ".-" if few else "-", ms=3, color=plot.COLORS["model"], label="predicted")
            ax.set(xlabel=q.input.label, ylabel=q.output.label)
            ax.set_title(f"{r.name}: output against input", loc="left")
            # The model's residual on its own scale (the baseline's, often 100x larger, is in the title).
            t = r.time - r.time[0]
            e = np.where(ev, r.residual, np.nan)
            t, e = plot.thin(t, e)
            ax_r.axhline(0.0, color="0.4", lw=0.6)
            ax_r.plot(t, e, ".-" if few else "-", ms=3, color=plot.COLORS["model"], label="residual (measured - predicted)")
            st = r.stats(prediction.output_span)
            ax_r.set(xlabel="time (s)", ylabel=f"residual ({q.output.unit})")
            ax_r.set_title(f"{r.name}: residual, RMS {q.output.format(st['rms'])} (baseline "
                           f"{q.output.format(st['baseline_rms'])})", loc="left")
        handles, labels = axes[0][0].get_legend_handles_labels()
        h2, l2 = axes[0][1].get_legend_handles_labels()
        fig.legend(handles + h2, labels + l2, loc="outside upper center", ncol=5, frameon=False)
        if len(prediction.runs) > MAX_RUNS:
            fig.suptitle(f"first {MAX_RUNS} of {len(prediction.runs)} runs", y=0.0, va="bottom")
    return plot.save(fig, path)
