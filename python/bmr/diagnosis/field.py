"""The field path of a model: commanded current → (delay, first-order lag) → CBH tables → output map → field
torque (N·mm, friction excluded).

The nominal path is the identified model's CBH operator on the commanded current. Extensions change one stage:
``coil_lag`` lags the current (time constant ``lag_tau_s``), ``time_delay`` delays it (``delay_s``),
``non_congruent`` puts an output map ``g(T) = S·n(1 + c|n| + k·n²)/(1 + c + k)`` (``n = T/S``, ``S`` the
full-scale torque, curvature ``c``, cubic term ``k``) after a Preisach core whose tables are the measured curves
mapped through ``g⁻¹`` (or identified again by least squares on the core's side of the map), or (its mean-field
form, a moving Preisach model) feeds the core's output back into its input, the core seeing
``u + feedback · y/S`` with ``y`` its output of the sample before (``feedback`` in input units; the tables identified
again on that input with the measured output), and ``table_resolution`` replaces the tables by least-squares refined
ones.

Re-identified tables (``reidentify=True``) come from a :class:`Reidentifier` that belongs to one diagnosis and
is carried by the path (``FieldPath.reidentifier``): it keeps the least-squares problem of each input history
(lag, delay) prepared (``bmr._core.EverettRegression``: regressors and normal matrix built once) so that
candidates that only change the output side (output map, removed corrections) cost one right-hand side and a
warm-started nonnegative solve, and it remembers the last solution's active set to warm-start the next input
history. Its caches are bounded; nothing is kept between diagnoses.
"""
from __future__ import annotations

import copy
import math
from collections import OrderedDict
from dataclasses import dataclass, field, replace
from typing import Any, Sequence

import numpy as np

from bmr import _core
from bmr._core import BmrError, Hysteresis
from bmr.identification.spans import SATURATION_TOL, evaluation_start
from bmr.identification.table_choice import SWEEP_DEADBAND, fold_of_each_sample, pooled_rms, sweep_folds

__all__ = ["FieldPath", "Reidentifier", "ProtocolRun", "lag", "delay", "output_map", "output_map_inverse",
           "steepest_slope"]

# Least-squares re-identification: table intervals and regression rows (speed vs resolution).
REIDENTIFY_INTERVALS = 40
REIDENTIFY_ROWS = 20_000
REIDENTIFY_SMOOTHING = 1e-4
# Shares of the smoothness penalty along the diagonal (equal switching width) tried for the re-identified tables,
# the isotropic 0 first; one is taken when it predicts whole held-out sweeps of the protocol runs (a first-order
# curve, a loop's branch) better by DIAGONAL_GAIN of their RMS: a clear preference (the paper's protocol on the
# independent plant preferred 0.9 by 8 %, and those tables hid a cubic yield map there). A narrow coercivity
# spread and a broad interaction field (a hard steel) make a ridge along the diagonal that a few measured curves
# cross: the isotropic penalty blurs it between them (a clean `rig_soft` bundle, 7 curves per family: 2.43 N·mm
# held out, noise 1.48; 0.9 along the diagonal: 2.06). The whole penalty along it (1.75) leaves the density free
# across the diagonal, and what a per-recording calibration left there an output map took: a wrong name.
DIAGONAL_SHARES = (0.0, 0.5, 0.9)
DIAGONAL_GAIN = 0.1
DIAGONAL_FOLDS = 3
# Identifications of a rate-dependent path's tables with the slopes of the tables identified before (see
# Reidentifier.settle_slopes): 2 passes left a coil lag to name beside a dynamic field, 4 none.
RATE_SLOPE_PASSES = 4
# ... stopping early once a pass moves no point of the tables' first-order curves by more than this share of the
# noise floor.
RATE_SLOPE_SETTLED = 0.1

Curves = tuple[list[tuple[np.ndarray, np.ndarray]], list[tuple[np.ndarray, np.ndarray]]]


def lag(x: np.ndarray, tau_s: float, dt_s: float) -> np.ndarray:
    """First-order lag ``y' = (x − y)/tau`` sampled exactly for a held input, starting at rest at ``x[0]`` (the
    core's filter, ``bmr._core.lag``)."""
    x = np.asarray(x, dtype=float)
    if tau_s <= 0.0 or x.size == 0:
        return x.copy()
    return _core.lag(x, tau_s, dt_s)


