"""The effect library: each effect of the physical effect vocabulary (plus ``table_resolution``) as a parametric
extension of the nominal model.

Two families:

* **field effects** change the field path (:class:`bmr.diagnosis.field.FieldPath`) through one nonlinear
  parameter found by a 1-D search over a grid (``coil_lag``: time constant, ``time_delay``: delay,
  ``non_congruent``: output-map curvature) or by a refit (``table_resolution``: least-squares tables);
* **linear effects** add regressor columns, linear in their parameters given at most one nonlinear one (the
  heating's thermal time constant, the extra friction harmonic's order; the others have none).

The actuator's effects (seal friction, rotor ripple) need an angle (``needs_angle``, from the vocabulary); the
material and measurement effects any device can show need none (``rate_dependence`` is a field effect: the core
input lags with a time constant that follows the branch's slope). They read the evaluated spans run by run (``data.runs``: each run's full input, its first evaluated sample
``start`` and sample period ``dt_s``) and the configuration's field output over the evaluated spans.

States that carry over between runs get their initial value fitted with the effect: ``thermal_drift`` splits the
heating state into each run's own heating from cold coils and the heat carried over from the runs before, with the
carried share fitted (1 when the runs followed back to back, 0 when the rig rested long enough between them: the
rig's history is estimated, not assumed), and removes the protocol runs' heating with that share.

Every effect has a stable ``name`` and reports its parameters with units in their names; ``params`` follow the
virtual actuator's parametrisation (``bmr.effect_parameters()``) so a simulated truth can be compared.

Linear effects that also bent the protocol runs implement ``update_path`` (the path re-identified with the
fitted effect removed) and ``remove(y, value, beta, protocol_run)``, which takes a
:class:`bmr.diagnosis.field.ProtocolRun` (signals, the nominal friction, the diagnosis's evaluation data). Column
builders read the signals the diagnosis prepared once (``data.theta``, ``data.current``, ``data.t_abs``,
``data.friction_nmm``) and keep what they derive in ``data.cache`` (bounded, owned by the diagnosis).
"""
from __future__ import annotations

import copy
import math
from abc import ABC, abstractmethod
from typing import Any

import numpy as np

from bmr import _core
from bmr._core import BmrError
from bmr.diagnosis.field import REIDENTIFY_INTERVALS, FieldPath, steepest_slope
from bmr.diagnosis.residuals import EvalData, reversal_order

__all__ = ["Effect", "LIBRARY", "PHYSICAL", "ANGLE_EFFECTS", "thermal_state", "CREEP_TAUS_S"]


class Effect(ABC):
    """Base class: ``name``, ``field`` (True for field effects), ``grid(data)`` of the nonlinear parameter
    (``[None]`` when there is none)."""

    name = ""
    field = False
    doc = ""
    # The excitation whose response shows this effect's own signature (what to record when the data cannot tell
    # it from another effect).
    excitation = "a run with a different excitation"
    # The run of ``bmr simulate --separate`` that records that excitation on the virtual actuator (a key of
    # ``bmr.simulation.excitation.SEPARATING_RUNS``; None: none does).
    separating_run: str | None = None
    needs_reidentify = False  # the effect needs least-squares core tables (compare against those)
    # Order in which fitted effects are removed from the protocol runs before re-identification: additive terms
    # (rank 0) before multiplicative gains (rank 1).
    removal_rank = 0
    # A drive-scaled effect whose columns a per-run gain and offset partly reproduce (a recording with another
    # calibration looks like more or less seal friction): it is judged on what it explains
    # beyond the per-run calibration, so that structure the calibration explains is not named after it.
    beyond_run_calibration = False
    # Grid values that switch a part of the effect on or off (a yield force beside a viscous one): the fit on all
    # data ranks only the values whose parameters stay in the vocabulary's range, so an optional part fitted
    # against its physics (a negative yield force) is left off instead of making the whole effect unphysical.
    ranks_in_range = False
    # A linear effect whose grid values may re-identify the tables (``adjust_path``) while the configuration keeps
    # the measured curves' tables: folds that choose such a value are judged against the configuration on
    # least-squares tables, so that the gain is the effect's and not the table method's.
    gain_beyond_refitted_tables = False
    # A grid value the others extend by one more parameter (a drift that never settles, for the warm-up's settling
    # rate): the others are taken only where they predict the held-out blocks better than it in most folds, each
    # fold's fit its own (the training fit always prefers the extra parameter, and a settling drift fitted to a
    # line's training blocks predicted the piezo's held-out blocks worse: 0.0214 → 0.0266 µm).
    simplest: Any = None

    def value_in(self, config: Any, default: Any) -> Any:
        """This effect's grid value in ``config`` when it is the configuration's last linear effect (the candidate
        just fitted), else ``default``."""
        if config is not None and config.linear and config.linear[-1][0] is self:
            return config.linear[-1][1]
        return default

    @property
    def needs_angle(self) -> bool:
        """The effect lives on the rotor angle (seal friction, ripple): actuators only (the vocabulary says)."""
        return self.name in _core.ANGLE_EFFECTS

    def grid(self, data: EvalData) -> list[Any]:
        return [None]

    def grid_shape(self, data: EvalData) -> tuple[int, int] | None:
        """``(outer, inner)`` when ``grid(data)`` is the product of two axes listed outer-major (searched one axis
        at a time); None for a plain list."""
        return None

    def grid_families(self, data: EvalData) -> list[range] | None:
        """The stretches of ``grid(data)`` along each of which one continuous parameter runs in order (each searched
        coarse to fine on its own when the values are costly); None: the grid is one such stretch or no order."""
        return None

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

    def adjust_path(self, path: FieldPath, value: Any) -> FieldPath:
        """A linear effect whose nonlinear value also changes the field path (e.g. the correction of the
        protocol runs the tables come from) returns that path; the others leave it alone."""
        return path

    def update_path(self, path: FieldPath, value: Any, own_beta: np.ndarray, data: EvalData
                    ) -> FieldPath | None:
        """The field path re-identified with this effect's fitted parameters removed from the protocol runs
        (None: the effect leaves the tables alone)."""
        return None

    def refine(self) -> bool:
        """Whether the nonlinear parameter is continuous (refined by a golden-section search)."""
        return False

    def settle(self, path: FieldPath) -> FieldPath:
        """A field effect's path as it is judged and kept: its search ranks values on tables identified once, and
        the values chosen may need more (the rate dependence's slopes at their fixed point). Default: as is."""
        return path

    def along(self, a: Any, b: Any) -> tuple[float, float, Any] | None:
        """The line between grid values ``a`` and ``b`` the refinement searches: ``(x_a, x_b, value_of(x))``, or
        None when no continuous path joins them. Default: plain numbers."""
        if isinstance(a, (int, float)) and isinstance(b, (int, float)):
            return float(a), float(b), lambda x: x
        return None

    def outside_physics(self, path: FieldPath) -> list[str]:
        """Why a field effect's fitted path is unphysical beyond its parameters' documented ranges (a condition on
        the fitted tables as well), as ``"feedback=0.4 × steepest slope 3.1/A = 1.24 (must be below 1)"``; empty
        when it is physical. Checked where a candidate is accepted, with the ranges."""
        return []

    def acts_on(self, fitter: Any, values: Any = None) -> np.ndarray | None:
        """The evaluated samples the mechanism acts on, when it acts on part of them only (None: on all): its
        held-out gain must then be consistent over the folds on those samples (elsewhere it has nothing to
        explain), and positive on all of them. ``values``: the grid values the folds chose, when known."""
        return None

    # signature_missing reads the configuration without the effect only (not ``after``): it is checked before the
    # candidate's grid is searched, and a candidate without its signature is not evaluated (it could be neither
    # named nor an alternative to another).
    signature_before_only = False

    def signature_missing(self, fitter: Any, before: Any, after: Any) -> str:
        """Why the residual of the configuration ``before`` (without this effect) does not show the effect's own
        mechanism signature, or the configuration ``after`` (``before`` plus this effect fitted on all data: its
        columns last in ``after.linear``, their coefficients last in ``after.beta``) contradicts it ("" when it
        does, or when the effect checks none beyond its held-out gain and range)."""
        return ""

    def without_signature(self) -> "Effect | None":
        """The effect narrowed to the forms whose mechanism its signature does not test, searched when that
        signature is missing (None: it has no such forms)."""
        return None


# ------------------------------------------------------------------------------------------------ field effects
class CoilLag(Effect):
    name = "coil_lag"
    excitation = "input steps held long enough to see the approach (a first-order lag relaxes, a delay shifts)"
    separating_run = "dwell"
    field = True
    doc = "field lags the commanded current: first-order lag of time constant tau_s"

    def grid(self, data: EvalData) -> list[Any]:
        return [float(v) for v in np.geomspace(5e-4, 2.0, 22)]

    needs_reidentify = True

    def apply(self, path, value, data, train):
        # Tables cut from first-order curves of a lagged current are inconsistent; identify them by least squares.
        # A lag trails a ramp by its time constant, as a delay does: a delay fitted before it took that shift too,
        # and keeps only what the lag leaves (whole samples), so that the two together shift ramps as before.
        tau = float(value)
        delay = path.delay_s
        if delay > 0.0:
            dt = min(r.dt_s for r in data.runs)
            delay = max(0.0, round((delay - tau) / dt) * dt)
        return path.with_(lag_tau_s=tau, delay_s=delay, reidentify=True)

    def params(self, value, beta, path):
        return {"tau_s": float(path.lag_tau_s)}

    def refine(self) -> bool:
        return True

    def signature_missing(self, fitter: Any, before: Any, after: Any) -> str:
        """A first-order lag relaxes over its time constant: the samples must resolve that approach. A lag shorter
        than half the sample period relaxes within the sample it starts in and shows as a shift of less than half a
        sample, and so does how a lag already on the path is sampled (a lag of ``tau`` sampled with the input held
        over each sample trails a ramp by ``tau − dt/2``, one with the input taken at the sample's end by ``tau``:
        for a rate dependence, the dynamic field of a backward-Euler plant, up to half a sample more where the
        branch is steep). Such a lag is the sampling of the path's timing, not a relaxation the data show. A longer
        lag must show as the residual growing with the drive's rate (:func:`rate_growth_missing`)."""
        tau = float(after.path.lag_tau_s) if after is not None else 0.0
        dt = min(r.dt_s for r in fitter.data.runs)
        if tau <= 0.0:
            return ""
        if tau >= 0.5 * dt:
            if before.path.delay_s > 0.0 or before.path.rate_tau_s > 0.0:
                # Beside a time shift already on the path, the ramps' shift is that one's: what the lag adds is
                # its approach after steps.
                return ""
            shift = time_shift(fitter, after.path, after.path.with_(lag_tau_s=0.0))
            return rate_growth_missing(fitter, before, shift, f"the fitted lag ({1e3 * tau:.3g} ms)")
        return (f"the lag ({1e3 * tau:.3g} ms) is shorter than half the sample period ({1e3 * dt:.3g} ms): it relaxes "
                "within one sample, a sub-sample shift that how the path's timing is sampled makes as well (record "
                "at a higher sample rate to see its approach)")


