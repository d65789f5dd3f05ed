"""Blocked folds, grouped forward selection over the effect library and its acceptance rule.

A configuration is a field path (nominal plus accepted field effects) and a list of linear effects; its linear
parameters (plus one constant offset, part of every configuration including the nominal one) are fitted by
least squares on the training blocks. For each candidate effect and each fold, the candidate's nonlinear
parameter is chosen on the training blocks (1-D grid search) and the held-out RMS of the configuration with and
without it is compared on the test block. An effect is **accepted** when

* its held-out gain ``(rms_before − rms_after)/rms_before`` is positive in most folds, and
* the t interval (95 %, over folds) of the gain excludes zero, and
* the mean gain is at least :data:`MIN_GAIN` and the effect explains at least :data:`MIN_EXCESS` of the
  held-out residual variance above the noise floor (so that a statistically sure but negligible improvement —
  fitting the last table errors of noise-free data, say — does not name a physical effect).

The best accepted candidate joins the model (its parameters refitted on all evaluation data), and the round
repeats until nothing is accepted or the held-out RMS is within :data:`NOISE_MARGIN` of the noise floor. When no
candidate of a round is accepted alone, two that improve most folds are tried together: both join when each is
accepted by the same rule once the other is in (two effects of one session, e.g. a heating and a sensor drift,
each of which the other hides in some folds; :func:`_needed_pair`).

A named effect is physical: a candidate whose parameters, refitted on all data, fall outside the documented range
of the effect vocabulary (``bmr.effect_parameters()``) — or that pushes an effect already accepted outside its
range — is not that effect and is rejected (the next best candidate is tried; the structure may still be learned
by the sparse regression). A candidate whose mechanism signature the residual does not show
(:meth:`bmr.diagnosis.effects.Effect.signature_missing`: a ``viscous`` loss whose loop width does not grow with the
rate across drive speeds, a ``coil_lag`` shorter than half the sample period (a relaxation the samples do not
resolve), a ``thermal_drift`` that would carry more heat into a run than the current's history leaves, a
``sensor_drift`` whose trend one recording makes, a ``run_gain_offset`` that changes along a recording or
follows the session's time) is rejected the same way, and is no alternative to another either. When another accepted candidate of the same round explains as much (the paired fold
gains differ by less than their 95 % interval) and is no longer needed once the chosen one is in, the two are
reported as indistinguishable on this excitation (:class:`Alternative`), with the excitation that shows each one's
own signature.

An effect that acts on part of the samples only (:meth:`bmr.diagnosis.effects.Effect.acts_on`: an output map
after a congruent core shows only on the higher-order reversal curves, the first-order ones are in the tables) is
judged there: its held-out gain over all samples must still be positive in most folds and at least
:data:`MIN_GAIN`, and over those samples it must be positive in most folds and explain :data:`MIN_EXCESS` of their
excess over the noise floor; the t interval of its gains must exclude zero over those samples or over all of them
(the folds whose blocks hold few such curves have little to gain, so the interval over all samples would judge
the excitation, not the effect; a block whose higher-order curves are small loops, where a map is nearly linear,
has little to gain on those samples too). Each fold chooses among such values by its training fit on those samples
(:func:`_chosen_where_it_acts`).

Recording-level effects are recording-level: a drive-scaled effect (``beyond_run_calibration``: seal friction
growing with current) is judged on what it explains beyond a per-run gain and offset when the
configuration has none, so a calibration that differs between recordings is named ``run_gain_offset`` and not
after an effect that happens to scale with the drive. Once a per-run calibration is in the configuration, a
candidate that identifies the core tables again does so from protocol runs with their own calibrations divided out
(:func:`judged_on`): the recordings were shown to differ in calibration, and the protocol runs are recordings too.

How the fits are computed (:class:`Fitter`, one per diagnosis): the field torque of each path is simulated once
(bounded cache); a configuration's design ``[1, effect columns…, target]`` is gathered once on the fit rows
(grouped by fold, :attr:`bmr.diagnosis.residuals.EvalData.fit_rows`) into one small Gram matrix per fold, from
which every fold's training fit (all blocks but one), its training and held-out sums of squares and the fit on
all data follow (:class:`FoldFit`) without touching the samples again. The fits solve the column-scaled normal
equations with a pseudo-inverse (eigenvalues below 1e-13 of the largest dropped), the same least-squares
solution as a QR/SVD of the design for every design that is not rank deficient.

A linear effect that also bends the identification data re-identifies the core tables in every fold (its fitted
correction removed from the protocol runs). Those folds run worst first (by the gain of the fit on the
configuration's tables) and stop once the candidate cannot have positive gains in most folds, or once it is
clearly below :data:`MIN_GAIN` (:func:`_clearly_below`); a rejected candidate's row then holds the folds evaluated
(``folds_evaluated``). A correction that changes the protocol runs by less than :data:`CONVERGED_CORRECTION` of
the noise floor is not re-identified at all: the configuration's own least-squares tables stand.

Fewer grid values are re-identified than the grids hold: a field effect whose every value is a re-identification
is scanned coarse to fine (every eighth value first on long grids; each family of the output map on its own,
:meth:`bmr.diagnosis.effects.Effect.grid_families`). A candidate whose
mechanism signature reads the configuration's residual alone (``Effect.signature_before_only``) and is missing
is not searched at all: it could be neither named nor an alternative (its row says so, with no fold evaluated);
only its forms the signature does not test are (``Effect.without_signature``: ``non_congruent``'s mean field,
which acts on every sample where an output map shows after higher-order reversals only).
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from bmr._core import BmrError, effect_parameters

from bmr.diagnosis.effects import LIBRARY, Effect
from bmr.diagnosis.field import FieldPath, Reidentifier
from bmr.diagnosis.residuals import BoundedCache, EvalData, return_freed_memory

__all__ = ["Configuration", "Fitter", "FoldFit", "Candidate", "Alternative", "forward_selection", "out_of_range",
           "coarse_to_fine", "coordinate_scan", "MIN_GAIN", "NOISE_MARGIN"]

MIN_GAIN = 0.02
MIN_EXCESS = 0.25
NOISE_MARGIN = 1.03
# Candidates of a round tried in pairs when none is accepted alone (:func:`_needed_pair`).
PAIR_CANDIDATES = 4
# Further candidates tried as the second of a pair: those that gain most in one fold (:func:`_needed_pair`).
PAIR_PARTNERS = 2
# Two-sided 95 % Student t quantiles by degrees of freedom.
_T975 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306, 9: 2.262, 10: 2.228}
# Relative eigenvalue below which a direction of the scaled normal equations is treated as rank deficient.
_RCOND = 1e-13
# Share of the noise floor (RMS over the protocol runs) below which a further change of a fitted correction is not
# applied to the protocol runs again (see _fit_with).
CONVERGED_CORRECTION = 0.01
# Grid steps of the first pass of a costly field effect's coarse-to-fine scan (grid values, see coarse_to_fine): the
# largest that leaves more than two steps in the grid (a grid of at most two steps is scanned whole).
COARSE_STRIDES = (8, 4)
# Held-out gain added to each fold not yet re-identified when judging whether a candidate is clearly below
# MIN_GAIN on its first folds (see _clearly_below).
EARLY_EXIT_MARGIN = 0.01


def t975(df: int) -> float:
    return _T975.get(df, 2.0 + 2.4 / max(df, 1))


_RANGES: dict[str, dict[str, tuple[float, float]]] = {}


def out_of_range(name: str, params: dict[str, float]) -> list[str]:
    """The parameters of effect ``name`` outside the vocabulary's documented range, as ``"fraction=-13.8 (range
    0..0.9)"`` (empty: all in range; parameters the vocabulary does not document are not judged)."""
    if not _RANGES:
        for effect, spec in effect_parameters(model_entries=True).items():
            documented: dict[str, dict[str, float]] = spec["params"]  # type: ignore[index, assignment]
            _RANGES[effect] = {k: (float(v["min"]), float(v["max"])) for k, v in documented.items()}
    ranges = _RANGES.get(name, {})
    bad = []
    for key, value in params.items():
        if key not in ranges:
            continue
        lo, hi = ranges[key]
        v = float(value)
        if not (math.isfinite(v) and lo <= v <= hi):
            bad.append(f"{key}={v:.4g} (range {lo:g}..{hi:g})")
    return bad