def lead(x: np.ndarray, tau_s: float, dt_s: float) -> np.ndarray:
    """Exact inverse of :func:`lag`: ``lag(lead(x)) == x`` (up to round-off)."""
    x = np.asarray(x, dtype=float)
    if tau_s <= 0.0 or x.size == 0:
        return x.copy()
    return _core.lead(x, tau_s, dt_s)


def delay(x: np.ndarray, delay_s: float, dt_s: float) -> np.ndarray:
    """``x`` delayed by ``round(delay_s/dt_s)`` samples (the first value held before the start)."""
    x = np.asarray(x, dtype=float)
    if x.size == 0:
        return x.copy()
    return _core.delay(x, delay_s, dt_s)


def output_map(y: np.ndarray, curvature: float, scale_nmm: float, cubic: float = 0.0) -> np.ndarray:
    """``g(T) = S·n(1 + c|n| + k·n²)/(1 + c + k)`` with ``n = T/S`` (identity for ``c = k = 0``), as the core
    tabulates it."""
    y = np.asarray(y, dtype=float)
    if curvature == 0.0 and cubic == 0.0:
        return y.copy()
    return _core.output_map(y, curvature, scale_nmm, cubic)


def output_map_inverse(t: np.ndarray, curvature: float, scale_nmm: float, cubic: float = 0.0) -> np.ndarray:
    """``g⁻¹`` of :func:`output_map` (a concave map only up to its turning point)."""
    t = np.asarray(t, dtype=float)
    if curvature == 0.0 and cubic == 0.0:
        return t.copy()
    return _core.output_map_inverse(t, curvature, scale_nmm, cubic)


def steepest_slope(curves: Curves) -> float:
    """The steepest slope (output per input unit) of a core's first-order curves: the largest over their intervals
    of the rise over the run (the slope a mean field multiplies)."""
    best = 0.0
    for family in curves:
        for u, y in family:
            du, dy = np.diff(np.asarray(u, dtype=float)), np.diff(np.asarray(y, dtype=float))
            ok = du > 0
            if np.any(ok):
                best = max(best, float(np.max(np.abs(dy[ok] / du[ok]))))
    return best


def previous_sample(y: np.ndarray) -> np.ndarray:
    """``y`` one sample back (its first value held): what a mean field feeds back."""
    y = np.asarray(y, dtype=float)
    return np.concatenate([y[:1], y[:-1]]) if y.size else y.copy()


