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
repeats until nothing is accepted or the held-out RMS is within :data:`NOISE_MARGIN` of the noise floor.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from bmr._core import BmrError

from bmr.diagnosis.effects import LIBRARY, Effect
from bmr.diagnosis.field import FieldPath
from bmr.diagnosis.residuals import EvalData

__all__ = ["Configuration", "Fitter", "Candidate", "forward_selection", "MIN_GAIN", "NOISE_MARGIN"]

MIN_GAIN = 0.02
MIN_EXCESS = 0.25
NOISE_MARGIN = 1.03
# Two-sided 95 % Student t quantiles by degrees of freedom.
_T975 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306, 9: 2.262, 10: 2.228}


def t975(df: int) -> float:
    return _T975.get(df, 2.0 + 2.4 / max(df, 1))


@dataclass
class Configuration:
    """A field path and linear effects ``[(effect, value)]``; ``beta`` after a fit (constant first)."""

    path: FieldPath
    linear: list[tuple[Effect, Any]] = field(default_factory=list)
    beta: np.ndarray | None = None


MAX_FIT_ROWS = 200_000
"""Training rows used per least-squares fit (evenly strided when there are more)."""


class Fitter:
    """Least-squares fits and residuals of configurations on the evaluated spans (field simulations cached)."""

    def __init__(self, data: EvalData, model: Any) -> None:
        self.data = data
        self.model = model
        th = data.concat(data.eval_slice("theta_rad"))
        self.measured = data.concat(data.eval_slice("torque_nmm")) - model.friction_torque(th)
        self._fields: dict[tuple, np.ndarray] = {}

    def field(self, path: FieldPath) -> np.ndarray:
        key = path.key()
        if key not in self._fields:
            try:
                ys = path.simulate(self.data.runs)
                self._fields[key] = self.data.concat([y[r.start:] for y, r in zip(ys, self.data.runs)])
            except BmrError:
                # This parameter value gives no valid tables (e.g. a lag so long the protocol never saturates).
                self._fields[key] = np.full(self.data.n_eval, np.nan)
            if len(self._fields) > 200:
                self._fields.pop(next(iter(self._fields)))
        return self._fields[key]

    def design(self, path: FieldPath, linear: Sequence[tuple[Effect, Any]]) -> tuple[np.ndarray, np.ndarray]:
        y = self.field(path)
        cols = [np.ones((y.size, 1))]
        for eff, value in linear:
            cols.append(eff.columns(self.data, value, y, self.model))
        return np.hstack(cols), y

    def fit(self, path: FieldPath, linear: Sequence[tuple[Effect, Any]], train: np.ndarray | None
            ) -> tuple[np.ndarray, np.ndarray]:
        """Residual (measured − predicted, N·mm, all evaluated samples) and ``beta`` fitted on ``train``."""
        x, y = self.design(path, linear)
        if not np.all(np.isfinite(y)):
            return np.full(y.size, np.inf), np.zeros(x.shape[1])
        target = self.measured - y
        rows = np.arange(y.size) if train is None else np.flatnonzero(train) if train.dtype == bool else train
        # Quasi-static logs are heavily oversampled for a handful of columns: an evenly strided subset of the
        # training rows gives the same fit at a fraction of the cost.
        stride = max(1, rows.size // MAX_FIT_ROWS)
        rows = rows[::stride]
        xt, tt = x[rows], target[rows]
        scale = np.maximum(np.sqrt(np.mean(xt * xt, axis=0)), 1e-300)
        beta_s, *_ = np.linalg.lstsq(xt / scale, tt, rcond=None)
        beta = beta_s / scale
        return target - x @ beta, beta


@dataclass
class Candidate:
    """The held-out result of one effect in one round."""

    effect: Effect
    fold_gains: np.ndarray
    rms_before: float
    rms_after: float
    values: list[Any]
    noise_nmm: float = 0.0

    @property
    def mean_gain(self) -> float:
        return float(np.mean(self.fold_gains))

    @property
    def folds_positive(self) -> int:
        return int(np.sum(self.fold_gains > 0))

    @property
    def interval(self) -> tuple[float, float]:
        g = self.fold_gains
        k = g.size
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
        lo, _ = self.interval
        return (self.folds_positive * 2 > self.fold_gains.size and lo > 0 and self.mean_gain >= MIN_GAIN
                and self.excess_explained >= MIN_EXCESS)

    def row(self) -> dict[str, Any]:
        lo, hi = self.interval
        return {"name": self.effect.name, "gain": self.mean_gain, "folds_positive": self.folds_positive,
                "gain_interval": [lo, hi], "heldout_rms_before_nmm": self.rms_before,
                "heldout_rms_after_nmm": self.rms_after, "fold_gains": [float(v) for v in self.fold_gains],
                "excess_explained": self.excess_explained}


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x * x))) if x.size else float("nan")


