"""The least-squares table's resolution (grid intervals over the input range) and its smoothing, chosen by blocked
cross-validation inside the identification runs.

Each training run is cut into contiguous time blocks; fold ``f`` holds out every block whose index is ``f`` modulo
the number of folds, in every run at once. The held-out samples still drive the memory (a Preisach state is the
whole input history) but are kept out of the regression, and they are scored with the run's own calibration
(offset, gain, initial state, leakage) fitted on the rest. Runs held out of the identification are never seen.
The search is coordinate-wise on a coarse grid — smoothing at the default resolution, then the resolution at the
best smoothing, then the neighbouring smoothings once more at the chosen resolution — so its cost is at most a
dozen fits per fold, not the whole product. Among settings within :data:`TIE_SHARE` of the best score the smoother, then the coarser, is
kept: a smoother density moves little when the range's ends move a little.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from bmr._core import BmrError
from bmr.data.bundle import Run
from bmr.identification.lstsq import fit_tables_lstsq
from bmr.identification.signals import run_input, run_output, running_integral

__all__ = ["TableCandidate", "TableChoice", "choose_table_settings", "block_folds", "RESOLUTIONS", "SMOOTHINGS",
           "DEFAULT_INTERVALS", "DEFAULT_SMOOTHING", "FOLDS", "TIE_SHARE"]

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
# Initial-state estimation rounds in the cross-validation fits (the final fit uses the full count).
CV_ROUNDS = 1


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
    setting's scores (output units), and which settings the caller fixed (not searched)."""

    n_intervals: int
    smoothing: float
    input_range: tuple[float, float]
    folds: int
    blocks: int
    candidates: list[TableCandidate] = field(default_factory=list)
    fixed: tuple[str, ...] = ()

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
                "default_cv_rms": finite(self.default_cv_rms), "fixed": list(self.fixed),
                "candidates": [c.to_dict() for c in self.candidates]}

    def __repr__(self) -> str:
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


def _cv_rms(runs: Sequence[Run], friction: Any, masks: list[list[np.ndarray]], n_intervals: int,
            smoothing: float, fit_options: dict[str, Any]) -> float:
    """RMS over every fold's held-out samples of the fit on the rest."""
    sse, count = 0.0, 0
    us = [run_input(r) for r in runs]
    ys = [run_output(r, friction) for r in runs]
    for fold in masks:
        exclude = {r.name: m for r, m in zip(runs, fold)}
        try:
            tables = fit_tables_lstsq(runs, friction, n_intervals=n_intervals, smoothing=smoothing,
                                      exclude=exclude, iterations=CV_ROUNDS, **fit_options)
        except BmrError:
            return math.inf
        for k, (r, u, y, m) in enumerate(zip(runs, us, ys, fold)):
            if not m.any():
                continue
            integral = running_integral(u, r.t) if tables.leakage_rate is not None else None
            e = (y - tables.run_prediction(k, u, integral))[m]
            sse += float(np.sum(e * e))
            count += int(m.sum())
    return math.sqrt(sse / count) if count else math.inf


def choose_table_settings(runs: Sequence[Run], friction: Any = None, *, input_range: tuple[float, float],
                          n_intervals: int | None = None, smoothing: float | None = None, folds: int = FOLDS,
                          **fit_options: Any) -> TableChoice:
    """Choose the resolution and smoothing of :func:`fit_tables_lstsq` on ``runs`` by blocked cross-validation
    (see the module). A value given for ``n_intervals`` or ``smoothing`` is kept and not searched.
    ``fit_options``: the other arguments of the fit (offsets, gains, initial state, drift)."""
    runs = list(runs)
    if not runs:
        raise BmrError("choosing the table settings needs at least one run")
    masks = block_folds([run_input(r).size for r in runs], folds)
    scores: dict[tuple[int, float], float] = {}

    def score(n: int, s: float) -> float:
        if (n, s) not in scores:
            scores[(n, s)] = _cv_rms(runs, friction, masks, n, s, dict(fit_options, input_range=input_range))
        return scores[(n, s)]

    def best(cands: list[tuple[int, float]]) -> tuple[int, float]:
        vals = [score(n, s) for n, s in cands]
        top = min(vals)
        if not math.isfinite(top):  # no fold could be fitted: keep the default (or the given) setting
            return (n0, s0)
        # Within the tie band: the smoothest, then the coarsest (stable to small moves of the range's ends).
        near = [c for c, v in zip(cands, vals) if v <= top * (1.0 + TIE_SHARE)]
        return max(near, key=lambda c: (c[1], -c[0]))

    resolutions = [int(n_intervals)] if n_intervals is not None else list(RESOLUTIONS)
    smoothings = [float(smoothing)] if smoothing is not None else list(SMOOTHINGS)
    n0 = resolutions[0] if n_intervals is not None else DEFAULT_INTERVALS
    s0 = smoothings[0] if smoothing is not None else DEFAULT_SMOOTHING
    s = best([(n0, x) for x in smoothings])[1]
    n = best([(x, s) for x in resolutions])[0]
    if n != n0 and len(smoothings) > 1:  # the neighbouring smoothings once more at the chosen resolution
        i = smoothings.index(s)
        s = best([(n, x) for x in smoothings[max(i - 1, 0):i + 2]])[1]
    score(n0, s0)  # the default's score, for the report
    fixed = tuple(k for k, v in (("n_intervals", n_intervals), ("smoothing", smoothing)) if v is not None)
    cands = [TableCandidate(k[0], k[1], v) for k, v in sorted(scores.items())]
    return TableChoice(n_intervals=n, smoothing=s, input_range=(float(input_range[0]), float(input_range[1])),
                       folds=folds, blocks=folds * BLOCKS_PER_FOLD, candidates=cands, fixed=fixed)
