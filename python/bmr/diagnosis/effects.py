"""The effect library: each effect of the physical effect vocabulary (plus ``table_resolution``) as a parametric
extension of the nominal model.

Two families:

* **field effects** change the field path (:class:`bmr.diagnosis.field.FieldPath`) through one nonlinear
  parameter found by a 1-D search over a grid (``coil_lag``: time constant, ``time_delay``: delay,
  ``non_congruent``: output-map curvature) or by a refit (``table_resolution``: least-squares tables);
* **linear effects** add regressor columns, linear in their parameters given at most one nonlinear one
  (``thermal_drift``: thermal time constant, ``friction_harmonics``: harmonic order; ``friction_current``,
  ``torque_ripple``, ``sensor_drift`` have none).

Every effect has a stable ``name`` and reports its parameters with units in their names; ``params`` follow the
virtual actuator's parametrisation (``bmr.effect_parameters()``) so a simulated truth can be compared.

Linear effects that also bent the protocol runs implement ``update_path`` (the path re-identified with the
fitted effect removed) and ``remove(y, value, beta, protocol_run)``, which takes a
:class:`bmr.diagnosis.field.ProtocolRun` (signals, the nominal friction, the diagnosis's evaluation data). Column
builders read the signals the diagnosis prepared once (``data.theta``, ``data.current``, ``data.t_abs``,
``data.friction_nmm``) and keep what they derive in ``data.cache`` (bounded, owned by the diagnosis).
"""
from __future__ import annotations

import math
from abc import ABC, abstractmethod
from typing import Any

import numpy as np

from bmr import _core
from bmr._core import BmrError
from bmr.diagnosis.field import REIDENTIFY_INTERVALS, FieldPath
from bmr.diagnosis.residuals import EvalData

__all__ = ["Effect", "LIBRARY", "PHYSICAL", "thermal_state"]


class Effect(ABC):
    """Base class: ``name``, ``field`` (True for field effects), ``grid(data)`` of the nonlinear parameter
    (``[None]`` when there is none)."""

    name = ""
    field = False
    doc = ""
    needs_reidentify = False  # the effect needs least-squares core tables (compare against those)
    # Order in which fitted effects are removed from the protocol runs before re-identification: additive terms
    # (rank 0) before multiplicative gains (rank 1).
    removal_rank = 0

    def grid(self, data: EvalData) -> list[Any]:
        return [None]

    # Field effects (``field = True``) change the field path and implement ``apply``; linear effects add
    # regression columns and implement ``columns``. Asking one kind for the other's method is a dispatch error.
    def apply(self, path: FieldPath, value: Any, data: EvalData, train: np.ndarray | None) -> FieldPath:
        raise TypeError(f"{self.name} is a linear effect: it adds columns, it does not change the field path")

    # linear effects: columns over the evaluated spans, concatenated over runs (n_eval × p)
    def columns(self, data: EvalData, value: Any, y_field: np.ndarray, model: Any) -> np.ndarray:
        raise TypeError(f"{self.name} is a field effect: it changes the field path, it adds no columns")

    @abstractmethod
    def params(self, value: Any, beta: np.ndarray, path: FieldPath) -> dict[str, float]:
        """The effect's parameters (named with units) from its nonlinear value, fitted ``beta`` and path."""

    def update_path(self, path: FieldPath, value: Any, own_beta: np.ndarray, data: EvalData
                    ) -> FieldPath | None:
        """The field path re-identified with this effect's fitted parameters removed from the protocol runs
        (None: the effect leaves the tables alone)."""
        return None

    def refine(self) -> bool:
        """Whether the nonlinear parameter is continuous (refined by a golden-section search)."""
        return False


# ------------------------------------------------------------------------------------------------ field effects
class CoilLag(Effect):
    name = "coil_lag"
    field = True
    doc = "field lags the commanded current: first-order lag of time constant tau_s"

    def grid(self, data: EvalData) -> list[Any]:
        return [float(v) for v in np.geomspace(5e-4, 2.0, 22)]

    needs_reidentify = True

    def apply(self, path, value, data, train):
        # Tables cut from first-order curves of a lagged current are inconsistent; identify them by least squares.
        return path.with_(lag_tau_s=float(value), reidentify=True)

    def params(self, value, beta, path):
        return {"tau_s": float(path.lag_tau_s)}

    def refine(self) -> bool:
        return True


