"""Predicting measured runs with an identified model, as they come off the bench: held-out RMS and largest error per
run in the device's own units, in % of the model's output span and (when the runs carry the output's sigma) in
measurement sigmas, next to the single-valued baseline; and ``bmr predict MODEL BUNDLE`` (a table, the
``bmr-prediction/1`` JSON and a figure).

A run's own offset (sensor offset, remanence left by the previous run), gain and initial state are parameters of
the prediction, not hidden fits: they are given, taken from the model (its common offset), or estimated from a
stated number of leading ``calibration`` samples, which are then not scored; the initial state may also be carried
through the measurement history the run was recorded in (``initial="continue"``). Samples are scored from the point
where the run's state is known (``evaluate="known"``: after it has been to both saturation ends, when it gets
there) or all of them; every sample not scored is counted with its reason, a run whose state the input never
determines is flagged, and inputs beyond the table's range are counted with their largest excess (clamped, or
extrapolated along the major branches on request).

The runs' input and output are converted to the model's units (a model in V predicts runs logged in mV); quantities
of other dimensions are an error. The baseline is the best a model without hysteresis can do from the same
identification: the single-valued curve through the middle of the model's major loop (the mean of its ascending and
descending major branches), with the run's gain and offset found the same way.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from bmr._core import BmrError
from bmr.data.bundle import Bundle, Run, read_bundle, runs_of
from bmr.data.files import jsonable, write_json
from bmr.data.quantities import Quantities
from bmr.data.signals import output_rails
from bmr.data.units import format_number
from bmr.identification.extended import parts, simulate_extended
from bmr.identification.model import Model
from bmr.identification.signals import run_input, run_output, running_integral
from bmr.identification.spans import SATURATION_TOL, evaluation_start

__all__ = ["FORMAT", "RunPrediction", "Prediction", "predict", "single_valued_baseline", "run_cli", "CALIBRATION",
           "BEFORE_KNOWN_STATE", "AT_RANGE_END"]

FORMAT = "bmr-prediction/1"
CALIBRATION = "used to calibrate the run (offset or initial state), not scored"
BEFORE_KNOWN_STATE = "before the run's state is known (not scored)"
AT_RANGE_END = "held at the output's range end, the sensor's limit (not scored)"
BASELINE = "single-valued curve through the middle of the model's major loop"


def _rms(e: np.ndarray) -> float:
    return float(np.sqrt(np.mean(e * e))) if e.size else math.nan


def _max_abs(e: np.ndarray) -> float:
    return float(np.max(np.abs(e))) if e.size else math.nan


@dataclass
class RunPrediction:
    """One run: the scored error (output units and % of the model's output span), the calibration it was predicted
    with, the samples not scored by reason, and the whole run's arrays in the model's units: ``time``, ``input``,
    ``measured``, ``predicted`` (friction included when the model has it), ``baseline`` (the single-valued curve,
    calibrated alike), ``sigma`` (the output's per-sample sigma, or None) and ``scored`` (a mask)."""

    name: str
    role: str
    samples: int
    evaluated: int
    rms: float
    max_abs: float
    span: float
    offset: float
    offset_source: str
    gain: float
    initial: str
    state_known: bool
    out_of_range: int
    max_excess: float
    dropped: dict[str, int] = field(default_factory=dict)
    time: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    input: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    measured: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    predicted: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    baseline: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    sigma: np.ndarray | None = field(default=None, repr=False)
    scored: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool), repr=False)

    @property
    def residual(self) -> np.ndarray:
        """Measured minus predicted, NaN where not scored."""
        return np.where(self.scored, self.measured - self.predicted, np.nan)

    @property
    def baseline_residual(self) -> np.ndarray:
        return np.where(self.scored, self.measured - self.baseline, np.nan)

    @property
    def rms_pct(self) -> float:
        return 100.0 * self.rms / self.span

    @property
    def max_pct(self) -> float:
        return 100.0 * self.max_abs / self.span

    def stats(self) -> dict[str, Any]:
        """Every figure of the run: errors, the baseline's, in sigmas when the run has them, and how it was
        predicted."""
        b = (self.measured - self.baseline)[self.scored]
        out: dict[str, Any] = {
            "role": self.role, "samples": self.samples, "evaluated": self.evaluated, "rms": self.rms,
            "max_abs": self.max_abs, "rms_pct_span": self.rms_pct, "max_pct_span": self.max_pct,
            "baseline_rms": _rms(b), "baseline_max_abs": _max_abs(b),
            "offset": self.offset, "offset_source": self.offset_source, "gain": self.gain, "initial": self.initial,
            "state_known": self.state_known, "out_of_range": self.out_of_range, "max_excess": self.max_excess,
            "dropped": dict(self.dropped),
        }
        if self.sigma is not None:
            s = _rms(self.sigma[self.scored])
            out["sigma_rms"] = s
            for k in ("rms", "max_abs", "baseline_rms", "baseline_max_abs"):
                out[f"{k}_sigmas"] = out[k] / s if s > 0 else math.nan
        return out

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, **self.stats()}