def _with(config: Configuration, eff: Effect, value: Any, data: EvalData, train: np.ndarray | None
          ) -> tuple[FieldPath, list[tuple[Effect, Any]]]:
    if eff.field:
        return eff.apply(config.path, value, data, train), list(config.linear)
    return config.path, list(config.linear) + [(eff, value)]


def _fit_with(fitter: Fitter, config: Configuration, eff: Effect, value: Any, train: np.ndarray | None
              ) -> tuple[np.ndarray, np.ndarray, FieldPath, list[tuple[Effect, Any]]]:
    """Fit ``config`` plus ``eff`` at ``value`` on ``train``; effects that also bend the identification data
    alternate fit and re-identification twice."""
    data = fitter.data
    path, linear = _with(config, eff, value, data, train)
    r, beta = fitter.fit(path, linear, train)
    if not eff.field:
        y = fitter.field(path)
        start = 1 + sum(e.columns(data, v, y, fitter.model).shape[1] for e, v in config.linear)
        for _ in range(2):
            new = eff.update_path(path, value, beta[start:], data)
            if new is None:
                break
            path = new
            r, beta = fitter.fit(path, linear, train)
    return r, beta, path, linear


def evaluate(fitter: Fitter, config: Configuration, eff: Effect, before: list[np.ndarray]) -> Candidate:
    """Held-out gain of adding ``eff`` to ``config`` in every fold (``before``: the configuration's held-out
    residual per fold)."""
    data = fitter.data
    if eff.needs_reidentify and not config.path.reidentify:
        # Compare at equal table method: the gain is the effect's, not the least-squares tables'.
        before = heldout_residuals(fitter, Configuration(config.path.with_(reidentify=True), config.linear))
    gains, after_all, before_all, values = [], [], [], []
    grid = eff.grid(data)
    for k in range(data.folds):
        test = data.test_mask(k)
        train = ~test
        best = None
        for v in grid:
            path, linear = _with(config, eff, v, data, train)
            r, _ = fitter.fit(path, linear, train)
            sse = float(np.sum(r[train] ** 2))
            if best is None or sse < best[0]:
                best = (sse, r, v)
        assert best is not None
        if type(eff).update_path is not Effect.update_path:
            r, _, _, _ = _fit_with(fitter, config, eff, best[2], train)
            best = (best[0], r, best[2])
        rb = before[k]
        ra = best[1][test]
        b, a = _rms(rb), _rms(ra)
        gains.append((b - a) / b if b > 0 else 0.0)
        after_all.append(ra)
        before_all.append(rb)
        values.append(best[2])
    return Candidate(eff, np.asarray(gains), _rms(np.concatenate(before_all)), _rms(np.concatenate(after_all)),
                     values, data.noise_floor_nmm)


def heldout_residuals(fitter: Fitter, config: Configuration) -> list[np.ndarray]:
    data = fitter.data
    out = []
    for k in range(data.folds):
        test = data.test_mask(k)
        r, _ = fitter.fit(config.path, config.linear, ~test)
        out.append(r[test])
    return out


def _golden(f: Callable[[float], float], a: float, b: float, iters: int = 14) -> float:
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


