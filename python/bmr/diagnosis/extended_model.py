"""The nominal model plus accepted effects: simulate, save (``model.extensions``) and compensate.

The extended torque of a run is

``T = g(H(lag(delay(I)))) · (1 − gain_loss·x + thermal_gain) · (1 + ripple(θ)) + F(θ) + extra friction(θ, I)
+ offset + drift·t``

where each factor is present only when its effect was accepted (:mod:`bmr.diagnosis.effects`). The
extensions are stored in the model file as ``{"name", "params"}`` entries (plus ``{"name": "offset"}`` for the
fitted constant), so a loaded model reproduces the extended simulation.

The extended compensator wraps :class:`bmr.Compensator` and applies the effect inverses where they act in the
loop: the friction feedforward gets the extra harmonic and the current-dependent friction, the field torque
target is divided by the ripple and thermal gains, ``non_congruent`` maps it through ``g⁻¹`` onto the core's
tables, ``coil_lag`` puts an exact lead on the current command and ``time_delay`` commands the reference
``delay`` ahead (the reference is known in advance in a tracking run). Sensor drift and the offset are
measurement effects and stay out of the loop.
"""
from __future__ import annotations

import copy
import math
from typing import Any, Sequence

import numpy as np

from bmr._core import BmrError, Compensator
from bmr.diagnosis.field import FieldPath, delay, lead, output_map_inverse

__all__ = ["ExtendedModel", "ExtendedCompensator", "extensions_from_selection"]

KNOWN = ("coil_lag", "thermal_drift", "friction_current", "friction_harmonics", "torque_ripple", "sensor_drift",
         "time_delay", "non_congruent", "table_resolution", "offset", "core_tables")


