"""Measure the figures of the README and of docs/results.md and write them in, so that they cannot drift.

    python benches/readme_figures.py measure [SECTION ...]   # run the measurements (all sections by default)
    python benches/readme_figures.py render                  # rewrite the documents' generated sections
    python benches/readme_figures.py check                   # exit 1 if a document differs from the record

Measurements land in ``docs/measurements.json`` (see ``benches/measurements.py``: other bench scripts record
their own sections there too). The documents (``DOCUMENTS``) hold each generated section between
``<!-- generated: NAME -->`` and ``<!-- end: NAME -->``; ``render`` replaces it from the record, and the tests
run ``check``. Timings are repeated (``--repeat``, default 3) and reported as the median with the spread of the
repeats, CPU time next to wall time: the machines here are shared, so the spread says how much to trust a figure.
Instruction counts (callgrind) do not depend on the load.
"""
from __future__ import annotations

import argparse
import json
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Callable

sys.path.insert(0, str(Path(__file__).resolve().parent))
from measurements import ROOT, load, record  # noqa: E402

from bmr.data.files import write_text  # noqa: E402

# The documents that hold generated sections: the README (the demo) and the results page (everything else).
DOCUMENTS = (ROOT / "README.md", ROOT / "docs" / "results.md")


# ------------------------------------------------------------------------------------------------ measuring
def _timed(cmd: list[str], cwd: Path = ROOT) -> tuple[float, float, str]:
    """Run ``cmd``; its wall time (s), CPU time of the children (user + system, s) and standard output."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, proc.stdout


def _spread(values: list[float]) -> dict[str, float]:
    return {"median": statistics.median(values), "min": min(values), "max": max(values), "n": len(values)}


def measure_demo(repeat: int) -> None:
    """The demo's error table (one full run, seed 0) and its wall/CPU time, full and --quick."""
    runs: dict[str, Any] = {}
    for label, extra in (("full", []), ("quick", ["--quick"])):
        walls, cpus, metrics = [], [], None
        for _ in range(repeat if label == "quick" else 1):
            with tempfile.TemporaryDirectory() as tmp:
                wall, cpu, _ = _timed(["bmr", "demo", "--out", f"{tmp}/demo", *extra])
                metrics = json.loads(Path(f"{tmp}/demo/metrics.json").read_text())
            walls.append(wall)
            cpus.append(cpu)
        runs[label] = {"wall_s": _spread(walls), "cpu_s": _spread(cpus), "metrics": metrics}
    record("demo", "python benches/readme_figures.py measure demo  (runs `bmr demo` and `bmr demo --quick`)", runs)


def measure_performance(repeat: int) -> None:
    """Step latency (Rust), instructions per step (callgrind) and the Python per-call costs with peers."""
    values: dict[str, Any] = {}
    latency: dict[str, list[dict[str, float]]] = {}
    for _ in range(repeat):
        _, _, out = _timed(["cargo", "bench", "-p", "bmr-bench", "--bench", "latency"])
        for line in out.splitlines():
            m = re.match(r"Compensator::step \((.+?)\).*median (\d+) ns, p99 (\d+) ns, p99\.9 (\d+) ns", line)
            if m:
                latency.setdefault(m.group(1), []).append(
                    {"median": float(m.group(2)), "p99": float(m.group(3)), "p999": float(m.group(4))})
    values["latency_ns"] = {k: {q: _spread([r[q] for r in v]) for q in ("median", "p99", "p999")}
                            for k, v in latency.items()}
    values["instructions"] = {}
    for what in ("compensator", "extended", "controller", "closed_loop", "hysteresis"):
        _, _, out = _timed(["bash", "benches/callgrind.sh", what])
        m = re.search(r"(\d+) instructions per step", out)
        values["instructions"][what] = int(m.group(1)) if m else None
    peers = []
    for _ in range(repeat):
        _, _, out = _timed([sys.executable, "benches/python_peers.py", "--json"])
        peers.append(json.loads(out.strip().splitlines()[-1]))
    values["python"] = {group: {name: _spread([p[group][name] for p in peers]) for name in peers[0][group]}
                        for group in peers[0]}
    record("performance", "python benches/readme_figures.py measure performance", values)


