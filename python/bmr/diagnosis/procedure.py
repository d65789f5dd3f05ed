"""``bmr.diagnose``: what the paper's model gets wrong in a bundle, the named cause, the extended model and the
held-out gain; ``bmr diagnose`` on the command line.

1. The nominal model (friction with 3 harmonics + CBH from the first-order curves, as in the paper) is identified
   from the identification runs unless one is given.
2. Every evaluation run is simulated from its start and judged from its first saturation on; the residual is
   compared with the noise floor (estimated from the off-state run's sample-to-sample spread).
3. Grouped forward selection over the effect library (:mod:`bmr.diagnosis.selection`) names the cause: each
   effect is fitted on training blocks and accepted only if its held-out gain is positive in most blocked folds
   and its interval excludes zero.
4. The accepted effects extend the model (``model.extensions``, saved in the model file), its simulation
   (:class:`bmr.diagnosis.extended_model.ExtendedModel`) and its compensator.
5. When the bundle records the simulator that made it, the closed-loop gain is measured too: tracking error of
   the extended compensator vs the nominal one on that same plant.

JSON (``bmr-diagnosis/2``, every value in the bundle's declared output unit, named in ``units``): ``cause`` (the
accepted physical effect that removed the most held-out RMS; ``table_resolution`` when only the tables were at
fault; ``"none"``), ``effects`` (accepted in order: ``name``, ``params``, ``heldout_rms_before``,
``heldout_rms_after``, ``gain``, ``folds_positive``; ``paired_with``: the effect it was accepted together
with, each judged once the other was in, when neither passed alone), ``rejected`` (the same; ``folds_evaluated`` below the
number of folds when the candidate was clearly not accepted on its first folds), ``noise_floor``,
``residual_rms`` (held-out RMS of the extended model), ``unexplained`` (``signal``, ``strength`` RMS),
``alternatives`` (pairs of effects the excitation could not tell apart, with what shows each one's signature),
``identification_drift`` (the leakage the nominal identification fitted with its tables when their branches did
not close), ``history`` (per measurement history of the bundle, what the model run through it cannot explain: the
level at each run's start, repeated loops that do not retrace, the candidate effects that explain them and which
were accepted; :mod:`bmr.diagnosis.history`) and more detail (per-run RMS, nominal held-out RMS, closed loop,
timing). Version 1 named the same fields with an ``_nmm`` suffix whatever the unit.
"""
from __future__ import annotations

import math
import sys
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from bmr._core import BmrError, ModelFileError, TableError, VirtualActuator
from bmr.data.files import check_output_file, jsonable, write_json, write_text
from bmr.data.bundle import Bundle, read_bundle
from bmr.data.signals import OutputRails
from bmr.diagnosis.discrepancy import candidate_library, learn
from bmr.diagnosis.effects import ANGLE_EFFECTS, LIBRARY, PHYSICAL
from bmr.diagnosis.field import FieldPath
from bmr.diagnosis.history import HistoryFindings, history_findings
from bmr.diagnosis.noise import from_residual
from bmr.diagnosis.extended_model import ExtendedModel, extensions_from_selection, stored_zero, with_extensions
from bmr.diagnosis.residuals import one_blas_thread, prepare, signal_label, structure
from bmr.diagnosis.selection import (MIN_EXCESS, NOISE_MARGIN, Alternative, Configuration, Fitter, forward_selection,
                                     heldout, t975)
from bmr.identification.procedure import identify
from bmr.identification.model import LOOP_STAGES, Model
from bmr.identification.table_choice import DEFAULT_INTERVALS, DEFAULT_SMOOTHING
from bmr.report.diagnosis import figures, html_page, html_section
from bmr.simulation.experiments import MULTIPEAK_SEED, reference_multipeak, tracking

__all__ = ["FORMAT", "Diagnosis", "diagnose", "closed_loop_gain", "check_duration_s", "run_cli", "PHYSICAL"]

FORMAT = "bmr-diagnosis/2"
# A learned equation (no mechanism behind it) must earn more held-out gain than a named effect.
LEARNED_MIN_GAIN = 0.05
# Nominal friction: the paper's 3 harmonics (eq 21-22); higher ones are the friction_harmonics effect.
NOMINAL_FRICTION_ORDER = 3


# Keys of an effect row in the JSON, and the row keys they come from (the selection's rows keep the actuator's
# historical names).
_ROW_KEYS = {"name": "name", "params": "params", "heldout_rms_before": "heldout_rms_before_nmm",
             "heldout_rms_after": "heldout_rms_after_nmm", "gain": "gain", "folds_positive": "folds_positive",
             "gain_interval": "gain_interval", "gain_interval_bootstrap": "gain_interval_bootstrap",
             "fold_gains": "fold_gains", "folds_evaluated": "folds_evaluated",
             "excess_explained": "excess_explained", "round": "round", "reason": "reason",
             "paired_with": "paired_with"}


