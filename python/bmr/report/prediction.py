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
    """Write the PNG to ``path``: one row per run (at most ``MAX_RUNS``), loop on the left (less a straight line
    when the loop is thin), residual on the right, in the declared units."""
    q = prediction.quantities
    runs = prediction.runs[:MAX_RUNS]
    # A thin loop (hysteresis a few % of the span, as in magnets) is invisible on the full scale: draw every output
    # less the straight line through the ends of the single-valued baseline instead.
    width = max(float(np.nanmax(np.abs((r.measured - r.baseline)[r.scored]), initial=0.0)) for r in runs)
    thin_loop = width < 0.05 * prediction.span
    u_all = np.concatenate([r.input for r in runs])
    b_all = np.concatenate([r.baseline for r in runs])
    i_lo, i_hi = int(np.argmin(u_all)), int(np.argmax(u_all))
    slope = (b_all[i_hi] - b_all[i_lo]) / (u_all[i_hi] - u_all[i_lo]) if u_all[i_hi] > u_all[i_lo] else 0.0

    def line(u: np.ndarray) -> np.ndarray:
        return b_all[i_lo] + slope * (u - u_all[i_lo]) if thin_loop else np.zeros_like(u)

    with plot.style():
        fig, axes = plot.figure("panel3", nrows=len(runs), ncols=2, height=2.6 * len(runs) + 0.6, squeeze=False)
        for row, r in zip(axes, runs):
            ax, ax_r = row
            trend = line(r.input)
            u, y, yhat, base = plot.thin(r.input, r.measured - trend, r.predicted - trend, r.baseline - trend)
            few = r.input.size <= 400
            if few:  # sparse logs (a few samples per reversal): points, joined by faint lines in time order
                ax.plot(u, y, "o-", ms=5, lw=0.5, color=plot.COLORS["measured"], label="measured")
                ax.plot(u, base, "x", ms=5, color=plot.COLORS["alternative"], label="single-valued baseline")
                ax.plot(u, yhat, ".-", ms=5, lw=0.5, color=plot.COLORS["model"], label="predicted")
            else:  # measured drawn wide underneath: where the prediction is right it shows as a grey halo
                ax.plot(u, y, "-", lw=2.0, color=plot.COLORS["measured"], label="measured")
                ax.plot(u, base, "--", color=plot.COLORS["alternative"], label="single-valued baseline")
                ax.plot(u, yhat, "-", color=plot.COLORS["model"], label="predicted")
            ylabel = f"{q.output.name} − straight line ({q.output.unit})" if thin_loop else q.output.label
            ax.set(xlabel=q.input.label, ylabel=ylabel)
            ax.set_title(f"{r.name}: output against input", loc="left")
            # The model's residual on its own scale (the baseline's, often 100x larger, is in the title).
            t = r.time - r.time[0]
            e = r.residual
            t, e = plot.thin(t, e)
            ax_r.axhline(0.0, color="0.4", lw=0.6)
            ax_r.plot(t, e, ".-" if few else "-", ms=3, color=plot.COLORS["model"],
                      label="residual (measured - predicted)")
            st = r.stats()
            ax_r.set(xlabel="time (s)", ylabel=f"residual ({q.output.unit})")
            ax_r.set_title(f"{r.name}: residual, RMS {q.output.format(st['rms'])} (baseline "
                           f"{q.output.format(st['baseline_rms'])})", loc="left")
        handles, labels = axes[0][0].get_legend_handles_labels()
        h2, l2 = axes[0][1].get_legend_handles_labels()
        fig.legend(handles + h2, labels + l2, loc="outside upper center", ncol=5, frameon=False)
        if len(prediction.runs) > MAX_RUNS:
            fig.suptitle(f"first {MAX_RUNS} of {len(prediction.runs)} runs", y=0.0, va="bottom")
    return plot.save(fig, path)