def measure_closed_loop(repeat: int) -> None:
    """Closed-loop tracking ratio per effect (deterministic for a seed: measured once, ``repeat`` is not used)."""
    _timed([sys.executable, "benches/closed_loop_ratios.py", "--record"])


def measure_identification(repeat: int) -> None:
    """Identification on an independent plant and on the SLAC quadrupole (``benches/identification_real_data.py``
    records its own section; no timings, so no repeats)."""
    _timed([sys.executable, "benches/identification_real_data.py"])


def measure_calibration(repeat: int) -> None:
    """Blind diagnoses of hidden effects on three plants (``benches/diagnosis_calibration.py`` records its own
    section; one seed per case keeps it to about two hours of CPU time on two workers)."""
    _timed(["nice", sys.executable, "benches/diagnosis_calibration.py", "--seeds", "1", "--sizes", "0.5,1,2",
            "--workers", "2", "--record"])


def measure_calibration_independent(repeat: int) -> None:
    """Blind diagnoses on the independently written plant family (``tests/python/independent_plant.py``; the
    calibration script records its own section): every mechanism at medium size, one seed, clean and pairs, on
    the diagnosis protocol and on the paper's coarse protocol alone."""
    _timed(["nice", sys.executable, "benches/diagnosis_calibration.py", "--family", "independent", "--plants",
            "independent,independent_coarse", "--sizes", "1", "--seeds", "1", "--workers", "1", "--record"])


def measure_diagnosis_speed(repeat: int) -> None:
    """CPU time, wall time and peak memory of ``bmr diagnose`` on a quick and a full bundle
    (``benches/diagnosis_speed.py`` records its own section)."""
    _timed([sys.executable, "benches/diagnosis_speed.py", "--full", "--record"])


def measure_slac_diagnosis(repeat: int) -> None:
    """The SLAC quadrupole diagnosed with runs 7 and 8 held out (``examples/slac_diagnosis.py``, its figure
    ``docs/fig_slac_diagnosis.png``); the data from ``$BMR_SLAC_DATA`` or ``../shared/data/slac-quad-4194``."""
    with tempfile.TemporaryDirectory() as tmp:
        wall, cpu, _ = _timed([sys.executable, "examples/slac_diagnosis.py", "--json", f"{tmp}/slac.json",
                               "--figure", "docs/fig_slac_diagnosis.png"])
        out = json.loads(Path(f"{tmp}/slac.json").read_text())
    out["process_wall_s"], out["process_cpu_s"] = wall, cpu
    record("slac_diagnosis", "python benches/readme_figures.py measure slac_diagnosis", out)


def measure_real_data(repeat: int) -> None:
    """Every recording in ``../shared/data`` through import → identify → predict (→ diagnose) with the defaults
    (``benches/real_data.py``, which records its own section)."""
    _timed([sys.executable, "benches/real_data.py", "--record"])


MEASURE: dict[str, Callable[[int], None]] = {"demo": measure_demo, "performance": measure_performance,
                                             "closed_loop": measure_closed_loop,
                                             "identification": measure_identification,
                                             "calibration": measure_calibration,
                                             "calibration_independent": measure_calibration_independent,
                                             "diagnosis_speed": measure_diagnosis_speed,
                                             "slac_diagnosis": measure_slac_diagnosis,
                                             "real_data": measure_real_data}


# ------------------------------------------------------------------------------------------------ rendering
def _pm(s: dict[str, float], fmt: str = "{:.3g}", unit: str = "") -> str:
    """Median with the spread of the repeats: ``0.14 µs (0.13-0.16, 3 runs)``."""
    if s["n"] == 1:
        return fmt.format(s["median"]) + unit
    return f"{fmt.format(s['median'])}{unit} ({fmt.format(s['min'])}-{fmt.format(s['max'])}, {s['n']} runs)"