@dataclass(eq=False, repr=False)
class Diagnosis:
    """The result of :func:`diagnose`. Every level and RMS is in the bundle's declared output unit
    (``quantities.output.unit``).

    ``device``: what the bundle says it was recorded on. ``cause``: the accepted physical effect that removed the
    most held-out RMS (``table_resolution`` when only the tables were at fault; ``"none"``). ``effects`` /
    ``rejected``: the selection's rows, accepted in order / rejected (``name``, ``params``, held-out RMS before and
    after, ``gain``, fold gains and intervals). ``noise_floor``: the measurement noise (one standard deviation),
    estimated as ``noise["method"]`` says. ``nominal_heldout_rms`` / ``residual_rms``: held-out RMS of the nominal
    and of the extended model. ``unexplained``: residual structure above the threshold (``signal``, ``strength``).
    ``structure_nominal`` / ``structure_extended``: residual RMS explained by each signal. ``per_run_rms``:
    ``{run: (nominal, extended)}``. ``model`` / ``extended_model``: the nominal ``bmr.Model`` and the same with the
    accepted effects in its ``extensions``. ``learned``: the sparse regression of what no effect names (or None).
    ``closed_loop``: the tracking check of the extended compensator, when the bundle records its simulator.
    ``alternatives``: pairs of effects the excitation could not tell apart (:class:`Alternative`, with what would
    separate them). ``identification_drift``: the leakage the nominal identification fitted with its tables because
    their branches did not close (``leakage_rate`` in output per input·s, ``closure`` the share of the span a
    saturation output moved), or None. ``history``: per measurement history of the bundle, what the model run
    through it cannot explain (:class:`bmr.diagnosis.history.HistoryFindings`). ``output_rails``: the output's
    range ends the recording is held at (:class:`bmr.data.signals.OutputRails`: a sensor at its limit), whose samples
    are neither fitted nor scored.
    ``to_dict()`` is the ``bmr-diagnosis/2`` JSON; ``html_section()`` a self-contained HTML fragment;
    ``write_report(path)`` a whole page."""

    device: str
    cause: str
    effects: list[dict[str, Any]]
    rejected: list[dict[str, Any]]
    noise_floor: float
    residual_rms: float
    nominal_heldout_rms: float
    unexplained: list[dict[str, Any]]
    structure_nominal: dict[str, float]
    structure_extended: dict[str, float]
    per_run_rms: dict[str, tuple[float, float]]
    folds: int
    seed: int
    model: Any
    extended_model: Any
    quantities: Any
    noise: dict[str, Any]
    learned: dict[str, Any] | None = None
    closed_loop: dict[str, Any] | None = None
    alternatives: list[Alternative] = field(default_factory=list)
    identification_drift: dict[str, float] | None = None
    reidentified_tables: dict[str, Any] | None = None
    history: list[HistoryFindings] = field(default_factory=list)
    output_rails: OutputRails = field(default_factory=OutputRails)
    wall_time_s: float = 0.0
    signals: dict[str, Any] = field(default_factory=dict)
    _figures: dict[str, str] | None = field(default=None, init=False)

    # The version-1 names (output unit whatever the device), kept readable for existing scripts.
    @property
    def actuator(self) -> str:
        return self.device

    @property
    def noise_floor_nmm(self) -> float:
        return self.noise_floor

    @property
    def residual_rms_nmm(self) -> float:
        return self.residual_rms

    @property
    def nominal_heldout_rms_nmm(self) -> float:
        return self.nominal_heldout_rms

    @property
    def extended(self) -> ExtendedModel:
        """The simulator/compensator view of :attr:`extended_model`."""
        return ExtendedModel(self.extended_model)

    def to_dict(self) -> dict[str, Any]:
        """The ``bmr-diagnosis/2`` JSON document (JSON-safe: non-finite numbers are null)."""
        def row(e: dict[str, Any]) -> dict[str, Any]:
            return {k: e[src] for k, src in _ROW_KEYS.items() if src in e}

        return jsonable({
            "format": FORMAT,
            "device": self.device,
            "quantities": self.quantities.to_dict(),
            "units": {"input": self.quantities.input.unit, "output": self.quantities.output.unit},
            "cause": self.cause,
            "effects": [row(e) for e in self.effects],
            "rejected": [row(r) for r in self.rejected],
            "noise_floor": self.noise_floor,
            "noise": self.noise,
            "learned": self.learned,
            "residual_rms": self.residual_rms,
            "nominal_heldout_rms": self.nominal_heldout_rms,
            "unexplained": self.unexplained,
            "structure": {"nominal": self.structure_nominal, "extended": self.structure_extended},
            "per_run_rms": {k: {"nominal": b, "extended": a} for k, (b, a) in self.per_run_rms.items()},
            "closed_loop": self.closed_loop,
            "alternatives": [a.to_dict() for a in self.alternatives],
            "identification_drift": self.identification_drift,
            "reidentified_tables": self.reidentified_tables,
            "history": [h.to_dict() for h in self.history],
            "output_rails": self.output_rails.to_dict() if self.output_rails.any else None,
            "folds": self.folds,
            "seed": self.seed,
            "wall_time_s": self.wall_time_s,
        })

    def figures(self) -> dict[str, str]:
        """``{title: base64 PNG}`` (computed once)."""
        if self._figures is None:
            self._figures = figures(self)
        return self._figures

    def html_section(self) -> str:
        return html_section(self)

    def write_report(self, path: str | Path) -> Path:
        """Write the HTML report (atomically)."""
        return write_text(path, html_page(self), what="report")

    def write_json(self, path: str | Path) -> Path:
        """Write the ``bmr-diagnosis/2`` JSON (atomically)."""
        return write_json(path, self.to_dict(), what="diagnosis")

    def __repr__(self) -> str:
        unit = self.quantities.output.unit
        learned = f", learned {self.learned['equation']!r}" if self.learned else ""
        return (f"Diagnosis(cause={self.cause!r}, effects={[e['name'] for e in self.effects]}{learned}, "
                f"held-out RMS {self.nominal_heldout_rms:.3g} -> {self.residual_rms:.3g} {unit}, "
                f"noise {self.noise_floor:.3g} {unit} ({self.noise['method']}))")


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x * x))) if x.size else float("nan")


