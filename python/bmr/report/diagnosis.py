"""Figures of a diagnosis (matplotlib, measured data only) and the self-contained HTML section/report (PNG
figures embedded as base64)."""
from __future__ import annotations

import html
from typing import Any

import numpy as np

from bmr import plot
from bmr.plot import COLORS, png_base64

__all__ = ["figures", "html_section", "html_page"]


def _binned(x: np.ndarray, r: np.ndarray, bins: int = 36) -> tuple[np.ndarray, np.ndarray]:
    edges = np.unique(np.quantile(x, np.linspace(0, 1, bins + 1)))
    if edges.size < 3:
        return np.zeros(0), np.zeros(0)
    idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, edges.size - 2)
    cnt = np.bincount(idx, minlength=edges.size - 1)
    s = np.bincount(idx, weights=r, minlength=edges.size - 1)
    centres = 0.5 * (edges[:-1] + edges[1:])
    ok = cnt > 0
    return centres[ok], s[ok] / cnt[ok]


def figures(d: Any) -> dict[str, str]:
    """``{title: base64 PNG}``: residual against time per run, against angle, current level and current rate
    (nominal vs extended), and held-out RMS along the selection (bmr figure style)."""
    with plot.style():
        return _figures(d)


def _figures(d: Any) -> dict[str, str]:
    out: dict[str, str] = {}
    s = d._signals
    runs = s["runs"]
    fig, axes = plot.figure("wide", nrows=len(runs), height=1.9 * len(runs) + 0.6, squeeze=False)
    for ax, (name, t, rn, re) in zip(axes[:, 0], runs):
        step = max(1, t.size // 4000)
        ax.plot(t[::step], rn[::step], lw=0.5, color=COLORS["nominal"], label="nominal")
        ax.plot(t[::step], re[::step], lw=0.5, color=COLORS["extended"], label="extended")
        ax.axhline(d.noise_floor_nmm, color="k", lw=0.5, ls=":")
        ax.axhline(-d.noise_floor_nmm, color="k", lw=0.5, ls=":")
        ax.set_ylabel(f"{name}\nN·mm")
    axes[0, 0].legend(loc="upper right")
    axes[-1, 0].set_xlabel("time in the bundle (s)")
    fig.suptitle("Residual (measured − simulated) from the first saturation on; dotted: ±noise floor")
    out["Residual against time"] = png_base64(fig)

    fig, axes = plot.figure("panel3", ncols=3)
    for ax, key, label in zip(axes, ("theta", "current", "rate"),
                              ("rotor angle (rad)", "current (A)", "current rate (A/s)")):
        x = s[key]
        if key == "rate":
            # Steps of a multi-step run have huge rates for one sample: keep the bulk of the range.
            lo, hi = np.quantile(x, [0.01, 0.99])
            x = np.clip(x, lo, hi)
        for r, color, lab in ((s["nominal"], COLORS["nominal"], "nominal"),
                              (s["extended"], COLORS["extended"], "extended")):
            c, m = _binned(x, r)
            ax.plot(c, m, "o-", ms=2.5, lw=0.8, color=color, label=lab)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_xlabel(label)
    axes[0].set_ylabel("mean residual (N·mm)")
    axes[0].legend()
    fig.suptitle("Where the simulation is wrong: residual conditional means")
    out["Residual against angle, current and rate"] = png_base64(fig)

    steps = [("nominal", d.nominal_heldout_rms_nmm)] + [(e["name"], e["heldout_rms_after_nmm"]) for e in d.effects]
    fig, ax = plot.figure("wide", height=2.9)
    ax.bar(range(len(steps)), [v for _, v in steps],
           color=[COLORS["nominal"]] + [COLORS["extended"]] * (len(steps) - 1))
    ax.axhline(d.noise_floor_nmm, color="k", ls=":", lw=1, label="noise floor")
    ax.set_xticks(range(len(steps)))
    ax.set_xticklabels(["nominal"] + ["+ " + n for n, _ in steps[1:]], rotation=20)
    ax.set_ylabel("held-out RMS (N·mm)")
    ax.legend()
    out["Held-out RMS along the selection"] = png_base64(fig)
    return out


def _table(rows: list[list[str]], head: list[str]) -> str:
    h = "".join(f"<th>{html.escape(c)}</th>" for c in head)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table class='bmr-diag'><tr>{h}</tr>{body}</table>"


def _fmt_params(p: dict[str, Any]) -> str:
    return ", ".join(f"{k}={v:.4g}" if isinstance(v, (int, float)) else f"{k}={v}" for k, v in p.items())


def html_section(d: Any) -> str:
    """A self-contained HTML fragment: heading, named cause, selection table, before/after and figures."""
    parts = [f"<section class='bmr-diagnosis'><h2>Diagnosis: {html.escape(d.actuator)}</h2>"]
    parts.append(f"<p><b>Named cause:</b> <code>{html.escape(d.cause)}</code>. Held-out RMS "
                 f"{d.nominal_heldout_rms_nmm:.3f} N·mm (nominal) → {d.residual_rms_nmm:.3f} N·mm (extended); "
                 f"noise floor {d.noise_floor_nmm:.3f} N·mm; {d.folds} blocked folds; "
                 f"{d.wall_time_s:.1f} s.</p>")
    rows = [[e["name"], "accepted", f"{e['gain'] * 100:.1f} %", f"{e['folds_positive']}/{d.folds}",
             f"{e['heldout_rms_before_nmm']:.3f} → {e['heldout_rms_after_nmm']:.3f}", _fmt_params(e["params"])]
            for e in d.effects]
    rows += [[r["name"], "rejected", f"{r['gain'] * 100:.1f} %", f"{r['folds_positive']}/{d.folds}",
              f"{r['heldout_rms_before_nmm']:.3f} → {r['heldout_rms_after_nmm']:.3f}", ""] for r in d.rejected]
    parts.append("<h3>Selection</h3>" + _table(rows, ["effect", "decision", "held-out gain", "folds positive",
                                                      "held-out RMS (N·mm)", "parameters"]))
    where = [[sig, f"{d.structure_nominal.get(sig, 0.0):.3f}", f"{d.structure_extended.get(sig, 0.0):.3f}"]
             for sig in d.structure_nominal]
    parts.append("<h3>What the nominal model gets wrong, by signal</h3><p>RMS (N·mm) of the residual's conditional "
                 "mean against each signal (noise share removed).</p>"
                 + _table(where, ["signal", "nominal", "extended"]))
    per_run = [[name, f"{b:.3f}", f"{a:.3f}"] for name, (b, a) in d.per_run_rms.items()]
    parts.append("<h3>Before / after per run</h3>" + _table(per_run, ["run", "nominal RMS (N·mm)",
                                                                     "extended RMS (N·mm)"]))
    if d.closed_loop and "ratio" in d.closed_loop:
        c = d.closed_loop
        plant = "the simulator that made the bundle" if c["plant"] == "simulator" else "the diagnosed model"
        parts.append(f"<p><b>Closed loop</b> on {plant} ({html.escape(str(c['reference']))} reference, "
                     f"{c['duration_s']:g} s): tracking RMS {c['nominal_rms_nmm']:.2f} N·mm (nominal compensator) "
                     f"→ {c['extended_rms_nmm']:.2f} N·mm (extended), ratio {c['ratio']:.2f}.</p>")
        rows = [[name, "on" if v["in_loop"] else "off (made tracking worse)", f"{v['ratio']:.2f}"]
                for name, v in c["stages"].items()]
        parts.append(_table(rows, ["stage", "in the compensator", "tracking with / without it"]))
    if d.unexplained:
        rows = [[u["signal"], f"{u['strength']:.3f}"] for u in d.unexplained]
        parts.append("<h3>Structure no effect explains</h3>" + _table(rows, ["signal", "strength (N·mm RMS)"]))
    else:
        parts.append("<p>No residual structure above the noise remains against angle, time, current level, "
                     "current rate or reversal order.</p>")
    for title, png in d.figures().items():
        parts.append(f"<h3>{html.escape(title)}</h3><img alt='{html.escape(title)}' "
                     f"src='data:image/png;base64,{png}'/>")
    parts.append("</section>")
    return "\n".join(parts)


def html_page(d: Any) -> str:
    style = ("body{font-family:sans-serif;max-width:1000px;margin:2em auto}table.bmr-diag{border-collapse:collapse}"
             "table.bmr-diag td,table.bmr-diag th{border:1px solid #bbb;padding:2px 6px;font-size:90%}")
    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>bmr diagnosis</title><style>{style}</style>"
            f"</head><body>{html_section(d)}</body></html>\n")