class TimeDelay(Effect):
    name = "time_delay"
    field = True
    doc = "pure delay of delay_s between the command and the field"

    def grid(self, data: EvalData) -> list[Any]:
        dt = min(r.dt_s for r in data.runs)
        # Every whole sample up to 40, then geometric up to 0.5 s.
        samples = np.unique(np.concatenate([np.arange(1, 41),
                                            np.round(np.geomspace(40, max(41.0, 0.5 / dt), 10))]).astype(int))
        return [float(k * dt) for k in samples]

    needs_reidentify = True

    def apply(self, path, value, data, train):
        return path.with_(delay_s=float(value), reidentify=True)

    def params(self, value, beta, path):
        return {"delay_s": float(path.delay_s)}


class NonCongruent(Effect):
    name = "non_congruent"
    field = True
    doc = "output nonlinearity after a Preisach core: T = S n (1 + curvature |n|)/(1 + curvature), n = B-torque/S"

    def grid(self, data: EvalData) -> list[Any]:
        return [-0.4, -0.3, -0.2, -0.12, -0.06, 0.06, 0.12, 0.2, 0.35, 0.5, 0.75, 1.0, 1.5, 2.2, 3.2, 4.5]

    def apply(self, path, value, data, train):
        return path.with_(curvature=float(value))

    def params(self, value, beta, path):
        return {"curvature": float(path.curvature), "scale_nmm": float(path.scale_nmm)}

    def refine(self) -> bool:
        return True


class TableResolution(Effect):
    """Not physics: the first-order curve tables are too coarse or too noisy. Fixed by identifying the tables
    again from the same protocol runs by nonnegative, smoothness-regularised least squares (``fit_everett``):
    the whole Preisach plane from every sample instead of interpolation between a few measured curves."""

    name = "table_resolution"
    field = True
    doc = "first-order curve tables too coarse or noisy; least-squares refinement of the tables"

    def apply(self, path, value, data, train):
        return path.with_(reidentify=True)

    def params(self, value, beta, path):
        return {"n_intervals": float(REIDENTIFY_INTERVALS)}


# ----------------------------------------------------------------------------------------------- linear effects
def bundle_thermal_state(data: EvalData, tau_s: float) -> list[np.ndarray]:
    """Coil heating state (1 = steady full current) of every run of the bundle, in bundle order:
    ``x' = ((I/I_full)² − x)/tau`` integrated over the runs in order (the actuator's state carries over); the
    core's heating filter (``bmr._core.heating_state``), the one the plant and the compensator step."""

    def make() -> list[np.ndarray]:
        states = []
        x0 = 0.0
        for u, dt in zip(data.bundle_currents, data.bundle_dt_s):
            x = _core.heating_state(np.asarray(u, float), tau_s, dt, data.full_current_a, initial=x0)
            states.append(x)
            x0 = float(x[-1]) if x.size else x0
        return states

    return data.cache.get(("thermal_all", tau_s), make)


def thermal_state(data: EvalData, tau_s: float) -> np.ndarray:
    """Coil heating state (1 = steady full current) over the evaluated spans: ``x' = ((I/I_full)² − x)/tau``
    integrated over every run of the bundle in order (the actuator's state carries over)."""

    def make() -> np.ndarray:
        states = bundle_thermal_state(data, tau_s)
        return data.concat([states[r.thermal_index][r.start:] for r in data.runs])

    return data.cache.get(("thermal", tau_s), make)


def _angle_harmonic(data: EvalData, order: Any) -> tuple[np.ndarray, np.ndarray]:
    """``sin(order·θ)``, ``cos(order·θ)`` over the evaluated spans (computed once per order)."""
    return data.cache.get(("angle_harmonic", order), lambda: (np.sin(order * data.theta), np.cos(order * data.theta)))


