"""What a memory model cannot explain across a measurement history (runs recorded one after the other on one
device, ``Bundle.histories``).

The nominal model is run through the whole history (``initial="continue"``: each run from the state the earlier
runs' inputs left), so every difference of memory state is the model's to explain. What is left in the residual
(measured − model) and changes along the history is not memory:

* **the output at a run's start** (its leading samples at the starting input): the same input and the state the
  history left, yet a level that differs from run to run — a remanence or zero the history does not explain (a
  per-run offset, a drifting sensor, heating);
* **a repeated loop that does not retrace**: a sweep between the same two extremes as an earlier one (a major loop
  cycled again, a minor loop repeated) lies above or below it — accommodation of repeated loops, or a drift in time.

Both are measured in the output's unit against the noise ``sigma`` and handed to the candidate effects that explain
them (:data:`EXPLAINED_BY`); the diagnosis reports which of those it accepted.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bmr import _core
from bmr.data.bundle import Bundle
from bmr.identification.prediction import predict
from bmr.identification.spans import evaluation_start

__all__ = ["LoopRepeat", "HistoryFindings", "history_findings", "EXPLAINED_BY"]

# The candidate effects that explain each finding.
EXPLAINED_BY = {
    "start_level": ("run_gain_offset", "sensor_drift", "thermal_drift"),
    "loop_within_run": ("accommodation", "sensor_drift", "thermal_drift"),
    "loop_across_runs": ("accommodation", "run_gain_offset", "sensor_drift", "thermal_drift"),
}
# Leading samples averaged for a run's start level (while the input stays at its first value).
START_SAMPLES = 50
# A repeated sweep is one whose extremes match an earlier sweep's within this share of the input span (or two
# reversal dead-bands, whichever is larger).
EXTREME_TOL_SHARE = 0.01
# A repeat is looked for among this many sweeps after each one (bounds the work on long, densely reversing runs).
LOOKAHEAD_SWEEPS = 256
# A change is a finding when it exceeds this many noise sigmas (and four standard errors of the estimate): smaller
# ones are within what the nominal tables' own error at two different memory states gives on clean data.
SIGNIFICANT_SIGMAS = 2.0


@dataclass
class LoopRepeat:
    """A sweep between the same extremes as an earlier one, compared on the later sweep's samples at the inputs
    both cover: ``shift`` = the later sweep's residual − the earlier one's at the same input (output unit), at the
    sweep's first (``shift_at_start``) and last (``shift_at_end``) sample, on average and at most. ``first`` /
    ``second``: the runs holding the sweeps. ``significant``: the mean shift exceeds both two noise sigmas and four
    standard errors of a difference of two noisy sweeps."""

    direction: str
    first: str
    second: str
    input_from: float
    input_to: float
    samples: int
    shift_at_start: float
    shift_at_end: float
    mean_shift: float
    max_abs_shift: float
    significant: bool

    @property
    def finding(self) -> str:
        return "loop_within_run" if self.first == self.second else "loop_across_runs"

    def to_dict(self) -> dict[str, Any]:
        return {"direction": self.direction, "first": self.first, "second": self.second,
                "input_from": self.input_from, "input_to": self.input_to, "samples": self.samples,
                "shift_at_start": self.shift_at_start, "shift_at_end": self.shift_at_end,
                "mean_shift": self.mean_shift, "max_abs_shift": self.max_abs_shift,
                "significant": self.significant, "explained_by": list(EXPLAINED_BY[self.finding])}


@dataclass
class HistoryFindings:
    """One history's findings. ``runs``: in recording order. ``sigma``: the output noise they are judged against.
    ``start_levels``: per run, the residual of the model continuing the history over the run's leading samples
    (runs that start before the history's state is known are left out); ``start_level_sd`` /
    ``start_level_range``: their spread; ``start_level_changes``: the spread exceeds two noise sigmas and twice the
    noise of one level. ``loops``: every repeated sweep compared (:class:`LoopRepeat`). ``candidates``: the effects
    that explain the significant findings; ``named``: those of them the diagnosis accepted."""

    runs: list[str]
    sigma: float
    start_levels: dict[str, float]
    start_level_sd: float
    start_level_range: float
    start_level_changes: bool
    loops: list[LoopRepeat] = field(default_factory=list)
    named: list[str] = field(default_factory=list)

    @property
    def loops_not_retracing(self) -> list[LoopRepeat]:
        return [lp for lp in self.loops if lp.significant]

    @property
    def candidates(self) -> list[str]:
        found = (["start_level"] if self.start_level_changes else []) + [lp.finding for lp in self.loops_not_retracing]
        return list(dict.fromkeys(name for f in found for name in EXPLAINED_BY[f]))

    def to_dict(self) -> dict[str, Any]:
        return {"runs": list(self.runs), "sigma": self.sigma, "start_levels": dict(self.start_levels),
                "start_level_sd": self.start_level_sd, "start_level_range": self.start_level_range,
                "start_level_changes": self.start_level_changes,
                "start_level_explained_by": list(EXPLAINED_BY["start_level"]),
                "loops": [lp.to_dict() for lp in self.loops],
                "loops_not_retracing": len(self.loops_not_retracing),
                "candidates": self.candidates, "named": list(self.named)}

    def lines(self, quantities: Any) -> list[str]:
        """The findings as text lines (the CLI's report)."""
        o = quantities.output
        head = f"history {self.runs[0]}..{self.runs[-1]} ({len(self.runs)} runs)"
        out = [f"{head}: level at each run's start, beyond what the history explains, spreads by "
               f"{o.format(self.start_level_range, 3)} (sd {o.format(self.start_level_sd, 3)}, noise "
               f"{o.format(self.sigma, 3)})" + ("" if self.start_level_changes else ": within the noise")]
        bad = self.loops_not_retracing
        out.append(f"{head}: {len(self.loops)} repeated sweep(s) compared, {len(bad)} do not retrace")
        for lp in sorted(bad, key=lambda lp: -abs(lp.mean_shift))[:5]:
            where = lp.first if lp.first == lp.second else f"{lp.first} -> {lp.second}"
            out.append(f"  {lp.direction} {quantities.input.format(lp.input_from, 4)} to "
                       f"{quantities.input.format(lp.input_to, 4)} ({where}): repeat lies "
                       f"{o.format(lp.shift_at_start, 3)} to {o.format(lp.shift_at_end, 3)} off the earlier "
                       f"(mean {o.format(lp.mean_shift, 3)})")
        if self.candidates:
            named = ", ".join(self.named) if self.named else "none of them accepted"
            out.append(f"{head}: explained by {', '.join(self.candidates)}: {named}")
        return out


def _sweeps(u: np.ndarray, deadband: float) -> list[tuple[int, int]]:
    """Monotone stretches of ``u`` between its reversals (and its ends): ``(first, last)`` sample indices."""
    rev = [int(k) for k in np.asarray(_core.find_reversals(np.ascontiguousarray(u), deadband), dtype=int)]
    cuts = sorted(set([0] + [k for k in rev if 0 < k < u.size - 1] + [u.size - 1]))
    return [(a, b) for a, b in zip(cuts[:-1], cuts[1:]) if b > a]


def _as_function(u: np.ndarray, e: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``e`` as a function of ``u`` on a sweep: increasing unique inputs, the residual averaged over repeats."""
    order = np.argsort(u, kind="stable")
    us, es = u[order], e[order]
    uniq, inv = np.unique(us, return_inverse=True)
    return uniq, np.bincount(inv, weights=es) / np.bincount(inv)


def _compare(u: np.ndarray, e: np.ndarray, run_of: np.ndarray, a: tuple[int, int], b: tuple[int, int],
             names: list[str], sigma: float, tol: float) -> LoopRepeat | None:
    lo = max(min(u[a[0]], u[a[1]]), min(u[b[0]], u[b[1]]))
    hi = min(max(u[a[0]], u[a[1]]), max(u[b[0]], u[b[1]]))
    ua, ea = _as_function(u[a[0]:a[1] + 1], e[a[0]:a[1] + 1])
    sel = np.arange(b[0], b[1] + 1)
    sel = sel[(u[sel] >= lo - tol) & (u[sel] <= hi + tol)]  # extremes that match within tol are the same
    if sel.size < 2 or ua.size < 2:
        return None
    shift = e[sel] - np.interp(u[sel], ua, ea)
    mean = float(np.mean(shift))
    significant = abs(mean) > max(SIGNIFICANT_SIGMAS * sigma, 4.0 * sigma * math.sqrt(2.0 / sel.size))
    direction = "ascending" if u[b[1]] > u[b[0]] else "descending"
    return LoopRepeat(direction, names[int(run_of[a[0]])], names[int(run_of[b[0]])], float(u[b[0]]), float(u[b[1]]),
                      int(sel.size), float(shift[0]), float(shift[-1]), mean, float(np.max(np.abs(shift))),
                      bool(significant))


def history_findings(model: Any, bundle: Bundle, sigma: float) -> list[HistoryFindings]:
    """The findings of every measurement history of ``bundle`` against ``model``'s core tables (run from negative
    saturation through the whole history), judged against the output noise ``sigma``."""
    out = []
    lo, hi = model.hysteresis.input_range
    span = hi - lo
    deadband = float(bundle.meta.get("reversal_deadband", 0.0) or 0.0) if isinstance(bundle.meta, dict) else 0.0
    deadband = deadband if math.isfinite(deadband) and deadband > 0 else 0.005 * span
    tol = max(2.0 * deadband, EXTREME_TOL_SHARE * span)
    sigma = float(sigma) if math.isfinite(sigma) and sigma > 0 else 0.0
    for names in bundle.histories:
        runs = [bundle.run(n) for n in names]
        p = predict(model, runs, initial="continue", offset="model", evaluate="all", bundle=bundle,
                    whole_model=False)
        u = np.concatenate([r.input for r in p.runs])
        e = np.concatenate([r.measured - r.predicted for r in p.runs])
        run_of = np.concatenate([np.full(r.input.size, j) for j, r in enumerate(p.runs)])
        starts = np.cumsum([0] + [r.input.size for r in p.runs])[:-1]
        # Before the history has been to both ends of the input range its state is the assumed start (unless it
        # starts at an end): nothing before that is compared.
        at_end = bool(u[0] <= lo + tol or u[0] >= hi - tol)
        known = 0 if at_end else evaluation_start(u, lo, hi, tol)
        levels: dict[str, float] = {}
        counts = []
        for r, s0 in zip(p.runs, starts):
            if s0 < known:
                continue
            k = int(np.argmax(np.abs(r.input - r.input[0]) > deadband)) or r.input.size
            k = min(k, START_SAMPLES)
            levels[r.name] = float(np.mean((r.measured - r.predicted)[:k]))
            counts.append(k)
        values = np.array(list(levels.values()))
        sd = float(np.std(values, ddof=1)) if values.size > 1 else 0.0
        level_sigma = sigma / math.sqrt(min(counts)) if counts else sigma
        sweeps = [s for s in _sweeps(u, deadband) if abs(u[s[1]] - u[s[0]]) > 2.0 * tol and s[0] >= known]
        loops = []
        used: set[int] = set()
        for j, a in enumerate(sweeps):
            up = u[a[1]] > u[a[0]]
            for m in range(j + 1, min(j + 1 + LOOKAHEAD_SWEEPS, len(sweeps))):
                b = sweeps[m]
                if m in used or (u[b[1]] > u[b[0]]) != up:
                    continue
                if abs(u[b[0]] - u[a[0]]) <= tol and abs(u[b[1]] - u[a[1]]) <= tol:
                    found = _compare(u, e, run_of, a, b, names, sigma, tol)
                    if found is not None:
                        loops.append(found)
                        used.add(m)
                    break
        changes = bool(values.size > 1 and sd > max(SIGNIFICANT_SIGMAS * sigma, 2.0 * level_sigma))
        out.append(HistoryFindings(list(names), sigma, levels, sd, float(np.ptp(values)) if values.size else 0.0,
                                   changes, loops))
    return out