def render_demo(rec: dict[str, Any]) -> str:
    v = rec["values"]
    m = v["full"]["metrics"]
    fs = m["full_scale_nmm"]
    rows = ["| case | paper fig | RMS (N·mm) | max (N·mm) | RMS (% FS) | max (% FS) |", "|---|---|---|---|---|---|"]
    # The paper's order: triangle experiments (figs 18-22), then the multi-peak reference (24-25) and the baselines,
    # then the closed loop on the heating actuator.
    order = ["triangle_current_without_friction_compensation", "triangle_current_with_friction_compensation",
             "triangle_hysteresis_compensation", "multipeak_uncompensated", "multipeak_hysteresis_compensation",
             "multipeak_both_compensations", "multipeak_both_paper_inverse", "multipeak_heating_open_loop",
             "multipeak_heating_controller"]
    cases = sorted(m["cases"].items(), key=lambda kv: (order.index(kv[0]) if kv[0] in order else len(order), kv[0]))
    for _, c in cases:
        fig = c["paper_figure"] if c["paper_figure"][:1].isdigit() else "—"
        rows.append(f"| {c['title']} | {fig} | {c['rms_nmm']:.3g} | {c['max_abs_nmm']:.4g} | "
                    f"{c['rms_pct_fs']:.2g} | {c['max_pct_fs']:.2g} |")
    t = {k: v[k] for k in ("full", "quick")}
    d = m.get("diagnosis") or {}
    text = [f"Errors on `{m['preset']}`, seed {m['seed']} (full run, {m['sample_rate_hz']:g} Hz; "
            f"FS = {fs:.4g} N·mm, the model's full-scale torque):", "", *rows, ""]
    if d:
        steps = " → ".join([f"{d['effects'][0]['heldout_rms_before']:.3g}" if d.get("effects") else "",
                            *[f"{e['heldout_rms_after']:.3g}" for e in d.get("effects", [])]]).strip(" →")
        text.append(f"The demo's diagnosis names **`{d['cause']}`**; held-out RMS {steps} N·mm "
                    f"(noise floor {d['noise_floor']:.3g} N·mm).")
        text.append("")
    text.append(f"Time: full programme {_pm(t['full']['wall_s'], '{:.0f}', ' s')} wall, "
                f"{_pm(t['full']['cpu_s'], '{:.0f}', ' s')} CPU; `--quick` {_pm(t['quick']['wall_s'], '{:.0f}', ' s')}"
                f" wall, {_pm(t['quick']['cpu_s'], '{:.0f}', ' s')} CPU.")
    return "\n".join(text)


def render_performance(rec: dict[str, Any]) -> str:
    v = rec["values"]
    lat = v["latency_ns"]
    py = v["python"]
    ins = v["instructions"]
    rows = ["| what | figure | command |", "|---|---|---|"]
    for name, q in lat.items():
        rows.append(f"| `Compensator::step` (Rust, {name}) | median {_pm(q['median'], '{:.0f}', ' ns')}, "
                    f"p99 {q['p99']['median']:.0f} ns, p99.9 {q['p999']['median']:.0f} ns over 10⁶ steps | "
                    "`cargo bench -p bmr-bench --bench latency` |")
    for what, n in ins.items():
        name = {"compensator": "`Compensator::step`", "extended": "`Compensator::step` with every extension stage",
                "controller": "`Controller::step` around every extension stage",
                "closed_loop": "`Controller::step` + `VirtualActuator::step` (closed loop, one sample)",
                "hysteresis": "`Hysteresis::step`"}[what]
        rows.append(f"| {name} instructions | {n} per step | `benches/callgrind.sh {what}` |")
    cmd = "`python benches/python_peers.py`"
    cpu_us = py.get("per_call_cpu_us", {})
    for name, s in py["per_call_us"].items():
        cpu = f", CPU {_pm(cpu_us[name], '{:.3g}', ' µs')}" if name in cpu_us else ""
        rows.append(f"| `{name}` from Python | wall {_pm(s, '{:.3g}', ' µs')}{cpu} per call | {cmd} |")
    cpu_rate = py.get("throughput_cpu_msps", {})
    for name, s in py["throughput_msps"].items():
        cpu = f" ({_pm(cpu_rate[name], '{:.3g}', ' M')} per CPU-second)" if name in cpu_rate else ""
        rows.append(f"| `{name}` | {_pm(s, '{:.3g}', ' M samples/s')}{cpu} | {cmd} |")
    for name, s in py["ratio_to_compensator_step"].items():
        rows.append(f"| peer: {name} | {_pm(s, '{:.3g}', '×')} the cost of our `Compensator.step()` | {cmd} |")
    return "\n".join(rows)


