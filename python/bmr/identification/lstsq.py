"""Least-squares Preisach tables: the output of a Preisach model is linear in its Everett table given the input
history, so the table is identified by nonnegative, smoothness-regularised least squares from any excitation
(``bmr._core.fit_everett``) — first-order curves, a major loop with scattered minor loops, or a random drive.

Every run keeps its own calibration, as explicit, reported parameters: an output offset (sensor offsets, remanence
the previous run left), optionally a gain (drift between recording days, shrunk towards 1), and its initial state:
a run that starts from an unknown state is not cut to the part after its first saturation; its initial memory is
estimated (negative or positive saturation, or one reversal after either, at any grid node) together with the
table. Every sample is used unless the caller asks otherwise, and the result says how many were used and why any
others were not.

Branches that do not close are a finding, not an error: when the output at a saturation end moves from one visit
to the next within a run (a charge measurement integrating a leakage current), the leakage rate — one coefficient
of the running input integral shared by all runs — is identified jointly with the table and reported
(``drift="auto"``). The nonnegative solve always terminates; its conditioning is reported.

A nonnegative Preisach density only makes loops that run counter-clockwise in the input-output plane: the output
lags the input. Loops that run clockwise (an output that leads its input: a damper's force, driven by the rate of
its displacement) are a finding too: which way the loops turn is measured (:func:`loop_orientation`), and
where it says clockwise the table is identified with masses free in sign (``density="auto"``). Such a table
predicts, but its branches need not be monotone and it has no exact inverse (the model then refuses a
compensator)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from bmr import _core
from bmr._core import BmrError, find_reversals
from bmr.data.bundle import Run
from bmr.data.signals import default_deadband, output_rails
from bmr.identification.accounting import AT_RANGE_END, SampleAccount
from bmr.identification.forc import Curve
from bmr.identification.signals import run_input, run_output, running_integral
from bmr.identification.spans import SATURATION_TOL, evaluation_start, input_range_of

__all__ = ["RunCalibration", "LstsqTables", "fit_tables_lstsq", "row_weights", "INITIAL_STATES", "DRIFTS", "GRIDS",
           "descending_top", "reversible_above", "FALL_SHARE",
           "DENSITIES", "CLOCKWISE_SHARE", "loop_orientation", "resolved_density",
           "DEFAULT_GRID", "table_nodes", "resolved_grid", "saturation_closure", "Conditioning", "OPEN_BRANCH_SHARE", "MAX_ROWS"]

INITIAL_STATES = ("estimate", "saturation", "negative")
DENSITIES = ("auto", "nonnegative", "signed")
# Loops count as clockwise when the output while the input rises exceeds the output while it falls, at the same
# input, by at least this share of the output span (:func:`loop_orientation`); a single-valued map with noise
# gives next to none, a Preisach system a negative share.
CLOCKWISE_SHARE = 0.02
# Input bins in which rising and falling outputs are compared.
ORIENTATION_BINS = 32
DRIFTS = ("none", "leakage", "auto")
# Branches count as open when a run's output at one saturation end moves by more than this share of its output
# span between visits (a closed Preisach loop repeats its saturation outputs to the noise).
OPEN_BRANCH_SHARE = 0.02
# Regression rows above which the runs are thinned uniformly.
MAX_ROWS = 2_000_000
# A fall is a sweep down by more than this share of the input range (input noise is not).
FALL_SHARE = 0.01
BEFORE_KNOWN_STATE = "before the run's state is known (initial_state='saturation')"
THINNED = "thinned to max_rows (every k-th sample kept)"
HELD_OUT = "held out (cross-validation)"
GRIDS = ("auto", "uniform", "adaptive")
DEFAULT_GRID = "auto"
# "auto" takes the adaptive grid for a family of first-order reversal curves: at least this many runs, and at least
# this share of them one reversal each (the corner their curve starts from).
FORC_FAMILY_MIN_RUNS = 8
FORC_FAMILY_SHARE = 0.9
# ... and their reversal inputs spread over at least this share of the input span.
FORC_CORNER_SPREAD = 0.25
# Shares of an adaptive grid's intervals placed by the branches' steepness and by the reversals (the rest even).
GRID_SLOPE_SHARE = 0.2
GRID_TURN_SHARE = 0.4
GRID_BINS_PER_INTERVAL = 4


@dataclass
class RunCalibration:
    """One training run's own parameters: output ``offset`` (output units), ``gain`` on the model output (1 when
    not fitted), its initial state as the ``history`` of inputs after negative saturation that sets it (empty:
    negative saturation) and how it was obtained, the fit's RMS residual on the run (output units), and the offset
    its first sample alone would give (how well one leading sample calibrates a run)."""

    name: str
    offset: float
    gain: float
    history: tuple[float, ...]
    initial_state: str
    rms: float
    samples: int
    first_sample_offset: float = math.nan

    def describe_state(self) -> str:
        h = self.history
        if not h:
            return "negative saturation"
        if len(h) == 1:
            return f"up from negative saturation to {h[0]:.6g}"
        return f"down from positive saturation to {h[1]:.6g}" if len(h) == 2 else f"history {list(h)}"

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "offset": self.offset, "gain": self.gain, "history": list(self.history),
                "first_sample_offset": self.first_sample_offset,
                "initial_state": self.initial_state, "state": self.describe_state(), "rms": self.rms,
                "samples": self.samples}


@dataclass
class Conditioning:
    """How the nonnegative solve ended: ``converged`` (optimality conditions met to 1e-9, relative),
    ``kkt_violation`` (the largest relative violation), ``condition`` (condition-number estimate of the
    regularised normal equations on the unknowns off their bound) and ``iterations``."""

    converged: bool
    kkt_violation: float
    condition: float
    iterations: int

    @classmethod
    def of(cls, fit: Any) -> "Conditioning":
        return cls(bool(fit.converged), float(fit.kkt_violation), float(fit.condition), int(fit.iterations))

    def to_dict(self) -> dict[str, Any]:
        return {"converged": self.converged, "kkt_violation": self.kkt_violation,
                "condition": self.condition if math.isfinite(self.condition) else None,
                "iterations": self.iterations}


def loop_orientation(us: Sequence[np.ndarray], ys: Sequence[np.ndarray], bins: int = ORIENTATION_BINS) -> float:
    """Which way the runs' loops turn: the output measured while the input rises minus the output measured while it
    falls, at the same input, relative to the outputs' span. Each sample counts as rising or falling by the step
    that led to it (a jump counts where it lands, so sparse captures are read right; samples at rest count
    neither); the difference of the mean rising and falling outputs in each of ``bins`` input bins is averaged,
    weighted by the fewer of the two counts. Positive: loops that run clockwise (the output leads the input),
    negative: counter-clockwise (the output lags, a Preisach system), about 0 for a single-valued map; 0 when no
    bin holds both."""
    u_all = np.concatenate([np.asarray(u, dtype=float) for u in us]) if us else np.zeros(0)
    y_all = np.concatenate([np.asarray(y, dtype=float) for y in ys]) if ys else np.zeros(0)
    ok = np.isfinite(u_all) & np.isfinite(y_all)
    if not ok.any():
        return 0.0
    lo, hi = float(np.min(u_all[ok])), float(np.max(u_all[ok]))
    span = float(np.ptp(y_all[ok]))
    if not (hi > lo and span > 0):
        return 0.0
    sums = np.zeros((2, bins))
    counts = np.zeros((2, bins))
    for u, y in zip(us, ys):
        u = np.asarray(u, dtype=float)
        y = np.asarray(y, dtype=float)
        step = np.diff(u)
        at = np.clip(((u[1:] - lo) / (hi - lo) * bins).astype(int, copy=False), 0, bins - 1) \
            if u.size > 1 else np.zeros(0, dtype=int)
        good = np.isfinite(step) & np.isfinite(y[1:])
        for row, moving in ((0, good & (step > 0)), (1, good & (step < 0))):
            np.add.at(sums[row], at[moving], y[1:][moving])
            np.add.at(counts[row], at[moving], 1.0)
    weight = np.minimum(counts[0], counts[1])
    if not weight.sum() > 0:
        return 0.0
    both = weight > 0
    diff = sums[0][both] / counts[0][both] - sums[1][both] / counts[1][both]
    return float(np.sum(weight[both] * diff) / weight.sum() / span)


def resolved_density(density: str, us: Sequence[np.ndarray], ys: Sequence[np.ndarray]) -> str:
    """The density ``"auto"`` stands for on runs with inputs ``us`` and outputs ``ys``: ``"signed"`` when their
    loops run clockwise (:func:`loop_orientation` at least :data:`CLOCKWISE_SHARE`), else ``"nonnegative"``.
    Other values are returned as they are."""
    if density not in DENSITIES:
        raise BmrError(f"density must be one of {', '.join(DENSITIES)}, got {density!r}")
    if density != "auto":
        return density
    return "signed" if loop_orientation(us, ys) >= CLOCKWISE_SHARE else "nonnegative"


def saturation_closure(us: Sequence[np.ndarray], ys: Sequence[np.ndarray], lo: float, hi: float,
                       tol: float) -> float:
    """The largest change of a run's output between its visits to one saturation end (each visit: the mean
    output of a stretch with the input within ``tol`` of the end), relative to the outputs' span; 0 when no run
    visits an end twice. A Preisach loop closes: its saturation outputs repeat to the noise."""
    span = max((float(np.ptp(y)) for y in ys if np.size(y)), default=0.0)
    if not span > 0:
        return 0.0
    worst = 0.0
    for u, y in zip(us, ys):
        for at_end in (u >= hi - tol, u <= lo + tol):
            edges = np.flatnonzero(np.diff(at_end.astype(np.int8)))
            bounds = np.split(np.arange(u.size), edges + 1)
            visits = [float(np.mean(y[b])) for b in bounds if b.size and at_end[b[0]]]
            if len(visits) > 1:
                worst = max(worst, float(np.ptp(visits)))
    return worst / span


@dataclass(repr=False)
class LstsqTables:
    """Result of the least-squares table identification: the Everett model (its offset is the common offset, the
    mean over runs), its first-order curves, each run's calibration and the sample account. ``rms``: RMS residual
    over the regression rows (output units). ``orientation``: the training loops' :func:`loop_orientation`
    (positive: clockwise); ``density``: ``"nonnegative"`` (a Preisach density) or ``"signed"`` (masses free in
    sign, identified because the loops run clockwise)."""

    everett: Any
    ascending: list[Curve]
    descending: list[Curve]
    input_range: tuple[float, float]
    rms: float
    n_rows: int
    iterations: int
    runs: list[RunCalibration]
    samples: SampleAccount
    n_intervals: int
    settings: dict[str, Any] = field(default_factory=dict)
    leakage_rate: float | None = None
    closure: float = 0.0
    conditioning: Conditioning | None = None
    # The final solve's passive set (unknowns off their bound): a warm start for neighbouring problems.
    passive: np.ndarray | None = None
    orientation: float = 0.0
    density: str = "nonnegative"

    @property
    def signed(self) -> bool:
        return self.density == "signed"

    def orientation_note(self) -> str:
        """The loops' direction in words, and what was identified for it."""
        if self.signed and self.orientation >= CLOCKWISE_SHARE:
            return (f"loops run clockwise (rising above falling by {100 * self.orientation:.3g} % of the output "
                    f"span): output leads input, a rate-driven output (force from a velocity); a signed density "
                    f"was identified (no exact inverse)")
        if self.signed:
            return (f"loops run counter-clockwise (rising minus falling output {100 * self.orientation:.3g} % of "
                    f"the output span); a signed density was identified: a Preisach system with negative regions "
                    f"in its density (interacting particles); a compensator inverts the nonnegative table beside it")
        turn = "clockwise" if self.orientation > 0 else "counter-clockwise"
        return f"loops run {turn} (rising minus falling output {100 * self.orientation:.3g} % of the output span)"

    @property
    def offsets(self) -> np.ndarray:
        """Each run's output offset, in run order."""
        return np.array([r.offset for r in self.runs])

    @property
    def gains(self) -> np.ndarray:
        return np.array([r.gain for r in self.runs])

    @property
    def offset(self) -> float:
        """The common offset (what a new run gets unless calibrated)."""
        return float(self.everett.offset)

    def offset_prior(self) -> dict[str, float]:
        """How the per-run offsets spread around the common one (``spread``: their standard deviation) and how far
        one leading sample's offset falls from a run's fitted offset (``first_sample_error``: RMS over the runs);
        a new run's offset calibrated on leading samples is shrunk towards the common offset with these."""
        offs = self.offsets
        first = np.array([r.first_sample_offset for r in self.runs]) - offs
        return {"common": self.offset, "runs": float(offs.size),
                "spread": float(np.std(offs, ddof=1)) if offs.size > 1 else math.nan,
                "first_sample_error": float(np.sqrt(np.mean(first ** 2))) if first.size else math.nan}

    def run_prediction(self, k: int, u: np.ndarray, integral: np.ndarray | None = None) -> np.ndarray:
        """Training run ``k``'s output as fitted, along its input ``u``: its offset plus its gain times the table's
        output from its initial state, plus the leakage along the input's running ``integral`` when one was
        fitted (``integral`` needed then)."""
        r = self.runs[k]
        part = r.gain * self.everett.simulate(np.ascontiguousarray(u, dtype=float), 0.0, list(r.history))
        if self.leakage_rate is not None:
            if integral is None:
                raise BmrError("run_prediction: the fit has a leakage term; pass the input's running integral")
            part = part + self.leakage_rate * integral
        return r.offset + part

    def calibration(self, name: str) -> RunCalibration:
        for r in self.runs:
            if r.name == name:
                return r
        raise BmrError(f"no training run named {name!r} (runs: {', '.join(r.name for r in self.runs)})")

    def to_dict(self) -> dict[str, Any]:
        return {"rms": self.rms, "rows": self.n_rows, "iterations": self.iterations, "n_intervals": self.n_intervals,
                "input_range": list(self.input_range), "offset": self.offset, "offset_prior": self.offset_prior(),
                "runs": [r.to_dict() for r in self.runs], "samples": self.samples.to_dict(),
                "settings": dict(self.settings), "leakage_rate": self.leakage_rate, "closure": self.closure,
                "orientation": self.orientation, "density": self.density, "loops": self.orientation_note(),
                "conditioning": self.conditioning.to_dict() if self.conditioning is not None else None}

    def __repr__(self) -> str:
        lo, hi = self.input_range
        est = sum(r.initial_state == "estimated" for r in self.runs)
        g = self.gains
        gains = f", gains {g.min():.4g}..{g.max():.4g}" if np.any(g != 1.0) else ""
        leak = (f", leakage {self.leakage_rate:.4g} per input·s (branches open by {100 * self.closure:.3g} % of "
                f"the span)" if self.leakage_rate is not None else "")
        cond = self.conditioning
        solve = ("" if cond is None else f"; solve {'converged' if cond.converged else 'NOT converged'}, "
                 f"condition {cond.condition:.3g}")
        return (f"LstsqTables({self.n_intervals} intervals over {lo:.6g}..{hi:.6g}, {len(self.runs)} runs "
                f"({est} initial states estimated{gains}){leak}, RMS {self.rms:.4g} on {self.n_rows} rows; "
                f"{self.samples.used} of {self.samples.total} samples used{solve}; {self.orientation_note()})")


