"""Reference controllers the compensator is measured against: the linear current↔torque map of a controller that
ignores hysteresis, with or without the friction feedforward (paper figs 18-19). Same ``run`` interface as
:class:`bmr.Compensator`."""
from __future__ import annotations

from typing import Any

import numpy as np

from bmr._core import BmrError


class LinearCompensator:
    """``I = (T_ref − T_f(θ)) / K``, clipped to ``±current_limit`` (A). ``gain_nmm_per_a`` is the secant slope K
    of the torque map (N·mm/A); ``friction`` any callable on angles (rad) → N·mm, or None."""

    def __init__(self, gain_nmm_per_a: float, friction: Any = None, *, current_limit: float = 1.25) -> None:
        if not (np.isfinite(gain_nmm_per_a) and gain_nmm_per_a > 0):
            raise BmrError(f"gain_nmm_per_a must be positive and finite, got {gain_nmm_per_a!r}")
        if not (np.isfinite(current_limit) and current_limit > 0):
            raise BmrError(f"current_limit must be positive and finite, got {current_limit!r}")
        self.gain_nmm_per_a = float(gain_nmm_per_a)
        self.friction = friction
        self.current_limit = float(current_limit)

    @classmethod
    def from_hysteresis(cls, hysteresis: Any, friction: Any = None, **kwargs: Any) -> "LinearCompensator":
        """Secant of the major loop: output span over input span."""
        (lo, hi), (ylo, yhi) = hysteresis.input_range, hysteresis.output_range
        return cls((yhi - ylo) / (hi - lo), friction, **kwargs)

    def run(self, torque_ref_nmm: Any, theta_rad: Any) -> dict[str, np.ndarray]:
        ref = np.asarray(torque_ref_nmm, dtype=float)
        theta = np.asarray(theta_rad, dtype=float)
        if ref.shape != theta.shape:
            raise BmrError(f"torque_ref_nmm has shape {ref.shape} but theta_rad has {theta.shape}")
        target = ref - (self.friction(theta) if self.friction is not None else 0.0)
        current = np.clip(target / self.gain_nmm_per_a, -self.current_limit, self.current_limit)
        current = np.where(np.isfinite(current), current, 0.0)
        return {"current_a": current, "coil1_a": np.maximum(-current, 0.0), "coil2_a": np.maximum(current, 0.0)}
