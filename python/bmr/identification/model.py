"""The identified model of one device (friction + CBH tables) and its versioned file format ``bmr-model/2``.

File layout (JSON)::

    {"format": "bmr-model/2",
     "quantities": {"input": {"name": "current", "unit": "A", "column": "current_a"},
                    "output": {"name": "torque", "unit": "N·mm", "column": "torque_nmm"},
                    "angle": {"name": "angle", "unit": "rad", "column": "theta_rad"} | null},
     "friction": {"c0": ..., "a": [...], "b": [...], "order": K, "stderr": {...}} | null,
     "hysteresis": {"ascending": [[[u...], [y...]], ...], "descending": [[[u...], [y...]], ...],
                    "initial": "negative", "build": {"subdivisions": 4, "node_tolerance": 1e-4},
                    "signed_table": {"nodes": [...], "masses": [...], "offset": y0}},
     "limits": {"<input column>": [lo, hi], "<output column>": [lo, hi]},
     "converter_gain_a_per_v": 0.125,
     "extensions": [{"name": ..., "params": {...}, "tracking": {...}, "in_loop": true}, ...],
     "meta": {...},
     "sha256": "..."}

``quantities`` says what the tables map (input and output in their units; the friction series, in output units,
needs an angle). ``bmr-model/1`` files (the same without ``quantities``) load as the BMR actuator's model
(current A → torque N·mm, angle rad). ``sha256`` is the digest of the canonical JSON of everything else: a
damaged file is reported as such. Loading a missing, unknown or newer format is an error that names the format
found; every other problem is a ``bmr.ModelFileError`` naming the field. Non-finite numbers are stored as ``null``
(a friction score that could not be computed reads back as infinity). Files are written atomically, and a model
that cannot be read back is refused before anything is written: every model that saves, loads, and saves again to
the same bytes.

``hysteresis.signed_table`` (optional) is a Preisach table whose cell masses are free in sign, identified where the
loops run clockwise (the output leads the input; ``bmr.identification.lstsq``) or where a family of first-order
reversal curves is predicted clearly better with negative regions in the density (interacting particles;
``bmr.identification.table_choice``): the forward core of :meth:`Model.simulate`, on its grid ``nodes`` (input
unit), from negative saturation at output ``offset``. The curves beside it are the nonnegative table's (the
monotone operator the stages and the diagnosis run). A signed table has no exact inverse: where its loops run
clockwise the model refuses a compensator and a firmware export; where they run counter-clockwise the compensator
inverts the nonnegative table beside it, with a warning (:meth:`Model.signed_loops_turn_clockwise`).

``extensions`` are the effects a diagnosis added (names and parameters from the effect vocabulary,
``bmr.effect_parameters(model_entries=True)``; an unknown name or an out-of-range parameter is an error at load
time). An entry may carry ``tables`` (``core_tables``: the hysteretic core's own curves), ``tracking`` (its
measured effect on closed-loop tracking) and ``in_loop`` (false: the closed-loop check found that it hurts, so
the compensator leaves it off unless asked).
"""
from __future__ import annotations

import copy
import hashlib
import json
import math
import numbers
import re
import warnings
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from bmr import _core
from bmr._core import BmrError, Compensator, Hysteresis, ModelFileError, ResourceLimitError
from bmr.data.files import jsonable, path_kind, read_json, write_text
from bmr.data.quantities import ACTUATOR, Quantities
from bmr.identification.friction import FrictionFit
from bmr.identification.lstsq import CLOCKWISE_SHARE, loop_orientation

__all__ = ["FORMAT", "LOOP_STAGES", "Model"]

# Extensions the compensator can undo, in the order the physics acts (the vocabulary's loop order; the others
# are measurement-only or notes).
LOOP_STAGES: tuple[str, ...] = _core.LOOP_STAGES

FORMAT = "bmr-model/2"
FORMATS = ("bmr-model/1", FORMAT)
_FAMILY = "bmr-model/"
_VERSION = 2


