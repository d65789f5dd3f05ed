"""Figures of a diagnosis (matplotlib, measured data only) and the self-contained HTML section/report (PNG
figures embedded as base64)."""
from __future__ import annotations

import html
from typing import Any

import numpy as np

from bmr import plot
from bmr.diagnosis.residuals import signal_label
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
    s = d.signals
    runs = s["runs"]
    q = d.quantities
    yu = q.output.unit
    fig, axes = plot.figure("wide", nrows=len(runs), height=1.9 * len(runs) + 0.6, squeeze=False)
    for ax, (name, t, rn, re) in zip(axes[:, 0], runs):
        step = max(1, t.size // 4000)
        ax.plot(t[::step], rn[::step], lw=0.5, color=COLORS["nominal"], label="nominal")
        ax.plot(t[::step], re[::step], lw=0.5, color=COLORS["extended"], label="extended")
        ax.axhline(d.noise_floor, color="k", lw=0.5, ls=":")
        ax.axhline(-d.noise_floor, color="k", lw=0.5, ls=":")
        ax.set_ylabel(f"{name}\n{yu}")
    axes[0, 0].legend(loc="upper right")
    axes[-1, 0].set_xlabel("time in the bundle (s)")
    fig.suptitle("Residual (measured − simulated) from the first saturation on; dotted: ±noise floor")
    out["Residual against time"] = png_base64(fig)

    panels = [("current", q.input.label), ("rate", f"{q.input.name} rate ({q.input.unit}/s)")]
    if q.angle is not None:
        panels.insert(0, ("theta", "rotor angle (rad)"))
    fig, axes = plot.figure("panel3", ncols=len(panels))
    axes = np.atleast_1d(axes)
    for ax, (key, label) in zip(axes, panels):
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
    axes[0].set_ylabel(f"mean residual ({yu})")
    axes[0].legend()
    fig.suptitle("Where the simulation is wrong: residual conditional means")
    out[f"Residual against {', '.join(k if k != 'theta' else 'angle' for k, _ in panels)}"] = png_base64(fig)

    steps = [("nominal", d.nominal_heldout_rms)] + [(e["name"], e["heldout_rms_after_nmm"]) for e in d.effects]
    if d.learned and d.learned.get("accepted"):
        steps.append(("learned term", d.learned["heldout_rms_after"]))
    fig, ax = plot.figure("wide", height=2.9)
    ax.bar(range(len(steps)), [v for _, v in steps],
           color=[COLORS["nominal"]] + [COLORS["extended"]] * (len(steps) - 1))
    ax.axhline(d.noise_floor, color="k", ls=":", lw=1, label="noise floor")
    ax.set_xticks(range(len(steps)))
    ax.set_xticklabels(["nominal"] + ["+ " + n for n, _ in steps[1:]], rotation=20)
    ax.set_ylabel(f"held-out RMS ({yu})")
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
    """A self-contained HTML fragment: heading, named cause, selection table, learned term, before/after and
    figures, in the bundle's declared quantities and units."""
    q = d.quantities
    yu = html.escape(q.output.unit)
    f = q.output.format
    noise = d.noise
    parts = [f"<section class='bmr-diagnosis'><h2>Diagnosis: {html.escape(d.device)}</h2>",
             f"<p>{html.escape(q.describe())}.</p>"]
    parts.append(f"<p><b>Named cause:</b> <code>{html.escape(d.cause)}</code>. Held-out RMS "
                 f"{html.escape(f(d.nominal_heldout_rms, 4))} (nominal) → "
                 f"{html.escape(f(d.residual_rms, 4))} (extended); noise floor "
                 f"{html.escape(f(d.noise_floor, 4))} ({html.escape(noise['detail'])}); {d.folds} blocked "
                 f"folds; {d.wall_time_s:.1f} s.</p>")
    rows = [[e["name"], f"accepted with {e['paired_with']}" if e.get("paired_with") else "accepted",
             f"{e['gain'] * 100:.1f} %", f"{e['folds_positive']}/{d.folds}",
             f"{e['heldout_rms_before_nmm']:.4g} → {e['heldout_rms_after_nmm']:.4g}", _fmt_params(e["params"])]
            for e in d.effects]
    rows += [[r["name"], "rejected", f"{r['gain'] * 100:.1f} %",
              f"{r['folds_positive']}/{r.get('folds_evaluated', d.folds)}",
              f"{r['heldout_rms_before_nmm']:.4g} → {r['heldout_rms_after_nmm']:.4g}",
              r["reason"] if r.get("reason", "").startswith("parameters outside") else ""] for r in d.rejected]
    parts.append("<h3>Selection</h3>" + _table(rows, ["effect", "decision", "held-out gain", "folds positive",
                                                      f"held-out RMS ({q.output.unit})", "parameters"]))
    for a in d.alternatives:
        parts.append(f"<p><b>Not separable:</b> {html.escape(a.message)}.</p>")
    if d.output_rails.any:
        parts.append(f"<p><b>Sensor range:</b> {html.escape(d.output_rails.describe(q.output))}.</p>")
    drift = d.identification_drift
    if drift:
        parts.append(f"<p><b>Identification:</b> the branches did not close (a saturation output moved by "
                     f"{100 * drift['closure']:.3g} % of the span); a leakage of {drift['leakage_rate']:.4g} "
                     f"{yu} per {html.escape(q.input.unit)}·s was fitted with the tables.</p>")
    for h in d.history:
        parts.append("<h3>Across the measurement history</h3><ul>"
                     + "".join(f"<li>{html.escape(line.strip())}</li>" for line in h.lines(q)) + "</ul>")
    if d.learned:
        lr = d.learned
        verdict = "kept" if lr["accepted"] else "not kept (held-out gain too small)"
        parts.append(f"<h3>What no named effect explains: learned term ({verdict})</h3><p><code>"
                     f"{html.escape(lr['equation'])}</code>; held-out gain {100 * lr['gain']:.1f} % "
                     f"({lr['folds_positive']}/{d.folds} folds), held-out RMS {lr['heldout_rms_before']:.4g} → "
                     f"{lr['heldout_rms_after']:.4g} {yu}.</p>")
        rows = [[t["name"], f"{t['coefficient']:.4g} {t['coefficient_unit']}", t["doc"]] for t in lr["terms"]]
        if rows:
            parts.append(_table(rows, ["signal", "coefficient", "signal's definition"]))
    where = [[signal_label(sig, q), f"{d.structure_nominal.get(sig, 0.0):.4g}", f"{d.structure_extended.get(sig, 0.0):.4g}"]
             for sig in d.structure_nominal]
    parts.append(f"<h3>What the nominal model gets wrong, by signal</h3><p>RMS ({q.output.unit}) of the "
                 "residual's conditional mean against each signal (noise share removed).</p>"
                 + _table(where, ["signal", "nominal", "extended"]))
    per_run = [[name, f"{b:.4g}", f"{a:.4g}"] for name, (b, a) in d.per_run_rms.items()]
    parts.append("<h3>Before / after per run</h3>" + _table(per_run, ["run", f"nominal RMS ({q.output.unit})",
                                                                     f"extended RMS ({q.output.unit})"]))
    if d.closed_loop and "ratio" in d.closed_loop:
        c = d.closed_loop
        plant = "the simulator that made the bundle" if c["plant"] == "simulator" else "the diagnosed model"
        parts.append(f"<p><b>Closed loop</b> on {plant} ({html.escape(str(c['reference']))} reference, "
                     f"{c['duration_s']:g} s): tracking RMS {c['nominal_rms_nmm']:.2f} {yu} (nominal compensator) "
                     f"→ {c['extended_rms_nmm']:.2f} {yu} (extended), ratio {c['ratio']:.2f}.</p>")
        rows = [[name, "on" if v["in_loop"] else "off (made tracking worse)", f"{v['ratio']:.2f}"]
                for name, v in c["stages"].items()]
        parts.append(_table(rows, ["stage", "in the compensator", "tracking with / without it"]))
    if d.unexplained:
        rows = [[signal_label(u["signal"], q), f"{u['strength']:.4g}"] for u in d.unexplained]
        parts.append("<h3>Structure no effect explains</h3>"
                     + _table(rows, ["signal", f"strength ({q.output.unit} RMS)"]))
    else:
        parts.append("<p>No residual structure above the noise remains against "
                     + ", ".join(signal_label(k, q) for k in d.structure_nominal) + ".</p>")
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