def nominal_model(bundle: Bundle) -> Any:
    """The model a bundle is diagnosed against when none is given. With first-order runs, the paper's model:
    friction (3 harmonics) from the off-state run, CBH tables from the measured first-order curves alone (no curves
    added between them); least-squares tables at the fixed default resolution when its curves give no tables
    (branches that do not close are a finding: the least-squares fit then estimates a leakage with the table, see
    ``fit_tables_lstsq``). Without them (lab logs, FORC files, loops as an import makes them) the tables
    ``bmr identify`` chooses for the bundle with its defaults, next to the paper's friction: there are no measured
    curves to take the tables from, and an extended model built on coarser tables than the user's own could
    predict worse than them (a friction with more harmonics is a finding, ``friction_harmonics``)."""
    if not bundle.roles().protocol:
        return identify(bundle, max_order=NOMINAL_FRICTION_ORDER)
    try:
        return identify(bundle, method="forc", max_order=NOMINAL_FRICTION_ORDER, subdivisions=1)
    except TableError:
        pass
    # The fixed default resolution and smoothing: the paper's model, not one tuned by cross-validation.
    return identify(bundle, method="lstsq", max_order=NOMINAL_FRICTION_ORDER, subdivisions=1, drift="auto",
                    n_intervals=DEFAULT_INTERVALS, smoothing=DEFAULT_SMOOTHING)


# Least-squares tables identified again from a bundle's training runs (no first-order protocol) are tried only when,
# with nothing removed, they predict the held-out runs within this share of the nominal tables' RMS: beyond it the
# training runs cannot stand for the nominal tables (a single major loop, a density of both signs).
REIDENTIFY_TOLERANCE = 0.25


def _fitters(bundle: Bundle, data: Any, model: Any) -> tuple[list[tuple[str, Fitter]], dict[str, Any]]:
    """The diagnosis's fitters, each named by the runs its candidates identify the core tables again from
    (``Bundle.roles().train``): ``protocol`` (the first-order protocol runs), ``training`` (every training run of a
    bundle without them: lab logs as they come, FORC files, sweeps, loops) or ``none`` (the candidates are judged
    on the nominal tables, their corrections not removed from the training runs). Without a protocol both
    ``training`` and ``none`` are tried, ``training`` only while its tables with nothing removed predict the
    held-out runs within :data:`REIDENTIFY_TOLERANCE` of the nominal ones; the diagnosis keeps the selection that
    predicts the held-out blocks better. Also returns that check's figures."""
    roles = bundle.roles()
    runs = [(r, data.run_start_s[r.name]) for r in roles.train]
    if roles.protocol or not runs:
        return [("protocol" if roles.protocol else "none", Fitter(data, model, runs))], {}
    fitter = Fitter(data, model, runs)
    nominal = heldout(fitter, Configuration(fitter.nominal_path())).rms()
    again = heldout(fitter, Configuration(fitter.nominal_path().with_(reidentify=True))).rms()
    record = {"heldout_rms_nominal": nominal, "heldout_rms_reidentified": again}
    plain = Fitter(data, model, [])
    if again <= (1.0 + REIDENTIFY_TOLERANCE) * nominal:
        return [("training", fitter), ("none", plain)], record
    fitter.release()
    return [("none", plain)], record