@dataclass
class Alternative:
    """Two effects the data cannot tell apart: ``chosen`` (named) and ``other`` explained the same structure —
    their held-out gains (``gains``) differ by less than the 95 % interval of their paired fold differences
    (``difference_interval``), and ``other`` was not needed once ``chosen`` was in. ``excitation``: what to record
    to separate them."""

    chosen: str
    other: str
    gains: tuple[float, float]
    difference_interval: tuple[float, float]
    excitation: str
    # The runs of ``bmr simulate --separate`` that record that excitation on the virtual actuator.
    separating_runs: tuple[str, ...] = ()

    @property
    def message(self) -> str:
        text = (f"{self.chosen} or {self.other}: indistinguishable on this excitation (held-out gains "
                f"{100 * self.gains[0]:.1f} % and {100 * self.gains[1]:.1f} %); {self.excitation} would show each "
                "one's own signature")
        if self.separating_runs:
            text += f" (on the virtual actuator: bmr simulate {self.simulate_options})"
        return text

    @property
    def simulate_options(self) -> str:
        """The ``bmr simulate`` options that append the separating runs."""
        return " ".join(f"--separate {kind}" for kind in self.separating_runs)

    def to_dict(self) -> dict[str, Any]:
        return {"chosen": self.chosen, "other": self.other, "gains": list(self.gains),
                "difference_interval": list(self.difference_interval), "excitation": self.excitation,
                "separating_runs": list(self.separating_runs), "message": self.message}


@dataclass
class Configuration:
    """A field path and linear effects ``[(effect, value)]``; ``beta`` after a fit (constant first)."""

    path: FieldPath
    linear: list[tuple[Effect, Any]] = field(default_factory=list)
    beta: np.ndarray | None = None


@dataclass
class FoldFit:
    """The least-squares fits of one configuration: ``beta[k]`` fitted on the training blocks of fold ``k`` and
    ``beta[folds]`` on all fit rows; ``sse_train`` the matching training sums of squares (N·mm², the last one
    over all rows), ``sse_test[k]`` / ``n_test[k]`` the held-out sum of squares and row count of fold ``k``;
    ``widths`` the number of columns of each linear effect (after the constant)."""

    beta: np.ndarray
    sse_train: np.ndarray
    sse_test: np.ndarray
    n_test: np.ndarray
    widths: tuple[int, ...]

    @property
    def folds(self) -> int:
        return self.sse_test.size

    def test_rms(self, fold: int) -> float:
        return math.sqrt(self.sse_test[fold] / self.n_test[fold]) if self.n_test[fold] else float("nan")


def _solve_normal(gram: np.ndarray, p: int) -> tuple[np.ndarray, np.ndarray]:
    """Batched least squares from Gram matrices of ``[X | t]`` (shape ``(m, p + 1, p + 1)``): ``beta`` (m, p)
    and the residual sums of squares (m,)."""
    xx = gram[:, :p, :p]
    xt = gram[:, :p, p]
    tt = gram[:, p, p]
    scale = np.sqrt(np.maximum(np.einsum("mii->mi", xx), 0.0))
    scale = np.where(scale > 0, scale, 1.0)
    a = xx / (scale[:, :, None] * scale[:, None, :])
    b = xt / scale
    w, v = np.linalg.eigh(a)
    cutoff = _RCOND * np.max(w, axis=1, keepdims=True)
    inv = np.where(w > cutoff, 1.0 / np.where(w > cutoff, w, 1.0), 0.0)
    beta = np.einsum("mij,mj->mi", v, inv * np.einsum("mji,mj->mi", v, b)) / scale
    sse = tt - 2.0 * np.einsum("mi,mi->m", beta, xt) + np.einsum("mi,mij,mj->m", beta, xx, beta)
    return beta, np.maximum(sse, 0.0)


class Fitter:
    """Least-squares fits and residuals of configurations on the evaluated spans, for one diagnosis: it owns the
    field simulations (bounded cache), the fits already made (bounded cache) and the :class:`Reidentifier` of
    the protocol runs (``protocol``: ``(bmr.Run, start time in the bundle (s))``)."""

    def __init__(self, data: EvalData, model: Any, protocol: Sequence[Any] = (), *, max_fields: int = 3) -> None:
        self.data = data
        self.model = model
        self.measured = data.torque - data.friction_nmm
        # The measured torque on the fit rows, gathered once: every configuration's fit subtracts its field from it.
        self.measured_rows = np.take(self.measured, data.fit_rows)
        self.reidentifier = Reidentifier(model, protocol, data)
        self._fields = BoundedCache(max_entries=max_fields, max_bytes=max_fields * 8 * data.n_eval + 1)
        # Fields asked for again after their first use (the configuration of the round, its least-squares-table
        # variant): every candidate starts from them, and the paths of one candidate's folds would evict them.
        self._reused = BoundedCache(max_entries=max_fields, max_bytes=max_fields * 8 * data.n_eval + 1)
        # The drive inputs of the two most recent (delay, lag) pairs: later rounds re-simulate many paths (other
        # effects, re-identified tables) behind the same selected input stages.
        full = sum(r.current_a.size for r in data.runs)
        self._drives = BoundedCache(max_entries=2, max_bytes=2 * 8 * full + 1)
        self._fits = BoundedCache(max_entries=512, max_bytes=16 << 20)
        self.simulations = 0  # field paths simulated (for the benchmarks)

    def release(self) -> None:
        """Free what only further fits would read (prepared regressions, simulated fields, fits, derived columns)
        and give the freed heap back to the system: called once the configuration is chosen, before the
        memory-heavy steps that follow."""
        self.reidentifier.release()
        self._fields.clear()
        self._reused.clear()
        self._drives.clear()
        self._fits.clear()
        self.data.cache.clear()
        return_freed_memory()

    def nominal_path(self) -> FieldPath:
        return FieldPath.nominal(self.model, self.reidentifier.protocol, self.reidentifier)

    def field(self, path: FieldPath) -> np.ndarray:
        """Field torque (N·mm) of ``path`` over the evaluated spans (NaN when the path gives no valid tables)."""
        key = path.key()
        if key in self._reused:
            return self._reused[key]
        if key in self._fields:
            self._reused[key] = self._fields[key]
            return self._fields[key]
        self.simulations += 1
        try:
            inputs = self._drives.get((path.delay_s, path.lag_tau_s), lambda: path.drive_inputs(self.data.runs))
            ys = path.simulate(self.data.runs, inputs=inputs)
            y = self.data.concat([y[r.start:] for y, r in zip(ys, self.data.runs)])
        except BmrError:
            # This parameter value gives no valid tables (e.g. a lag so long the protocol never saturates).
            y = np.full(self.data.n_eval, np.nan)
        self._fields[key] = y
        return y

    def _blocks(self, path: FieldPath, linear: Sequence[tuple[Effect, Any]], y: np.ndarray
                ) -> tuple[list[np.ndarray], tuple[int, ...]]:
        cols, widths = [], []
        if not np.all(np.isfinite(y)):
            # A path without valid tables: its fit is discarded (infinite error), but the columns' shapes are
            # still needed, and effects that run the field output through the core refuse NaN.
            y = np.zeros_like(y)
        for eff, value in linear:
            c = np.asarray(eff.columns(self.data, value, y, self.model), dtype=float)
            c = c.reshape(c.shape[0], -1)
            cols.append(c)
            widths.append(c.shape[1])
        return cols, tuple(widths)

    def design(self, path: FieldPath, linear: Sequence[tuple[Effect, Any]]) -> tuple[np.ndarray, np.ndarray]:
        """The design matrix ``[1, effect columns…]`` over all evaluated samples and the field torque."""
        y = self.field(path)
        cols, _ = self._blocks(path, linear, y)
        return np.hstack([np.ones((y.size, 1))] + cols), y

    def solve(self, path: FieldPath, linear: Sequence[tuple[Effect, Any]]) -> FoldFit:
        """The fits of ``path`` plus ``linear`` in every fold and on all data (see :class:`FoldFit`)."""
        key = (path.key(), tuple((eff.name, value) for eff, value in linear))
        if key in self._fits:
            return self._fits[key]
        data = self.data
        k = data.folds
        y = self.field(path)
        cols, widths = self._blocks(path, linear, y)
        p = 1 + sum(widths)
        rows = data.fit_rows
        z = np.empty((p + 1, rows.size))
        z[0] = 1.0
        j = 1
        for c in cols:
            if c.shape[1] == 1:
                # A single column gathered straight into its row of z; the rows are in range, so mode="clip" only
                # spares np.take its buffered copy.
                np.take(c[:, 0], rows, out=z[j], mode="clip")
            else:
                # np.take gathers whole rows of the (samples × columns) block: faster than column by column.
                z[j:j + c.shape[1]] = np.take(c, rows, axis=0).T
            j += c.shape[1]
        np.take(y, rows, out=z[p], mode="clip")
        np.subtract(self.measured_rows, z[p], out=z[p])
        b = data.fold_bounds
        blocks = np.stack([z[:, b[i]:b[i + 1]] @ z[:, b[i]:b[i + 1]].T for i in range(k)])
        # A non-finite value anywhere in z makes its column's diagonal entries non-finite: checked on the small
        # Gram blocks instead of on every sample.
        if not np.all(np.isfinite(np.einsum("kii->ki", blocks))):
            out = FoldFit(np.zeros((k + 1, p)), np.full(k + 1, np.inf), np.full(k, np.inf),
                          np.diff(data.fold_bounds), widths)
            self._fits[key] = out
            return out
        total = blocks.sum(axis=0)
        grams = np.concatenate([total[None] - blocks, total[None]])
        beta, sse = _solve_normal(grams, p)
        xx, xt, tt = blocks[:, :p, :p], blocks[:, :p, p], blocks[:, p, p]
        bk = beta[:k]
        sse_test = tt - 2.0 * np.einsum("mi,mi->m", bk, xt) + np.einsum("mi,mij,mj->m", bk, xx, bk)
        out = FoldFit(beta, sse, np.maximum(sse_test, 0.0), np.diff(b), widths)
        self._fits[key] = out
        return out

    def fit(self, path: FieldPath, linear: Sequence[tuple[Effect, Any]], fold: int | None = None
            ) -> tuple[np.ndarray, np.ndarray]:
        """Residual (measured − predicted, N·mm, every evaluated sample) and ``beta`` fitted on the training blocks
        of ``fold`` (None: on all data)."""
        ff = self.solve(path, linear)
        beta = ff.beta[self.data.folds if fold is None else fold]
        x, y = self.design(path, linear)
        if not np.all(np.isfinite(y)):
            return np.full(y.size, np.inf), beta
        return self.measured - y - x @ beta, beta


