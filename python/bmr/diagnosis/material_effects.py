"""Effects of the hysteretic material and of the measurement that any device can show (no angle needed), as
parametric extensions of the nominal model: ``creep``, ``run_gain_offset``, ``leakage``, ``accommodation`` (linear
in their amplitudes given at most one nonlinear parameter) and ``rate_dependence`` (a field effect: the core's input
lags with a time constant that follows the branch's slope). Parameters follow the effect vocabulary
(``bmr.effect_parameters()``) so a simulated truth can be compared; the per-sample signals come from the core
(:func:`bmr._core.creep_columns`, :func:`bmr._core.accommodation_shift`, ``Hysteresis.run_rate_dependent``).

Every effect here reads the evaluated spans run by run (``data.runs``: each run's full input, its first evaluated
sample ``start`` and sample period ``dt_s``) and the field output of the configuration's path over the evaluated
spans (``y_field``), so it works for any declared input and output.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from bmr import _core
from bmr.diagnosis.effects import Effect

__all__ = ["Creep", "RateDependence", "RunGainOffset", "Leakage", "Accommodation", "MATERIAL", "CREEP_TAUS_S",
           "ACCOMMODATION_DEADBAND", "ACCOMMODATION_SATURATION"]

# Relaxation times the creep spectrum is built from (three per decade), limited per bundle by its sample period and
# the length of its runs.
CREEP_TAUS_S = tuple(float(v) for v in np.geomspace(0.01, 1000.0, 16))
# Reversal dead-band and saturation tolerance of accommodation, as shares of the input span (the plant's own).
ACCOMMODATION_DEADBAND = 0.01
ACCOMMODATION_SATURATION = 0.002


def _split(data: Any, y: np.ndarray) -> list[np.ndarray]:
    """``y`` over the evaluated spans, cut run by run."""
    bounds = np.cumsum([r.n_eval for r in data.runs])[:-1]
    return np.split(np.asarray(y, dtype=float), bounds)


def _fingerprint(y: np.ndarray) -> tuple:
    """A cheap identity of a field-output array (the caches' key: paths are re-simulated, arrays change)."""
    return (y.size, float(y[0]) if y.size else 0.0, float(np.sum(y)), float(np.sum(y[::97] ** 2)))


def _run_input(r: Any) -> np.ndarray:
    return r.current_a


class Creep(Effect):
    """After each change of the core output, a share ``fraction`` keeps arriving through relaxations with time
    constants spread evenly in ``log τ`` from ``tau_min_s`` to ``tau_max_s`` (creep logarithmic in time between
    them; one exponential when they coincide). Linear in ``fraction`` for a given spectrum: the column is the mean
    of ``lag(v, τ) − v`` over the spectrum's time constants (``v`` the field output, each run from rest at its
    first evaluated sample)."""

    name = "creep"
    doc = "output relaxes after every change: y = v + fraction·mean_τ(lag(v, τ) − v), τ log-uniform in a range"
    needs_reidentify = True

    def _taus(self, data: Any) -> list[float]:
        dt = min(r.dt_s for r in data.runs)
        longest = max(r.n_eval * r.dt_s for r in data.runs)
        return [t for t in CREEP_TAUS_S if 3.0 * dt <= t <= 3.0 * longest]

    def grid(self, data: Any) -> list[Any]:
        taus = self._taus(data)
        decades = taus[::3] if len(taus) > 3 else taus
        return [(a, b) for i, a in enumerate(decades) for b in decades[i:]]

    def _bank(self, data: Any, y_field: np.ndarray) -> tuple[list[float], np.ndarray]:
        taus = self._taus(data)

        def make() -> np.ndarray:
            cols = [_core.creep_columns(np.ascontiguousarray(y), taus, r.dt_s)
                    for y, r in zip(_split(data, y_field), data.runs)]
            return np.vstack(cols)

        return taus, data.cache.get(("creep_bank", _fingerprint(y_field)), make)

    def columns(self, data, value, y_field, model):
        taus, bank = self._bank(data, y_field)
        lo, hi = value
        sel = [j for j, t in enumerate(taus) if lo * (1 - 1e-9) <= t <= hi * (1 + 1e-9)]
        return bank[:, sel].mean(axis=1)[:, None]

    def update_path(self, path, value, own_beta, data):
        # Creep also bent the identification runs: identify the tables again with it removed.
        return path.with_correction(self, value, own_beta)

    @staticmethod
    def remove(y, value, beta, run):
        lo, hi = value
        taus = [t for t in CREEP_TAUS_S if lo * (1 - 1e-9) <= t <= hi * (1 + 1e-9)]
        # The relaxation of the measured output approximates that of the core output (second order in fraction).
        cols = _core.creep_columns(np.ascontiguousarray(y), taus, run.dt)
        return y - beta[0] * cols.mean(axis=1)

    def params(self, value, beta, path):
        return {"fraction": float(beta[0]), "tau_min_s": float(value[0]), "tau_max_s": float(value[1])}


class RateDependence(Effect):
    """The core's input lags the applied input with a time constant ``tau_s · ŝ`` that follows the branch's
    relative slope ``ŝ`` (a dynamic field opposing the change of the material's state: eddy currents, domain-wall
    damping). A field effect: the path runs the core through the rate-dependence stage."""

    name = "rate_dependence"
    field = True
    doc = "core input lags with a time constant proportional to the branch's differential slope (dynamic field)"
    needs_reidentify = True

    def grid(self, data: Any) -> list[Any]:
        return [float(v) for v in np.geomspace(2e-4, 0.5, 18)]

    def apply(self, path, value, data, train):
        return path.with_(rate_tau_s=float(value), reidentify=True)

    def params(self, value, beta, path):
        return {"tau_s": float(path.rate_tau_s)}

    def refine(self) -> bool:
        return True


class RunGainOffset(Effect):
    """Each evaluation run has its own output gain and offset (calibration that changed between recordings): the
    columns are the field output and a constant, each restricted to one run. The reported spreads are those of the
    per-run estimates, shrunk towards the common value by their estimation noise."""

    name = "run_gain_offset"
    doc = "per-run gain and offset of the measured output (calibration between recordings)"

    def columns(self, data, value, y_field, model):
        def make() -> np.ndarray:
            n = y_field.size
            k = len(data.runs)
            cols = np.zeros((n, 2 * k))
            start = 0
            for j, r in enumerate(data.runs):
                cols[start:start + r.n_eval, 2 * j + 1] = 1.0
                start += r.n_eval
            return cols

        cols = data.cache.get(("run_indicator", y_field.size), make).copy()
        ind = cols[:, 1::2]
        cols[:, 0::2] = ind * y_field[:, None]
        return cols

    def params(self, value, beta, path):
        gains = np.asarray(beta[0::2], dtype=float)
        offsets = np.asarray(beta[1::2], dtype=float)
        return {"gain_sd": float(np.std(gains, ddof=1)) if gains.size > 1 else 0.0,
                "offset_sd": float(np.std(offsets - np.mean(offsets), ddof=1)) if offsets.size > 1 else 0.0}


class Leakage(Effect):
    """The measured output integrates the input: ``rate_per_s · ∫u dt`` from the start of each run (trapezoids of
    the input, as a charge amplifier integrates a leakage current)."""

    name = "leakage"
    doc = "the measured output integrates the input: rate_per_s · ∫u dt from each run's start"
    needs_reidentify = True

    def columns(self, data, value, y_field, model):
        def make() -> np.ndarray:
            out = []
            for r in data.runs:
                u = _run_input(r)
                integral = np.concatenate([[0.0], np.cumsum(0.5 * r.dt_s * (u[1:] + u[:-1]))])
                out.append(integral[r.start:])
            return np.concatenate(out)[:, None]

        return data.cache.get("leakage_integral", make)

    def update_path(self, path, value, own_beta, data):
        return path.with_correction(self, value, own_beta)

    @staticmethod
    def remove(y, value, beta, run):
        u = run.current
        integral = np.concatenate([[0.0], np.cumsum(0.5 * run.dt * (u[1:] + u[:-1]))])
        return y - beta[0] * integral

    def params(self, value, beta, path):
        return {"rate_per_s": float(beta[0])}


class Accommodation(Effect):
    """Repeated minor loops drift towards the middle of the output range: the unit-``kappa`` shift of
    :func:`bmr._core.accommodation_shift` along the run (reversals beyond 1 % of the input span, saturation within
    0.2 %), linear in ``kappa`` for each ``cycles`` of the grid."""

    name = "accommodation"
    doc = "minor loops drift over repeated cycling: shift → −kappa·(loop centre − middle), settling in `cycles`"

    def grid(self, data: Any) -> list[Any]:
        return [0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0]

    def columns(self, data, value, y_field, model):
        lo, hi = model.hysteresis.input_range
        ylo, yhi = model.hysteresis.output_range
        span = hi - lo

        def make() -> np.ndarray:
            out = []
            for y, r in zip(_split(data, y_field), data.runs):
                u = np.ascontiguousarray(_run_input(r)[r.start:])
                out.append(_core.accommodation_shift(u, np.ascontiguousarray(y), kappa=1.0, cycles=float(value),
                                                     lo=lo, hi=hi, deadband=ACCOMMODATION_DEADBAND * span,
                                                     saturation_tol=ACCOMMODATION_SATURATION * span,
                                                     y_mid=0.5 * (ylo + yhi)))
            return np.concatenate(out)[:, None]

        return data.cache.get(("accommodation", float(value), _fingerprint(y_field)), make)

    def params(self, value, beta, path):
        return {"kappa": float(beta[0]), "cycles": float(value)}


MATERIAL: tuple[Effect, ...] = (Creep(), RateDependence(), RunGainOffset(), Leakage(), Accommodation())