class TimeDelay(Effect):
    name = "time_delay"
    excitation = "input steps held long enough to see the approach (a delay shifts, a first-order lag relaxes)"
    separating_run = "dwell"
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
        # A lag fitted before the delay took its shift of ramps too, and keeps only what the delay leaves.
        d = float(value)
        return path.with_(delay_s=d, lag_tau_s=max(0.0, path.lag_tau_s - d), reidentify=True)

    def params(self, value, beta, path):
        return {"delay_s": float(path.delay_s)}


class NonCongruent(Effect):
    """An output map after a congruent Preisach core, ``T = S·n(1 + c|n| + k·n²)/(1 + c + k)`` (``n`` the core
    torque over the full scale ``S``): curvature ``c`` (a square-law bend) or an odd cubic ``k`` (an MR fluid's
    yield stress cubic in the steel's flux); or a mean field (a moving Preisach model), the core seeing
    ``u + feedback · y/S`` with ``y`` its output of the sample before. The grid value is ``(curvature, cubic,
    feedback)`` with one of the three nonzero (three families, each searched on its own). The core's tables are
    identified again by least squares on the core's side of the map (one right-hand side per value: the input
    history is the nominal one) or on the fed-back input (the measured output of the sample before: one input
    history per value, so that family is short, a fraction of the full current each), since the measured
    first-order curves already carry the map and only the higher-order reversals show it."""

    name = "non_congruent"
    excitation = "minor loops between the same input extremes at different histories (their size changes)"
    separating_run = "minor_loops"
    field = True
    needs_reidentify = True
    doc = ("output map after a Preisach core: T = S n (1 + curvature |n| + cubic n²)/(1 + curvature + cubic), "
           "n = core torque/S")
    CURVATURES = (-0.4, -0.3, -0.2, -0.12, -0.06, 0.06, 0.12, 0.2, 0.35, 0.5, 0.75, 1.0, 1.5, 2.2, 3.2, 4.5)
    CUBICS = (-0.25, -0.12, 0.06, 0.12, 0.2, 0.3, 0.45, 0.65, 0.9, 1.3, 1.9, 2.8)
    # Mean-field feedback as a share of the full current (input units per full-scale output); positive:
    # magnetizing. Bounded above by the single-valued loop (see outside_physics). Every value is an input history
    # of its own (a regression prepared again): scanned coarse to fine like the map's families, refined by golden
    # section. The full-scale output S is the nominal tables' largest output, counted from the off-state's
    # remanence, so it can be well above the core's own saturation: a moving Preisach with 0.3 A per 600 N·mm of
    # core output on a 1.25 A drive is 0.42 of the full current over the S = 1050 N·mm its tables give.
    FEEDBACKS = (-0.24, -0.17, -0.12, -0.06, 0.06, 0.14, 0.24, 0.36, 0.5)
    # The residual's mean square on the higher-order reversal curves (reversal order 2 and above, the curves the
    # first-order tables do not measure) must exceed that on the major loop and the first-order curves by this
    # share of the noise floor's square.
    HIGHER_ORDER_EXCESS = 0.1
    signature_before_only = True

    def __init__(self, mean_field_only: bool = False) -> None:
        # The mean-field family alone (``without_signature``).
        self.mean_field_only = mean_field_only

    def without_signature(self) -> "Effect | None":
        """The mean field alone: it shifts the core's input on every sample, so the excess after higher-order
        reversals that an output map leaves is not its signature (on a protocol with few of them, its error shows
        on the first-order-like curves between the measured ones as much)."""
        return None if self.mean_field_only else NonCongruent(mean_field_only=True)

    def grid(self, data: EvalData) -> list[Any]:
        # Three one-parameter families, each in order of its parameter.
        full = float(data.full_current_a)
        fed = [(0.0, 0.0, f * full) for f in self.FEEDBACKS]
        if self.mean_field_only:
            return fed
        return [(c, 0.0, 0.0) for c in self.CURVATURES] + [(0.0, k, 0.0) for k in self.CUBICS] + fed

    def grid_families(self, data: EvalData) -> list[range] | None:
        if self.mean_field_only:
            return [range(len(self.FEEDBACKS))]
        a, b = len(self.CURVATURES), len(self.CURVATURES) + len(self.CUBICS)
        return [range(0, a), range(a, b), range(b, b + len(self.FEEDBACKS))]

    def apply(self, path, value, data, train):
        return path.with_(curvature=float(value[0]), cubic=float(value[1]), feedback=float(value[2]),
                          reidentify=True)

    def params(self, value, beta, path):
        return {"curvature": float(path.curvature), "scale_nmm": float(path.scale_nmm), "cubic": float(path.cubic),
                "feedback": float(path.feedback)}

    def refine(self) -> bool:
        return True

    def along(self, a: Any, b: Any) -> tuple[float, float, Any] | None:
        # Between two values of the same family: its nonzero parameter.
        for i in range(3):
            if all(a[j] == 0.0 and b[j] == 0.0 for j in range(3) if j != i):
                return float(a[i]), float(b[i]), lambda x, i=i: tuple(x if j == i else 0.0 for j in range(3))
        return None

    def outside_physics(self, path: FieldPath) -> list[str]:
        """A mean field keeps the loop single-valued only while the feedback times the core's steepest normalised
        slope (its tables' largest slope over the full scale) stays below 1: beyond, the output would jump
        (a positive feedback's avalanche)."""
        if path.feedback == 0.0:
            return []
        slope = steepest_slope(path.core_curves()) / path.scale_nmm
        if path.feedback * slope < 1.0:
            return []
        return [f"feedback={path.feedback:.3g} × steepest normalised slope {slope:.3g}/input unit = "
                f"{path.feedback * slope:.3g} (must be below 1: the loop would not be single-valued)"]

    def _order(self, fitter: Any) -> np.ndarray:
        """The reversal order of every evaluated sample (0 major loop, 1 first-order curves, 2 and above the
        higher-order reversal curves)."""
        data = fitter.data
        lo, hi = fitter.model.hysteresis.input_range
        return data.cache.get("reversal_order", lambda: data.concat(
            [reversal_order(r.current_a, lo, hi)[r.start:] for r in data.runs]))

    def acts_on(self, fitter: Any, values: Any = None) -> np.ndarray | None:
        # The tables hold the major loop and the first-order curves: the map shows after further reversals only.
        # A mean field shifts the core's input on every sample (the loop tilts and shears as a whole).
        if values and all(v[2] != 0.0 for v in values):
            return None
        return self._order(fitter) >= 2

    def signature_missing(self, fitter: Any, before: Any, after: Any) -> str:
        """A congruent core's tables hold every first-order curve, so an output map shows only after further
        reversals: the residual of ``before`` must be larger (in mean square, by :attr:`HIGHER_ORDER_EXCESS` of the
        noise floor's square) on the curves of reversal order 2 and above than on the major loop and the
        first-order curves."""
        if self.mean_field_only:
            return ""
        data = fitter.data
        residual, _ = fitter.fit(before.path, before.linear)
        order = self._order(fitter)
        ok = np.isfinite(residual)
        low, high = ok & (order <= 1), ok & (order >= 2)
        if np.count_nonzero(high) < 100 or np.count_nonzero(low) < 100:
            return "too few samples on first-order and on higher-order reversal curves to compare"
        ms_low, ms_high = float(np.mean(residual[low] ** 2)), float(np.mean(residual[high] ** 2))
        if ms_high - ms_low >= self.HIGHER_ORDER_EXCESS * data.noise_floor_nmm ** 2:
            return ""
        return (f"the residual is not larger after higher-order reversals (RMS {math.sqrt(ms_high):.3g} on reversal "
                f"order 2 and above, {math.sqrt(ms_low):.3g} on the major loop and first-order curves)")


class TableResolution(Effect):
    """Not physics: the first-order curve tables are too coarse or too noisy. Fixed by identifying the tables
    again from the same protocol runs by nonnegative, smoothness-regularised least squares (``fit_everett``):
    the whole Preisach plane from every sample instead of interpolation between a few measured curves."""

    name = "table_resolution"
    excitation = "more first-order curves (finer reversal points)"
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