def _monotone(u: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    # Mapped curves stay monotone up to round-off; clamp the round-off.
    return u, np.maximum.accumulate(y) if y[-1] >= y[0] else np.minimum.accumulate(y)


class ProtocolRun:
    """One protocol run as re-identification reads it: signals extracted once, the nominal friction removed from
    the torque, and what a correction's ``remove`` may need (``theta``, ``current``, ``t``, ``t0_s`` its start in
    the bundle, ``friction()``, ``nominal_field()``, ``context`` the diagnosis's evaluation data, ``bundle_index``
    its place in the bundle)."""

    def __init__(self, run: Any, t0_s: float, model: Any, context: Any = None) -> None:
        self.run = run
        self.name = run.name
        self.t0_s = float(t0_s)
        self.t = run.t
        self.current = run.input
        self.theta = run.angle if run.angle is not None else np.zeros(self.current.size)
        self.has_angle = run.angle is not None
        self.dt = float(np.median(np.diff(self.t))) if self.current.size > 1 else 1.0
        self.model = model
        self.context = context
        names = list(getattr(context, "run_start_s", {}) or {})
        self.bundle_index = names.index(run.name) if run.name in names else None
        self._friction: np.ndarray | None = None
        self._nominal_field: np.ndarray | None = None
        self._harmonic: tuple[Any, tuple[np.ndarray, np.ndarray]] | None = None
        self.torque = run.output - self.friction()
        # Samples at the output's range end (a sensor at its limit) carry no measurement: not fitted.
        rails = getattr(context, "rails", None)
        self.at_rail = rails.mask(run.output) if rails is not None and rails.any else None

    @property
    def current_a(self) -> np.ndarray:
        """The input, under the name :meth:`FieldPath.simulate` reads of a run."""
        return self.current

    @property
    def dt_s(self) -> float:
        return self.dt

    def known_from(self, lo: float, hi: float) -> int:
        """The first sample whose state is known: after the run's first saturation (input range ``lo``..``hi``)."""
        return evaluation_start(self.current, lo, hi, SATURATION_TOL * (hi - lo))

    def harmonic(self, order: Any) -> tuple[np.ndarray, np.ndarray]:
        """``sin(order·θ)``, ``cos(order·θ)`` along the run (the last order asked for is kept: the folds of one
        candidate remove the same harmonic again and again)."""
        if self._harmonic is None or self._harmonic[0] != order:
            self._harmonic = (order, (np.sin(order * self.theta), np.cos(order * self.theta)))
        return self._harmonic[1]

    def nominal_field(self) -> np.ndarray:
        """The nominal core's output on the run's current from negative saturation (computed once: every creep
        correction's response to its fluctuation field is taken against it)."""
        if self._nominal_field is None:
            h = copy.copy(self.model.forward_hysteresis())
            h.reset(initial="negative")
            self._nominal_field = np.asarray(h.run(np.ascontiguousarray(self.current, dtype=float)), dtype=float)
        return self._nominal_field

    def friction(self) -> np.ndarray:
        """The nominal model's friction (output units) along the run (computed once; zero without an angle)."""
        if self._friction is None:
            self._friction = (self.model.friction_torque(self.theta) if self.has_angle
                              else np.zeros(self.current.size))
        return self._friction


class Reidentifier:
    """Least-squares core tables of the protocol runs (``(bmr.Run, start time in the bundle (s))``) under any field
    path, for one diagnosis of ``model``. ``context`` (the diagnosis's :class:`bmr.diagnosis.residuals.EvalData`)
    is what the corrections' ``remove`` may read (e.g. the heating state of the whole bundle).

    Caches (bounded): the prepared regression of the last few input histories (one slot kept for the history asked
    for again, the configuration's) and the tables of recent paths.
    """

    def __init__(self, model: Any, protocol: Sequence[Any], context: Any = None, *, max_inputs: int = 3,
                 max_tables: int = 64) -> None:
        self.model = model
        self.protocol = tuple(protocol)
        self.context = context
        self.max_inputs = max_inputs
        self.max_tables = max_tables
        self._regressions: OrderedDict[tuple, Any] = OrderedDict()
        self._kept: tuple[tuple, Any] | None = None  # the regression asked for again (counted in max_inputs)
        self._tables: OrderedDict[tuple, Curves] = OrderedDict()
        # Cores whose slopes set a rate dependence's lag (FieldPath.rate_slopes n is the n-th) and the number each
        # settled path ended at (settle_slopes).
        self._slope_cores: list[Any] = []
        self._settled: dict[tuple, int] = {}
        self._passive: np.ndarray | None = None
        self.fits = 0  # least-squares solves done (for the benchmarks)
        self.regressions = 0  # input histories prepared
        lo, hi = model.hysteresis.input_range
        self.input_range = (float(lo), float(hi))
        self.runs = [ProtocolRun(r, t0_s, model, context) for r, t0_s in self.protocol]
        self._diagonal: tuple[float, dict[float, float]] | None = None

    @property
    def diagonal_smoothing(self) -> float:
        """The share of the tables' smoothness penalty along the diagonal (:data:`DIAGONAL_SHARES`), chosen once per
        diagnosis on the commanded current and the measured torque by whole held-out sweeps."""
        return self.diagonal_choice[0]

    @property
    def diagonal_choice(self) -> tuple[float, dict[float, float]]:
        """The chosen share and the held-out sweep RMS (output units) of each share tried (empty: not tried)."""
        if self._diagonal is None:
            self._diagonal = self._choose_diagonal()
        return self._diagonal

    @property
    def diagonal_chosen(self) -> tuple[float, dict[float, float]] | None:
        """:attr:`diagonal_choice` once it was made (None before any table was identified again)."""
        return self._diagonal

    def _choose_diagonal(self) -> tuple[float, dict[float, float]]:
        inputs, weights = self._inputs(FieldPath.nominal(self.model))
        if not inputs:
            return 0.0, {}
        lo, hi = self.input_range
        masks = sweep_folds(inputs, weights, SWEEP_DEADBAND * (hi - lo), DIAGONAL_FOLDS)
        if sum(1 for fold in masks if any(np.count_nonzero(w[m]) for w, m in zip(weights, fold))) < 2:
            return 0.0, {}
        data = [(u, np.ascontiguousarray(pr.torque), w, fold_of_each_sample(masks, k), k, np.zeros(0), 1.0)
                for k, (u, w, pr) in enumerate(zip(inputs, weights, self.runs))]
        try:
            folds = _core.EverettFolds(np.linspace(lo, hi, REIDENTIFY_INTERVALS + 1), data, len(data), len(masks))
            rms = {share: pooled_rms(folds.score(REIDENTIFY_SMOOTHING, ridge=1e-9, diagonal_smoothing=share))
                   for share in DIAGONAL_SHARES}
        except BmrError:
            return 0.0, {}
        best = min(rms, key=lambda share: (rms[share], share))
        if not rms[best] <= (1.0 - DIAGONAL_GAIN) * rms[0.0]:
            best = 0.0
        return best, rms

    def release(self) -> None:
        """Drop the prepared regressions (tens of MB each on a long bundle) once no more tables will be
        identified; the tables identified so far stay."""
        self._regressions.clear()
        self._kept = None

    def correction_change(self, effect: Any, value: Any, before: Sequence[float], after: Sequence[float]) -> float:
        """RMS (output units, over the protocol runs' samples) of what changes in the corrected protocol torque
        when ``effect``'s linear parameters go from ``before`` to ``after``: how much a re-identification with the
        new parameters could change the tables."""
        total, count = 0.0, 0
        b0, b1 = np.asarray(before, dtype=float), np.asarray(after, dtype=float)
        for pr in self.runs:
            d = effect.remove(pr.torque, value, b1, pr) - effect.remove(pr.torque, value, b0, pr)
            total += float(np.dot(d, d))
            count += d.size
        return math.sqrt(total / count) if count else 0.0

    @staticmethod
    def _tables_key(path: "FieldPath") -> tuple:
        """What the re-identified tables of ``path`` depend on."""
        return (path.lag_tau_s, path.delay_s, path.rate_tau_s, path.feedback, path.curvature, path.cubic,
                path.corrections, path.rate_slopes if path.rate_tau_s > 0.0 else 0)

    def curves(self, path: "FieldPath") -> Curves:
        key = self._tables_key(path)
        if key in self._tables:
            self._tables.move_to_end(key)
            return self._tables[key]
        tables = self._identify(path)
        self._tables[key] = tables
        while len(self._tables) > self.max_tables:
            self._tables.popitem(last=False)
        return tables

    def settle_slopes(self, path: "FieldPath") -> int:
        """The rate dependence's lag follows the core's slopes, taken at first from the nominal core, which was
        identified from runs the rate dependence itself distorted: the tables of ``path`` are identified again
        with the slopes of the core they describe, :data:`RATE_SLOPE_PASSES` times (towards that fixed point).
        Returns the number that names the last slope core (``FieldPath.rate_slopes``); the path's own when it
        has no rate dependence or there are no protocol runs (nothing to identify), or the first core is rejected."""
        if path.rate_tau_s <= 0.0 or not self.runs:
            return path.rate_slopes
        key = self._tables_key(path)
        if key in self._settled:
            return self._settled[key]
        n = path.rate_slopes
        before = None
        for _ in range(RATE_SLOPE_PASSES):
            asc, desc = self.curves(path.with_(rate_slopes=n))
            outputs = np.concatenate([y for _, y in asc] + [y for _, y in desc])
            if before is not None and before.shape == outputs.shape and np.max(np.abs(outputs - before)) < (
                    RATE_SLOPE_SETTLED * self._noise_floor()):
                break
            before = outputs
            try:
                core = Hysteresis.from_curves(list(asc), list(desc), initial="negative")
            except BmrError:
                break
            self._slope_cores.append(core)
            n = len(self._slope_cores)
        self._settled[key] = n
        return n

    def _noise_floor(self) -> float:
        """The output noise floor of the diagnosis (output units; the output span's 1e-3 without one)."""
        floor = getattr(self.context, "noise_floor_nmm", None)
        if floor is not None and floor > 0:
            return float(floor)
        lo, hi = self.model.hysteresis.output_range
        return 1e-3 * float(hi - lo)

    def _regression(self, path: "FieldPath") -> Any:
        """The prepared least squares of the protocol runs under ``path``'s input stages (with a mean field: the
        core's input shifted by the feedback times the measured output of the sample before, mapped to the core's
        side of the output map; with a rate dependence, its lag following the slopes of the core
        ``path.rate_slopes`` names)."""
        key = (path.lag_tau_s, path.delay_s, path.rate_tau_s, path.feedback,
               path.rate_slopes if path.rate_tau_s > 0.0 else 0)
        if self._kept is not None and self._kept[0] == key:
            return self._kept[1]
        if key in self._regressions:
            # Asked for again: the input history of the round's configuration, which every output-side
            # candidate re-identifies under while the input-side ones fill the other slots.
            reg = self._regressions.pop(key)
            if self._kept is not None:
                self._regressions[self._kept[0]] = self._kept[1]
            self._kept = (key, reg)
            return reg
        slope_core = self._slope_cores[path.rate_slopes - 1] if path.rate_slopes else self.model.forward_hysteresis()
        reg = self._prepare(path, slope_core)
        self.regressions += 1
        self._regressions[key] = reg
        while len(self._regressions) + (self._kept is not None) > self.max_inputs:
            self._regressions.popitem(last=False)
        return reg

    def _prepare(self, path: "FieldPath", slope_core: Any) -> Any:
        """:meth:`_regression` built (not cached)."""
        lo, hi = self.input_range
        inputs, weights = self._inputs(path, slope_core)
        # One output offset per protocol run: each is its own recording (a zero or a remanence of its own).
        return _core.EverettRegression(np.linspace(lo, hi, REIDENTIFY_INTERVALS + 1),
                                       [(u, w, k) for k, (u, w) in enumerate(zip(inputs, weights))], len(inputs),
                                       smoothing=REIDENTIFY_SMOOTHING, ridge=1e-9,
                                       diagonal_smoothing=self.diagonal_smoothing)

    def _inputs(self, path: "FieldPath", slope_core: Any = None) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """The core's input of every protocol run under ``path`` and its row weights (zero before the state is
        known, at the output's rails and between the rows kept)."""
        lo, hi = self.input_range
        inputs, weights = [], []
        for pr in self.runs:
            u = pr.current
            # The state is known from the *commanded* current's saturations (a lagged current never quite
            # reaches them), plus five time constants for the lag to settle.
            s = pr.known_from(lo, hi) + int(np.ceil(5 * path.lag_tau_s / pr.dt))
            w = np.zeros(u.size)
            w[s:] = 1.0
            if pr.at_rail is not None:
                w[pr.at_rail] = 0.0
            core_u = path.core_input(u, pr.dt, rate_core=slope_core)
            if path.feedback != 0.0:
                core_y = output_map_inverse(pr.torque, path.curvature, path.scale_nmm, path.cubic)
                core_u = core_u + path.feedback / path.scale_nmm * previous_sample(core_y)
            inputs.append(np.ascontiguousarray(core_u))
            weights.append(w)
        total = sum(int(np.count_nonzero(w)) for w in weights)
        stride = max(1, int(np.ceil(total / REIDENTIFY_ROWS)))
        for w in weights:
            keep = np.zeros(w.size, dtype=bool)
            keep[np.flatnonzero(w)[::stride]] = True
            w[~keep] = 0.0
        return inputs, weights

    def _identify(self, path: "FieldPath") -> Curves:
        """Core tables identified again from the protocol runs as the core sees them — current through the delay
        and lag, torque (friction removed) through ``g⁻¹`` — by least squares (exact for any input history, unlike
        cutting first-order curves out of a lagged current)."""
        reg = self._regression(path)
        outputs = []
        corrections = sorted(path.corrections, key=lambda c: c[0].removal_rank)
        for pr in self.runs:
            y = pr.torque
            for effect, value, beta in corrections:
                y = effect.remove(y, value, np.asarray(beta), pr)
            outputs.append(np.ascontiguousarray(output_map_inverse(y, path.curvature, path.scale_nmm, path.cubic)))
        res = reg.fit(outputs, self._passive)
        self._passive = res.passive
        self.fits += 1
        asc, desc = res.model.first_order_curves()
        return ([(np.asarray(u), np.asarray(y)) for u, y in asc], [(np.asarray(u), np.asarray(y)) for u, y in desc])


@dataclass(frozen=True)
class FieldPath:
    """One field path (see the module doc). ``tables`` (ascending, descending first-order curves, already in
    the core's domain) replaces the model's tables when given; with ``reidentify`` the tables come from
    ``reidentifier`` (a :class:`Reidentifier` of the protocol runs; one is made on the spot when none is given)."""

    model: Any
    lag_tau_s: float = 0.0
    delay_s: float = 0.0
    # rate_dependence: time constant of the core-input lag at the loop's mean slope (s).
    rate_tau_s: float = 0.0
    # rate_dependence: the core whose slopes set the protocol runs' lag when the tables are identified again
    # (0: the nominal core; n: the n-th core of the reidentifier, see Reidentifier.settle_slopes).
    rate_slopes: int = 0
    curvature: float = 0.0
    cubic: float = 0.0  # non_congruent: the output map's odd cubic term
    # non_congruent: the mean field, input added per full-scale core output y/S of the sample before (input units).
    feedback: float = 0.0
    tables: Any = None
    scale_nmm: float = 600.0
    protocol: tuple = ()  # identification runs for re-identification: (bmr.Run, start time in the bundle (s))
    # Fitted effects removed from the protocol torque before re-identification: ((effect, value, beta), ...).
    corrections: tuple = ()
    reidentify: bool = False  # core tables by least squares on the protocol runs under this path
    reidentifier: Any = field(default=None, compare=False, repr=False)

    @staticmethod
    def nominal(model: Any, protocol: Sequence[Any] = (), reidentifier: Any = None) -> "FieldPath":
        lo, hi = model.hysteresis.output_range
        return FieldPath(model, scale_nmm=float(max(abs(lo), abs(hi), 1e-9)), protocol=tuple(protocol),
                         reidentifier=reidentifier)

    def with_(self, **kwargs: Any) -> "FieldPath":
        return replace(self, **kwargs)

    def key(self) -> tuple:
        return (self.lag_tau_s, self.delay_s, self.rate_tau_s, self.feedback, self.curvature, self.cubic,
                id(self.tables), self.reidentify, self.corrections, self.rate_slopes)

    def core_curves(self) -> Curves:
        """First-order curves of the Preisach core (the model's, mapped through ``g⁻¹``, or the refined ones)."""
        if self.tables is not None:
            return self.tables
        if self.reidentify and self.protocol:
            reid = self.reidentifier
            if reid is None:
                reid = Reidentifier(self.model, self.protocol)
            return reid.curves(self)
        asc, desc = self.model.forward_hysteresis().curves()
        if self.curvature == 0.0 and self.cubic == 0.0:
            return list(asc), list(desc)

        def fam(curves: Sequence[Any]) -> list[tuple[np.ndarray, np.ndarray]]:
            return [_monotone(np.asarray(u, float), output_map_inverse(np.asarray(y, float), self.curvature,
                                                                        self.scale_nmm, self.cubic))
                    for u, y in curves]

        return fam(asc), fam(desc)

    def hysteresis(self) -> Any:
        """A fresh ``bmr.Hysteresis`` of the core."""
        if self.tables is None and self.curvature == 0.0 and self.cubic == 0.0 and not self.reidentify:
            # The nominal core is the model's own operator: built once, not rebuilt from its stored curves (which
            # hold derived and added curves a second build need not accept).
            h = copy.copy(self.model.forward_hysteresis())
            h.reset(initial="negative")
            return h
        asc, desc = self.core_curves()
        try:
            return Hysteresis.from_curves(list(asc), list(desc), initial="negative")
        except BmrError as exc:
            raise BmrError(f"field path with curvature {self.curvature:g}, cubic {self.cubic:g}: tables rejected: "
                           f"{exc}") from None

    def drive_input(self, current_a: np.ndarray, dt_s: float) -> np.ndarray:
        """The input after the delay and the lag (each coil's current lagged on its own: coil 1 carries the
        negative part of the nominal current, coil 2 the positive part, recombined as a nominal current)."""
        u = delay(current_a, self.delay_s, dt_s)
        if self.lag_tau_s <= 0.0:
            return u
        return lag(np.maximum(u, 0.0), self.lag_tau_s, dt_s) - lag(np.maximum(-u, 0.0), self.lag_tau_s, dt_s)

    def core_input(self, current_a: np.ndarray, dt_s: float, rate_core: Any = None) -> np.ndarray:
        """The input the core sees: :meth:`drive_input`, then (``rate_dependence``) the slope-following lag,
        whose slopes come from ``rate_core`` (a ``bmr.Hysteresis``; default this path's own core) run from
        negative saturation."""
        u = self.drive_input(current_a, dt_s)
        if self.rate_tau_s <= 0.0:
            return u
        h = copy.copy(rate_core) if rate_core is not None else self.hysteresis()
        h.reset(initial="negative")
        _, core = h.run_rate_dependent(np.ascontiguousarray(u), tau_s=self.rate_tau_s, dt_s=dt_s)
        return np.asarray(core, dtype=float)

    def drive_inputs(self, runs: Sequence[Any]) -> list[np.ndarray]:
        """:meth:`drive_input` of every run (contiguous, read-only: what :meth:`simulate` may be given back)."""
        out = []
        for r in runs:
            u = np.ascontiguousarray(self.drive_input(r.current_a, r.dt_s))
            u.flags.writeable = False
            out.append(u)
        return out

    def simulate(self, runs: Sequence[Any], hysteresis: Any = None,
                 inputs: Sequence[np.ndarray] | None = None) -> list[np.ndarray]:
        """Field output of every run (full length), each from negative saturation. ``inputs``: this path's
        :meth:`drive_inputs` of ``runs`` when the caller already has them (they depend on the delay and lag only)."""
        h = hysteresis if hysteresis is not None else self.hysteresis()
        out = []
        for i, r in enumerate(runs):
            h.reset(initial="negative")
            u = inputs[i] if inputs is not None else np.ascontiguousarray(self.drive_input(r.current_a, r.dt_s))
            if self.feedback != 0.0:
                core, _ = h.run_mean_field(u, per_output=self.feedback / self.scale_nmm, tau_s=self.rate_tau_s,
                                           dt_s=r.dt_s)
            elif self.rate_tau_s > 0.0:
                core, _ = h.run_rate_dependent(u, tau_s=self.rate_tau_s, dt_s=r.dt_s)
            else:
                core = h.run(u)
            core = np.asarray(core, dtype=float)
            # The core's output is a fresh array: without an output map it is the field (no copy).
            identity = self.curvature == 0.0 and self.cubic == 0.0
            out.append(core if identity else output_map(core, self.curvature, self.scale_nmm, self.cubic))
        return out

    def with_correction(self, effect: Any, value: Any, beta: Sequence[float]) -> "FieldPath":
        """This path re-identified with ``effect`` (an effect of the library with a ``remove`` method and a
        ``removal_rank``; nonlinear ``value``, linear ``beta``) removed from the protocol runs (replacing an earlier
        correction of the same effect)."""
        kept = tuple(c for c in self.corrections if c[0] is not effect)
        return self.with_(corrections=kept + ((effect, value, tuple(float(b) for b in beta)),), reidentify=True)

    def params(self) -> dict[str, float]:
        return {"lag_tau_s": self.lag_tau_s, "delay_s": self.delay_s, "rate_tau_s": self.rate_tau_s,
                "curvature": self.curvature, "cubic": self.cubic, "feedback": self.feedback,
                "scale_nmm": self.scale_nmm}