def resolved_grid(grid: str, us: Sequence[np.ndarray]) -> str:
    """The grid ``"auto"`` stands for on runs with inputs ``us``: ``"adaptive"`` for a family of first-order
    reversal curves (:data:`FORC_FAMILY_MIN_RUNS` runs or more, :data:`FORC_FAMILY_SHARE` of them one reversal
    each beyond the inputs' reversal dead-band, at inputs spread over :data:`FORC_CORNER_SPREAD` of the span or
    more), ``"uniform"`` otherwise (loops, minor loops, free excitation:
    there the even grid predicted held-out runs better). Other grids are returned as they are."""
    if grid not in GRIDS:
        raise BmrError(f"grid must be one of {', '.join(GRIDS)}, got {grid!r}")
    if grid != "auto":
        return grid
    if len(us) < FORC_FAMILY_MIN_RUNS:
        return "uniform"
    deadband = default_deadband(list(us))
    corners = []  # the reversal input of each run that reverses once
    for u in us:
        u = np.ascontiguousarray(u, dtype=float)
        rev = find_reversals(u, deadband)
        if len(rev) == 1:
            corners.append(float(u[int(rev[0])]))
    span = max(float(np.max(u)) for u in us) - min(float(np.min(u)) for u in us)
    # Repeated loops reverse once each too, all at the same input: a FORC family's corners spread over the range.
    family = len(corners) >= FORC_FAMILY_SHARE * len(us) and np.ptp(corners) >= FORC_CORNER_SPREAD * span
    return "adaptive" if family else "uniform"


