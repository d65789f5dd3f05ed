"""The paper's figures (11-25) redrawn from measured (simulated) data, one PNG each.

Axes and units as in the paper: torque in N·mm, current in the paper's units of 0.125 A (±10 units = ±1.25 A)
where the paper plots current, time in s, angle in rad.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from bmr import plot
from bmr.plot import COLORS, legend_outside, reference_line, thin

CURRENT_UNIT_A = 0.125
"""The paper plots current in units of its converter gain (0.125 A per volt)."""


def _evaluated(run: Any) -> slice:
    fs = 1.0 / np.median(np.diff(run.t[:100]))
    return slice(int(round(run.meta.get("opening_end_s", 0.0) * fs)), None)


def paper_figures(out: Path, bundle: Any, model: Any, cases: dict[str, Any]) -> dict[str, Path]:
    """Draw every figure into ``out`` (one PNG each, bmr style); returns ``{key: path}``."""
    with plot.style():
        return _draw(out, bundle, model, cases)


def _draw(out: Path, bundle: Any, model: Any, cases: dict[str, Any]) -> dict[str, Path]:
    figs: dict[str, Path] = {}

    def save(fig: Any, name: str, key: str) -> None:
        figs[key] = plot.save(fig, out / name)

    friction = model.friction
    off = bundle.by_kind("off_state")[0]
    sl = _evaluated(off)
    t, tq, th = off.t[sl], off.torque[sl], off.theta[sl]

    fig, ax = plot.figure("wide")
    ax.plot(*thin(t - t[0], tq), lw=0.6, color=COLORS["model"])
    ax.set(xlabel="Time (s)", ylabel="Torque (N·mm)", title="Fig 11: off-state torque (zero current, motor on)")
    save(fig, "fig11_off_state.png", "fig11")

    fig, ax = plot.figure("wide")
    wrapped = np.mod(th, 2 * np.pi)
    a, b = thin(wrapped, tq)
    ax.plot(a, b, ".", ms=1.5, alpha=0.4, color=COLORS["measured"], label="measured")
    grid = np.linspace(0, 2 * np.pi, 400)
    if friction is not None:
        ax.plot(grid, friction(grid), color=COLORS["nominal"], lw=1.5, label=f"identified (order {friction.order})")
    ax.set(xlabel="Rotor angle (rad)", ylabel="Torque (N·mm)", title="Fig 12: off-state torque vs identified friction")
    legend_outside(ax)
    save(fig, "fig12_friction.png", "fig12")

    ms = bundle.by_kind("multi_step")[0]
    sl = _evaluated(ms)
    fig, ax = plot.figure("tall")
    t, tq = ms.t[sl], ms.torque[sl]
    removed = tq - model.friction_torque(ms.theta[sl])
    x, y1, y2, cur = thin(t - t[0], tq, removed, ms.current[sl])
    h1 = ax.plot(x, y1, lw=0.5, color=COLORS["alternative"], label="measured torque")[0]
    h2 = ax.plot(x, y2, lw=0.7, color=COLORS["model"], label="torque, friction excluded")[0]
    ax2 = ax.twinx()
    h3 = ax2.plot(x, cur / CURRENT_UNIT_A, color="k", lw=0.6, alpha=0.5, label="current (right axis)")[0]
    ax2.set_ylabel("Current (×0.125 A)")
    ax2.grid(False)
    ax.set(xlabel="Time (s)", ylabel="Torque (N·mm)")
    ax.set_title("Fig 13: multi-step current, with/without friction", pad=22)
    legend_outside(ax, [h1, h2, h3])
    save(fig, "fig13_multi_step.png", "fig13")

    asc, desc = model.hysteresis.curves()
    for key, fam, title in (("fig14", asc, "Fig 14: first-order ascending torque curves"),
                            ("fig15", desc, "Fig 15: first-order descending torque curves")):
        fig, ax = plot.figure("square")
        kind = "first_order_ascending" if key == "fig14" else "first_order_descending"
        runs = bundle.by_kind(kind)
        if runs:
            r = runs[0]
            s = _evaluated(r)
            x, y = thin(r.current[s], r.torque[s] - model.friction_torque(r.theta[s]))
            ax.plot(x / CURRENT_UNIT_A, y, ".", ms=1, color=COLORS["measured"], label="measured, friction excluded")
        for i, (u, y) in enumerate(fam):
            ax.plot(np.asarray(u) / CURRENT_UNIT_A, y, lw=0.9,
                    label=f"identified curves ({len(fam)})" if i == 0 else "_nolegend_")
        ax.set(xlabel="Current (×0.125 A)", ylabel="Torque (N·mm)")
        ax.set_title(title, pad=22)
        legend_outside(ax)
        save(fig, f"{key}_{'ascending' if key == 'fig14' else 'descending'}_torque_curves.png", key)
    # The paper's current curves are the torque curves with their axes swapped (eq 17-20).
    for key, fam, title in (("fig16", asc, "Fig 16: first-order ascending current curves"),
                            ("fig17", desc, "Fig 17: first-order descending current curves")):
        fig, ax = plot.figure("square")
        for u, y in fam:
            ax.plot(y, np.asarray(u) / CURRENT_UNIT_A, lw=0.9)
        ax.set(xlabel="Torque (N·mm)", ylabel="Current (×0.125 A)", title=title)
        save(fig, f"{key}_{'ascending' if key == 'fig16' else 'descending'}_current_curves.png", key)

    c0 = cases["triangle_current_without_friction_compensation"]
    c1 = cases["triangle_current_with_friction_compensation"]
    fig, ax = plot.figure("wide")
    ax.plot(*thin(c0.t, c0.reference_nmm / (c0.reference_nmm.max() / (0.9 * 10.0))), lw=0.8,
            color=COLORS["reference"])
    ax.set(xlabel="Time (s)", ylabel="Nominal current (×0.125 A)", title="Fig 18: triangular nominal current")
    save(fig, "fig18_triangle_current.png", "fig18")

    fig, ax = plot.figure("tall")
    x, y0, y1, r = thin(c0.t, c0.torque, c1.torque, c0.reference_nmm)
    ax.plot(x, y0, lw=0.6, color=COLORS["nominal"],
            label=f"without friction compensation (RMS error {c0.metrics['rms_nmm']:.1f} N·mm)")
    ax.plot(x, y1, lw=0.6, color=COLORS["model"],
            label=f"with friction compensation (RMS error {c1.metrics['rms_nmm']:.1f} N·mm)")
    reference_line(ax, x, r, label="linear-map torque")
    ax.set(xlabel="Time (s)", ylabel="Torque (N·mm)")
    ax.set_title("Fig 19: response to the triangular current", pad=22)
    legend_outside(ax, ncol=2)
    save(fig, "fig19_triangle_response.png", "fig19")

    c = cases["triangle_hysteresis_compensation"]
    fig, ax = plot.figure("tall")
    x, y, r = thin(c.t, c.torque, c.reference_nmm)
    ax.plot(x, y, lw=0.6, color=COLORS["model"], label=f"response (RMS error {c.metrics['rms_nmm']:.1f} N·mm)")
    reference_line(ax, x, r)
    ax.set(xlabel="Time (s)", ylabel="Torque (N·mm)")
    ax.set_title("Fig 21: triangle reference, hysteresis compensation", pad=22)
    legend_outside(ax)
    save(fig, "fig21_triangle_tracking.png", "fig21")

    fig, ax = plot.figure("square")
    ax.plot(r, y, lw=0.5, color=COLORS["model"])
    lim = [min(r.min(), y.min()), max(r.max(), y.max())]
    ax.plot(lim, lim, "k--", lw=0.7)
    ax.set(xlabel="Reference (N·mm)", ylabel="Torque (N·mm)", title="Fig 22: torque vs reference")
    save(fig, "fig22_torque_vs_reference.png", "fig22")

    h = cases["multipeak_hysteresis_compensation"]
    b = cases["multipeak_both_compensations"]
    fig, ax = plot.figure("tall")
    x, r, yh, yb = thin(b.t, b.reference_nmm, h.torque, b.torque)
    ax.plot(x, yh, lw=0.5, color=COLORS["alternative"],
            label=f"hysteresis compensation only (RMS error {h.metrics['rms_nmm']:.1f} N·mm)")
    ax.plot(x, yb, lw=0.5, color=COLORS["model"],
            label=f"hysteresis + friction compensation (RMS error {b.metrics['rms_nmm']:.1f} N·mm)")
    reference_line(ax, x, r)
    ax.set(xlabel="Time (s)", ylabel="Torque (N·mm)")
    ax.set_title("Fig 24: random multi-peak reference", pad=30)
    legend_outside(ax, ncol=2)
    save(fig, "fig24_multipeak_tracking.png", "fig24")

    fig, ax = plot.figure("tall")
    x, eh, eb = thin(b.t, h.error, b.error)
    ax.plot(x, eh, lw=0.5, color=COLORS["alternative"], label=f"hysteresis only (RMS {h.metrics['rms_nmm']:.1f} N·mm)")
    ax.plot(x, eb, lw=0.5, color=COLORS["model"], label=f"both compensations (RMS {b.metrics['rms_nmm']:.1f} N·mm)")
    ax.axhline(60, color=COLORS["limit"], ls=":", lw=0.8)
    ax.axhline(-60, color=COLORS["limit"], ls=":", lw=0.8, label="paper fig 25: about ±60 N·mm")
    ax.set(xlabel="Time (s)", ylabel="Error (N·mm)")
    ax.set_title("Fig 25: tracking error", pad=22)
    legend_outside(ax)
    save(fig, "fig25_multipeak_error.png", "fig25")

    u = cases["multipeak_uncompensated"]
    p = cases["multipeak_both_paper_inverse"]
    fig, ax = plot.figure("tall")
    x, eu, ep, eb = thin(b.t, u.error, p.error, b.error)
    ax.plot(x, eu, lw=0.5, color=COLORS["nominal"], label=f"uncompensated linear map (RMS {u.metrics['rms_nmm']:.1f})")
    ax.plot(x, ep, lw=0.5, color=COLORS["alternative"],
            label=f"paper's inverse + friction (RMS {p.metrics['rms_nmm']:.1f})")
    ax.plot(x, eb, lw=0.5, color=COLORS["model"], label=f"exact inverse + friction (RMS {b.metrics['rms_nmm']:.1f})")
    ax.set(xlabel="Time (s)", ylabel="Error (N·mm)")
    ax.set_title("Baseline and inverses on the multi-peak reference (errors in N·mm)", pad=22)
    legend_outside(ax)
    save(fig, "extra_baseline_and_inverses.png", "baseline")

    o = cases.get("multipeak_heating_open_loop")
    c = cases.get("multipeak_heating_controller")
    if o is not None and c is not None:
        fig, (ax, ax_e) = plot.figure("tall", nrows=2, sharex=True, height=6.0)
        x, r, yo, yc, eo, ec = thin(c.t, c.reference_nmm, o.torque, c.torque, o.error, c.error)
        ax.plot(x, yo, lw=0.5, color=COLORS["alternative"],
                label=f"open loop (RMS error {o.metrics['rms_nmm']:.1f} N·mm)")
        ax.plot(x, yc, lw=0.5, color=COLORS["model"],
                label=f"Controller (RMS error {c.metrics['rms_nmm']:.1f} N·mm)")
        reference_line(ax, x, r)
        ax.set(ylabel="Torque (N·mm)")
        ax.set_title("Closed loop: multi-peak reference, coils heating", pad=30)
        legend_outside(ax, ncol=3)
        ax_e.plot(x, eo, lw=0.5, color=COLORS["alternative"], label="open loop")
        ax_e.plot(x, ec, lw=0.5, color=COLORS["model"], label="Controller")
        ax_e.set(xlabel="Time (s)", ylabel="Error (N·mm)")
        save(fig, "closed_loop_heating.png", "closed_loop")
    return figs