def refit(fitter: Fitter, config: Configuration, eff: Effect) -> tuple[Configuration, dict[str, float]]:
    """``config`` plus ``eff`` fitted on all evaluation data: grid search, then (continuous parameters) a golden
    section search between the neighbours of the best grid value."""
    data = fitter.data
    grid = eff.grid(data)

    def sse(v: Any) -> float:
        path, linear = _with(config, eff, v, data, None)
        r, _ = fitter.fit(path, linear, None)
        return float(np.sum(r * r))

    scores = [sse(v) for v in grid]
    i = int(np.argmin(scores))
    best = grid[i]
    if eff.refine() and len(grid) > 2:
        lo_v = grid[max(i - 1, 0)]
        hi_v = grid[min(i + 1, len(grid) - 1)]
        log = all(isinstance(v, float) and v > 0 for v in (lo_v, hi_v))
        if log:
            x = _golden(lambda z: sse(math.exp(z)), math.log(lo_v), math.log(hi_v))
            cand = math.exp(x)
        else:
            cand = _golden(sse, float(lo_v), float(hi_v))
        if sse(cand) < scores[i]:
            best = cand
    _, beta, path, linear = _fit_with(fitter, config, eff, best, None)
    new = Configuration(path, linear, beta)
    # The effect's own linear parameters follow the constant and the earlier effects' columns.
    start = 1 + sum(e.columns(data, v, fitter.field(path), fitter.model).shape[1] for e, v in config.linear)
    own = beta[start:] if not eff.field else np.zeros(0)
    return new, eff.params(best, own, path)


def linear_params(fitter: Fitter, config: Configuration) -> dict[str, dict[str, float]]:
    """Every effect's parameters from a fitted configuration (field effects from the path)."""
    out = {}
    pos = 1
    y = fitter.field(config.path)
    for eff, value in config.linear:
        p = eff.columns(fitter.data, value, y, fitter.model).shape[1]
        out[eff.name] = eff.params(value, config.beta[pos:pos + p], config.path)
        pos += p
    return out


def forward_selection(fitter: Fitter, *, library: Sequence[Effect] = LIBRARY, max_effects: int = 4,
                      progress: Any = None, protocol: Sequence[Any] = ()) -> dict[str, Any]:
    """Grouped forward selection (see the module doc). Returns the final configuration, the accepted steps, the
    rejected candidates (their last round) and the held-out RMS of the nominal and final configurations."""
    data = fitter.data
    config = Configuration(FieldPath.nominal(fitter.model, protocol))
    _, config.beta = fitter.fit(config.path, config.linear, None)
    before = heldout_residuals(fitter, config)
    nominal_rms = _rms(np.concatenate(before))
    accepted: list[dict[str, Any]] = []
    last: dict[str, Candidate] = {}
    remaining = list(library)
    rounds = 0
    # Round 0: are the nominal tables themselves adequate? (Not physics; tested first so that no physical
    # effect is credited with what finer tables explain.)
    tables = [e for e in remaining if e.name == "table_resolution"]
    remaining = [e for e in remaining if e.name != "table_resolution"]
    while (remaining or tables) and len(accepted) < max_effects:
        current_rms = _rms(np.concatenate(before))
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
        for eff in candidates:
            if progress is not None:
                progress.set_postfix_str(f"round {rounds}: {eff.name}")
            cands.append(evaluate(fitter, config, eff, before))
            if progress is not None:
                progress.update(1)
        for c in cands:
            last[c.effect.name] = c
            c.round = rounds
        ok = [c for c in cands if c.accepted]
        if not ok:
            if candidates[0].name == "table_resolution":
                continue
            break
        best = max(ok, key=lambda c: c.mean_gain)
        config, params = refit(fitter, config, best.effect)
        before = heldout_residuals(fitter, config)
        row = best.row()
        row["params"] = params
        row["round"] = rounds
        accepted.append(row)
        remaining = [e for e in remaining if e is not best.effect]
    final_params = linear_params(fitter, config)
    for row in accepted:
        eff_name = row["name"]
        if eff_name in final_params:
            row["params"] = final_params[eff_name]
    for row in accepted:
        if row["name"] in ("coil_lag", "time_delay", "non_congruent"):
            path = config.path
            row["params"] = {"coil_lag": {"tau_s": path.lag_tau_s}, "time_delay": {"delay_s": path.delay_s},
                             "non_congruent": {"curvature": path.curvature, "scale_nmm": path.scale_nmm}
                             }[row["name"]]
    names = {r["name"] for r in accepted}
    rejected = []
    for name, c in last.items():
        if name in names:
            continue
        row = c.row()
        row["round"] = getattr(c, "round", 0)
        row["reason"] = ("not accepted" if not c.accepted else
                         "accepted but another effect explained more; not needed afterwards")
        rejected.append(row)
    return {"config": config, "accepted": accepted, "rejected": rejected, "nominal_heldout_rms_nmm": nominal_rms,
            "final_heldout_rms_nmm": _rms(np.concatenate(before)), "heldout_residual": before}
