"""The field path of a model: commanded current → (delay, first-order lag) → CBH tables → output map → field
torque (N·mm, friction excluded).

The nominal path is the identified model's CBH operator on the commanded current. Extensions change one stage:
``coil_lag`` lags the current (time constant ``lag_tau_s``), ``time_delay`` delays it (``delay_s``),
``non_congruent`` puts an output map ``g(T) = S·n(1 + c|n|)/(1 + c)`` (``n = T/S``, ``S`` the full-scale
torque) after a Preisach core whose tables are the measured curves mapped through ``g⁻¹``, and
``table_resolution`` replaces the tables by least-squares refined ones.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, Sequence

import numpy as np

from bmr import _core
from bmr._core import BmrError, Hysteresis
from bmr.identification.spans import SATURATION_TOL, evaluation_start

__all__ = ["FieldPath", "lag", "delay", "output_map", "output_map_inverse"]

# Least-squares re-identification: table intervals and regression rows (speed vs resolution).
REIDENTIFY_INTERVALS = 40
REIDENTIFY_ROWS = 20_000
_REIDENTIFIED: dict[tuple, Any] = {}

Curves = tuple[list[tuple[np.ndarray, np.ndarray]], list[tuple[np.ndarray, np.ndarray]]]


def lag(x: np.ndarray, tau_s: float, dt_s: float) -> np.ndarray:
    """First-order lag ``y' = (x − y)/tau`` sampled exactly for a held input, starting at rest at ``x[0]``."""
    x = np.asarray(x, dtype=float)
    if tau_s <= 0.0 or x.size == 0:
        return x.copy()
    from scipy.signal import lfilter

    p = math.exp(-dt_s / tau_s)
    y, _ = lfilter([1.0 - p], [1.0, -p], x, zi=[p * x[0]])
    return y


def lead(x: np.ndarray, tau_s: float, dt_s: float) -> np.ndarray:
    """Exact inverse of :func:`lag`: ``lag(lead(x)) == x`` (up to round-off)."""
    x = np.asarray(x, dtype=float)
    if tau_s <= 0.0 or x.size == 0:
        return x.copy()
    p = math.exp(-dt_s / tau_s)
    prev = np.concatenate([[x[0]], x[:-1]])
    return (x - p * prev) / (1.0 - p)


def delay(x: np.ndarray, delay_s: float, dt_s: float) -> np.ndarray:
    """``x`` delayed by ``round(delay_s/dt_s)`` samples (the first value held before the start)."""
    x = np.asarray(x, dtype=float)
    d = int(round(delay_s / dt_s))
    if d <= 0 or x.size == 0:
        return x.copy()
    d = min(d, x.size)
    return np.concatenate([np.full(d, x[0]), x[: x.size - d]])


def output_map(y: np.ndarray, curvature: float, scale_nmm: float) -> np.ndarray:
    """``g(T) = S·n(1 + c|n|)/(1 + c)`` with ``n = T/S`` (identity for ``c = 0``)."""
    y = np.asarray(y, dtype=float)
    if curvature == 0.0:
        return y.copy()
    n = y / scale_nmm
    return scale_nmm * n * (1.0 + curvature * np.abs(n)) / (1.0 + curvature)


def output_map_inverse(t: np.ndarray, curvature: float, scale_nmm: float) -> np.ndarray:
    """``g⁻¹``: solves ``|n| + c n² = |m|(1 + c)`` for ``|n|`` (``m = T/S``), sign kept; clipped where ``g``
    stops being monotone (concave maps beyond their turning point)."""
    t = np.asarray(t, dtype=float)
    c = curvature
    if c == 0.0:
        return t.copy()
    m = np.abs(t) / scale_nmm
    disc = np.maximum(1.0 + 4.0 * c * (1.0 + c) * m, 0.0)
    n = (np.sqrt(disc) - 1.0) / (2.0 * c)
    return np.sign(t) * scale_nmm * n


