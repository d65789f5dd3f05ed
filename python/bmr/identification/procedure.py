"""Identification of the paper's model from a bundle: seal friction (eq 22), then the CBH tables, by first-order
curves (``"forc"``, :mod:`bmr.identification.forc`), least squares (``"lstsq"``,
:mod:`bmr.identification.lstsq`) or both; and ``bmr identify`` on the command line.

Friction is identified first from the ``off_state`` runs and subtracted from every run ("friction exclusion").
"""
from __future__ import annotations

import math
import time
from typing import Any, Sequence

import numpy as np

from bmr._core import BmrError, ModelFileError
from bmr.data.bundle import Bundle, Run, read_bundle
from bmr.data.files import check_output_file
from bmr.identification.forc import extract_first_order_curves
from bmr.identification.friction import DEFAULT_MAX_ORDER, fit_friction
from bmr.identification.lstsq import fit_tables_lstsq
from bmr.identification.model import Model
from bmr.identification.spans import SATURATION_TOL, evaluation_start, input_range_of

__all__ = ["identify", "run_cli"]


def _heldout_rms(model: Any, runs: Sequence[Run], lo: float, hi: float) -> dict[str, float]:
    out = {}
    tol = SATURATION_TOL * (hi - lo)
    for r in runs:
        y = model.simulate(r.current, r.theta)
        s = evaluation_start(r.current, lo, hi, tol)
        e = r.torque[s:] - y[s:]
        out[r.name] = float(np.sqrt(np.mean(e * e))) if e.size else float("nan")
    return out


def identify(
    bundle: Bundle | str,
    *,
    method: str = "forc",
    max_order: int = DEFAULT_MAX_ORDER,
    n_nodes: int = 40,
    n_intervals: int = 48,
    smoothing: float = 1e-4,
    train_kinds: Sequence[str] | None = None,
    deadband_a: float | None = None,
) -> "Model":
    """Identify friction and hysteresis from ``bundle`` and return a ``bmr.Model``.

    ``method``: ``"forc"`` (first-order curves of the protocol runs), ``"lstsq"`` (Everett table by least
    squares from the runs of ``train_kinds``, default the ``first_order_*`` runs, or every non-off-state run
    when there are none) or ``"both"`` (fit both and keep the one with the lower held-out RMS over the
    evaluation runs). The model's ``meta["identification"]`` records the friction table, the chosen order and
    its scores, held-out RMS per evaluation run for each method and the timings.
    """
    if isinstance(bundle, str):
        bundle = read_bundle(bundle)
    if method not in ("forc", "lstsq", "both"):
        raise BmrError(f"unknown identification method {method!r}; use 'forc', 'lstsq' or 'both'")
    t0 = time.perf_counter()
    friction = fit_friction(bundle, max_order=max_order) if bundle.by_kind("off_state") else None
    t_friction = time.perf_counter() - t0
    protocol = bundle.by_kind("first_order_ascending", "first_order_descending")
    evaluation = bundle.evaluation_runs()
    lo, hi = input_range_of([r.current for r in bundle.runs if r.kind != "off_state"] or [np.zeros(2)])
    info: dict[str, Any] = {"method": method, "friction": friction.to_dict() if friction else None,
                            "time_s": {"friction": t_friction}, "heldout_rms_nmm": {}}
    candidates: dict[str, Model] = {}
    limits = {"current_a": [lo, hi]}

    if method in ("forc", "both"):
        if not protocol:
            raise BmrError("the bundle has no first_order_ascending/descending run for the 'forc' method; "
                           "use method='lstsq'")
        t = time.perf_counter()
        curves = extract_first_order_curves(protocol, friction, n_nodes=n_nodes, deadband_a=deadband_a,
                                            input_range=(lo, hi))
        candidates["forc"] = Model.from_curves(curves.ascending, curves.descending, friction, limits=limits)
        # Ascending vs descending family disagreement: zero for Preisach data (docs/architecture.md §2.2).
        info["forc_consistency_nmm"] = candidates["forc"].hysteresis.consistency()
        info["time_s"]["forc"] = time.perf_counter() - t
        info["forc_curves"] = {"ascending": len(curves.ascending), "descending": len(curves.descending)}
    if method in ("lstsq", "both"):
        if train_kinds is not None:
            train = bundle.by_kind(*train_kinds)
        else:
            train = protocol or [r for r in bundle.runs if r.kind != "off_state"]
        if not train:
            raise BmrError("no runs to train the least-squares tables on")
        t = time.perf_counter()
        tables = fit_tables_lstsq(train, friction, n_intervals=n_intervals, smoothing=smoothing,
                                  input_range=(lo, hi))
        candidates["lstsq"] = Model.from_curves(tables.ascending, tables.descending, friction, limits=limits)
        info["time_s"]["lstsq"] = time.perf_counter() - t
        info["lstsq_fit"] = {"rms_nmm": tables.rms, "rows": tables.n_rows, "iterations": tables.iterations,
                             "runs": [r.name for r in train], "n_intervals": n_intervals}
    for name, m in candidates.items():
        info["heldout_rms_nmm"][name] = _heldout_rms(m, evaluation, lo, hi)
    chosen = method
    if method == "both":
        def score(name: str) -> float:
            vals = [v for v in info["heldout_rms_nmm"][name].values() if math.isfinite(v)]
            return float(np.mean(vals)) if vals else float("inf")
        chosen = min(candidates, key=score)
    info["chosen"] = chosen
    info["time_s"]["total"] = time.perf_counter() - t0
    model = candidates[chosen]
    model.meta["identification"] = info
    return model


def run_cli(args: Any) -> int:
    """``bmr identify BUNDLE --method M -o model.json``: identify, save, print a short summary."""
    check_output_file(args.out, "model file", error=ModelFileError)
    bundle = read_bundle(args.bundle)
    model = identify(bundle, method=args.method)
    model.save(args.out)
    info = model.meta["identification"]
    print(f"bmr identify: {bundle.actuator or args.bundle} ({len(bundle)} runs), method {args.method}"
          f" -> {info['chosen']}, {info['time_s']['total']:.2f} s")
    f = info["friction"]
    if f:
        print(f"  friction: order {f['order']} ({f['criterion']}), c0 = {f['c0']:.3f} ± {f['stderr']['c0']:.3f} "
              f"N·mm, residual RMS {f['residual_rms_nmm']:.3f} N·mm")
    else:
        print("  friction: no off_state run, none identified")
    lo, hi = model.hysteresis.input_range
    ylo, yhi = model.hysteresis.output_range
    print(f"  hysteresis: input {lo:.4g}..{hi:.4g} A, output {ylo:.4g}..{yhi:.4g} N·mm")
    for name, per_run in info["heldout_rms_nmm"].items():
        if per_run:
            vals = ", ".join(f"{k} {v:.3f}" for k, v in per_run.items())
            print(f"  held-out RMS [{name}] (N·mm): {vals}")
    print(f"  wrote {args.out}")
    return 0