class ThermalDrift(Effect):
    name = "thermal_drift"
    doc = "coil heating lowers the torque gain: field × (1 − gain_loss·x), x the heating state of time constant tau_s"
    removal_rank = 1

    def grid(self, data: EvalData) -> list[Any]:
        return [float(v) for v in np.geomspace(3.0, 3000.0, 16)]

    needs_reidentify = True

    def columns(self, data, value, y_field, model):
        x = thermal_state(data, float(value))
        return np.column_stack([-x * y_field, y_field])

    def update_path(self, path, value, own_beta, data):
        # Heating also changed the gain along the protocol runs: identify the tables again without it.
        return path.with_correction(self, float(value), own_beta)

    @staticmethod
    def remove(y, value, beta, run):
        if run.context is None or run.bundle_index is None:
            raise BmrError(f"protocol run {run.name!r}: the heating state needs the bundle's evaluation data")
        x = bundle_thermal_state(run.context, float(value))[run.bundle_index]
        # Only the heating is undone, relative to cold coils: the fitted field gain ``1 + beta[1]`` is the
        # tables' own error (identified warm) and belongs in the re-identified tables, which are cold.
        return y / np.maximum(1.0 - ThermalDrift._gain_loss(beta) * x, 1e-3)

    @staticmethod
    def _gain_loss(beta: Any) -> float:
        """Fractional gain loss at unit heating from the fitted ``field × (1 + beta[1] − beta[0]·x)``."""
        return float(beta[0] / (1.0 + beta[1]))

    def params(self, value, beta, path):
        return {"gain_loss": self._gain_loss(beta), "tau_s": float(value)}

    def refine(self) -> bool:
        return True


class FrictionCurrent(Effect):
    name = "friction_current"
    doc = "seal friction grows with current: angle-dependent friction × (1 + gain_per_a·|I|)"

    def columns(self, data, value, y_field, model):
        def make() -> np.ndarray:
            c0 = model.friction.c0 if model.friction is not None else 0.0
            return (np.abs(data.current) * (data.friction_nmm - c0))[:, None]

        return data.cache.get("friction_current_cols", make)

    needs_reidentify = True

    def update_path(self, path, value, own_beta, data):
        return path.with_correction(self, value, own_beta)

    @staticmethod
    def remove(y, value, beta, run):
        c0 = run.model.friction.c0 if run.model.friction is not None else 0.0
        return y - beta[0] * np.abs(run.current) * (run.friction() - c0)

    def params(self, value, beta, path):
        return {"gain_per_a": float(beta[0])}


class FrictionHarmonics(Effect):
    name = "friction_harmonics"
    doc = "a friction harmonic above the 3rd: amplitude_nmm·sin(order·θ + phase_rad)"

    def grid(self, data: EvalData) -> list[Any]:
        return list(range(4, 13))

    def columns(self, data, value, y_field, model):
        return np.column_stack(_angle_harmonic(data, value))

    needs_reidentify = True

    def update_path(self, path, value, own_beta, data):
        return path.with_correction(self, value, own_beta)

    @staticmethod
    def remove(y, value, beta, run):
        th = run.theta
        return y - beta[0] * np.sin(value * th) - beta[1] * np.cos(value * th)

    def params(self, value, beta, path):
        return {"order": float(value), "amplitude_nmm": float(math.hypot(beta[0], beta[1])),
                "phase_rad": float(math.atan2(beta[1], beta[0]))}


class TorqueRipple(Effect):
    name = "torque_ripple"
    doc = "eccentric gap: field × (1 + eps·cos(θ + phase_rad))"
    removal_rank = 1

    def columns(self, data, value, y_field, model):
        s, c = _angle_harmonic(data, 1)
        return np.column_stack([y_field * c, y_field * s])

    needs_reidentify = True

    def update_path(self, path, value, own_beta, data):
        return path.with_correction(self, value, own_beta)

    @staticmethod
    def remove(y, value, beta, run):
        th = run.theta
        return y / np.maximum(1.0 + beta[0] * np.cos(th) + beta[1] * np.sin(th), 1e-3)

    def params(self, value, beta, path):
        return {"eps": float(math.hypot(beta[0], beta[1])), "phase_rad": float(math.atan2(-beta[1], beta[0]))}


class SensorDrift(Effect):
    name = "sensor_drift"
    doc = "torque sensor offset drifting linearly with time at rate_nmm_per_s"

    needs_reidentify = True

    def columns(self, data, value, y_field, model):
        return data.t_abs[:, None]

    def update_path(self, path, value, own_beta, data):
        # The drift also bent the protocol runs the tables come from: identify them again without it.
        return path.with_correction(self, value, own_beta)

    @staticmethod
    def remove(y, value, beta, run):
        return y - beta[0] * (run.t0_s + run.t - run.t[0])

    def params(self, value, beta, path):
        return {"rate_nmm_per_s": float(beta[0])}


LIBRARY: tuple[Effect, ...] = (CoilLag(), ThermalDrift(), FrictionCurrent(), FrictionHarmonics(), TorqueRipple(),
                               SensorDrift(), TimeDelay(), NonCongruent(), TableResolution())
PHYSICAL = tuple(e.name for e in LIBRARY if e.name != "table_resolution")
