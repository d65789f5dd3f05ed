"""The evaluation data of a bundle, the nominal model's residual on it, the noise floor and residual structure.

Every evaluation run (``multi_step``, ``triangle``, ``tracking``, ``multipeak``, ``custom``) is simulated from the
run's start (its opening excursion puts the steel in a known state) and judged from its *first saturation* on
(:func:`bmr.identification.spans.evaluation_start`). Each run's evaluated span is cut into ``folds`` contiguous time blocks;
fold ``k`` holds block ``k`` of every run (blocked by run and time, never random samples).

:class:`EvalData` holds everything one diagnosis reads more than once: the evaluated spans concatenated over
runs (angle, current, torque, time, the nominal friction), the fit rows grouped by fold (all evaluated samples, or
an even stride of them in every block of long logs: see :data:`MAX_FIT_ROWS`) and a :class:`BoundedCache` for
what the effects derive from them. Nothing is kept between diagnoses.

Units: torque N·mm, current A, angle rad, time s.
"""
from __future__ import annotations

import functools
import math
from collections import OrderedDict
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Callable, Sequence, TypeVar

import numpy as np
from threadpoolctl import threadpool_limits

from bmr import _core
from bmr._core import BmrError
from bmr.data.bundle import Bundle, Run
from bmr.data.signals import OutputRails, output_rails
from bmr.identification.spans import SATURATION_TOL, evaluation_start

F = TypeVar("F", bound=Callable[..., Any])


def one_blas_thread(fn: F) -> F:
    """Run ``fn`` with the linear-algebra library on one thread (restored after). A diagnosis multiplies many small
    matrices (a few dozen columns): threads add no speed there but spin while they wait, costing CPU time that,
    on a loaded machine, is most of the diagnosis's."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with threadpool_limits(limits=1, user_api="blas"):
            return fn(*args, **kwargs)

    return wrapper  # type: ignore[return-value]

__all__ = ["EvalRun", "EvalData", "BoundedCache", "return_freed_memory", "prepare", "noise_floor", "reversal_order",
           "signal_label", "structure", "SIGNALS", "MAX_FIT_ROWS"]

# Signals the residual structure is studied against.
SIGNALS = ("angle", "time", "input_level", "input_rate", "reversal_order", "time_since_reversal")
"""Signals the residual structure is studied against (``input_*``: the declared input, e.g. current or voltage)."""


def signal_label(signal: str, quantities: Any) -> str:
    """A residual-structure signal in the device's words: ``input_level`` → ``current level``."""
    name = quantities.input.name
    return {"input_level": f"{name} level", "input_rate": f"{name} rate",
            "time_since_reversal": "time since the last reversal"}.get(signal, signal.replace("_", " "))

@functools.cache
def _malloc_trim() -> Callable[[int], int] | None:
    """glibc's ``malloc_trim`` (None elsewhere)."""
    import ctypes
    import platform

    if platform.system() != "Linux" or platform.libc_ver()[0] != "glibc":
        return None
    try:
        return ctypes.CDLL(None).malloc_trim  # type: ignore[no-any-return]
    except (OSError, AttributeError):
        return None


def return_freed_memory() -> None:
    """Give the freed pages of the heap back to the operating system (glibc; elsewhere nothing). Arrays freed in
    the middle of the heap stay resident otherwise, and the steps after a search (the learned library, the closed
    loop) would add their memory on top of the search's."""
    trim = _malloc_trim()
    if trim is not None:
        trim(0)


MAX_FIT_ROWS = 200_000
"""Rows used by the least-squares fits of the selection (an even stride in every fold block when the evaluated
spans hold more): quasi-static logs are heavily oversampled for a handful of columns."""


def _nbytes(value: Any) -> int:
    if isinstance(value, np.ndarray):
        return int(value.nbytes)
    if isinstance(value, (list, tuple)):
        return sum(_nbytes(v) for v in value)
    if isinstance(value, dict):
        return sum(_nbytes(v) for v in value.values())
    return 64