def render_closed_loop(rec: dict[str, Any]) -> str:
    v = rec["values"]
    rows = [f"Seed {v['seed']}, `{v['preset']}`, multi-peak reference of {v['duration_s']:g} s, or two thermal time "
            "constants when the heating stage is diagnosed (its state builds up no faster; the closed-loop check "
            "uses the same length); ratio = extended / nominal tracking RMS; the last two columns are the "
            "closed-loop check's verdicts stored in the model file (tracking with / without the stage, the other "
            "stages in; above 1: left off).", "",
            "| effect (medium size) | named | stages on | reference (s) | nominal RMS (N·mm) | extended RMS (N·mm) | "
            "ratio | its stage, with / without | refined tables, with / without |",
            "|---|---|---|---|---|---|---|---|---|"]

    def verdict(r: dict[str, Any], stage: str) -> str:
        s = r["stages"].get(stage)
        if s is None:
            return "—"
        return f"{s['ratio']:.2f}" + ("" if s["in_loop"] else " (left off)")

    ratios = []
    for r in v["rows"]:
        params = ", ".join(f"{k}={x:g}" for k, x in r["params"].items())
        ratios.append(r["ratio"])
        rows.append(f"| {r['effect']} ({params}) | {', '.join(r['named'])} | {', '.join(r['stages_on']) or '—'} | "
                    f"{r.get('duration_s', v['duration_s']):.0f} | {r['nominal_rms_nmm']:.2f} | {r['extended_rms_nmm']:.2f} | {r['ratio']:.2f} | "
                    f"{verdict(r, r['effect'])} | {verdict(r, 'core_tables')} |")
    rows += ["", f"Ratios {min(ratios):.2f}-{max(ratios):.2f} over {len(ratios)} effects."]
    return "\n".join(rows)


def render_identification(rec: dict[str, Any]) -> str:
    v = rec["values"]
    f = v["forc_protocol"]
    b = v["bench"]
    nd = v["nodes"]
    text = [
        "Independent Preisach plant, 21 first-order curves per family at 0.5 A/s, 500 Hz, exact currents, "
        f"{f['noise_nmm']:g} N·mm noise; RMS error on a held-out multi-peak run (N·mm):",
        "",
        "| data | `forc` | `lstsq` | `auto` | raw curves |",
        "|---|---|---|---|---|",
        f"| both families, exact Preisach | {f['forc']:.3g} | {f['lstsq']:.3g} | {f['auto']:.3g} "
        f"(chose `{f['auto_chose']}`) | {f['raw_curves']:.3g} |",
    ]
    for label, name in (("both", "both families"), ("ascending_only", "ascending family only"),
                        ("descending_only", "descending family only")):
        text.append(f"| {name}, 30 ms continued switching, unknown start | {b[label]['forc']:.3g} | "
                    f"{b[label]['lstsq']:.3g} | | |")
    us = b["unknown_start"]
    text += [
        "",
        f"Measured families of the exact plant differ by {f['family_mismatch_nmm']:.3g} N·mm at most. A run that "
        f"reaches saturation only at its end: initial state estimated, {us['estimate']['used']} of "
        f"{us['estimate']['total']} samples used, held-out RMS {us['estimate']['rms']:.3g} N·mm; rows after both "
        f"saturation ends only (the former default): {us['saturation']['used']} samples, "
        f"{us['saturation']['rms']:.3g} N·mm.",
        "",
        f"Nodes: dense noise-free curves (20 × 2 500 samples) keep {nd['default']['nodes']} of "
        f"{nd['default']['inputs']} grid inputs at the default bound; replayed from their reversals they are "
        f"reproduced to {nd['default']['error']:.1e} of the span. Compressed for firmware: "
        + ", ".join(f"bound {c['bound']:g} → {c['nodes']} nodes, error {c['error']:.1e}"
                    for k, c in nd.items() if k.startswith("compressed")) + " of the span.",
    ]
    sl = v.get("slac")
    if sl:
        sg = sl["sigma_t"]

        def cell(r: dict[str, float]) -> str:
            return f"{r['rms_t']:.3g} T ({r['rms_t'] / sg:.1f} σ), max {r['max_t']:.3g} T"

        text += [
            "",
            f"SLAC quadrupole 4194 (runs 3-6 train, 7 and 8 held out, σ = {sg:.2g} T measurement noise):",
            "",
            "| model | held-out RMS |",
            "|---|---|",
            f"| `bmr identify` (least squares), offset shrunk from the first sample | {cell(sl['default_shrunk'])} |",
            f"| same, offset from the first sample alone | {cell(sl['default_first'])} |",
            f"| smoothing 0.1, offset shrunk | {cell(sl['smoothing_0.1_shrunk'])} |",
            f"| single-valued curve (degree 7) | {cell(sl['single_valued'])} |",
            f"| before (`examples/slac_magnet.py`) | {sl['before_rms_t']:.3g} T ({sl['before_rms_t'] / sg:.1f} σ) |",
        ]
    return "\n".join(text)


