"""Type stubs for the Rust extension module ``bmr._core`` (checked against the module by ``mypy.stubtest`` in CI,
so they cannot drift)."""
from typing import Sequence, Tuple, Union, final, overload

import numpy as np
import numpy.typing as npt
from typing_extensions import Self

_ArrayLike = npt.ArrayLike
_Curve = Tuple[npt.ArrayLike, npt.ArrayLike]
_Initial = Union[str, Tuple[str, float]]

__all__ = [
    "ACCOMMODATION_DEADBAND_SHARE",
    "ACCOMMODATION_SATURATION_SHARE",
    "ACTUATOR_PARAMETERS",
    "BmrError",
    "BundleError",
    "ExcitationError",
    "IdentificationError",
    "InUseError",
    "LIMITS",
    "ModelFileError",
    "ResourceLimitError",
    "TableError",
    "_rebuild_hysteresis",
    "_rebuild_hysteresis_state",
    "_rebuild_virtual_actuator",
    "ActuatorSample",
    "Command",
    "Compensator",
    "CompensatorState",
    "CurveFit",
    "CurveReport",
    "EFFECTS",
    "EverettFit",
    "EverettModel",
    "ExtendedSimulation",
    "EverettRegression",
    "EverettFolds",
    "Friction",
    "Hysteresis",
    "HysteresisState",
    "PRESETS",
    "TableReport",
    "VirtualActuator",
    "effect_parameters",
    "fit_curve",
    "fit_everett",
    "find_reversals",
    "fit_friction_order",
    "FrictionOrderFit",
    "CANDIDATES",
    "DEVICE_PARAMETERS",
    "DEVICE_PRESETS",
    "FRICTION_MAX_ORDER",
    "MODEL_EXTENSIONS",
    "LOOP_STAGES",
    "PERIOD_EFFECTS",
    "ANGLE_EFFECTS",
    "VirtualDevice",
    "accommodation_shift",
    "candidate_signals",
    "check_extensions",
    "creep_fluctuation_shift",
    "creep_relaxation",
    "delay",
    "export_source",
    "friction_series",
    "heating_state",
    "lag",
    "leak_integral",
    "drift_offset",
    "lead",
    "output_map",
    "output_map_inverse",
    "_rebuild_compensator",
    "_rebuild_controller",
    "_simulate_closed_loop",
    "Controller",
    "ControllerDesign",
    "ControllerState",
    "_rebuild_compensator_state",
    "reversal_order",
]

class BmrError(ValueError):
    """Invalid bmr input, table or file."""

class TableError(BmrError):
    """Curves or tables that cannot make a hysteresis operator (the message names family, curve and sample)."""

class BundleError(BmrError):
    """A bundle folder, manifest or run file that cannot be read or written (the message names the file)."""

class ModelFileError(BmrError):
    """A model file that cannot be read or written (the message names the file and the field)."""

class ExcitationError(BmrError):
    """An excitation or experiment protocol with invalid parameters."""

class IdentificationError(BmrError):
    """Data from which friction or tables cannot be identified."""

class ResourceLimitError(BmrError):
    """A requested size above its documented limit (checked before anything is allocated)."""

class InUseError(BmrError):
    """The object is in use by another thread (inside a run() that released the interpreter lock)."""

LIMITS: dict[str, float]
"""Documented bounds on every size and magnitude a caller can ask for (checked before allocation)."""

def _rebuild_hysteresis(
    asc: bytes, asc_nodes: int, asc_curves: int, desc: bytes, desc_nodes: int, desc_curves: int, y_lo: float,
    y_hi: float, state: bytes,
) -> Hysteresis: ...
def _rebuild_hysteresis_state(state: bytes) -> HysteresisState: ...
def _rebuild_virtual_actuator(
    preset: str, seed: int, sample_rate_hz: float, effects: object, overrides: object, state: object
) -> VirtualActuator: ...

@final
class HysteresisState:
    """Opaque snapshot of a Hysteresis state."""
    def __copy__(self) -> HysteresisState: ...
    def __deepcopy__(self, memo: dict[int, object]) -> HysteresisState: ...
    @property
    def input(self) -> float: ...
    @property
    def output(self) -> float: ...

