"""Held-out prediction: a model's error on a bundle's runs, in the declared units, against a single-valued baseline;
and ``bmr predict MODEL BUNDLE`` (table, ``bmr-prediction/1`` JSON, figure).

For each run the model is simulated from negative saturation and compared from the first sample whose hysteresis
state the input determines: the run's start when it starts at the bottom of the model's input range, else the first
time the input reaches either end of that range (every earlier memory is wiped out there); a run that never gets
there is compared from its start, flagged ``state_known=False``. ``offset="first-sample"`` shifts each run's
prediction (and the baseline) to its first compared sample, for devices whose output offset differs from run to run
(remanence left by earlier excitation, sensor offsets); that sample is then not counted.

The baseline is the best a model without hysteresis can do from the same identification: the single-valued curve
through the middle of the model's major loop (the mean of its ascending and descending major branches). Errors are
reported in the output unit, in % of the model's output span and, when the bundle has the output's sigma, in
measurement sigmas (the error divided by the RMS sigma of the same samples).
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from bmr._core import BmrError
from bmr.data.bundle import Bundle, Run, read_bundle
from bmr.data.quantities import Quantities
from bmr.data.units import format_number
from bmr.identification.model import Model
from bmr.identification.spans import SATURATION_TOL

__all__ = ["FORMAT", "OFFSETS", "RunPrediction", "Prediction", "predict", "run_cli"]

FORMAT = "bmr-prediction/1"
OFFSETS = ("none", "first-sample")


def _rms(e: np.ndarray) -> float:
    return float(np.sqrt(np.mean(e * e))) if e.size else float("nan")


def _max_abs(e: np.ndarray) -> float:
    return float(np.max(np.abs(e))) if e.size else float("nan")


@dataclass
class RunPrediction:
    """One run's prediction. Arrays cover the whole run (``time``, ``input``, ``output`` measured in the model's
    units, ``predicted``, ``baseline``); statistics cover ``evaluated`` (the samples compared)."""

    name: str
    role: str
    start: int
    state_known: bool
    start_reason: str
    offset: float
    out_of_range: int
    max_excess: float
    time: np.ndarray
    input: np.ndarray
    output: np.ndarray
    predicted: np.ndarray
    baseline: np.ndarray
    sigma: np.ndarray | None = None
    evaluated: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))

    @property
    def residual(self) -> np.ndarray:
        return self.output - self.predicted

    @property
    def baseline_residual(self) -> np.ndarray:
        return self.output - self.baseline

    @property
    def n(self) -> int:
        return int(self.evaluated.sum())

    def stats(self, span: float) -> dict[str, Any]:
        e = self.residual[self.evaluated]
        b = self.baseline_residual[self.evaluated]
        out: dict[str, Any] = {
            "samples": int(self.output.size), "evaluated": self.n, "start": self.start,
            "state_known": self.state_known, "start_reason": self.start_reason, "offset": self.offset,
            "rms": _rms(e), "max": _max_abs(e), "rms_pct_span": 100.0 * _rms(e) / span,
            "max_pct_span": 100.0 * _max_abs(e) / span,
            "baseline_rms": _rms(b), "baseline_max": _max_abs(b),
            "out_of_range": self.out_of_range, "max_excess": self.max_excess,
        }
        if self.sigma is not None:
            s = _rms(self.sigma[self.evaluated])
            out["sigma_rms"] = s
            out["rms_sigmas"] = out["rms"] / s if s > 0 else float("nan")
            out["max_sigmas"] = out["max"] / s if s > 0 else float("nan")
            out["baseline_rms_sigmas"] = out["baseline_rms"] / s if s > 0 else float("nan")
        return out


@dataclass
class Prediction:
    """A model's prediction of a bundle's runs: per-run and pooled statistics in the model's declared units."""

    quantities: Quantities
    output_span: float
    offset: str
    runs: list[RunPrediction]
    model_source: str = ""
    bundle_source: str = ""
    baseline: str = "single-valued curve through the middle of the model's major loop"

    def run(self, name: str) -> RunPrediction:
        for r in self.runs:
            if r.name == name:
                return r
        raise BmrError(f"no predicted run named {name!r} (runs: {', '.join(r.name for r in self.runs)})")

    def total(self) -> dict[str, Any]:
        """Statistics over every evaluated sample of every run."""
        e = np.concatenate([r.residual[r.evaluated] for r in self.runs])
        b = np.concatenate([r.baseline_residual[r.evaluated] for r in self.runs])
        out: dict[str, Any] = {"evaluated": int(e.size), "rms": _rms(e), "max": _max_abs(e),
                               "rms_pct_span": 100.0 * _rms(e) / self.output_span,
                               "max_pct_span": 100.0 * _max_abs(e) / self.output_span,
                               "baseline_rms": _rms(b), "baseline_max": _max_abs(b)}
        if all(r.sigma is not None for r in self.runs):
            s = _rms(np.concatenate([r.sigma[r.evaluated] for r in self.runs]))  # type: ignore[index]
            out["sigma_rms"] = s
            for k in ("rms", "max", "baseline_rms", "baseline_max"):
                out[f"{k}_sigmas"] = out[k] / s if s > 0 else float("nan")
        return out

    def to_dict(self) -> dict[str, Any]:
        """The ``bmr-prediction/1`` JSON content (non-finite numbers as null)."""
        return _finite({
            "format": FORMAT, "model": self.model_source, "bundle": self.bundle_source,
            "quantities": self.quantities.to_dict(), "output_unit": self.quantities.output.unit,
            "output_span": self.output_span, "offset": self.offset, "baseline": self.baseline,
            "runs": {r.name: {"role": r.role, **r.stats(self.output_span)} for r in self.runs},
            "total": self.total(),
        })

    def table(self) -> str:
        """One line per run and a total: RMS and max in the output unit, % of span, sigmas, baseline."""
        q = self.quantities.output
        sig = all(r.sigma is not None for r in self.runs)
        head = ["run", "evaluated", f"RMS ({q.unit})", f"max ({q.unit})", "RMS % span", "max % span"]
        head += ["RMS (sigma)", "max (sigma)"] if sig else []
        head += [f"baseline RMS ({q.unit})", f"baseline max ({q.unit})"]
        rows = [head]

        def line(name: str, st: dict[str, Any]) -> list[str]:
            cells = [name, str(st["evaluated"]), format_number(st["rms"]), format_number(st["max"]),
                     format_number(st["rms_pct_span"]), format_number(st["max_pct_span"])]
            if sig:
                cells += [format_number(st["rms_sigmas"]), format_number(st["max_sigmas"])]
            return cells + [format_number(st["baseline_rms"]), format_number(st["baseline_max"])]

        for r in self.runs:
            rows.append(line(r.name + ("" if r.state_known else " *"), r.stats(self.output_span)))
        if len(self.runs) > 1:
            rows.append(line("all", self.total()))
        widths = [max(len(row[k]) for row in rows) for k in range(len(head))]
        text = ["  ".join(c.rjust(w) if k else c.ljust(w) for k, (c, w) in enumerate(zip(row, widths)))
                for row in rows]
        notes = [f"* {r.name}: {r.start_reason}" for r in self.runs if not r.state_known]
        notes += [f"{r.name}: samples 0..{r.start - 1} not compared (the state is unknown until the input first "
                  "reaches an end of its range)" for r in self.runs if r.state_known and r.start > 0]
        notes += [f"{r.name}: sample {r.start} sets the output offset ({self.quantities.output.format(r.offset)}) "
                  "and is not compared" for r in self.runs if self.offset == "first-sample"]
        notes += [f"{r.name}: {r.out_of_range} sample(s) outside the model's input range (largest excess "
                  f"{self.quantities.input.format(r.max_excess)}); the model holds its end value there"
                  for r in self.runs if r.out_of_range]
        return "\n".join(text + notes)

    def write_json(self, path: str | Path) -> Path:
        return _write_text(Path(path), json.dumps(self.to_dict(), indent=1, allow_nan=False) + "\n")

    def figure(self, path: str | Path) -> Path:
        """PNG: per run, measured and predicted output against the input (with the baseline), and the residual
        of both along the run."""
        from bmr.report.prediction import prediction_figure

        return prediction_figure(self, Path(path))