def table_nodes(us: Sequence[np.ndarray], ys: Sequence[np.ndarray], lo: float, hi: float, n_intervals: int,
                grid: str = DEFAULT_GRID) -> np.ndarray:
    """The ``n_intervals + 1`` input nodes of an Everett table over ``[lo, hi]`` (input units).

    ``grid="auto"`` (default): :func:`resolved_grid`. ``"uniform"``: evenly spaced. ``"adaptive"``: the intervals are spread by a density over the
    input that is part even, part (:data:`GRID_SLOPE_SHARE`) how steep the measured branches are there (mean
    ``|dy/du|`` in :data:`GRID_BINS_PER_INTERVAL` bins per interval) and part (:data:`GRID_TURN_SHARE`) how many
    reversals the runs make there. A Preisach density lives where the branches switch (its α) and where the
    memory's corners are (its β, the reversal inputs of first-order curves), so those get finer cells for the same
    unknowns, the input range's unvisited stretches coarser ones; no interval is wider than
    ``1 / (1 − GRID_SLOPE_SHARE − GRID_TURN_SHARE)`` times the even spacing."""
    grid = resolved_grid(grid, us)
    n = int(n_intervals)
    uniform = np.linspace(lo, hi, n + 1)
    if grid == "uniform":
        return uniform
    bins = GRID_BINS_PER_INTERVAL * n
    edges = np.linspace(lo, hi, bins + 1)
    rise, run, turns = np.zeros(bins), np.zeros(bins), np.zeros(bins)

    def at(x: np.ndarray) -> np.ndarray:
        return np.clip(np.searchsorted(edges, x, side="right") - 1, 0, bins - 1)

    for u, y in zip(us, ys):
        du, dy = np.diff(u), np.diff(y)
        ok = np.isfinite(du) & np.isfinite(dy) & (du != 0.0)
        np.add.at(rise, at(0.5 * (u[1:] + u[:-1])[ok]), np.abs(dy[ok]))
        np.add.at(run, at(0.5 * (u[1:] + u[:-1])[ok]), np.abs(du[ok]))
        sign = np.sign(du[ok])
        turn = np.flatnonzero(sign[1:] != sign[:-1]) + 1  # reversal points: where the memory gets a new corner
        np.add.at(turns, at(u[1:][ok][turn - 1] if turn.size else np.zeros(0)), 1.0)
    slope = np.divide(rise, run, out=np.zeros(bins), where=run > 0)
    density = np.full(bins, (1.0 - GRID_SLOPE_SHARE - GRID_TURN_SHARE) / bins)
    for share, part in ((GRID_SLOPE_SHARE, slope), (GRID_TURN_SHARE, turns)):
        total = part.sum()
        density += share * part / total if np.isfinite(total) and total > 0 else share / bins
    cdf = np.concatenate([[0.0], np.cumsum(density)])
    nodes = np.interp(np.linspace(0.0, cdf[-1], n + 1), cdf, edges)
    nodes[0], nodes[-1] = lo, hi
    return nodes