@dataclass
class Heldout:
    """Held-out sums of squares and row counts of a configuration, per fold."""

    sse: np.ndarray
    n: np.ndarray

    def rms(self, fold: int | None = None) -> float:
        if fold is None:
            total = float(np.sum(self.n))
            return math.sqrt(float(np.sum(self.sse)) / total) if total else float("nan")
        return math.sqrt(float(self.sse[fold]) / float(self.n[fold])) if self.n[fold] else float("nan")


@dataclass
class Candidate:
    """The held-out result of one effect in one round."""

    effect: Effect
    fold_gains: np.ndarray
    rms_before: float
    rms_after: float
    values: list[Any]
    noise_nmm: float = 0.0
    # The parameters outside the vocabulary's range when refitted on all data (empty: physical or not refitted).
    unphysical: str = ""
    # Why the residual does not show the effect's mechanism signature (empty: shown or not checked).
    no_signature: str = ""
    # An effect that acts on part of the samples only (``Effect.acts_on``): the same held-out comparison over
    # those samples, on which its consistency over the folds and its share of the excess are judged.
    local: "Candidate | None" = None

    @staticmethod
    def unevaluated(effect: Effect, rms: float, noise_nmm: float, no_signature: str) -> "Candidate":
        """A candidate whose mechanism signature the configuration's residual (``rms`` held out) does not show,
        checked before its grid is searched (``Effect.signature_before_only``): no fold evaluated, no gain."""
        return Candidate(effect, np.zeros(0), rms, rms, [], noise_nmm, no_signature=no_signature)

    @property
    def mean_gain(self) -> float:
        return float(np.mean(self.fold_gains)) if self.fold_gains.size else 0.0

    @property
    def folds_positive(self) -> int:
        return int(np.sum(self.fold_gains > 0))

    @property
    def interval(self) -> tuple[float, float]:
        g = self.fold_gains
        k = g.size
        if k == 0:
            return 0.0, 0.0
        half = t975(k - 1) * float(np.std(g, ddof=1)) / math.sqrt(k) if k > 1 else float("inf")
        return float(np.mean(g) - half), float(np.mean(g) + half)

    @property
    def excess_explained(self) -> float:
        """Fraction of the held-out residual variance above the noise floor that the effect removes."""
        excess = self.rms_before ** 2 - self.noise_nmm ** 2
        if excess <= 0:
            return 0.0
        return float((self.rms_before ** 2 - self.rms_after ** 2) / excess)

    @property
    def accepted(self) -> bool:
        judged = self.local if self.local is not None else self
        lo = max(judged.interval[0], self.interval[0])
        return (self.folds_positive * 2 > self.fold_gains.size and self.mean_gain >= MIN_GAIN
                and judged.folds_positive * 2 > judged.fold_gains.size and lo > 0
                and judged.excess_explained >= MIN_EXCESS)

    @property
    def accepted_but_interval(self) -> bool:
        """The acceptance rule without its interval: consistent over the folds and enough of the excess, but
        with fold gains too spread to bound their mean above zero on their own."""
        judged = self.local if self.local is not None else self
        return (self.folds_positive * 2 > self.fold_gains.size and self.mean_gain >= MIN_GAIN
                and judged.folds_positive * 2 > judged.fold_gains.size and judged.excess_explained >= MIN_EXCESS)

    def dominates(self, other: "Candidate") -> bool:
        """At least ``other``'s gain in every fold (within half of :data:`MIN_GAIN`) and more on average, judged
        from the same configuration: where ``other`` is accepted, this explains at least as much (a 6 ms
        transport delay against the coil lag that fits it less well: 0.38 against 0.27, every fold at least as
        much, but spread wider)."""
        if self.fold_gains.size != other.fold_gains.size or not self.fold_gains.size \
                or not math.isclose(self.rms_before, other.rms_before, rel_tol=1e-9):
            return False
        return bool(np.all(self.fold_gains >= other.fold_gains - MIN_GAIN / 2)) and self.mean_gain > other.mean_gain

    def row(self) -> dict[str, Any]:
        lo, hi = self.interval
        return {"name": self.effect.name, "gain": self.mean_gain, "folds_positive": self.folds_positive,
                "gain_interval": [lo, hi], "heldout_rms_before_nmm": self.rms_before,
                "heldout_rms_after_nmm": self.rms_after, "fold_gains": [float(v) for v in self.fold_gains],
                "folds_evaluated": int(self.fold_gains.size),
                "excess_explained": self.excess_explained}


def _with(config: Configuration, eff: Effect, value: Any, data: EvalData
          ) -> tuple[FieldPath, list[tuple[Effect, Any]]]:
    if eff.field:
        return eff.apply(config.path, value, data, None), list(config.linear)
    return eff.adjust_path(config.path, value), list(config.linear) + [(eff, value)]


def judged_on(config: Configuration, eff: Effect) -> Configuration:
    """The configuration ``eff`` is judged on and joins. A candidate that identifies the core tables again from the
    protocol runs, after a per-run calibration was named on tables measured as they came (``run_gain_offset``
    without ``"+tables"``), gets its tables from protocol runs with their own calibrations divided out too: the
    recordings were shown to differ in calibration, and re-identified tables that kept the protocol runs' gains
    would be distorted by them, leaving structure to the candidate that is not its own (a creep after a
    recalibration, each fold then fitting a different share of the gain). Unchanged when the protocol runs' gains
    are negligible (:meth:`bmr.diagnosis.effects.RunGainOffset.adjust_path`) or ``eff`` keeps the tables."""
    if not eff.needs_reidentify or eff.name == "run_gain_offset":
        return config
    for i, (other, value) in enumerate(config.linear):
        tables = getattr(other, "TABLES", None)
        if other.name != "run_gain_offset" or tables is None or str(value).endswith(tables):
            continue
        path = other.adjust_path(config.path, str(value) + tables)
        if path is config.path:
            return config
        linear = list(config.linear)
        linear[i] = (other, str(value) + tables)
        return Configuration(path, linear)
    return config


