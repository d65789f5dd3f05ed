"""The forward run of a model with its extensions (what ``bmr diagnose --model-out`` added): the Rust
``bmr.ExtendedSimulation`` chain of stages, plus the learned discrepancy term. Prediction and the diagnosis's
extended model both run a model this way."""
from __future__ import annotations

from typing import Any

import numpy as np

from bmr._core import BmrError, ExtendedSimulation

__all__ = ["INTERNAL", "extended_simulation", "learned_term", "simulate_extended", "parts"]

# Entries of a model's extensions that are not stages: the refined core's tables and the fitted output offset.
INTERNAL = ("core_tables", "offset")


def parts(model: Any) -> list[str]:
    """What a forward run of ``model`` runs, in words: the core tables (refined when the model has them), each
    stage and the learned term, and the offset."""
    names = [e["name"] for e in model.extensions]
    out = ["core tables (refined)" if "core_tables" in names else "core tables"]
    out += [n for n in names if n not in INTERNAL]
    return out + (["offset"] if "offset" in names else [])


def extended_simulation(model: Any, dt_s: float) -> Any:
    """The forward chain of ``model`` as a ``bmr.ExtendedSimulation`` at sample period ``dt_s`` (s)."""
    friction = model.friction.to_friction() if model.friction is not None else None
    return ExtendedSimulation(model.core_hysteresis(forward=True), friction, extensions=model.extensions, dt_s=dt_s,
                              full_current_a=model.full_current_a, full_torque_nmm=model.full_torque_nmm)


def simulate_extended(model: Any, u: Any, theta: Any, *, dt_s: float, t0_s: float = 0.0, heating: float = 0.0,
                      measured: bool = True, initial: Any = None) -> np.ndarray:
    """The output of ``model`` with its extensions for input ``u`` and angle ``theta`` (rad; zeros for a device
    without one) sampled every ``dt_s`` from bundle time ``t0_s``; ``measured`` adds the sensor terms (offset,
    drift) and the learned term. ``initial``: the core's starting state (default negative saturation)."""
    u = np.ascontiguousarray(u, dtype=float)
    th = np.ascontiguousarray(theta, dtype=float)
    if u.ndim != 1 or th.shape != u.shape:
        raise BmrError(f"input and angle must be 1-D of one length (got {u.shape} and {th.shape})")
    out = extended_simulation(model, dt_s).run(u, th, heating=heating, t0_s=t0_s, initial=initial)
    y = out["measured_nmm" if measured else "torque_nmm"]
    learned = model.extension("learned_discrepancy")
    if learned is not None and measured:
        y = y + learned_term(learned, u, y, th, dt_s)
    return y


def learned_term(entry: dict[str, Any], u: np.ndarray, y: np.ndarray, theta: np.ndarray | None, dt_s: float
                 ) -> np.ndarray:
    """The ``learned_discrepancy`` entry's term along a run (input ``u``, model output ``y``, angle, sample period):
    its intercept plus each signal of ``bmr._core.candidate_signals`` times its coefficient."""
    from bmr._core import CANDIDATES, candidate_signals

    names = [c[0] for c in CANDIDATES]
    harmonics = max((int(t["name"][4:].split("θ")[0]) for t in entry.get("terms", [])
                     if t["name"].startswith(("sin(", "cos("))), default=0)
    lib = candidate_signals(np.arange(u.size) * dt_s, u, y, deadband=float(entry["deadband"]),
                            theta_rad=theta if harmonics else None, harmonics=harmonics)
    for k in range(1, harmonics + 1):
        names += [f"sin({k}θ)", f"cos({k}θ)"]
    out = np.full(u.size, float(entry.get("intercept", 0.0)))
    for t in entry.get("terms", []):
        if t["name"] not in names:
            raise BmrError(f"learned_discrepancy: unknown signal {t['name']!r}")
        out += float(t["coefficient"]) * lib[:, names.index(t["name"])]
    return out
