"""First-order reversal curves (the paper's identification path): find the reversals of the protocol runs with a
dead-band, cut the first-order curves, fit each one monotonically (local linear smoothing on a node grid, then
isotonic regression: no invented wiggles) and hand them to ``bmr.Hysteresis.from_curves``. (The paper's current curves, the torque curves with their axes
swapped, are ``bmr.Hysteresis.current_curves()``.)"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Iterable

import numpy as np

from bmr._core import BmrError, find_reversals
from bmr.data.bundle import Run, runs_of
from bmr.identification.spans import input_range_of, sample_noise

if TYPE_CHECKING:
    from bmr.identification.friction import FrictionFit

__all__ = ["Curve", "FirstOrderCurves", "find_reversals", "extract_first_order_curves"]

Curve = tuple[np.ndarray, np.ndarray]


@dataclass
class FirstOrderCurves:
    """First-order curves in ``bmr.Hysteresis.from_curves`` form: ascending curves from their reversal minimum
    up (increasing ``u``), descending ones from their reversal maximum down (decreasing ``u``)."""

    ascending: list[Curve]
    descending: list[Curve]
    input_range: tuple[float, float]

    def __len__(self) -> int:
        return len(self.ascending) + len(self.descending)


def _default_deadband(u: np.ndarray) -> float:
    """1 % of the input span, or 10 × the sample noise of ``u`` if larger."""
    return max(0.01 * float(np.ptp(u)), 10.0 * sample_noise(u), 1e-12)


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
    runs = runs_of(run)
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
    pool_tol = min(db, max(0.005 * (hi - lo), 4.0 * sample_noise(all_u)))
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