def _reidentified_tables(reidentifier: Any, table_runs: dict[str, Any]) -> dict[str, Any]:
    """Which runs the candidates identified the core tables again from (``table_runs``: ``runs`` and the figures
    that chose them, :func:`_fitters`) and how those least-squares tables were regularised: the share of the
    smoothness penalty along the diagonal and the held-out sweep RMS of each share tried (absent when none was
    tried)."""
    out = dict(table_runs)
    if reidentifier.diagonal_chosen is not None:
        share, rms = reidentifier.diagonal_chosen
        if rms:
            out.update({"diagonal_smoothing": share,
                        "sweep_rms": [{"diagonal_smoothing": k, "rms": v} for k, v in rms.items()]})
    return out


@one_blas_thread
def diagnose(bundle: Bundle | str | Path, model: Any = None, *, folds: int = 5, seed: int = 0,
             progress: bool = True, closed_loop: bool = True) -> Diagnosis:
    """Diagnose ``bundle`` (a :class:`bmr.Bundle` or its folder) against ``model`` (default: :func:`nominal_model`:
    the paper's model from the bundle's first-order runs; without any, the tables ``bmr identify`` chooses).
    ``folds``: number of blocked folds (time blocks of every evaluation run); ``seed``: fixes the bootstrap of the
    fold gains (reported next to the t interval). Shows progress on stderr unless ``progress=False``.
    ``closed_loop``: when the bundle records its simulator, measure the tracking error of the extended vs the
    nominal compensator on that plant."""
    from tqdm import tqdm

    t0 = time.perf_counter()
    if isinstance(bundle, (str, Path)):
        bundle = read_bundle(bundle)
    if not isinstance(bundle, Bundle):
        raise BmrError(f"diagnose needs a bmr.Bundle or a bundle folder, got {type(bundle).__name__}")
    if model is None:
        model = nominal_model(bundle)
    elif isinstance(model, (str, Path)):
        model = Model.load(model)
    lo, hi = model.hysteresis.input_range
    data = prepare(bundle, (lo, hi), folds, friction=model.friction)
    fitters, table_runs = _fitters(bundle, data, model)
    fitter = fitters[0][1]
    if data.noise is None:
        # No off-state run, dwell, repeated run or declared uncertainty: the high-frequency part of the nominal
        # residual is the noise.
        r0, _ = fitter.fit(FieldPath.nominal(model), [])
        data.noise = from_residual(np.split(r0, np.cumsum([r.n_eval for r in data.runs])[:-1]))
        data.noise_floor_nmm = data.noise.sigma
    library = [e for e in LIBRARY if data.has_angle or e.name not in ANGLE_EFFECTS]
    bar = tqdm(total=0, file=sys.stderr, desc="bmr diagnose", unit="test", disable=not progress,
               leave=False)
    try:
        selections = [(runs, f, forward_selection(f, library=library, progress=bar)) for runs, f in fitters]
    finally:
        bar.close()
    # Without a protocol: the tables the held-out blocks prefer (on a tie, the nominal ones).
    runs_used, fitter, sel = min(selections, key=lambda x: (x[2]["final_heldout_rms_nmm"], x[0] != "none"))
    for _, f, _ in selections:
        if f is not fitter:
            f.release()
    table_runs = {"runs": runs_used, **table_runs}
    if len(selections) > 1:
        table_runs["final_heldout_rms"] = {runs: s["final_heldout_rms_nmm"] for runs, _, s in selections}
    config = sel["config"]
    accepted = sel["accepted"]
    rng = np.random.default_rng(seed)
    for row in accepted + sel["rejected"]:
        g = np.asarray(row["fold_gains"])
        if g.size == 0:
            # Not evaluated (its mechanism signature was not in the residual): no gain to resample.
            row["gain_interval_bootstrap"] = [0.0, 0.0]
            continue
        boots = g[rng.integers(0, g.size, size=(2000, g.size))].mean(axis=1)
        row["gain_interval_bootstrap"] = [float(np.quantile(boots, 0.025)), float(np.quantile(boots, 0.975))]
    # The cause: the accepted physical effect that removed the most held-out RMS; table_resolution (not physics)
    # only when it is all that was found.
    cause = "none"
    ranked = sorted(accepted, key=lambda e: (e["name"] in PHYSICAL,
                                            e["heldout_rms_before_nmm"] - e["heldout_rms_after_nmm"]))
    if ranked:
        cause = ranked[-1]["name"]

    # Residuals on all data (nominal with its offset, extended) for the figures and the structure study.
    r_nom, _ = fitter.fit(FieldPath.nominal(model), [])
    r_ext, _ = fitter.fit(config.path, config.linear)
    if data.rails.any:
        # Samples at the output's range end say nothing of the model: no residual there.
        r_nom, r_ext = np.where(data.valid, r_nom, 0.0), np.where(data.valid, r_ext, 0.0)
    # The model's entries (its core tables) while the configuration's input history is still prepared: tables the
    # search's cache no longer holds are then one solve, not a new regression after the release.
    zero = stored_zero(config, accepted)
    extensions = extensions_from_selection(config, accepted, zero)
    fitter.release()  # every fit is made: free the regressions and caches before the library is built
    split = np.cumsum([r.n_eval for r in data.runs])[:-1]
    nom_runs, ext_runs = np.split(r_nom, split), np.split(r_ext, split)
    struct_nom = structure(data, nom_runs, lo, hi)
    struct_ext = structure(data, ext_runs, lo, hi)
    resid_rms = sel["final_heldout_rms_nmm"]
    threshold = max(0.25 * data.noise_floor_nmm, 0.1 * resid_rms, 1e-9)
    unexplained = sorted(({"signal": k, "strength": float(v)} for k, v in struct_ext.items() if v > threshold),
                         key=lambda u: -u["strength"])
    learned = None
    if resid_rms > NOISE_MARGIN * data.noise_floor_nmm:
        learned = _learn_discrepancy(data, r_ext, lo, hi, bundle.quantities)
        if learned is not None and learned["accepted"]:
            r_ext = r_ext - learned["prediction"]
            resid_rms = learned["heldout_rms_after"]
            ext_runs = np.split(r_ext, split)
            struct_ext = structure(data, ext_runs, lo, hi)
            unexplained = sorted(({"signal": k, "strength": float(v)} for k, v in struct_ext.items()
                                  if v > threshold), key=lambda u: -u["strength"])
        if learned is not None:
            learned.pop("prediction")
    valid_runs = np.split(data.valid, split)
    per_run = {r.name: (_rms(a[v]), _rms(b[v])) for r, a, b, v in zip(data.runs, nom_runs, ext_runs, valid_runs)}
    signals = {
        "runs": [(r.name, r.t_abs_s[r.start:], a, b) for r, a, b in zip(data.runs, nom_runs, ext_runs)],
        "theta": data.concat(data.eval_slice("theta_rad")),
        "current": data.concat(data.eval_slice("current_a")),
        "rate": data.concat([np.gradient(r.current_a, r.dt_s)[r.start:] for r in data.runs]),
        "nominal": r_nom, "extended": r_ext,
    }
    if learned is not None and learned["accepted"]:
        extensions.append({"name": "learned_discrepancy", "params": {},
                           "terms": [{k: t[k] for k in ("name", "coefficient", "unit", "coefficient_unit")}
                                     for t in learned["terms"]],
                           "intercept": learned["intercept"], "deadband": learned["deadband"],
                           "equation": learned["equation"]})
    # What the memory model cannot explain across each measurement history, and which accepted effect explains it.
    history = history_findings(model, bundle, data.noise_floor_nmm)
    for h in history:
        h.named = [e["name"] for e in accepted if e["name"] in h.candidates]
    ext_model = with_extensions(model, extensions, zero=zero)
    ext_model.meta["diagnosis"] = {"cause": cause, "effects": [e["name"] for e in accepted]}
    d = Diagnosis(device=bundle.actuator, cause=cause, effects=accepted, rejected=sel["rejected"],
                  noise_floor=data.noise_floor_nmm, residual_rms=resid_rms,
                  nominal_heldout_rms=sel["nominal_heldout_rms_nmm"], unexplained=unexplained,
                  structure_nominal=struct_nom, structure_extended=struct_ext, per_run_rms=per_run, folds=folds,
                  seed=seed, wall_time_s=0.0, model=model, extended_model=ext_model, signals=signals,
                  quantities=bundle.quantities, noise=data.noise.to_dict(), learned=learned,
                  alternatives=sel["alternatives"], identification_drift=_identification_drift(model),
                  reidentified_tables=_reidentified_tables(fitter.reidentifier, table_runs), history=history,
                  output_rails=data.rails)
    # What each extension does: held-out prediction for all, closed-loop tracking for those the compensator undoes.
    rows = {e["name"]: e for e in accepted}
    for entry in ext_model.extensions:
        row = rows.get(entry["name"])
        if row is not None:
            entry["heldout"] = {"gain": float(row["gain"]), "rms_before_nmm": float(row["heldout_rms_before_nmm"]),
                                "rms_after_nmm": float(row["heldout_rms_after_nmm"])}
    if closed_loop and bundle.quantities.is_actuator and any(e["name"] in LOOP_STAGES for e in ext_model.extensions):
        sim = bundle.meta.get("simulator") if isinstance(bundle.meta, dict) else None
        plant = _simulator_plant(sim, bundle.sample_rate_hz) if isinstance(sim, dict) and "preset" in sim else None
        try:
            d.closed_loop = closed_loop_gain(d, plant=plant, sample_rate_hz=bundle.sample_rate_hz,
                                             speed_rad_s=_rotor_speed(bundle))
        except BmrError as exc:
            d.closed_loop = {"error": str(exc)}
    d.wall_time_s = time.perf_counter() - t0
    return d


