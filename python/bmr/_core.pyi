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
    "_rebuild_command",
    "_rebuild_compensator",
    "_rebuild_compensator_state",
    "_rebuild_hysteresis",
    "_rebuild_hysteresis_state",
    "_rebuild_virtual_actuator",
    "Command",
    "Compensator",
    "CompensatorState",
    "CurveFit",
    "CurveReport",
    "EFFECTS",
    "EverettModel",
    "EverettRegression",
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

def _rebuild_command(
    current_a: float, coil1_a: float, coil2_a: float, volt1_v: float, volt2_v: float, saturated: bool, fault: bool
) -> Command: ...
def _rebuild_compensator(
    hysteresis: Hysteresis, friction: Friction, inverse: str, converter_gain: float, current_limit: float,
    paper_state: bytes | None = None,
) -> Compensator: ...
def _rebuild_compensator_state(forward: bytes, paper: bytes | None = None) -> CompensatorState: ...
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
    """Seal friction c0 + Σ a_k sin kθ + b_k cos kθ (N·mm), up to 12 harmonics."""
    def __new__(cls, c0: float = 0.0, a: Sequence[float] | None = None, b: Sequence[float] | None = None) -> Self: ...
    @staticmethod
    def from_amplitude_phase(c0: float, amplitude: Sequence[float], phase: Sequence[float]) -> "Friction": ...
    def __copy__(self) -> Friction: ...
    def __deepcopy__(self, memo: dict[int, object]) -> Friction: ...
    @overload
    def __call__(self, theta: float) -> float: ...
    @overload
    def __call__(self, theta: _ArrayLike) -> np.ndarray: ...
    @property
    def c0(self) -> float: ...
    @property
    def a(self) -> list[float]: ...
    @property
    def b(self) -> list[float]: ...
    @property
    def order(self) -> int: ...
    def amplitude_phase(self) -> tuple[np.ndarray, np.ndarray]: ...

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

def fit_friction_order(theta_rad: np.ndarray, torque_nmm: np.ndarray, order: int) -> dict:
    """Friction c0 + Σ a_k sin kθ + b_k cos kθ of one order: c0, a, b, *_stderr, covariance, rss, n, order."""

@final
class EverettModel:
    """Preisach model with a tabulated Everett function E(β, α) on an input grid (nonnegative cell masses)."""
    def __copy__(self) -> EverettModel: ...
    def __deepcopy__(self, memo: dict[int, object]) -> EverettModel: ...
    def __new__(cls, grid: np.ndarray, masses: np.ndarray, offset: float) -> Self: ...
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
) -> dict:
    """Regularised NNLS Everett table from runs ``(u, y, weight, offset_col[, history[, gain]])``: model, offsets,
    rss, rms, n_rows, iterations, passive."""

@final
class EverettRegression:
    """The ``fit_everett`` least squares prepared for one input history (regressors and normal matrix built
    once); ``fit`` identifies the table for any outputs of the same runs, optionally warm-started."""
    def __new__(
        cls,
        grid: _ArrayLike,
        inputs: Sequence[tuple[_ArrayLike, _ArrayLike, int]],
        n_offsets: int = 1,
        *,
        smoothing: float = 1e-4,
        ridge: float = 1e-9,
        max_iter: int = 500,
    ) -> Self: ...
    @property
    def n_rows(self) -> int: ...
    def fit(self, outputs: Sequence[_ArrayLike], warm_start: Sequence[bool] | np.ndarray | None = None) -> dict: ...
EFFECTS: tuple[str, ...]
"""Names of the virtual actuator's switchable effects (the diagnosis vocabulary)."""
PRESETS: tuple[str, ...]
"""Names of the virtual actuator presets."""
ACTUATOR_PARAMETERS: tuple[str, ...]
"""Dotted names of the physical parameters ``VirtualActuator(overrides=...)`` can change."""

def effect_parameters() -> dict[str, dict[str, object]]:
    """Every effect: ``{name: {"doc": str, "params": {param: {"unit", "default", "min", "max", "doc"}}}}``."""

_EffectsSpec = Union[None, dict[str, Union[dict[str, float], None]], Sequence[str], str]

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
    def step(self, current_a: float) -> dict[str, float | bool]:
        """One sample: the keys of ``run`` as floats, plus ``command_valid`` (NaN applies 0 A, flagged)."""
    def reset(self) -> None: ...
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
    """One control-period command."""
    current_a: float
    coil1_a: float
    coil2_a: float
    volt1_v: float
    volt2_v: float
    saturated: bool
    fault: bool
    def __copy__(self) -> Command: ...
    def __deepcopy__(self, memo: dict[int, object]) -> Command: ...

@final
class CompensatorState:
    """Opaque snapshot of a Compensator's memory."""
    def __copy__(self) -> CompensatorState: ...
    def __deepcopy__(self, memo: dict[int, object]) -> CompensatorState: ...

@final
class Compensator:
    """Open-loop torque compensator: I = H⁻¹[T_ref − T_f(θ)], coil split, current limit, converter voltages."""
    def __new__(
        cls,
        hysteresis: Hysteresis,
        friction: Friction | None = None,
        *,
        inverse: str = "exact",
        converter_gain: float = 0.125,
        current_limit: float = 1.25,
        initial: _Initial | None = None,
    ) -> Self: ...
    def step(self, torque_ref_nmm: float, theta_rad: float) -> Command: ...
    def run(self, torque_ref_nmm: _ArrayLike, theta_rad: _ArrayLike) -> dict[str, np.ndarray]: ...
    def reset(self, initial: _Initial | None = None) -> None: ...
    def snapshot(self) -> CompensatorState: ...
    def restore(self, state: CompensatorState) -> None: ...
    def __copy__(self) -> Compensator: ...
    def __deepcopy__(self, memo: dict[int, object]) -> Compensator: ...
    @property
    def inverse(self) -> str: ...
    @property
    def converter_gain(self) -> float: ...
    @property
    def current_limit(self) -> float: ...
    @property
    def predicted_torque_nmm(self) -> float: ...
    @property
    def hysteresis(self) -> Hysteresis: ...
    @property
    def friction(self) -> Friction: ...