@dataclass
class Prediction:
    """Every predicted run, with totals over all scored samples, in the model's quantities and units.
    ``out_of_range``: how inputs beyond the table were handled."""

    runs: list[RunPrediction]
    quantities: Quantities
    span: float
    out_of_range: str = "clamp"
    model_source: str = ""
    bundle_source: str = ""
    baseline: str = BASELINE
    ran: list[str] = field(default_factory=lambda: ["core tables"])

    @property
    def evaluated(self) -> int:
        return sum(r.evaluated for r in self.runs)

    @property
    def rms(self) -> float:
        n = self.evaluated
        return math.sqrt(sum(r.rms ** 2 * r.evaluated for r in self.runs if r.evaluated) / n) if n else math.nan

    @property
    def max_abs(self) -> float:
        vals = [r.max_abs for r in self.runs if r.evaluated]
        return max(vals) if vals else math.nan

    def run(self, name: str) -> RunPrediction:
        for r in self.runs:
            if r.name == name:
                return r
        raise BmrError(f"no predicted run named {name!r} (runs: {', '.join(r.name for r in self.runs)})")

    def total(self) -> dict[str, Any]:
        """The figures over every scored sample of every run."""
        e = np.concatenate([(r.measured - r.predicted)[r.scored] for r in self.runs])
        b = np.concatenate([(r.measured - r.baseline)[r.scored] for r in self.runs])
        out: dict[str, Any] = {"evaluated": int(e.size), "rms": _rms(e), "max_abs": _max_abs(e),
                               "rms_pct_span": 100.0 * _rms(e) / self.span,
                               "max_pct_span": 100.0 * _max_abs(e) / self.span,
                               "baseline_rms": _rms(b), "baseline_max_abs": _max_abs(b)}
        if self.runs and all(r.sigma is not None for r in self.runs):
            s = _rms(np.concatenate([r.sigma[r.scored] for r in self.runs if r.sigma is not None]))
            out["sigma_rms"] = s
            for k in ("rms", "max_abs", "baseline_rms", "baseline_max_abs"):
                out[f"{k}_sigmas"] = out[k] / s if s > 0 else math.nan
        return out

    def to_dict(self) -> dict[str, Any]:
        """The ``bmr-prediction/1`` JSON content (non-finite numbers as null)."""
        return jsonable({
            "format": FORMAT, "model": self.model_source, "bundle": self.bundle_source,
            "quantities": self.quantities.to_dict(), "output_unit": self.quantities.output.unit,
            "output_span": self.span, "out_of_range": self.out_of_range, "baseline": self.baseline,
            "ran": list(self.ran),
            "runs": {r.name: r.stats() for r in self.runs}, "total": self.total(),
        })

    def write_json(self, path: str | Path) -> Path:
        return write_json(path, self.to_dict(), what="prediction")

    def figure(self, path: str | Path) -> Path:
        """PNG: per run, measured and predicted output against the input (with the baseline), and the residual
        along the run."""
        from bmr.report.prediction import prediction_figure

        return prediction_figure(self, Path(path))

    def table(self) -> str:
        """One line per run and a total: RMS and max in the output unit, % of span, sigmas, the baseline; then
        what was not scored and why, and inputs beyond the table."""
        q = self.quantities
        u = q.output.unit
        sig = bool(self.runs) and all(r.sigma is not None for r in self.runs)
        head = ["run", "evaluated", f"RMS ({u})", f"max ({u})", "RMS % span", "max % span"]
        head += ["RMS (sigma)", "max (sigma)"] if sig else []
        head += [f"baseline RMS ({u})", f"baseline max ({u})"]
        rows = [head]

        def line(name: str, st: dict[str, Any]) -> list[str]:
            cells = [name, str(st["evaluated"]), format_number(st["rms"]), format_number(st["max_abs"]),
                     format_number(st["rms_pct_span"]), format_number(st["max_pct_span"])]
            if sig:
                cells += [format_number(st["rms_sigmas"]), format_number(st["max_abs_sigmas"])]
            return cells + [format_number(st["baseline_rms"]), format_number(st["baseline_max_abs"])]

        for r in self.runs:
            rows.append(line(r.name + ("" if r.state_known else " *"), r.stats()))
        if len(self.runs) > 1:
            rows.append(line("all", self.total()))
        widths = [max(len(row[k]) for row in rows) for k in range(len(head))]
        text = ["  ".join(c.rjust(w) if k else c.ljust(w) for k, (c, w) in enumerate(zip(row, widths)))
                for row in rows]
        for r in self.runs:
            state = f"{r.name}: {r.initial}; offset {q.output.format(r.offset, 6)} ({r.offset_source})"
            text.append(("* " if not r.state_known else "") + state + (f", gain {r.gain:.6g}" if r.gain != 1 else ""))
            text += [f"{r.name}: {n} sample(s) {why}" for why, n in r.dropped.items()]
            if r.out_of_range:
                text.append(f"{r.name}: {r.out_of_range} sample(s) outside the model's input range (largest excess "
                            f"{q.input.format(r.max_excess)}; {self.out_of_range}ed)")
        return "\n".join(text)

    def __repr__(self) -> str:
        q = self.quantities
        o = q.output
        lines = [f"Prediction of {o.label} from {q.input.label}: RMS {o.format(self.rms, 4)}, max "
                 f"{o.format(self.max_abs, 4)} over {self.evaluated} scored samples"]
        for r in self.runs:
            extra = (f", {r.out_of_range} inputs beyond the table (up to {q.input.format(r.max_excess, 4)})"
                     if r.out_of_range else "")
            lines.append(f"  {r.name}: RMS {o.format(r.rms, 4)} ({r.rms_pct:.3g} % of span), max "
                         f"{o.format(r.max_abs, 4)} ({r.max_pct:.3g} %), {r.evaluated}/{r.samples} scored, offset "
                         f"{o.format(r.offset, 6)} ({r.offset_source}), {r.initial}{extra}")
        return "\n".join(lines)