def _identification_drift(model: Any) -> dict[str, float] | None:
    """The leakage the model's least-squares identification fitted with its table because the branches did not
    close (rate: output per input·s; closure: the largest move of a saturation output, share of the span)."""
    report = getattr(model, "identification", None)
    tables = getattr(report, "lstsq", None) if report is not None else None
    if tables is None or tables.leakage_rate is None or getattr(report, "chosen", None) != "lstsq":
        return None
    return {"leakage_rate": float(tables.leakage_rate), "closure": float(tables.closure)}


def _learn_discrepancy(data: Any, residual: np.ndarray, lo: float, hi: float, quantities: Any
                       ) -> dict[str, Any] | None:
    """The sparse regression of what the accepted effects leave (:mod:`bmr.diagnosis.discrepancy`), judged like
    an effect on the blocked folds; None when the runs give no library."""
    from types import SimpleNamespace

    predicted = data.torque - residual
    runs = []
    pos = 0
    for r in data.runs:
        y = np.empty(r.current_a.size)
        y[r.start:] = predicted[pos:pos + r.n_eval]
        y[:r.start] = y[r.start]
        pos += r.n_eval
        runs.append(SimpleNamespace(t_s=np.arange(r.current_a.size) * r.dt_s, u=r.current_a, y=y,
                                    theta=r.theta_rad if data.has_angle else None, start=r.start))
    deadband = 0.01 * (hi - lo)
    lib = candidate_library(runs, deadband)
    if lib.matrix.shape[0] < 4 * data.folds:
        return None
    res = learn(lib, residual, data.block, data.folds, data.noise_floor_nmm, input_unit=quantities.input.unit,
                output_unit=quantities.output.unit)
    g = res.fold_gains
    k = g.size
    half = t975(k - 1) * float(np.std(g, ddof=1)) / math.sqrt(k) if k > 1 else float("inf")
    excess = res.rms_before ** 2 - data.noise_floor_nmm ** 2
    explained = (res.rms_before ** 2 - res.rms_after ** 2) / excess if excess > 0 else 0.0
    accepted = bool(res.terms) and res.folds_positive * 2 > k and res.mean_gain - half > 0 and \
        res.mean_gain >= LEARNED_MIN_GAIN and explained >= MIN_EXCESS
    out = res.to_dict()
    out.update({"accepted": accepted, "gain_interval": [res.mean_gain - half, res.mean_gain + half],
                "excess_explained": float(explained), "deadband": deadband,
                "prediction": res.predict(lib.matrix, lib.names) if accepted else np.zeros(residual.size)})
    return out


