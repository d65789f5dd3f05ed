"""First-order reversal curves (the paper's identification path): find the reversals of the protocol runs with a
dead-band (``bmr._core.find_reversals``), cut the first-order curves, fit each one from its raw samples
(``bmr._core.fit_curve``: adaptive bins on the input axis, wide where the curve is straight and narrow where it
switches sharply, then the least-squares monotone fit) and hand them to ``bmr.Hysteresis.from_curves``, which
derives a missing family from the measured one. (The paper's current curves, the torque curves with their axes
swapped, are ``bmr.Hysteresis.current_curves()``.)

Real curves are accepted as they are: how far each one moved against its direction (continued switching after a
reversal, noise, creep) is measured and kept in the result, and every sample of every run is accounted for (on a
curve, or not, and why)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Iterable

import numpy as np

from bmr._core import BmrError, find_reversals, fit_curve
from bmr.data.bundle import Run, runs_of
from bmr.data.signals import default_deadband, output_rails
from bmr.identification.accounting import AT_RANGE_END, SampleAccount
from bmr.identification.signals import run_input, run_output
from bmr.identification.spans import input_range_of, sample_noise

__all__ = ["Curve", "FirstOrderCurves", "find_reversals", "extract_first_order_curves"]

Curve = tuple[np.ndarray, np.ndarray]

# Reasons a protocol-run sample is on no first-order curve.
BEFORE_FIRST_REVERSAL = "before the run's first reversal (unknown state)"
NOT_FIRST_ORDER = "not on a first-order curve (inner reversal or no saturation reached)"
HELD_OUT = "on a curve held out (cross-validation)"


@dataclass
class FirstOrderCurves:
    """First-order curves in ``bmr.Hysteresis.from_curves`` form: ascending curves from their reversal minimum
    up (increasing ``u``), descending ones from their reversal maximum down (decreasing ``u``).

    ``fits``: the ``bmr.CurveFit`` of every curve (ascending first, in the same order), with its noise, bins and
    how far the data moved against the curve's direction; ``samples``: which samples of each run lie on a curve
    and why the others do not; ``deadband``: the reversal dead-band used (input units); ``membership``: per run,
    the index of the curve each sample lies on (-1: none; ascending curves first, numbered over every curve found,
    held-out ones included; the first ``n_ascending_found`` are ascending, the major branches first).
    """

    ascending: list[Curve]
    descending: list[Curve]
    input_range: tuple[float, float]
    fits: list[Any] = field(default_factory=list)
    samples: SampleAccount = field(default_factory=SampleAccount)
    deadband: float = 0.0
    membership: dict[str, np.ndarray] = field(default_factory=dict)
    n_ascending_found: int = 0

    def __len__(self) -> int:
        return len(self.ascending) + len(self.descending)

    @property
    def noise(self) -> float:
        """Median output noise of one sample over the curves (output units)."""
        return float(np.median([f.noise for f in self.fits])) if self.fits else float("nan")

    def worst_violation(self) -> Any:
        """The curve fit that moved furthest against its direction (or None)."""
        return max(self.fits, key=lambda f: f.violation) if self.fits else None

    def __repr__(self) -> str:
        lo, hi = self.input_range
        w = self.worst_violation()
        worst = (f", largest move against a curve's direction {w.violation:.3g} at input {w.violation_input:.4g}"
                 if w is not None else "")
        return (f"FirstOrderCurves({len(self.ascending)} ascending, {len(self.descending)} descending, input "
                f"{lo:.4g}..{hi:.4g}, noise {self.noise:.3g}{worst}; {self.samples.used} of {self.samples.total} "
                "samples on a curve)")




def _segments(u: np.ndarray, deadband: float) -> list[tuple[int, int]]:
    rev = find_reversals(u, deadband)
    bounds = [0, *rev.tolist(), len(u) - 1]
    return [(a, b) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]


def _raw_first_order_segments(u: np.ndarray, deadband: float, lo: float, hi: float, sat_tol: float
                              ) -> tuple[dict[str, list[tuple[int, int, bool]]], int]:
    """Index ranges ``(a, b, full)`` of first-order ascending and descending curves within one run (``full``: it
    reaches the opposite saturation; a partial one only extends a full curve from the same reversal), and the
    run's first reversal (samples before it have an unknown history)."""
    segs = _segments(u, deadband)
    out: dict[str, list[tuple[int, int, bool]]] = {"asc": [], "desc": []}
    for k, (a, b) in enumerate(segs):
        if k == 0:
            continue  # the run's start is not a reversal of known history
        prev_a, _ = segs[k - 1]
        if u[b] > u[a]:
            # From negative saturation, or from a minimum reached coming down from positive saturation.
            if u[a] <= lo + sat_tol or u[prev_a] >= hi - sat_tol:
                out["asc"].append((a, b, bool(u[b] >= hi - sat_tol)))
        elif u[a] >= hi - sat_tol or u[prev_a] <= lo + sat_tol:
            out["desc"].append((a, b, bool(u[b] <= lo + sat_tol)))
    first = segs[1][0] if len(segs) > 1 else len(u)
    return out, first


