"""A magnetometer's FORC measurement as runs: the file holds one sequence of segments, a single point at the
calibration field (the instrument's drift check, measured after each saturation) before every first-order reversal
curve. Each curve becomes a table of its own (one run of the bundle, so curves can be held out), led by its
calibration point: that point is a measurement of the state the curve starts from (the branch's top after
saturation), and its moment, which should be the same before every curve, is the drift of the instrument; the
tables' metadata keep it (``calibration_field``, ``calibration_moment``). The curves were measured one after the
other on one sample, so they are one measurement history in file order (:class:`~bmr.data.tables.Recorded`), as are
a hysteresis export's initial curve and loop."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bmr._core import BundleError
from bmr.data.tables import Recorded, Table

__all__ = ["Segment", "forc_tables"]


@dataclass
class Segment:
    """One blank-line-separated block of the file: its columns (equal length), in file order."""

    columns: dict[str, np.ndarray]

    @property
    def size(self) -> int:
        return len(next(iter(self.columns.values())))


def forc_tables(path: Path, segments: list[Segment], *, forc: bool, field: str, moment: str, units: dict[str, str],
                time_column: str | None, meta: dict[str, Any], calibration_field: float | None = None,
                aliases: dict[str, list[str]] | None = None) -> list[Table]:
    """One table per curve (``<stem>-forc001`` ...), each led by the calibration point measured before it.

    A one-point segment within 2 % of the field span from the calibration field (the header's, else the file's
    first point) is a calibration point; every other segment is a curve (a FORC's first curve may be one point,
    its reversal field). A file that is not a FORC measurement (``forc`` False: a hysteresis export) gives the initial curve (a first
    segment that starts at zero field, when there are several) and the loop (the other segments, joined) as tables
    ``<stem>-initial`` and ``<stem>-loop``."""
    segments = [s for s in segments if s.size]
    if not segments:
        raise BundleError(f"{path}: no data points")
    fields = np.concatenate([s.columns[field] for s in segments])
    span = float(np.ptp(fields)) or 1.0
    h_cal = calibration_field if calibration_field is not None else float(segments[0].columns[field][0])
    is_cal = [s.size == 1 and abs(float(s.columns[field][0]) - h_cal) <= 0.02 * span for s in segments]
    stem = path.stem or path.name
    made: list[Table] = []

    def table(name: str, columns: dict[str, np.ndarray], where: str, extra: dict[str, Any]) -> Table:
        made.append(Table(f"{stem}-{name}", columns, f"{path} ({where})", dict(units), time_column=time_column,
                          meta={**meta, **extra}, aliases=dict(aliases or {}),
                          recorded=Recorded(f"measurement sequence of {path}", float(len(made)))))
        return made[-1]

    def joined(parts: list[Segment]) -> dict[str, np.ndarray]:
        return {k: np.concatenate([p.columns[k] for p in parts]) for k in parts[0].columns}

    if not forc:
        initial = len(segments) > 1 and abs(float(segments[0].columns[field][0])) <= 0.05 * span
        tables = [table("initial", dict(segments[0].columns), "initial curve", {})] if initial else []
        loop = segments[1:] if initial else segments
        return tables + [table("loop", joined(loop), "hysteresis loop", {})]
    tables = []
    pending: Segment | None = None
    curve = 0
    for seg, cal in zip(segments, is_cal):
        if cal:
            pending = seg
            continue
        curve += 1
        lead = pending is not None
        columns = {k: np.concatenate([pending.columns[k], v]) if pending is not None else v
                   for k, v in seg.columns.items()}
        extra = ({"calibration_field": float(pending.columns[field][0]),
                  "calibration_moment": float(pending.columns[moment][0]), "calibration_points": 1}
                 if pending is not None else {"calibration_points": 0})
        tables.append(table(f"forc{curve:03d}", columns,
                            f"curve {curve}" + (", after its calibration point" if lead else ""),
                            {"curve": curve, **extra}))
        pending = None
    if not tables:
        raise BundleError(f"{path}: only calibration points, no curve")
    return tables