@final
class Hysteresis:
    """CBH hysteresis operator built from measured first-order reversal curves (memory of 64 reversal points)."""
    @staticmethod
    def from_curves(
        ascending: Sequence[_Curve],
        descending: Sequence[_Curve],
        *,
        initial: _Initial | None = None,
        monotone_tolerance: float = 0.25,
        reach_tolerance: float = 0.01,
        closure_tolerance: float = 0.05,
        node_tolerance: float = 0.0,
        max_nodes: int = 16384,
        subdivisions: int = 1,
    ) -> "Hysteresis": ...
    @property
    def build_report(self) -> TableReport | None:
        """What from_curves measured, fitted and derived (None for operators not built from curves)."""
    def compressed(self, tolerance: float, max_nodes: int = 16384) -> tuple["Hysteresis", dict[str, dict[str, float]]]:
        """The same operator on fewer nodes within ``tolerance`` (fraction of the output span), and the bound."""
    def step(self, u: float) -> float: ...
    def run(self, u: _ArrayLike) -> np.ndarray: ...
    def run_rate_dependent(self, u: _ArrayLike, *, tau_s: float, dt_s: float,
                           slope_ref: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``u`` through the rate-dependence stage (core-input lag of time constant ``tau_s`` scaled by the
        branch's differential slope over ``slope_ref``, default output span / input span), then the operator:
        ``(outputs, core_inputs)``."""
    def run_mean_field(self, u: _ArrayLike, *, per_output: float, tau_s: float = 0.0, dt_s: float = 1.0,
                       slope_ref: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``u`` through the operator with ``non_congruent``'s mean field: the core sees ``u + per_output · y``, ``y``
        its output of the sample before (after the rate-dependence stage when ``tau_s > 0``): ``(outputs,
        core_inputs)``."""
    def __copy__(self) -> Hysteresis: ...
    def __deepcopy__(self, memo: dict[int, object]) -> Hysteresis: ...
    def reset(self, initial: _Initial | None = None) -> None: ...
    def snapshot(self) -> HysteresisState: ...
    def restore(self, state: HysteresisState) -> None: ...
    @property
    def memory(self) -> list[tuple[float, float]]: ...
    @property
    def capacity(self) -> int: ...
    @property
    def input(self) -> float: ...
    @property
    def output(self) -> float: ...
    @property
    def input_range(self) -> tuple[float, float]: ...
    @property
    def output_range(self) -> tuple[float, float]: ...
    def consistency(self) -> dict[str, float]: ...
    def curves(self) -> tuple[list[tuple[np.ndarray, np.ndarray]], list[tuple[np.ndarray, np.ndarray]]]: ...
    def current_curves(self) -> tuple[list[tuple[np.ndarray, np.ndarray]], list[tuple[np.ndarray, np.ndarray]]]:
        """The paper's current curves (torque, current): the stored curves with their axes swapped."""

@final
class CurveReport:
    """One measured curve: its move against the curve's direction and what the monotone fit changed."""
    @property
    def family(self) -> str: ...
    @property
    def curve(self) -> int: ...
    @property
    def samples(self) -> int: ...
    @property
    def reversal(self) -> float: ...
    @property
    def violation(self) -> float: ...
    @property
    def violation_sample(self) -> int: ...
    @property
    def violation_input(self) -> float: ...
    @property
    def reshaped_rms(self) -> float: ...
    @property
    def input_backtrack(self) -> float: ...
    def to_dict(self) -> dict[str, object]: ...

@final
class TableReport:
    """What Hysteresis.from_curves measured (per-curve violations), fitted, derived (a missing family) and added
    (curves between measured reversals), the node grids with their error bound, and the family mismatch."""
    @property
    def curves(self) -> list[CurveReport]: ...
    @property
    def worst_violation(self) -> CurveReport | None: ...
    @property
    def derived(self) -> str | None: ...
    @property
    def derived_major(self) -> str | None: ...
    @property
    def derived_curves(self) -> int: ...
    @property
    def derived_adjustment(self) -> float: ...
    @property
    def densified(self) -> tuple[int, int]: ...
    @property
    def nodes(self) -> tuple[int, int]: ...
    @property
    def inputs(self) -> tuple[int, int]: ...
    @property
    def node_tolerance(self) -> tuple[float, float]: ...
    @property
    def node_error(self) -> tuple[float, float]: ...
    @property
    def mismatch(self) -> dict[str, float] | None: ...
    def to_dict(self) -> dict[str, object]: ...

@final
class CurveFit:
    """One raw curve fitted by adaptive bins on the input axis and a monotone fit (``fit_curve``)."""
    @property
    def u(self) -> np.ndarray: ...
    @property
    def y(self) -> np.ndarray: ...
    @property
    def counts(self) -> np.ndarray: ...
    @property
    def nodes(self) -> int: ...
    @property
    def direction(self) -> str: ...
    @property
    def samples(self) -> int: ...
    @property
    def noise(self) -> float: ...
    @property
    def node_sigma(self) -> float: ...
    @property
    def violation(self) -> float: ...
    @property
    def violation_sample(self) -> int: ...
    @property
    def violation_input(self) -> float: ...
    @property
    def reshaped_rms(self) -> float: ...
    @property
    def input_backtrack(self) -> float: ...
    def to_dict(self) -> dict[str, object]: ...

def fit_curve(u: _ArrayLike, y: _ArrayLike, direction: str, *, pilot: int = 16) -> CurveFit:
    """Fit one raw measured curve (first sample at its reversal): adaptive bins on the input axis, each bin's
    local linear fit, then the least-squares monotone fit; ``direction``: "ascending" or "descending"."""

@final
class Friction:
    """Seal friction c0 + (1 + gain_per_a·|I|)·Σ a_k sin kθ + b_k cos kθ (N·mm), up to FRICTION_MAX_ORDER
    harmonics."""
    def __new__(
        cls,
        c0: float = 0.0,
        a: Sequence[float] | None = None,
        b: Sequence[float] | None = None,
        gain_per_a: float = 0.0,
    ) -> Self: ...
    @staticmethod
    def from_amplitude_phase(c0: float, amplitude: Sequence[float], phase: Sequence[float]) -> "Friction": ...
    @overload
    def __call__(self, theta: float, current_a: float | None = None) -> float: ...
    @overload
    def __call__(self, theta: _ArrayLike, current_a: _ArrayLike | float | None = None) -> np.ndarray: ...
    @property
    def gain_per_a(self) -> float: ...
    def __copy__(self) -> Self: ...
    def __deepcopy__(self, memo: object) -> Self: ...
    def __reduce__(self) -> tuple[type, tuple[float, list[float], list[float], float]]: ...
    @property
    def c0(self) -> float: ...
    @property
    def a(self) -> list[float]: ...
    @property
    def b(self) -> list[float]: ...
    @property
    def order(self) -> int: ...
    def amplitude_phase(self) -> tuple[np.ndarray, np.ndarray]: ...

FRICTION_MAX_ORDER: int
"""Most harmonics a ``Friction`` holds."""

def friction_series(theta_rad: _ArrayLike, c0: float, a: Sequence[float], b: Sequence[float]) -> np.ndarray:
    """The friction series c0 + Σ a_k sin kθ + b_k cos kθ (N·mm) of any order: the one evaluator of every friction
    model."""

# --- identification (least squares, faer) ---
# --- reversal points (dead-band extrema), streaming in Rust ---
def find_reversals(u: _ArrayLike, deadband: float) -> np.ndarray:
    """Indices (int64) of the reversal extrema of ``u``: a maximum (minimum) is confirmed once the input has come
    back from it by more than ``deadband`` (input units, > 0); the run's start is no reversal."""

def reversal_order(
    u: _ArrayLike, lo: float, hi: float, deadband: float | None = None, *, saturation_tol: float | None = None
) -> np.ndarray:
    """Reversal order (int64) of every sample: 0 after the input came within ``saturation_tol`` (default 0.2 % of
    ``hi - lo``) of ``lo`` or ``hi``, +1 at every later reversal beyond ``deadband`` (default 1 % of ``hi - lo``)."""

@final
class FrictionOrderFit:
    """Friction ``c0 + Σ a_k sin kθ + b_k cos kθ`` (N·mm) of one harmonic order with its uncertainties."""
    @property
    def order(self) -> int: ...
    @property
    def c0(self) -> float: ...
    @property
    def a(self) -> np.ndarray: ...
    @property
    def b(self) -> np.ndarray: ...
    @property
    def c0_stderr(self) -> float: ...
    @property
    def a_stderr(self) -> np.ndarray: ...
    @property
    def b_stderr(self) -> np.ndarray: ...
    @property
    def covariance(self) -> np.ndarray: ...
    @property
    def rss(self) -> float: ...
    @property
    def n(self) -> int: ...

def fit_friction_order(theta_rad: _ArrayLike, torque_nmm: _ArrayLike, order: int) -> FrictionOrderFit:
    """Least-squares friction series of one order (BmrError on bad input or rank deficiency)."""

@final
class EverettModel:
    """Preisach model with a tabulated Everett function E(β, α) on an input grid (nonnegative cell masses, or
    masses free in sign when built ``signed``)."""
    def __copy__(self) -> EverettModel: ...
    def __deepcopy__(self, memo: dict[int, object]) -> EverettModel: ...
    def __new__(cls, grid: np.ndarray, masses: np.ndarray, offset: float, signed: bool = False) -> Self: ...
    @property
    def monotone(self) -> bool:
        """Every cell mass nonnegative (monotone branches, an exact inverse)."""
    @property
    def grid(self) -> np.ndarray: ...
    @property
    def masses(self) -> np.ndarray: ...
    @property
    def offset(self) -> float: ...
    def everett(self, beta: float, alpha: float) -> float: ...
    def everett_table(self) -> np.ndarray: ...
    def simulate(
        self, u: np.ndarray, offset: float | None = None, history: Sequence[float] | None = None
    ) -> np.ndarray:
        """Output along ``u`` from negative saturation followed by ``history`` (the run's initial state)."""
    def best_initial_state(
        self,
        u: np.ndarray,
        y: np.ndarray,
        weight: np.ndarray | None = None,
        *,
        free_offset: bool = True,
        gain: float = 1.0,
    ) -> tuple[list[float], float, float]:
        """(history, rss, offset) of the candidate initial state that predicts the run best."""
    def first_order_curves(
        self, subdivisions: int = 1
    ) -> tuple[list[tuple[np.ndarray, np.ndarray]], list[tuple[np.ndarray, np.ndarray]]]: ...
    def hysteresis(self, subdivisions: int = 1) -> Hysteresis:
        """The CBH operator of this table, built in Rust (no curve lists cross the boundary)."""

def fit_everett(
    grid: np.ndarray,
    runs: Sequence[tuple[object, ...]],
    n_offsets: int = 1,
    *,
    smoothing: float = 1e-4,
    ridge: float = 1e-9,
    max_iter: int = 500,
    drift: Sequence[np.ndarray] | None = None,
    signed: bool = False,
    diagonal_smoothing: float = 0.0,
) -> EverettFit:
    """Regularised NNLS Everett table from runs ``(u, y, weight, offset_col[, history[, gain]])``, with one
    shared coefficient of a per-run ``drift`` regressor when given; ``signed``: masses free in sign;
    ``diagonal_smoothing``: share of the smoothness penalty along the diagonal (equal ``α − β``), in [0, 1]."""

@final
class EverettFit:
    """Result of ``fit_everett`` / ``EverettRegression.fit``: the model (offset column 0 is its offset), every
    offset, the data term's residual and the solver's passive set (a warm start)."""
    @property
    def model(self) -> EverettModel: ...
    @property
    def offsets(self) -> np.ndarray: ...
    @property
    def rss(self) -> float: ...
    @property
    def rms(self) -> float: ...
    @property
    def n_rows(self) -> int: ...
    @property
    def iterations(self) -> int: ...
    @property
    def passive(self) -> np.ndarray: ...
    @property
    def converged(self) -> bool: ...
    @property
    def kkt_violation(self) -> float: ...
    @property
    def condition(self) -> float: ...
    @property
    def drift(self) -> float | None: ...

@final
class EverettRegression:
    """The ``fit_everett`` least squares prepared for one input history (regressors and normal matrix built
    once); ``fit`` identifies the table for any outputs of the same runs, each fit starting from the last one's
    answer (``warm_start``: where the first fit starts)."""
    def __new__(
        cls,
        grid: _ArrayLike,
        inputs: Sequence[tuple[_ArrayLike, _ArrayLike, int]],
        n_offsets: int = 1,
        *,
        smoothing: float = 1e-4,
        ridge: float = 1e-9,
        max_iter: int = 500,
        diagonal_smoothing: float = 0.0,
    ) -> Self: ...
    @property
    def n_rows(self) -> int: ...
    def fit(self, outputs: Sequence[_ArrayLike], warm_start: Sequence[bool] | np.ndarray | None = None) -> EverettFit: ...
@final
class EverettFolds:
    """The ``fit_everett`` least squares split into folds for cross-validation (regressors built once): ``runs``
    as ``(u, y, weight, fold, offset_col, history, gain)`` with ``fold[i]`` the fold holding sample ``i`` out
    (negative or ``>= folds``: never held out); ``score`` returns every fold's held-out ``(sse, weight)``."""
    def __new__(
        cls,
        grid: _ArrayLike,
        runs: Sequence[tuple[_ArrayLike, _ArrayLike, _ArrayLike, _ArrayLike, int, _ArrayLike, float]],
        n_offsets: int = 1,
        folds: int = 3,
        *,
        drift: Sequence[_ArrayLike] | None = None,
    ) -> Self: ...
    @property
    def n_unknowns(self) -> int: ...
    def score(
        self,
        smoothing: float = 1e-4,
        *,
        ridge: float = 1e-9,
        max_iter: int = 500,
        warm_start: Sequence[bool] | np.ndarray | None = None,
        signed: bool = False,
        diagonal_smoothing: float = 0.0,
    ) -> list[tuple[float, float]]: ...

EFFECTS: tuple[str, ...]
"""Names of the virtual actuator's switchable effects (the diagnosis vocabulary)."""
PRESETS: tuple[str, ...]
"""Names of the virtual actuator presets."""
ACTUATOR_PARAMETERS: tuple[str, ...]
"""Dotted names of the physical parameters ``VirtualActuator(overrides=...)`` can change."""

LOOP_STAGES: tuple[str, ...]
"""The model-file entries the compensator undoes (effects and ``core_tables``), in loop order (command side
first): the vocabulary's ``loop_order``."""
PERIOD_EFFECTS: tuple[str, ...]
"""Effects whose compensator stage keeps time (needs the control period ``dt_s``)."""
ANGLE_EFFECTS: tuple[str, ...]
"""Effects that live on the rotor angle (need an angle signal)."""

MODEL_EXTENSIONS: tuple[str, ...]
"""Names a model file's ``extensions`` may hold: the effects plus ``core_tables``, ``table_resolution``,
``offset``."""

def effect_parameters(*, model_entries: bool = False) -> dict[str, dict[str, object]]:
    """Every effect: ``{name: {"doc": str, "acts": str, "params": {param: {"unit", "default", "min", "max",
    "whole", "smallest_nonzero", "doc"}}}}`` (``smallest_nonzero``: where 0 means automatic, the smallest magnitude
    a set value may have; else 0); ``model_entries=True`` adds the model-file entries that are not effects."""

def lag(x: _ArrayLike, tau_s: float, dt_s: float, *, initial: float | None = None) -> np.ndarray:
    """Exact first-order lag (zero-order hold): ``y[n] = p·y[n−1] + (1 − p)·x[n]``, ``p = exp(−dt/τ)``, at rest
    at ``initial`` (default ``x[0]``)."""

def lead(y: _ArrayLike, tau_s: float, dt_s: float, *, initial: float | None = None) -> np.ndarray:
    """Exact inverse of :func:`lag` (``y[−1] = initial``, default ``y[0]``)."""

def delay(x: _ArrayLike, delay_s: float, dt_s: float, *, fill: float | None = None) -> np.ndarray:
    """``x`` delayed by ``round(delay_s/dt_s)`` samples, ``fill`` (default ``x[0]``) before the start."""

def heating_state(current_a: _ArrayLike, tau_s: float, dt_s: float, full_current_a: float, *,
                  initial: float = 0.0) -> np.ndarray:
    """Coil heating state (1 = steady full current) driven by ``(I/I_full)²`` with time constant ``tau_s``."""

def leak_integral(x: _ArrayLike, dt_s: float, decay_per_s: float = 0.0) -> np.ndarray:
    """The leakage integral of ``x`` from its first sample (0 there): ``q' = x − decay·q`` by trapezoids, the
    charge a leakage current leaves on a charge amplifier discharging it at ``decay_per_s`` (0: ``∫x dt``)."""

def drift_offset(t_s: _ArrayLike, settle_per_s: float = 0.0) -> np.ndarray:
    """A sensor's zero drift per unit of its initial rate at times ``t_s`` (s from the device's start): ``t``, or
    ``(1 − e^(−settle·t))/settle`` for a drift settling at ``settle_per_s`` (a strain bridge warming up)."""

def creep_relaxation(v: _ArrayLike, taus_s: _ArrayLike, dt_s: float) -> np.ndarray:
    """Mean over ``taus_s`` of ``lag(v, τ) − v`` per sample (exact lags from rest at ``v[0]``): the creep output of
    an equal-weight spectrum is ``v + fraction · relaxation``."""

def creep_fluctuation_shift(u: _ArrayLike, tau0_s: float, dt_s: float) -> np.ndarray:
    """Per unit fluctuation field along applied input ``u``: the input's last direction × ``ln(1 + t/tau0_s)``,
    ``t`` the time since it turned; creep's log-time after-effect feeds the core ``u + fluctuation · shift``."""

def accommodation_shift(u: _ArrayLike, v: _ArrayLike, *, kappa: float, cycles: float, lo: float, hi: float,
                        deadband: float, saturation_tol: float, y_mid: float) -> np.ndarray:
    """Minor-loop accommodation shift (output units) along input ``u`` and core output ``v``."""

def candidate_signals(t_s: _ArrayLike, u: _ArrayLike, y: _ArrayLike, *, deadband: float,
                      theta_rad: _ArrayLike | None = None, harmonics: int = 0) -> np.ndarray:
    """``n × m`` candidate library of one run (columns named in :data:`CANDIDATES`, then angle harmonics)."""

ACCOMMODATION_DEADBAND_SHARE: float
"""Reversal dead-band of accommodation as a share of the input span."""
ACCOMMODATION_SATURATION_SHARE: float
"""Saturation tolerance of accommodation as a share of the input span."""
CANDIDATES: tuple[tuple[str, str, str], ...]
"""The candidate library's run signals: ``(name, unit template, definition)``; ``{u}``/``{y}`` stand for the
input/output unit."""

DEVICE_PRESETS: tuple[str, ...]
"""Names of the virtual device presets (``piezo``, ``ferroelectric``)."""
DEVICE_PARAMETERS: tuple[str, ...]
"""Names of the parameters ``VirtualDevice(overrides=...)`` can change."""

_EffectsSpec = Union[None, dict[str, Union[dict[str, float], None]], Sequence[str], str]

@final
class ActuatorSample:
    """One sample of the virtual actuator: measured ``t_s`` (s), ``current_a``, ``coil1_a``, ``coil2_a`` (A),
    ``theta_rad``, ``speed_rad_s``, ``torque_nmm`` (N·mm) and the hidden ``b1_t``, ``b2_t`` (T),
    ``field_torque_nmm``, ``friction_nmm``, ``torque_true_nmm`` (N·mm); ``command_valid`` False when a non-finite
    command was replaced by 0 A. ``sample["torque_nmm"]`` reads a field by name."""
    @property
    def t_s(self) -> float: ...
    @property
    def current_a(self) -> float: ...
    @property
    def coil1_a(self) -> float: ...
    @property
    def coil2_a(self) -> float: ...
    @property
    def theta_rad(self) -> float: ...
    @property
    def speed_rad_s(self) -> float: ...
    @property
    def torque_nmm(self) -> float: ...
    @property
    def b1_t(self) -> float: ...
    @property
    def b2_t(self) -> float: ...
    @property
    def field_torque_nmm(self) -> float: ...
    @property
    def friction_nmm(self) -> float: ...
    @property
    def torque_true_nmm(self) -> float: ...
    @property
    def command_valid(self) -> bool: ...
    def __getitem__(self, key: str, /) -> float | bool: ...
    @staticmethod
    def keys() -> list[str]: ...

@final
class VirtualActuator:
    """Seeded physical simulator of the BMR rig (converters, hysteretic steel per coil, MR fluid, rotors, seal
    friction, torque sensor, switchable effects). Bit-for-bit deterministic for a seed."""
    def __copy__(self) -> VirtualActuator: ...
    def __deepcopy__(self, memo: dict[int, object]) -> VirtualActuator: ...
    def __new__(
        cls,
        preset: str = "bmr2013",
        *,
        seed: int | None = None,
        sample_rate_hz: float = ...,
        effects: _EffectsSpec = None,
        overrides: dict[str, float] | None = None,
    ) -> Self: ...
    def run(self, current_a: _ArrayLike) -> dict[str, np.ndarray]:
        """Commanded nominal currents (A) → ``t_s, current_a, coil1_a, coil2_a, theta_rad, speed_rad_s,
        torque_nmm`` and the hidden ``b1_t, b2_t, field_torque_nmm, friction_nmm, torque_true_nmm``."""
    def step(self, current_a: float) -> ActuatorSample:
        """One sample: the columns of ``run`` as floats, plus ``command_valid`` (NaN applies 0 A, flagged)."""
    def reset(self) -> None: ...
    def start_run(self, rest_s: float = 0.0) -> None:
        """A new recording after resting ``rest_s`` s at zero current (inf: settled, coils cold)."""
    @property
    def run_calibration(self) -> tuple[float, float]:
        """This recording's sensor ``(gain, offset_nmm)`` (``run_gain_offset``)."""
    def true_friction(self, theta_rad: _ArrayLike) -> np.ndarray: ...
    def theta_ahead(self, n: int) -> np.ndarray: ...
    @property
    def effects(self) -> dict[str, dict[str, float]]: ...
    @property
    def preset(self) -> str: ...
    @property
    def name(self) -> str: ...
    @property
    def seed(self) -> int: ...
    @property
    def sample_rate_hz(self) -> float: ...
    @property
    def time_s(self) -> float: ...
    @property
    def parameters(self) -> dict[str, object]:
        """Physical parameters of every stage (converter, steel1/2, fluid, geometry, drive, friction, sensor)."""
    @property
    def noise_nmm(self) -> float: ...
    @property
    def resolution_nmm(self) -> float: ...
    @property
    def converter_gain_a_per_v(self) -> float: ...
@final
class Command:
    """One control-period command: nominal current (A, negative drives coil 1), coil currents (A), converter
    voltages (V); ``saturated``: the torque asked for was not reachable; ``fault``: a non-finite input or
    intermediate, zero current commanded."""
    current_a: float
    coil1_a: float
    coil2_a: float
    volt1_v: float
    volt2_v: float
    saturated: bool
    fault: bool
    def __new__(
        cls, current_a: float, coil1_a: float, coil2_a: float, volt1_v: float, volt2_v: float, saturated: bool,
        fault: bool
    ) -> Self: ...
    def __copy__(self) -> Self: ...
    def __deepcopy__(self, memo: object) -> Self: ...
    def __reduce__(self) -> tuple[type, tuple[float, float, float, float, float, bool, bool]]: ...

@final
class CompensatorState:
    """Opaque snapshot of a Compensator's memory and stage states."""
    def __copy__(self) -> Self: ...
    def __deepcopy__(self, memo: object) -> Self: ...
    def __reduce__(self) -> tuple[object, tuple[bytes]]: ...

def _rebuild_compensator_state(state: bytes) -> CompensatorState: ...
def _rebuild_compensator(
    hysteresis: Hysteresis,
    friction: Friction,
    inverse: str,
    converter_gain: float,
    current_limit: float,
    extensions: _Extensions,
    dt_s: float | None,
    full_torque_nmm: float,
    state: bytes,
) -> Compensator: ...

_Extensions = Sequence[Union[dict[str, object], Tuple[str, dict[str, float]]]]

@final
class Compensator:
    """Open-loop torque compensator: I = H⁻¹[T_ref − T_f(θ)], coil split, current limit, converter voltages;
    optionally extended by a model's stages (``extensions`` at control period ``dt_s``)."""
    def __new__(
        cls,
        hysteresis: Hysteresis,
        friction: Friction | None = None,
        *,
        inverse: str = "exact",
        converter_gain: float = 0.125,
        current_limit: float = 1.25,
        initial: _Initial | None = None,
        extensions: _Extensions | None = None,
        dt_s: float | None = None,
        full_torque_nmm: float | None = None,
    ) -> Self: ...
    @staticmethod
    def from_model(model: object, *, dt_s: float, **kwargs: object) -> "Compensator":
        """The full extended compensator of a ``bmr.Model`` or model file (``Model.compensator``)."""
    def step(self, torque_ref_nmm: float, theta_rad: float) -> Command: ...
    def step_ahead(self, torque_ref_ahead_nmm: float, theta_ahead_rad: float) -> Command: ...
    def step_into(self, torque_ref_nmm: float, theta_rad: float, out: np.ndarray) -> float: ...
    def run(
        self,
        torque_ref_nmm: _ArrayLike,
        theta_rad: _ArrayLike,
        *,
        columns: Sequence[str] | None = None,
        out: dict[str, np.ndarray] | None = None,
    ) -> dict[str, np.ndarray]: ...
    def reset(self, initial: _Initial | None = None) -> None: ...
    def snapshot(self) -> CompensatorState: ...
    def restore(self, state: CompensatorState) -> None: ...
    def __copy__(self) -> Self: ...
    def __deepcopy__(self, memo: object) -> Self: ...
    def __reduce__(self) -> tuple[object, tuple[object, ...]]: ...
    @property
    def inverse(self) -> str: ...
    @property
    def converter_gain(self) -> float: ...
    @property
    def current_limit(self) -> float: ...
    @property
    def dt_s(self) -> float | None: ...
    @property
    def predicted_torque_nmm(self) -> float: ...
    @property
    def preview_samples(self) -> int: ...
    @property
    def extensions(self) -> list[dict[str, object]]: ...
    @property
    def stages(self) -> list[str]: ...
    @property
    def hysteresis(self) -> Hysteresis: ...
    @property
    def friction(self) -> Friction: ...

@final
class ControllerDesign:
    """The closed loop as designed from the model: bandwidth asked and given (Hz), integral gain (1/s), the loop's
    delay (s) and the phase margin it leaves (degrees), the coil lag the feedforward leads (s)."""
    @property
    def dt_s(self) -> float: ...
    @property
    def asked_hz(self) -> float: ...
    @property
    def bandwidth_hz(self) -> float: ...
    @property
    def ki_per_s(self) -> float: ...
    @property
    def loop_delay_s(self) -> float: ...
    @property
    def phase_margin_deg(self) -> float: ...
    @property
    def coil_lag_s(self) -> float: ...
    @property
    def delay_samples(self) -> int: ...
    @property
    def forgetting(self) -> float: ...
    @property
    def correction_limit_nmm(self) -> float: ...
    @property
    def full_torque_nmm(self) -> float: ...
    @property
    def fault_after(self) -> int: ...
    @property
    def feedback(self) -> bool: ...

@final
class ControllerState:
    """Opaque snapshot of a Controller (compensator memory, stages, correction, adaptation)."""

@final
class Controller:
    """Closed-loop torque controller: the compensator as feedforward, integral feedback on the measured torque,
    online gain/offset adaptation between model and measurement."""
    def __new__(
        cls,
        compensator: Compensator,
        *,
        dt_s: float | None = None,
        bandwidth_hz: float = 0.0,
        noise_share: float = 0.02,
        adaptation_time_s: float = 5.0,
        fault_after: int = 50,
        correction_limit_nmm: float = 0.0,
        feedback: bool = True,
        adaptation: bool = True,
    ) -> Self: ...
    @staticmethod
    def from_model(model: object, *, dt_s: float, **kwargs: object) -> "Controller":
        """The controller around a model's full extended compensator."""
    def step(self, reference_nmm: float, theta_rad: float, measured_nmm: float) -> Command: ...
    @property
    def design(self) -> ControllerDesign: ...
    @property
    def gain(self) -> float: ...
    @property
    def offset_nmm(self) -> float: ...
    @property
    def correction_nmm(self) -> float: ...
    @property
    def missing_samples(self) -> int: ...
    @property
    def adaptation_frozen(self) -> bool: ...
    def freeze_adaptation(self, frozen: bool = True) -> None: ...
    def reset_adaptation(self) -> None: ...
    def reset(self, initial: _Initial | None = None) -> None: ...
    def snapshot(self) -> ControllerState: ...
    def restore(self, state: ControllerState) -> None: ...
    @property
    def compensator(self) -> Compensator: ...
    def __copy__(self) -> Self: ...
    def __deepcopy__(self, memo: object) -> Self: ...
    def __reduce__(self) -> tuple[object, tuple[object, ...]]: ...

def _rebuild_controller(
    compensator: Compensator,
    dt_s: float,
    settings: object,
    state: bytes,
) -> Controller: ...
def _simulate_closed_loop(
    controller: Controller,
    plant: VirtualActuator,
    reference_nmm: _ArrayLike,
    theta_rad: _ArrayLike | None = None,
) -> dict[str, np.ndarray]: ...

@final
class ExtendedSimulation:
    """The forward chain of a model with its extensions: commanded current (A) and rotor angle (rad) → torque
    (N·mm), through the very stages the extended Compensator inverts."""
    def __new__(
        cls,
        hysteresis: Hysteresis,
        friction: Friction | None = None,
        *,
        extensions: _Extensions | None = None,
        dt_s: float,
        full_current_a: float,
        full_torque_nmm: float | None = None,
    ) -> Self: ...
    def run(
        self,
        current_a: _ArrayLike,
        theta_rad: _ArrayLike,
        *,
        initial: _Initial | None = None,
        heating: float = 0.0,
        t0_s: float = 0.0,
    ) -> dict[str, np.ndarray]: ...

def check_extensions(extensions: _Extensions) -> list[dict[str, object]]:
    """Validate a model's extensions against the vocabulary (names, parameters, ranges); the entries with every
    parameter filled in."""

def output_map(core_nmm: _ArrayLike, curvature: float, scale_nmm: float, cubic: float = 0.0) -> np.ndarray:
    """The non_congruent output map (the compensator's table) of core torques (N·mm)."""

def output_map_inverse(field_nmm: _ArrayLike, curvature: float, scale_nmm: float, cubic: float = 0.0
                       ) -> np.ndarray:
    """Core torques (N·mm) giving field torques ``field_nmm`` through :func:`output_map`."""

def export_source(compensator: Compensator, language: str, *, title: str = "bmr compensator",
                  prefix: str = "bmr") -> str:
    """Firmware source of an exact-inverse compensator: ``"rust"`` (static tables and ``compensator(dt_s)`` for
    the no_std crate) or ``"c"`` (arrays and ``<prefix>_model`` for ``bmr_compensator_init``)."""

@final
class VirtualDevice:
    """Seeded virtual hysteretic device with one input and one output and no angle (a piezo stack, a
    ferroelectric capacitor): Preisach core plus the vocabulary's effects that need no angle."""
    def __new__(
        cls,
        preset: str = "piezo",
        *,
        seed: int = 0,
        sample_rate_hz: float | None = None,
        effects: _EffectsSpec = None,
        overrides: dict[str, float] | None = None,
    ) -> Self: ...
    def run(self, u: _ArrayLike) -> dict[str, np.ndarray]:
        """Commanded inputs → ``t_s, input, output`` (measured) and ``output_true``."""
    def start_run(self, rest_s: float = 0.0) -> None: ...
    @property
    def effects(self) -> dict[str, dict[str, float]]: ...
    @property
    def quantities(self) -> tuple[tuple[str, str], tuple[str, str]]: ...
    @property
    def input_range(self) -> tuple[float, float]: ...
    @property
    def run_calibration(self) -> tuple[float, float]: ...
    @property
    def noise(self) -> float: ...
    @property
    def preset(self) -> str: ...
    @property
    def name(self) -> str: ...
    @property
    def seed(self) -> int: ...
    @property
    def sample_rate_hz(self) -> float: ...
    @property
    def time_s(self) -> float: ...