def _fit_with(fitter: Fitter, config: Configuration, eff: Effect, value: Any, fold: int | None
              ) -> tuple[FoldFit, np.ndarray, FieldPath, list[tuple[Effect, Any]]]:
    """Fit ``config`` plus ``eff`` at ``value`` on the training blocks of ``fold`` (None: all data); effects that
    also bend the identification data alternate fit and re-identification until a pass would change the corrected
    protocol runs by less than :data:`CONVERGED_CORRECTION` of the noise floor (none: the configuration's
    least-squares tables stand), at most :func:`_correction_passes` times, each correction after the first
    extrapolated from the passes before (:func:`_next_correction`); the result is the pass whose fitted parameters
    differ least (in output units) from the correction its tables were identified with."""
    data = fitter.data
    index = data.folds if fold is None else fold
    path, linear = _with(config, eff, value, data)
    if eff.field:
        path = eff.settle(path)
    ff = fitter.solve(path, linear)
    beta = ff.beta[index]
    if not eff.field:
        start = 1 + sum(ff.widths[:-1])
        scale: np.ndarray | None = None
        applied = None
        tried: list[np.ndarray] = []
        fitted: list[np.ndarray] = []
        passes: list[tuple[float, FoldFit, np.ndarray, FieldPath]] = []  # (mismatch, fit, beta, path) of each pass
        correction = beta[start:]
        for _ in range(_correction_passes(ff.widths[-1])):
            new = eff.update_path(path, value, correction, data)
            if new is None:
                break
            # Converged: the refitted parameters would change the corrected protocol runs by a small share of
            # the noise, and the tables identified from them by as little. Before the first pass, against no
            # correction: the tables are then the configuration's own least-squares ones (already identified).
            if fitter.reidentifier.correction_change(
                    eff, value, np.zeros(len(beta) - start) if applied is None else applied,
                    correction) < CONVERGED_CORRECTION * data.noise_floor_nmm:
                if applied is None:
                    path = path.with_(reidentify=True)
                    ff = fitter.solve(path, linear)
                    beta = ff.beta[index]
                break
            applied = correction
            path = new
            ff = fitter.solve(path, linear)
            beta = ff.beta[index]
            if scale is None:
                # Each parameter's scale in output units (the RMS of its column), so that the extrapolation and the
                # choice of the pass weigh them alike.
                columns = np.asarray(eff.columns(data, value, fitter.field(path), fitter.model), dtype=float)
                scale = np.sqrt(np.mean(columns.reshape(data.n_eval, -1) ** 2, axis=0))
            tried.append(applied)
            fitted.append(beta[start:])
            passes.append((float(np.linalg.norm((fitted[-1] - applied) * scale)), ff, beta, path))
            correction = _next_correction(tried, fitted, scale)
        if passes:
            # The pass whose tables agree best with the parameters fitted on them: an extrapolation that overshot
            # (the map is affine only while the nonnegative tables keep their active set) is not the result.
            _, ff, beta, path = min(passes, key=lambda p: p[0])
    return ff, beta, path, linear


def _correction_passes(width: int) -> int:
    """Fit and re-identification passes of a linear effect with ``width`` parameters: a fitted correction is an
    affine map of the correction the tables were identified with (least-squares tables, a linear fit), whose fixed
    point :func:`_next_correction` reaches from ``width + 1`` passes; one more confirms it."""
    return width + 2


def _next_correction(tried: Sequence[np.ndarray], fitted: Sequence[np.ndarray], scale: np.ndarray) -> np.ndarray:
    """The next correction to identify the tables with, from the corrections ``tried`` and the parameters
    ``fitted`` on the tables each gave: the combination ``Σ a_i fitted_i`` (``Σ a_i = 1``) whose mismatches
    ``fitted_i − tried_i`` (in output units: times ``scale``) cancel best, the fixed point of an affine map once
    the passes span its parameters (Anderson mixing; one pass: the fitted parameters themselves). A plain
    alternation can crawl: tables identified at the protocol's one drive speed keep what the correction leaves of a
    loss as a wider loop, which the other speeds then read as a smaller loss, so each pass removes only a share of
    the remainder."""
    f = np.array(fitted, dtype=float)
    if len(tried) < 2:
        return f[-1]
    g = (f - np.array(tried, dtype=float)) * scale
    # Σ a_i g_i with Σ a_i = 1: the last one plus a least-squares combination of the differences.
    diff = (g[:-1] - g[-1]).T
    a, *_ = np.linalg.lstsq(diff, -g[-1], rcond=None)
    out = f[-1] + (f[:-1] - f[-1]).T @ a
    return out if np.all(np.isfinite(out)) else f[-1]


def _costly(eff: Effect) -> bool:
    """A field effect whose every grid value is a least-squares re-identification of the core tables and a new
    field simulation (the costly part of a diagnosis): its grid is scanned coarse to fine. On the core's input side
    a value is also a new input history (its regression prepared again); on the output side one more right-hand
    side."""
    return bool(eff.field and eff.needs_reidentify)


def coarse_stride(n: int) -> int | None:
    """The first step of a coarse-to-fine scan of ``n`` grid values (None: scan them all)."""
    return next((s for s in COARSE_STRIDES if n > 2 * s), None)