def extract_first_order_curves(
    run: Run | Iterable[Run],
    friction: Any | None = None,
    *,
    deadband: float | None = None,
    saturation_tol: float | None = None,
    input_range: tuple[float, float] | None = None,
    pilot: int = 16,
    exclude_curves: Iterable[int] = (),
) -> FirstOrderCurves:
    """Cut and fit the first-order curves of one run (or several runs of one device).

    Friction ``friction(theta)`` is subtracted first (when the runs have an angle). Reversals of the input are
    found with a dead-band (``deadband``, input units; default: the larger of 1 % of the input span and 10 × the
    input's sample noise); a rising segment from a minimum that followed positive saturation (or from negative
    saturation) up to positive saturation is an ascending first-order curve, and symmetrically for descending
    ones. Curves whose reversals lie within a few noise sigmas of each other are pooled (repeated branches average
    their noise); the major branch pools only curves that start within that distance of saturation. Each curve is
    fitted from its raw samples by ``bmr._core.fit_curve`` (``pilot``: samples per pilot bin).

    One family is enough (``bmr.Hysteresis.from_curves`` derives the other one); a run set in which no first-order
    curve is found is an error naming the runs and the dead-band. ``exclude_curves``: indices (into ``membership``
    numbering of the same runs) of curves to hold out, e.g. for cross-validation; their samples are counted as held
    out.
    """
    runs = runs_of(run)
    if not runs:
        raise BmrError("extract_first_order_curves needs at least one run")
    inputs = [run_input(r) for r in runs]
    all_u = np.concatenate(inputs)
    lo, hi = input_range if input_range is not None else input_range_of(inputs)
    names = ", ".join(repr(r.name) for r in runs)
    q = runs[0].quantities.input
    if not hi > lo:
        raise BmrError(f"runs {names}: the input never varies; no curves to extract")
    db = deadband if deadband is not None else default_deadband(inputs)
    if not (np.isfinite(db) and db > 0):
        raise BmrError(f"reversal dead-band must be positive and finite, got {db!r}")
    # Repeats of one curve (e.g. the major branches of several runs) have reversals a few noise sigmas apart.
    pool_tol = min(db, max(0.005 * (hi - lo), 4.0 * sample_noise(all_u)))
    sat_tol = saturation_tol if saturation_tol is not None else max(2.0 * db, 0.02 * (hi - lo))
    # Pools of segments from one reversal: [reversal, [(run name, a, b)], ...] per family.
    pools: dict[str, list[list[Any]]] = {"asc": [], "desc": []}
    partial: list[tuple[str, float, str, int, int]] = []
    firsts: dict[str, int] = {}
    signals: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    rails = output_rails([(u, r.output) for r, u in zip(runs, inputs)])
    railed = {r.name: rails.mask(r.output) for r in runs}
    for r, u in zip(runs, inputs):
        y = run_output(r, friction)
        signals[r.name] = (u, y)
        segs, firsts[r.name] = _raw_first_order_segments(u, db, lo, hi, sat_tol)
        for key in ("asc", "desc"):
            for a, b, full in segs[key]:
                rev = float(u[a])
                # The major branch: a start within the pooling distance of saturation is saturation.
                if key == "asc" and rev <= lo + pool_tol:
                    rev = lo
                if key == "desc" and rev >= hi - pool_tol:
                    rev = hi
                if not full:
                    partial.append((key, rev, r.name, a, b))
                    continue
                for entry in pools[key]:
                    if abs(entry[0] - rev) <= pool_tol:
                        entry[1].append((r.name, a, b))
                        break
                else:
                    pools[key].append([rev, [(r.name, a, b)]])
    # A curve cut short (the protocol reversed before saturation) extends a full curve from the same reversal.
    for key, rev, name, a, b in partial:
        for entry in pools[key]:
            if abs(entry[0] - rev) <= pool_tol:
                entry[1].append((name, a, b))
                break
    span = hi - lo
    ascending: list[Curve] = []
    descending: list[Curve] = []
    fits: list[Any] = []
    membership = {r.name: np.full(u.size, -1, dtype=np.int64) for r, u in zip(runs, inputs)}
    held_out = {int(k) for k in exclude_curves}
    # Samples of curves not cut because their reversal is held at the output's range end.
    no_start = {r.name: np.zeros(u.size, dtype=bool) for r, u in zip(runs, inputs)}
    for key in ("asc", "desc"):
        for rev, segs in sorted(pools[key], key=lambda e: e[0]):
            end = hi if key == "asc" else lo
            if abs(end - rev) < 1e-9 * span:
                continue
            uu = np.concatenate([signals[n][0][a:b + 1] for n, a, b in segs])
            yy = np.concatenate([signals[n][1][a:b + 1] for n, a, b in segs])
            # Every pooled sample enters the fit; the curve starts at its (pooled) reversal input.
            start = np.argmin(uu) if key == "asc" else np.argmax(uu)
            order = np.r_[start, np.delete(np.arange(uu.size), start)]
            uu, yy = uu[order], yy[order]
            uu[0] = rev
            if rails.any:
                # Samples held at the output's range end are no measurement of the curve: the fit ends before
                # them; a curve whose reversal itself sits there has no measured start and is not a curve.
                keep = ~np.concatenate([railed[n][a:b + 1] for n, a, b in segs])[order]
                if not keep[0]:
                    for n, a, b in segs:
                        no_start[n][a:b + 1] = True
                    continue
                uu, yy = uu[keep], yy[keep]
            try:
                f = fit_curve(uu, yy, "ascending" if key == "asc" else "descending", pilot=pilot)
            except BmrError:
                continue  # a degenerate pool (all samples at one input): nothing to fit
            index = len(fits)
            for n, a, b in segs:
                membership[n][a:b + 1] = index
            fits.append(f)
            if index in held_out:
                continue
            (ascending if key == "asc" else descending).append((f.u, f.y))
    if max(len(ascending), len(descending)) < 2:
        raise BmrError(f"runs {names}: found {len(ascending)} ascending and {len(descending)} descending "
                       f"first-order curves (reversal dead-band {q.format(db, 4)}, saturation within "
                       f"{q.format(sat_tol, 4)} of {q.format(lo, 6)}..{q.format(hi, 6)}); one family needs its major "
                       "branch and at least one more curve")
    account = SampleAccount()
    for r, u in zip(runs, inputs):
        m = membership[r.name]
        on_curve = m >= 0
        out = np.isin(m, sorted(held_out)) if held_out else np.zeros(u.size, dtype=bool)
        account.add_run(r.name, u.size)
        # At the range end: a fitted curve's railed samples, and the other samples of curves whose reversal is.
        held = (on_curve & ~out & railed[r.name]) | (no_start[r.name] & ~on_curve)
        account.use(r.name, int(np.count_nonzero(on_curve & ~out & ~held)))
        account.drop(r.name, HELD_OUT, int(np.count_nonzero(out)))
        account.drop(r.name, AT_RANGE_END, int(np.count_nonzero(held)))
        early = int(np.count_nonzero(~on_curve[:firsts[r.name]] & ~held[:firsts[r.name]]))
        account.drop(r.name, BEFORE_FIRST_REVERSAL, early)
        account.drop(r.name, NOT_FIRST_ORDER, int(np.count_nonzero(~on_curve & ~held)) - early)
    n_asc = sum(1 for f in fits if f.direction == "ascending")
    kept = [f for i, f in enumerate(fits) if i not in held_out]
    return FirstOrderCurves(ascending, descending, (lo, hi), kept, account.check(), float(db), membership,
                            n_asc)