def _per_run(value: Any, name: str, default: Any) -> Any:
    if isinstance(value, Mapping):
        return value.get(name, default)
    return value


def _describe(initial: Any, history: Sequence[float]) -> str:
    start = initial if isinstance(initial, str) else f"{initial[0]} branch at {initial[1]:.6g}"
    if not len(history):
        return f"from {start} saturation" if initial in ("negative", "positive") else f"from {start}"
    if len(history) == 1:
        return f"from negative saturation up to {history[0]:.6g}"
    if len(history) == 2:
        return f"from positive saturation down to {history[1]:.6g}"
    return f"from history {list(history)}"


def _offset_prior(model: Any) -> dict[str, float] | None:
    """The training runs' offset spread and leading-sample error, when the model was fitted by least squares on
    at least two runs."""
    ident = getattr(model, "meta", {}).get("identification") or {}
    prior = (ident.get("lstsq_fit") or {}).get("offset_prior") if ident.get("chosen") == "lstsq" else None
    if not prior:
        return None
    # A model file stores an unknown figure as null (one training run has no spread).
    values = {k: prior.get(k) for k in ("spread", "first_sample_error")}
    if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in values.values()):
        return None
    return {k: float(v) for k, v in values.items()}


def _core_name(model: Model) -> str:
    """What ran as the model's core: its CBH tables, or its signed table and why it is signed."""
    if model.signed_table is None:
        return "core tables"
    if model.signed_loops_turn_clockwise():
        return "signed table (loops run clockwise)"
    return "signed table (negative density regions)"