def coarse_to_fine(n: int, score: Callable[[int], np.ndarray], stride: int | None = None) -> dict[int, np.ndarray]:
    """Scores (one per criterion, lower is better) of the indices ``0 … n−1`` of a grid, evaluated coarse to fine:
    every ``stride``-th index and the last, then, halving the step, both neighbours of each criterion's best so far,
    until every criterion's best has its immediate neighbours evaluated (the minimum of the full grid when a score
    is unimodal along it). Returns the evaluated indices' scores."""
    stride = stride if stride is not None else coarse_stride(n) or 1
    done: dict[int, np.ndarray] = {}

    def ev(i: int) -> None:
        if 0 <= i < n and i not in done:
            done[i] = np.asarray(score(i), dtype=float).reshape(-1)

    for i in list(range(0, n, max(1, stride))) + [n - 1]:
        ev(i)
    step = max(1, stride)
    while True:
        step = max(1, step // 2)
        keys = sorted(done)
        table = np.array([done[i] for i in keys])
        table = np.where(np.isnan(table), np.inf, table)
        best = {keys[int(j)] for j in np.argmin(table, axis=0)}
        size = len(done)
        for b in sorted(best):
            ev(b - step)
            ev(b + step)
        if step == 1 and len(done) == size:
            return done


def coordinate_scan(shape: tuple[int, int], score: Callable[[int], np.ndarray]) -> dict[int, np.ndarray]:
    """Scores (one per criterion, lower is better) of a grid that is the product of two axes (``shape`` = (outer,
    inner), index ``outer·n_inner + inner``), evaluated one axis at a time: the outer axis at the middle of the
    inner one, then the inner axis at each criterion's best outer value, then the outer axis at each criterion's
    best inner value, and so on until a pass evaluates nothing new (every criterion's best is then the best along
    both of its axes). Returns the evaluated indices' scores."""
    n_outer, n_inner = shape
    done: dict[int, np.ndarray] = {}

    def ev(i: int) -> None:
        if i not in done:
            done[i] = np.asarray(score(i), dtype=float).reshape(-1)

    def best() -> set[int]:
        keys = sorted(done)
        table = np.array([done[i] for i in keys])
        table = np.where(np.isnan(table), np.inf, table)
        return {keys[int(j)] for j in np.argmin(table, axis=0)}

    inner = {n_inner // 2}
    while True:
        size = len(done)
        for j in sorted(inner):
            for o in range(n_outer):
                ev(o * n_inner + j)
        for o in sorted({b // n_inner for b in best()}):
            for j in range(n_inner):
                ev(o * n_inner + j)
        inner = {b % n_inner for b in best()}
        if len(done) == size:
            return done


def _family_score(score: Callable[[int], np.ndarray], family: range, i: int) -> np.ndarray:
    """``score`` of the ``i``-th value of a grid family (an index of the whole grid)."""
    return score(family[i])


def _scan(eff: Effect, data: EvalData, n: int, score: Callable[[int], np.ndarray]) -> dict[int, np.ndarray] | None:
    """The scores of the grid values a search needs (None: every value is scored): a costly field effect's grid
    coarse to fine (each of its families on its own), a product grid (``Effect.grid_shape``) one axis at a time."""
    shape = eff.grid_shape(data)
    if shape is not None and shape[0] * shape[1] == n and shape[0] > 2 and shape[1] > 2:
        # Searched for the best total over the criteria (the folds' training fits): every fold then picks its own
        # best among the values evaluated around it.
        return coordinate_scan(shape, lambda i: np.array([np.sum(score(i))]))
    if _costly(eff):
        families = eff.grid_families(data) or [range(n)]
        out: dict[int, np.ndarray] = {}
        for fam in families:
            if coarse_stride(len(fam)) is not None:
                part = coarse_to_fine(len(fam), functools.partial(_family_score, score, fam))
            else:
                part = {i: np.asarray(score(f_i), dtype=float).reshape(-1) for i, f_i in enumerate(fam)}
            out.update({fam[i]: v for i, v in part.items()})
        return out
    return None


def _grid_fits(fitter: Fitter, config: Configuration, eff: Effect, grid: Sequence[Any], criterion: slice,
               acting: dict[int, np.ndarray] | None = None) -> list[FoldFit | None]:
    """The fits of ``config`` plus ``eff`` at each grid value (None: not evaluated): every value, or those the
    effect's search (:func:`_scan`) needs to find the best by ``sse_train[criterion]``. ``acting`` receives, for
    each evaluated value that acts on part of the samples only, its folds' training sums of squares there
    (:func:`_masked_train_sse`)."""
    data = fitter.data
    fits: list[FoldFit | None] = [None] * len(grid)

    def score(i: int) -> np.ndarray:
        path, linear = _with(config, eff, grid[i], data)
        ff = fitter.solve(path, linear)
        fits[i] = ff
        if acting is not None:
            mask = eff.acts_on(fitter, [grid[i]])
            if mask is not None:
                # Now, while the value's field torque is cached (it may be a re-identification of the tables).
                acting[i] = _masked_train_sse(fitter, path, linear, mask, ff)
        return ff.sse_train[criterion]

    if _scan(eff, data, len(grid), score) is None:
        for i in range(len(grid)):
            score(i)
    return fits


def evaluate(fitter: Fitter, config: Configuration, eff: Effect, before: Heldout) -> Candidate:
    """Held-out gain of adding ``eff`` to ``config`` in every fold (``before``: the configuration's held-out
    sums of squares per fold)."""
    data = fitter.data
    calibration = next((e for e in LIBRARY if e.name == "run_gain_offset"), None)
    if (eff.beyond_run_calibration and calibration is not None and len(data.runs) > 1
            and all(e.name != calibration.name for e, _ in config.linear)):
        # What the effect explains beyond a per-run gain and offset (the evidence of a recording-level effect).
        config = Configuration(config.path, list(config.linear) + [(calibration, calibration.grid(data)[-1])])
        before = heldout(fitter, config)
    compared = config
    if eff.needs_reidentify and not config.path.reidentify:
        # Compare at equal table method: the gain is the effect's, not the least-squares tables'. Unless those
        # tables predict worse than the configuration's own: the gain is then over the model the configuration is
        # (else an effect could be named whose extended model predicts worse than the model it extends).
        on_tables = Configuration(config.path.with_(reidentify=True), config.linear)
        before_on_tables = heldout(fitter, on_tables)
        if np.sum(before_on_tables.sse) <= np.sum(before.sse):
            compared, before = on_tables, before_on_tables
    grid = eff.grid(data)
    acting: dict[int, np.ndarray] = {}
    fits = _grid_fits(fitter, config, eff, grid, slice(0, data.folds), acting)
    done = [f for f in fits if f is not None]
    train_sse = np.array([f.sse_train[:data.folds] if f is not None else np.full(data.folds, np.inf)
                          for f in fits])
    if eff.ranks_in_range and not eff.field:
        # Each fold ranks only the values whose parameters, fitted on its training blocks, stay in range, as the
        # fit on all data does (:func:`refit`): a value fitted against the effect's physics (a negative yield
        # force cancelling the loop width the tables keep) could never be named. A fold where none stays in range
        # ranks them all.
        inside = np.array([[f is not None and _in_range(eff, config, grid[i], f, k, data) for k in range(data.folds)]
                           for i, f in enumerate(fits)])
        train_sse = np.where(inside | ~np.any(inside, axis=0), train_sse, np.inf)
    # Grid values may differ in their number of columns (nested variants, e.g. per-run offsets with or without
    # per-run gains): rank them on the training blocks by the Bayesian information criterion.
    n_train = np.maximum(np.sum(done[0].n_test) - done[0].n_test, 2.0)
    widths = np.array([sum(f.widths) if f is not None else 0 for f in fits], dtype=float)

    def criterion(sse: np.ndarray, width: Any) -> np.ndarray:
        # Training sums of squares (NaN: no fit) and column counts → the information criterion per fold.
        sse = np.where(np.isnan(sse), np.inf, sse)
        with np.errstate(divide="ignore", invalid="ignore"):
            return n_train * np.log(np.maximum(sse, 1e-300) / n_train) + width * np.log(n_train)

    train_sse = criterion(train_sse, widths[:, None])
    reidentifies = type(eff).update_path is not Effect.update_path
    best = [int(np.argmin(train_sse[:, k])) for k in range(data.folds)]
    if eff.field:
        # The values the folds chose are fitted again on their settled paths (Effect.settle), and each fold
        # chooses again among them: the quick identification may rank a value first that settles worse.
        near = sorted(set(best))
        changed = False
        for i in near:
            path, linear = _with(config, eff, grid[i], data)
            settled = eff.settle(path)
            if settled is not path:
                fits[i] = fitter.solve(settled, linear)
                changed = True
                if i in acting:
                    acting[i] = _masked_train_sse(fitter, settled, linear, eff.acts_on(fitter, [grid[i]]), fits[i])
        if changed:
            settled_sse = np.full_like(train_sse, np.inf)
            for i in near:
                ff = fits[i]
                assert ff is not None
                settled_sse[i] = criterion(ff.sse_train[:data.folds], widths[i])
            best = [int(np.argmin(settled_sse[:, k])) for k in range(data.folds)]
    if acting:
        best = _chosen_where_it_acts(acting, best)
    best = _simplest_unless_beaten(fitter, config, eff, grid, best)
    if eff.gain_beyond_refitted_tables and not compared.path.reidentify:
        refitted = {i for i in set(best) if _with(config, eff, grid[i], data)[0].reidentify}
        if refitted:
            # The folds that chose re-identified tables are judged against the configuration on such tables.
            on_tables = heldout(fitter, Configuration(compared.path.with_(reidentify=True), compared.linear))
            pick = np.array([best[k] in refitted for k in range(data.folds)])
            before = Heldout(np.where(pick, on_tables.sse, before.sse), before.n)
    mask = eff.acts_on(fitter, [grid[i] for i in best])
    local_before = _masked_test_sse(fitter, compared.path, compared.linear, mask) if mask is not None else None
    local_after = np.zeros(data.folds)
    assert all(fits[i] is not None for i in best)  # the best of each fold was evaluated

    def gain(k: int, ff: FoldFit) -> float:
        b, a = before.rms(k), ff.test_rms(k)
        return (b - a) / b if b > 0 else 0.0

    order = list(range(data.folds))
    if reidentifies:
        # Each fold re-identifies the tables: the folds the grid fits (tables not yet re-identified) score worst
        # go first, so that a candidate without a majority of positive folds is found out early.
        order.sort(key=lambda k: gain(k, fits[best[k]]))  # type: ignore[arg-type]
    allowed = data.folds - (data.folds // 2 + 1)  # non-positive folds a majority of positive ones tolerates
    evaluated: dict[int, FoldFit] = {}
    for k in order:
        ff = fits[best[k]]
        assert ff is not None
        if reidentifies:
            ff, _, path, linear = _fit_with(fitter, config, eff, grid[best[k]], k)
        elif mask is not None:
            path, linear = _with(config, eff, grid[best[k]], data)
            path = eff.settle(path) if eff.field else path
        if mask is not None:
            local_after[k] = _masked_test_sse(fitter, path, linear, mask, fold=k)[k]
        evaluated[k] = ff
        if not reidentifies:
            continue
        if sum(gain(j, f) <= 0 for j, f in evaluated.items()) > allowed:
            # Acceptance needs positive gains in most folds: no later fold can change the decision.
            break
        if len(evaluated) >= 2 and _clearly_below(gain, fits, best, evaluated, data.folds):
            break
    folds = sorted(evaluated)
    n = float(np.sum(before.n[folds]))
    sse_after = float(sum(evaluated[k].sse_test[k] for k in folds))
    values = [grid[best[k]] for k in folds]
    cand = Candidate(eff, np.array([gain(k, evaluated[k]) for k in folds]),
                     math.sqrt(float(np.sum(before.sse[folds])) / n), math.sqrt(sse_after / n),
                     values, data.noise_floor_nmm)
    if mask is not None and local_before is not None:
        counts = _masked_counts(data, mask)[folds]
        lb, la = local_before[folds], local_after[folds]
        if np.all(counts > 0) and np.all(lb > 0):
            rb, ra = np.sqrt(lb / counts), np.sqrt(la / counts)
            cand.local = Candidate(eff, (rb - ra) / rb, math.sqrt(float(np.sum(lb) / np.sum(counts))),
                                   math.sqrt(float(np.sum(la) / np.sum(counts))), values, data.noise_floor_nmm)
        else:
            cand.local = Candidate(eff, np.zeros(len(folds)), 0.0, 0.0, values, data.noise_floor_nmm)
    return cand


def _simplest_unless_beaten(fitter: Fitter, config: Configuration, eff: Effect, grid: Sequence[Any],
                           best: list[int]) -> list[int]:
    """The folds' chosen values (``best``), or the effect's simplest value in every fold (``Effect.simplest``)
    unless the chosen ones predict their held-out blocks better than it in most folds, each fitted on its fold's
    training blocks as the acceptance fits it (the tables identified again with the correction removed: on the
    configuration's tables, which the effect itself bent, the extra parameter fits their error)."""
    if eff.simplest is None or eff.simplest not in grid:
        return best
    s = list(grid).index(eff.simplest)
    if all(b == s for b in best):
        return best
    folds = len(best)
    beaten = 0
    open_folds = [k for k in range(folds) if best[k] != s]
    for n, k in enumerate(open_folds):
        if beaten > folds // 2 or beaten + len(open_folds) - n <= folds // 2:
            break  # the majority is decided whatever the folds left show
        chosen = _fit_with(fitter, config, eff, grid[best[k]], k)[0]
        simple = _fit_with(fitter, config, eff, eff.simplest, k)[0]
        beaten += int(chosen.sse_test[k] < simple.sse_test[k])
    return best if beaten > folds // 2 else [s] * folds


def _clearly_below(gain: Callable[[int, FoldFit], float], fits: Sequence[FoldFit | None], best: Sequence[int],
                   done: dict[int, FoldFit], folds: int) -> bool:
    """Whether a candidate's mean held-out gain stays below :data:`MIN_GAIN` even if every fold not yet
    re-identified (``done``: those that are) gains what its fit on the configuration's tables gained, plus the most
    any re-identified fold gained from its re-identification, plus :data:`EARLY_EXIT_MARGIN`, and the folds
    re-identified stay below it too (a candidate stopped early is never accepted): its remaining folds are then not
    re-identified (each would be a least-squares identification of the core tables)."""
    def grid_gain(k: int) -> float:
        ff = fits[best[k]]
        assert ff is not None
        return gain(k, ff)

    if sum(gain(k, f) for k, f in done.items()) >= MIN_GAIN * len(done):
        return False
    shift = max(gain(k, f) - grid_gain(k) for k, f in done.items())
    bound = sum(gain(k, f) for k, f in done.items()) + sum(
        grid_gain(k) + max(shift, 0.0) + EARLY_EXIT_MARGIN for k in range(folds) if k not in done)
    return bound < MIN_GAIN * folds


def _masked_counts(data: EvalData, mask: np.ndarray) -> np.ndarray:
    """Held-out rows of each fold inside ``mask``."""
    b, rows = data.fold_bounds, data.fit_rows
    return np.array([np.count_nonzero(mask[rows[b[k]:b[k + 1]]]) for k in range(data.folds)], dtype=float)


def _chosen_where_it_acts(acting: dict[int, np.ndarray], best: list[int]) -> list[int]:
    """Each fold whose best value acts on part of the samples only (an output map after a congruent core, which
    shows after higher-order reversals) chooses again among such values by its training sums of squares on those
    samples (``acting``). Elsewhere these values differ only in how the tables identified under each interpolate
    between the measured curves, which can outweigh the evidence where the map acts: on the paper's protocol a
    fold of a cubic yield map (0.5) chose 0.9 by every training sample (held-out gain -2.7 %; -13 % where the map
    acts), and chooses 0.65 where the map acts (+3.8 %; +6.5 % there)."""
    keys = sorted(acting)
    table = np.array([acting[i] for i in keys])
    return [keys[int(np.argmin(table[:, k]))] if best[k] in acting else best[k] for k in range(len(best))]


def _masked_rows(fitter: Fitter, path: FieldPath, linear: Sequence[tuple[Effect, Any]], mask: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Over the fit rows inside ``mask``, in fold order: the measured output less the path's field torque, the
    design rows and each row's fold."""
    data = fitter.data
    x, y = fitter.design(path, linear)
    rows = data.fit_rows
    inside = np.flatnonzero(mask[rows])
    sel = rows[inside]
    return fitter.measured[sel] - y[sel], x[sel], np.searchsorted(data.fold_bounds, inside, side="right") - 1


def _masked_train_sse(fitter: Fitter, path: FieldPath, linear: Sequence[tuple[Effect, Any]], mask: np.ndarray,
                      ff: FoldFit) -> np.ndarray:
    """Training sums of squares of each fold over its training rows inside ``mask`` (the fit rows of the other
    folds), each fold with the parameters ``ff`` fitted on its training blocks."""
    target, design, fold_of = _masked_rows(fitter, path, linear, mask)
    out = np.empty(fitter.data.folds)
    for k in range(out.size):
        train = fold_of != k
        r = target[train] - design[train] @ ff.beta[k]
        out[k] = float(np.dot(r, r)) if np.all(np.isfinite(r)) else np.inf
    return out


def _masked_test_sse(fitter: Fitter, path: FieldPath, linear: Sequence[tuple[Effect, Any]], mask: np.ndarray,
                     fold: int | None = None) -> np.ndarray:
    """Held-out sums of squares of each fold (or only ``fold``; the others 0) over its rows inside ``mask``, each
    fold with the parameters fitted on its training blocks."""
    ff = fitter.solve(path, linear)
    target, design, fold_of = _masked_rows(fitter, path, linear, mask)
    out = np.zeros(fitter.data.folds)
    for k in range(out.size) if fold is None else [fold]:
        held = fold_of == k
        r = target[held] - design[held] @ ff.beta[k]
        out[k] = float(np.dot(r, r)) if np.all(np.isfinite(r)) else np.inf
    return out


def heldout(fitter: Fitter, config: Configuration) -> Heldout:
    """The configuration's held-out sums of squares per fold."""
    ff = fitter.solve(config.path, config.linear)
    return Heldout(ff.sse_test.copy(), ff.n_test.copy())


# Golden-section steps of the refinement between the grid neighbours of the best value: each may be a
# re-identification of the core tables, and 8 steps narrow the interval to 2 % of its width, below which the
# criterion (least-squares tables whose active set changes with the parameter) is no longer smooth.
REFINE_STEPS = 8


def _golden(f: Callable[[float], float], a: float, b: float, iters: int = REFINE_STEPS) -> float:
    g = (math.sqrt(5.0) - 1.0) / 2.0
    c, d = b - g * (b - a), a + g * (b - a)
    fc, fd = f(c), f(d)
    for _ in range(iters):
        if fc < fd:
            b, d, fd = d, c, fc
            c = b - g * (b - a)
            fc = f(c)
        else:
            a, c, fc = c, d, fd
            d = a + g * (b - a)
            fd = f(d)
    return (a + b) / 2.0


def _in_range(eff: Effect, config: Configuration, value: Any, ff: FoldFit, index: int, data: EvalData) -> bool:
    """Whether the linear effect ``eff`` at ``value``, fitted after ``config``'s effects (``ff.beta[index]``: on
    the training blocks of fold ``index``, or on all data), has its parameters in the vocabulary's range."""
    own = ff.beta[index][1 + sum(ff.widths[:len(config.linear)]):]
    return not out_of_range(eff.name, eff.params(value, own, _with(config, eff, value, data)[0]))


def refit(fitter: Fitter, config: Configuration, eff: Effect, chosen: Sequence[Any] | None = None
          ) -> tuple[Configuration, dict[str, float]]:
    """``config`` plus ``eff`` fitted on all evaluation data: grid search, then (continuous parameters) a golden
    section search between the neighbours of the best grid value. ``chosen``: the values the folds chose when the
    candidate was judged; where every fold kept the effect's simplest value (``Effect.simplest``), so does this
    fit."""
    data = fitter.data
    grid = eff.grid(data)
    if eff.simplest is not None and chosen and all(v == eff.simplest for v in chosen):
        grid = [eff.simplest]

    def crit(cfg: Configuration, v: Any, settle: bool = False) -> float:
        # The information criterion of the fit on all data (as the selection ranks grid values).
        path, linear = _with(cfg, eff, v, data)
        ff = fitter.solve(eff.settle(path) if settle and eff.field else path, linear)
        if eff.ranks_in_range and not eff.field and not _in_range(eff, cfg, v, ff, data.folds, data):
            return math.inf
        n = max(float(np.sum(ff.n_test)), 2.0)
        return float(n * math.log(max(float(ff.sse_train[data.folds]), 1e-300) / n) + sum(ff.widths) * math.log(n))

    def sse(v: Any, settle: bool = False) -> float:
        return crit(config, v, settle)

    scanned = _scan(eff, data, len(grid), lambda j: np.array([sse(grid[j])]))
    if scanned is not None:
        scores = [float(scanned[j][0]) if j in scanned else math.inf for j in range(len(grid))]
    else:
        scores = [sse(v) for v in grid]
    i = int(np.argmin(scores))
    settle = eff.field and type(eff).settle is not Effect.settle
    if settle:
        # Ranked again on settled paths (Effect.settle), the best and its neighbours, and refined on them.
        near = range(max(i - 1, 0), min(i + 2, len(grid)))
        settled = {j: sse(grid[j], settle=True) for j in near}
        i = min(settled, key=lambda j: settled[j])
        scores[i] = settled[i]
    best = grid[i]
    line = eff.along(grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]) if len(grid) > 2 else None
    if eff.refine() and line is not None:
        lo_x, hi_x, value_of = line
        if lo_x > 0 and hi_x > 0:
            cand = value_of(math.exp(_golden(lambda z: sse(value_of(math.exp(z)), settle), math.log(lo_x),
                                             math.log(hi_x))))
        else:
            cand = value_of(_golden(lambda x: sse(value_of(x), settle), lo_x, hi_x))
        if sse(cand, settle) < scores[i]:
            best = cand
    if (eff.name == "coil_lag" and config.path.delay_s > 0.0) or (
            eff.name == "time_delay" and config.path.lag_tau_s > 0.0):
        config, best = _retune_timing(fitter, config, eff, best, crit)
    ff, beta, path, linear = _fit_with(fitter, config, eff, best, None)
    new = Configuration(path, linear, beta)
    # The effect's own linear parameters follow the constant and the earlier effects' columns.
    start = 1 + sum(ff.widths[:len(config.linear)])
    own = beta[start:] if not eff.field else np.zeros(0)
    return new, eff.params(best, own, path)


# Whole samples by which a delay is moved, either way, when it and a coil lag are fitted together.
RETUNE_DELAY_SAMPLES = 3


def _retune_timing(fitter: Fitter, config: Configuration, eff: Effect, value: float,
                   crit: Callable[[Configuration, float], float]) -> tuple[Configuration, float]:
    """A coil lag joining a delay fitted before it, or a delay joining a lag: the two shift ramps alike, so the
    one fitted first took the other's shift of ramps too, and keeps what the newcomer leaves (``apply`` keeps their
    sum), off by the newcomer's share of the steps. Both are searched together: whole samples of delay within
    :data:`RETUNE_DELAY_SAMPLES` of the value so found, the lag refined by golden section for each. ``crit(
    configuration, value)``: the criterion the fit on all data ranks ``eff``'s values by. Returns the
    configuration (carrying the sum the newcomer's ``apply`` divides) and ``eff``'s value."""
    dt = min(r.dt_s for r in fitter.data.runs)
    lag_joins = eff.name == "coil_lag"
    if lag_joins:
        tau, d0 = value, max(0.0, round((config.path.delay_s - value) / dt) * dt)
    else:
        d0, tau = value, config.path.lag_tau_s - value
    if not tau > 0.0:
        return config, value

    def joined(d: float, t: float) -> tuple[Configuration, float]:
        path = config.path.with_(delay_s=d + t) if lag_joins else config.path.with_(lag_tau_s=t + d)
        return Configuration(path, config.linear, config.beta), (t if lag_joins else d)

    best = (crit(*joined(d0, tau)), d0, tau)
    for k in range(-RETUNE_DELAY_SAMPLES, RETUNE_DELAY_SAMPLES + 1):
        d = d0 + k * dt
        if d < 0.0 or (d == 0.0 and not lag_joins):
            continue
        t = math.exp(_golden(lambda z, d=d: crit(*joined(d, math.exp(z))), math.log(0.5 * tau),
                             math.log(2.0 * tau)))
        score = crit(*joined(d, t))
        if score < best[0]:
            best = (score, d, t)
    return joined(best[1], best[2])


def linear_params(fitter: Fitter, config: Configuration) -> dict[str, dict[str, float]]:
    """Every effect's parameters from a fitted configuration (field effects from the path)."""
    out = {}
    pos = 1
    widths = fitter.solve(config.path, config.linear).widths
    for (eff, value), p in zip(config.linear, widths):
        out[eff.name] = eff.params(value, config.beta[pos:pos + p], config.path)
        pos += p
    return out


def forward_selection(fitter: Fitter, *, library: Sequence[Effect] = LIBRARY, max_effects: int = 4,
                      progress: Any = None) -> dict[str, Any]:
    """Grouped forward selection (see the module doc). Returns the final configuration, the accepted steps, the
    rejected candidates (their last round), the held-out RMS of the nominal and final configurations and the
    :class:`Alternative` pairs the data could not separate."""
    data = fitter.data
    config = Configuration(fitter.nominal_path())
    config.beta = fitter.solve(config.path, config.linear).beta[data.folds]
    before = heldout(fitter, config)
    nominal_rms = before.rms()
    accepted: list[dict[str, Any]] = []
    field_effects: list[Effect] = []
    pending: list[Alternative] = []
    last: dict[str, Candidate] = {}
    remaining = list(library)
    rounds = 0
    # Round 0: are the nominal tables themselves adequate? (Not physics; tested first so that no physical
    # effect is credited with what finer tables explain.)
    tables = [e for e in remaining if e.name == "table_resolution"]
    remaining = [e for e in remaining if e.name != "table_resolution"]
    while (remaining or tables) and len(accepted) < max_effects:
        current_rms = before.rms()
        if current_rms <= NOISE_MARGIN * data.noise_floor_nmm:
            break
        candidates = tables if tables else remaining
        if tables:
            tables = []
        else:
            rounds += 1
        if progress is not None:
            progress.total = (progress.total or 0) + len(candidates)
            progress.refresh()
        cands = []
        # An effect whose parameter has no admissible value on these data (e.g. relaxation times longer than
        # the runs) cannot be tested.
        candidates = [e for e in candidates if e.grid(data)]
        for eff in candidates:
            if progress is not None:
                progress.set_postfix_str(f"round {rounds}: {eff.name}")
            missing = eff.signature_missing(fitter, config, None) if eff.signature_before_only else ""
            narrower = eff.without_signature() if missing else None
            if missing and narrower is None:
                # It could be neither named nor an alternative: its grid is not searched.
                cands.append(Candidate.unevaluated(eff, before.rms(), data.noise_floor_nmm, missing))
            else:
                # Without its signature, the forms the signature does not test are searched alone.
                base = judged_on(config, eff)
                cands.append(evaluate(fitter, base, narrower or eff,
                                      before if base is config else heldout(fitter, base)))
            if progress is not None:
                progress.update(1)
        for c in cands:
            last[c.effect.name] = c
            c.round = rounds
        ok = [c for c in cands if c.accepted]
        # A candidate that explains at least as much as an accepted one, fold by fold, is as well established.
        ok += [c for c in cands if not c.accepted and c.accepted_but_interval and any(c.dominates(a) for a in ok)]
        ok.sort(key=lambda c: -c.mean_gain)
        best = None
        for c in ok:
            trial, params = refit(fitter, judged_on(config, c.effect), c.effect, c.values)
            bad = _unphysical(fitter, trial, field_effects + ([c.effect] if c.effect.field else []))
            if bad:
                c.unphysical = "; ".join(f"{name}: {', '.join(v)}" for name, v in bad.items())
                continue
            missing = c.effect.signature_missing(fitter, judged_on(config, c.effect), trial)
            if missing:
                c.no_signature = missing
                continue
            best = c
            break
        if best is None:
            if candidates and candidates[0].name == "table_resolution":
                # A large physical effect can hide what finer tables give: try them again in later rounds.
                remaining.append(candidates[0])
                continue
            pair = _needed_pair(fitter, config, cands, field_effects)
            if pair is None:
                break
            config, steps = pair
            for c, params in steps:
                if c.effect.field:
                    field_effects.append(c.effect)
                row = c.row()
                row["params"] = params
                row["round"] = rounds
                row["paired_with"] = next(o.effect.name for o, _ in steps if o is not c)
                accepted.append(row)
                last[c.effect.name] = c
                remaining = [e for e in remaining if e is not c.effect]
            before = heldout(fitter, config)
            continue
        pending.extend(_alternatives(fitter, config, best, [c for c in ok if c is not best and not c.unphysical
                                                            and not c.no_signature],
                                     field_effects))
        config = trial
        if best.effect.field:
            field_effects.append(best.effect)
        before = heldout(fitter, config)
        row = best.row()
        row["params"] = params
        row["round"] = rounds
        accepted.append(row)
        remaining = [e for e in remaining if e is not best.effect]
    # Every accepted effect's parameters in the final configuration (checked in range when it was accepted).
    final_params = _config_params(fitter, config, field_effects)
    for row in accepted:
        eff_name = row["name"]
        if eff_name in final_params:
            row["params"] = final_params[eff_name]
    # A field effect's parameters are those of the final field path (later rounds may have refined it).
    by_name = {e.name: e for e in library}
    for row in accepted:
        effect = by_name.get(row["name"])
        if effect is not None and effect.field:
            row["params"] = effect.params(None, None, config.path)
    names = {r["name"] for r in accepted}
    rejected = []
    for name, c in last.items():
        if name in names:
            continue
        row = c.row()
        row["round"] = getattr(c, "round", 0)
        row["reason"] = (f"its mechanism signature is not in the residual ({c.no_signature}); not evaluated"
                         if c.no_signature and not c.fold_gains.size else
                         "not accepted" if not c.accepted else
                         f"parameters outside the documented range ({c.unphysical})" if c.unphysical else
                         f"its mechanism signature is not in the residual ({c.no_signature})" if c.no_signature else
                         "accepted but another effect explained more; not needed afterwards")
        rejected.append(row)
    alternatives = [a for a in pending if a.other not in names]
    return {"config": config, "accepted": accepted, "rejected": rejected, "nominal_heldout_rms_nmm": nominal_rms,
            "final_heldout_rms_nmm": before.rms(), "heldout": before, "alternatives": alternatives}


def _needed_pair(fitter: Fitter, config: Configuration, cands: Sequence[Candidate], field_effects: Sequence[Effect]
                 ) -> tuple[Configuration, list[tuple[Candidate, dict[str, float]]]] | None:
    """Two effects that each pass the acceptance rule once the other is in, where neither passed alone (two drifts
    of one session, each of which looks like noise in the folds the other dominates). Tried among the round's
    :data:`PAIR_CANDIDATES` candidates with the most gain that improve most folds without being accepted, or
    accepted without their mechanism signature: the other effect of the pair can hide it (a warming sensor's
    offset read by the heating's share carried over between runs); both must keep physical parameters and show
    their mechanism signature once the other is in. Returns the configuration with both
    and each one's candidate (judged given the other) with its parameters, or None."""
    hopeful = sorted((c for c in cands if c.fold_gains.size and c.folds_positive * 2 > c.fold_gains.size
                      and c.mean_gain >= MIN_GAIN and not c.unphysical),
                     key=lambda c: -c.mean_gain)[:PAIR_CANDIDATES]
    # The second effect of a pair may improve only the folds the first does not dominate (a 6 ms delay and a
    # reptation: the delay's correction cancels the reptation's shifts in one time block, so either alone loses
    # there): the candidates that gain most in one fold, at least a quarter, join as second partners.
    partners = sorted((c for c in cands if c.fold_gains.size and c not in hopeful and not c.unphysical
                       and c.mean_gain > 0 and float(np.max(c.fold_gains)) >= MIN_EXCESS),
                      key=lambda c: -float(np.max(c.fold_gains)))[:PAIR_PARTNERS]
    alone: dict[str, Configuration] = {}  # each candidate refitted on ``config`` once, whichever pair asks

    def with_(c: Candidate) -> Configuration:
        if c.effect.name not in alone:
            alone[c.effect.name] = refit(fitter, config, c.effect, c.values)[0]
        return alone[c.effect.name]

    for i, a in enumerate(hopeful):
        for b in hopeful[i + 1:] + partners:
            with_a = with_(a)
            b_given_a = evaluate(fitter, with_a, b.effect, heldout(fitter, with_a))
            if not b_given_a.accepted:
                continue
            with_b = with_(b)
            a_given_b = evaluate(fitter, with_b, a.effect, heldout(fitter, with_b))
            if not a_given_b.accepted:
                continue
            both, _ = refit(fitter, with_a, b.effect, b_given_a.values)
            fields = list(field_effects) + [e.effect for e in (a, b) if e.effect.field]
            if _unphysical(fitter, both, fields):
                continue
            # Each signature reads its own effect's columns last in the configuration it is given.
            if b.effect.signature_missing(fitter, with_a, both):
                continue
            if a.effect.signature_missing(fitter, with_b, refit(fitter, with_b, a.effect, a_given_b.values)[0]):
                continue
            params = _config_params(fitter, both, fields)
            return both, [(a_given_b, params[a.effect.name]), (b_given_a, params[b.effect.name])]
    return None


def _config_params(fitter: Fitter, config: Configuration, field_effects: Sequence[Effect]) -> dict[str, dict]:
    """Every effect's parameters in a fitted configuration: linear ones from its coefficients, field ones from
    its path."""
    out = linear_params(fitter, config)
    for eff in field_effects:
        out[eff.name] = eff.params(None, np.zeros(0), config.path)
    return out


def _unphysical(fitter: Fitter, config: Configuration, field_effects: Sequence[Effect]) -> dict[str, list[str]]:
    """The effects of ``config`` with parameters outside the vocabulary's range or a fitted path outside their
    physics (``Effect.outside_physics``), and which."""
    bad = {}
    physics = {eff.name: eff.outside_physics(config.path) for eff in field_effects}
    for name, params in _config_params(fitter, config, field_effects).items():
        v = out_of_range(name, params) + physics.get(name, [])
        if v:
            bad[name] = v
    return bad


def _alternatives(fitter: Fitter, config: Configuration, best: Candidate, others: Sequence[Candidate],
                  field_effects: Sequence[Effect]) -> list[Alternative]:
    """The accepted candidates of a round that explain as much as ``best`` (paired fold gains within their 95 %
    interval) with physical parameters and their mechanism signature: alternatives to it, unless a later round
    accepts them too."""
    out = []
    for c in others:
        d = best.fold_gains - c.fold_gains
        k = d.size
        if k < 2:
            continue
        half = t975(k - 1) * float(np.std(d, ddof=1)) / math.sqrt(k)
        lo, hi = float(np.mean(d)) - half, float(np.mean(d)) + half
        if lo > 0:
            continue
        trial, _ = refit(fitter, config, c.effect, c.values)
        if _unphysical(fitter, trial, list(field_effects) + ([c.effect] if c.effect.field else [])):
            continue
        # An alternative is a name too: its mechanism signature must be in the residual.
        missing = c.effect.signature_missing(fitter, config, trial)
        if missing:
            c.no_signature = missing
            continue
        ea, eb = best.effect.excitation, c.effect.excitation
        excitation = ea if ea == eb else f"{ea}, or {eb}"
        runs = tuple(dict.fromkeys(k for k in (best.effect.separating_run, c.effect.separating_run) if k))
        out.append(Alternative(best.effect.name, c.effect.name, (best.mean_gain, c.mean_gain), (lo, hi),
                               excitation, runs))
    return out