class _ModelPlant:
    """The diagnosed extended model as the plant of a closed-loop check (the virtual actuator's interface that
    :func:`bmr.simulation.experiments.tracking` uses): rotor at constant speed, no sensor noise."""

    def __init__(self, model: Any, sample_rate_hz: float, speed_rad_s: float) -> None:
        self.sample_rate_hz = float(sample_rate_hz)
        self.time_s = 0.0
        self._speed = float(speed_rad_s)
        self._sim = ExtendedModel(model).simulation(1.0 / self.sample_rate_hz)

    def theta_ahead(self, n: int) -> np.ndarray:
        return np.mod(self._speed * np.arange(n) / self.sample_rate_hz, 2.0 * np.pi)

    def run(self, current_a: np.ndarray) -> dict[str, np.ndarray]:
        th = self.theta_ahead(len(current_a))
        out = self._sim.run(current_a, th)
        i = np.asarray(current_a, dtype=float)
        return {"current_a": i, "theta_rad": th, "torque_nmm": out["torque_nmm"], "coil1_a": np.maximum(-i, 0.0),
                "coil2_a": np.maximum(i, 0.0)}


def _simulator_plant(sim: dict[str, Any], sample_rate_hz: float) -> Callable[[], Any]:
    preset, effects, seed = sim["preset"], sim.get("effects") or {}, int(sim.get("seed", 0))
    overrides = sim.get("overrides") or None

    def make() -> Any:
        return VirtualActuator(preset, seed=seed, sample_rate_hz=sample_rate_hz, effects=effects,
                               **({"overrides": overrides} if overrides else {}))

    return make


def _rotor_speed(bundle: Bundle) -> float:
    """Median rotor speed (rad/s) of the bundle's runs (1 rad/s when it cannot be told)."""
    speeds = []
    for r in bundle.runs:
        th = np.unwrap(np.asarray(r.theta, dtype=float))
        if th.size > 1:
            speeds.append(abs(th[-1] - th[0]) / max(float(r.t[-1] - r.t[0]), 1e-12))
    v = float(np.median(speeds)) if speeds else 0.0
    return v if math.isfinite(v) and v > 0 else 1.0