def _identified_leakage(model: Any) -> float | None:
    """The leakage rate (output per input·s) least squares fitted with the tables, when the model holds one: the
    tables alone describe the sample, the measured output also integrates the leakage current."""
    ident = getattr(model, "meta", {}).get("identification") or {}
    rate = (ident.get("lstsq_fit") or {}).get("leakage_rate") if ident.get("chosen") == "lstsq" else None
    return float(rate) if isinstance(rate, (int, float)) and math.isfinite(rate) and rate != 0.0 else None


def _run_gain(model: Any, y: np.ndarray, p: np.ndarray, y_lo: float) -> tuple[float, str]:
    """A run's gain on the model output about ``y_lo`` (with a free offset) when the training runs' fitted gains
    spread, shrunk towards 1 by that spread; ``(1, "")`` otherwise."""
    ident = getattr(model, "meta", {}).get("identification") or {}
    runs = (ident.get("lstsq_fit") or {}).get("runs") or []
    gains = np.array([r.get("gain") for r in runs if isinstance(r.get("gain"), (int, float))], dtype=float)
    tau = float(np.std(gains, ddof=1)) if gains.size > 1 else 0.0
    x = p - y_lo
    if not (tau > 0 and math.isfinite(tau)) or y.size < 3 or float(np.var(x)) <= 0:
        return 1.0, ""
    xc, yc = x - x.mean(), y - y.mean()
    g_ls = float(xc @ yc / (xc @ xc))
    var = float(np.var(yc - g_ls * xc)) / float(xc @ xc)
    weight = tau ** 2 / (tau ** 2 + var)
    g = 1.0 + weight * (g_ls - 1.0)
    if not (math.isfinite(g) and g > 0):
        return 1.0, ""
    return g, f"; gain {g:.4g} fitted on them (shrunk towards 1 by the training runs' gain spread {tau:.3g})"


