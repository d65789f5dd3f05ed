"""Identification of a device model from a bundle: the angle-periodic friction (paper eq 22, when the bundle has
off-state runs), then the hysteresis tables by first-order curves (``"forc"``, :mod:`bmr.identification.forc`), by
least squares from any excitation (``"lstsq"``, :mod:`bmr.identification.lstsq`), or the better of both
(``"auto"``, the default); and ``bmr identify`` on the command line.

``"auto"`` fits both where both are possible and keeps the one that predicts held-out data better: the bundle's
evaluation runs when it has any, else first-order curves held out in two folds (every other curve of each
family). The result (``model.identification``, an :class:`IdentificationReport`; ``model.meta["identification"]``
is its ``to_dict()``) says which was chosen and why, how many samples each run contributed and why any others were
not used, how far the curves moved against their direction, which family was derived, the node error bound, the
per-run calibration and the held-out errors, in the bundle's declared units (``bundle.quantities``; the model
records them). Devices without an angle have no friction model.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from bmr._core import BmrError, ModelFileError
from bmr.data.bundle import Bundle, Run, read_bundle
from bmr.data.files import check_output_file
from bmr.data.quantities import Quantities
from bmr.identification.accounting import SampleAccount
from bmr.identification.forc import FirstOrderCurves, extract_first_order_curves
from bmr.identification.friction import DEFAULT_MAX_ORDER, fit_friction
from bmr.identification.lstsq import DEFAULT_GRID, LstsqTables, fit_tables_lstsq
from bmr.identification.model import Model
from bmr.identification.prediction import Prediction, predict
from bmr.identification.signals import run_input, run_output
from bmr.identification.spans import input_range_of
from bmr.identification.table_choice import DEFAULT_INTERVALS, DEFAULT_SMOOTHING, TableChoice, choose_table_settings

__all__ = ["IdentificationReport", "identify", "run_cli", "METHODS"]

METHODS = ("auto", "forc", "lstsq", "both")
FRICTION_ONLY = "off-state run (friction fit only)"
EVALUATION = "evaluation run (held out, scored)"
NOT_TRAINED = "not a training run of this method"


@dataclass(repr=False)
class IdentificationReport:
    """What ``identify`` did, in the bundle's units (``quantities``).

    ``chosen``: the method whose tables the model holds; ``selection``: why. ``samples``: per run, how many samples
    the chosen tables were fitted on and why the others were not used. ``curves``: the first-order curves found
    (with each one's noise and move against its direction); ``table``: what building the CBH tables measured,
    fitted, derived and added (``bmr.TableReport.to_dict()``); ``lstsq``: the least-squares fit with every
    training run's offset, gain and initial state. ``scores``: per method, per scored run, RMS and largest error
    (output units) on held-out data; ``cv``: cross-validated RMS per method when the bundle has no evaluation run.
    ``out_of_range``: per scored run, inputs beyond the table's range and the largest excess. ``table_choice``:
    the least-squares table's resolution and smoothing and how cross-validation inside the training runs chose
    them (None when both were given).
    """

    method: str
    chosen: str
    selection: str
    quantities: Quantities
    input_range: tuple[float, float]
    output_range: tuple[float, float]
    friction: dict[str, Any] | None
    samples: SampleAccount
    curves: FirstOrderCurves | None = None
    table: dict[str, Any] | None = None
    lstsq: LstsqTables | None = None
    scores: dict[str, dict[str, dict[str, float]]] = field(default_factory=dict)
    cv: dict[str, float] | None = None
    out_of_range: dict[str, dict[str, float]] = field(default_factory=dict)
    time_s: dict[str, float] = field(default_factory=dict)
    table_choice: TableChoice | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe content (what the model file keeps in ``meta["identification"]``)."""
        q = self.quantities
        c = self.curves
        worst = c.worst_violation() if c is not None else None
        out: dict[str, Any] = {
            "method": self.method, "chosen": self.chosen, "selection": self.selection,
            "quantities": q.to_dict(), "units": {"input": q.input.unit, "output": q.output.unit},
            "input_range": list(self.input_range),
            "output_range": list(self.output_range), "friction": self.friction,
            "samples": self.samples.to_dict(),
            "heldout_rms": {m: {r: v["rms"] for r, v in runs.items()} for m, runs in self.scores.items()},
            "heldout": self.scores, "cv_rms": self.cv, "out_of_range": self.out_of_range,
            "time_s": dict(self.time_s),
        }
        if c is not None:
            out["forc_curves"] = {"ascending": len(c.ascending), "descending": len(c.descending),
                                  "noise": c.noise, "deadband": c.deadband,
                                  "fits": [f.to_dict() for f in c.fits],
                                  "worst_violation": worst.to_dict() if worst is not None else None}
        if self.table is not None:
            out["table"] = self.table
            out["forc_consistency"] = self.table.get("mismatch")
        if self.lstsq is not None:
            out["lstsq_fit"] = self.lstsq.to_dict()
        if self.table_choice is not None:
            out["table_choice"] = self.table_choice.to_dict()
        return out

    def __repr__(self) -> str:
        q = self.quantities
        i, o = q.input, q.output
        lo, hi = self.input_range
        lines = [f"IdentificationReport({self.method} -> {self.chosen}: {self.selection})",
                 f"  {i.name} {i.format(lo, 6)}..{i.format(hi, 6)} -> {o.name} "
                 f"{o.format(self.output_range[0], 6)}..{o.format(self.output_range[1], 6)}",
                 f"  {self.samples!r}"]
        if self.friction:
            lines.append(f"  friction: order {self.friction['order']}, residual RMS "
                         f"{o.format(self.friction['residual_rms_nmm'], 4)}")
        elif q.angle is None:
            lines.append("  friction: the device has no angle, none identified")
        c = self.curves
        if c is not None:
            w = c.worst_violation()
            lines.append(f"  first-order curves: {len(c.ascending)} ascending, {len(c.descending)} descending, "
                         f"noise {o.format(c.noise)}"
                         + (f"; largest move against a curve's direction {o.format(w.violation)} at "
                            f"{i.format(w.violation_input, 4)}" if w is not None else ""))
        t = self.table
        if t is not None:
            derived = f"{t['derived']} family derived ({t['derived_major']} major branch); " if t["derived"] else ""
            mm = t.get("mismatch")
            mism = f"families differ by {o.format(mm['max_abs'])} (RMS {o.format(mm['rms'])}); " if mm else ""
            nd = t["nodes"]
            lines.append(f"  tables: {derived}{mism}nodes {nd['ascending']['nodes']}/{nd['descending']['nodes']}, "
                         f"bound {o.format(max(nd['ascending']['tolerance'], nd['descending']['tolerance']))}")
        if self.lstsq is not None:
            lines.append(f"  {self.lstsq!r}")
        if self.table_choice is not None:
            lines.append(f"  {self.table_choice!r}")
        if self.cv:
            lines.append("  cross-validated RMS: " + ", ".join(f"{m} {o.format(v, 4)}" for m, v in self.cv.items()))
        for m, runs in self.scores.items():
            if runs:
                lines.append(f"  held-out RMS [{m}]: " + ", ".join(f"{r} {o.format(v['rms'], 4)} (max "
                                                                    f"{o.format(v['max'], 4)})"
                                                                    for r, v in runs.items()))
        if any(self.scores.values()):
            # The same runs give other figures in `bmr predict`, whose default fits each run's own offset.
            lines.append("  (held-out RMS with the model's common offset, which chooses the method; `bmr predict` "
                         "fits each run's own offset by default: --offset run)")
        for r, v in self.out_of_range.items():
            if v["count"]:
                lines.append(f"  {r}: {int(v['count'])} inputs beyond the table, up to {i.format(v['max_excess'], 4)}"
                             " (clamped)")
        return "\n".join(lines)


def _scores(pred: Prediction) -> dict[str, dict[str, float]]:
    return {r.name: {"rms": r.rms, "max": r.max_abs, "evaluated": float(r.evaluated)} for r in pred.runs}


def _mean_rms(scores: dict[str, dict[str, float]]) -> float:
    vals = [v["rms"] for v in scores.values() if math.isfinite(v["rms"])]
    return float(np.mean(vals)) if vals else math.inf


def _forc_model(curves: FirstOrderCurves, friction: Any, subdivisions: int, limits: dict[str, Any],
                quantities: Quantities) -> Model:
    """CBH tables from the curves: derived family if one is missing, curves added between measured reversals,
    grid nodes dropped only within a quarter of the curves' node noise."""
    ys = np.concatenate([np.asarray(y) for _, y in curves.ascending + curves.descending])
    span = float(np.ptp(ys)) or 1.0
    sig = float(np.median([f.node_sigma for f in curves.fits])) if curves.fits else 0.0
    build = {"subdivisions": int(subdivisions), "node_tolerance": min(0.25 * sig / span, 1e-3)}
    return Model.from_curves(curves.ascending, curves.descending, friction, limits=limits, build=build,
                             quantities=quantities)


def _lstsq_model(tables: LstsqTables, friction: Any, limits: dict[str, Any], quantities: Quantities) -> Model:
    return Model.from_curves(tables.ascending, tables.descending, friction, limits=limits, quantities=quantities)


def _held_curves(curves: FirstOrderCurves, fold: int) -> set[int]:
    """Every other non-major curve of each family (``fold`` 0 or 1)."""
    na = curves.n_ascending_found
    total = len(curves.fits)
    asc = [i for i in range(1, na) if i % 2 == fold]
    desc = [i for i in range(na, total - 1) if (i - na) % 2 == fold]
    return set(asc + desc)


def _cross_validate(protocol: Sequence[Run], curves: FirstOrderCurves, friction: Any, lo: float, hi: float,
                    n_intervals: int, smoothing: float, offsets: str, subdivisions: int,
                    deadband: float, grid: str) -> dict[str, float]:
    """RMS of each method on curves held out in two folds, both scored on the same samples."""
    sse = {"forc": 0.0, "lstsq": 0.0}
    count = 0
    for fold in (0, 1):
        held = _held_curves(curves, fold)
        if not held:
            continue
        masks = {r.name: np.isin(curves.membership[r.name], sorted(held)) for r in protocol}
        part = extract_first_order_curves(protocol, friction, deadband=deadband, input_range=(lo, hi),
                                          exclude_curves=held)
        forc = _forc_model(part, friction, subdivisions, {}, protocol[0].quantities)
        tables = fit_tables_lstsq(protocol, friction, n_intervals=n_intervals, input_range=(lo, hi),
                                  smoothing=smoothing, offsets=offsets, exclude=masks, grid=grid)
        lst = _lstsq_model(tables, friction, {}, protocol[0].quantities)
        for r in protocol:
            m = masks[r.name]
            if not m.any():
                continue
            theta = r.angle
            y = run_output(r)
            cal = tables.calibration(r.name)
            p_f = forc.simulate(run_input(r), theta)
            p_l = lst.simulate(run_input(r), theta, history=cal.history) - tables.offset + cal.offset
            sse["forc"] += float(np.sum((y[m] - p_f[m]) ** 2))
            sse["lstsq"] += float(np.sum((y[m] - p_l[m]) ** 2))
            count += int(m.sum())
    if count == 0:
        return {}
    return {k: math.sqrt(v / count) for k, v in sse.items()}


def identify(
    bundle: Bundle | str,
    *,
    method: str = "auto",
    max_order: int = DEFAULT_MAX_ORDER,
    n_intervals: int | None = None,
    smoothing: float | None = None,
    train_kinds: Sequence[str] | None = None,
    deadband: float | None = None,
    offsets: str = "per_run",
    gains: bool = False,
    initial_state: str = "estimate",
    subdivisions: int = 4,
    deadband_a: float | None = None,
    n_nodes: int | None = None,
    drift: str = "auto",
    input_range: tuple[float, float] | None = None,
    grid: str = DEFAULT_GRID,
    density: str = "auto",
) -> Model:
    """Identify friction and hysteresis from ``bundle`` and return a ``bmr.Model`` whose ``identification``
    (an :class:`IdentificationReport`) says what was done.

    ``method``: ``"auto"`` (default: both where possible, the better on held-out data: evaluation runs, else
    first-order curves held out in two folds), ``"forc"`` (first-order curves of the ``first_order_*`` runs; one
    family is enough), ``"lstsq"`` (Everett table by least squares from the runs of ``train_kinds``, default the
    ``first_order_*`` runs, or every non-off-state run when there are none) or ``"both"`` (as ``"auto"``, and
    an error when one of them is impossible). ``offsets``, ``gains``, ``initial_state``: the least-squares fit's
    per-run calibration (see ``fit_tables_lstsq``); ``drift``: its leakage term (default ``"auto"``: fitted with the
    table when the branches do not close and it closes them; the rate is in ``model.identification.lstsq``).
    ``input_range``: the tables' input range (default: the range the runs not held out measure). ``grid``: where
    the least-squares table's nodes lie: ``"auto"`` (default: adaptive for a family of first-order reversal
    curves), ``"uniform"`` or ``"adaptive"`` (finer where the branches switch and the runs reverse:
    :func:`~bmr.identification.lstsq.table_nodes`). ``density``: the least-squares table's cell masses,
    ``"auto"`` (default: free in sign when the training loops run clockwise, the output leading the input;
    nonnegative otherwise), ``"nonnegative"`` or ``"signed"``. A signed table is the model's forward core
    (``model.signed_table``); the model's CBH tables are then the nonnegative fit at the same setting, which a
    compensator inverts where the loops run counter-clockwise (a signed table has no exact inverse; with loops
    that run clockwise the model refuses a compensator). The loops' orientation and the density are in
    ``model.identification.lstsq``; with ``"auto"`` the table choice's cross-validation also takes the signed table
    when it predicts held-out blocks clearly better (``model.identification.table_choice.density``).
    ``n_intervals``, ``smoothing``: the least-squares table's resolution (grid intervals over the input range) and
    the weight of its density's smoothness; each one not given is chosen by cross-validation over time blocks of
    the training runs, trusted only where whole sweeps held out are predicted from the rest (else the default is
    kept: one major loop says nothing of the loops inside it)
    (:func:`~bmr.identification.table_choice.choose_table_settings`; the evaluation runs are never used), reported
    as ``model.identification.table_choice``.
    ``subdivisions``: curves added per interval between measured
    reversals of the first-order tables. ``deadband``: reversal dead-band in input units (``deadband_a``: its
    former name; ``n_nodes`` is ignored: curve nodes now follow the data).
    """
    if isinstance(bundle, str):
        bundle = read_bundle(bundle)
    if method not in METHODS:
        raise BmrError(f"unknown identification method {method!r}; use one of {', '.join(METHODS)}")
    if deadband is None:
        deadband = deadband_a
    t0 = time.perf_counter()
    q = bundle.quantities
    roles = bundle.roles(train_kinds)
    off_state, protocol, active = roles.off_state, roles.protocol, roles.active
    # Seal friction depends on the rotor angle: devices without one have none.
    friction = fit_friction(off_state, max_order=max_order) if off_state and q.angle is not None else None
    times: dict[str, float] = {"friction": time.perf_counter() - t0}
    if not active:
        raise BmrError("the bundle has no run besides off-state runs; nothing to identify the hysteresis from")
    if input_range is None:
        # Held-out runs never set the range: their inputs beyond it are counted as out of range when predicted.
        held_out = {id(r) for r in roles.evaluation}
        lo, hi = input_range_of([run_input(r) for r in active if id(r) not in held_out] or
                                [run_input(r) for r in active])
    else:
        lo, hi = (float(x) for x in input_range)
        if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
            raise BmrError(f"input_range must be two finite inputs, the lower first, got {input_range!r}")
    limits = {q.input.column: [lo, hi]}
    train, evaluation = roles.train, roles.evaluation

    candidates: dict[str, Model] = {}
    accounts: dict[str, SampleAccount] = {}
    curves: FirstOrderCurves | None = None
    tables: LstsqTables | None = None
    choice: TableChoice | None = None
    forc_error: BmrError | None = None
    if method in ("auto", "both", "forc"):
        if not protocol:
            forc_error = BmrError("the bundle has no first_order_ascending/descending run for the 'forc' method; "
                                  "use method='lstsq'")
        else:
            t = time.perf_counter()
            try:
                curves = extract_first_order_curves(protocol, friction, deadband=deadband, input_range=(lo, hi))
                candidates["forc"] = _forc_model(curves, friction, subdivisions, limits, q)
                accounts["forc"] = curves.samples
            except BmrError as exc:
                forc_error = exc
                curves = None
            times["forc"] = time.perf_counter() - t
        if forc_error is not None and method != "auto":
            raise forc_error
    if method in ("auto", "both", "lstsq"):
        if not train:
            raise BmrError("no runs to train the least-squares tables on")
        t = time.perf_counter()
        if n_intervals is None or smoothing is None:
            choice = choose_table_settings(train, friction, input_range=(lo, hi), n_intervals=n_intervals,
                                           smoothing=smoothing, offsets=offsets, gains=gains,
                                           initial_state=initial_state, drift=drift, grid=grid, density=density)
            n_intervals, smoothing = choice.n_intervals, choice.smoothing
            density = choice.density or density
            times["table_choice"] = time.perf_counter() - t
        reference = choice.reference if choice is not None else None
        if reference is not None and (reference.n_intervals, reference.settings["smoothing"]) == (n_intervals,
                                                                                                   smoothing) \
                and (choice is None or choice.density is None):
            tables = reference  # the folds' reference fit is the fit at the setting chosen
        else:
            tables = fit_tables_lstsq(train, friction, n_intervals=n_intervals, smoothing=smoothing,
                                      input_range=(lo, hi), offsets=offsets, gains=gains,
                                      initial_state=initial_state, drift=drift, grid=grid, density=density)
        if tables.signed:
            # The CBH tables (what the stages and the diagnosis run) come from the nonnegative fit at this setting;
            # the signed table is the forward core.
            monotone = fit_tables_lstsq(train, friction, n_intervals=n_intervals, smoothing=smoothing,
                                        input_range=(lo, hi), offsets=offsets, gains=gains,
                                        initial_state=initial_state, drift=drift, grid=grid, density="nonnegative")
            candidates["lstsq"] = _lstsq_model(monotone, friction, limits, q)
            candidates["lstsq"].signed_table = tables.everett
        else:
            candidates["lstsq"] = _lstsq_model(tables, friction, limits, q)
        accounts["lstsq"] = tables.samples
        times["lstsq"] = time.perf_counter() - t

    scores: dict[str, dict[str, dict[str, float]]] = {}
    for name, m in candidates.items():
        scores[name] = _scores(predict(m, evaluation)) if evaluation else {}
    cv = None
    if len(candidates) == 1:
        chosen = next(iter(candidates))
        selection = ("the only method asked for" if method in ("forc", "lstsq") else
                     "no first_order_* run: least squares" if not protocol else
                     f"first-order curves unusable ({forc_error})")
    elif evaluation:
        chosen = min(candidates, key=lambda k: _mean_rms(scores[k]))
        selection = f"lower mean held-out RMS over {len(evaluation)} evaluation run(s)"
    else:
        t = time.perf_counter()
        assert curves is not None
        cv = _cross_validate(protocol, curves, friction, lo, hi,
                             DEFAULT_INTERVALS if n_intervals is None else n_intervals,
                             DEFAULT_SMOOTHING if smoothing is None else smoothing, offsets, subdivisions,
                             curves.deadband, grid)
        times["cross_validation"] = time.perf_counter() - t
        if cv:
            chosen = min(cv, key=lambda k: cv[k])
            selection = "lower RMS on first-order curves held out in two folds (no evaluation run)"
        else:
            chosen, selection = "forc", "no curve to hold out; first-order curves by default"
    model = candidates[chosen]
    # Every sample of every run: used by the chosen tables, or why not.
    acc = SampleAccount()
    chosen_acc = accounts[chosen]
    for r in bundle.runs:
        if r.name in chosen_acc.runs:
            acc.runs[r.name] = chosen_acc.runs[r.name]
            continue
        n = len(r.data)
        acc.add_run(r.name, n)
        reason = (FRICTION_ONLY if r.kind == "off_state" else
                  EVALUATION if r.name in {e.name for e in evaluation} else NOT_TRAINED)
        acc.drop(r.name, reason, n)
    acc.check()
    out_of_range = {}
    for r in evaluation:
        count, excess = model.input_excess(run_input(r))
        out_of_range[r.name] = {"count": float(count), "max_excess": excess}
    times["total"] = time.perf_counter() - t0
    report = IdentificationReport(
        method=method, chosen=chosen, selection=selection, quantities=q, input_range=(lo, hi),
        output_range=tuple(model.hysteresis.output_range), friction=friction.to_dict() if friction else None,
        samples=acc, curves=curves, table=(model.hysteresis.build_report.to_dict()
                                           if model.hysteresis.build_report is not None else None),
        lstsq=tables, scores=scores, cv=cv, out_of_range=out_of_range, time_s=times, table_choice=choice)
    model.identification = report
    model.meta["identification"] = report.to_dict()
    return model


def run_cli(args: Any) -> int:
    """``bmr identify BUNDLE [--method M] [--intervals N] [--smoothing S] -o model.json``: identify, save, print
    the report."""
    check_output_file(args.out, "model file", error=ModelFileError)
    bundle = read_bundle(args.bundle)
    model = identify(bundle, method=args.method, n_intervals=args.intervals, smoothing=args.smoothing,
                     grid=args.grid, density=args.density)
    model.save(args.out)
    report = model.identification
    print(f"bmr identify: {bundle.actuator or args.bundle} ({len(bundle)} runs, {bundle.quantities.describe()}), "
          f"method {args.method} -> {report.chosen}, {report.time_s['total']:.2f} s")
    for line in repr(report).splitlines()[1:]:
        print(line)
    print(f"  wrote {args.out}")
    return 0