def _rate(x: float | None) -> str:
    return "—" if x is None else f"{x:.2f}"


def _ambiguous(r: dict[str, Any]) -> str:
    """The share of bundles whose report says "a or b" (an effect the excitation could not tell from another)."""
    return f" ({r['ambiguous']:.2f} as 'a or b')" if r.get("ambiguous") else ""


def render_calibration(rec: dict[str, Any]) -> str:
    v = rec["values"]
    units = {"rig_preisach": "N·mm", "rig_soft": "N·mm", "piezo": "µm", "piezo_import": "µm", "rig_import": "N·mm",
             "independent": "N·mm", "independent_coarse": "N·mm"}
    text = ["| plant | hidden effect | size | detected | wrong name | false alarm | median param. error | "
            "held-out RMS nominal → extended (noise floor) |", "|---|---|---|---|---|---|---|---|"]
    for g in v["groups"]:
        size = "—" if g["label"] == "clean" else f"×{g['size']:g}"
        if "error" in g:
            text.append(f"| {g['plant']} | {g['label']} | {size} | failed: {g['error'][:80]} | | | | |")
            continue
        clean = g["label"] == "clean"
        wrong = "—" if clean else _rate(g["wrong"]) + (f" ({', '.join(g['wrong_names'])})" if g["wrong_names"]
                                                          else "")
        fa = (_rate(g["false_alarm"]) + (f" ({', '.join(g['found'])})" if g["found"] else "")) if clean else "—"
        err = "—" if g["param_err"] is None else f"{g['param_err']:.2f}"
        det = "—" if clean else _rate(g["detection"]) + (f" ({g['ambiguous']:.2f} as 'a or b')"
                                                         if g.get("ambiguous") else "")
        text.append(f"| {g['plant']} | {g['label']} | {size} | {det} | {wrong} | "
                    f"{fa} | {err} | {g['nominal']:.3g} → {g['final']:.3g} ({g['noise']:.3g}) "
                    f"{units.get(g['plant'], '')} |")
    text += ["", "| plant | single effects: detected | wrong name | pairs: both detected | wrong name | "
             "clean: false alarm | learned term kept on clean |", "|---|---|---|---|---|---|---|"]
    for plant, r in v["rates"].items():
        s, p, c = r["single"], r["pairs"], r["clean"]
        text.append(f"| {plant} | {_rate(s['detection'])} of {s['n']}{_ambiguous(s)} | {_rate(s['wrong'])} | "
                    f"{_rate(p['detection'])} of {p['n']}{_ambiguous(p)} | {_rate(p['wrong'])} | "
                    f"{_rate(c['false_alarm'])} of "
                    f"{c['n']} | {c['learned']} |")
    bw, bc = v["bundle_wall_s"], v["bundle_cpu_s"]
    text += ["", f"{v['bundles']} bundles ({v['failed']} failed) on {v['workers']} Dask workers in "
             f"{v['wall_s'] / 60:.0f} min; per bundle (made and diagnosed on its worker): CPU time median "
             f"{bc['median']:.1f} s, max {bc['max']:.1f} s; diagnosis wall time median {bw['median']:.1f} s, max "
             f"{bw['max']:.1f} s."]
    return "\n".join(text)


