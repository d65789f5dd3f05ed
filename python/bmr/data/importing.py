"""One import step from raw lab logs to a bundle: ``bmr import`` and :func:`import_logs`.

    bmr import forc.dat --input Vplus:V --output P1:uC_per_cm2 --protocol forc-ascending -o capacitor
    bmr import strplt.ru3 strplt.ru4 ... --input MAIN:A --output BL:T --output-name "integrated gradient" \\
        --output-sigma sigBL --holdout run7,run8 -o quad

Every table of every file (:func:`bmr.data.formats.read_tables`: CSV, Parquet, TDMS, MAT, ControlDesk captures,
analyzer exports, SLAC tables) that holds the declared columns becomes a run. A column is given as ``COL``,
``COL:UNIT`` (the bundle stores ``UNIT``; values are converted from the unit the file states) or
``COL:SOURCE:UNIT`` (the file's values are in ``SOURCE``, for files that state no unit). The protocol's reversals
are found in each identification run (``bmr._core.find_reversals``, dead-band default: 1 % of the input span or
10× the input's sample noise if larger) and checked against the protocol; runs named in ``holdout`` are labelled
for evaluation, the others for identification. The summary lists runs, samples, reversals, the input range and
the sample rate (rounded to the timestamps' resolution), and every table that was not imported and why.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Iterable

import numpy as np
import pandas as pd

from bmr import _core
from bmr._core import BmrError, BundleError
from bmr.data.bundle import Bundle, Run, write_bundle
from bmr.data.formats import read_tables
from bmr.data.quantities import ANGLE, Quantities, Quantity
from bmr.data.signals import (CaptureEdges, SampleRate, capture_edges, default_deadband, output_rails,
                              sample_rate)
from bmr.data.tables import Recorded, Table
from bmr.data.units import format_number, unit

__all__ = ["PROTOCOLS", "ColumnSpec", "ImportedRun", "ImportResult", "import_logs", "run_cli"]

PROTOCOLS = ("forc-ascending", "forc-descending", "major-loop", "any")
_KIND = {"forc-ascending": "first_order_ascending", "forc-descending": "first_order_descending",
         "major-loop": "major_loop", "any": "custom"}
# "tout" is Simulink's time variable ("Save to workspace"), the time of MATLAB logs of plain variables.
_TIME_NAMES = ("t_s", "time", "t", "zeit", "timestamp", "tout")
# A time column named with its unit after an underscore (``time_ms``, ``t_us``), as logging scripts write them.
_TIME_WITH_UNIT = re.compile(r"^(?:t|time|zeit|timestamp)_(\w+)$", re.IGNORECASE)


@dataclass(frozen=True)
class ColumnSpec:
    """A column of the raw files: its name, the unit the bundle stores (None: the unit the file states) and the
    unit of the file's values when the file states none."""

    column: str
    unit: str | None = None
    source_unit: str | None = None

    @classmethod
    def parse(cls, spec: "str | ColumnSpec", role: str) -> "ColumnSpec":
        """``COL``, ``COL:UNIT`` or ``COL:SOURCE:UNIT`` (units checked against the registry)."""
        if isinstance(spec, ColumnSpec):
            return spec
        if not isinstance(spec, str) or not spec.strip():
            raise BundleError(f"the {role} column must be given as COL, COL:UNIT or COL:SOURCE:UNIT, got {spec!r}")
        parts = spec.split(":")
        if len(parts) > 3 or not parts[0].strip() or any(not p.strip() for p in parts[1:]):
            raise BundleError(f"the {role} column {spec!r} must be COL, COL:UNIT or COL:SOURCE:UNIT")
        for p in parts[1:]:
            unit(p, what=f"{role} {parts[0]!r}")
        if len(parts) == 3:
            return cls(parts[0].strip(), parts[2].strip(), parts[1].strip())
        return cls(parts[0].strip(), parts[1].strip() if len(parts) == 2 else None)


@dataclass
class ImportedRun:
    """What the import found in one run."""

    name: str
    source: str
    kind: str
    role: str
    samples: int
    reversals: int
    curves: int | None
    input_range: tuple[float, float]
    duration_s: float
    edges: CaptureEdges = field(default_factory=CaptureEdges)

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "source": self.source, "kind": self.kind, "role": self.role,
                "samples": self.samples, "reversals": self.reversals, "first_order_curves": self.curves,
                "input_range": list(self.input_range), "duration_s": self.duration_s,
                "idle_hold_samples": self.edges.hold, "end_jump_samples": self.edges.jump}