def _fit(grid: np.ndarray, packed: list[tuple], n_offsets: int, smoothing: float, ridge: float,
         drift: list[np.ndarray] | None = None, signed: bool = False) -> _core.EverettFit:
    return _core.fit_everett(grid, packed, n_offsets, smoothing=smoothing, ridge=ridge, drift=drift, signed=signed)


def row_weights(us: Sequence[np.ndarray], lo: float, hi: float, initial_state: str,
                max_rows: int) -> list[np.ndarray]:
    """Each run's row weights in :func:`fit_tables_lstsq` before any sample is held out: 1 on the rows fitted, 0
    before the known state (``initial_state="saturation"``) and between rows thinned uniformly above ``max_rows``."""
    stride = max(1, math.ceil(sum(u.size for u in us) / max_rows))
    tol = SATURATION_TOL * (hi - lo)
    out = []
    for u in us:
        w = np.zeros(u.size)
        w[(evaluation_start(u, lo, hi, tol) if initial_state == "saturation" else 0)::stride] = 1.0
        out.append(w)
    return out


def fit_tables_lstsq(
    runs: Iterable[Run],
    friction: Any = None,
    *,
    n_intervals: int = 48,
    input_range: tuple[float, float] | None = None,
    smoothing: float = 1e-4,
    ridge: float = 1e-9,
    offsets: str = "per_run",
    gains: bool = False,
    gain_prior: float = 0.05,
    initial_state: str = "estimate",
    iterations: int = 3,
    max_rows: int = MAX_ROWS,
    curve_subdivisions: int = 1,
    exclude: Mapping[str, np.ndarray] | None = None,
    drift: str = "none",
    grid: str = DEFAULT_GRID,
    density: str = "nonnegative",
    per_run_offset: bool | None = None,
    start_at_saturation: bool | None = None,
) -> LstsqTables:
    """Identify an Everett table (Preisach model) from any runs by regularised nonnegative least squares.

    ``offsets``: ``"per_run"`` (each run its own output offset: sensor offsets, unknown remanence) or
    ``"shared"``. ``gains``: also fit one gain per run on the model output, shrunk towards 1 with prior standard
    deviation ``gain_prior`` (their geometric mean is 1; the table carries the common scale). ``initial_state``:
    ``"estimate"`` (default: every run's initial memory is chosen among negative or positive saturation and one
    reversal after either, alternating with the table fit ``iterations`` times; every sample is used),
    ``"saturation"`` (rows before the run has reached both saturation ends are left out and counted) or
    ``"negative"`` (every run starts at negative saturation). Rows are thinned uniformly only above ``max_rows``
    (counted). The first-order curves start at every grid node (and at ``curve_subdivisions − 1`` points inside
    each interval); the CBH operator built from them reproduces the table at every input history (its strip rule
    is exact for the table's bilinear cells and reversible diagonal).

    ``exclude``: ``{run name: boolean mask}`` of samples kept out of the regression (held out, e.g. for
    cross-validation; they still drive the memory and are counted).

    ``drift``: ``"leakage"`` fits a leakage rate with the table (the output gains ``rate · ∫u dt`` from each run's
    start: output unit per input unit · s), ``"none"`` (default) does not, ``"auto"`` does when the branches do
    not close (:func:`saturation_closure` above :data:`OPEN_BRANCH_SHARE`) and keeps it only when it closes them
    (halves the closure): an open loop from a changing gain (heating) is not a leakage.

    ``grid``: where the table's nodes lie, ``"auto"`` (default: adaptive for a family of first-order reversal curves), ``"uniform"`` or ``"adaptive"``
    (:func:`table_nodes`; the one used is in ``settings["grid"]``).

    ``density``: ``"nonnegative"`` (default: a Preisach density, monotone branches, an exact inverse), ``"signed"``
    (cell masses free in sign: loops that run clockwise) or ``"auto"`` (signed when the runs' loops run clockwise,
    :func:`resolved_density`; the one used is ``density`` of the result and ``settings["density"]``).

    ``per_run_offset`` / ``start_at_saturation``: the former boolean spellings of ``offsets`` / ``initial_state``.
    """
    runs = list(runs)
    if not runs:
        raise BmrError("fit_tables_lstsq needs at least one run")
    if per_run_offset is not None:
        offsets = "per_run" if per_run_offset else "shared"
    if start_at_saturation is not None:
        initial_state = "saturation" if start_at_saturation else "negative"
    if offsets not in ("per_run", "shared"):
        raise BmrError(f"offsets must be 'per_run' or 'shared', got {offsets!r}")
    if initial_state not in INITIAL_STATES:
        raise BmrError(f"initial_state must be one of {', '.join(INITIAL_STATES)}, got {initial_state!r}")
    if not (isinstance(n_intervals, (int, np.integer)) and n_intervals >= 2):
        raise BmrError(f"n_intervals must be an integer of at least 2, got {n_intervals!r}")
    if not (isinstance(iterations, (int, np.integer)) and iterations >= 1):
        raise BmrError(f"iterations must be a positive integer, got {iterations!r}")
    if not (math.isfinite(gain_prior) and gain_prior > 0):
        raise BmrError(f"gain_prior must be positive and finite, got {gain_prior!r}")
    if drift not in DRIFTS:
        raise BmrError(f"drift must be one of {', '.join(DRIFTS)}, got {drift!r}")
    us = [run_input(r) for r in runs]
    ys = [run_output(r, friction) for r in runs]
    lo, hi = input_range if input_range is not None else input_range_of(us)
    if not hi > lo:
        raise BmrError(f"runs {', '.join(repr(r.name) for r in runs)}: the input never varies; nothing to identify")
    grid = resolved_grid(grid, us)
    orientation = loop_orientation(us, ys)
    density = resolved_density(density, us, ys)
    signed = density == "signed"
    nodes = table_nodes(us, ys, lo, hi, n_intervals, grid)
    tol = SATURATION_TOL * (hi - lo)
    closure = saturation_closure(us, ys, lo, hi, tol)
    leakage = drift == "leakage" or (drift == "auto" and closure > OPEN_BRANCH_SHARE)
    integrals = [running_integral(u, r.t) for r, u in zip(runs, us)] if leakage else None
    per_run = offsets == "per_run"
    n_off = len(runs) if per_run else 1

    account = SampleAccount()
    weights = []
    # Samples held at the output's range end (a sensor at its limit) are no measurement: not fitted.
    rails = output_rails([(u, r.output) for r, u in zip(runs, us)])
    for r, u, w in zip(runs, us, row_weights(us, lo, hi, initial_state, max_rows)):
        s = evaluation_start(u, lo, hi, tol) if initial_state == "saturation" else 0
        held = np.zeros(u.size, dtype=bool)
        if exclude is not None and r.name in exclude:
            held = np.asarray(exclude[r.name], dtype=bool)
            if held.shape != u.shape:
                raise BmrError(f"run {r.name!r}: exclude mask has {held.size} samples, the run {u.size}")
            held[:s] = False  # counted as before the known state already
            w[held] = 0.0
        railed = rails.mask(r.output) & ~held
        railed[:s] = False
        at_rail = int(np.count_nonzero(railed & (w > 0)))
        w[railed] = 0.0
        weights.append(w)
        acc = account.add_run(r.name, u.size)
        acc.used = int(np.count_nonzero(w))
        account.drop(r.name, BEFORE_KNOWN_STATE, s)
        account.drop(r.name, HELD_OUT, int(held.sum()))
        account.drop(r.name, AT_RANGE_END, at_rail)
        account.drop(r.name, THINNED, u.size - s - int(held.sum()) - at_rail - acc.used)
    account.check()
    if account.used == 0:
        raise BmrError("no sample is left to fit: every run is before its state is known "
                       "(use initial_state='estimate')")

    histories: list[list[float]] = [[] for _ in runs]
    run_gains = [1.0] * len(runs)
    rate = 0.0

    def hysteretic(k: int) -> np.ndarray:
        """Run ``k``'s output less the leakage found so far (what the table has to explain)."""
        return ys[k] - rate * integrals[k] if integrals is not None else ys[k]

    def pack() -> list[tuple]:
        return [(np.ascontiguousarray(u), np.ascontiguousarray(y), w, k if per_run else 0, h, g)
                for k, (u, y, w, h, g) in enumerate(zip(us, ys, weights, histories, run_gains))]

    # First fit on what is known: rows after both saturation ends (if estimating and any exist).
    if initial_state == "estimate":
        known = []
        for u, w in zip(us, weights):
            k = w.copy()
            s = evaluation_start(u, lo, hi, tol)
            full = np.any(u >= hi - tol) and np.any(u <= lo + tol)
            k[:s if full else u.size] = 0.0
            known.append(k)
        # Runs without a known part sit out the first fit (their offset columns would be empty).
        with_rows = [i for i, k in enumerate(known) if np.count_nonzero(k)]
        if sum(np.count_nonzero(known[i]) for i in with_rows) >= 4 * nodes.size:
            first = [(np.ascontiguousarray(us[i]), np.ascontiguousarray(ys[i]), known[i], j if per_run else 0)
                     for j, i in enumerate(with_rows)]
            res = _fit(nodes, first, len(with_rows) if per_run else 1, smoothing, ridge,
                       [integrals[i] for i in with_rows] if integrals is not None else None, signed)
        else:
            res = _fit(nodes, pack(), n_off, smoothing, ridge, integrals, signed)
    else:
        res = _fit(nodes, pack(), n_off, smoothing, ridge, integrals, signed)
    if integrals is not None:
        rate = res.drift if res.drift is not None else 0.0

    rounds = iterations if (initial_state == "estimate" or gains) else 0
    for _ in range(rounds):
        model = res.model
        offs = res.offsets
        own = [hysteretic(k) for k in range(len(runs))]
        if initial_state == "estimate":
            for k, (u, w) in enumerate(zip(us, weights)):
                h, _, _ = model.best_initial_state(u, own[k], w, free_offset=per_run, gain=run_gains[k])
                histories[k] = list(h)
        if gains:
            run_gains = _fit_gains(model, us, own, weights, histories, offs, per_run, gain_prior)
        res = _fit(nodes, pack(), n_off, smoothing, ridge, integrals, signed)
        if integrals is not None:
            rate = res.drift if res.drift is not None else 0.0

    model = res.model
    offs = res.offsets
    run_offsets = offs if per_run else np.full(len(runs), offs[0])
    common = float(np.mean(run_offsets))
    masses = reversible_above(np.asarray(model.grid), np.asarray(model.masses), descending_top(us, lo, hi))
    everett = _core.EverettModel(model.grid, masses, common, signed)
    calib = []
    for k, (r, u, y, w) in enumerate(zip(runs, us, ys, weights)):
        part = run_gains[k] * everett.simulate(u, 0.0, histories[k])
        if integrals is not None:
            part = part + rate * integrals[k]
        pred = run_offsets[k] + part
        sel = w > 0
        e = (y - pred)[sel]
        state = ("estimated" if initial_state == "estimate" else
                 "negative saturation (rows before the known state left out)" if initial_state == "saturation"
                 else "negative saturation")
        calib.append(RunCalibration(r.name, float(run_offsets[k]), float(run_gains[k]), tuple(histories[k]),
                                    state, float(np.sqrt(np.mean(e * e))) if e.size else float("nan"),
                                    int(np.count_nonzero(sel)), float(y[0] - part[0])))
    if drift == "auto" and integrals is not None:
        closed = saturation_closure(us, [hysteretic(k) for k in range(len(runs))], lo, hi, tol)
        if not closed < 0.5 * closure:
            return fit_tables_lstsq(runs, friction, n_intervals=n_intervals, input_range=(lo, hi),
                                    smoothing=smoothing, ridge=ridge, offsets=offsets, gains=gains,
                                    gain_prior=gain_prior, initial_state=initial_state, iterations=iterations,
                                    max_rows=max_rows, curve_subdivisions=curve_subdivisions, exclude=exclude,
                                    drift="none", grid=grid, density=density)
    asc, desc = everett.first_order_curves(subdivisions=curve_subdivisions)
    settings = {"smoothing": smoothing, "ridge": ridge, "offsets": offsets, "gains": gains,
                "gain_prior": gain_prior, "initial_state": initial_state, "iterations": iterations,
                "max_rows": max_rows, "curve_subdivisions": curve_subdivisions, "drift": drift, "grid": grid,
                "density": density}
    return LstsqTables(everett=everett, ascending=[(np.asarray(u), np.asarray(y)) for u, y in asc],
                       descending=[(np.asarray(u), np.asarray(y)) for u, y in desc], input_range=(lo, hi),
                       rms=res.rms, n_rows=res.n_rows, iterations=res.iterations,
                       runs=calib, samples=account, n_intervals=int(n_intervals), settings=settings,
                       leakage_rate=rate if integrals is not None else None, closure=closure,
                       conditioning=Conditioning.of(res), passive=np.asarray(res.passive),
                       orientation=orientation, density=density)