def _tracking_rms(make_plant: Callable[[], Any], comp: Any, ref: np.ndarray, fs: float) -> float:
    run = tracking(make_plant(), comp, ref, opening_duration_s=2.0)
    k = int(run.meta.get("opening_end_s", 0.0) * fs)
    return _rms(run.torque[k:] - run.column("reference_nmm")[k:])


# The closed-loop check's multi-peak reference: at least this long (s), and long enough for the slowest stage state
# to matter (CHECK_TIME_CONSTANTS of its time constant), but at most CHECK_MAX_S.
CHECK_MIN_S = 20.0
CHECK_TIME_CONSTANTS = 2.0
CHECK_MAX_S = 300.0


def check_duration_s(model: Any) -> float:
    """Length (s) of the closed-loop check's reference for ``model``'s stages. A stage with a slow state (the
    ``thermal_drift`` heating, time constant ``tau_s``) changes nothing in a run much shorter than its time
    constant: from cold coils a 20 s run heats to a few per cent of the steady state, so the check would judge the
    stage on the tables' error instead of on the heating it undoes."""
    slowest = model.extension_params("thermal_drift").get("tau_s", 0.0)
    return float(min(max(CHECK_MIN_S, CHECK_TIME_CONSTANTS * slowest), CHECK_MAX_S))


def closed_loop_gain(d: Diagnosis, plant: Callable[[], Any] | None = None, *, sample_rate_hz: float = 500.0,
                     duration_s: float | None = None, speed_rad_s: float = 1.0) -> dict[str, Any]:
    """Closed-loop check of the extended compensator: tracking error (RMS of measured − reference torque, N·mm,
    after the opening) on the multi-peak torque reference (``duration_s``, default :func:`check_duration_s`),
    nominal compensator against extended ones, on ``plant()`` (a fresh virtual actuator per run: the simulator
    that made the bundle) or, without one, on the diagnosed extended model itself (rotor at ``speed_rad_s``).

    Every extension the compensator can undo is judged in the company of the others: starting from all of them,
    the one whose removal cuts the error most is removed while any removal does, so each stage left in helps
    (``ratio`` = error with it / error without it, below 1) and each stage taken out hurt. The model's extension
    entries get ``tracking`` and ``in_loop``; ``ratio`` = the extended compensator (the stages left in) /
    nominal."""
    fs = float(sample_rate_hz)
    dt = 1.0 / fs
    ext = d.extended_model
    if duration_s is None:
        duration_s = check_duration_s(ext)
    ref = reference_multipeak(MULTIPEAK_SEED, sample_rate_hz=fs, duration_s=duration_s)
    if plant is None:
        model_plant = ext

        def plant() -> Any:
            return _ModelPlant(model_plant, fs, speed_rad_s)

        where = "model"
    else:
        where = "simulator"
    stages = [n for n in LOOP_STAGES if ext.extension(n) is not None]

    def rms_with(names: list[str]) -> float:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            comp = ext.compensator(dt, stages=names)
        return _tracking_rms(plant, comp, ref, fs)

    nominal = _tracking_rms(plant, d.model.compensator(), ref, fs)
    kept = list(stages)
    err = rms_with(kept)
    all_err = err
    verdict: dict[str, dict[str, Any]] = {}
    while kept:
        without = {n: rms_with([k for k in kept if k != n]) for n in kept}
        worst = min(without, key=lambda n: without[n])
        if without[worst] < err:
            verdict[worst] = {"ratio": err / without[worst], "in_loop": False}
            kept.remove(worst)
            err = without[worst]
            continue
        for n in kept:
            verdict[n] = {"ratio": err / without[n] if without[n] > 0 else float("nan"), "in_loop": True}
        break
    for entry in ext.extensions:
        v = verdict.get(entry["name"])
        if v is not None:
            entry["tracking"] = {"ratio": float(v["ratio"]), "plant": where, "reference": "multipeak"}
            entry["in_loop"] = bool(v["in_loop"])
    return {"plant": where, "reference": "multipeak", "duration_s": duration_s, "nominal_rms_nmm": nominal,
            "extended_rms_nmm": err, "all_stages_rms_nmm": all_err, "stages_on": kept,
            "stages": {n: verdict[n] for n in stages}, "ratio": err / nominal if nominal > 0 else float("nan")}