def extensions_from_selection(config: Any, accepted: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """``model.extensions`` entries of a selected configuration (refined tables stored with their effect)."""
    out = []
    for row in accepted:
        out.append({"name": row["name"], "params": {k: float(v) for k, v in row["params"].items()}})
    path = config.path
    if path.tables is not None or path.reidentify or path.lag_tau_s > 0 or path.delay_s > 0 or path.curvature != 0:
        # The Preisach core's own tables (refined, or re-identified under the field effects).
        asc, desc = path.core_curves()
        out.append({"name": "core_tables", "params": {},
                    "tables": {"ascending": [[list(map(float, u)), list(map(float, y))] for u, y in asc],
                               "descending": [[list(map(float, u)), list(map(float, y))] for u, y in desc]}})
    out.append({"name": "offset", "params": {"offset_nmm": float(config.beta[0])}})
    return out


class ExtendedModel:
    """A ``bmr.Model`` whose ``extensions`` are applied by :meth:`simulate` and :meth:`compensator`.

    ``full_current_a``: the current of the thermal model's unit heating (default: the model's current limit).
    """

    def __init__(self, model: Any) -> None:
        self.model = model
        for e in model.extensions:
            if e.get("name") not in KNOWN:
                raise BmrError(f"model extension {e.get('name')!r} is unknown; known: {', '.join(KNOWN)}")
        self.ext = {e["name"]: e for e in model.extensions}
        lo, hi = model.limits["current_a"]
        self.full_current_a = max(abs(lo), abs(hi))
        p = self.params("non_congruent")
        tables = None
        tr = self.ext.get("core_tables", {}).get("tables")
        if tr:
            tables = ([(np.asarray(u), np.asarray(y)) for u, y in tr["ascending"]],
                      [(np.asarray(u), np.asarray(y)) for u, y in tr["descending"]])
        ylo, yhi = model.hysteresis.output_range
        self.path = FieldPath(model, lag_tau_s=self.params("coil_lag").get("tau_s", 0.0),
                              delay_s=self.params("time_delay").get("delay_s", 0.0),
                              curvature=p.get("curvature", 0.0), tables=tables,
                              scale_nmm=p.get("scale_nmm", float(max(abs(ylo), abs(yhi), 1e-9))))

    def params(self, name: str) -> dict[str, float]:
        return dict(self.ext.get(name, {}).get("params", {}))

    @property
    def names(self) -> list[str]:
        return [e["name"] for e in self.model.extensions if e["name"] not in ("offset", "core_tables")]

    def thermal_state(self, current_a: np.ndarray, dt_s: float, x0: float = 0.0) -> np.ndarray:
        """Heating state (1 = steady full current) along ``current_a``, from ``x0``."""
        p = self.params("thermal_drift")
        u = np.asarray(current_a, float)
        if not p:
            return np.zeros(u.size)
        from scipy.signal import lfilter

        a = math.exp(-dt_s / p["tau_s"])
        x, _ = lfilter([1.0 - a], [1.0, -a], (u / self.full_current_a) ** 2, zi=[a * x0])
        return x

    def field_gain(self, theta_rad: np.ndarray, thermal_x: np.ndarray) -> np.ndarray:
        """Multiplicative gain of the field torque (thermal loss and ripple)."""
        g = np.ones(np.shape(theta_rad))
        p = self.params("thermal_drift")
        if p:
            g = g * (1.0 - p["gain_loss"] * thermal_x)
        r = self.params("torque_ripple")
        if r:
            g = g * (1.0 + r["eps"] * np.cos(theta_rad + r["phase_rad"]))
        return g

    def friction(self, theta_rad: np.ndarray, current_a: np.ndarray) -> np.ndarray:
        """Seal friction (N·mm) with the extra harmonic and the current-dependent growth."""
        th = np.asarray(theta_rad, float)
        base = self.model.friction_torque(th)
        c0 = self.model.friction.c0 if self.model.friction is not None else 0.0
        ripple = base - c0
        h = self.params("friction_harmonics")
        if h:
            ripple = ripple + h["amplitude_nmm"] * np.sin(h["order"] * th + h["phase_rad"])
        fc = self.params("friction_current")
        if fc:
            ripple = ripple * (1.0 + fc["gain_per_a"] * np.abs(current_a))
        return c0 + ripple

    def simulate(self, current_a: Any, theta_rad: Any, *, dt_s: float, t0_s: float = 0.0,
                 thermal_x0: float = 0.0, measured: bool = True) -> np.ndarray:
        """Torque (N·mm) for commanded current (A) and angle (rad) sampled every ``dt_s``; ``measured`` adds the
        sensor terms (offset and drift from bundle time ``t0_s``)."""
        u = np.ascontiguousarray(current_a, dtype=float)
        th = np.asarray(theta_rad, dtype=float)
        if u.ndim != 1 or th.shape != u.shape:
            raise BmrError(f"current and theta must be 1-D of one length (got {u.shape} and {th.shape})")
        if not np.all(np.isfinite(u)):
            raise BmrError(f"current sample {int(np.flatnonzero(~np.isfinite(u))[0])} is not finite")
        (y,) = self.path.simulate([_Signal(u, dt_s)])
        x = self.thermal_state(u, dt_s, thermal_x0)
        t = self.field_gain(th, x) * y + self.friction(th, u)
        if measured:
            t = t + self.params("offset").get("offset_nmm", 0.0)
            d = self.params("sensor_drift")
            if d:
                t = t + d["rate_nmm_per_s"] * (t0_s + dt_s * np.arange(u.size))
        return t

    def compensator(self, *, dt_s: float, **kwargs: Any) -> "ExtendedCompensator":
        return ExtendedCompensator(self, dt_s=dt_s, **kwargs)


class _Signal:
    def __init__(self, current_a: np.ndarray, dt_s: float) -> None:
        self.current_a = current_a
        self.dt_s = dt_s


class ExtendedCompensator:
    """Open-loop compensator of an extended model (see the module doc); ``run`` has the ``bmr.Compensator``
    signature and returns its dict (``current_a`` after the lead, limited)."""

    def __init__(self, ext: ExtendedModel, *, dt_s: float, inverse: str = "exact") -> None:
        self.ext = ext
        self.dt_s = float(dt_s)
        lo, hi = ext.model.limits["current_a"]
        self.current_limit = max(abs(lo), abs(hi))
        self._core = Compensator(ext.path.hysteresis(), None, inverse=inverse,
                                 converter_gain=ext.model.converter_gain_a_per_v, current_limit=self.current_limit)

    def run(self, torque_ref_nmm: Any, theta_rad: Any) -> dict[str, np.ndarray]:
        ref = np.asarray(torque_ref_nmm, dtype=float)
        th = np.asarray(theta_rad, dtype=float)
        if ref.shape != th.shape or ref.ndim != 1:
            raise BmrError(f"torque_ref_nmm and theta_rad must be 1-D of one length (got {ref.shape}, {th.shape})")
        ext = self.ext
        d = int(round(ext.params("time_delay").get("delay_s", 0.0) / self.dt_s))
        if d > 0:
            # Command now what must act d samples later (the reference is known ahead; hold the last value).
            ref_ahead = np.concatenate([ref[d:], np.full(min(d, ref.size), ref[-1])])[: ref.size]
            th_ahead = np.concatenate([th[d:], th[-1] + (th[-1] - th[-2] if th.size > 1 else 0.0)
                                       * np.arange(1, min(d, th.size) + 1)])[: th.size]
        else:
            ref_ahead, th_ahead = ref, th
        current = np.zeros(ref.size)
        out: dict[str, np.ndarray] = {}
        for _ in range(2):  # second pass: friction growth and heating from the first pass's currents
            x = ext.thermal_state(delay(current, d * self.dt_s, self.dt_s), self.dt_s)
            x_ahead = np.concatenate([x[d:], np.full(min(d, x.size), x[-1])])[: x.size] if d > 0 else x
            field_ref = (ref_ahead - ext.friction(th_ahead, current)) / np.maximum(
                ext.field_gain(th_ahead, x_ahead), 1e-3)
            core_ref = output_map_inverse(field_ref, ext.path.curvature, ext.path.scale_nmm)
            self._core.reset(initial="negative")
            out = self._core.run(core_ref, th_ahead)
            current = np.asarray(out["current_a"], dtype=float)
        tau = ext.params("coil_lag").get("tau_s", 0.0)
        cmd = np.clip(lead(current, tau, self.dt_s), -self.current_limit, self.current_limit)
        result = dict(out)
        result["current_a"] = cmd
        result["saturated"] = np.asarray(out["saturated"], dtype=bool) | (np.abs(cmd) >= self.current_limit)
        return result


def with_extensions(model: Any, extensions: Sequence[dict[str, Any]]) -> Any:
    """A copy of ``model`` carrying ``extensions`` (the file format keeps them)."""
    m = copy.copy(model)
    m.extensions = [dict(e) for e in extensions]
    m.meta = dict(model.meta)
    return m

