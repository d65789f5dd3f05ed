"""The nominal model plus accepted effects: simulate, save (``model.extensions``) and compensate.

The extended torque of a run is

``T = g(H(lag(delay(I)))) · (1 − gain_loss·x) · (1 + eps cos(θ + φ)) + F(θ, |I_field|) + offset + drift·t``

where each factor is present only when its effect was accepted (:mod:`bmr.diagnosis.effects`). With a heating
the core's stored tables count from zero field torque (the middle of the major loop, about which the heating
scales the field torque; the level the identification started from is in the friction's mean ``F``), unless an
output map ``g``, a mean field or the gap ripple reads them on the level they were identified on. The
extensions are stored in the model file as ``{"name", "params"}`` entries (plus ``core_tables`` with the core's
curves and ``offset`` for the fitted constant), so a loaded model reproduces the extended simulation.

Both directions run in the core: :meth:`ExtendedModel.simulate` is ``bmr.ExtendedSimulation`` (the forward
chain of stages) and :meth:`ExtendedModel.compensator` is ``bmr.Compensator`` built from the same model
(``Model.compensator``), which walks the same stages backwards. Sensor drift and the offset are measurement
effects and stay out of the loop.
"""
from __future__ import annotations

import copy
import dataclasses
import math
from typing import Any, Sequence

import numpy as np

from bmr._core import check_extensions, effect_parameters
from bmr.diagnosis.effects import field_zero
from bmr.identification.extended import extended_simulation, learned_term, simulate_extended

__all__ = ["ExtendedModel", "extensions_from_selection", "learned_term", "stored_zero", "with_extensions"]


def _clip(value: float, param: dict[str, Any]) -> float:
    """``value`` moved to the nearest value the vocabulary accepts for ``param`` (its range; away from the gap
    above 0 of a parameter whose 0 means "automatic")."""
    v = min(max(value, param["min"]), param["max"])
    smallest = param.get("smallest_nonzero", 0.0)
    if v != 0.0 and abs(v) < smallest:
        v = math.copysign(smallest, v)
    return v


def extensions_from_selection(config: Any, accepted: Sequence[dict[str, Any]], zero: float = 0.0
                              ) -> list[dict[str, Any]]:
    """``model.extensions`` entries of a selected configuration (refined tables stored with their effect, counted
    from ``zero``: :func:`stored_zero`, which the model's friction then takes back in :func:`with_extensions`)."""
    out = []
    specs = effect_parameters(model_entries=True)
    for row in accepted:
        params = {k: float(v) for k, v in row["params"].items()}
        entry: dict[str, Any] = {"name": row["name"], "params": params}
        # A fit outside the vocabulary's physical range (a negative creep fraction, say) is kept as fitted and
        # stored clipped, so the model file stays valid.
        spec = specs.get(row["name"], {}).get("params", {})
        clipped = {k: _clip(v, spec[k]) for k, v in params.items() if k in spec}
        if any(clipped[k] != params[k] for k in clipped):
            entry["params"] = {**params, **clipped}
            entry["params_fitted"] = params
        out.append(entry)
    path = config.path
    if (path.tables is not None or path.reidentify or path.lag_tau_s > 0 or path.delay_s > 0 or path.curvature != 0
            or path.cubic != 0):
        # The Preisach core's own tables (refined, or re-identified under the field effects), counted from the
        # field torque's zero when a heating scales about it (``stored_zero``).
        asc, desc = path.core_curves()
        out.append({"name": "core_tables", "params": {},
                    "tables": {side: [[list(map(float, u)), list(map(float, np.asarray(y, dtype=float) - zero))]
                                      for u, y in curves]
                               for side, curves in (("ascending", asc), ("descending", desc))}})
    out.append({"name": "offset", "params": {"offset_nmm": float(config.beta[0])}})
    return out


def stored_zero(config: Any, accepted: Sequence[dict[str, Any]]) -> float:
    """The level the stored core tables count from, in the tables' output: the field torque's zero
    (``field_zero``) when a heating was accepted, which scales the field torque about it, and the model has a
    friction, whose mean then takes the level back (the tables were identified from the state the identification
    started in, whose torque the friction's mean absorbed: it belongs to the torque the compensator produces, not
    to the sensor's offset); 0 (the tables as identified) otherwise, and when a stage reads the tables on the level
    they were identified on: an output map or a mean field (fitted there) or the gap ripple (scaling about that
    level: the friction holds the remanence's ripple)."""
    path = config.path
    names = {row["name"] for row in accepted}
    if ("thermal_drift" not in names or "torque_ripple" in names or path.curvature != 0 or path.cubic != 0
            or path.feedback != 0 or path.model.friction is None):
        return 0.0
    return field_zero(path.model)


class ExtendedModel:
    """A ``bmr.Model`` whose ``extensions`` are applied by :meth:`simulate` and :meth:`compensator` (both in the
    core). The thermal model's unit heating is the model's current limit."""

    def __init__(self, model: Any) -> None:
        self.model = model

    def params(self, name: str) -> dict[str, float]:
        """Parameters of extension ``name`` (defaults filled in; {} when the model does not have it)."""
        return self.model.extension_params(name)

    @property
    def names(self) -> list[str]:
        return [e["name"] for e in self.model.extensions if e["name"] not in ("offset", "core_tables")]

    def simulation(self, dt_s: float) -> Any:
        """The forward chain as a ``bmr.ExtendedSimulation`` at sample period ``dt_s``."""
        return extended_simulation(self.model, dt_s)

    def simulate(self, current_a: Any, theta_rad: Any, *, dt_s: float, t0_s: float = 0.0,
                 thermal_x0: float = 0.0, measured: bool = True) -> np.ndarray:
        """Torque (N·mm) for commanded current (A) and angle (rad) sampled every ``dt_s``, from negative
        saturation with heating state ``thermal_x0``; ``measured`` adds the sensor terms (offset and drift from
        bundle time ``t0_s``)."""
        return simulate_extended(self.model, current_a, theta_rad, dt_s=dt_s, t0_s=t0_s, heating=thermal_x0,
                                 measured=measured)

    def compensator(self, *, dt_s: float, **kwargs: Any) -> Any:
        """The extended ``bmr.Compensator`` (``Model.compensator``; by default every stage: ``stages="all"``)."""
        kwargs.setdefault("stages", "all")
        return self.model.compensator(dt_s, **kwargs)


def with_extensions(model: Any, extensions: Sequence[dict[str, Any]], *, zero: float = 0.0) -> Any:
    """A copy of ``model`` carrying ``extensions`` (the file format keeps them); ``zero``: the level its stored core
    tables count from (``stored_zero``), added back to the friction's mean."""
    m = copy.copy(model)
    check_extensions(list(extensions))
    m.extensions = [dict(e) for e in extensions]
    m.meta = dict(model.meta)
    if zero != 0.0:
        m.friction = dataclasses.replace(model.friction, c0=float(model.friction.c0) + zero)
    return m

