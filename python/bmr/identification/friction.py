"""Seal friction identification (paper eq 22): ``c0 + Σ a_k sin kθ + b_k cos kθ`` by linear least squares on the
off-state runs (zero current, motor on), with the harmonic order chosen by BIC or blocked hold-out."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Iterable, Sequence

import numpy as np

from bmr import _core
from bmr._core import BmrError, Friction
from bmr.data.bundle import Bundle, Run, runs_of

__all__ = ["DEFAULT_MAX_ORDER", "FrictionFit", "fit_friction"]

DEFAULT_MAX_ORDER = 12


@dataclass
class FrictionFit:
    """Seal friction ``c0 + Σ a_k sin kθ + b_k cos kθ`` (N·mm) with standard errors and the order selection.

    ``scores`` maps each tried order to its criterion value (lower is better); ``criterion`` names it
    (``"bic"`` or ``"holdout"``: blocked cross-validation RMS in N·mm).
    """

    order: int
    c0: float
    a: np.ndarray
    b: np.ndarray
    c0_stderr: float
    a_stderr: np.ndarray
    b_stderr: np.ndarray
    covariance: np.ndarray
    residual_rms_nmm: float
    n: int
    criterion: str = "bic"
    scores: dict[int, float] = field(default_factory=dict)

    def __call__(self, theta_rad: np.ndarray | float) -> np.ndarray:
        """Friction torque (N·mm) at rotor angle(s) ``theta_rad`` (the core's friction series)."""
        theta = np.asarray(theta_rad, dtype=float)
        a = [float(x) for x in self.a[: self.order]]
        b = [float(x) for x in self.b[: self.order]]
        return _core.friction_series(theta.reshape(-1), float(self.c0), a, b).reshape(theta.shape)

    def to_friction(self) -> Any:
        """The core ``bmr.Friction`` with these coefficients."""
        return Friction(float(self.c0), [float(x) for x in self.a], [float(x) for x in self.b])

    def table(self) -> list[dict[str, Any]]:
        """One row per coefficient: name, value and standard error (N·mm)."""
        rows = [{"name": "c0", "value": float(self.c0), "stderr": float(self.c0_stderr)}]
        for k in range(self.order):
            rows.append({"name": f"a{k + 1}", "value": float(self.a[k]), "stderr": float(self.a_stderr[k])})
            rows.append({"name": f"b{k + 1}", "value": float(self.b[k]), "stderr": float(self.b_stderr[k])})
        return rows

    def to_dict(self) -> dict[str, Any]:
        return {
            "c0": float(self.c0), "a": [float(x) for x in self.a], "b": [float(x) for x in self.b],
            "order": int(self.order),
            "stderr": {"c0": float(self.c0_stderr), "a": [float(x) for x in self.a_stderr],
                       "b": [float(x) for x in self.b_stderr]},
            "residual_rms_nmm": float(self.residual_rms_nmm), "n": int(self.n), "criterion": self.criterion,
            "scores": {str(k): float(v) for k, v in self.scores.items()},
        }

    @classmethod
    def from_coefficients(cls, c0: float, a: Sequence[float], b: Sequence[float]) -> "FrictionFit":
        """A friction model with known coefficients and no uncertainty information."""
        a = np.asarray(a, dtype=float)
        b = np.asarray(b, dtype=float)
        if a.shape != b.shape or a.ndim != 1:
            raise BmrError(f"friction needs as many sine as cosine coefficients (got {a.size} and {b.size})")
        if not (math.isfinite(c0) and np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
            raise BmrError("friction coefficients must be finite")
        k = a.size
        return cls(order=k, c0=float(c0), a=a, b=b, c0_stderr=float("nan"), a_stderr=np.full(k, np.nan),
                   b_stderr=np.full(k, np.nan), covariance=np.full((2 * k + 1, 2 * k + 1), np.nan),
                   residual_rms_nmm=float("nan"), n=0, criterion="given")


def _off_state_samples(runs: list[Run], current_tol_a: float | None) -> tuple[np.ndarray, np.ndarray]:
    """Angle and torque of the zero-current part of each off-state run: everything after the opening excursion
    (the last sample whose current exceeds ``current_tol_a``, default 5 % of the excursion: measured currents are
    noisy), less 1 % settling, and without samples above that tolerance. The excursion's own tail (the last few
    per cent of its ramp back to zero) carries hysteretic torque, not friction, and stays out."""
    thetas, torques = [], []
    for run in runs:
        i_a = np.abs(run.current)
        peak = float(np.max(i_a))
        tol = current_tol_a if current_tol_a is not None else max(1e-9, 0.05 * peak)
        excursion = np.flatnonzero(i_a > tol)
        start = int(excursion[-1]) + 1 if excursion.size else 0
        start += (len(i_a) - start) // 100
        keep = np.arange(start, len(i_a))
        keep = keep[i_a[keep] <= tol]
        if keep.size == 0:
            raise BmrError(f"run {run.name!r}: no zero-current samples for the friction fit "
                           f"(|current| ≤ {tol:.3g} A after the opening excursion)")
        thetas.append(run.theta[keep])
        torques.append(run.torque[keep])
    return np.concatenate(thetas), np.concatenate(torques)


def fit_friction(
    runs: Bundle | Run | Iterable[Run],
    *,
    max_order: int = DEFAULT_MAX_ORDER,
    criterion: str = "bic",
    folds: int = 5,
    current_tol_a: float | None = None,
) -> FrictionFit:
    """Fit the seal friction from off-state runs (zero current, motor on) by linear least squares (Rust/faer).

    ``runs``: a bundle (its ``off_state`` runs are used), one run or a list of runs. Samples at zero current after
    any opening excursion are used. The harmonic order ``K = 0..max_order`` is chosen by ``criterion``:
    ``"bic"`` (``n ln(RSS/n) + (2K+1) ln n``) or ``"holdout"`` (RMS over ``folds`` contiguous blocks, each
    predicted from the others). Orders the angle coverage cannot determine are skipped.
    """
    if isinstance(runs, Bundle):
        chosen = runs.by_kind("off_state")
        if not chosen:
            raise BmrError("bundle has no off_state run to identify friction from")
    else:
        chosen = runs_of(runs)
    if not chosen:
        raise BmrError("fit_friction needs at least one run")
    if not isinstance(max_order, (int, np.integer)) or max_order < 0:
        raise BmrError(f"max_order must be a nonnegative integer, got {max_order!r}")
    if criterion not in ("bic", "holdout"):
        raise BmrError(f"unknown order criterion {criterion!r}; use 'bic' or 'holdout'")
    theta, torque = _off_state_samples(chosen, current_tol_a)
    theta = np.ascontiguousarray(theta, dtype=float)
    torque = np.ascontiguousarray(torque, dtype=float)
    n = theta.size
    # Residuals below round-off carry no information: without this floor noise-free data would "prefer" every
    # extra harmonic that fits the rounding error.
    rss_floor = n * (1e-9 * max(float(np.max(np.abs(torque))), 1e-12)) ** 2
    scores: dict[int, float] = {}
    fits: dict[int, _core.FrictionOrderFit] = {}
    for k in range(int(max_order) + 1):
        try:
            fit = _core.fit_friction_order(theta, torque, k)
        except BmrError:
            break  # higher orders are not determined by this angle coverage either
        fits[k] = fit
        if criterion == "bic":
            rss = max(fit.rss, rss_floor)
            scores[k] = n * math.log(rss / n) + (2 * k + 1) * math.log(n)
        else:
            scores[k] = _holdout_rms(theta, torque, k, folds)
    if not fits:
        raise BmrError(f"friction fit failed: {n} off-state samples do not determine even the constant term")
    best = min(scores, key=lambda k: scores[k])
    f = fits[best]
    return FrictionFit(order=best, c0=f.c0, a=f.a, b=f.b, c0_stderr=f.c0_stderr, a_stderr=f.a_stderr,
                       b_stderr=f.b_stderr, covariance=f.covariance, residual_rms_nmm=math.sqrt(f.rss / n), n=n,
                       criterion=criterion, scores=scores)


def _holdout_rms(theta: np.ndarray, torque: np.ndarray, order: int, folds: int) -> float:
    n = theta.size
    edges = np.linspace(0, n, max(2, folds) + 1).astype(int)
    sse, count = 0.0, 0
    for lo, hi in zip(edges[:-1], edges[1:]):
        mask = np.ones(n, bool)
        mask[lo:hi] = False
        try:
            f = _core.fit_friction_order(np.ascontiguousarray(theta[mask]), np.ascontiguousarray(torque[mask]),
                                         order)
        except BmrError:
            return float("inf")
        fit = FrictionFit(order, f.c0, f.a, f.b, 0.0, f.a_stderr, f.b_stderr, f.covariance, 0.0, 0)
        e = torque[lo:hi] - fit(theta[lo:hi])
        sse += float(e @ e)
        count += e.size
    return math.sqrt(sse / max(count, 1))