def descending_top(us: Sequence[np.ndarray], lo: float, hi: float) -> float:
    """The highest input the runs reach on a fall (a sweep down between two reversals beyond :data:`FALL_SHARE`
    of the range, the run's start counting as one): every row of the Everett table the runs read lies at or below
    it."""
    deadband = FALL_SHARE * (hi - lo)
    top = lo
    for u in us:
        u = np.asarray(u, dtype=float)
        if u.size < 2:
            continue
        ends = [0, *[int(i) for i in _core.find_reversals(np.ascontiguousarray(u), deadband)], u.size - 1]
        for a, b in zip(ends[:-1], ends[1:]):
            if b > a and u[b] < u[a]:
                top = max(top, float(u[a + 1:b + 1].max()))
    return top


def reversible_above(grid: np.ndarray, masses: np.ndarray, top: float) -> np.ndarray:
    """The cell masses with every cell whose down-switching field lies above the cells the runs read (``top``,
    :func:`descending_top`) moved onto the diagonal at its up-switching field.

    The runs change those cells only together with the diagonal cell of their column (each falls below them at
    once), so the data fix the column's sum and not its split: the fit's split is the smoothing's. Nothing the runs
    show switches irreversibly above their highest fall (a FORC file's curves reverse below its calibration field),
    so the column's mass is taken as reversible there; every output along the runs is unchanged, and the major
    loop's descending branch above the highest reversal follows the measured reversible slope."""
    n = grid.size - 1
    p_top = int(np.clip(np.searchsorted(grid, top, side="right") - 1, 0, n - 1))
    out = np.array(masses, dtype=float)
    for p in range(p_top + 1, n):
        for q in range(p + 1, n):
            k = p * n - p * (p + 1) // 2 + q
            d = q * n - q * (q + 1) // 2 + q
            out[d] += out[k]
            out[k] = 0.0
    return out