class BoundedCache:
    """A least-recently-used cache bounded in entries and in bytes (numpy arrays counted by size), so that what
    a diagnosis derives once and reads again stays within a fixed memory however long the log."""

    def __init__(self, max_entries: int = 64, max_bytes: int = 64 << 20) -> None:
        self.max_entries = int(max_entries)
        self.max_bytes = int(max_bytes)
        self._items: OrderedDict[Any, tuple[Any, int]] = OrderedDict()
        self._bytes = 0

    def __contains__(self, key: Any) -> bool:
        return key in self._items

    def __len__(self) -> int:
        return len(self._items)

    @property
    def nbytes(self) -> int:
        return self._bytes

    def __getitem__(self, key: Any) -> Any:
        value, _ = self._items[key]
        self._items.move_to_end(key)
        return value

    def __setitem__(self, key: Any, value: Any) -> None:
        if key in self._items:
            self._bytes -= self._items.pop(key)[1]
        size = _nbytes(value)
        self._items[key] = (value, size)
        self._bytes += size
        while len(self._items) > 1 and (len(self._items) > self.max_entries or self._bytes > self.max_bytes):
            _, (_, old) = self._items.popitem(last=False)
            self._bytes -= old

    def get(self, key: Any, make: Callable[[], Any]) -> Any:
        """The cached value of ``key``, made (and kept) on a miss."""
        if key in self._items:
            return self[key]
        value = make()
        self[key] = value
        return value

    def clear(self) -> None:
        self._items.clear()
        self._bytes = 0


@dataclass
class EvalRun:
    """One evaluation run: full-length signals (the simulation needs the opening) and its evaluated span."""

    name: str
    kind: str
    current_a: np.ndarray
    theta_rad: np.ndarray
    torque_nmm: np.ndarray
    t_abs_s: np.ndarray  # time since the bundle's first sample (runs are consecutive on one actuator)
    dt_s: float
    start: int  # first evaluated sample (first saturation)
    block: np.ndarray  # fold index of each evaluated sample (len = n - start)
    thermal_index: int  # index of the run in the bundle (for the thermal state)

    @property
    def n_eval(self) -> int:
        return self.current_a.size - self.start