def render_diagnosis_speed(rec: dict[str, Any]) -> str:
    text = ["| bundle | `bmr diagnose`: CPU | wall | peak memory | `bmr identify`: CPU | named |",
            "|---|---|---|---|---|---|"]
    for r in rec["values"]["rows"]:
        d, i = r["diagnose"], r["identify"]
        text.append(f"| {r['bundle']} | {d['cpu_s']:.1f} s | {d['wall_s']:.1f} s | {d['peak_mb']:.0f} MB | "
                    f"{i['cpu_s']:.1f} s | {', '.join(r['effects']) or '—'} |")
    return "\n".join(text)


def render_slac_diagnosis(rec: dict[str, Any]) -> str:
    v = rec["values"]
    named = ", ".join(f"`{n}`" for n in v["named"] if n != "table_resolution") or "no effect"
    learned = f"the learned term `{v['learned']}`" if v["learned"] else "no learned term"
    text = [f"Runs 3-6 identify, runs 7 and 8 held out in {v['folds']} blocked folds; σ = {v['sigma_t']:.2g} T "
            f"({v['noise_method'].replace('_', ' ')}). Named: {named}; kept: {learned}.", "",
            "| held-out runs 7 and 8 | RMS (T) | RMS (σ) |", "|---|---|---|",
            f"| identified model | {v['heldout_rms_before_t']:.3g} | {v['heldout_rms_before_sigmas']:.1f} |",
            f"| after discovery | {v['heldout_rms_after_t']:.3g} | {v['heldout_rms_after_sigmas']:.1f} |", "",
            "| candidate (rejected) | mean fold gain (share of held-out variance removed) | folds with a gain | "
            "held-out RMS with it (T) |", "|---|---|---|---|"]
    for name, r in sorted(v["rejected"].items(), key=lambda kv: -kv[1]["gain"]):
        text.append(f"| `{name}` | {r['gain']:.3g} | {r['folds_positive']} of {v['folds']} | "
                    f"{r['heldout_rms_after_t']:.3g} |")
    if v.get("learned_tried") and not v["learned"]:
        text += ["", f"Learned equation tried and not kept: `{v['learned_tried']}`."]
    if v["unexplained"]:
        text += ["", "Structure left, by the signal it depends on: " + ", ".join(
            f"{u['signal'].replace('_', ' ')} {u['strength']:.2g} T ({u['strength'] / v['sigma_t']:.1f} σ)"
            for u in v["unexplained"]) + "."]
    text += ["", f"Diagnosis wall time {v['wall_time_s']:.1f} s; the whole script (import, diagnosis, figure) "
             f"{v['process_wall_s']:.1f} s wall, {v['process_cpu_s']:.1f} s CPU."]
    return "\n".join(text)


def render_real_data(rec: dict[str, Any]) -> str:
    from real_data import render

    return render(rec["values"])