def _finite(x: Any) -> Any:
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite(v) for v in x]
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    return x


def _write_text(p: Path, text: str) -> Path:
    tmp = p.with_name(f".{p.name}.tmp")
    try:
        tmp.write_text(text)
        tmp.replace(p)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise BmrError(f"cannot write {str(p)!r}: {exc.strerror or exc}") from None
    return p


def _branches(model: Model) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """The major ascending branch (from the lowest reversal) and major descending branch (from the highest)."""
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


def _start(u: np.ndarray, lo: float, hi: float, unit_fmt: Any) -> tuple[int, bool, str]:
    tol = SATURATION_TOL * (hi - lo)
    if u[0] <= lo + tol:
        return 0, True, "starts at the bottom of the input range"
    ends = np.flatnonzero((u >= hi - tol) | (u <= lo + tol))
    if ends.size:
        return int(ends[0]), True, f"from sample {int(ends[0])}, where the input first reaches an end of its range"
    return 0, False, (f"never reaches an end of the model's input range ({unit_fmt(lo)}..{unit_fmt(hi)}): the "
                      "initial state is unknown and taken as negative saturation")


def _aligned(model: Model, bundle: Bundle) -> tuple[tuple[float, float], tuple[float, float]]:
    """``(scale, shift)`` of the input and of the output that bring the bundle's values into the model's units
    (``BmrError`` when the quantities differ in dimension, e.g. a model of torque and a bundle of displacement)."""
    mq, bq = model.quantities, bundle.quantities
    maps = []
    for role in ("input", "output"):
        a, b = getattr(mq, role), getattr(bq, role)
        if a.dimension != b.dimension:
            raise BmrError(f"the model's {role} is {a.label} but the bundle's is {b.label}: they do not convert")
        zero = float(a.from_unit(0.0, b.unit))
        maps.append((float(a.from_unit(1.0, b.unit)) - zero, zero))
    return maps[0], maps[1]