def _digest(content: dict[str, Any]) -> str:
    canonical = json.dumps(content, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(canonical.encode()).hexdigest()


class Model:
    """Friction + CBH hysteresis of one device.

    ``hysteresis``: a ``bmr.Hysteresis``; ``friction``: a ``FrictionFit`` (callable on angles, with ``c0, a, b``)
    or None; ``quantities``: what the input and output are (default: the BMR actuator's current A → torque N·mm);
    ``limits``: ``{input column: [lo, hi], output column: [lo, hi]}`` (e.g. ``current_a``, ``torque_nmm``);
    ``converter_gain_a_per_v``: the voltage-to-current converter gain (paper: 0.125 A/V); ``extensions``:
    discovered effects ``[{"name": ..., "params": {...}}]``; ``meta``: free information (identification report);
    ``signed_table``: a ``bmr._core.EverettModel`` with masses free in sign (loops that run clockwise), the forward
    core of :meth:`simulate` when given (no compensator then).
    """

    def __init__(
        self,
        hysteresis: Any,
        friction: FrictionFit | None = None,
        *,
        limits: dict[str, Sequence[float]] | None = None,
        converter_gain_a_per_v: float = 0.125,
        extensions: Sequence[dict[str, Any]] | None = None,
        meta: dict[str, Any] | None = None,
        curves: tuple[list[tuple[np.ndarray, np.ndarray]], list[tuple[np.ndarray, np.ndarray]]] | None = None,
        quantities: Quantities = ACTUATOR,
        signed_table: Any = None,
    ) -> None:
        if not isinstance(quantities, Quantities):
            raise TypeError(f"quantities must be a bmr.data.quantities.Quantities, got {type(quantities).__name__}")
        if not (_is_number(converter_gain_a_per_v) and math.isfinite(converter_gain_a_per_v)
                and converter_gain_a_per_v > 0):
            raise BmrError(f"converter_gain_a_per_v must be positive and finite (A/V), got {converter_gain_a_per_v!r}")
        self.hysteresis = hysteresis
        self.signed_table = signed_table
        self.friction = friction
        # The first-order curves the hysteresis was built from (saved instead of its resampled tables: the build
        # is deterministic, and the source curves are usually far smaller).
        self._source_curves = curves
        self.converter_gain_a_per_v = float(converter_gain_a_per_v)
        self.extensions = [dict(e) for e in (extensions or [])]
        _core.check_extensions(self.extensions)
        self.meta = dict(meta or {})
        self.quantities = quantities
        lo, hi = hysteresis.input_range
        ylo, yhi = hysteresis.output_range
        self._build: dict[str, Any] = {}
        self._forward: tuple[Any, Any] | None = None  # (signed table, its operator): see forward_hysteresis
        # What identify() did (an IdentificationReport; its to_dict() is meta["identification"]).
        self.identification: Any = None
        self.limits = {quantities.input.column: [float(lo), float(hi)],
                       quantities.output.column: [float(ylo), float(yhi)]}
        for key, value in (limits or {}).items():
            self.limits[key] = _limit(key, value, "limits")

    @classmethod
    def from_curves(cls, ascending: Sequence[tuple[Any, Any]], descending: Sequence[tuple[Any, Any]],
                    friction: FrictionFit | None = None, *, initial: str = "negative",
                    build: dict[str, Any] | None = None, **kwargs: Any) -> "Model":
        """Build the ``bmr.Hysteresis`` from first-order curves (``from_curves`` form) and wrap it. ``build``:
        options of ``bmr.Hysteresis.from_curves`` (``subdivisions``, ``node_tolerance``, ...), kept in the model
        file so that loading rebuilds the same operator."""
        asc = [(np.asarray(u, float), np.asarray(y, float)) for u, y in ascending]
        desc = [(np.asarray(u, float), np.asarray(y, float)) for u, y in descending]
        build = _build_options(build or {}, "from_curves")
        model = cls(Hysteresis.from_curves(asc, desc, initial=initial, **build), friction, curves=(asc, desc),
                    **kwargs)
        model._build = build
        return model

    @property
    def input_limits(self) -> tuple[float, float]:
        """The input range the model was identified on (input unit)."""
        lo, hi = self.limits[self.quantities.input.column]
        return float(lo), float(hi)

    @property
    def output_limits(self) -> tuple[float, float]:
        """The output range of the model's major loop (output unit)."""
        lo, hi = self.limits[self.quantities.output.column]
        return float(lo), float(hi)

    # ------------------------------------------------------------------------------------------- use
    def friction_torque(self, theta_rad: Any) -> np.ndarray:
        """Friction (output unit, N·mm for the actuator) at rotor angles ``theta_rad`` (zeros without a friction
        model)."""
        theta = np.asarray(theta_rad, dtype=float)
        return self.friction(theta) if self.friction is not None else np.zeros(theta.shape)

    def simulate(self, current: Any, theta: Any = None, *, initial: Any = "negative",
                 history: Sequence[float] | None = None, out_of_range: str = "clamp") -> np.ndarray:
        """Output (``quantities.output``; torque in N·mm for the actuator) for the input ``current``
        (``quantities.input``; nominal current in A for the actuator) and angle ``theta`` (rad; None: no friction),
        starting from the ``initial`` state (``"negative"``, ``"positive"``, ``("ascending", u)``,
        ``("descending", u)``) followed by the inputs of ``history`` (an initial memory, e.g. an estimated
        ``[hi, b]``: positive saturation, then down to ``b``).

        Inputs outside the table's input range: ``out_of_range="clamp"`` (default: the operator saturates, as
        the real-time core does) or ``"extrapolate"`` (the output continues along the major branch's end slope
        beyond each end; the memory still saturates). ``input_excess`` counts such samples."""
        i_a = _real_array(current, "current")
        if i_a.ndim != 1:
            raise BmrError(f"current must be one-dimensional, got shape {i_a.shape}")
        bad = np.flatnonzero(~np.isfinite(i_a))
        if bad.size:
            raise BmrError(f"current sample {int(bad[0])} is not finite ({i_a[bad[0]]!r})")
        if out_of_range not in ("clamp", "extrapolate"):
            raise BmrError(f"out_of_range must be 'clamp' or 'extrapolate', got {out_of_range!r}")
        hist = np.zeros(0)
        if history is not None and len(history):
            hist = np.asarray(history, dtype=float)
            if hist.ndim != 1 or not np.all(np.isfinite(hist)):
                raise BmrError("history must be a one-dimensional sequence of finite inputs")
        lo, hi = self.hysteresis.input_range
        if self.signed_table is not None:
            y = np.asarray(self.signed_table.simulate(i_a, None, self._table_history(initial, hist)), dtype=float)
        else:
            # A copy: simulating never changes the model (its operator may be shared with a compensator).
            h = copy.copy(self.hysteresis)
            h.reset(initial=initial)
            if hist.size:
                h.run(hist)
            y = np.asarray(h.run(i_a), dtype=float)
        if out_of_range == "extrapolate":
            s_lo, s_hi = self.end_slopes()
            y = y + s_hi * np.maximum(i_a - hi, 0.0) + s_lo * np.minimum(i_a - lo, 0.0)
        if theta is not None:
            th = _real_array(theta, "theta")
            if th.shape != i_a.shape:
                raise BmrError(f"theta has shape {th.shape} but current has {i_a.shape}")
            y = y + self.friction_torque(th)
        return y

    def _table_history(self, initial: Any, history: np.ndarray) -> np.ndarray:
        """The inputs after negative saturation that give the signed table the ``initial`` state of
        :meth:`simulate`, followed by ``history``."""
        hi = float(self.signed_table.grid[-1])
        if isinstance(initial, str) and initial in ("negative", "positive"):
            start = [] if initial == "negative" else [hi]
        elif isinstance(initial, (tuple, list)) and len(initial) == 2 and initial[0] in ("ascending", "descending") \
                and _is_number(initial[1]) and math.isfinite(initial[1]):
            start = [float(initial[1])] if initial[0] == "ascending" else [hi, float(initial[1])]
        else:
            raise BmrError(f"initial must be 'negative', 'positive', ('ascending', u) or ('descending', u), "
                           f"got {initial!r}")
        return np.concatenate([np.asarray(start, dtype=float), history])

    def signed_loops_turn_clockwise(self) -> bool:
        """Whether the signed table's own major loop runs clockwise (the output leads the input: a rate-driven
        output with no hysteretic inverse), measured on the table, not read from how it was identified. False
        without a signed table; a signed table whose loops run counter-clockwise is a Preisach system with
        negative regions in its density (interacting particles in a FORC diagram)."""
        if self.signed_table is None:
            return False
        lo, hi = self.hysteresis.input_range
        u = np.concatenate([np.linspace(lo, hi, 201), np.linspace(hi, lo, 201)[1:]])
        y = np.asarray(self.signed_table.simulate(u, None, self._table_history("negative", np.zeros(0))), dtype=float)
        return loop_orientation([u], [y]) >= CLOCKWISE_SHARE

    def _refuse_signed(self, what: str) -> None:
        if self.signed_loops_turn_clockwise():
            raise BmrError(f"no {what}: this model's core is a signed Preisach table whose loops run clockwise (the "
                           "output leads the input, a rate-driven output); exact inversion needs a nonnegative "
                           "density, whose branches are monotone")
        if self.signed_table is not None:
            warnings.warn(f"the {what} inverts the nonnegative table fitted beside this model's signed core (exact "
                          "inversion needs monotone branches): the signed density's negative regions are not "
                          "compensated", stacklevel=3)

    def extension(self, name: str) -> dict[str, Any] | None:
        """The extension entry ``name`` (None if the model has none)."""
        return next((e for e in self.extensions if e.get("name") == name), None)

    def extension_params(self, name: str) -> dict[str, float]:
        """Parameters of extension ``name`` with the vocabulary's defaults filled in ({} if absent)."""
        e = self.extension(name)
        if e is None:
            return {}
        (full,) = _core.check_extensions([{"name": name, "params": e.get("params") or {}}])
        return dict(full["params"])  # type: ignore[call-overload]

    @property
    def full_torque_nmm(self) -> float:
        """Full-scale torque of the model's tables (N·mm): the largest |torque| they reach."""
        lo, hi = self.hysteresis.output_range
        return float(max(abs(lo), abs(hi), 1e-9))

    @property
    def full_current_a(self) -> float:
        """The current limit (input unit; A for the actuator): the largest |input| the model was identified on,
        the thermal model's unit heating."""
        lo, hi = self.input_limits
        return float(max(abs(lo), abs(hi)))

    def forward_hysteresis(self) -> Any:
        """The operator nearest the one :meth:`simulate` runs, as a ``bmr.Hysteresis`` (shared: copy it before
        running it): with a signed table, the CBH operator of its first-order curves (built once) when that is
        nearer the table than :attr:`hysteresis` (:meth:`_signed_operator`); else :attr:`hysteresis`. Forward
        only: a compensator inverts :attr:`hysteresis` (see :meth:`compensator`)."""
        table = self.signed_table
        if table is None:
            return self.hysteresis
        if self._forward is None or self._forward[0] is not table:
            self._forward = (table, self._signed_operator(table))
        return self._forward[1]

    def _signed_operator(self, table: Any) -> Any:
        """Of the CBH operator built from the signed ``table``'s first-order curves and :attr:`hysteresis` (the
        nonnegative table), the one closer to the table on a decaying alternating probe: the built one reproduces
        a density negative in places whose branches stay monotone (interacting particles: FeCo nanowires 6e-4 of
        the span, the nonnegative table 8e-3), not branches it refuses or reshapes (loops that run clockwise)."""
        asc, desc = table.first_order_curves()
        try:
            op = Hysteresis.from_curves([(np.asarray(u), np.asarray(y)) for u, y in asc],
                                        [(np.asarray(u), np.asarray(y)) for u, y in desc])
        except BmrError:
            return self.hysteresis
        lo, hi = (float(v) for v in table.grid[[0, -1]])
        # Reversals at decreasing amplitude about the middle, each sweep sampled finely.
        mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
        turns = [hi] + [mid + s * half * a for a in np.linspace(1.0, 0.05, 24) for s in (-1.0, 1.0)][1:]
        probe = np.concatenate([np.linspace(a, b, 40)[1:] for a, b in zip([lo] + turns[:-1], turns)])
        want = np.asarray(table.simulate(probe, None, np.zeros(0)), dtype=float)

        def deviation(h: Any) -> float:
            run = copy.copy(h)
            run.reset(initial="negative")
            return float(np.max(np.abs(np.asarray(run.run(probe), dtype=float) - want)))

        return op if deviation(op) < deviation(self.hysteresis) else self.hysteresis

    def core_hysteresis(self, *, refined: bool = True, forward: bool = False) -> Any:
        """The hysteretic core of the extended model: the ``core_tables`` entry's curves when the model has them
        (and ``refined``), else the model's tables (``forward``: those :meth:`simulate` runs, the signed table's
        when there is one; else the nonnegative ones a compensator inverts), mapped through the inverse of a
        ``non_congruent`` output map."""
        tr = self.extension("core_tables")
        if refined and tr is not None and tr.get("tables"):
            t = tr["tables"]
            try:
                return Hysteresis.from_curves(_curves(t["ascending"], "core_tables.ascending"),
                                              _curves(t["descending"], "core_tables.descending"))
            except (KeyError, TypeError) as exc:
                raise BmrError(f"core_tables entry: expected 'ascending' and 'descending' curves ({exc})") from None
        p = self.extension_params("non_congruent")
        cubic = p.get("cubic", 0.0) if p else 0.0
        operator = self.forward_hysteresis() if forward else self.hysteresis
        if not p or (p["curvature"] == 0.0 and cubic == 0.0):
            return copy.copy(operator)
        scale = p["scale_nmm"] or self.full_torque_nmm

        def fam(curves: Any) -> list[tuple[np.ndarray, np.ndarray]]:
            out = []
            for u, y in curves:
                core = _core.output_map_inverse(np.asarray(y, float), p["curvature"], scale, cubic)
                # The mapped curves stay monotone up to round-off; clamp the round-off.
                core = np.maximum.accumulate(core) if core[-1] >= core[0] else np.minimum.accumulate(core)
                out.append((np.asarray(u, float), core))
            return out

        if operator is not self.hysteresis:
            return Hysteresis.from_curves(*(fam(c) for c in operator.curves()))
        asc, desc = self._source_curves if self._source_curves is not None else self.hysteresis.curves()
        return Hysteresis.from_curves(fam(asc), fam(desc), **self._build)

    def stage_plan(self, stages: Any = None) -> list[dict[str, Any]]:
        """Which extensions the compensator undoes, and why: ``[{"name", "on", "reason", "tracking"}]`` for every
        extension it could undo (measurement-only ones are not listed). ``stages``: None (every extension the
        closed-loop check did not find harmful), ``"all"``, or a list of names."""
        available = [e for e in self.extensions if e.get("name") in LOOP_STAGES]
        names = [e["name"] for e in available]
        if isinstance(stages, str) and stages != "all":
            raise BmrError(f"stages={stages!r}: expected None, 'all' or a list of extension names")
        if stages is not None and not isinstance(stages, str):
            wanted = list(stages)
            for n in wanted:
                if n not in names:
                    raise BmrError(f"stage {n!r} is not among this model's extensions that can be compensated "
                                   f"({', '.join(names) or 'none'})")
        plan = []
        for e in available:
            tracking = e.get("tracking") if isinstance(e.get("tracking"), dict) else None
            ratio = tracking.get("ratio") if tracking else None
            measured = (f"closed-loop tracking ratio {ratio:.2f} on the {tracking.get('plant', 'model')}"
                        if isinstance(ratio, (int, float)) else "no closed-loop measurement")
            if stages == "all":
                on, why = True, f"all stages asked for ({measured})"
            elif stages is not None:
                on = e["name"] in wanted
                why = f"{'asked for' if on else 'not asked for'} ({measured})"
            elif e.get("in_loop", True) is False:
                on, why = False, f"left off: it made tracking worse ({measured})"
            else:
                on, why = True, f"on: {measured}" if ratio is not None else "on: " + measured
            plan.append({"name": e["name"], "on": on, "reason": why, "tracking": tracking})
        return plan

    def end_slopes(self) -> tuple[float, float]:
        """Slopes (output per input) of the major branches where they meet the ends of the input range: the
        descending major branch at the lowest input, the ascending one at the highest (used to extrapolate)."""
        asc, desc = self.hysteresis.curves()
        ua, ya = np.asarray(asc[0][0]), np.asarray(asc[0][1])
        ud, yd = np.asarray(desc[0][0]), np.asarray(desc[0][1])
        s_hi = float((ya[-1] - ya[-2]) / (ua[-1] - ua[-2])) if ua.size > 1 else 0.0
        s_lo = float((yd[-1] - yd[-2]) / (ud[-1] - ud[-2])) if ud.size > 1 else 0.0
        return s_lo, s_hi

    def input_excess(self, current: Any) -> tuple[int, float]:
        """How many samples of ``current`` lie outside the table's input range, and the largest distance beyond
        it (input units; 0 when none)."""
        u = np.asarray(current, dtype=float)
        lo, hi = self.hysteresis.input_range
        excess = np.maximum(u - hi, 0.0) + np.maximum(lo - u, 0.0)
        excess[excess <= 1e-9 * (hi - lo)] = 0.0  # round-off at the ends is not beyond them
        return int(np.count_nonzero(excess)), float(excess.max()) if excess.size else 0.0

    def compensator(self, dt_s: float | None = None, *, stages: Any = None, **kwargs: Any) -> Any:
        """The full compensator of this model, built in the core: friction and converter gain filled in, the
        extensions made into stages at control period ``dt_s`` (s; needed when the model has extensions).
        ``stages``: see :meth:`stage_plan` (default: every extension the closed-loop check did not find
        harmful; the ones left off, or asked for although they hurt, are named in a warning). ``kwargs`` pass
        through to ``bmr.Compensator`` (e.g. ``inverse="paper"``, ``initial``). A model with a signed table
        whose loops run clockwise has no hysteretic inverse: a ``BmrError`` says so; with a signed table whose loops
        run counter-clockwise the compensator inverts the nonnegative table fitted beside it (a warning says so)."""
        self._refuse_signed("compensator")
        friction = self.friction.to_friction() if self.friction is not None else None
        kwargs.setdefault("converter_gain", self.converter_gain_a_per_v)
        lo, hi = self.input_limits
        kwargs.setdefault("current_limit", max(abs(lo), abs(hi)))
        plan = self.stage_plan(stages)
        for row in plan:
            ratio = (row["tracking"] or {}).get("ratio")
            hurts = isinstance(ratio, (int, float)) and ratio > 1.0
            if hurts and row["on"]:
                warnings.warn(f"extension {row['name']} is in the loop although it made closed-loop tracking "
                              f"worse (ratio {ratio:.2f})", stacklevel=2)
            elif not row["on"] and stages is None:
                warnings.warn(f"extension {row['name']} {row['reason']}; pass stages='all' or a list to use it",
                              stacklevel=2)
        on = [row["name"] for row in plan if row["on"]]
        if not on:
            return Compensator(self.hysteresis, friction, **kwargs)
        effects = [e for e in self.extensions if e["name"] in on and e["name"] != "core_tables"]
        needs_dt = any(e["name"] in _core.PERIOD_EFFECTS for e in effects)
        if needs_dt and dt_s is None:
            raise BmrError(f"this model's extensions ({', '.join(on)}) need the control period: pass dt_s")
        core = self.core_hysteresis(refined="core_tables" in on)
        return Compensator(core, friction, extensions=effects, dt_s=dt_s, full_torque_nmm=self.full_torque_nmm,
                           **kwargs)

    def export(self, path: str | Path, language: str, *, stages: Any = None, prefix: str = "bmr") -> Path:
        """Write the compensator (:meth:`compensator` with ``stages``) as firmware source: ``language`` "rust"
        (static tables and ``model::compensator(dt_s)`` for the no_std crate) or "c" (arrays and
        ``<prefix>_model`` for ``bmr_compensator_init`` of the C ABI, ``include/bmr.h``). The control period is
        the firmware's: it is given when the compensator is built there."""
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            # Any valid period builds the stages here; the source carries their parameters, not the period.
            comp = self.compensator(1e-3, stages=stages)
        names = ", ".join(comp.stages) or "none"
        digest = _digest(self.to_dict())[:16]
        title = f"bmr compensator of model {digest} (stages: {names})"
        text = _core.export_source(comp, language, title=title, prefix=prefix)
        return write_text(path, text, what=f"{language} source")

    def current_curves(self) -> tuple[list[tuple[np.ndarray, np.ndarray]], list[tuple[np.ndarray, np.ndarray]]]:
        """The paper's current curves (torque → current) from the stored torque curves."""
        return self.hysteresis.current_curves()

    # --------------------------------------------------------------------------------------- files
    def to_dict(self) -> dict[str, Any]:
        """The ``bmr-model/2`` content (without the digest)."""
        asc, desc = self._source_curves if self._source_curves is not None else self.hysteresis.curves()

        def fam(curves: Any) -> list[list[list[float]]]:
            return [[[float(v) for v in u], [float(v) for v in y]] for u, y in curves]

        hyst: dict[str, Any] = {"ascending": fam(asc), "descending": fam(desc), "initial": "negative"}
        if self._source_curves is not None and self._build:
            hyst["build"] = dict(self._build)
        if self.signed_table is not None:
            t = self.signed_table
            hyst["signed_table"] = {"nodes": [float(v) for v in t.grid], "masses": [float(v) for v in t.masses],
                                    "offset": float(t.offset)}
        return {
            "format": FORMAT,
            "quantities": self.quantities.to_dict(),
            "friction": jsonable(self.friction.to_dict()) if self.friction is not None else None,
            "hysteresis": hyst,
            "limits": self.limits,
            "converter_gain_a_per_v": self.converter_gain_a_per_v,
            "extensions": self.extensions,
            "meta": jsonable(self.meta),
        }

    def save(self, path: str | Path) -> Path:
        """Write the model as ``bmr-model/2`` JSON (with its sha256 digest), atomically. A model whose file would
        not load (its tables do not rebuild from the stored curves, say) is refused before anything is written."""
        try:
            content = self.to_dict()
            content["sha256"] = _digest(content)
            text = json.dumps(content, indent=1, allow_nan=False)
        except RecursionError:
            raise ModelFileError(f"cannot save the model to {str(path)!r}: its meta is nested too deeply") from None
        try:
            Model.from_dict(json.loads(text), source="model to save")
        except BmrError as exc:
            raise ModelFileError(f"cannot save the model to {str(path)!r}: it would not load back ({exc})") from None
        return write_text(path, _compact_number_lists(text) + "\n", what="model file", error=ModelFileError)

    @classmethod
    def from_dict(cls, content: Any, *, source: str = "model") -> "Model":
        """Rebuild a model from ``bmr-model/1`` or ``/2`` content; every problem is a ``ModelFileError`` naming the
        field."""
        try:
            return cls._from_dict(content, source)
        except RecursionError:
            raise ModelFileError(f"{source}: nested too deeply to be a model") from None
        except (ModelFileError, ResourceLimitError):
            raise
        except BmrError as exc:
            msg = str(exc)
            raise ModelFileError(msg if msg.startswith(source) else f"{source}: {msg}") from None

    @classmethod
    def _from_dict(cls, content: Any, source: str) -> "Model":
        err = ModelFileError
        if not isinstance(content, dict):
            raise err(f"{source}: expected a JSON object, got {type(content).__name__}")
        fmt = content.get("format")
        if fmt not in FORMATS:
            if isinstance(fmt, str) and fmt.startswith(_FAMILY):
                try:
                    version = int(fmt[len(_FAMILY):])
                except ValueError:
                    version = None
                if version is not None and version > _VERSION:
                    raise err(f"{source}: format {fmt!r} is newer than this bmr reads ({FORMAT!r}); upgrade bmr")
            raise err(f"{source}: missing or unknown 'format' {fmt!r}; expected {FORMAT!r}")
        if "sha256" in content:
            body = {k: v for k, v in content.items() if k != "sha256"}
            try:
                ok = _digest(body) == content["sha256"]
            except (TypeError, ValueError):
                ok = False
            if not ok:
                raise err(f"{source}: content does not match its sha256 digest (the file is corrupted or was "
                          "edited; delete the 'sha256' field to load an edited file)")
        hyst = content.get("hysteresis")
        if not isinstance(hyst, dict) or "ascending" not in hyst or "descending" not in hyst:
            raise err(f"{source}: 'hysteresis' must hold 'ascending' and 'descending' curve lists")
        asc = _curves(hyst["ascending"], f"{source}: hysteresis.ascending")
        desc = _curves(hyst["descending"], f"{source}: hysteresis.descending")
        initial = hyst.get("initial", "negative")
        if initial not in ("negative", "positive"):
            raise err(f"{source}: hysteresis.initial must be 'negative' or 'positive', got {initial!r}")
        friction = _friction(content.get("friction"), source)
        quantities = (ACTUATOR if fmt == "bmr-model/1"
                      else Quantities.from_dict(content.get("quantities"), f"{source}: quantities"))
        gain = content.get("converter_gain_a_per_v", 0.125)
        if not (_is_number(gain) and math.isfinite(gain) and gain > 0):
            raise err(f"{source}: converter_gain_a_per_v must be a positive number (A/V), got {gain!r}")
        limits = content.get("limits")
        if limits is None:
            limits = {}
        if not isinstance(limits, dict):
            raise err(f"{source}: 'limits' must be an object")
        limits = {key: _limit(key, val, f"{source}: limits") for key, val in limits.items()}
        ext = content.get("extensions", [])
        if not isinstance(ext, list):
            raise err(f"{source}: 'extensions' must be a list")
        for k, e in enumerate(ext):
            if not (isinstance(e, dict) and isinstance(e.get("name"), str)):
                raise err(f"{source}: extensions[{k}] must be an object with a 'name' string")
        meta = content.get("meta")
        if meta is None:
            meta = {}
        if not isinstance(meta, dict):
            raise err(f"{source}: 'meta' must be an object")
        build = _build_options(hyst.get("build") or {}, f"{source}: hysteresis.build")
        try:
            _core.check_extensions(ext)
        except BmrError as exc:
            raise err(f"{source}: extensions: {exc}") from None
        try:
            h = Hysteresis.from_curves(asc, desc, initial=initial, **build)
        except ResourceLimitError as exc:
            raise ResourceLimitError(f"{source}: hysteresis tables: {exc}") from None
        except BmrError as exc:
            raise err(f"{source}: hysteresis tables rejected: {exc}") from None
        model = cls(h, friction, limits=limits, converter_gain_a_per_v=gain, extensions=ext, meta=meta,
                    curves=(asc, desc), quantities=quantities,
                    signed_table=_signed_table(hyst.get("signed_table"), f"{source}: hysteresis.signed_table"))
        model._build = build
        return model

    @classmethod
    def load(cls, path: str | Path) -> "Model":
        """Read a ``bmr-model/1`` or ``bmr-model/2`` file; every problem is a ``ModelFileError`` naming the file
        and the field."""
        p = Path(path)
        kind = path_kind(p, "model file", error=ModelFileError)
        if kind == "folder":
            raise ModelFileError(f"model file {str(p)!r} is a folder")
        if kind != "file":
            raise ModelFileError(f"model file {str(p)!r} does not exist")
        return cls.from_dict(read_json(p, "model file", error=ModelFileError), source=str(p))

    def __repr__(self) -> str:
        q = self.quantities
        lo, hi = self.input_limits
        fr = f"friction order {self.friction.order}" if self.friction is not None else "no friction"
        return (f"Model({q.describe()}, {q.input.name} {q.input.format(lo, 4)}..{q.input.format(hi, 4)}, {fr}, "
                f"extensions={[e['name'] for e in self.extensions]})")


def run_export_cli(args: Any) -> int:
    """``bmr export MODEL (--rust OUT.rs | --c OUT.h) [--stages all|a,b] [--prefix P]``."""
    model = Model.load(args.model)
    stages: Any = args.stages
    if stages is not None and stages != "all":
        stages = [s.strip() for s in stages.split(",") if s.strip()]
    language, out = ("rust", args.rust) if args.rust else ("c", args.c)
    for row in model.stage_plan(stages):
        print(f"  {row['name']}: {'on' if row['on'] else 'off'} ({row['reason']})")
    p = model.export(out, language, stages=stages, prefix=args.prefix)
    print(f"bmr export: wrote {p} ({language})")
    return 0


# Options of ``Hysteresis.from_curves`` a model file may carry, with their types.
_BUILD_OPTIONS = {"monotone_tolerance": float, "reach_tolerance": float, "closure_tolerance": float,
                  "node_tolerance": float, "max_nodes": int, "subdivisions": int}


def _signed_table(value: Any, where: str) -> Any:
    """The ``signed_table`` entry as a ``bmr._core.EverettModel`` (None when absent)."""
    if value is None:
        return None
    if not (isinstance(value, dict) and _number_list(value.get("nodes")) and _number_list(value.get("masses"))
            and _is_number(value.get("offset"))):
        raise BmrError(f"{where} must hold 'nodes' and 'masses' (number lists) and an 'offset' number")
    try:
        return _core.EverettModel(np.asarray(value["nodes"], dtype=float),
                                  np.asarray(value["masses"], dtype=float), float(value["offset"]), True)
    except BmrError as exc:
        raise BmrError(f"{where}: {exc}") from None


def _build_options(value: Any, where: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise BmrError(f"{where} must be an object of Hysteresis.from_curves options")
    out: dict[str, Any] = {}
    for k, v in value.items():
        kind = _BUILD_OPTIONS.get(k)
        if kind is None:
            raise BmrError(f"{where}: unknown option {k!r} (known: {', '.join(_BUILD_OPTIONS)})")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or (kind is int and int(v) != v):
            raise BmrError(f"{where}.{k} must be {'an integer' if kind is int else 'a number'}, got {v!r}")
        out[k] = kind(v)
    return out


def _curves(value: Any, where: str) -> list[tuple[np.ndarray, np.ndarray]]:
    # A family may be empty (derived from the other one).
    if not isinstance(value, list):
        raise ModelFileError(f"{where} must be a list of [[u...], [y...]] curves")
    out = []
    for k, c in enumerate(value):
        if not (isinstance(c, list) and len(c) == 2 and isinstance(c[0], list) and isinstance(c[1], list)):
            raise ModelFileError(f"{where}[{k}] must be [[u...], [y...]]")
        if not _all_numbers(c[0]) or not _all_numbers(c[1]):
            raise ModelFileError(f"{where}[{k}] holds values that are not numbers")
        u = np.asarray(c[0], dtype=float)
        y = np.asarray(c[1], dtype=float)
        if u.shape != y.shape or u.size < 2:
            raise ModelFileError(f"{where}[{k}]: u and y need the same length ≥ 2 (got {u.size} and {y.size})")
        bad = np.flatnonzero(~(np.isfinite(u) & np.isfinite(y)))
        if bad.size:
            raise ModelFileError(f"{where}[{k}] sample {int(bad[0])} is not finite")
        out.append((u, y))
    return out


def _friction(value: Any, source: str) -> FrictionFit | None:
    err = ModelFileError
    if value is None:
        return None
    if not isinstance(value, dict) or not all(k in value for k in ("c0", "a", "b")):
        raise err(f"{source}: 'friction' must be null or hold 'c0', 'a' and 'b'")
    if not (_is_number(value["c0"]) and _number_list(value["a"]) and _number_list(value["b"])):
        raise err(f"{source}: friction c0, a and b must be numbers (N·mm)")
    try:
        fit = FrictionFit.from_coefficients(float(value["c0"]), value["a"], value["b"])
    except BmrError as exc:
        raise err(f"{source}: friction: {exc}") from None
    se = value.get("stderr")
    if se is not None:
        if not isinstance(se, dict):
            raise err(f"{source}: friction.stderr must be an object")
        c0_se, a_se, b_se = se.get("c0"), se.get("a", [None] * fit.order), se.get("b", [None] * fit.order)
        # Unknown uncertainties are stored as null.
        if not (_number_or_null(c0_se) and _number_list(a_se, nulls=True) and _number_list(b_se, nulls=True)):
            raise err(f"{source}: friction.stderr must hold numbers or null")
        fit.c0_stderr = _num(c0_se)
        fit.a_stderr = np.array([_num(v) for v in a_se], dtype=float)
        fit.b_stderr = np.array([_num(v) for v in b_se], dtype=float)
        if fit.a_stderr.shape != fit.a.shape or fit.b_stderr.shape != fit.b.shape:
            raise err(f"{source}: friction.stderr must have one entry per coefficient")
    if "residual_rms_nmm" in value:
        if not _number_or_null(value["residual_rms_nmm"]):
            raise err(f"{source}: friction.residual_rms_nmm must be a number or null")
        fit.residual_rms_nmm = _num(value["residual_rms_nmm"])
    if "n" in value:
        if isinstance(value["n"], bool) or not isinstance(value["n"], int) or value["n"] < 0:
            raise err(f"{source}: friction.n must be a count of samples, got {value['n']!r}")
        fit.n = value["n"]
    if "criterion" in value:
        if not isinstance(value["criterion"], str):
            raise err(f"{source}: friction.criterion must be a string")
        fit.criterion = value["criterion"]
    scores = value.get("scores")
    if scores is not None:
        if not isinstance(scores, dict) or not all(
                isinstance(k, str) and k.isdigit() and _number_or_null(v) for k, v in scores.items()):
            raise err(f"{source}: friction.scores must map harmonic orders to numbers or null")
        # A score that could not be computed (infinite) is stored as null.
        fit.scores = {int(k): float("inf") if v is None else float(v) for k, v in scores.items()}
    return fit


def _is_number(v: Any) -> bool:
    """A real number (numpy scalars included), not a bool."""
    return isinstance(v, numbers.Real) and not isinstance(v, (bool, np.bool_))


def _all_numbers(values: list[Any]) -> bool:
    """Every value a real number (:func:`_is_number`); plain floats and ints, what a model file holds, are
    recognised without the abstract-class check (a table holds thousands of values)."""
    return all(type(v) in (float, int) or _is_number(v) for v in values)


def _number_or_null(v: Any) -> bool:
    return v is None or _is_number(v)


def _number_list(v: Any, *, nulls: bool = False) -> bool:
    return isinstance(v, (list, tuple)) and all(_number_or_null(x) if nulls else _is_number(x) for x in v)


def _limit(key: Any, value: Any, where: str) -> list[float]:
    """``[low, high]`` finite numbers with ``low < high``."""
    if (not isinstance(key, str) or not isinstance(value, (list, tuple)) or len(value) != 2
            or not all(_is_number(v) and math.isfinite(v) for v in value)):
        raise ModelFileError(f"{where}.{key} must be [low, high] finite numbers, got {value!r}")
    low, high = float(value[0]), float(value[1])
    if not low < high:
        raise ModelFileError(f"{where}.{key} must have low < high, got [{low}, {high}]")
    return [low, high]


def _real_array(x: Any, name: str) -> np.ndarray:
    """Real numbers as a float array; booleans and complex numbers are a TypeError naming the argument."""
    a = np.asarray(x)
    if a.dtype.kind not in "iuf":
        raise TypeError(f"{name}: expected real numbers, got an array of {a.dtype}")
    return np.ascontiguousarray(a, dtype=float)


# A list of numbers as indented by json.dumps: opening bracket, then a newline (JSON strings cannot hold raw
# newlines, so only structural lists match), numbers and commas, closing bracket on its own line.
_NUMBER_LIST = re.compile(r"\[\n\s*([-+0-9.eE,\s]+?)\n\s*\]")


def _compact_number_lists(text: str) -> str:
    """Put every list of plain numbers on one line (curve tables would otherwise take a line per value)."""
    return _NUMBER_LIST.sub(lambda m: "[" + ", ".join(v.strip() for v in m.group(1).split(",")) + "]", text)


def _num(v: Any) -> float:
    return float("nan") if v is None else float(v)


def _compensator_from_model(model: Model | str | Path, *, dt_s: float, **kwargs: Any) -> Compensator:
    """The full (extended) compensator of a model: a ``bmr.Model`` or the path of a model file
    (:meth:`Model.compensator` with ``dt_s`` and ``kwargs``)."""
    if isinstance(model, (str, Path)) or hasattr(model, "__fspath__"):
        model = Model.load(model)
    if not isinstance(model, Model):
        raise TypeError(f"model: expected a bmr.Model or the path of a model file, got {type(model).__name__}")
    return model.compensator(dt_s, **kwargs)


# Building a compensator from a model belongs to the model: the core takes plain data and never reads model files.
Compensator.from_model = staticmethod(_compensator_from_model)  # type: ignore[attr-defined]