def _fit_gains(model: Any, us: Sequence[np.ndarray], ys: Sequence[np.ndarray], weights: Sequence[np.ndarray],
               histories: Sequence[list[float]], offs: np.ndarray, per_run: bool, prior: float) -> list[float]:
    """Per-run gain on the model output by weighted least squares with the run's offset, shrunk towards 1 (normal
    prior with standard deviation ``prior``); normalised to a geometric mean of 1."""
    out = []
    for k, (u, y, w, h) in enumerate(zip(us, ys, weights, histories)):
        p = model.simulate(u, 0.0, h)
        sel = w > 0
        p, yy, ww = p[sel], y[sel], w[sel]
        if p.size < 3:
            out.append(1.0)
            continue
        pm = np.average(p, weights=ww)
        ym = np.average(yy, weights=ww)
        sxx = float(np.sum(ww * (p - pm) ** 2))
        if sxx <= 0:
            out.append(1.0)
            continue
        g_hat = float(np.sum(ww * (p - pm) * (yy - ym))) / sxx
        resid = yy - ym - g_hat * (p - pm)
        sigma2 = float(np.sum(ww * resid ** 2) / max(np.sum(ww) - 2, 1.0))
        var_g = sigma2 / sxx
        shrink = prior ** 2 / (prior ** 2 + var_g)
        out.append(1.0 + shrink * (g_hat - 1.0))
    g = np.asarray(out)
    g = g / math.exp(float(np.mean(np.log(np.clip(g, 1e-6, None)))))
    return [float(x) for x in g]
