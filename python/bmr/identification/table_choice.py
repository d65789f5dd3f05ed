"""The least-squares table's resolution (grid intervals over the input range) and its smoothing, chosen by blocked
cross-validation inside the identification runs.

Each training run is cut into contiguous time blocks; fold ``f`` holds out every block whose index is ``f`` modulo
the number of folds, in every run at once. The held-out samples still drive the memory (a Preisach state is the
whole input history) but are kept out of the regression, and they are scored with the run's own offset fitted on
the rest; every run keeps the initial state, gain and leakage of one reference fit at the default setting. Runs
held out of the identification are never seen. The regressors are built once per resolution
(``bmr._core.EverettFolds``: each fold's training problem is the whole less its own part), so a smoothing costs
one warm-started solve per fold. The search is coordinate-wise on a coarse grid and local — from the default,
the smoothing at the default resolution, then the resolution at that smoothing, then the smoothing once more at
the chosen resolution, each walked one step at a time while the score improves. Among settings within :data:`TIE_SHARE` of the best score the smoother, then the coarser, is kept: a
smoother density moves little when the range's ends move a little.

Resolutions are capped by the data: a table finer than the default gets at most one cell per
:data:`ROWS_PER_CELL` regression rows (a short recording does not pay for tables it cannot inform), and every table
stays within the solver's unknowns. Cross-validation is skipped (the default kept, the reason reported) when the
runs have fewer than :data:`MIN_ROWS_PER_BLOCK` rows per time block or fewer than two folds hold anything out.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from bmr import _core
from bmr._core import BmrError
from bmr.data.bundle import Run
from bmr.identification.lstsq import MAX_ROWS, LstsqTables, fit_tables_lstsq, row_weights
from bmr.identification.signals import run_input, run_output, running_integral

__all__ = ["TableCandidate", "TableChoice", "choose_table_settings", "block_folds", "RESOLUTIONS", "SMOOTHINGS",
           "DEFAULT_INTERVALS", "DEFAULT_SMOOTHING", "FOLDS", "TIE_SHARE", "ROWS_PER_CELL", "MIN_ROWS_PER_BLOCK",
           "MAX_UNKNOWNS"]

DEFAULT_INTERVALS = 48
DEFAULT_SMOOTHING = 1e-4
RESOLUTIONS = (24, 32, 48, 64, 80)
SMOOTHINGS = (1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1)
FOLDS = 3
BLOCKS_PER_FOLD = 8
# Samples a run keeps in the fit in every fold (its offset is fitted on them).
MIN_KEPT = 2
# Scores within this share of the best count as equal (the noise of a cross-validated RMS on a few folds).
TIE_SHARE = 0.01
# Regression rows a table finer than the default needs per cell to be tried.
ROWS_PER_CELL = 4
# Regression rows per time block below which the blocks are too short to score (no cross-validation).
MIN_ROWS_PER_BLOCK = 2
# The least-squares solver's limit on unknowns (cells, offsets and a drift coefficient).
MAX_UNKNOWNS = int(_core.LIMITS["everett_unknowns"])


@dataclass(frozen=True)
class TableCandidate:
    """One setting tried: ``n_intervals``, ``smoothing`` and its cross-validated RMS (output units) over the
    held-out blocks of every fold (``inf`` when a fold's fit failed)."""

    n_intervals: int
    smoothing: float
    cv_rms: float

    def to_dict(self) -> dict[str, Any]:
        return {"n_intervals": self.n_intervals, "smoothing": self.smoothing,
                "cv_rms": self.cv_rms if math.isfinite(self.cv_rms) else None}


@dataclass
class TableChoice:
    """The setting chosen (``n_intervals``, ``smoothing``) over ``input_range``, how (``folds`` folds of
    contiguous time blocks, ``blocks`` per run), every candidate's cross-validated RMS, the chosen and the default
    setting's scores (output units), which settings the caller fixed (not searched), and ``skipped``: why no
    cross-validation was run (the default setting kept), None when it was."""

    n_intervals: int
    smoothing: float
    input_range: tuple[float, float]
    folds: int
    blocks: int
    candidates: list[TableCandidate] = field(default_factory=list)
    fixed: tuple[str, ...] = ()
    skipped: str | None = None
    # The fit at the reference setting the folds were built on (reused when that setting is chosen).
    reference: LstsqTables | None = field(default=None, repr=False, compare=False)

    def score(self, n_intervals: int, smoothing: float) -> float:
        for c in self.candidates:
            if c.n_intervals == n_intervals and c.smoothing == smoothing:
                return c.cv_rms
        return math.nan

    @property
    def cv_rms(self) -> float:
        return self.score(self.n_intervals, self.smoothing)

    @property
    def default_cv_rms(self) -> float:
        return self.score(DEFAULT_INTERVALS, DEFAULT_SMOOTHING)

    def to_dict(self) -> dict[str, Any]:
        def finite(x: float) -> float | None:
            return x if math.isfinite(x) else None

        return {"n_intervals": self.n_intervals, "smoothing": self.smoothing, "input_range": list(self.input_range),
                "folds": self.folds, "blocks": self.blocks, "cv_rms": finite(self.cv_rms),
                "default_cv_rms": finite(self.default_cv_rms), "fixed": list(self.fixed), "skipped": self.skipped,
                "candidates": [c.to_dict() for c in self.candidates]}

    def __repr__(self) -> str:
        if self.skipped is not None:
            return (f"TableChoice({self.n_intervals} intervals, smoothing {self.smoothing:g}: the default, "
                    f"not cross-validated: {self.skipped})")
        d = self.default_cv_rms
        default = f", default ({DEFAULT_INTERVALS}, {DEFAULT_SMOOTHING:g}) {d:.4g}" if math.isfinite(d) else ""
        return (f"TableChoice({self.n_intervals} intervals, smoothing {self.smoothing:g}: cross-validated RMS "
                f"{self.cv_rms:.4g} over {self.folds} folds of time blocks{default}; {len(self.candidates)} "
                f"settings tried)")


def block_folds(lengths: Sequence[int], folds: int = FOLDS,
                blocks_per_fold: int = BLOCKS_PER_FOLD) -> list[list[np.ndarray]]:
    """Held-out masks, ``[fold][run]``: each run of ``lengths[k]`` samples cut into ``folds · blocks_per_fold``
    contiguous blocks, fold ``f`` holding out the blocks with index ``f`` modulo ``folds`` (a run left with fewer
    than :data:`MIN_KEPT` samples is not held out in that fold)."""
    if folds < 2:
        raise BmrError(f"cross-validation needs at least 2 folds, got {folds}")
    nb = folds * blocks_per_fold
    out: list[list[np.ndarray]] = [[] for _ in range(folds)]
    for n in lengths:
        block = (np.arange(n) * nb) // max(n, 1)
        for f in range(folds):
            held = block % folds == f
            # A run too short to keep samples for its own offset in this fold is not held out in it.
            out[f].append(held if n - int(held.sum()) >= MIN_KEPT else np.zeros(n, dtype=bool))
    return out


def cells(n_intervals: int) -> int:
    """Cells of a table of ``n_intervals`` intervals (the triangle and its diagonal)."""
    return n_intervals * (n_intervals + 1) // 2


def choose_table_settings(runs: Sequence[Run], friction: Any = None, *, input_range: tuple[float, float],
                          n_intervals: int | None = None, smoothing: float | None = None, folds: int = FOLDS,
                          **fit_options: Any) -> TableChoice:
    """Choose the resolution and smoothing of :func:`fit_tables_lstsq` on ``runs`` by blocked cross-validation
    (see the module). A value given for ``n_intervals`` or ``smoothing`` is kept and not searched.
    ``fit_options``: the other arguments of the fit (offsets, gains, initial state, drift, max_rows)."""
    runs = list(runs)
    if not runs:
        raise BmrError("choosing the table settings needs at least one run")
    lo, hi = float(input_range[0]), float(input_range[1])
    resolutions = [int(n_intervals)] if n_intervals is not None else list(RESOLUTIONS)
    smoothings = [float(smoothing)] if smoothing is not None else list(SMOOTHINGS)
    n0 = resolutions[0] if n_intervals is not None else DEFAULT_INTERVALS
    s0 = smoothings[0] if smoothing is not None else DEFAULT_SMOOTHING
    fixed = tuple(k for k, v in (("n_intervals", n_intervals), ("smoothing", smoothing)) if v is not None)
    us = [run_input(r) for r in runs]
    ys = [run_output(r, friction) for r in runs]
    weights = row_weights(us, lo, hi, fit_options.get("initial_state", "estimate"),
                          fit_options.get("max_rows", MAX_ROWS))
    masks = block_folds([u.size for u in us], folds)
    n_off = len(runs) if fit_options.get("offsets", "per_run") == "per_run" else 1
    rows = sum(int(np.count_nonzero(w)) for w in weights)
    held = sum(1 for fold in masks if any(np.count_nonzero(w[m]) for w, m in zip(weights, fold)))
    # Resolutions the data can carry (finer than the default: enough rows per cell) within the solver's unknowns.
    resolutions = [n for n in resolutions
                   if (n <= n0 or cells(n) * ROWS_PER_CELL <= rows) and cells(n) + n_off + 1 <= MAX_UNKNOWNS]

    def choice(**kw: Any) -> TableChoice:
        return TableChoice(input_range=(lo, hi), folds=folds, blocks=folds * BLOCKS_PER_FOLD, fixed=fixed, **kw)

    blocks = folds * BLOCKS_PER_FOLD
    skipped = (f"{rows} regression rows, fewer than {MIN_ROWS_PER_BLOCK} per time block of {blocks}"
               if rows < MIN_ROWS_PER_BLOCK * blocks else
               f"only {held} of {folds} folds hold samples out (runs too short to cut into blocks)" if held < 2 else
               f"the {n0}-interval table exceeds the solver's {MAX_UNKNOWNS} unknowns" if n0 not in resolutions
               else None)
    if skipped is not None:
        return choice(n_intervals=n0, smoothing=s0, skipped=skipped)
    reference = fit_tables_lstsq(runs, friction, n_intervals=n0, smoothing=s0, input_range=(lo, hi), **fit_options)
    # Every fold keeps the reference's initial states, gains and leakage; only the table and the offsets are refitted.
    drift = ([running_integral(u, r.t) for r, u in zip(runs, us)] if reference.leakage_rate is not None else None)
    data = [(u, y, w, np.where(np.array([fold[k] for fold in masks]).T, np.arange(folds), folds).min(axis=1),
             k if n_off > 1 else 0, np.asarray(c.history, dtype=float), c.gain)
            for k, (u, y, w, c) in enumerate(zip(us, ys, weights, reference.runs))]
    regressions: dict[int, Any] = {}
    scores: dict[tuple[int, float], float] = {}

    def score(n: int, s: float) -> float:
        if (n, s) not in scores:
            try:
                if n not in regressions:
                    regressions.clear()  # one resolution's normal equations at a time (they are large)
                    regressions[n] = _core.EverettFolds(np.linspace(lo, hi, n + 1), data, n_off, folds,
                                                        drift=drift)
                start = reference.passive if n == reference.n_intervals else None
                parts = regressions[n].score(s, warm_start=None if start is None else [bool(x) for x in start])
                weight = sum(w for _, w in parts)
                scores[(n, s)] = math.sqrt(sum(e for e, _ in parts) / weight) if weight > 0 else math.inf
            except BmrError:
                scores[(n, s)] = math.inf
        return scores[(n, s)]

    def best(cands: list[tuple[int, float]], start: tuple[int, float]) -> tuple[int, float]:
        """Walk from ``start`` along ``cands`` (ordered) each way while the score improves (warm-starting each solve
        from its neighbour's), then keep, within the tie band of the best score seen, the smoothest and coarsest."""
        i = cands.index(start)
        top = score(*start)
        for step in (-1, 1):
            j = i + step
            while 0 <= j < len(cands) and (v := score(*cands[j])) < top:
                top, j = v, j + step
        if not math.isfinite(top):  # no fold could be fitted: keep the default (or the given) setting
            return (n0, s0)
        seen = [c for c in cands if c in scores]
        near = [c for c in seen if scores[c] <= top * (1.0 + TIE_SHARE)]
        return max(near, key=lambda c: (c[1], -c[0]))

    s = best([(n0, x) for x in smoothings], (n0, s0))[1]
    n = best([(x, s) for x in resolutions], (n0, s))[0]
    if n != n0 and len(smoothings) > 1:  # the smoothing once more at the chosen resolution
        s = best([(n, x) for x in smoothings], (n, s))[1]
    score(n0, s0)  # the default's score, for the report
    cands = [TableCandidate(k[0], k[1], v) for k, v in sorted(scores.items())]
    return choice(n_intervals=n, smoothing=s, candidates=cands, reference=reference)