@dataclass
class ImportResult:
    """The bundle and what the import found: runs, the dead-band, the sample rate, tables not imported (with
    the reason) and notes on assumptions (e.g. a time column without a unit taken as seconds)."""

    bundle: Bundle
    runs: list[ImportedRun]
    protocol: str
    deadband: float
    rate: SampleRate
    skipped: list[tuple[str, str]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def summary(self) -> str:
        q = self.bundle.quantities
        u = q.input
        lines = [f"{len(self.runs)} runs ({sum(r.role == 'identification' for r in self.runs)} identification, "
                 f"{sum(r.role == 'evaluation' for r in self.runs)} evaluation), "
                 f"{sum(r.samples for r in self.runs)} samples: {q.describe()}"
                 + (", with output sigma" if q.output_sigma is not None else "")
                 + (", with angle" if q.angle is not None else ""),
                 f"protocol {self.protocol}, reversal dead-band {u.format(self.deadband)}; "
                 f"sample rate {self.rate.describe()}"]
        rows = [("run", "role", "kind", "samples", "reversals", "curves", f"input range ({u.unit})",
                 "duration (s)", "source")]
        for r in self.runs:
            rows.append((r.name, r.role, r.kind, str(r.samples), str(r.reversals),
                         "-" if r.curves is None else str(r.curves),
                         f"{format_number(r.input_range[0], 4)}..{format_number(r.input_range[1], 4)}",
                         format_number(r.duration_s, 4), r.source))
        widths = [max(len(row[k]) for row in rows) for k in range(len(rows[0]))]
        lines += ["  " + "  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip() for row in rows]
        for h in self.bundle.histories:
            shown = h if len(h) <= 8 else h[:3] + ["..."] + h[-3:]
            lines.append(f"one measurement history of {len(h)} runs in recording order: {', '.join(shown)}")
        lines += [f"not imported: {src}: {why}" for src, why in self.skipped]
        lines += [f"note: {n}" for n in self.notes]
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        return {"quantities": self.bundle.quantities.to_dict(), "protocol": self.protocol,
                "deadband": self.deadband, "sample_rate_hz": self.rate.hz, "irregular_sampling": self.rate.irregular,
                "runs": [r.to_dict() for r in self.runs],
                "skipped": [{"source": s, "reason": w} for s, w in self.skipped], "notes": list(self.notes)}


# ----------------------------------------------------------------------------------------------- columns
def _source_unit(table: Table, key: str, spec: ColumnSpec, role: str) -> str:
    stated = table.unit_of(key)
    if spec.source_unit is not None:
        if stated is not None and unit(stated, what=f"{table.source}: column {key!r}") != unit(spec.source_unit):
            raise BundleError(f"{table.source}: column {key!r} states unit {stated!r} but the {role} was given as "
                              f"{spec.source_unit!r}")
        return spec.source_unit
    if stated is not None:
        return stated
    if spec.unit is not None:
        return spec.unit
    raise BundleError(f"{table.source}: column {key!r} states no unit; give the {role} as {spec.column}:UNIT")


def _values(table: Table, spec: ColumnSpec, target: Quantity, role: str) -> np.ndarray:
    key, values = table.column(spec.column, role)
    src = _source_unit(table, key, spec, role)
    return target.from_unit(values, src, what=f"{table.source}: column {key!r} ({role})")


def _quantity(table: Table, spec: ColumnSpec, name: str | None, role: str) -> Quantity:
    key, _ = table.column(spec.column, role)
    target = spec.unit or _source_unit(table, key, spec, role)
    return Quantity.declare(target, name)


def _time(table: Table, spec: ColumnSpec | None, rate_hz: float | None, notes: list[str]) -> np.ndarray:
    if spec is not None:
        key, values = table.column(spec.column, "time")
        stated = table.unit_of(key)
        if spec.source_unit is None and stated is None and spec.unit is None:
            notes.append(f"{table.source}: time column {key!r} states no unit; taken as s")
        src = spec.source_unit or stated or spec.unit or "s"
        return Quantity("time", "s", "t_s").from_unit(values, src, what=f"{table.source}: column {key!r} (time)")
    key = table.time_column
    if key is None:
        key = next((k for n in _TIME_NAMES for k in [table.find(n)] if k is not None), None)
    if key is None:
        named = _time_named_with_unit(table)
        if named is not None:
            key, suffix = named
            return Quantity("time", "s", "t_s").from_unit(table.columns[key], table.unit_of(key) or suffix,
                                                          what=f"{table.source}: column {key!r} (time)")
    if key is not None:
        stated = table.unit_of(key)
        if stated is None:
            notes.append(f"{table.source}: time column {key!r} states no unit; taken as s")
        return Quantity("time", "s", "t_s").from_unit(table.columns[key], stated or "s",
                                                      what=f"{table.source}: column {key!r} (time)")
    if rate_hz is None:
        # Quasi-static records (a hysteresisgraph's B(H) loops) have no time: the samples are numbered.
        notes.append(f"{table.source}: no time column (looked for {', '.join(_TIME_NAMES)}); samples numbered "
                     "1 s apart (give --time COL[:UNIT] or --sample-rate HZ for the real time)")
        rate_hz = 1.0
    return np.arange(table.n_samples) / float(rate_hz)


def _time_named_with_unit(table: Table) -> tuple[str, str] | None:
    """The first column named like ``time_ms`` whose suffix is a time unit: ``(column, unit)``."""
    for key in table.columns:
        m = _TIME_WITH_UNIT.match(key)
        if m is None:
            continue
        try:
            return key, unit(m.group(1), dimension="time").symbol
        except BmrError:
            continue
    return None


# ------------------------------------------------------------------------------------------ table layouts
def _per_column(table: Table, specs: list[ColumnSpec]) -> list[Table]:
    """A table whose declared columns are matrices (``name[1]``, ``name[2]`` ... : one loop per column) as one
    table per column index, each holding ``name``; other tables as they are."""
    grouped = [s.column for s in specs if table.find(s.column) is None and table.find(f"{s.column}[1]") is not None]
    if not grouped:
        return [table]
    count = 1
    while all(table.find(f"{g}[{count + 1}]") is not None for g in grouped):
        count += 1
    out = []
    for k in range(1, count + 1):
        columns = {n: v for n, v in table.columns.items() if not re.search(r"\[\d+\]$", n)}
        for g in grouped:
            columns[g] = table.columns[table.find(f"{g}[{k}]") or g]
        out.append(Table(f"{table.name}-{k}", columns, f"{table.source} (column {k})", dict(table.units),
                         table.time_column, dict(table.meta)))
    return out


def _joined(read: list[tuple[Path, list[Table]]], in_spec: ColumnSpec, out_spec: ColumnSpec,
            notes: list[str]) -> list[tuple[Path, list[Table]]]:
    """Input and output in separate files (a hysteresisgraph's ``H_*.mat`` and ``B_*.mat``): the tables of a file
    that hold only the input are joined, in order, with those of another file that hold only the output and as many
    samples."""
    def holds(t: Table, spec: ColumnSpec) -> bool:
        return t.find(spec.column) is not None

    inputs = [(p, t) for p, ts in read for t in ts if holds(t, in_spec) and not holds(t, out_spec)]
    outputs = [(p, t) for p, ts in read for t in ts if holds(t, out_spec) and not holds(t, in_spec)]
    if not inputs or not outputs:
        return read
    joined: dict[Path, list[Table]] = {}
    used: set[int] = set()
    for p, a in inputs:
        match = next((k for k, (q, b) in enumerate(outputs)
                      if k not in used and q != p and b.n_samples == a.n_samples), None)
        if match is None:
            continue
        used.add(match)
        q, b = outputs[match]
        columns = {**{f"{n}": v for n, v in b.columns.items()}, **a.columns}
        units = {**b.units, **a.units}
        name = _common_suffix(a.name, b.name) or f"{a.name}+{b.name}"
        joined.setdefault(p, []).append(Table(name, columns, f"{a.source} + {b.source}", units,
                                              a.time_column or b.time_column, {**b.meta, **a.meta}))
    if not joined:
        return read
    notes.append(f"input and output read from separate files: {sum(map(len, joined.values()))} table(s) joined "
                 "in file order")
    rest = [(p, [t for t in ts if holds(t, in_spec) and holds(t, out_spec)]) for p, ts in read]
    return [(p, ts) for p, ts in joined.items()] + [(p, ts) for p, ts in rest if ts]


def _common_suffix(a: str, b: str) -> str:
    n = 0
    while n < min(len(a), len(b)) and a[-1 - n] == b[-1 - n]:
        n += 1
    return a[len(a) - n:].strip("._- ") if n else ""


# ---------------------------------------------------------------------------------------------- protocol
def _first_order_curves(u: np.ndarray, rev: np.ndarray, lo: float, hi: float, tol: float, rising: bool) -> int:
    """Reversals that start a first-order curve: a minimum between two visits of the top end (ascending), or a
    maximum between two visits of the bottom end (descending). The run's start and end count as visits."""
    ext = [0, *rev.tolist(), len(u) - 1]
    count = 0
    for k in range(1, len(ext) - 1):
        before, here, after = u[ext[k - 1]], u[ext[k]], u[ext[k + 1]]
        if rising and here < before and before >= hi - tol and after >= hi - tol and here < hi - tol:
            count += 1
        if not rising and here > before and before <= lo + tol and after <= lo + tol and here > lo + tol:
            count += 1
    return count


def _check_protocol(protocol: str, source: str, name: str, u: np.ndarray, rev: np.ndarray, lo: float, hi: float,
                    tol: float, q: Quantity, deadband: float) -> int | None:
    """The number of first-order curves (FORC protocols) after checking the run against the protocol."""
    found = (f"found {rev.size} reversal(s)"
             + (f" at {', '.join(q.format(x, 4) for x in u[rev][:8])}{' ...' if rev.size > 8 else ''}"
                if rev.size else "")
             + f" with dead-band {q.format(deadband)}; the run spans {q.format(u.min(), 4)}..{q.format(u.max(), 4)}"
             + f", the import {q.format(lo, 4)}..{q.format(hi, 4)}")
    if protocol in ("forc-ascending", "forc-descending"):
        rising = protocol == "forc-ascending"
        n = _first_order_curves(u, rev, lo, hi, tol, rising)
        if n == 0:
            shape = ("fall from the top of the input range to a reversal and rise back to the top" if rising else
                     "rise from the bottom of the input range to a reversal and fall back to the bottom")
            raise BundleError(f"{source} (run {name!r}): protocol {protocol}: no first-order curve found; each curve "
                              f"must {shape} ({found})")
        return n
    if protocol == "major-loop":
        if not (u.max() >= hi - tol and u.min() <= lo + tol and rev.size >= 1):
            raise BundleError(f"{source} (run {name!r}): protocol major-loop: the input must go from one end of the "
                              f"input range to the other and back ({found})")
    return None


# ------------------------------------------------------------------------------------------------ import
def _run_name(text: str, taken: set[str]) -> str:
    base = re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("._") or "run"
    name, k = base, 2
    while name in taken:
        name, k = f"{base}-{k}", k + 1
    taken.add(name)
    return name


def _jsonable_meta(meta: dict[str, Any]) -> dict[str, Any]:
    return {str(k): (v if isinstance(v, (str, int, float, bool)) or v is None else str(v)) for k, v in meta.items()}


def _histories(built: list[tuple[Path, Table, str, pd.DataFrame]]) -> list[list[str]]:
    """The runs whose tables the reader placed in one measurement history, in recording order (a history of one run
    says nothing and is left out)."""
    groups: dict[str, list[tuple[float, int, str]]] = {}
    for k, (_, t, name, _) in enumerate(built):
        if t.recorded is not None:
            groups.setdefault(t.recorded.history, []).append((t.recorded.order, k, name))
    return [[name for *_, name in sorted(g)] for g in groups.values() if len(g) > 1]


# Fewest samples either part of a run split by ``holdout_tail`` keeps.
MIN_SPLIT_SAMPLES = 10


def _split_tails(built: list[tuple[Path, Table, str, pd.DataFrame]], roles: dict[str, str], share: float,
                 taken: set[str], notes: list[str]) -> list[tuple[Path, Table, str, pd.DataFrame]]:
    """Every identification run of ``built`` cut into its head (identification) and its last ``share`` of samples
    (``<run>-tail``, evaluation), both in one measurement history (the run's own, or a new one of the two)."""
    out = []
    for path, t, name, df in built:
        if roles[name] != "identification":
            out.append((path, t, name, df))
            continue
        n = len(df)
        k = int(round(n * (1.0 - share)))
        if min(k, n - k) < MIN_SPLIT_SAMPLES:
            raise BundleError(f"{t.source} (run {name!r}): {n} samples split at {share:g} from the end leave {k} "
                              f"and {n - k}; each part needs at least {MIN_SPLIT_SAMPLES}")
        history = t.recorded or Recorded(f"{t.source} (split)", 0.0)
        head = replace(t, recorded=Recorded(history.history, history.order))
        tail = replace(t, name=f"{t.name}-tail", recorded=Recorded(history.history, history.order + 0.5))
        tail_name = _run_name(f"{name}-tail", taken)
        roles[tail_name] = "evaluation"
        out.append((path, head, name, df.iloc[:k].reset_index(drop=True)))
        out.append((path, tail, tail_name, df.iloc[k:].reset_index(drop=True)))
        notes.append(f"{t.source} (run {name!r}): the last {n - k} of {n} samples held out as run {tail_name!r}")
    return out


def import_logs(
    files: Iterable[str | Path],
    *,
    input: str | ColumnSpec,
    output: str | ColumnSpec,
    angle: str | ColumnSpec | None = None,
    time: str | ColumnSpec | None = None,
    output_sigma: str | ColumnSpec | None = None,
    input_name: str | None = None,
    output_name: str | None = None,
    protocol: str = "any",
    holdout: Iterable[str] = (),
    format: str | None = None,
    device: str = "",
    sample_rate_hz: float | None = None,
    deadband: float | None = None,
    keep_edges: bool = False,
    holdout_tail: float | None = None,
) -> ImportResult:
    """Read raw logs into a bundle (``ImportResult.bundle``) with the declared quantities.

    ``input``/``output``/``angle``/``time``/``output_sigma``: columns as ``COL``, ``COL:UNIT`` or
    ``COL:SOURCE:UNIT`` (or :class:`ColumnSpec`); the angle is stored in rad and time in s (a single unit given
    for them is the file's), the sigma in the output's unit. ``input_name``/``output_name`` name the quantities
    (default: from the unit's dimension, e.g. V → voltage). ``protocol``: one of ``PROTOCOLS``; ``holdout``: run
    or file names labelled for evaluation. ``format`` forces a reader (see :data:`bmr.data.formats.FORMATS`).
    ``sample_rate_hz`` builds time from the sample index for files without a time column. ``deadband``: the
    reversal dead-band in input units. An idle hold at a run's start and a command jump at its end
    (:func:`bmr.data.signals.capture_edges`) are left out and named in the notes unless ``keep_edges``.
    ``holdout_tail``: a share (0-1) of every identification run held out from its end, for a recording that is
    one long run: the run's head identifies, its tail (``<run>-tail``, the same measurement history: it starts
    from the state the head left) is evaluated.
    """
    if protocol not in PROTOCOLS:
        raise BundleError(f"unknown protocol {protocol!r}; use one of {', '.join(PROTOCOLS)}")
    paths = [Path(f) for f in files]
    if not paths:
        raise BundleError("import needs at least one file")
    in_spec = ColumnSpec.parse(input, "input")
    out_spec = ColumnSpec.parse(output, "output")
    angle_spec = ColumnSpec.parse(angle, "angle") if angle is not None else None
    time_spec = ColumnSpec.parse(time, "time") if time is not None else None
    sigma_spec = ColumnSpec.parse(output_sigma, "output sigma") if output_sigma is not None else None
    if angle_spec is not None and angle_spec.unit is not None and unit(angle_spec.unit) != unit("rad"):
        # The angle is always stored in rad: a single unit given for it is the file's.
        if angle_spec.source_unit is not None:
            raise BundleError(f"the angle is stored in rad; give it as {angle_spec.column}:{angle_spec.source_unit} "
                              f"or {angle_spec.column}:{angle_spec.source_unit}:rad")
        angle_spec = ColumnSpec(angle_spec.column, "rad", angle_spec.unit)
    if holdout_tail is not None and not (isinstance(holdout_tail, (int, float)) and 0.0 < holdout_tail < 1.0):
        raise BundleError(f"holdout_tail must be a share between 0 and 1 (exclusive), got {holdout_tail!r}")
    if sample_rate_hz is not None and not (isinstance(sample_rate_hz, (int, float)) and sample_rate_hz > 0
                                           and np.isfinite(sample_rate_hz)):
        raise BundleError(f"sample_rate_hz must be a positive finite number, got {sample_rate_hz!r}")
    holdout = [h for h in holdout if h]

    skipped: list[tuple[str, str]] = []
    notes: list[str] = []
    found: list[tuple[Path, Table]] = []
    specs = [s for s in (in_spec, out_spec, angle_spec, sigma_spec) if s is not None]
    read = [(path, [u for t in read_tables(path, format) for u in _per_column(t, specs)]) for path in paths]
    read = _joined(read, in_spec, out_spec, notes)
    for path, tables in read:
        usable = []
        first_missing = ""
        for t in tables:
            missing = [f"{role} {spec.column!r}" for role, spec in
                       (("input", in_spec), ("output", out_spec), ("angle", angle_spec),
                        ("output sigma", sigma_spec)) if spec is not None and t.find(spec.column) is None]
            if missing:
                skipped.append((t.source, f"no column for the {', '.join(missing)}"))
                first_missing = first_missing or ", ".join(missing)
            else:
                usable.append(t)
        if not usable:
            t = tables[0]
            where = t.source if len(tables) == 1 else f"{path} ({len(tables)} tables)"
            raise BundleError(f"{where}: no column for the {first_missing} (columns: {', '.join(t.columns)})")
        found += [(path, t) for t in usable]

    first = found[0][1]
    q_in = _quantity(first, in_spec, input_name, "input")
    q_out = _quantity(first, out_spec, output_name, "output")
    if q_in.name == q_out.name:
        # Same unit on both sides (a piezo drive and its sensor, both in V): each is named by its column.
        if input_name is None:
            q_in = Quantity.declare(q_in.unit, in_spec.column)
        if output_name is None:
            q_out = Quantity.declare(q_out.unit, out_spec.column)
        if q_in.column == q_out.column:
            raise BundleError(f"the input and the output are both {q_in.label}; name them apart with --input-name "
                              "and --output-name")
    q_sigma = (Quantity(f"{q_out.name} sigma", q_out.unit, f"{q_out.column}_sigma")
               if sigma_spec is not None else None)
    quantities = Quantities(q_in, q_out, ANGLE if angle_spec is not None else None, q_sigma)

    taken: set[str] = set()
    built = []
    for path, t in found:
        cols = {"t_s": _time(t, time_spec, sample_rate_hz, notes),
                q_in.column: _values(t, in_spec, q_in, "input"),
                q_out.column: _values(t, out_spec, q_out, "output")}
        if angle_spec is not None:
            cols[ANGLE.column] = _values(t, angle_spec, ANGLE, "angle")
        if sigma_spec is not None and q_sigma is not None:
            cols[q_sigma.column] = _values(t, sigma_spec, q_sigma, "output sigma")
        name = _run_name(t.name, taken)
        built.append((path, t, name, pd.DataFrame(cols)))

    matched: set[str] = set()
    roles = {}
    for path, t, name, _ in built:
        keys = {name, t.name, path.name, str(path)}
        hit = [h for h in holdout if h in keys]
        matched.update(hit)
        roles[name] = "evaluation" if hit else "identification"
    unknown = [h for h in holdout if h not in matched]
    if unknown:
        raise BundleError(f"holdout {', '.join(map(repr, unknown))} names no imported run or file (runs: "
                          f"{', '.join(n for _, _, n, _ in built)})")

    # A capture's idle hold before the excitation and a command jump as it ends are not the experiment: left out
    # of the bundle (so of identification and scoring), counted per run and named in the notes.
    edges: dict[str, CaptureEdges] = {}
    if not keep_edges:
        trimmed = []
        for path, t, name, df in built:
            e = capture_edges(df[q_in.column].to_numpy())
            if e.any:
                edges[name] = e
                tt = df["t_s"].to_numpy()
                if e.hold:
                    notes.append(f"{t.source} (run {name!r}): idle hold at the start, {e.hold} samples "
                                 f"({format_number(tt[e.hold] - tt[0], 4)} s at {q_in.format(e.hold_level, 4)}) "
                                 "left out (its last sample kept as the run's start)")
                if e.jump:
                    notes.append(f"{t.source} (run {name!r}): command jump at the end, the last {e.jump} sample(s) "
                                 "left out")
                df = df.iloc[e.hold:len(df) - e.jump].reset_index(drop=True)
            trimmed.append((path, t, name, df))
        built = trimmed
    if holdout_tail is not None:
        built = _split_tails(built, roles, float(holdout_tail), taken, notes)

    inputs = [df[q_in.column].to_numpy() for *_, df in built]
    for (path, t, name, df), u in zip(built, inputs):
        if not np.all(np.isfinite(u)):
            row = int(np.flatnonzero(~np.isfinite(u))[0])
            raise BundleError(f"{t.source} (run {name!r}): the input has a non-finite value at row {row}")
    db = float(deadband) if deadband is not None else default_deadband(inputs)
    if not (db > 0 and np.isfinite(db)):
        raise BundleError(f"the reversal dead-band must be positive and finite, got {deadband!r}")
    lo = float(min(u.min() for u in inputs))
    hi = float(max(u.max() for u in inputs))
    tol = max(2.0 * db, 0.02 * (hi - lo))

    runs: list[Run] = []
    report: list[ImportedRun] = []
    off_protocol: list[BmrError] = []
    for (path, t, name, df), u in zip(built, inputs):
        rev = np.asarray(_core.find_reversals(np.ascontiguousarray(u), db), dtype=int)
        role = roles[name]
        kind = _KIND[protocol]
        curves = None
        if protocol != "any":
            try:
                curves = _check_protocol(protocol, t.source, name, u, rev, lo, hi, tol, q_in, db)
            except BmrError as exc:
                # A held-out run need not follow the identification protocol; an identification run that does
                # not (an instrument's first, partial measurement) is kept as a custom run and named in the
                # notes, unless no run follows the protocol at all.
                kind = "custom"
                if role == "identification":
                    off_protocol.append(exc)
                    notes.append(f"{exc}; kept as a custom run (not used as first-order curves)")
        e = edges.get(name, CaptureEdges())
        meta = {"source": t.source, "reversals": int(rev.size),
                **({"idle_hold_samples": e.hold, "end_jump_samples": e.jump} if e.any else {}),
                **({"first_order_curves": curves} if curves is not None else {}),
                **_jsonable_meta(t.meta)}
        try:
            runs.append(Run(name, kind, df, meta, quantities, role))
        except BmrError as exc:
            raise BundleError(f"{t.source}: {exc}") from None
        tt = df["t_s"].to_numpy()
        report.append(ImportedRun(name, t.source, kind, role, len(df), int(rev.size), curves,
                                  (float(u.min()), float(u.max())), float(tt[-1] - tt[0]), e))
    if off_protocol and not any(r.role == "identification" and r.kind != "custom" for r in runs):
        raise off_protocol[0]
    rate = sample_rate([r.time for r in runs])
    rails = output_rails([(r.input, r.output) for r in runs])
    if rails.any:
        notes.append(rails.describe(quantities.output))
    meta = {"imported_from": [str(p) for p in paths], "protocol": protocol, "reversal_deadband": db}
    bundle = Bundle(device, rate.hz, runs, meta, quantities, _histories(built))
    return ImportResult(bundle, report, protocol, db, rate, skipped, notes)


def run_cli(args: Any) -> int:
    """``bmr import FILES... --input COL[:UNIT] --output COL[:UNIT] ... -o BUNDLE``."""
    out = Path(args.out)
    if out.exists() and not (out.is_dir() and not any(out.iterdir())):
        raise BundleError(f"{out}: exists; give a new (or empty) folder for the bundle")
    holdout = [h.strip() for item in args.holdout for h in item.split(",")]
    result = import_logs(args.files, input=args.input, output=args.output, angle=args.angle, time=args.time,
                         output_sigma=args.output_sigma, input_name=args.input_name, output_name=args.output_name,
                         protocol=args.protocol, holdout=holdout, format=args.format, device=args.device or "",
                         sample_rate_hz=args.sample_rate, deadband=args.deadband, keep_edges=args.keep_edges,
                         holdout_tail=args.holdout_tail)
    write_bundle(result.bundle, out, fmt=args.file_format)
    print(f"bmr import: {len(args.files)} file(s) -> {out}")
    for line in result.summary().splitlines():
        print(f"  {line}")
    return 0