def run_cli(args: Any) -> int:
    """``bmr diagnose BUNDLE [--model M] [--json OUT] [--report OUT.html] [--model-out OUT.json]``: print the
    named cause and the selection, write the JSON, the HTML report and the extended model file on request."""
    # Outputs that cannot be written fail now, not after the whole diagnosis.
    if args.json_out:
        check_output_file(args.json_out, "diagnosis JSON")
    if args.report:
        check_output_file(args.report, "report")
    if args.model_out:
        check_output_file(args.model_out, "model file", error=ModelFileError)
    d = diagnose(args.bundle, args.model, folds=args.folds, seed=args.seed)
    q = d.quantities
    u = q.output.unit
    print(f"bmr diagnose: {d.device} ({q.describe()}): cause {d.cause}; held-out RMS "
          f"{q.output.format(d.nominal_heldout_rms, 4)} -> {q.output.format(d.residual_rms, 4)} "
          f"(noise floor {q.output.format(d.noise_floor, 4)}, {d.noise['method'].replace('_', ' ')}), "
          f"{d.wall_time_s:.1f} s")
    for e in d.effects:
        params = ", ".join(f"{k}={v:.4g}" for k, v in e["params"].items())
        pair = f" (accepted together with {e['paired_with']}: each is needed once the other is in)" \
            if e.get("paired_with") else ""
        print(f"  accepted {e['name']}: gain {100 * e['gain']:.1f} % ({e['folds_positive']}/{d.folds} folds){pair}, "
              f"{params}")
    for r in d.rejected:
        why = f"; {r['reason']}" if r.get("reason", "").startswith("parameters outside") else ""
        print(f"  rejected {r['name']}: gain {100 * r['gain']:.1f} % ({r['folds_positive']}/"
              f"{r.get('folds_evaluated', d.folds)} folds){why}")
    for a in d.alternatives:
        print(f"  {a.message}")
    if d.output_rails.any:
        print(f"  {d.output_rails.describe(q.output)}")
    tables = d.reidentified_tables or {}
    finals = tables.get("final_heldout_rms")
    if finals:
        kept = "training runs" if tables["runs"] == "training" else "nominal tables"
        print(f"  no first-order runs: the candidates were selected on tables identified again from the training runs "
              f"({q.output.format(finals['training'], 4)} held out) and on the nominal tables "
              f"({q.output.format(finals['none'], 4)}); kept the {kept}")
    elif "heldout_rms_nominal" in tables:
        print(f"  no first-order runs: judged on the nominal tables (the training runs' least-squares tables predict "
              f"{q.output.format(tables['heldout_rms_reidentified'], 4)} held out against "
              f"{q.output.format(tables['heldout_rms_nominal'], 4)})")
    if d.identification_drift:
        print(f"  identification: branches open by {100 * d.identification_drift['closure']:.3g} % of the span; "
              f"leakage {d.identification_drift['leakage_rate']:.4g} {q.output.unit} per {q.input.unit}·s fitted "
              "with the tables")
    for h in d.history:
        for line in h.lines(q):
            print(f"  {line}")
    if d.learned:
        state = "learned" if d.learned["accepted"] else "not kept"
        print(f"  {state} (no named effect): {d.learned['equation']}; gain {100 * d.learned['gain']:.1f} % "
              f"({d.learned['folds_positive']}/{d.folds} folds)")
    for un in d.unexplained:
        print(f"  unexplained structure against {signal_label(un['signal'], q)}: "
              f"{q.output.format(un['strength'], 3)} RMS")
    c = d.closed_loop or {}
    if "ratio" in c:
        print(f"  closed loop on the {c['plant']} ({c['duration_s']:g} s multi-peak): tracking RMS "
              f"{c['nominal_rms_nmm']:.2f} (nominal) -> "
              f"{c['extended_rms_nmm']:.2f} {u} (extended), ratio {c['ratio']:.2f}; all stages "
              f"{c['all_stages_rms_nmm']:.2f} {u}")
        for name, v in c["stages"].items():
            state = "on " if v["in_loop"] else "OFF"
            print(f"    stage {state} {name}: tracking ratio {v['ratio']:.2f} (with / without it)")
        for name, v in c["stages"].items():
            if not v["in_loop"]:
                print(f"  warning: {name} made closed-loop tracking worse (ratio {v['ratio']:.2f}): the compensator "
                      "leaves it off (Model.compensator(stages='all') to use it anyway)", file=sys.stderr)
    elif "error" in c:
        print(f"  closed loop: not measured ({c['error']})")
    if args.json_out:
        d.write_json(args.json_out)
        print(f"  wrote {args.json_out}")
    if args.report:
        d.write_report(args.report)
        print(f"  wrote {args.report}")
    if args.model_out:
        d.extended_model.save(args.model_out)
        print(f"  wrote {args.model_out} (bmr.Compensator.from_model, bmr export)")
        if args.model is None:
            # The diagnosis's nominal is the paper's model (measured curves alone); identify's default tables are
            # often finer, and an extended model is only as good as the core it extends.
            print("  it extends the nominal model of the measured curves alone; to extend the model `bmr identify` "
                  "chose, pass --model model.json")
    return 0