@dataclass
class EvalData:
    """All the evaluation runs of a bundle plus what the effects need from the whole bundle. ``current`` /
    ``torque`` / ``theta`` are the declared input / output / angle (zeros without an angle); ``has_angle`` says
    whether the device has one; ``noise`` is the noise floor with the estimate it came from."""

    runs: list[EvalRun]
    folds: int
    full_current_a: float
    noise_floor_nmm: float
    bundle_currents: list[np.ndarray]  # every run's current in bundle order (heating history)
    bundle_dt_s: list[float]
    sample_rate_hz: float
    run_start_s: dict[str, float] = field(default_factory=dict)  # every run's start time in the bundle
    friction_nmm: np.ndarray | None = None  # the nominal model's friction over the evaluated spans
    has_angle: bool = True
    noise: Any = None
    cache: BoundedCache = field(default_factory=lambda: BoundedCache(max_entries=64, max_bytes=24 << 20))
    max_fit_rows: int = MAX_FIT_ROWS
    # The output's range ends over the whole bundle (a sensor at its limit): those samples are not fitted.
    rails: OutputRails = field(default_factory=OutputRails)

    def concat(self, arrays: Sequence[np.ndarray]) -> np.ndarray:
        return np.concatenate(list(arrays)) if arrays else np.zeros(0)

    def eval_slice(self, name: str) -> list[np.ndarray]:
        """A per-run signal restricted to the evaluated spans (``name``: an attribute of :class:`EvalRun`)."""
        return [getattr(r, name)[r.start:] for r in self.runs]

    def test_mask(self, fold: int) -> np.ndarray:
        return self.concat([r.block == fold for r in self.runs])

    @cached_property
    def n_eval(self) -> int:
        return sum(r.n_eval for r in self.runs)

    # The evaluated spans concatenated over runs (computed once).
    @cached_property
    def theta(self) -> np.ndarray:
        return self.concat(self.eval_slice("theta_rad"))

    @cached_property
    def current(self) -> np.ndarray:
        return self.concat(self.eval_slice("current_a"))

    @cached_property
    def torque(self) -> np.ndarray:
        return self.concat(self.eval_slice("torque_nmm"))

    @cached_property
    def t_abs(self) -> np.ndarray:
        return self.concat(self.eval_slice("t_abs_s"))

    @cached_property
    def block(self) -> np.ndarray:
        """Fold index of every evaluated sample."""
        return self.concat([r.block for r in self.runs]).astype(np.int64)

    @cached_property
    def valid(self) -> np.ndarray:
        """Evaluated samples whose output is a measurement (not held at the output's range end)."""
        return ~self.rails.mask(self.torque)

    @cached_property
    def fit_rows(self) -> np.ndarray:
        """The evaluated samples the fits use, grouped by fold (fold ``k``'s rows are
        ``fit_rows[fold_bounds[k]:fold_bounds[k + 1]]``): all of them but those at the output's range end, or an
        even stride in every fold block when there are more than ``max_fit_rows``."""
        stride = max(1, -(-self.n_eval // self.max_fit_rows))
        order = np.argsort(self.block, kind="stable")
        if self.rails.any:
            order = order[self.valid[order]]
        if stride == 1:
            return order
        bounds = np.searchsorted(self.block[order], np.arange(self.folds + 1))
        return np.concatenate([order[a:b:stride] for a, b in zip(bounds[:-1], bounds[1:])])

    @cached_property
    def fold_bounds(self) -> np.ndarray:
        return np.searchsorted(self.block[self.fit_rows], np.arange(self.folds + 1))


def _run_dt(run: Run, fallback_s: float) -> float:
    t = run.t
    if t.size >= 2:
        d = np.diff(t)
        d = d[np.isfinite(d) & (d > 0)]
        if d.size:
            return float(np.median(d))
    return fallback_s


def noise_floor(bundle: Bundle, friction: Any = None) -> Any:
    """The noise floor from the data themselves (:func:`bmr.diagnosis.noise.from_data`: declared sigmas, the
    off-state run, dwells, repeated runs), with the seal friction removed along the angle when there is one; None
    when the data hold no estimate (the diagnosis then uses the high-frequency part of the nominal residual)."""
    from bmr.diagnosis.noise import from_data

    slow = (lambda r: friction(r.angle)) if friction is not None and bundle.quantities.angle is not None else None
    return from_data(bundle.runs, bundle.evaluation_runs(), slow=slow)


def prepare(bundle: Bundle, input_range: tuple[float, float], folds: int, friction: Any = None) -> EvalData:
    """Cut the bundle's evaluation runs into blocked folds; every run must reach a saturation end."""
    if not (isinstance(folds, (int, np.integer)) and 2 <= folds <= 50):
        raise BmrError(f"folds must be an integer in [2, 50], got {folds!r}")
    lo, hi = input_range
    tol = SATURATION_TOL * (hi - lo)
    fs = float(bundle.sample_rate_hz)
    t0 = 0.0
    out: list[EvalRun] = []
    currents, dts = [], []
    starts: dict[str, float] = {}
    evaluation = {r.name for r in bundle.evaluation_runs()}
    for index, r in enumerate(bundle.runs):
        dt = _run_dt(r, 1.0 / fs)
        t = r.t
        # The run's start in the actuator's time when the bundle records it, else runs back to back.
        start = r.meta.get("start_s") if isinstance(r.meta, dict) else None
        if isinstance(start, (int, float)) and np.isfinite(start):
            t0 = float(start)
        t_abs = t0 + (t - t[0])
        starts[r.name] = t0
        t0 = float(t_abs[-1]) + dt if t.size else t0
        currents.append(r.input)
        dts.append(dt)
        if r.name not in evaluation:
            continue
        u = r.input
        s = evaluation_start(u, lo, hi, tol)
        n = u.size - s
        if n < 2 * folds:
            continue
        block = np.minimum((np.arange(n) * folds) // n, folds - 1).astype(np.int64)
        theta = r.angle if r.angle is not None else np.zeros(u.size)
        out.append(EvalRun(r.name, r.kind, u, theta, r.output, t_abs, dt, s, block, index))
    if not out:
        raise BmrError("the bundle has no evaluation run (multi_step, triangle, multipeak, tracking or custom) "
                       f"with at least {2 * folds} samples after its first saturation; nothing to diagnose (hold "
                       "runs out with `bmr import --holdout RUN`, or the end of one long recording with "
                       "`--holdout-tail 0.3`)")
    full = max(abs(lo), abs(hi))
    noise = noise_floor(bundle, friction)
    sigma = noise.sigma if noise is not None else float("nan")
    has_angle = bundle.quantities.angle is not None
    rails = output_rails([(r.input, r.output) for r in bundle.runs])
    data = EvalData(out, int(folds), full, sigma, currents, dts, fs, starts, has_angle=has_angle, noise=noise,
                    rails=rails)
    data.friction_nmm = friction(data.theta) if friction is not None and has_angle else np.zeros(data.n_eval)
    return data


def reversal_order(u: np.ndarray, lo: float, hi: float, deadband_a: float | None = None) -> np.ndarray:
    """Order of the reversal curve each sample lies on: 0 on the major loop (after a saturation), 1 on a
    first-order curve, 2 after a further reversal, … (a dead-band reversal counter, reset at saturation;
    ``bmr._core.reversal_order``)."""
    return _core.reversal_order(np.asarray(u, dtype=float), lo, hi, deadband_a,
                                saturation_tol=SATURATION_TOL * (hi - lo))


def _binned_strength(x: np.ndarray, r: np.ndarray, bins: int = 20, min_count: int = 20) -> float:
    """RMS (N·mm) of the residual explained by its binned means against ``x`` (quantile bins)."""
    if x.size < bins * min_count:
        bins = max(2, x.size // min_count)
    if bins < 2:
        return 0.0
    edges = np.unique(np.quantile(x, np.linspace(0, 1, bins + 1)))
    if edges.size < 3:
        return 0.0
    idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, edges.size - 2)
    counts = np.bincount(idx, minlength=edges.size - 1)
    sums = np.bincount(idx, weights=r, minlength=edges.size - 1)
    means = np.where(counts > 0, sums / np.maximum(counts, 1), 0.0)
    means -= np.sum(sums) / max(1, r.size)
    # Remove the part binned means of pure noise would show (expected mean square σ²/count per bin).
    var = float(np.sum(counts * means ** 2) / r.size)
    noise_var = float(np.var(r)) * (edges.size - 2) / r.size
    return math.sqrt(max(0.0, var - noise_var))


def _angle_strength(theta: np.ndarray, r: np.ndarray, orders: int = 12, chunk: int = 1 << 16) -> float:
    """RMS (N·mm) of the residual's angle harmonics up to ``orders`` per revolution (least squares on
    ``[1, sin kθ, cos kθ]``), less what noise alone would show. The normal equations are accumulated over chunks
    of samples (bounded memory for long logs; the harmonics are orthogonal enough for them)."""
    p = 1 + 2 * orders
    gram = np.zeros((p, p))
    xr = np.zeros(p)
    for a in range(0, theta.size, chunk):
        th, rr = theta[a:a + chunk], r[a:a + chunk]
        x = np.empty((p, th.size))
        x[0] = 1.0
        s1, c1 = np.sin(th), np.cos(th)
        x[1], x[2] = s1, c1
        for k in range(2, orders + 1):
            # sin/cos of kθ from (k−1)θ by the angle-addition rule.
            s, c = x[2 * k - 3], x[2 * k - 2]
            x[2 * k - 1] = s * c1 + c * s1
            x[2 * k] = c * c1 - s * s1
        gram += x @ x.T
        xr += x @ rr
    n = max(r.size, 1)
    scale = np.sqrt(np.maximum(np.diag(gram), 1e-300))
    beta_s, *_ = np.linalg.lstsq(gram / np.outer(scale, scale), xr / scale, rcond=1e-13)
    beta = beta_s / scale
    mean_r = float(np.mean(r)) if r.size else 0.0
    # mean((Xβ − r̄)²) from the Gram matrix; its first column holds the sums of the columns.
    var = float(beta @ gram @ beta) / n - 2.0 * mean_r * float(gram[0] @ beta) / n + mean_r ** 2
    noise_var = float(np.var(r)) * (p - 1) / n
    return math.sqrt(max(0.0, var - noise_var))


def _time_since_reversal(u: np.ndarray, dt_s: float, deadband: float) -> np.ndarray:
    """Time (s) since the last dead-band reversal of ``u`` (from the start before the first one)."""
    from bmr import _core

    rev = np.asarray(_core.find_reversals(np.ascontiguousarray(u, dtype=float), deadband), dtype=np.int64)
    last = np.zeros(u.size, dtype=np.int64)
    if rev.size:
        marks = np.zeros(u.size, dtype=np.int64)
        marks[rev] = rev
        last = np.maximum.accumulate(marks)
    return (np.arange(u.size) - last) * dt_s


def structure(data: EvalData, residual: Sequence[np.ndarray], lo: float, hi: float) -> dict[str, float]:
    """How much of the residual (per-run arrays over the evaluated spans) each signal explains: the RMS (output
    units) of its conditional mean against angle (harmonics up to 12/rev, only with an angle), time, input level,
    input rate, reversal order and the logarithm of the time since the last reversal, with the part expected from
    noise alone removed."""
    r = data.concat(residual)
    t = data.concat(data.eval_slice("t_abs_s"))
    cur = data.concat(data.eval_slice("current_a"))
    rate = data.concat([np.gradient(run.current_a, run.dt_s)[run.start:] for run in data.runs])
    order = data.concat([reversal_order(run.current_a, lo, hi)[run.start:] for run in data.runs])
    since = data.concat([_time_since_reversal(run.current_a, run.dt_s, 0.01 * (hi - lo))[run.start:]
                         for run in data.runs])
    out = {}
    if data.has_angle:
        out["angle"] = _angle_strength(data.concat(data.eval_slice("theta_rad")), r)
    out.update({
        "time": _binned_strength(t, r),
        "input_level": _binned_strength(cur, r),
        "input_rate": _binned_strength(rate, r),
        "reversal_order": _binned_strength(np.minimum(order, 6).astype(float) + 1e-9 * cur, r, bins=7),
        "time_since_reversal": _binned_strength(np.log1p(since / max(min(run.dt_s for run in data.runs), 1e-12)),
                                                r),
    })
    return out
