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

The time blocks of one major loop interpolate the loop along itself: they say nothing of the cells inside it that
smaller loops visit, and there they rank settings by noise (a B(H) loop's smaller loops predicted 45 % worse).
So the ranking is trusted only when the data determine paths they do not contain: fold by fold, every sweep
between two input reversals (:func:`sweep_folds`: a branch of a loop, a first-order curve) is held out whole and
predicted at the default setting from the rest; when that RMS exceeds :data:`EVIDENCE_SHARE` of the held-out
outputs' spread, the runs do not determine their own unseen branches, the default is kept and the result says why
(``undecided``). Runs with fewer than two sweeps offer no such check, and the ranking stands.

A nonnegative density (a Preisach model: monotone branches, an exact inverse) is the default. Where the runs measure
the Everett function directly — a family of first-order reversal curves, reversing at :data:`FINE_MIN_REVERSALS`
distinct inputs or more — their loops run counter-clockwise and the density was left to ``"auto"``, the signed
table (cell masses free in sign) is scored on the same folds (its setting searched as the nonnegative one's) and
taken when it predicts the held-out blocks at least :data:`SIGNED_GAIN` better (loops and minor loops alone do not
determine a negative region: on the SLAC magnet the blocks preferred a signed table that predicted runs 7-8
2.5x worse): a measured first-order reversal curve family whose FORC
distribution has negative regions (interacting nanowires) is a finding, and no nonnegative density of any
resolution fits it (FeCo nanowire FORCs: 3.9x the noise floor at 80 intervals, 3.7x-4.5x at 120-160; signed, 1.9x).

Resolutions are capped by the data: a table finer than the default gets at most one cell per
:data:`ROWS_PER_CELL` regression rows (a short recording does not pay for tables it cannot inform), and every table
stays within the solver's unknowns. A family of first-order reversal curves measures its Everett function directly
at every reversal input, so when the runs reverse at :data:`FINE_MIN_REVERSALS` distinct inputs or more one row
per cell is enough for every resolution and the list goes on with :data:`FINE_RESOLUTIONS` (tables past the dense
solver's unknowns are solved matrix-free). Cross-validation is skipped (the default kept, the reason reported) when the
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
from bmr.identification.lstsq import (DEFAULT_GRID, MAX_ROWS, LstsqTables, fit_tables_lstsq, row_weights,
                                     table_nodes)
from bmr.identification.signals import run_input, run_output, running_integral

__all__ = ["TableCandidate", "TableChoice", "choose_table_settings", "block_folds", "sweeps", "sweep_folds",
           "RESOLUTIONS", "SMOOTHINGS", "DEFAULT_INTERVALS", "DEFAULT_SMOOTHING", "FOLDS", "TIE_SHARE",
           "ROWS_PER_CELL", "MIN_ROWS_PER_BLOCK", "MAX_UNKNOWNS", "EVIDENCE_SHARE", "SWEEP_DEADBAND", "SIGNED_GAIN",
           "FINE_RESOLUTIONS", "FINE_MIN_REVERSALS", "distinct_reversals"]

DEFAULT_INTERVALS = 48
DEFAULT_SMOOTHING = 1e-4
RESOLUTIONS = (24, 32, 48, 64, 80)
# Finer tables tried for runs that reverse at many distinct inputs (a FORC family), and how many they need (half of
# a file of about a hundred curves, the other half held out: a sharp switching-field peak needs 80 intervals).
FINE_RESOLUTIONS = (112, 144)
FINE_MIN_REVERSALS = 48
# Reversal inputs closer than this share of the input range count as one.
DISTINCT_SHARE = 1e-3
SMOOTHINGS = (1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1)
FOLDS = 3
BLOCKS_PER_FOLD = 8
# Samples a run keeps in the fit in every fold (its offset is fitted on them).
MIN_KEPT = 2
# A sweep ends where the input turns back by more than this share of the table's input range.
SWEEP_DEADBAND = 0.01
# The ranking is trusted when the default setting predicts whole held-out sweeps to within this share of their
# outputs' spread about their run's mean (0.2: 96 % of the variance; one major loop predicts its other branch at
# 0.6 of the spread, multi-loop recordings at 0.001-0.004).
EVIDENCE_SHARE = 0.2
# Scores within this share of the best count as equal (the noise of a cross-validated RMS on a few folds).
TIE_SHARE = 0.01
# Regression rows a table finer than the default needs per cell to be tried.
ROWS_PER_CELL = 4
# Regression rows per time block below which the blocks are too short to score (no cross-validation).
MIN_ROWS_PER_BLOCK = 2
# The least-squares solver's limit on unknowns (cells, offsets and a drift coefficient): past the dense solve's
# (``LIMITS["everett_unknowns"]``) the tables are solved matrix-free.
MAX_UNKNOWNS = int(_core.LIMITS["everett_large_unknowns"])
# A signed density is taken over a nonnegative one when its cross-validated RMS is lower by at least this share.
SIGNED_GAIN = 0.25


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
    cross-validation was run (the default setting kept), None when it was. The check of the ranking: ``sweeps``
    held out whole in ``sweep_folds`` folds, the default setting's RMS on them (``sweep_rms``) and their outputs'
    spread about their run's mean (``sweep_spread``, output units; NaN when the runs hold fewer than two sweeps);
    ``undecided``: why the default was kept although the blocks ranked another setting first (``ranked``; both None:
    the ranking was trusted). ``density``: ``"signed"`` when the folds chose cell masses free in sign over the
    nonnegative density the fit would have used (``signed_cv_rms``: the signed table's score at the chosen setting,
    ``nonnegative_cv_rms``: the best nonnegative one; NaN when not compared); None: the fit's own choice stands."""

    n_intervals: int
    smoothing: float
    input_range: tuple[float, float]
    folds: int
    blocks: int
    candidates: list[TableCandidate] = field(default_factory=list)
    fixed: tuple[str, ...] = ()
    skipped: str | None = None
    sweeps: int = 0
    sweep_folds: int = 0
    sweep_rms: float = math.nan
    sweep_spread: float = math.nan
    undecided: str | None = None
    ranked: tuple[int, float] | None = None
    density: str | None = None
    signed_cv_rms: float = math.nan
    nonnegative_cv_rms: float = math.nan
    # The fit at the reference setting the folds were built on (reused when that setting is chosen).
    reference: LstsqTables | None = field(default=None, repr=False, compare=False)

    def score(self, n_intervals: int, smoothing: float) -> float:
        for c in self.candidates:
            if c.n_intervals == n_intervals and c.smoothing == smoothing:
                return c.cv_rms
        return math.nan

    @property
    def cv_rms(self) -> float:
        return self.signed_cv_rms if self.density == "signed" else self.score(self.n_intervals, self.smoothing)

    @property
    def default_cv_rms(self) -> float:
        return self.score(DEFAULT_INTERVALS, DEFAULT_SMOOTHING)

    def to_dict(self) -> dict[str, Any]:
        def finite(x: float) -> float | None:
            return x if math.isfinite(x) else None

        return {"n_intervals": self.n_intervals, "smoothing": self.smoothing, "input_range": list(self.input_range),
                "folds": self.folds, "blocks": self.blocks, "cv_rms": finite(self.cv_rms),
                "default_cv_rms": finite(self.default_cv_rms), "fixed": list(self.fixed), "skipped": self.skipped,
                "sweeps": self.sweeps, "sweep_folds": self.sweep_folds, "sweep_rms": finite(self.sweep_rms),
                "sweep_spread": finite(self.sweep_spread), "undecided": self.undecided,
                "ranked": None if self.ranked is None else list(self.ranked), "density": self.density,
                "signed_cv_rms": finite(self.signed_cv_rms), "nonnegative_cv_rms": finite(self.nonnegative_cv_rms),
                "candidates": [c.to_dict() for c in self.candidates]}

    def __repr__(self) -> str:
        if self.skipped is not None:
            return (f"TableChoice({self.n_intervals} intervals, smoothing {self.smoothing:g}: the default, "
                    f"not cross-validated: {self.skipped})")
        if self.undecided is not None:
            return (f"TableChoice({self.n_intervals} intervals, smoothing {self.smoothing:g}: the default, kept: "
                    f"{self.undecided})")
        d = self.default_cv_rms
        default = f", default ({DEFAULT_INTERVALS}, {DEFAULT_SMOOTHING:g}) {d:.4g}" if math.isfinite(d) else ""
        signed = (f", signed density ({self.signed_cv_rms:.4g} against {self.nonnegative_cv_rms:.4g} nonnegative)"
                  if self.density == "signed" else "")
        return (f"TableChoice({self.n_intervals} intervals, smoothing {self.smoothing:g}: cross-validated RMS "
                f"{self.cv_rms:.4g} over {self.folds} folds of time blocks{default}; {len(self.candidates)} "
                f"settings tried{signed})")


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


def sweeps(u: np.ndarray, deadband: float) -> list[slice]:
    """The monotone sweeps of ``u``: from the sample after one reversal extremum (beyond ``deadband``, input units)
    to the next extremum; the first starts at the run's start, the last ends at its end."""
    u = np.asarray(u, dtype=float)
    ends = [int(i) + 1 for i in _core.find_reversals(u, deadband)]
    bounds = [0, *[e for e in ends if 0 < e < u.size], u.size]
    return [slice(a, b) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]


def sweep_folds(us: Sequence[np.ndarray], weights: Sequence[np.ndarray], deadband: float,
                folds: int = FOLDS) -> list[list[np.ndarray]]:
    """Held-out masks, ``[fold][run]``, of whole sweeps: the sweeps of every run (:func:`sweeps`), counted across
    the runs in order, go to the folds in turn, so a fold holds out paths — a branch of a loop, a first-order
    curve — that the rest of its run does not contain. A run that is one sweep keeps its first :data:`MIN_KEPT`
    fitted rows (``weights > 0``) for its own offset; a run left with fewer than :data:`MIN_KEPT` fitted rows is
    not held out in that fold. Fewer sweeps than ``folds`` give as many folds as sweeps (at least 2)."""
    if folds < 2:
        raise BmrError(f"cross-validation needs at least 2 folds, got {folds}")
    parts = [sweeps(u, deadband) for u in us]
    folds = max(2, min(folds, sum(len(p) for p in parts)))
    out: list[list[np.ndarray]] = [[] for _ in range(folds)]
    count = 0
    for u, w, run_sweeps in zip(us, weights, parts):
        fold = np.full(u.size, -1)
        for part in run_sweeps:
            fold[part] = count % folds
            count += 1
        fitted = np.flatnonzero(w > 0)
        if len(run_sweeps) == 1:
            fold[fitted[:MIN_KEPT]] = -1
        for f in range(folds):
            held = fold == f
            out[f].append(held if fitted.size - int(np.count_nonzero(held[fitted])) >= MIN_KEPT
                          else np.zeros(u.size, dtype=bool))
    return out


def held_out_spread(ys: Sequence[np.ndarray], weights: Sequence[np.ndarray],
                    masks: list[list[np.ndarray]]) -> float:
    """RMS (output units) of every fold's held-out fitted rows about their run's weighted mean output: the scale a
    held-out RMS is measured against."""
    sse = total = 0.0
    for k, (y, w) in enumerate(zip(ys, weights)):
        if not w.any():
            continue
        mean = float(np.average(y, weights=w))
        for fold in masks:
            wh = w[fold[k]]
            sse += float(np.sum(wh * (y[fold[k]] - mean) ** 2))
            total += float(wh.sum())
    return math.sqrt(sse / total) if total > 0 else math.nan


def fold_of_each_sample(masks: list[list[np.ndarray]], run: int) -> np.ndarray:
    """The fold holding each sample of ``run`` out (``len(masks)``: none)."""
    folds = len(masks)
    return np.where(np.array([fold[run] for fold in masks]).T, np.arange(folds), folds).min(axis=1)


def pooled_rms(parts: Sequence[tuple[float, float]]) -> float:
    """The RMS over every fold's held-out rows from the folds' ``(weighted squared error, weight)`` (``inf``
    without any)."""
    weight = sum(w for _, w in parts)
    return math.sqrt(sum(e for e, _ in parts) / weight) if weight > 0 else math.inf


def distinct_reversals(us: Sequence[np.ndarray], lo: float, hi: float) -> int:
    """How many distinct inputs the runs reverse at: each run's start (a first-order reversal curve starts at its
    reversal) and its reversals beyond :data:`SWEEP_DEADBAND` of the range, inputs closer than
    :data:`DISTINCT_SHARE` of the range counted once."""
    deadband = SWEEP_DEADBAND * (hi - lo)
    parts = []
    for u in us:
        u = np.asarray(u, dtype=float)
        if u.size:
            parts.append(u[:1])
            parts.append(u[_core.find_reversals(u, deadband)])
    turns = np.sort(np.concatenate(parts)) if parts else np.zeros(0)
    return int(np.count_nonzero(np.diff(turns) > DISTINCT_SHARE * (hi - lo))) + int(turns.size > 0)


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
    grid = fit_options.get("grid", DEFAULT_GRID)  # the fit's nodes
    rows = sum(int(np.count_nonzero(w)) for w in weights)
    held = sum(1 for fold in masks if any(np.count_nonzero(w[m]) for w, m in zip(weights, fold)))
    # Resolutions the data can carry (finer than the default: enough rows per cell) within the solver's unknowns.
    many_reversals = distinct_reversals(us, lo, hi) >= FINE_MIN_REVERSALS
    per_cell = 1 if many_reversals else ROWS_PER_CELL
    resolutions = [n for n in resolutions
                   if (n <= n0 or cells(n) * per_cell <= rows) and cells(n) + n_off + 1 <= MAX_UNKNOWNS]
    if n_intervals is None and many_reversals:
        resolutions += [n for n in FINE_RESOLUTIONS if cells(n) <= rows and cells(n) + n_off + 1 <= MAX_UNKNOWNS]

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
    data = [(u, y, w, fold_of_each_sample(masks, k), k if n_off > 1 else 0, np.asarray(c.history, dtype=float),
             c.gain) for k, (u, y, w, c) in enumerate(zip(us, ys, weights, reference.runs))]
    regressions: dict[int, Any] = {}
    scores: dict[tuple[int, float], float] = {}
    signed_scores: dict[tuple[int, float], float] = {}

    def score(n: int, s: float, signed: bool | None = None) -> float:
        signed = reference.signed if signed is None else signed
        table = signed_scores if signed != reference.signed else scores
        if (n, s) not in table:
            try:
                if n not in regressions:
                    regressions.clear()  # one resolution's normal equations at a time (they are large)
                    regressions[n] = _core.EverettFolds(table_nodes(us, ys, lo, hi, n, grid), data, n_off, folds,
                                                        drift=drift)
                start = reference.passive if n == reference.n_intervals and signed == reference.signed else None
                parts = regressions[n].score(s, warm_start=None if start is None else [bool(x) for x in start],
                                             signed=signed)
                table[(n, s)] = pooled_rms(parts)
            except BmrError:
                table[(n, s)] = math.inf
        return table[(n, s)]

    def best(cands: list[tuple[int, float]], start: tuple[int, float], signed: bool | None = None) -> tuple[int, float]:
        """Walk from ``start`` along ``cands`` (ordered) each way while the score improves (warm-starting each solve
        from its neighbour's), then keep, within the tie band of the best score seen, the smoothest and coarsest.
        ``signed``: the density scored (None: the reference fit's)."""
        i = cands.index(start)
        top = score(*start, signed)
        for step in (-1, 1):
            j = i + step
            while 0 <= j < len(cands) and (v := score(*cands[j], signed)) < top:
                top, j = v, j + step
        if not math.isfinite(top):  # no fold could be fitted: keep the default (or the given) setting
            return start if signed is not None else (n0, s0)
        table = signed_scores if signed is not None and signed != reference.signed else scores
        seen = [c for c in cands if c in table]
        near = [c for c in seen if table[c] <= top * (1.0 + TIE_SHARE)]
        return max(near, key=lambda c: (c[1], -c[0]))

    s = best([(n0, x) for x in smoothings], (n0, s0))[1]
    n = best([(x, s) for x in resolutions], (n0, s))[0]
    if n != n0 and len(smoothings) > 1:  # the smoothing once more at the chosen resolution
        s = best([(n, x) for x in smoothings], (n, s))[1]
    score(n0, s0)  # the default's score, for the report
    cands = [TableCandidate(k[0], k[1], v) for k, v in sorted(scores.items())]
    check = check_on_sweeps(us, ys, weights, reference, (lo, hi), n_off, drift, folds)
    undecided, ranked = None, None
    # Without two folds of sweeps (one monotone run) there is nothing to check against: the ranking stands.
    if (n, s) != (n0, s0) and check["sweep_rms"] > EVIDENCE_SHARE * check["sweep_spread"]:
        undecided = (f"whole sweeps held out are predicted at {check['sweep_rms']:.4g} RMS, more than "
                     f"{EVIDENCE_SHARE:g} of their spread {check['sweep_spread']:.4g}: the runs do not determine "
                     f"paths they do not contain, and the blocks' ranking ({n} intervals, smoothing {s:g}) is not "
                     f"evidence")
        ranked, (n, s) = (n, s), (n0, s0)
    density, signed_rms, plain_rms = None, math.nan, math.nan
    if (fit_options.get("density", "nonnegative") == "auto" and not reference.signed and undecided is None
            and many_reversals):
        plain_rms = score(n, s)
        # The signed table's own setting, searched as the nonnegative one was.
        s_signed = best([(n0, x) for x in smoothings], (n0, s0), True)[1]
        n_signed = best([(x, s_signed) for x in resolutions], (n0, s_signed), True)[0]
        if n_signed != n0 and len(smoothings) > 1:
            s_signed = best([(n_signed, x) for x in smoothings], (n_signed, s_signed), True)[1]
        if score(n_signed, s_signed, True) <= (1.0 - SIGNED_GAIN) * plain_rms:
            density, n, s = "signed", n_signed, s_signed
            signed_rms = score(n, s, True)
    return choice(n_intervals=n, smoothing=s, candidates=cands, reference=reference, undecided=undecided,
                  ranked=ranked, density=density, signed_cv_rms=signed_rms, nonnegative_cv_rms=plain_rms, **check)


def check_on_sweeps(us: list[np.ndarray], ys: list[np.ndarray], weights: list[np.ndarray], reference: LstsqTables,
                    input_range: tuple[float, float], n_off: int, drift: list[np.ndarray] | None,
                    folds: int) -> dict[str, Any]:
    """The reference setting's RMS on whole sweeps held out (:func:`sweep_folds`) and their outputs' spread: the
    :class:`TableChoice` fields ``sweeps``, ``sweep_folds``, ``sweep_rms``, ``sweep_spread`` (NaN figures when
    fewer than two folds hold a sweep out or a fold cannot be fitted)."""
    lo, hi = input_range
    deadband = SWEEP_DEADBAND * (hi - lo)
    count = sum(len(sweeps(u, deadband)) for u in us)
    masks = sweep_folds(us, weights, deadband, folds)
    out: dict[str, Any] = {"sweeps": count, "sweep_folds": len(masks), "sweep_rms": math.nan,
                           "sweep_spread": math.nan}
    if sum(1 for fold in masks if any(np.count_nonzero(w[m]) for w, m in zip(weights, fold))) < 2:
        return out
    data = [(u, y, w, fold_of_each_sample(masks, k), k if n_off > 1 else 0, np.asarray(c.history, dtype=float),
             c.gain) for k, (u, y, w, c) in enumerate(zip(us, ys, weights, reference.runs))]
    try:
        cv = _core.EverettFolds(np.asarray(reference.everett.grid), data, n_off, len(masks),
                                drift=drift)
        start = None if reference.passive is None else [bool(x) for x in reference.passive]
        parts = cv.score(reference.settings["smoothing"], warm_start=start, signed=reference.signed)
    except BmrError:
        return out
    out["sweep_rms"] = pooled_rms(parts)
    out["sweep_spread"] = held_out_spread(ys, weights, masks)
    return out