def _monotone(u: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    # Mapped curves stay monotone up to round-off; clamp the round-off.
    return u, np.maximum.accumulate(y) if y[-1] >= y[0] else np.minimum.accumulate(y)


@dataclass(frozen=True)
class FieldPath:
    """One field path (see the module doc). ``tables`` (ascending, descending first-order curves, already in
    the core's domain) replaces the model's tables when given."""

    model: Any
    lag_tau_s: float = 0.0
    delay_s: float = 0.0
    curvature: float = 0.0
    tables: Any = None
    scale_nmm: float = 600.0
    protocol: tuple = ()  # identification runs for re-identification: (bmr.Run, start time in the bundle (s))
    # Fitted effects removed from the protocol torque before re-identification: ((effect, value, beta), ...).
    corrections: tuple = ()
    reidentify: bool = False  # core tables by least squares on the protocol runs under this path

    @staticmethod
    def nominal(model: Any, protocol: Sequence[Any] = ()) -> "FieldPath":
        lo, hi = model.hysteresis.output_range
        return FieldPath(model, scale_nmm=float(max(abs(lo), abs(hi), 1e-9)), protocol=tuple(protocol))

    def with_(self, **kwargs: Any) -> "FieldPath":
        return replace(self, **kwargs)

    def key(self) -> tuple:
        return (self.lag_tau_s, self.delay_s, self.curvature, id(self.tables), self.reidentify,
                self.corrections)

    def core_curves(self) -> Curves:
        """First-order curves of the Preisach core (the model's, mapped through ``g⁻¹``, or the refined ones)."""
        if self.tables is not None:
            return self.tables
        if self.reidentify and self.protocol:
            key = (id(self.protocol), self.lag_tau_s, self.delay_s, self.curvature, self.corrections)
            if key not in _REIDENTIFIED:
                if len(_REIDENTIFIED) > 256:
                    _REIDENTIFIED.clear()
                # The entry holds the protocol itself, so its id cannot be reused by another bundle's runs while
                # the entry lives (an id alone would go stale once the protocol is freed).
                _REIDENTIFIED[key] = (self.protocol, self._reidentified())
            return _REIDENTIFIED[key][1]
        asc, desc = self.model.hysteresis.curves()
        if self.curvature == 0.0:
            return list(asc), list(desc)

        def fam(curves: Sequence[Any]) -> list[tuple[np.ndarray, np.ndarray]]:
            return [_monotone(np.asarray(u, float), output_map_inverse(np.asarray(y, float), self.curvature,
                                                                        self.scale_nmm)) for u, y in curves]

        return fam(asc), fam(desc)

    def _reidentified(self) -> Curves:
        """Core tables identified again from the protocol runs as the core sees them — current through the delay
        and lag, torque (friction removed) through ``g⁻¹`` — by least squares (``bmr.fit_tables_lstsq``: exact
        for any input history, unlike cutting first-order curves out of a lagged current)."""

        lo, hi = self.model.hysteresis.input_range
        packed = []
        for r, t0_s in self.protocol:
            u = r.current
            dt = float(np.median(np.diff(r.t))) if u.size > 1 else 1.0
            y = r.torque - self.model.friction_torque(r.theta)
            for effect, value, beta in sorted(self.corrections, key=lambda c: c[0].removal_rank):
                y = effect.remove(y, value, np.asarray(beta), r, t0_s, self.model)
            y = output_map_inverse(y, self.curvature, self.scale_nmm)
            # The state is known from the *commanded* current's saturations (a lagged current never quite
            # reaches them), plus five time constants for the lag to settle.
            s = evaluation_start(u, lo, hi, SATURATION_TOL * (hi - lo)) + int(np.ceil(5 * self.lag_tau_s / dt))
            w = np.zeros(u.size)
            w[s:] = 1.0
            packed.append((np.ascontiguousarray(self.core_input(u, dt)), np.ascontiguousarray(y), w, 0))
        total = sum(int(np.count_nonzero(p[2])) for p in packed)
        stride = max(1, int(np.ceil(total / REIDENTIFY_ROWS)))
        for _, _, w, _ in packed:
            keep = np.zeros(w.size, dtype=bool)
            keep[np.flatnonzero(w)[::stride]] = True
            w[~keep] = 0.0
        res = _core.fit_everett(np.linspace(lo, hi, REIDENTIFY_INTERVALS + 1), packed, 1, smoothing=1e-4,
                                ridge=1e-9)
        asc, desc = res["model"].first_order_curves()
        return ([(np.asarray(u), np.asarray(y)) for u, y in asc], [(np.asarray(u), np.asarray(y)) for u, y in desc])

    def hysteresis(self) -> Any:
        """A fresh ``bmr.Hysteresis`` of the core."""
        if self.tables is None and self.curvature == 0.0 and not self.reidentify:
            asc, desc = self.model.hysteresis.curves()
        else:
            asc, desc = self.core_curves()
        try:
            return Hysteresis.from_curves(list(asc), list(desc), initial="negative")
        except BmrError as exc:
            raise BmrError(f"field path with curvature {self.curvature:g}: tables rejected: {exc}") from None

    def core_input(self, current_a: np.ndarray, dt_s: float) -> np.ndarray:
        """The current the core sees: delayed, then each coil's current lagged on its own (coil 1 carries the
        negative part of the nominal current, coil 2 the positive part), recombined as a nominal current."""
        u = delay(current_a, self.delay_s, dt_s)
        if self.lag_tau_s <= 0.0:
            return u
        return lag(np.maximum(u, 0.0), self.lag_tau_s, dt_s) - lag(np.maximum(-u, 0.0), self.lag_tau_s, dt_s)

    def simulate(self, runs: Sequence[Any], hysteresis: Any = None) -> list[np.ndarray]:
        """Field torque (N·mm) of every run (full length), each from negative saturation."""
        h = hysteresis if hysteresis is not None else self.hysteresis()
        out = []
        for r in runs:
            h.reset(initial="negative")
            core = np.asarray(h.run(np.ascontiguousarray(self.core_input(r.current_a, r.dt_s))), dtype=float)
            out.append(output_map(core, self.curvature, self.scale_nmm))
        return out

    def with_correction(self, effect: Any, value: Any, beta: Sequence[float]) -> "FieldPath":
        """This path re-identified with ``effect`` (an effect of the library with a ``remove`` method and a
        ``removal_rank``; nonlinear ``value``, linear ``beta``) removed from the protocol runs (replacing an earlier
        correction of the same effect)."""
        kept = tuple(c for c in self.corrections if c[0] is not effect)
        return self.with_(corrections=kept + ((effect, value, tuple(float(b) for b in beta)),), reidentify=True)

    def params(self) -> dict[str, float]:
        return {"lag_tau_s": self.lag_tau_s, "delay_s": self.delay_s, "curvature": self.curvature,
                "scale_nmm": self.scale_nmm}