def predict(model: Model | str | Path, bundle: Bundle | str | Path, *, runs: Sequence[str] | None = None,
            offset: str = "none") -> Prediction:
    """Predict ``runs`` of ``bundle`` (default: its evaluation runs) with ``model``; see the module docstring.

    The bundle's input and output are converted to the model's units (a model in V predicts a bundle in mV);
    quantities of different dimensions are a ``BmrError``.
    """
    model_source = str(model) if isinstance(model, (str, Path)) else ""
    bundle_source = str(bundle) if isinstance(bundle, (str, Path)) else ""
    if isinstance(model, (str, Path)):
        model = Model.load(model)
    if isinstance(bundle, (str, Path)):
        bundle = read_bundle(bundle)
    if offset not in OFFSETS:
        raise BmrError(f"unknown offset mode {offset!r}; use one of {', '.join(OFFSETS)}")
    if runs:
        chosen: list[Run] = [bundle.run(name) for name in runs]
    else:
        chosen = bundle.evaluation_runs()
        if not chosen:
            raise BmrError("the bundle has no evaluation runs (hold runs out with `bmr import --holdout`, or name "
                           "the runs to predict)")
    (in_scale, in_shift), (out_scale, out_shift) = _aligned(model, bundle)
    lo, hi = model.input_limits
    ylo, yhi = model.output_limits
    span = yhi - ylo
    if not span > 0:
        raise BmrError(f"the model's output range {ylo!r}..{yhi!r} is empty")
    fmt = model.quantities.input.format
    out = []
    for r in chosen:
        u = r.input * in_scale + in_shift
        y = r.output * out_scale + out_shift
        sigma = r.output_sigma * out_scale if r.output_sigma is not None else None
        angle = r.angle if model.friction is not None else None
        yhat = model.simulate(u, angle)
        base = single_valued_baseline(model, u) + (model.friction_torque(angle) if angle is not None else 0.0)
        s, known, why = _start(u, lo, hi, fmt)
        evaluated = np.zeros(u.size, dtype=bool)
        evaluated[s:] = True
        shift = 0.0
        if offset == "first-sample":
            shift = float(y[s] - yhat[s])
            yhat = yhat + shift
            base = base + float(y[s] - base[s])
            evaluated[s] = False
        excess = np.maximum(u - hi, lo - u)
        outside = excess > 0
        out.append(RunPrediction(r.name, "identification" if r.is_identification else "evaluation", s, known, why,
                                 shift, int(outside.sum()), float(excess[outside].max()) if outside.any() else 0.0,
                                 r.time, u, y, yhat, base, sigma, evaluated))
    return Prediction(model.quantities, span, offset, out, model_source, bundle_source)


def run_cli(args: Any) -> int:
    """``bmr predict MODEL BUNDLE [--runs ...] [--offset ...] [--json OUT] [--figure OUT.png]``."""
    for target in (args.json_out, args.figure):
        if target is not None:
            parent = Path(target).resolve().parent
            if not parent.is_dir():
                raise BmrError(f"cannot write {target!r}: folder {str(parent)!r} does not exist")
    names = [n.strip() for item in args.runs for n in item.split(",") if n.strip()] or None
    p = predict(args.model, args.bundle, runs=names, offset=args.offset)
    q = p.quantities
    print(f"bmr predict: {args.model} ({q.describe()}) on {args.bundle}: {len(p.runs)} run(s), offset {p.offset}; "
          f"output span {q.output.format(p.output_span)}")
    print(f"  baseline: {p.baseline}")
    for line in p.table().splitlines():
        print(f"  {line}")
    if args.json_out:
        p.write_json(args.json_out)
        print(f"  wrote {args.json_out}")
    if args.figure:
        p.figure(args.figure)
        print(f"  wrote {args.figure}")
    return 0
