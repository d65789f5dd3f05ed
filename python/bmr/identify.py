"""Identification of the paper's model from a bundle: seal friction (eq 22), then the CBH first-order curves.

Two paths build the hysteresis tables:

* ``"forc"`` (the paper): find the reversals of the protocol runs (``first_order_ascending/descending``) with a
  dead-band, cut the first-order curves, fit each one monotonically (local linear smoothing on a node grid, then
  isotonic regression: no invented wiggles) and hand them to ``bmr.Hysteresis.from_curves``.
* ``"lstsq"`` (beyond the paper): the output of a Preisach model is linear in its Everett table given the input
  history, so the table is identified by nonnegative, smoothness-regularised least squares from any excitation
  (``bmr._core.fit_everett``); its first-order curves then build the ``bmr.Hysteresis``.

Friction is identified first from the ``off_state`` runs and subtracted from every run ("friction exclusion").
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Iterable, Sequence

import numpy as np

from bmr import _core
from bmr._core import BmrError
from bmr.bundle import Bundle, Run, read_bundle

__all__ = [
    "FrictionFit",
    "FirstOrderCurves",
    "LstsqTables",
    "fit_friction",
    "find_reversals",
    "extract_first_order_curves",
    "paper_current_curves",
    "fit_tables_lstsq",
    "evaluation_start",
    "input_range_of",
    "identify",
    "run_cli",
]

DEFAULT_MAX_ORDER = 12
# A run's state is known once its current is this close (fraction of the span) to a saturation end.
SATURATION_TOL = 0.002
Curve = tuple[np.ndarray, np.ndarray]


# --------------------------------------------------------------------------------------------------- friction
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
        """Friction torque (N·mm) at rotor angle(s) ``theta_rad``."""
        theta = np.asarray(theta_rad, dtype=float)
        y = np.full(theta.shape, float(self.c0))
        for k in range(self.order):
            y += self.a[k] * np.sin((k + 1) * theta) + self.b[k] * np.cos((k + 1) * theta)
        return y

    def to_friction(self) -> Any:
        """The core ``bmr.Friction`` with these coefficients."""
        from bmr import Friction

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


def _as_runs(runs: Bundle | Run | Iterable[Run]) -> list[Run]:
    if isinstance(runs, Bundle):
        return list(runs.runs)
    if isinstance(runs, Run):
        return [runs]
    return list(runs)


def _off_state_samples(runs: list[Run], current_tol_a: float | None) -> tuple[np.ndarray, np.ndarray]:
    """Angle and torque of the zero-current part of each off-state run: everything after the opening excursion
    (the last sample above a quarter of the run's largest current), less 1 % settling, and without samples whose
    current exceeds ``current_tol_a`` (default 5 % of the excursion; measured currents are noisy)."""
    thetas, torques = [], []
    for run in runs:
        i_a = np.abs(run.current)
        peak = float(np.max(i_a))
        tol = current_tol_a if current_tol_a is not None else max(1e-9, 0.05 * peak)
        excursion = np.flatnonzero(i_a > max(0.25 * peak, tol))
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
        chosen = _as_runs(runs)
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
    fits: dict[int, dict[str, Any]] = {}
    for k in range(int(max_order) + 1):
        try:
            fit = _core.fit_friction_order(theta, torque, k)
        except BmrError:
            break  # higher orders are not determined by this angle coverage either
        fits[k] = fit
        if criterion == "bic":
            rss = max(fit["rss"], rss_floor)
            scores[k] = n * math.log(rss / n) + (2 * k + 1) * math.log(n)
        else:
            scores[k] = _holdout_rms(theta, torque, k, folds)
    if not fits:
        raise BmrError(f"friction fit failed: {n} off-state samples do not determine even the constant term")
    best = min(scores, key=lambda k: scores[k])
    f = fits[best]
    return FrictionFit(order=best, c0=float(f["c0"]), a=np.asarray(f["a"]), b=np.asarray(f["b"]),
                       c0_stderr=float(f["c0_stderr"]), a_stderr=np.asarray(f["a_stderr"]),
                       b_stderr=np.asarray(f["b_stderr"]), covariance=np.asarray(f["covariance"]),
                       residual_rms_nmm=math.sqrt(f["rss"] / n), n=n, criterion=criterion, scores=scores)


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
        fit = FrictionFit(order, f["c0"], np.asarray(f["a"]), np.asarray(f["b"]), 0.0, f["a_stderr"],
                          f["b_stderr"], f["covariance"], 0.0, 0)
        e = torque[lo:hi] - fit(theta[lo:hi])
        sse += float(e @ e)
        count += e.size
    return math.sqrt(sse / max(count, 1))


# ------------------------------------------------------------------------------------- first-order curves
@dataclass
class FirstOrderCurves:
    """First-order curves in ``bmr.Hysteresis.from_curves`` form: ascending curves from their reversal minimum
    up (increasing ``u``), descending ones from their reversal maximum down (decreasing ``u``)."""

    ascending: list[Curve]
    descending: list[Curve]
    input_range: tuple[float, float]

    def __len__(self) -> int:
        return len(self.ascending) + len(self.descending)


def find_reversals(u: np.ndarray, deadband: float) -> np.ndarray:
    """Indices of the reversal extrema of ``u``: a maximum (minimum) is confirmed once the signal has come back
    from it by more than ``deadband`` — noise and small backward slips below the dead-band are ignored."""
    u = np.asarray(u, dtype=float)
    if not (deadband > 0 and math.isfinite(deadband)):
        raise BmrError(f"reversal dead-band must be positive and finite, got {deadband!r}")
    out: list[int] = []
    n = u.size
    if n < 2:
        return np.zeros(0, dtype=int)
    # Direction unknown until the signal leaves the starting value by more than the dead-band.
    i_max = i_min = 0
    direction = 0
    for i in range(1, n):
        x = u[i]
        if direction >= 0 and x > u[i_max]:
            i_max = i
        if direction <= 0 and x < u[i_min]:
            i_min = i
        if direction == 0:
            # The first move larger than the dead-band sets the direction; what came before is no reversal.
            if u[i_max] - x > deadband:
                direction, i_min = -1, i
            elif x - u[i_min] > deadband:
                direction, i_max = 1, i
        elif direction > 0 and u[i_max] - x > deadband:
            out.append(i_max)
            direction, i_min = -1, i
        elif direction < 0 and x - u[i_min] > deadband:
            out.append(i_min)
            direction, i_max = 1, i
    return np.asarray(out, dtype=int)


def _sample_noise(u: np.ndarray) -> float:
    """White-noise standard deviation of ``u`` from its second differences (zero on ramps and holds, ``σ√6`` for
    white noise), with the median so that the corners of the protocol do not count."""
    return float(np.median(np.abs(np.diff(u, 2)))) / (0.6745 * math.sqrt(6.0)) if u.size > 2 else 0.0


def input_range_of(currents: Sequence[np.ndarray], window: int = 21) -> tuple[float, float]:
    """The saturation ends reached by measured currents: the extremes of their ``window``-sample running mean
    (a noisy signal's single extreme samples overshoot the commanded saturation by several sigmas; the running
    mean of a ramp's apex stays within half a window of steps of it)."""
    lo, hi = math.inf, -math.inf
    for u in currents:
        u = np.asarray(u, dtype=float)
        w = max(1, min(window, u.size))
        mean = np.convolve(u, np.full(w, 1.0 / w), mode="valid")
        lo, hi = min(lo, float(mean.min())), max(hi, float(mean.max()))
    return lo, hi


def _default_deadband(u: np.ndarray) -> float:
    """1 % of the input span, or 10 × the sample noise of ``u`` if larger."""
    return max(0.01 * float(np.ptp(u)), 10.0 * _sample_noise(u), 1e-12)


def _monotone_fit(u: np.ndarray, y: np.ndarray, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Local linear estimate of ``y`` at each node (triangular window of one node spacing), then weighted
    isotonic (nondecreasing) regression. Nodes without data are dropped."""
    order = np.argsort(u, kind="stable")
    u, y = u[order], y[order]
    est, wts, keep = [], [], []
    for j, x in enumerate(nodes):
        h = (nodes[1] - nodes[0]) if len(nodes) > 1 else 1.0
        h = max(h, 1e-12)
        lo, hi = np.searchsorted(u, x - h, "left"), np.searchsorted(u, x + h, "right")
        if hi - lo < 1:
            continue
        d = u[lo:hi] - x
        w = np.clip(1.0 - np.abs(d) / h, 0.0, None) + 1e-9
        sw = w.sum()
        md = (w * d).sum() / sw
        my = (w * y[lo:hi]).sum() / sw
        var = (w * (d - md) ** 2).sum()
        if hi - lo >= 3 and var > 1e-6 * h * h * sw:
            slope = (w * (d - md) * (y[lo:hi] - my)).sum() / var
            est.append(my - slope * md)
        else:
            est.append(my)
        wts.append(sw)
        keep.append(j)
    if len(keep) < 2:
        return np.zeros(0), np.zeros(0)
    return nodes[keep], _isotonic(np.asarray(est), np.asarray(wts))


def _isotonic(y: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Pool-adjacent-violators: the weighted least-squares nondecreasing fit."""
    vals: list[float] = []
    wts: list[float] = []
    cnt: list[int] = []
    for yi, wi in zip(y, w):
        vals.append(float(yi))
        wts.append(float(wi))
        cnt.append(1)
        while len(vals) > 1 and vals[-2] > vals[-1]:
            wsum = wts[-2] + wts[-1]
            v = (vals[-2] * wts[-2] + vals[-1] * wts[-1]) / wsum
            c = cnt[-2] + cnt[-1]
            vals[-2:], wts[-2:], cnt[-2:] = [v], [wsum], [c]
    return np.repeat(vals, cnt)


def _segments(u: np.ndarray, deadband: float) -> list[tuple[int, int]]:
    rev = find_reversals(u, deadband)
    bounds = [0, *rev.tolist(), len(u) - 1]
    return [(a, b) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]


def _raw_first_order_segments(u: np.ndarray, deadband: float, lo: float, hi: float, sat_tol: float
                              ) -> tuple[list[tuple[int, int]], list[tuple[int, int]]]:
    """Index ranges of first-order ascending and descending curves within one run."""
    segs = _segments(u, deadband)
    asc, desc = [], []
    for k, (a, b) in enumerate(segs):
        rising = u[b] > u[a]
        if k == 0:
            continue  # the run's start is not a reversal of known history
        prev_a, _ = segs[k - 1]
        if rising:
            at_top = u[b] >= hi - sat_tol
            from_bottom = u[a] <= lo + sat_tol
            came_from_top = u[prev_a] >= hi - sat_tol
            if at_top and (from_bottom or came_from_top):
                asc.append((a, b))
        else:
            at_bottom = u[b] <= lo + sat_tol
            from_top = u[a] >= hi - sat_tol
            came_from_bottom = u[prev_a] <= lo + sat_tol
            if at_bottom and (from_top or came_from_bottom):
                desc.append((a, b))
    return asc, desc


def extract_first_order_curves(
    run: Run | Iterable[Run],
    friction: FrictionFit | Any | None = None,
    *,
    deadband_a: float | None = None,
    n_nodes: int = 40,
    saturation_tol_a: float | None = None,
    input_range: tuple[float, float] | None = None,
) -> FirstOrderCurves:
    """Cut and fit the first-order curves of one run (or several runs of one actuator).

    Friction ``friction(theta)`` (N·mm) is subtracted first. Reversals of the current are found with a
    dead-band (``deadband_a``, default: the larger of 1 % of the current span and 10 × the current's sample noise);
    a rising segment from a minimum that followed positive saturation (or from negative saturation) up to
    positive saturation is an ascending first-order curve, and symmetrically for descending ones. Curves whose
    reversals lie within a few noise sigmas of each other are pooled (repeated branches average their noise).
    Each curve is fitted monotonically on about ``n_nodes`` nodes per full input span.
    """
    runs = _as_runs(run)
    if not runs:
        raise BmrError("extract_first_order_curves needs at least one run")
    if n_nodes < 4:
        raise BmrError(f"n_nodes must be at least 4, got {n_nodes}")
    all_u = np.concatenate([r.current for r in runs])
    lo, hi = input_range if input_range is not None else input_range_of([r.current for r in runs])
    if not hi > lo:
        raise BmrError(f"runs {', '.join(r.name for r in runs)}: the current never varies; no curves to extract")
    db = deadband_a if deadband_a is not None else _default_deadband(all_u)
    # Repeats of one curve (e.g. the major branches of several runs) have reversals a few noise sigmas apart.
    pool_tol = min(db, max(0.005 * (hi - lo), 4.0 * _sample_noise(all_u)))
    sat_tol = saturation_tol_a if saturation_tol_a is not None else max(2.0 * db, 0.02 * (hi - lo))
    pools: dict[str, list[tuple[float, list[np.ndarray], list[np.ndarray]]]] = {"asc": [], "desc": []}
    for r in runs:
        u = r.current
        y = r.torque - (friction(r.theta) if friction is not None else 0.0)
        asc, desc = _raw_first_order_segments(u, db, lo, hi, sat_tol)
        for key, segs in (("asc", asc), ("desc", desc)):
            for a, b in segs:
                rev = float(u[a])
                if key == "asc" and rev <= lo + sat_tol:
                    rev = lo
                if key == "desc" and rev >= hi - sat_tol:
                    rev = hi
                for entry in pools[key]:
                    if abs(entry[0] - rev) <= pool_tol:
                        entry[1].append(u[a:b + 1])
                        entry[2].append(y[a:b + 1])
                        break
                else:
                    pools[key].append((rev, [u[a:b + 1]], [y[a:b + 1]]))
    span = hi - lo
    ascending: list[Curve] = []
    descending: list[Curve] = []
    for key in ("asc", "desc"):
        for rev, us, ys in sorted(pools[key], key=lambda e: e[0]):
            uu, yy = np.concatenate(us), np.concatenate(ys)
            start, end = (rev, hi) if key == "asc" else (lo, rev)
            if end - start < 1e-9 * span:
                continue
            k = max(3, int(round(n_nodes * (end - start) / span)))
            nodes = np.linspace(start, end, k + 1)
            nu, ny = _monotone_fit(uu, yy, nodes)
            if nu.size < 2:
                continue
            if key == "asc":
                ascending.append((nu, ny))
            else:
                descending.append((nu[::-1].copy(), ny[::-1].copy()))
    if not ascending or not descending:
        names = ", ".join(r.name for r in runs)
        raise BmrError(f"runs {names}: found {len(ascending)} ascending and {len(descending)} descending "
                       f"first-order curves (dead-band {db:.4g} A); both families need at least the major branch")
    return FirstOrderCurves(ascending, descending, (lo, hi))


def paper_current_curves(ascending: Sequence[Curve], descending: Sequence[Curve]
                         ) -> tuple[list[Curve], list[Curve]]:
    """The paper's current curves ``I^a(T_min, T)``, ``I^d(T_max, T)`` (eq 17-20): each torque curve with its
    axes swapped, in the same traversal order, flat stretches (no torque change) collapsed so torque is
    strictly monotone along each curve."""
    def swap(curves: Sequence[Curve], rising: bool) -> list[Curve]:
        out = []
        for u, y in curves:
            u, y = np.asarray(u, float), np.asarray(y, float)
            keep = [0]
            for i in range(1, y.size):
                if (y[i] > y[keep[-1]]) if rising else (y[i] < y[keep[-1]]):
                    keep.append(i)
            if len(keep) >= 2:
                out.append((y[keep], u[keep]))
        return out

    return swap(ascending, True), swap(descending, False)


# ------------------------------------------------------------------------------------------ lstsq tables
@dataclass
class LstsqTables:
    """Result of the least-squares table identification: the Everett model, its first-order curves and fit
    statistics (``rms`` in output units over the regression rows)."""

    everett: Any
    offsets: np.ndarray
    rms: float
    n_rows: int
    iterations: int
    ascending: list[Curve]
    descending: list[Curve]
    input_range: tuple[float, float]


def evaluation_start(u: np.ndarray, lo: float, hi: float, tol: float) -> int:
    """First sample from which the hysteresis state is known: the run has reached one saturation end and then
    the other (a real actuator's steel may not saturate within the current range, so one end alone does not erase
    the unknown initial state; the major loop does). Falls back to the one end reached, then to 0."""
    u = np.asarray(u, dtype=float)
    top = np.flatnonzero(u >= hi - tol)
    bottom = np.flatnonzero(u <= lo + tol)
    if top.size and bottom.size:
        return int(max(top[0], bottom[0]))
    if top.size or bottom.size:
        return int((top if top.size else bottom)[0])
    return 0


def fit_tables_lstsq(
    runs: Iterable[Run],
    friction: Any = None,
    *,
    n_intervals: int = 48,
    input_range: tuple[float, float] | None = None,
    smoothing: float = 1e-4,
    ridge: float = 1e-9,
    per_run_offset: bool = False,
    max_rows: int = 200_000,
    start_at_saturation: bool = True,
    curve_subdivisions: int = 4,
) -> LstsqTables:
    """Identify an Everett table (Preisach model) from any runs by regularised nonnegative least squares.

    The memory of each run starts at negative saturation; rows before the run's first saturation are left out
    (``start_at_saturation``). Rows are thinned uniformly to at most ``max_rows``. ``per_run_offset`` fits one
    free output offset per run (sensor offsets, unknown remanence) instead of one shared offset. The returned
    first-order curves start at every grid node and at ``curve_subdivisions − 1`` points inside each interval, so a
    CBH operator built from them follows the table between grid reversals too.
    """
    runs = list(runs)
    if not runs:
        raise BmrError("fit_tables_lstsq needs at least one run")
    if n_intervals < 2:
        raise BmrError(f"n_intervals must be at least 2, got {n_intervals}")
    us = [r.current for r in runs]
    ys = [r.torque - (friction(r.theta) if friction is not None else 0.0) for r in runs]
    all_u = np.concatenate(us)
    lo, hi = input_range if input_range is not None else input_range_of([r.current for r in runs])
    if not hi > lo:
        raise BmrError("the current never varies in the training runs; nothing to identify")
    grid = np.linspace(lo, hi, n_intervals + 1)
    tol = SATURATION_TOL * (hi - lo)
    total = sum(u.size for u in us)
    stride = max(1, math.ceil(total / max_rows))
    packed = []
    for k, (r, u, y) in enumerate(zip(runs, us, ys)):
        w = np.zeros(u.size)
        s = evaluation_start(u, lo, hi, tol) if start_at_saturation else 0
        w[s::stride] = 1.0
        packed.append((np.ascontiguousarray(u), np.ascontiguousarray(y), w, k if per_run_offset else 0))
    res = _core.fit_everett(grid, packed, len(runs) if per_run_offset else 1, smoothing=smoothing, ridge=ridge)
    model = res["model"]
    asc, desc = model.first_order_curves(subdivisions=curve_subdivisions)
    return LstsqTables(everett=model, offsets=np.asarray(res["offsets"]), rms=float(res["rms"]),
                       n_rows=int(res["n_rows"]), iterations=int(res["iterations"]),
                       ascending=[(np.asarray(u), np.asarray(y)) for u, y in asc],
                       descending=[(np.asarray(u), np.asarray(y)) for u, y in desc], input_range=(lo, hi))


# ------------------------------------------------------------------------------------------------ identify
def _heldout_rms(model: Any, runs: Sequence[Run], lo: float, hi: float) -> dict[str, float]:
    out = {}
    tol = SATURATION_TOL * (hi - lo)
    for r in runs:
        y = model.simulate(r.current, r.theta)
        s = evaluation_start(r.current, lo, hi, tol)
        e = r.torque[s:] - y[s:]
        out[r.name] = float(np.sqrt(np.mean(e * e))) if e.size else float("nan")
    return out


def identify(
    bundle: Bundle | str,
    *,
    method: str = "forc",
    max_order: int = DEFAULT_MAX_ORDER,
    n_nodes: int = 40,
    n_intervals: int = 48,
    smoothing: float = 1e-4,
    train_kinds: Sequence[str] | None = None,
    deadband_a: float | None = None,
) -> "Model":
    """Identify friction and hysteresis from ``bundle`` and return a ``bmr.Model``.

    ``method``: ``"forc"`` (first-order curves of the protocol runs), ``"lstsq"`` (Everett table by least
    squares from the runs of ``train_kinds``, default the ``first_order_*`` runs, or every non-off-state run
    when there are none) or ``"both"`` (fit both and keep the one with the lower held-out RMS over the
    evaluation runs). The model's ``meta["identification"]`` records the friction table, the chosen order and
    its scores, held-out RMS per evaluation run for each method and the timings.
    """
    from bmr.model import Model

    if isinstance(bundle, str):
        bundle = read_bundle(bundle)
    if method not in ("forc", "lstsq", "both"):
        raise BmrError(f"unknown identification method {method!r}; use 'forc', 'lstsq' or 'both'")
    t0 = time.perf_counter()
    friction = fit_friction(bundle, max_order=max_order) if bundle.by_kind("off_state") else None
    t_friction = time.perf_counter() - t0
    protocol = bundle.by_kind("first_order_ascending", "first_order_descending")
    evaluation = bundle.evaluation_runs()
    lo, hi = input_range_of([r.current for r in bundle.runs if r.kind != "off_state"] or [np.zeros(2)])
    info: dict[str, Any] = {"method": method, "friction": friction.to_dict() if friction else None,
                            "time_s": {"friction": t_friction}, "heldout_rms_nmm": {}}
    candidates: dict[str, Model] = {}
    limits = {"current_a": [lo, hi]}

    if method in ("forc", "both"):
        if not protocol:
            raise BmrError("the bundle has no first_order_ascending/descending run for the 'forc' method; "
                           "use method='lstsq'")
        t = time.perf_counter()
        curves = extract_first_order_curves(protocol, friction, n_nodes=n_nodes, deadband_a=deadband_a,
                                            input_range=(lo, hi))
        candidates["forc"] = Model.from_curves(curves.ascending, curves.descending, friction, limits=limits)
        # Ascending vs descending family disagreement: zero for Preisach data (DESIGN section 2).
        info["forc_consistency_nmm"] = candidates["forc"].hysteresis.consistency()
        info["time_s"]["forc"] = time.perf_counter() - t
        info["forc_curves"] = {"ascending": len(curves.ascending), "descending": len(curves.descending)}
    if method in ("lstsq", "both"):
        if train_kinds is not None:
            train = bundle.by_kind(*train_kinds)
        else:
            train = protocol or [r for r in bundle.runs if r.kind != "off_state"]
        if not train:
            raise BmrError("no runs to train the least-squares tables on")
        t = time.perf_counter()
        tables = fit_tables_lstsq(train, friction, n_intervals=n_intervals, smoothing=smoothing,
                                  input_range=(lo, hi))
        candidates["lstsq"] = Model.from_curves(tables.ascending, tables.descending, friction, limits=limits)
        info["time_s"]["lstsq"] = time.perf_counter() - t
        info["lstsq_fit"] = {"rms_nmm": tables.rms, "rows": tables.n_rows, "iterations": tables.iterations,
                             "runs": [r.name for r in train], "n_intervals": n_intervals}
    for name, m in candidates.items():
        info["heldout_rms_nmm"][name] = _heldout_rms(m, evaluation, lo, hi)
    chosen = method
    if method == "both":
        def score(name: str) -> float:
            vals = [v for v in info["heldout_rms_nmm"][name].values() if math.isfinite(v)]
            return float(np.mean(vals)) if vals else float("inf")
        chosen = min(candidates, key=score)
    info["chosen"] = chosen
    info["time_s"]["total"] = time.perf_counter() - t0
    model = candidates[chosen]
    model.meta["identification"] = info
    return model


def run_cli(args: Any) -> int:
    """``bmr identify BUNDLE --method M -o model.json``: identify, save, print a short summary."""
    bundle = read_bundle(args.bundle)
    model = identify(bundle, method=args.method)
    model.save(args.out)
    info = model.meta["identification"]
    print(f"bmr identify: {bundle.actuator or args.bundle} ({len(bundle)} runs), method {args.method}"
          f" -> {info['chosen']}, {info['time_s']['total']:.2f} s")
    f = info["friction"]
    if f:
        print(f"  friction: order {f['order']} ({f['criterion']}), c0 = {f['c0']:.3f} ± {f['stderr']['c0']:.3f} "
              f"N·mm, residual RMS {f['residual_rms_nmm']:.3f} N·mm")
    else:
        print("  friction: no off_state run, none identified")
    lo, hi = model.hysteresis.input_range
    ylo, yhi = model.hysteresis.output_range
    print(f"  hysteresis: input {lo:.4g}..{hi:.4g} A, output {ylo:.4g}..{yhi:.4g} N·mm")
    for name, per_run in info["heldout_rms_nmm"].items():
        if per_run:
            vals = ", ".join(f"{k} {v:.3f}" for k, v in per_run.items())
            print(f"  held-out RMS [{name}] (N·mm): {vals}")
    print(f"  wrote {args.out}")
    return 0