def _candidates(model: Any, u0: float) -> list[list[float]]:
    """Initial memories for a run starting at ``u0``: negative or positive saturation, or one reversal after either
    at every node of the model's ascending grid."""
    lo, hi = model.hysteresis.input_range
    asc, _ = model.hysteresis.curves()
    nodes = np.unique(np.concatenate([np.asarray(c[0], dtype=float) for c in asc]))
    step = max(1, nodes.size // 64)
    out: list[list[float]] = [[], [hi]]
    for x in nodes[::step]:
        if u0 < x < hi:
            out.append([float(x)])
        if lo < x < u0:
            out.append([hi, float(x)])
    return out


def _branches(model: Model) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """The major ascending branch (from the lowest reversal) and the major descending branch (from the highest),
    both with increasing input."""
    asc, desc = model.hysteresis.curves()
    a = min(asc, key=lambda c: float(np.asarray(c[0])[0]))
    d = max(desc, key=lambda c: float(np.asarray(c[0])[0]))
    ua, ya = (np.asarray(v, dtype=float) for v in a)
    ud, yd = (np.asarray(v, dtype=float)[::-1] for v in d)
    return (ua, ya), (ud, yd)


def single_valued_baseline(model: Model, u: np.ndarray) -> np.ndarray:
    """The mean of the model's major branches at ``u`` (held at their ends outside the input range)."""
    (ua, ya), (ud, yd) = _branches(model)
    return 0.5 * (np.interp(u, ua, ya) + np.interp(u, ud, yd))


def _converters(model: Model, run: Run) -> tuple[tuple[float, float], tuple[float, float]]:
    """``(scale, shift)`` of the input and of the output that bring the run's values into the model's units
    (``BmrError`` when the quantities differ in dimension, e.g. a model of torque and a run of displacement)."""
    out = []
    for role in ("input", "output"):
        a, b = getattr(model.quantities, role), getattr(run.quantities, role)
        if a.unit == b.unit:
            out.append((1.0, 0.0))
            continue
        if a.dimension != b.dimension:
            raise BmrError(f"run {run.name!r}: the model's {role} is {a.label} but the run's is {b.label}: they do "
                           "not convert")
        zero = float(a.from_unit(0.0, b.unit))
        out.append((float(a.from_unit(1.0, b.unit)) - zero, zero))
    return out[0], out[1]


CONTINUE_ALTERNATIVES = "use initial 'negative', 'positive' or 'estimate'"


@dataclass
class _Continued:
    """A measurement history run through the model in one piece: each run's model output (core units, before gain
    and offset), where the run starts in the concatenation, and the history's sample from which the state is
    known (0 when it starts at an end of the range; None when it neither starts at one nor reaches both, so its
    start is the assumed negative saturation)."""

    outputs: dict[str, np.ndarray]
    starts: dict[str, int]
    known_from: int | None


def _continued(model: Model, history: list[Run], extended: bool, out_of_range: str, tol: float) -> _Continued:
    """Every run of ``history`` predicted as one recording from negative saturation: each run starts from the
    state the model holds at the end of the previous one. Only inputs (and angles) are used, so held-out runs'
    outputs never enter. The extended model runs the concatenation once (its stages' state is carried along;
    the time between runs is not)."""
    lo, hi = model.hysteresis.input_range
    inputs, thetas, frictions = [], [], []
    for r in history:
        (si, oi), (so, oo) = _converters(model, r)
        inputs.append(run_input(r) * si + oi)
        thetas.append(r.angle if r.angle is not None else np.zeros(len(r.time)))
        measured = run_output(r, None) * so + oo
        frictions.append(measured - (run_output(r, model.friction) * so + oo))
    u = np.concatenate(inputs)
    if extended:
        first = history[0]
        dt = float(np.median(np.diff(first.time))) if len(first.time) > 1 else 1.0
        whole = simulate_extended(model, u, np.concatenate(thetas), dt_s=dt, t0_s=float(first.time[0]),
                                  initial="negative") - np.concatenate(frictions)
    else:
        whole = model.simulate(u, out_of_range=out_of_range)
    bounds = np.cumsum([0] + [x.size for x in inputs])
    # Known from the start when the history starts at an end of the range (as a single run is), else from where
    # it has been to both ends.
    reached = bool(np.any(u >= hi - tol)) and bool(np.any(u <= lo + tol))
    known_from = 0 if (u[0] <= lo + tol or u[0] >= hi - tol) else evaluation_start(u, lo, hi, tol) if reached else None
    return _Continued({r.name: whole[a:b] for r, a, b in zip(history, bounds[:-1], bounds[1:])},
                      {r.name: int(a) for r, a in zip(history, bounds[:-1])}, known_from)


def predict(
    model: Model | str | Path,
    runs: Bundle | Run | Iterable[Run] | str | Path,
    *,
    offset: Any = "model",
    gain: Any = 1.0,
    initial: Any = "negative",
    calibration: int = 0,
    evaluate: str = "known",
    out_of_range: str = "clamp",
    whole_model: bool = True,
    bundle: Bundle | None = None,
) -> Prediction:
    """Predict ``runs`` (a bundle's evaluation runs, or all its non-off-state runs when none is held out; one run;
    a list; or a bundle folder) with ``model`` (or a model file) and score them.

    ``offset``: ``"model"`` (the model's own output level), ``"run"`` (the run's own, fitted on its scored
    samples and shrunk towards the model's by how much the training runs' offsets spread; with a gain fitted
    alike when the training runs' gains spread), ``"first"`` (shift so the ``calibration`` leading
    samples are matched on average; needs ``calibration >= 1``), ``"shrunk"`` (that shift shrunk towards the
    model's common offset, weighted by how much the training runs' offsets spread and how far one leading sample
    fell from a training run's fitted offset; ``"first"`` when the model has no such record), a number, or
    ``{run name: number}``. ``gain``: the
    run's gain on the model output about its output at negative saturation (a number or ``{name: number}``).
    ``initial``: ``"negative"``, ``"positive"``, ``("ascending", u)``, ``("descending", u)``, a history of inputs
    after negative saturation (``{name: ...}`` per run), or ``"estimate"`` (the memory among negative or positive
    saturation and one reversal after either that best predicts the ``calibration`` leading samples, or the whole
    run when ``calibration`` is 0 — then the state is fitted on the scored samples, and the result says so), or
    ``"continue"``: the run is part of a measurement history (``Bundle.histories``) and starts from the state the
    model holds at the end of the previous run, the model having run over every earlier run's input from negative
    saturation (identification and held-out runs alike; no run's output is used); its samples are scored from
    where the history's state is known. ``bundle``: the bundle the runs belong to (for ``"continue"``; taken from
    ``runs`` when that is a bundle).
    ``evaluate``: ``"known"`` scores from the sample where the run has been to both saturation ends (all samples
    when it never gets there) or ``"all"``. ``out_of_range``: ``"clamp"`` or ``"extrapolate"`` (see
    ``Model.simulate``). Friction is added when the model has it and the run has an angle; the leakage least squares
    fitted with the tables (open branches) along the run's ``∫u dt`` from its first sample. A model with
    extensions (``bmr diagnose --model-out``) runs whole — its stages, learned term and offset through
    ``bmr.ExtendedSimulation``, from a saturation — unless ``whole_model`` is False (the core tables alone);
    ``Prediction.ran`` names what ran.
    """
    model_source = str(model) if isinstance(model, (str, Path)) else ""
    bundle_source = str(runs) if isinstance(runs, (str, Path)) else ""
    if isinstance(model, (str, Path)):
        model = Model.load(model)
    if isinstance(runs, (str, Path)):
        runs = read_bundle(runs)
    if isinstance(runs, Bundle):
        bundle = runs
    rs = runs_of(runs, scored=True)
    if not rs:
        raise BmrError("predict needs at least one run")
    if evaluate not in ("known", "all"):
        raise BmrError(f"evaluate must be 'known' or 'all', got {evaluate!r}")
    if not (isinstance(calibration, (int, np.integer)) and calibration >= 0) or isinstance(calibration, bool):
        raise BmrError(f"calibration must be a nonnegative number of samples, got {calibration!r}")
    lo, hi = model.hysteresis.input_range
    y_lo, y_hi = model.hysteresis.output_range
    span = y_hi - y_lo
    extended = bool(model.extensions) and whole_model
    # An extended model carries its leakage as a stage; the nominal model adds the one fitted with its tables.
    leakage = None if extended or not whole_model else _identified_leakage(model)
    tol = SATURATION_TOL * (hi - lo)
    continued: dict[str, _Continued] = {}
    # The output's range ends over the whole recording (a sensor at its limit): those samples are not scored.
    rails = output_rails([(x.input, x.output) for x in (bundle.runs if bundle is not None else rs)])
    out = []
    for r in rs:
        (si, oi), (so, oo) = _converters(model, r)
        u = run_input(r) * si + oi
        measured = run_output(r, None) * so + oo
        friction = measured - (run_output(r, model.friction) * so + oo)  # zero without friction or angle
        y = measured - friction  # compare the hysteresis: friction removed from the measurement
        sigma = np.asarray(r.output_sigma, dtype=float) * abs(so) if r.output_sigma is not None else None
        n = u.size
        k = int(calibration)
        if k >= n:
            raise BmrError(f"run {r.name!r}: calibration uses {k} samples but the run has {n}")
        init = _per_run(initial, r.name, "negative")
        g = float(_per_run(gain, r.name, 1.0))
        if not (math.isfinite(g) and g > 0):
            raise BmrError(f"run {r.name!r}: gain must be positive and finite, got {g!r}")
        fit_slice = slice(0, k) if k else slice(0, n)
        history: list[float] = []
        start: Any = "negative"
        estimated = False
        cont: _Continued | None = None
        if isinstance(init, str) and init == "continue":
            if bundle is None:
                raise BmrError(f"initial 'continue' needs the bundle run {r.name!r} was recorded in (pass bundle=); "
                               f"or {CONTINUE_ALTERNATIVES}")
            history_runs = bundle.history_of(r.name)
            if not history_runs:
                why = ("the bundle records no measurement history" if not bundle.histories else
                       f"run {r.name!r} is in none of the bundle's measurement histories")
                raise BmrError(f"initial 'continue': {why}; {CONTINUE_ALTERNATIVES}")
            key = history_runs[0].name
            if key not in continued:
                continued[key] = _continued(model, history_runs, extended, out_of_range, tol)
            cont = continued[key]
            position = [h.name for h in history_runs].index(r.name)
            state = (f"continuing the history from {history_runs[0].name} (run {position + 1} of "
                     f"{len(history_runs)})")
        elif isinstance(init, str) and init == "estimate":
            best = None
            for cand in _candidates(model, float(u[0])):
                p = y_lo + g * (model.simulate(u, history=cand) - y_lo)
                res = y[fit_slice] - p[fit_slice]
                rss = float(np.sum((res - res.mean()) ** 2))
                if best is None or rss < best[0]:
                    best = (rss, cand)
            history = list(best[1]) if best is not None else []
            state = _describe("negative", history) + (" (estimated on the scored samples)" if not k else
                                                       f" (estimated on {k} leading samples)")
            estimated = True
        elif isinstance(init, (str, tuple)):
            start = init
            state = _describe(init, [])
        else:
            history = [float(x) for x in init]
            state = _describe("negative", history)
        if cont is not None:
            p = cont.outputs[r.name]
        elif extended:
            # The whole model: its stages, learned term and offset in the Rust forward chain, from saturation.
            if estimated or history or not isinstance(start, str):
                raise BmrError(f"run {r.name!r}: the extended model runs from a saturation: use initial "
                               "'negative' or 'positive'")
            theta = r.angle if r.angle is not None else np.zeros(n)
            dt = float(np.median(np.diff(r.time))) if n > 1 else 1.0
            p = simulate_extended(model, u, theta, dt_s=dt, t0_s=float(r.time[0]), initial=start) - friction
        else:
            p = model.simulate(u, initial=start, history=history, out_of_range=out_of_range)
        p = y_lo + g * (p - y_lo)
        if leakage is not None:
            p = p + leakage * running_integral(u, r.time)
        base = y_lo + g * (single_valued_baseline(model, u) - y_lo)
        dropped: dict[str, int] = {}
        first = k
        if k:
            dropped[CALIBRATION] = k
        top = bool(np.any(u >= hi - tol))
        bottom = bool(np.any(u <= lo + tol))
        if cont is not None:
            # The state is known from where the history has been to both ends (before this run, or inside it).
            if evaluate == "known" and cont.known_from is not None:
                s = max(0, cont.known_from - cont.starts[r.name])
                if s > first:
                    dropped[BEFORE_KNOWN_STATE] = min(s, n) - first
                    first = min(s, n)
        elif evaluate == "known" and top and bottom:
            s = evaluation_start(u, lo, hi, tol)
            if s > first:
                dropped[BEFORE_KNOWN_STATE] = s - first
                first = s
        scored = np.zeros(n, dtype=bool)
        scored[first:] = True
        if rails.any:
            at_rail = rails.mask(r.output) & scored
            if np.any(at_rail):
                dropped[AT_RANGE_END] = int(np.count_nonzero(at_rail))
                scored &= ~at_rail
        off_spec = _per_run(offset, r.name, "model")
        if isinstance(off_spec, str):
            if off_spec == "model":
                shift = shift_b = 0.0
                source = "the model's"
            elif off_spec == "run":
                g, gain_note = _run_gain(model, y[scored], p[scored], y_lo) if g == 1.0 else (g, "")
                p = y_lo + g * (p - y_lo)
                base = y_lo + g * (base - y_lo)
                res = y[scored] - p[scored]
                spread = (_offset_prior(model) or {}).get("spread")
                # The run's own offset, shrunk towards the model's by how much training runs' offsets spread.
                s2 = float(np.var(res)) / res.size if res.size else 0.0
                weight = spread ** 2 / (spread ** 2 + s2) if spread is not None and spread ** 2 + s2 > 0 else 1.0
                shift = weight * (float(np.mean(res)) if res.size else 0.0)
                shift_b = weight * (float(np.mean(y[scored] - base[scored])) if res.size else 0.0)
                source = (f"the run's own, fitted on its {res.size} scored samples"
                          + (f", {weight:.2f} × that + {1 - weight:.2f} × the model's (spread {spread:.3g} between "
                             f"training runs)" if spread is not None else "") + gain_note)
            elif off_spec in ("first", "shrunk"):
                if k == 0:
                    raise BmrError(f"offset={off_spec!r} needs calibration >= 1 leading samples")
                shift = float(np.mean(y[:k] - p[:k]))
                shift_b = float(np.mean(y[:k] - base[:k]))
                source = f"from {k} leading sample{'s' if k > 1 else ''}"
                prior = _offset_prior(model)
                if off_spec == "shrunk" and prior is not None:
                    tau2, s2 = prior["spread"] ** 2, prior["first_sample_error"] ** 2 / k
                    weight = tau2 / (tau2 + s2) if tau2 + s2 > 0 else 1.0
                    shift *= weight
                    shift_b *= weight
                    source = (f"{weight:.2f} × {k} leading sample{'s' if k > 1 else ''} + {1 - weight:.2f} × the "
                              f"model's (spread {prior['spread']:.3g} between training runs, leading-sample "
                              f"error {prior['first_sample_error']:.3g})")
            else:
                raise BmrError(f"offset must be 'model', 'run', 'first', 'shrunk', a number or {{run: number}}, "
                               f"got {off_spec!r}")
        else:
            shift = shift_b = float(off_spec) - y_lo
            source = "given"
        p = p + shift
        base = base + shift_b
        # The state is determined once the input has been to both ends, or from the start when it starts at one;
        # otherwise it is the stated (or estimated) assumption, and the run is flagged.
        known = (top and bottom) or bool(u[0] <= lo + tol or u[0] >= hi - tol) or estimated
        if cont is not None:
            known = cont.known_from is not None and cont.known_from < cont.starts[r.name] + n
        if not known:
            state += " (assumed: the input never reaches both ends of the model's range)"
        e = (y - p)[scored]
        count, excess = model.input_excess(u)
        out.append(RunPrediction(
            name=r.name, role="identification" if r.is_identification else "evaluation", samples=n,
            evaluated=int(e.size), rms=_rms(e), max_abs=_max_abs(e), span=span, offset=y_lo + shift,
            offset_source=source, gain=g, initial=state, state_known=known, out_of_range=count, max_excess=excess,
            dropped=dropped, time=r.time, input=u, measured=measured, predicted=p + friction,
            baseline=base + friction, sigma=sigma, scored=scored))
    return Prediction(out, model.quantities, span, out_of_range, model_source, bundle_source,
                      ran=parts(model) if extended else
                      [_core_name(model)]
                      + (["leakage identified with the tables"] if leakage is not None else []))


def run_cli(args: Any) -> int:
    """``bmr predict MODEL BUNDLE [--runs ...] [--offset ...] [--calibration N] [--initial ...] [--json OUT]
    [--figure OUT.png]``."""
    for target in (args.json_out, args.figure):
        if target is not None:
            parent = Path(target).resolve().parent
            if not parent.is_dir():
                raise BmrError(f"cannot write {target!r}: folder {str(parent)!r} does not exist")
    model = Model.load(args.model)
    bundle = read_bundle(args.bundle)
    names = [n.strip() for item in args.runs for n in item.split(",") if n.strip()]
    if names:
        runs = [bundle.run(n) for n in names]
    else:
        runs = bundle.evaluation_runs()
        if not runs:
            raise BmrError(f"{args.bundle}: the bundle has no evaluation runs (hold runs out with `bmr import "
                           "--holdout`, or the end of one long recording with `--holdout-tail 0.3`, or name the "
                           "runs to predict with --runs)")
    calibration = args.calibration if args.calibration is not None else (1 if args.offset in ("first", "shrunk")
                                                                         else 0)
    p = predict(model, runs, offset=args.offset, calibration=calibration, initial=args.initial,
                evaluate=args.evaluate, out_of_range=args.out_of_range, bundle=bundle)
    p.model_source, p.bundle_source = str(args.model), str(args.bundle)
    q = p.quantities
    print(f"bmr predict: {args.model} ({q.describe()}) on {args.bundle}: {len(p.runs)} run(s); output span "
          f"{q.output.format(p.span)}; ran: {', '.join(p.ran)}; baseline: {p.baseline}")
    for line in p.table().splitlines():
        print(f"  {line}")
    if args.json_out:
        p.write_json(args.json_out)
        print(f"  wrote {args.json_out}")
    if args.figure:
        p.figure(args.figure)
        print(f"  wrote {args.figure}")
    return 0