def render_closed_loop_controller(rec: dict[str, Any]) -> str:
    v = rec["values"]
    plants = [k for k in ("virtual", "independent") if k in v]
    titles = {"virtual": "virtual actuator (`rig_preisach` + coil lag + heating), run in Rust",
              "independent": "independently written rig (eddy-current coil circuit, resistive heating), stepped "
                             "from Python"}
    names = [r["controller"] for r in v[plants[0]]["rows"]]
    head = "| controller | " + " | ".join(f"{titles[p]}: RMS (N·mm)" for p in plants) + " |"
    lines = [head, "|---|" + "---|" * len(plants)]
    for n in names:
        cells = []
        for p in plants:
            row = next((r for r in v[p]["rows"] if r["controller"] == n), None)
            cells.append(f"{row['rms_nmm']:.2f}" if row else "—")
        lines.append(f"| {n} | " + " | ".join(cells) + " |")
    notes = []
    for p in plants:
        d = v[p]["design"]
        rates = [r["samples_per_cpu_s"] for r in v[p]["rows"] if r.get("samples_per_cpu_s")]
        rate = f"; batch closed loop {min(rates) / 1e6:.2g}-{max(rates) / 1e6:.2g} M samples per CPU-second" if rates else ""
        notes.append(f"{titles[p].split(' (')[0]}: diagnosis named {', '.join(v[p]['named']) or 'nothing'}; "
                     f"{v[p]['duration_s']:g} s multi-peak reference, seed {v[p]['seed']}; design: integral gain "
                     f"{d['ki_per_s']:.3g}/s, bandwidth {d['bandwidth_hz']:.3g} Hz, phase margin "
                     f"{d['phase_margin_deg']:.3g}° over a loop delay of {1e3 * d['loop_delay_s']:.3g} ms{rate}.")
    return "\n".join(lines) + "\n\n" + "\n\n".join(notes)


RENDER: dict[str, Callable[[dict[str, Any]], str]] = {"closed_loop_controller": render_closed_loop_controller,
                                                       "demo": render_demo, "performance": render_performance,
                                                       "closed_loop": render_closed_loop,
                                                       "identification": render_identification,
                                                       "calibration": render_calibration,
                                                       "calibration_independent": render_calibration,
                                                       "diagnosis_speed": render_diagnosis_speed,
                                                       "slac_diagnosis": render_slac_diagnosis,
                                                       "real_data": render_real_data}


def _footer(rec: dict[str, Any]) -> str:
    mach = rec["machine"]
    return (f"\n\n<sub>Measured {rec['measured']} on {mach['cpus']} × {mach['cpu'] or 'CPU'} "
            f"(Python {mach['python']}) by `{rec['command']}`.</sub>")


def rendered(readme: str, data: dict[str, Any]) -> str:
    """The document with every generated section replaced from the record (sections without a record stay)."""
    def sub(m: re.Match[str]) -> str:
        name = m.group(1)
        rec = data.get(name)
        if rec is None or name not in RENDER:
            return m.group(0)
        return f"<!-- generated: {name} -->\n{RENDER[name](rec)}{_footer(rec)}\n<!-- end: {name} -->"

    return re.sub(r"<!-- generated: (\w+) -->.*?<!-- end: \1 -->", sub, readme, flags=re.S)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    m = sub.add_parser("measure")
    m.add_argument("sections", nargs="*", help=f"any of {', '.join(MEASURE)} (default: all)")
    m.add_argument("--repeat", type=int, default=3)
    sub.add_parser("render")
    sub.add_parser("check")
    args = ap.parse_args(argv)
    if args.cmd == "measure":
        unknown = [s for s in args.sections if s not in MEASURE]
        if unknown:
            ap.error(f"unknown section(s) {', '.join(unknown)}; choose from {', '.join(MEASURE)}")
        for name in args.sections or list(MEASURE):
            print(f"measuring {name} ...", file=sys.stderr)
            MEASURE[name](args.repeat)
        args.cmd = "render"
    data = load()
    stale = []
    for doc in DOCUMENTS:
        text = doc.read_text()
        new = rendered(text, data)
        if new == text:
            continue
        if args.cmd == "check":
            stale.append(doc.relative_to(ROOT).as_posix())
        else:
            write_text(doc, new)
    if stale:
        print(f"{', '.join(stale)} differ(s) from docs/measurements.json: run `python benches/readme_figures.py "
              "render` (or measure again)", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
