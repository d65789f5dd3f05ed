"""What no named effect explains: a sparse regression of the residual on signals built from the run.

When the accepted effects leave structure above the noise, the residual ``r`` (measured − extended model) is
regressed on a candidate library ``Θ`` of run signals (``bmr._core.CANDIDATES``: input, |input|, input², input
rate, model output, time, time since the last reversal and its logarithm, the branch direction, running integrals
of the input and of its square, products with the model output, angle harmonics when there is an angle; built per
run in Rust, :func:`bmr._core.candidate_signals`) by sequentially thresholded least squares (STLSQ, as in SINDy):
least squares, cut every term whose contribution is below a threshold, refit on the rest, until nothing changes.
This is the discrepancy-modelling idea of Ebers, Steele and Kutz (SIAM J. Appl. Dyn. Syst. 2024): learn the
missing term from data. bmr tries its named mechanisms first and learns an equation only for what they leave.

Every choice is made on blocked held-out data (the diagnosis's folds):

* the threshold (a term's RMS contribution, a multiple of the noise floor) by inner blocked cross-validation on
  the training blocks of each outer fold;
* each term of the support is kept only if dropping it loses held-out accuracy (backward elimination);
* the learned equation is accepted like an effect: held-out gain positive in most folds, its t interval excluding
  zero, at least ``MIN_GAIN`` and ``MIN_EXCESS`` of the held-out variance above the noise.

All fits use the blocks' Gram matrices (``ΘᵀΘ``, ``Θᵀr``, ``rᵀr`` summed per block), so a candidate threshold costs
a few small solves. Coefficients are reported in the declared units: ``{u}`` the input unit, ``{y}`` the output's.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from bmr import _core

__all__ = ["CandidateLibrary", "LearnedTerms", "candidate_library", "coefficient_unit", "learn", "unit_text",
           "THRESHOLDS"]

# Thresholds on a term's RMS contribution, in multiples of the noise floor.
THRESHOLDS = (0.03, 0.06, 0.12, 0.25, 0.5, 1.0)
# A learned term stays only if dropping it costs at least this share of the held-out sum of squares, and an
# equation keeps at most MAX_TERMS terms (the least useful go first): parsimony, as in SINDy.
MIN_TERM_GAIN = 0.005
MAX_TERMS = 5
# Signals more correlated than this with an earlier one of the library are left out of the regression.
COLLINEAR = 0.999
_RIDGE = 1e-8
# Rows per chunk of the moment sums in `learn` (bounds its temporaries to a few MB).
_CHUNK_ROWS = 16384


def unit_text(template: str, input_unit: str, output_unit: str) -> str:
    """A library unit template in the declared units: ``"{u}*s"`` → ``"A·s"``, ``"{y}*{u}^2*s"`` →
    ``"N·mm·A²·s"``."""
    text = template.replace("{u}", input_unit).replace("{y}", output_unit)
    return text.replace("^2", "²").replace("*", "·")


def coefficient_unit(template: str, input_unit: str, output_unit: str) -> str:
    """The unit of a term's coefficient: the output unit over the signal's (``"{u}*s"`` → ``"N·mm/(A·s)"``; a
    signal that carries the output, ``"{y}*s"``, → ``"1/s"``; a dimensionless one → the output unit)."""
    factors = [f for f in template.split("*") if f]
    if "{y}" in factors:
        factors.remove("{y}")
        rest = unit_text("*".join(factors), input_unit, output_unit) if factors else "1"
        if rest == "1":
            return "1"
        return f"1/({rest})" if ("·" in rest or "/" in rest) else f"1/{rest}"
    column = unit_text(template, input_unit, output_unit)
    if column == "1":
        return output_unit
    return f"{output_unit}/({column})" if ("·" in column or "/" in column) else f"{output_unit}/{column}"


@dataclass
class CandidateLibrary:
    """The candidate signals over the evaluated spans (``matrix``: samples × terms), with names, unit templates and
    definitions."""

    matrix: np.ndarray
    names: list[str]
    units: list[str]
    docs: list[str]


def candidate_library(runs: Sequence[Any], deadband: float, *, harmonics: int = 12) -> CandidateLibrary:
    """The library of the evaluation runs: each run is an object with ``t_s`` (time since the run's start, s),
    ``u`` (input), ``y`` (model output), ``theta`` (angle, rad, or None) over the whole run and ``start`` (first
    evaluated sample); signals are built on the whole run (integrals and reversal times from its start) and cut to
    the evaluated span."""
    with_angle = all(r.theta is not None for r in runs)
    h = harmonics if with_angle else 0
    names = [c[0] for c in _core.CANDIDATES]
    units = [c[1] for c in _core.CANDIDATES]
    docs = [c[2] for c in _core.CANDIDATES]
    for k in range(1, h + 1):
        names += [f"sin({k}θ)", f"cos({k}θ)"]
        units += ["1", "1"]
        docs += [f"angle harmonic {k}", f"angle harmonic {k}"]
    # Each run's block is copied into the library as soon as it is made: a list of every run's whole-run block
    # stacked at the end would hold the library twice (with the openings) at the diagnosis's peak of memory.
    matrix = np.empty((sum(max(r.u.size - r.start, 0) for r in runs), len(names)))
    pos = 0
    for r in runs:
        m = _core.candidate_signals(r.t_s, r.u, r.y, deadband=deadband,
                                    theta_rad=r.theta if with_angle else None, harmonics=h)
        part = m[r.start:]
        matrix[pos:pos + part.shape[0]] = part
        pos += part.shape[0]
        del m, part
    return CandidateLibrary(matrix, names, units, docs)


@dataclass
class _Moments:
    """Per-block sufficient statistics of the standardised regression ``r ~ [1, Θ/scale]``."""

    gram: np.ndarray  # blocks × p × p
    cross: np.ndarray  # blocks × p
    sq: np.ndarray  # blocks
    count: np.ndarray  # blocks

    def train(self, blocks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.gram[blocks].sum(axis=0), self.cross[blocks].sum(axis=0)

    def sse(self, blocks: np.ndarray, beta: np.ndarray) -> float:
        g, c = self.gram[blocks].sum(axis=0), self.cross[blocks].sum(axis=0)
        return float(self.sq[blocks].sum() - 2.0 * beta @ c + beta @ g @ beta)


def _solve(g: np.ndarray, c: np.ndarray, support: np.ndarray) -> np.ndarray:
    """Least squares on the columns in ``support`` (the intercept, column 0, always in)."""
    idx = np.flatnonzero(support)
    beta = np.zeros(g.shape[0])
    if idx.size == 0:
        return beta
    gs = g[np.ix_(idx, idx)]
    ridge = _RIDGE * max(float(np.trace(gs)) / idx.size, 1e-300)
    try:
        beta[idx] = np.linalg.solve(gs + ridge * np.eye(idx.size), c[idx])
    except np.linalg.LinAlgError:
        beta[idx] = np.linalg.lstsq(gs, c[idx], rcond=None)[0]
    return beta


def _stlsq(g: np.ndarray, c: np.ndarray, n: float, threshold: float, support: np.ndarray | None = None
           ) -> np.ndarray:
    """Sequentially thresholded least squares: a term stays while its RMS contribution ``|β|`` (columns have unit
    RMS) is at least ``threshold``."""
    keep = np.ones(g.shape[0], dtype=bool) if support is None else support.copy()
    keep[0] = True
    beta = _solve(g, c, keep)
    for _ in range(20):
        small = np.abs(beta) < threshold
        small[0] = False
        new = keep & ~small
        if np.array_equal(new, keep):
            break
        keep = new
        beta = _solve(g, c, keep)
    return beta


def _choose_threshold(m: _Moments, train_blocks: np.ndarray, thresholds: Sequence[float]) -> float:
    """The threshold with the smallest inner blocked cross-validation error on ``train_blocks``."""
    best = (math.inf, thresholds[-1])
    for th in thresholds:
        sse = 0.0
        for b in train_blocks:
            inner = train_blocks[train_blocks != b]
            g, c = m.train(inner)
            beta = _stlsq(g, c, float(m.count[inner].sum()), th)
            sse += m.sse(np.array([b]), beta)
        if sse < best[0]:
            best = (sse, th)
    return best[1]


def _heldout_sse(m: _Moments, blocks: np.ndarray, support: np.ndarray) -> np.ndarray:
    """Held-out SSE of each of ``blocks`` for the least-squares fit on ``support`` fitted on the other ones (the
    folds' systems solved as one stack: the backward elimination asks for thousands of them)."""
    trains = [m.train(blocks[blocks != k]) for k in blocks]
    g = np.stack([t[0] for t in trains])
    c = np.stack([t[1] for t in trains])
    idx = np.flatnonzero(support)
    beta = np.zeros(c.shape)
    if idx.size:
        gs = g[:, idx[:, None], idx[None, :]]
        ridge = _RIDGE * np.maximum(np.trace(gs, axis1=1, axis2=2) / idx.size, 1e-300)
        try:
            beta[:, idx] = np.linalg.solve(gs + ridge[:, None, None] * np.eye(idx.size), c[:, idx, None])[..., 0]
        except np.linalg.LinAlgError:
            beta = np.stack([_solve(gk, ck, support) for gk, ck in zip(g, c)])
    gk, ck = m.gram[blocks], m.cross[blocks]
    return (m.sq[blocks] - 2.0 * np.einsum("ki,ki->k", beta, ck)
            + np.einsum("ki,kij,kj->k", beta, gk, beta))


def _select(m: _Moments, blocks: np.ndarray, thresholds: Sequence[float]) -> tuple[np.ndarray, float, list[int]]:
    """The support learned from ``blocks`` alone: the STLSQ threshold by leave-one-block-out cross-validation,
    then backward elimination of every term whose removal does not cost held-out accuracy. Returns the support,
    the threshold and the terms dropped on held-out gain."""
    threshold = _choose_threshold(m, blocks, thresholds)
    g, c = m.train(blocks)
    beta = _stlsq(g, c, float(m.count[blocks].sum()), threshold)
    support = np.abs(beta) > 0
    support[0] = True
    dropped: list[int] = []
    base = _heldout_sse(m, blocks, support).sum()
    while support[1:].any():
        trials = []
        for j in np.flatnonzero(support[1:]) + 1:
            s = support.copy()
            s[j] = False
            trials.append((_heldout_sse(m, blocks, s).sum(), int(j)))
        sse, j = min(trials)
        if sse > base * (1.0 + MIN_TERM_GAIN) and int(support[1:].sum()) <= MAX_TERMS:
            break
        support[j] = False
        dropped.append(j)
        base = sse
    return support, threshold, dropped


@dataclass
class LearnedTerms:
    """The learned discrepancy: ``Δy = Σ coefficientᵢ · signalᵢ`` (plus a constant), its held-out gain and what
    was tried. ``terms``: ``{"name", "unit" (the signal's, declared units), "coefficient", "coefficient_unit",
    "doc", "heldout_gain_if_dropped"}``."""

    terms: list[dict[str, Any]]
    intercept: float
    fold_gains: np.ndarray
    rms_before: float
    rms_after: float
    noise: float
    threshold: float
    output_unit: str
    rejected: list[str] = field(default_factory=list)

    @property
    def mean_gain(self) -> float:
        return float(np.mean(self.fold_gains)) if self.fold_gains.size else 0.0

    @property
    def folds_positive(self) -> int:
        return int(np.sum(self.fold_gains > 0))

    def equation(self, digits: int = 3) -> str:
        """``Δy = 0.0123 N·mm/(A·s) · int(u dt) − 4.1e-3 N·mm · dir*ln(1+t_rev/dt)``."""
        from bmr.data.units import format_number

        if not self.terms:
            return "Δy = 0"
        parts = []
        for i, t in enumerate(self.terms):
            coef = t["coefficient"]
            sign = "−" if coef < 0 else "+"
            unit = "" if t["coefficient_unit"] == "1" else f" {t['coefficient_unit']}"
            text = f"{format_number(abs(coef), digits)}{unit} · {t['name']}"
            parts.append((("−" if coef < 0 else "") if i == 0 else f" {sign} ") + text)
        return "Δy = " + "".join(parts)

    def predict(self, library: np.ndarray, names: Sequence[str]) -> np.ndarray:
        out = np.full(library.shape[0], self.intercept)
        for t in self.terms:
            out += t["coefficient"] * library[:, list(names).index(t["name"])]
        return out

    def to_dict(self) -> dict[str, Any]:
        return {"equation": self.equation(), "terms": self.terms, "intercept": self.intercept,
                "gain": self.mean_gain, "folds_positive": self.folds_positive,
                "fold_gains": [float(g) for g in self.fold_gains],
                "heldout_rms_before": self.rms_before, "heldout_rms_after": self.rms_after,
                "threshold": self.threshold, "dropped_on_heldout_gain": self.rejected}


def learn(library: CandidateLibrary, residual: np.ndarray, block: np.ndarray, folds: int, noise: float, *,
          input_unit: str, output_unit: str, thresholds: Sequence[float] = THRESHOLDS) -> LearnedTerms:
    """Learn the sparse discrepancy of ``residual`` (evaluated samples) on ``library`` with blocked folds
    (``block``: the fold of each sample). ``noise``: the noise floor (output units) that scales the thresholds."""
    x = np.asarray(library.matrix, dtype=float)
    r = np.asarray(residual, dtype=float)
    block = np.asarray(block)
    n, width = x.shape
    # Every moment below is accumulated over row chunks: the library is samples × ~60 terms, and full-size
    # temporaries of it (squares, centred copies, scaled copies) would each cost as much memory as the library.
    chunks = [(a, min(a + _CHUNK_ROWS, n)) for a in range(0, n, _CHUNK_ROWS)]
    sumsq = np.zeros(width)
    for a, b in chunks:
        sumsq += np.einsum("ij,ij->j", x[a:b], x[a:b])
    scale = np.sqrt(sumsq / n) if n else np.zeros(width)
    cols = np.flatnonzero(scale > 1e-300)
    # Near-duplicate signals (|u| of a one-sided input is u; the model output of a nearly linear device follows u)
    # would share a term with opposite, unstable coefficients: keep the first of each near-collinear group.
    mean = x.mean(axis=0)[cols] if n else np.zeros(cols.size)
    inner = np.zeros((cols.size, cols.size))
    for a, b in chunks:
        zc = x[a:b, cols] - mean
        inner += zc.T @ zc
    norm = np.sqrt(np.maximum(np.diag(inner), 0.0))
    keep_cols: list[int] = []
    for j in range(cols.size):
        if norm[j] <= 1e-12 * max(float(np.max(norm)), 1e-300):
            continue
        if all(abs(float(inner[j, i])) < COLLINEAR * norm[j] * norm[i] for i in keep_cols):
            keep_cols.append(j)
    idx = cols[keep_cols]
    usable = np.zeros(width, dtype=bool)
    usable[idx] = True
    names = [library.names[i] for i in idx]
    units = [library.units[i] for i in idx]
    docs = [library.docs[i] for i in idx]
    # Per fold: the Gram matrix of [1, scaled terms], its products with the residual, the residual's square sum.
    p = 1 + idx.size
    gram = np.zeros((folds, p, p))
    cross = np.zeros((folds, p))
    sq = np.zeros(folds)
    count = np.zeros(folds)
    for a, b in chunks:
        z = np.empty((b - a, p))
        z[:, 0] = 1.0
        np.divide(x[a:b, idx], scale[idx], out=z[:, 1:])
        rc, bc = r[a:b], block[a:b]
        for k in range(folds):
            rows = bc == k
            if not rows.any():
                continue
            zk, rk = z[rows], rc[rows]
            gram[k] += zk.T @ zk
            cross[k] += zk.T @ rk
            sq[k] += rk @ rk
            count[k] += np.count_nonzero(rows)
    m = _Moments(gram, cross, sq, count)
    ths = [noise * t for t in thresholds]
    every = np.arange(folds)
    # Nested: each outer fold's support is learned from the other folds only, then judged on it.
    gains = np.zeros(folds)
    before_sse = np.zeros(folds)
    after_sse = np.zeros(folds)
    intercept_only = np.zeros(p, dtype=bool)
    intercept_only[0] = True
    for k in every:
        train = every[every != k]
        sup_k, _, _ = _select(m, train, ths)
        g, c = m.train(train)
        after_sse[k] = m.sse(np.array([k]), _solve(g, c, sup_k))
        before_sse[k] = m.sse(np.array([k]), _solve(g, c, intercept_only))
        b, a = math.sqrt(before_sse[k]), math.sqrt(after_sse[k])
        gains[k] = (b - a) / b if b > 0 else 0.0
    support, threshold, dropped_idx = _select(m, every, ths)
    dropped = [names[j - 1] for j in dropped_idx]
    base = _heldout_sse(m, every, support).sum()
    g, c = m.train(every)
    beta = _solve(g, c, support)
    terms = []
    for j in np.flatnonzero(support[1:]) + 1:
        s = support.copy()
        s[j] = False
        without = _heldout_sse(m, every, s).sum()
        col_unit = unit_text(units[j - 1], input_unit, output_unit)
        terms.append({"name": names[j - 1], "unit": col_unit,
                      "coefficient": float(beta[j] / scale[usable][j - 1]),
                      "coefficient_unit": coefficient_unit(units[j - 1], input_unit, output_unit),
                      "doc": docs[j - 1],
                      "contribution_rms": float(abs(beta[j])),
                      "heldout_gain_if_dropped": float(1.0 - math.sqrt(base / without)) if without > 0 else 0.0})
    terms.sort(key=lambda t: -t["contribution_rms"])
    n = float(count.sum())
    return LearnedTerms(terms, float(beta[0]), gains, math.sqrt(before_sse.sum() / n),
                        math.sqrt(after_sse.sum() / n), noise, threshold, output_unit, dropped)
