"""Predicting measured runs with an identified model, as they come off the bench: held-out RMS and largest error
per run, in the device's own units and in % of the model's output span, with every calibration made explicit.

A run's own offset (sensor offset, remanence left by the previous run), gain and initial state are parameters of
the prediction, not hidden fits: they are given, taken from the model (its common offset), or estimated from a
stated number of leading ``calibration`` samples, which are then not scored. Samples are scored from the point
where the run's state is known (``evaluate="known"``: after it has been to both saturation ends, when it gets
there) or all of them; every sample not scored is counted with its reason, and inputs beyond the table's range
are counted with their largest excess (clamped, or extrapolated along the major branches on request)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from bmr._core import BmrError
from bmr.data.bundle import Bundle, Run
from bmr.identification.signals import ACTUATOR, Quantities, quantities_of, run_input, run_output
from bmr.identification.spans import SATURATION_TOL, evaluation_start

__all__ = ["RunPrediction", "Prediction", "predict", "CALIBRATION", "BEFORE_KNOWN_STATE"]

CALIBRATION = "used to calibrate the run (offset or initial state), not scored"
BEFORE_KNOWN_STATE = "before the run's state is known (not scored)"


@dataclass
class RunPrediction:
    """One run: its predicted output (as measured: friction included when the model has it), the scored error
    (output units and % of the model's output span; ``residual`` is NaN where not scored), the calibration it was
    predicted with, and the samples not scored by reason."""

    name: str
    samples: int
    evaluated: int
    rms: float
    max_abs: float
    span: float
    offset: float
    offset_source: str
    gain: float
    initial: str
    out_of_range: int
    max_excess: float
    dropped: dict[str, int] = field(default_factory=dict)
    output: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    residual: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)

    @property
    def rms_pct(self) -> float:
        return 100.0 * self.rms / self.span

    @property
    def max_pct(self) -> float:
        return 100.0 * self.max_abs / self.span

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "samples": self.samples, "evaluated": self.evaluated, "rms": self.rms,
                "max_abs": self.max_abs, "rms_pct_span": self.rms_pct, "max_pct_span": self.max_pct,
                "offset": self.offset, "offset_source": self.offset_source, "gain": self.gain,
                "initial": self.initial, "out_of_range": self.out_of_range, "max_excess": self.max_excess,
                "dropped": dict(self.dropped)}


@dataclass
class Prediction:
    """Every predicted run, with totals over all scored samples. ``quantities`` names the input and output and
    their units; ``out_of_range``: how inputs beyond the table were handled."""

    runs: list[RunPrediction]
    quantities: Quantities = ACTUATOR
    out_of_range: str = "clamp"

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

    def to_dict(self) -> dict[str, Any]:
        return {"quantities": self.quantities.to_dict(), "out_of_range": self.out_of_range,
                "rms": self.rms, "max_abs": self.max_abs, "evaluated": self.evaluated,
                "runs": [r.to_dict() for r in self.runs]}

    def __repr__(self) -> str:
        q = self.quantities
        lines = [f"Prediction of {q.output_name} ({q.output_unit}) from {q.input_name} ({q.input_unit}): RMS "
                 f"{self.rms:.4g}, max {self.max_abs:.4g} over {self.evaluated} scored samples"]
        for r in self.runs:
            extra = f", {r.out_of_range} inputs beyond the table (up to {r.max_excess:.4g})" if r.out_of_range else ""
            lines.append(f"  {r.name}: RMS {r.rms:.4g} ({r.rms_pct:.3g} % of span), max {r.max_abs:.4g} "
                         f"({r.max_pct:.3g} %), {r.evaluated}/{r.samples} scored, offset {r.offset:.6g} "
                         f"({r.offset_source}), {r.initial}{extra}")
        return "\n".join(lines)


def _runs_of(runs: Bundle | Run | Iterable[Run]) -> list[Run]:
    if isinstance(runs, Bundle):
        return [r for r in runs.runs if r.kind != "off_state"]
    if isinstance(runs, Run):
        return [runs]
    return list(runs)


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
    if not prior or not all(math.isfinite(prior.get(k, math.nan)) for k in ("spread", "first_sample_error")):
        return None
    return prior


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


def predict(
    model: Any,
    runs: Bundle | Run | Iterable[Run],
    *,
    offset: Any = "model",
    gain: Any = 1.0,
    initial: Any = "negative",
    calibration: int = 0,
    evaluate: str = "known",
    out_of_range: str = "clamp",
    quantities: Quantities | None = None,
) -> Prediction:
    """Predict ``runs`` (a bundle's non-off-state runs, one run or a list) with ``model`` and score them.

    ``offset``: ``"model"`` (the model's own output level), ``"first"`` (shift so the ``calibration`` leading
    samples are matched on average; needs ``calibration >= 1``), ``"shrunk"`` (that shift shrunk towards the
    model's common offset, weighted by how much the training runs' offsets spread and how far one leading sample
    fell from a training run's fitted offset; ``"first"`` when the model has no such record), a number, or
    ``{run name: number}``. ``gain``: the
    run's gain on the model output about its output at negative saturation (a number or ``{name: number}``).
    ``initial``: ``"negative"``, ``"positive"``, ``("ascending", u)``, ``("descending", u)``, a history of inputs
    after negative saturation (``{name: ...}`` per run), or ``"estimate"`` (the memory among negative or positive
    saturation and one reversal after either that best predicts the ``calibration`` leading samples, or the whole
    run when ``calibration`` is 0 — then the state is fitted on the scored samples, and the result says so).
    ``evaluate``: ``"known"`` scores from the sample where the run has been to both saturation ends (all samples
    when it never gets there) or ``"all"``. ``out_of_range``: ``"clamp"`` or ``"extrapolate"`` (see
    ``Model.simulate``). Friction is added when the model has it and the run has an angle.
    """
    rs = _runs_of(runs)
    if not rs:
        raise BmrError("predict needs at least one run")
    if evaluate not in ("known", "all"):
        raise BmrError(f"evaluate must be 'known' or 'all', got {evaluate!r}")
    if not (isinstance(calibration, (int, np.integer)) and calibration >= 0) or isinstance(calibration, bool):
        raise BmrError(f"calibration must be a nonnegative number of samples, got {calibration!r}")
    q = quantities or (quantities_of(runs) if isinstance(runs, Bundle) else ACTUATOR)
    lo, hi = model.hysteresis.input_range
    y_lo, y_hi = model.hysteresis.output_range
    span = y_hi - y_lo
    out = []
    for r in rs:
        u = run_input(r)
        y = run_output(r, model.friction)  # friction removed from the measurement: compare the hysteresis
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
        if isinstance(init, str) and init == "estimate":
            best = None
            for cand in _candidates(model, float(u[0])):
                p = y_lo + g * (model.simulate(u, history=cand) - y_lo)
                res = y[fit_slice] - p[fit_slice]
                rss = float(np.sum((res - res.mean()) ** 2))
                if best is None or rss < best[0]:
                    best = (rss, cand)
            history = list(best[1])
            state = _describe("negative", history) + (" (estimated on the scored samples)" if not k else
                                                       f" (estimated on {k} leading samples)")
        elif isinstance(init, (str, tuple)):
            start = init
            state = _describe(init, [])
        else:
            history = [float(x) for x in init]
            state = _describe("negative", history)
        p = model.simulate(u, initial=start, history=history, out_of_range=out_of_range)
        p = y_lo + g * (p - y_lo)
        off_spec = _per_run(offset, r.name, "model")
        if isinstance(off_spec, str):
            if off_spec == "model":
                shift, source = 0.0, "the model's"
            elif off_spec in ("first", "shrunk"):
                if k == 0:
                    raise BmrError(f"offset={off_spec!r} needs calibration >= 1 leading samples")
                shift = float(np.mean(y[:k] - p[:k]))
                source = f"from {k} leading sample{'s' if k > 1 else ''}"
                prior = _offset_prior(model)
                if off_spec == "shrunk" and prior is not None:
                    tau2, s2 = prior["spread"] ** 2, prior["first_sample_error"] ** 2 / k
                    weight = tau2 / (tau2 + s2) if tau2 + s2 > 0 else 1.0
                    shift *= weight
                    source = (f"{weight:.2f} × {k} leading sample{'s' if k > 1 else ''} + {1 - weight:.2f} × the "
                              f"model's (spread {prior['spread']:.3g} between training runs, leading-sample "
                              f"error {prior['first_sample_error']:.3g})")
            else:
                raise BmrError(f"offset must be 'model', 'first', 'shrunk', a number or {{run: number}}, "
                               f"got {off_spec!r}")
        else:
            shift, source = float(off_spec) - y_lo, "given"
        p = p + shift
        dropped: dict[str, int] = {}
        first = k
        if k:
            dropped[CALIBRATION] = k
        if evaluate == "known":
            s = evaluation_start(u, lo, hi, SATURATION_TOL * (hi - lo))
            reaches = np.any(u >= hi - SATURATION_TOL * (hi - lo)) and np.any(u <= lo + SATURATION_TOL * (hi - lo))
            if reaches and s > first:
                dropped[BEFORE_KNOWN_STATE] = s - first
                first = s
        res = np.full(n, np.nan)
        res[first:] = y[first:] - p[first:]
        e = res[first:]
        count, excess = model.input_excess(u)
        out.append(RunPrediction(
            name=r.name, samples=n, evaluated=int(e.size),
            rms=float(np.sqrt(np.mean(e * e))) if e.size else math.nan,
            max_abs=float(np.max(np.abs(e))) if e.size else math.nan, span=span,
            offset=y_lo + shift, offset_source=source, gain=g, initial=state, out_of_range=count,
            max_excess=excess, dropped=dropped, output=p + (run_output(r, None) - y), residual=res))
    return Prediction(out, q, out_of_range)