def _cold_and_carried(data: EvalData, tau_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Over the evaluated spans: the heating state of every run started with cold coils, and the decaying heat each
    run carried over from the runs before it (``x = cold + rho·carried``, ``rho`` = 1 back to back, 0 after long
    rests)."""

    def make() -> tuple[np.ndarray, np.ndarray]:
        states = bundle_thermal_state(data, tau_s)
        cold, carried = [], []
        for r in data.runs:
            i = r.thermal_index
            x0 = float(states[i - 1][-1]) if i > 0 and states[i - 1].size else 0.0
            decay = x0 * np.exp(-np.arange(r.current_a.size) * r.dt_s / tau_s)
            carried.append(decay[r.start:])
            cold.append(states[i][r.start:] - decay[r.start:])
        return data.concat(cold), data.concat(carried)

    return data.cache.get(("thermal_cold_carried", tau_s), make)


def field_zero(model: Any) -> float:
    """Where the field torque is zero in the core tables' output. On an input range around zero (a current of
    either sign: the actuator, a magnet) the middle of the major loop's output range: a magnetic torque is odd in
    the field, so its major loop is symmetric about zero torque; the tables count from the state the
    identification started in (a remanence, which the friction's mean absorbed), so a gain that changes after the
    friction was identified (the coils' heating) scales the tables' output about this level, not about theirs. On
    a one-sided input range (a piezo stack's 0-100 V) the tables' own zero: the state at the input's rest."""
    lo_u, hi_u = model.hysteresis.input_range
    if not float(lo_u) < 0.0 < float(hi_u):
        return 0.0
    lo, hi = model.hysteresis.output_range
    return 0.5 * (float(lo) + float(hi))


class ThermalDrift(Effect):
    name = "thermal_drift"
    excitation = "a long run near full input followed by a rest (the gain falls as the coils heat and recovers)"
    separating_run = "heat_rest"
    doc = ("coil heating lowers the torque gain: field torque × (1 − gain_loss·x), x the heating state of time "
           "constant tau_s")
    removal_rank = 1

    def grid(self, data: EvalData) -> list[Any]:
        return [float(v) for v in np.geomspace(3.0, 3000.0, 16)]

    needs_reidentify = True

    def columns(self, data, value, y_field, model):
        # The heating of each run from cold coils, the heat carried over from the runs before (its share fitted:
        # the rig may have rested between runs), and a gain.
        cold, carried = _cold_and_carried(data, float(value))
        torque = y_field - field_zero(model)
        return np.column_stack([-cold * torque, y_field, -carried * torque])

    def update_path(self, path, value, own_beta, data):
        # Heating also changed the gain along the protocol runs: identify the tables again without it.
        return path.with_correction(self, float(value), own_beta)

    @staticmethod
    def carried_share(beta: np.ndarray) -> float:
        """The share of the heat each run carried over from the runs before (1: back to back, 0: after rests
        long enough for the coils to cool), in [0, 1]."""
        return float(np.clip(beta[2] / beta[0], 0.0, 1.0)) if beta[0] != 0 else 1.0

    @staticmethod
    def remove(y, value, beta, run):
        if run.context is None or run.bundle_index is None:
            raise BmrError(f"protocol run {run.name!r}: the heating state needs the bundle's evaluation data")
        tau = float(value)
        states = bundle_thermal_state(run.context, tau)
        i = run.bundle_index
        x0 = float(states[i - 1][-1]) if i > 0 and states[i - 1].size else 0.0
        decay = x0 * np.exp(-np.arange(states[i].size) * run.dt / tau)
        # The protocol run's start state as the evaluation runs show it (cold after rests).
        x = states[i] - (1.0 - ThermalDrift.carried_share(np.asarray(beta))) * decay
        # Only the heating is undone, relative to cold coils: the fitted field gain ``1 + beta[1]`` is the
        # tables' own error (identified warm) and belongs in the re-identified tables, which are cold.
        zero = field_zero(run.model)
        return zero + (y - zero) / np.maximum(1.0 - ThermalDrift._gain_loss(beta) * x, 1e-3)

    @staticmethod
    def _gain_loss(beta: Any) -> float:
        """Fractional gain loss at unit heating from the fitted ``field × (1 + beta[1] − beta[0]·x)``."""
        return float(beta[0] / (1.0 + beta[1]))

    def params(self, value, beta, path):
        return {"gain_loss": self._gain_loss(beta), "tau_s": float(value)}

    def detail(self, value, beta) -> dict[str, float]:
        return {"carried_share": self.carried_share(np.asarray(beta))}

    # How far outside [0, 1] the fitted share of the heat carried over between runs may fall (estimation error)
    # before the runs' gains are judged not to follow the heating history.
    CARRIED_SHARE_TOLERANCE = 0.5

    def signature_missing(self, fitter: Any, before: Any, after: Any) -> str:
        """The gain follows the coils' heating: one state driven by ``(I/I_full)^2`` through the whole session, so
        each run starts with at most the heat the runs before it left (a share in [0, 1]: 1 back to back, 0 after
        long rests) and heats further with its own current. Fitted freely (``after``: the heating of each run from
        cold and the heat carried over as separate columns), a share far outside [0, 1]
        (:attr:`CARRIED_SHARE_TOLERANCE`) means the carried-over column fits something else: gains that change
        from recording to recording (a calibration per run) and not with the current's history."""
        beta = np.asarray(after.beta, dtype=float)[-3:]
        if beta.size < 3 or not beta[0] != 0:
            return ""
        share = float(beta[2] / beta[0])
        tol = self.CARRIED_SHARE_TOLERANCE
        if -tol <= share <= 1.0 + tol:
            return ""
        return (f"the heat each run would carry over from the runs before is {share:.2f} times what the coils' "
                "current history leaves (a share in [0, 1]): the gain changes between recordings, not with the "
                "heating")

    def refine(self) -> bool:
        return True


class FrictionCurrent(Effect):
    name = "friction_current"
    beyond_run_calibration = True
    excitation = "rotation at several constant currents (angle ripple growing with |current|)"
    separating_run = "constant_currents"
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
    excitation = "rotation at constant current over several revolutions (a line at the harmonic's order)"
    separating_run = "constant_currents"
    doc = "a friction harmonic above the 3rd: amplitude_nmm·sin(order·θ + phase_rad)"

    def grid(self, data: EvalData) -> list[Any]:
        return list(range(4, 13))

    def columns(self, data, value, y_field, model):
        return data.cache.get(("friction_harmonics_cols", value), lambda: np.column_stack(_angle_harmonic(data, value)))

    needs_reidentify = True

    def update_path(self, path, value, own_beta, data):
        return path.with_correction(self, value, own_beta)

    @staticmethod
    def remove(y, value, beta, run):
        s, c = run.harmonic(value)
        return y - beta[0] * s - beta[1] * c

    def params(self, value, beta, path):
        return {"order": float(value), "amplitude_nmm": float(math.hypot(beta[0], beta[1])),
                "phase_rad": float(math.atan2(beta[1], beta[0]))}


class TorqueRipple(Effect):
    name = "torque_ripple"
    excitation = "rotation at several constant torques (once-per-revolution ripple proportional to torque)"
    separating_run = "constant_currents"
    doc = "eccentric gap: field × (1 + eps·cos(θ + phase_rad))"
    removal_rank = 1

    def columns(self, data, value, y_field, model):
        # About the tables' own zero, not the field torque's (``field_zero``): the friction was identified on the
        # off-state run, whose field torque (the remanence the tables count from) the gap modulated too, so the
        # friction's once-per-revolution term holds the remanence's ripple already.
        s, c = _angle_harmonic(data, 1)
        return np.column_stack([y_field * c, y_field * s])

    needs_reidentify = True

    def update_path(self, path, value, own_beta, data):
        return path.with_correction(self, value, own_beta)

    @staticmethod
    def remove(y, value, beta, run):
        s, c = run.harmonic(1)
        return y / np.maximum(1.0 + beta[0] * c + beta[1] * s, 1e-3)

    def params(self, value, beta, path):
        return {"eps": float(math.hypot(beta[0], beta[1])), "phase_rad": float(math.atan2(-beta[1], beta[0]))}


class SensorDrift(Effect):
    """The torque sensor's zero drifts with time from the device's start: at ``rate_nmm_per_s`` along a line, or
    settling at ``settle_per_s`` as a strain bridge warms up, ``rate · (1 − e^(−settle·t))/settle``
    (:func:`bmr._core.drift_offset`, the plant's and the extended simulation's own drift)."""

    name = "sensor_drift"
    excitation = "dwells at zero input spread over the session (the zero moves with time)"
    separating_run = "dwell"
    doc = ("torque sensor offset drifting with time at rate_nmm_per_s: linearly, or settling at settle_per_s "
           "(a strain bridge warming up: rate · (1 − e^(−settle·t))/settle)")

    needs_reidentify = True
    signature_before_only = True
    simplest = 0.0

    # Warm-up time constants (s) searched besides a drift that never settles, each kept only up to three times the
    # session's length (a slower warm-up is a line there). A bridge warming with 100 s on the paper's protocol
    # bends within the session: the line left 9.8 → 2.3 N·mm (noise 1.46) and `thermal_drift` took the rest.
    WARMUP_TAUS_S = (3000.0, 1000.0, 300.0, 100.0, 30.0)

    def grid(self, data: EvalData) -> list[Any]:
        t = data.t_abs
        session = float(np.max(t)) if t.size else 0.0
        return [0.0] + [1.0 / tau for tau in self.WARMUP_TAUS_S if tau <= 3.0 * session]

    def refine(self) -> bool:
        return True

    def columns(self, data, value, y_field, model):
        settle = float(value)
        return data.cache.get(("drift_offset", settle), lambda: _core.drift_offset(data.t_abs, settle)[:, None])

    def update_path(self, path, value, own_beta, data):
        # The drift also bent the protocol runs the tables come from: identify them again without it.
        return path.with_correction(self, value, own_beta)

    @staticmethod
    def remove(y, value, beta, run):
        return y - beta[0] * _core.drift_offset(run.t0_s + run.t - run.t[0], float(value))

    def params(self, value, beta, path):
        return {"rate_nmm_per_s": float(beta[0]), "settle_per_s": float(value)}

    def signature_missing(self, fitter: Any, before: Any, after: Any) -> str:
        """A sensor's zero moves with time all through the session: the residual of ``before``, fitted on the drift's
        column over all runs, keeps at least :data:`LEAVE_ONE_OUT_SHARE` of its coefficient, in the same direction,
        with any one run left out. A step between one recording and the others (the tables identified between
        them, a gain that the coils' heating changed in one run) tilts a line through all runs too, but not through
        the others."""
        value = self.value_in(after, 0.0)
        overall, weak = leave_one_run_out(fitter, before, self.columns(fitter.data, value, None, None)[:, 0])
        if not weak:
            return ""
        return (f"the trend ({overall:.3g} per s) comes from single recordings: without them the others keep "
                f"{weak} of it")


# Every run left out, the others' coefficient must keep at least this share of the one over all runs
# (:func:`leave_one_run_out`).
LEAVE_ONE_OUT_SHARE = 0.25


def leave_one_run_out(fitter: Any, before: Any, column: np.ndarray) -> tuple[float, str]:
    """The residual of ``before`` fitted on ``column`` (one value per evaluated sample) plus a constant over all runs,
    and again with each run left out: the coefficient over all runs and the runs without which the others keep
    less than :data:`LEAVE_ONE_OUT_SHARE` of it in the same direction (``"name: share, ..."``; empty when every run
    keeps it, when the coefficient is zero or when there is a single run). A device's property acts in every
    recording; one recording's own misfit tilts a fit through all runs but not through the others."""
    data = fitter.data
    residual, _ = fitter.fit(before.path, before.linear)
    ok = np.isfinite(residual) & np.isfinite(column)

    def coefficient(mask: np.ndarray) -> float:
        if np.count_nonzero(mask) < 3 or not np.ptp(column[mask]) > 0:
            return math.nan
        x = np.column_stack([np.ones(np.count_nonzero(mask)), column[mask]])
        return float(np.linalg.lstsq(x, residual[mask], rcond=None)[0][1])

    overall = coefficient(ok)
    if not (math.isfinite(overall) and overall != 0) or len(data.runs) < 2:
        return overall, ""
    bounds = _run_bounds(data)
    weak = []
    for j, run in enumerate(data.runs):
        rest = ok.copy()
        rest[bounds[j]:bounds[j + 1]] = False
        kept = coefficient(rest) / overall
        if math.isfinite(kept) and kept < LEAVE_ONE_OUT_SHARE:
            weak.append(f"{run.name}: {kept:.2f}")
    return overall, ", ".join(weak)


# ------------------------------------------------------------------------------ material and measurement effects
# Relaxation times the creep spectrum is built from (three per decade), limited per bundle by its sample period and
# the length of its runs.
CREEP_TAUS_S = tuple(float(v) for v in np.geomspace(0.01, 1000.0, 16))


def run_indicator(data: Any) -> np.ndarray:
    """One column per evaluation run, 1 on its evaluated span and 0 elsewhere (made once per diagnosis)."""

    def make() -> np.ndarray:
        bounds = _run_bounds(data)
        ind = np.zeros((int(bounds[-1]), len(data.runs)))
        for j in range(len(data.runs)):
            ind[bounds[j]:bounds[j + 1], j] = 1.0
        return ind

    return data.cache.get("run_indicator", make)


def _run_bounds(data: Any) -> np.ndarray:
    """Where each run's evaluated span starts in the concatenated arrays, then where the last one ends."""
    return np.concatenate([[0], np.cumsum([r.n_eval for r in data.runs])]).astype(int)


class _SessionTrend:
    """The evaluation runs' calibration corrections (offset and gain on the sensed output, per run) against a
    straight line in the runs' times: how much of their spread between runs the line leaves and how far each run
    moves along it between its halves. ``designs[i]``: run ``i``'s ``[1, sensed]`` columns; ``fits[i]``: its
    coefficients; ``times[i]``: its mean time; ``halves[i]``: (the coefficients' change from its first half to
    its second, the time between the halves' means), for the first ``len(halves)`` runs only (the evaluation runs;
    protocol runs after them join the line, not the within-run test)."""

    def __init__(self, designs: list[np.ndarray], fits: list[np.ndarray], times: list[float],
                 halves: list[tuple[np.ndarray, float]]) -> None:
        self.designs, self.halves = designs, halves
        self.coef = np.asarray(fits)
        self.tt = np.column_stack([np.ones(len(times)), np.asarray(times)])
        self.n = sum(x.shape[0] for x in designs)

    def _spread(self, coef: np.ndarray) -> float:
        """Sum of squares (over the samples) of the runs' corrections ``coef`` around their mean."""
        mean = float(np.mean(np.concatenate([x @ f for x, f in zip(self.designs, coef)])))
        return sum(float(np.sum((x @ f - mean) ** 2)) for x, f in zip(self.designs, coef))

    def spread(self, mask: np.ndarray) -> float:
        """RMS of the masked corrections between runs."""
        return math.sqrt(self._spread(self.coef * mask) / self.n)

    def judge(self, mask: np.ndarray) -> tuple[float, float, float]:
        """For the corrections' components in ``mask`` (1: offset, gain): the share of their spread between runs
        the line leaves; how far the runs move along it between their halves (1: as far as the line predicts);
        the share of the halves' change (squared) that movement explains."""
        coef = self.coef * mask
        between = self._spread(coef)
        if between <= 0.0:
            return 1.0, 0.0, 0.0
        line = np.linalg.lstsq(self.tt, coef, rcond=None)[0]
        share = self._spread(coef - self.tt @ line) / between
        predicted = [x @ (line[1] * dt) for x, (_, dt) in zip(self.designs, self.halves)]
        measured = [x @ (d * mask) for x, (d, _) in zip(self.designs, self.halves)]
        norm = sum(float(np.sum(p * p)) for p in predicted)
        changes = sum(float(np.sum(m * m)) for m in measured)
        dot = sum(float(np.sum(m * p)) for m, p in zip(measured, predicted))
        along = dot / norm if norm > 0 else 0.0
        # The runs' halves also differ where the tables err differently over the input range each half covers:
        # a drift explains most of that change, not a small part that happens to line up.
        explained = dot * dot / (norm * changes) if norm > 0 and changes > 0 else 0.0
        return share, along, explained


def _split(data: Any, y: np.ndarray) -> list[np.ndarray]:
    """``y`` over the evaluated spans, cut run by run."""
    return np.split(np.asarray(y, dtype=float), _run_bounds(data)[1:-1])


def _fingerprint(y: np.ndarray) -> tuple:
    """A cheap identity of a field-output array (the caches' key: paths are re-simulated, arrays change)."""
    return (y.size, float(y[0]) if y.size else 0.0, float(np.sum(y)), float(np.sum(y[::97] ** 2)))


def _run_input(r: Any) -> np.ndarray:
    return r.current_a


def nominal_field_full(data: Any, model: Any) -> list[np.ndarray]:
    """The nominal core's output along every evaluation run, whole runs from negative saturation (made once and
    kept in the diagnosis's cache: both creep forms read it for every grid value)."""
    return data.cache.get("nominal_field_full",
                          lambda: FieldPath.nominal(model).simulate(data.runs, copy.copy(model.forward_hysteresis())))


class Creep(Effect):
    """After each change of the core output, a share ``fraction`` keeps arriving through relaxations with time
    constants spread evenly in ``log τ`` from ``tau_min_s`` to ``tau_max_s`` (creep logarithmic in time between
    them; one exponential when they coincide). The column is the mean of ``lag(v, τ) − v`` over the spectrum's
    time constants (``v`` the field output; the relaxations run through the whole run, the nominal core standing
    in before the evaluated span), linear in ``fraction``.

    Creep also bent the protocol runs the tables come from, and tables identified from creeping runs absorb part of
    it (with the opposite sign on faster or slower runs): so the grid value is ``(tau_min_s, tau_max_s,
    fraction removed from the protocol runs)`` — each candidate's tables are identified again from the protocol
    runs with that creep removed (an output-side change: one right-hand side), and the evaluation runs fit the
    fraction linearly on those tables.

    The unbounded form (magnetic viscosity over a flat spectrum of barrier energies: a thermal fluctuation field
    ``fluctuation · d · ln(1 + t/tau0_s)`` pushing the core's input the way it last moved, ``t`` the time since it
    turned, :func:`bmr._core.creep_fluctuation_shift`) has grid values ``("log", tau0_s, share of the input span
    removed from the protocol runs as fluctuation field)``. Its column is the nominal core's response to that field
    per unit field, linearised: ``(H(u + ε·shift) − H(u))/ε`` with ``ε`` :attr:`LINEARISE_SHARE` of the input
    span, so a saturated branch creeps no more and the turning points the field moved stay in the core's memory;
    the protocol runs lose the field's exact response."""

    name = "creep"
    excitation = "a dwell after a reversal (relaxation logarithmic in the time since it)"
    separating_run = "dwell"
    doc = "output relaxes after every change: y = v + fraction·mean_τ(lag(v, τ) − v), τ log-uniform in a range"
    needs_reidentify = True
    FRACTIONS = (0.0025, 0.005, 0.01, 0.02, 0.04, 0.08)

    def _taus(self, data: Any) -> list[float]:
        dt = min(r.dt_s for r in data.runs)
        longest = max(r.current_a.size * r.dt_s for r in data.runs)
        return [t for t in CREEP_TAUS_S if 3.0 * dt <= t <= 3.0 * longest]

    # Fluctuation fields removed from the protocol runs (shares of the input span) and onsets of the log law (s).
    FIELD_SHARES = (0.0, 0.00025, 0.0005, 0.001, 0.002, 0.004)
    ONSETS_S = (0.01, 0.03, 0.1, 0.3, 1.0)
    # The fluctuation field (share of the input span) the core's response is linearised with.
    LINEARISE_SHARE = 1e-3

    def grid(self, data: Any) -> list[Any]:
        return ([(a, b, f) for a, b in self._spectra(data) for f in self.FRACTIONS]
                + [("log", t, s) for t in self.ONSETS_S for s in self.FIELD_SHARES])

    def _spectra(self, data: Any) -> list[tuple[float, float]]:
        taus = self._taus(data)
        decades = taus[::3] if len(taus) > 3 else taus
        # Creep starts fast: the spectrum's shortest time constant is at most a second (or the shortest the
        # sample period allows).
        first = max(1.0, decades[0]) if decades else 1.0
        return [(a, b) for i, a in enumerate(decades) for b in decades[i:] if a <= first * (1 + 1e-9)]

    def grid_shape(self, data: Any) -> tuple[int, int] | None:
        # Spectra × fractions removed from the protocol runs: every value is a re-identification of the tables.
        return len(self._spectra(data)) + len(self.ONSETS_S), len(self.FRACTIONS)

    def adjust_path(self, path, value):
        if value[2] == 0.0:
            # Nothing removed: the tables of the path re-identified as they are (shared by every onset's zero).
            kept = tuple(c for c in path.corrections if c[0] is not self)
            return path.with_(corrections=kept, reidentify=True)
        return path.with_correction(self, value, (value[2],))

    @staticmethod
    def _unbounded(value: Any) -> bool:
        return value[0] == "log"

    @staticmethod
    def _spectrum(value: Any) -> list[float]:
        lo, hi = value[0], value[1]
        return [t for t in CREEP_TAUS_S if lo * (1 - 1e-9) <= t <= hi * (1 + 1e-9)]

    def columns(self, data, value, y_field, model):
        if self._unbounded(value):
            return self._fluctuation_column(data, float(value[1]), model)
        taus = self._spectrum(value)

        def make() -> np.ndarray:
            # Relaxations carry the run's whole history: before the evaluated span (the opening excursion) the
            # nominal core's output stands in for the path's, from rest at the run's first sample.
            before = nominal_field_full(data, model)
            cols = []
            for y, v0, r in zip(_split(data, y_field), before, data.runs):
                v = np.concatenate([v0[:r.start], y])
                cols.append(_core.creep_relaxation(v, taus, r.dt_s)[r.start:])
            return np.concatenate(cols)[:, None]

        return data.cache.get(("creep", _fingerprint(y_field), tuple(taus)), make)

    @staticmethod
    def _fluctuation_response(hysteresis: Any, u: np.ndarray, field: float, tau0_s: float, dt_s: float,
                              plain: np.ndarray | None = None) -> np.ndarray:
        """The core's output change (from negative saturation) when a fluctuation field ``field`` (input units per
        e-fold of time) pushes its input ``u``. ``plain``: the core's output on ``u`` itself when the caller has
        it (the nominal field, the same for every onset and field)."""
        u = np.ascontiguousarray(u, dtype=float)
        pushed = np.ascontiguousarray(u + field * _core.creep_fluctuation_shift(u, tau0_s, dt_s))
        h = copy.copy(hysteresis)
        if plain is None:
            h.reset(initial="negative")
            plain = np.asarray(h.run(u), dtype=float)
        h.reset(initial="negative")
        return np.asarray(h.run(pushed), dtype=float) - plain

    def _fluctuation_column(self, data: Any, tau0_s: float, model: Any) -> np.ndarray:
        def make() -> np.ndarray:
            lo, hi = model.hysteresis.input_range
            eps = self.LINEARISE_SHARE * (hi - lo)
            plain = nominal_field_full(data, model)
            return np.concatenate([self._fluctuation_response(model.forward_hysteresis(), _run_input(r), eps, tau0_s,
                                                              r.dt_s, v)[r.start:] / eps
                                   for r, v in zip(data.runs, plain)])[:, None]

        return data.cache.get(("creep_fluctuation", tau0_s), make)

    @classmethod
    def remove(cls, y, value, beta, run):
        if cls._unbounded(value):
            # The nominal core's response to the field (a share of the input span) along the run.
            lo, hi = run.model.hysteresis.input_range
            return y - cls._fluctuation_response(run.model.forward_hysteresis(), run.current, beta[0] * (hi - lo),
                                                 float(value[1]), run.dt, run.nominal_field())
        # The relaxation of the measured output approximates that of the core output (second order in fraction).
        return y - beta[0] * _core.creep_relaxation(np.asarray(y, dtype=float), cls._spectrum(value), run.dt)

    # Samples a part of the evaluated data needs for its own fit in the signature check.
    SIGNATURE_SAMPLES = 100

    def signature_missing(self, fitter: Any, before: Any, after: Any) -> str:
        """The unbounded form's signature: the output keeps creeping the way the input last moved, after a reversal
        while the input moves on and in a dwell (the input held), and still grows late after the turn. What the
        fitted configuration ``after`` leaves without the creep column (its tables re-identified with the creep
        removed) is fitted on the column (with a constant) separately on the moving samples, on the dwell samples
        and on the samples later after the turn than the median: each coefficient must be positive (parts with fewer
        than :attr:`SIGNATURE_SAMPLES` samples are not judged). The spectrum form checks none beyond its gain."""
        if not after.linear or after.linear[-1][0] is not self or not self._unbounded(after.linear[-1][1]):
            return ""
        data = fitter.data
        value = after.linear[-1][1]
        residual, _ = fitter.fit(after.path, after.linear[:-1])
        column = self.columns(data, value, None, fitter.model)[:, 0]
        held = data.concat([np.concatenate([[False], np.diff(_run_input(r)) == 0])[r.start:] for r in data.runs])
        since = np.abs(data.concat([_core.creep_fluctuation_shift(_run_input(r), float(value[1]), r.dt_s)[r.start:]
                                    for r in data.runs]))
        ok = np.isfinite(residual)
        late = since > np.median(since[ok])
        parts = {"while the input moves on after a reversal": ok & ~held, "in dwells": ok & held,
                 "late after the turn": ok & late}
        against = []
        for what, mask in parts.items():
            if np.count_nonzero(mask) < self.SIGNATURE_SAMPLES or not np.ptp(column[mask]) > 0:
                continue
            x = np.column_stack([np.ones(np.count_nonzero(mask)), column[mask]])
            c = float(np.linalg.lstsq(x, residual[mask], rcond=None)[0][1])
            if not c > 0:
                against.append(f"{what} (fluctuation {c:.3g})")
        if not against:
            return ""
        return "the residual does not creep the way the input last moved " + ", ".join(against)

    def params(self, value, beta, path):
        if self._unbounded(value):
            spec = _core.effect_parameters()["creep"]["params"]
            return {"fraction": 0.0, "tau_min_s": float(spec["tau_min_s"]["default"]),
                    "tau_max_s": float(spec["tau_max_s"]["default"]), "fluctuation": float(beta[0]),
                    "tau0_s": float(value[1])}
        return {"fraction": float(beta[0]), "tau_min_s": float(value[0]), "tau_max_s": float(value[1])}


class RateDependence(Effect):
    """The core's input lags the applied input with a time constant ``tau_s · ŝ`` that follows the branch's
    relative slope ``ŝ`` (a dynamic field opposing the change of the material's state: eddy currents, domain-wall
    damping). A field effect: the path runs the core through the rate-dependence stage."""

    name = "rate_dependence"
    excitation = "the same loop at a second drive speed (widening where the branch is steep)"
    separating_run = "second_speed"
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

    def settle(self, path: FieldPath) -> FieldPath:
        # The lag follows the core's slopes: those of the tables the path identifies, not the nominal core's.
        if path.rate_tau_s <= 0.0 or not path.reidentify or not path.protocol or path.reidentifier is None:
            return path
        return path.with_(rate_slopes=path.reidentifier.settle_slopes(path))

    def signature_missing(self, fitter: Any, before: Any, after: Any) -> str:
        """The residual grows with the drive's rate as the fitted dynamic field predicts
        (:func:`rate_growth_missing`)."""
        if after is None or after.path.rate_tau_s <= 0.0:
            return ""
        if before.path.delay_s > 0.0 or before.path.lag_tau_s > 0.0:
            # Beside a time shift already on the path, the ramps' shift is that one's.
            return ""
        path = after.path
        shift = time_shift(fitter, path, path.with_(rate_tau_s=0.0, rate_slopes=0))
        what = f"the fitted dynamic field (tau {1e3 * path.rate_tau_s:.3g} ms)"
        return rate_growth_missing(fitter, before, shift, what)


# Share of a fitted time shift (lag, dynamic field) that the residual without it must show as growth with the rate
# beyond a width change at one speed: the gain must come from the rate, not from a shift absorbing something else
# the tables miss.
RATE_GROWTH_SHARE = 0.4


def time_shift(fitter: Any, path: FieldPath, unshifted: FieldPath) -> np.ndarray:
    """What an effect fitted on ``path`` adds to the field output over the evaluated spans: ``path``'s field minus
    that of ``unshifted`` (``path`` without the effect) run on ``path``'s tables."""
    return fitter.field(path) - fitter.field(unshifted.with_(tables=path.core_curves(), reidentify=False))


def rate_growth_missing(fitter: Any, before: Any, d_all: np.ndarray, what: str) -> str:
    """Why the residual of the configuration ``before`` (without the effect) does not grow with the drive's rate
    as the effect's fitted shift ``d_all`` (:func:`time_shift`, ``≈ −tau·slope·du/dt``) predicts ("": it does). At
    one speed the shift is a wider loop ``w = d/|du/dt|``, which tables identified at another speed absorb. The
    residual fitted on ``[each run's constant, w, d]`` must give ``d`` a coefficient of at least
    :data:`RATE_GROWTH_SHARE`, and ``d`` must differ from a width (the share of it the constants and ``w`` leave at
    least :attr:`Viscous.SECOND_SPEED_SHARE`): when every sample moves at one speed a shift is a wider loop."""
    data = fitter.data
    residual, _ = fitter.fit(before.path, before.linear)
    rate = evaluated_input_rate(data)
    moving = np.abs(rate) > 1e-3 * float(np.sqrt(np.mean(rate ** 2)))
    width = np.divide(d_all, np.abs(rate), out=np.zeros_like(d_all), where=moving)
    ok = np.isfinite(residual) & np.isfinite(d_all)
    constants = run_indicator(data)
    used = np.any(constants[ok], axis=0)
    base = np.column_stack([constants[ok][:, used], width[ok]])
    d = d_all[ok]
    if not np.any(d):
        return f"{what} does not move the output"
    beyond = d - base @ np.linalg.lstsq(base, d, rcond=None)[0]
    if float(np.sqrt(np.sum(beyond ** 2) / np.sum(d ** 2))) < Viscous.SECOND_SPEED_SHARE:
        return ("the input moves at one speed: a shift in time is a wider loop there (record the same loop at a "
                "second drive speed)")
    c = float(np.linalg.lstsq(np.column_stack([base, d]), residual[ok], rcond=None)[0][-1])
    if c >= RATE_GROWTH_SHARE:
        return ""
    return (f"the residual grows with the rate by {c:.2f} of what {what} predicts beyond the loop's width (at "
            f"least {RATE_GROWTH_SHARE:g} asked): its gain is not the rate's")


class RunGainOffset(Effect):
    """Each evaluation run has its own output offset and, when the data support it, its own gain (calibration
    that changed between recordings, a remanence or zero that differs per run): the columns are a constant and
    (grid value ``"gain_offset"``) the field output, each restricted to one run. On an actuator the seal friction
    was identified on a recording of its own (the off-state run) with its own calibration, so its scale is one more
    calibration parameter (``"gain_offset_friction"``: the angle-dependent friction as one column shared by the
    runs); without it a calibration that differs between recordings leaves a friction ripple that a drive-scaled
    friction effect would be named for. The reported spreads are those of the per-run estimates.

    The protocol recordings the core tables come from carry calibrations of their own too: an ascending and a
    descending family recorded with different sensor gains give tables that agree with neither (a per-run offset
    is already part of every re-identification). The grid value with ``"+tables"`` also estimates each protocol
    run's gain (:meth:`protocol_gains`, from the protocol runs alone) and re-identifies the tables with it divided
    out; it is offered only when dividing them out changes the protocol runs by more than
    :attr:`PROTOCOL_GAIN_NOISE` of the noise floor, and judged against the configuration on least-squares tables
    (``gain_beyond_refitted_tables``)."""

    name = "run_gain_offset"
    excitation = "a repeat of a run (the same input history recorded again)"
    separating_run = "repeat"
    doc = "per-run gain and offset of the measured output (calibration between recordings)"
    # Undone first when the protocol runs are corrected: the sensor's calibration is the outermost stage.
    removal_rank = -1
    TABLES = "+tables"
    gain_beyond_refitted_tables = True
    # The protocol runs' gains are used when dividing them out changes the runs (RMS around each run's mean) by
    # more than this share of the noise floor (the estimate on a bundle without calibration differences differs
    # from 1 by about 1e-4: 0.03 N·mm on a 600 N·mm span), their estimate converged to PROTOCOL_GAIN_TOL in at
    # most PROTOCOL_GAIN_PASSES passes (each a re-identification; the error shrinks about threefold per pass).
    PROTOCOL_GAIN_NOISE = 0.5
    PROTOCOL_GAIN_TOL = 1e-4
    PROTOCOL_GAIN_PASSES = 8
    # One protocol run per measured curve (a FORC file) gives each table row to one run alone: a per-run gain is
    # then the row's own scale, not a calibration the other runs can reveal.
    PROTOCOL_GAIN_MAX_RUNS = 8

    def grid(self, data: Any) -> list[Any]:
        gain = "gain_offset_friction" if data.has_angle else "gain_offset"
        return ["offset", gain, gain + self.TABLES]

    @classmethod
    def _base(cls, value: Any) -> str:
        return str(value).removesuffix(cls.TABLES)

    def adjust_path(self, path, value):
        if not str(value).endswith(self.TABLES):
            return path
        reid = path.reidentifier
        if reid is None or not 2 <= len(reid.runs) <= self.PROTOCOL_GAIN_MAX_RUNS:
            return path
        kept = tuple(c for c in path.corrections if c[0] is not self)
        base = path.with_(corrections=kept, reidentify=True)
        gains = reid.context.cache.get(("protocol_gains", base.key()), lambda: self.protocol_gains(base))
        if gains is None:
            return path
        return base.with_correction(self, tuple(pr.name for pr in reid.runs), gains)

    def _negligible(self, reid: Any, gains: np.ndarray) -> bool:
        """Dividing ``gains`` out changes the protocol runs (RMS around each run's mean) by at most
        :attr:`PROTOCOL_GAIN_NOISE` of the noise floor."""
        change = [(pr.torque + pr.friction()) * (1.0 / g - 1.0) for pr, g in zip(reid.runs, gains)]
        rms = math.sqrt(sum(float(np.sum((c - np.mean(c)) ** 2)) for c in change) / sum(c.size for c in change))
        return rms <= self.PROTOCOL_GAIN_NOISE * reid.context.noise_floor_nmm

    def protocol_gains(self, path: FieldPath) -> np.ndarray | None:
        """Each protocol run's gain (geometric mean 1) under ``path`` (re-identified tables): the tables are
        identified, each run's measured output is fitted as a gain times the simulated output (friction included)
        plus an offset, the gains are divided out and the tables identified again, until the gains settle. The
        runs share input histories (the ascending family's falls are the descending family's branches): the
        relative gains are what one set of tables can reconcile. None when the first estimate is negligible
        (:meth:`_negligible`: no further identification is spent) or the runs give no positive gains."""
        reid = path.reidentifier
        lo, hi = reid.input_range
        names = tuple(pr.name for pr in reid.runs)
        others = sorted(path.corrections, key=lambda c: c[0].removal_rank)
        measured, starts = [], []
        for pr in reid.runs:
            y = pr.torque
            for effect, value, beta in others:
                y = effect.remove(y, value, np.asarray(beta), pr)
            measured.append(y + pr.friction())
            starts.append(pr.known_from(lo, hi) + int(np.ceil(5 * path.lag_tau_s / pr.dt)))
        gains = np.ones(len(names))
        current = path
        for _ in range(self.PROTOCOL_GAIN_PASSES):
            sims = current.simulate(reid.runs)
            new = np.ones(len(names))
            for i, (pr, y, sim, s) in enumerate(zip(reid.runs, measured, sims, starts)):
                x = np.column_stack([sim[s:] + pr.friction()[s:], np.ones(y.size - s)])
                ok = np.all(np.isfinite(x), axis=1) & np.isfinite(y[s:])
                if np.count_nonzero(ok) > 2:
                    new[i] = float(np.linalg.lstsq(x[ok], y[s:][ok], rcond=None)[0][0])
            if not np.all(np.isfinite(new)) or np.any(new <= 0.0):
                return None  # no gain the tables can reconcile: leave the runs alone
            new /= math.exp(float(np.mean(np.log(new))))
            if current is path and self._negligible(reid, new):
                return None
            done = float(np.max(np.abs(np.log(new / gains)))) < self.PROTOCOL_GAIN_TOL
            gains = new
            if done:
                break
            current = path.with_correction(self, names, gains)
        return None if self._negligible(reid, gains) else gains

    @staticmethod
    def remove(y, value, beta, run):
        # The run's calibration gain divided out of the measured output (friction included; its offset is the
        # re-identification's own per-run offset).
        g = float(beta[value.index(run.name)])
        f = run.friction()
        return (y + f) / g - f

    def columns(self, data, value, y_field, model):
        ind = run_indicator(data)
        value = self._base(value)
        if value == "offset":
            return ind
        # The calibration scales what the sensor reads: the field output and the friction alike. The columns are
        # written into one array (a long bundle's indicator block is tens of MB: no stacked copy of it).
        runs = ind.shape[1]
        friction = value == "gain_offset_friction"
        out = np.empty((y_field.size, 2 * runs + int(friction)))
        np.multiply(ind, (y_field + data.friction_nmm)[:, None], out=out[:, :runs])
        out[:, runs:2 * runs] = ind
        if friction:
            c0 = model.friction.c0 if model.friction is not None else 0.0
            np.subtract(data.friction_nmm, c0, out=out[:, 2 * runs])
        return out

    # The calibration's differences between recordings must exceed its changes within one recording this many
    # times (in mean square), or what the per-run terms fit is not a calibration.
    BETWEEN_OVER_WITHIN = 4.0
    # Share of the corrections' spread between runs that a straight line in the runs' times must leave unexplained
    # (a line through 5 runs' random offsets explains 75 % of their spread in 5 % of sessions, through 4 runs in
    # 13 %: judged on TREND_RUNS runs or more), unless the runs do not move along the line within themselves: less
    # than WITHIN_RUN_TREND of the change it predicts between each run's halves.
    UNTRENDED_SHARE = 0.25
    WITHIN_RUN_TREND = 0.5
    WITHIN_RUN_EXPLAINED = 0.2
    TREND_RUNS = 5
    # The offsets alone or the gains alone may follow the line more closely: leaving less than this share of
    # their spread (a line through 5 runs' random values does so in 0.5 % of sessions, through more runs more
    # rarely), a drift needs only the runs' own movement along it (WITHIN_RUN_TREND) as confirmation.
    COMPONENT_UNTRENDED_SHARE = 0.05

    def signature_missing(self, fitter: Any, before: Any, after: Any) -> str:
        """A calibration differs between recordings and holds along each. The residual of ``before`` is fitted in
        each run as an offset plus a gain on the sensed output (field output and friction), on the whole run and
        separately on its two halves; the runs' corrections (RMS over the samples, around their mean) must

        * differ between runs by more than the noise floor (per-run terms fit any slow model error by a little:
          a calibration is named when recordings differ by more than one reading's noise),
        * change between runs at least :attr:`BETWEEN_OVER_WITHIN` times more (mean square) than between the
          halves of one run (a drift, a leakage or a heating moves the output along a recording), and
        * not follow a straight line in the runs' times (at least :attr:`TREND_RUNS` runs; explaining more than
          ``1 -`` :attr:`UNTRENDED_SHARE` of their spread) along which each run also moves from its first half to its second (at least
          :attr:`WITHIN_RUN_TREND` of the change the line predicts, the line explaining at least
          :attr:`WITHIN_RUN_EXPLAINED` of the change between the halves): what a drift along the session leaves;
          nor have their offsets alone or their gains alone follow it to within :attr:`COMPONENT_UNTRENDED_SHARE`
          (spread above the noise floor) with each run moving along it (:attr:`WITHIN_RUN_TREND`): a drifting
          sensor offset next to a gain that follows the drive (a heating)."""
        data = fitter.data
        if len(data.runs) < 2:
            return ""
        residual, _ = fitter.fit(before.path, before.linear)
        sensed = fitter.field(before.path) + data.friction_nmm
        within, n = 0.0, 0
        designs, fits, times, halves = [], [], [], []
        for r, y, t in zip(_split(data, residual), _split(data, sensed), _split(data, data.t_abs)):
            ok = np.isfinite(r) & np.isfinite(y)
            r, y, t = r[ok], y[ok], t[ok]
            if r.size < 20:
                continue
            x = np.column_stack([np.ones(r.size), y])
            half = r.size // 2
            a = np.linalg.lstsq(x[:half], r[:half], rcond=None)[0]
            b = np.linalg.lstsq(x[half:], r[half:], rcond=None)[0]
            within += float(np.sum((x @ (a - b) / 2.0) ** 2))
            designs.append(x)
            fits.append(np.linalg.lstsq(x, r, rcond=None)[0])
            times.append(float(np.mean(t)))
            halves.append((b - a, float(np.mean(t[half:]) - np.mean(t[:half]))))
            n += r.size
        if len(fits) < 2 or n == 0:
            return ""
        mean = float(np.mean(np.concatenate([x @ f for x, f in zip(designs, fits)])))
        between = sum(float(np.sum((x @ f - mean) ** 2)) for x, f in zip(designs, fits))
        spread = math.sqrt(between / n)
        if spread <= data.noise_floor_nmm:
            return (f"the recordings' corrections differ by {spread:.3g} (RMS), less than the noise floor "
                    f"{data.noise_floor_nmm:.3g}")
        if between < self.BETWEEN_OVER_WITHIN * within:
            return (f"the per-run corrections change as much within a run as between runs (mean squares "
                    f"{between / n:.3g} between, {within / n:.3g} within): not a calibration per recording")
        if len(fits) < self.TREND_RUNS:
            # Few evaluation runs: the protocol recordings were made in the same session and carry its trend too.
            for x, f, t in self._protocol_corrections(fitter, before):
                designs.append(x)
                fits.append(f)
                times.append(t)
            if len(fits) < self.TREND_RUNS:
                return ""
        # The runs' offsets and gains as straight lines of the runs' times: what a drift along the session leaves.
        # Judged on both together, and on each alone: a sensor's offset warming up along the session while the
        # gain follows a heating (which tracks the drive, not the clock) lines up in the offsets alone.
        trend = _SessionTrend(designs, fits, times, halves)
        share, along, explained = trend.judge(np.ones(2))
        if share >= self.UNTRENDED_SHARE or along < self.WITHIN_RUN_TREND or explained < self.WITHIN_RUN_EXPLAINED:
            for k, part in enumerate(("offsets", "gains")):
                mask = np.eye(2)[k]
                share, along, explained = trend.judge(mask)
                if (share < self.COMPONENT_UNTRENDED_SHARE and along >= self.WITHIN_RUN_TREND
                        and trend.spread(mask) > data.noise_floor_nmm):
                    return (f"the recordings' {part} follow a straight line in time ({100 * (1 - share):.1f} % of "
                            f"their spread between runs) that moves each run along it too ({100 * along:.0f} % of "
                            "the line's change between its halves): a drift along the session, not a calibration "
                            "per recording")
            return ""
        return (f"the per-run corrections follow a trend in time ({100 * (1 - share):.0f} % of their "
                f"spread between runs) that moves each run along it too ({100 * along:.0f} % of the trend's change "
                f"between its halves, {100 * explained:.0f} % of their change): a drift along the session, not a "
                "calibration per recording")

    @staticmethod
    def _protocol_corrections(fitter: Any, before: Any) -> list[tuple[np.ndarray, np.ndarray, float]]:
        """Each protocol run's offset and gain on the sensed output against the configuration ``before``, from its
        first saturation on: ``(design [1, sensed], coefficients, mean time in the bundle (s))``. The tables come
        from these runs, so the corrections are smaller than the runs' own calibrations, but a session's trend
        still orders them in time."""
        reid = fitter.reidentifier
        if not reid.runs:
            return []
        lo, hi = reid.input_range
        sims = before.path.simulate(reid.runs)
        out = []
        for pr, sim in zip(reid.runs, sims):
            s = pr.known_from(lo, hi)
            f = pr.friction()[s:]
            r, y = pr.torque[s:] - sim[s:], sim[s:] + f
            ok = np.isfinite(r) & np.isfinite(y)
            if np.count_nonzero(ok) < 20:
                continue
            x = np.column_stack([np.ones(int(np.count_nonzero(ok))), y[ok]])
            t = pr.t0_s + float(np.mean(pr.t[s:][ok] - pr.t[0]))
            out.append((x, np.linalg.lstsq(x, r[ok], rcond=None)[0], t))
        return out

    def params(self, value, beta, path):
        beta = np.asarray(beta, dtype=float)
        value = self._base(value)
        if value == "gain_offset_friction":
            beta = beta[:-1]
        k = beta.size if value == "offset" else beta.size // 2
        offsets = beta if value == "offset" else beta[k:]
        gains = np.zeros(k) if value == "offset" else beta[:k]
        return {"gain_sd": float(np.std(gains, ddof=1)) if k > 1 else 0.0,
                "offset_sd": float(np.std(offsets - np.mean(offsets), ddof=1)) if k > 1 else 0.0}


class Leakage(Effect):
    """The measured output integrates the input: ``rate_per_s · q`` from the start of each run, ``q`` the charge a
    leakage current leaves on a charge amplifier whose feedback discharges it at ``decay_per_s``
    (``q' = u − decay·q``; 0: an ideal integrator, ``∫u dt``; :func:`bmr._core.leak_integral`)."""

    name = "leakage"
    excitation = "a dwell at a nonzero input (the output keeps moving in proportion to the input)"
    separating_run = "dwell"
    doc = ("the measured output integrates the input: rate_per_s · q from each run's start, q' = u − decay_per_s·q "
           "(a charge amplifier's discharge; 0: ∫u dt)")
    needs_reidentify = True

    # Time constants (s) of the charge amplifier's discharge searched besides an ideal integrator, each kept only
    # up to twice the longest evaluation run (beyond, it is an integrator there). None below 10 s: a faster
    # discharge turns the integral into a lagged copy of the input, which creep fits as well (creep on the soft
    # rig was reported as "leakage or creep" with a 3 s discharge chosen).
    AMPLIFIER_TAUS_S = (1000.0, 300.0, 100.0, 30.0, 10.0)

    def grid(self, data: EvalData) -> list[Any]:
        longest = max(r.current_a.size * r.dt_s for r in data.runs)
        return [0.0] + [1.0 / tau for tau in self.AMPLIFIER_TAUS_S if tau <= 2.0 * longest]

    def refine(self) -> bool:
        return True

    def columns(self, data, value, y_field, model):
        decay = float(value)

        def make() -> np.ndarray:
            q = [_core.leak_integral(_run_input(r), r.dt_s, decay)[r.start:] for r in data.runs]
            return data.concat(q)[:, None]

        return data.cache.get(("leakage_integral", decay), make)

    def update_path(self, path, value, own_beta, data):
        return path.with_correction(self, value, own_beta)

    @staticmethod
    def remove(y, value, beta, run):
        return y - beta[0] * _core.leak_integral(run.current, run.dt, float(value))

    def params(self, value, beta, path):
        return {"rate_per_s": float(beta[0]), "decay_per_s": float(value)}

    def signature_missing(self, fitter: Any, before: Any, after: Any) -> str:
        """A leakage is the device's: every recording integrates its input at the same rate. The residual of
        ``before`` fitted on the running integral of the input keeps at least :data:`LEAVE_ONE_OUT_SHARE` of its
        coefficient, in the same direction, with any one run left out. The misfit an after-effect leaves in one
        recording can follow that integral there (creep with t0 = 10 ms next to per-recording calibrations on the
        paper's protocol: leakage gained 5 % of a residual 1.17 × the noise), but not in the others."""
        value = self.value_in(after, 0.0)
        column = self.columns(fitter.data, value, None, None)[:, 0]
        overall, weak = leave_one_run_out(fitter, before, column)
        if not weak:
            return ""
        return (f"the integral's coefficient ({overall:.3g} per s) comes from single recordings: without them the "
                f"others keep {weak} of it")


class Accommodation(Effect):
    """Repeated minor loops drift towards the middle of the output range: the unit-``kappa`` shift of
    :func:`bmr._core.accommodation_shift` along the run (reversals and saturation by the core's shares of the
    input span), linear in ``kappa`` for each ``cycles`` of the grid."""

    name = "accommodation"
    excitation = "minor loops cycled many times between the same extremes"
    separating_run = "minor_loops"
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
                                                     lo=lo, hi=hi, deadband=_core.ACCOMMODATION_DEADBAND_SHARE * span,
                                                     saturation_tol=_core.ACCOMMODATION_SATURATION_SHARE * span,
                                                     y_mid=0.5 * (ylo + yhi)))
            return np.concatenate(out)[:, None]

        return data.cache.get(("accommodation", float(value), _fingerprint(y_field)), make)

    def params(self, value, beta, path):
        return {"kappa": float(beta[0]), "cycles": float(value)}

    def refine(self) -> bool:
        return True


def evaluated_input_rate(data: Any) -> np.ndarray:
    """:func:`input_rate` of every run over the evaluated spans (computed once per diagnosis)."""
    return data.cache.get("input_rate", lambda: np.concatenate(
        [input_rate(_run_input(r), r.dt_s)[r.start:] for r in data.runs]))


def input_rate(u: np.ndarray, dt_s: float) -> np.ndarray:
    """``du/dt`` by the backward difference over each sample (input units/s; 0 at the first sample): the rate the
    ``viscous`` stage of the core (:class:`bmr.ExtendedSimulation`, the compensator) sees."""
    u = np.asarray(u, dtype=float)
    out = np.zeros_like(u)
    out[1:] = np.diff(u) / dt_s
    return out


class Viscous(Effect):
    """A loss of the input's rate adds to the output in the Bingham form ``c · du/dt + f_y · tanh((du/dt)/v0)``
    (``c ≥ 0`` output units per input unit per second, ``f_y ≥ 0`` output units, ``v0 > 0`` input units per
    second), the same on steep and saturated branches. Linear in ``c`` and ``f_y``: the grid runs over the yield
    rate ``v0`` (None: the viscous part alone, one column, the input's backward-difference rate; a value: that
    column and ``tanh(rate/v0)``), so the selection ranks the yield part against the plain loss on the training
    blocks by the information criterion and the candidate keeps it only where it wins there, its gain then measured
    on the held-out folds. The loss also bent the protocol runs the tables come from, so they are identified again
    with it removed. What tells it from a time shift (``time_delay``, ``coil_lag``) is a second drive speed: the
    loss widens the loop with the rate and leaves the loop tips (where the rate passes through zero) in place, a
    shift moves the tips too."""

    name = "viscous"
    excitation = ("the same loop at a second drive speed (a rate-proportional loss widens the loop and leaves its "
                  "tips in place; a time shift moves the tips)")
    separating_run = "second_speed"
    doc = "a loss of the input's rate adds to the output: c·du/dt + f_y·tanh((du/dt)/v0)"
    needs_reidentify = True
    ranks_in_range = True
    # Yield rates tried, as shares of the RMS input rate of the evaluated data: from a nearly stepped yield force
    # (a Bingham fluid) through one that is still proportional at the typical rate (where it is the viscous part)
    # to one proportional at every rate the drive follows and level only at the fastest: a loss bounded where a
    # step of the input in one sample makes its backward-difference rate far exceed any rate the drive moves at.
    YIELD_RATE_SHARES = (0.01, 0.03, 0.1, 0.3, 1.0, 3.0)

    def grid(self, data: Any) -> list[Any]:
        rate = self.columns(data, None, None, None)[:, 0]
        rms = float(np.sqrt(np.mean(rate ** 2))) if rate.size else 0.0
        if not (math.isfinite(rms) and rms > 0):
            return [None]
        v0 = self._v0_spec()
        lo, hi = float(v0["min"]), float(v0["max"])
        return [None] + [float(min(max(share * rms, lo), hi)) for share in self.YIELD_RATE_SHARES]

    @staticmethod
    def _v0_spec() -> dict[str, Any]:
        """The vocabulary's yield rate ``v0``: its range and default (input units per second)."""
        return _core.effect_parameters()["viscous"]["params"]["v0"]

    def columns(self, data, value, y_field, model):
        q = evaluated_input_rate(data)[:, None]
        if value is None:
            return q
        return data.cache.get(("viscous_yield", float(value)),
                              lambda: np.column_stack([q[:, 0], np.tanh(q[:, 0] / float(value))]))

    def update_path(self, path, value, own_beta, data):
        return path.with_correction(self, value, own_beta)

    @staticmethod
    def remove(y, value, beta, run):
        rate = input_rate(run.current, run.dt)
        out = y - beta[0] * rate
        return out if value is None else out - beta[1] * np.tanh(rate / float(value))

    def params(self, value, beta, path):
        if value is None:
            return {"c": float(beta[0]), "f_y": 0.0, "v0": float(self._v0_spec()["default"])}
        return {"c": float(beta[0]), "f_y": float(beta[1]), "v0": float(value)}

    # Share of a run's rate (RMS) that its direction of motion and a constant must leave unexplained for the run
    # to move at more than one speed: below it, a loss in proportion to the rate is a wider loop at that speed.
    SECOND_SPEED_SHARE = 0.1

    def signature_missing(self, fitter: Any, before: Any, after: Any) -> str:
        """Loop width growing with the input's rate across speeds. Tables identified at one drive speed absorb the
        loss at that speed as a wider loop, so the residual of ``before`` is that width change ``±w`` (the sign of
        the motion, the same in every run) plus the loss's growth with the rate beyond it: fitted on all runs as
        ``[each run's constant, sign(du/dt), du/dt]``, the rate's coefficient ``c`` (N·mm per A/s) must be
        positive, and so must it be, fitted the same way, in every run that moves at more than one speed itself
        (its rate not a constant times its direction, :attr:`SECOND_SPEED_SHARE`). A time shift (``time_delay``,
        ``coil_lag``, ``rate_dependence``) lowers the output where it rises and gives ``c < 0``; when every sample
        moves at one speed a loss cannot be told from a wider loop. With a yield part fitted in ``after`` the
        coefficient is that of the fitted loss ``c·du/dt + f_y·tanh((du/dt)/v0)`` instead of the rate alone (a
        yield force grows with the rate below ``v0`` and is level above it, which the rate alone reads against)."""
        data = fitter.data
        residual, _ = fitter.fit(before.path, before.linear)
        rate = self.columns(data, None, residual, fitter.model)[:, 0]
        shape = self._fitted_loss(data, after, rate)
        ok = np.isfinite(residual)
        if not np.any(rate[ok]):
            return "the input never moves"
        against = []
        bounds = _run_bounds(data)
        constants = run_indicator(data)
        for j, run in enumerate(data.runs):
            lo, hi = bounds[j], bounds[j + 1]
            keep = ok[lo:hi]
            q, r = rate[lo:hi][keep], residual[lo:hi][keep]
            if r.size < 3 or not np.any(q):
                continue
            c, speeds = self._rate_beyond_width(np.ones((q.size, 1)), q, r, shape[lo:hi][keep])
            if speeds >= self.SECOND_SPEED_SHARE and not c > 0:
                against.append(f"{run.name}: c = {c:.3g}")
        used = np.any(constants[ok], axis=0)
        c, speeds = self._rate_beyond_width(constants[ok][:, used], rate[ok], residual[ok], shape[ok])
        if speeds < self.SECOND_SPEED_SHARE:
            return ("the input moves at one speed: a loss in proportion to the rate is a wider loop there (record "
                    "the same loop at a second drive speed)")
        if not c > 0:
            return f"the residual does not grow with the rate beyond the loop's width (c = {c:.3g})"
        return ("the residual opposes the motion beyond the loop width in " + ", ".join(against)) if against else ""

    def _fitted_loss(self, data: Any, after: Any, rate: np.ndarray) -> np.ndarray:
        """The loss's shape over the evaluated spans: ``c·rate + f_y·tanh(rate/v0)`` as fitted in ``after`` when it
        carries a yield part, else the rate itself."""
        if after is None or not after.linear or after.linear[-1][0].name != self.name or after.linear[-1][1] is None:
            return rate
        v0 = float(after.linear[-1][1])
        c, f_y = (float(b) for b in np.asarray(after.beta)[-2:])
        shape = self.columns(data, v0, None, None) @ np.array([c, f_y])
        return shape if np.all(np.isfinite(shape)) and np.any(shape) else rate

    @staticmethod
    def _rate_beyond_width(constants: np.ndarray, rate: np.ndarray, residual: np.ndarray,
                           shape: np.ndarray) -> tuple[float, float]:
        """The coefficient of the loss ``shape`` in the least-squares fit of ``residual`` on ``[constants,
        sign(rate), shape]`` and the share (RMS) of the rate ``[constants, sign(rate)]`` leave unexplained (0: one
        speed)."""
        x = np.column_stack([constants, np.sign(rate), shape])
        beyond = rate - x[:, :-1] @ np.linalg.lstsq(x[:, :-1], rate, rcond=None)[0]
        share = float(np.sqrt(np.sum(beyond ** 2) / np.sum(rate ** 2)))
        if share < 1e-9:
            return math.nan, share
        return float(np.linalg.lstsq(x, residual, rcond=None)[0][-1]), share


LIBRARY: tuple[Effect, ...] = (CoilLag(), ThermalDrift(), FrictionCurrent(), FrictionHarmonics(), TorqueRipple(),
                               SensorDrift(), TimeDelay(), NonCongruent(), Creep(), RateDependence(),
                               RunGainOffset(), Leakage(), Accommodation(), Viscous(), TableResolution())
# The candidates that are physical effects of the vocabulary (the others are notes on the tables).
PHYSICAL = tuple(e.name for e in LIBRARY if e.name in _core.EFFECTS)
ANGLE_EFFECTS: tuple[str, ...] = _core.ANGLE_EFFECTS
