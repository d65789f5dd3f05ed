"""Lake Shore VSM CSV exports (Lake Shore 8600/7400 software).

The file opens with ``#SECTION`` lines and ``key: value`` settings (``FORC type``, ``Saturation field``,
``Averaging time`` ...), then ``#DATA: 1``, ``##DATA TABLE ... vs ...`` and a comma-separated column header such
as ``Step,Iteration,Segment,Field (µ0H) [T],Moment (m) [A·m²],Time Stamp [s],Field Status,Moment (m) Status``, then
rows in blank-line separated segments. Text is Latin-1 (``µ`` and ``²`` are single bytes) with CRLF line ends.

Columns are named as a user types them: ``Field``, ``Moment``, ``Time Stamp`` (the header's full names such as
``Field (µ0H)`` are aliases), units from the brackets; the time stamps are the time axis. A FORC measurement becomes
one table per curve led by its calibration point (:mod:`bmr.data.formats.forc_sequence`), any other measurement
its initial curve and loop.
"""
from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

from bmr._core import BmrError, BundleError
from bmr.data.formats.forc_sequence import Segment, forc_tables
from bmr.data.tables import Table, split_name_unit
from bmr.data.units import unit

__all__ = ["read", "looks_like"]

MARK = "##DATA TABLE"


def _text(path: Path) -> str:
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise BundleError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def looks_like(path: Path) -> bool:
    try:
        with open(path, "rb") as f:
            head = f.read(16384)
    except OSError:
        return False
    return MARK.encode() in head


def _column(header: str) -> tuple[str, str | None, str]:
    """``(short name, unit, full name)`` of ``"Field (µ0H) [T]"``: ``("Field", "T", "Field (µ0H)")``."""
    full, u = split_name_unit(header)
    short = re.sub(r"\s*\([^)]*\)\s*$", "", full).strip() or full
    return short, u, full


def read(path: str | Path) -> list[Table]:
    p = Path(path)
    lines = _text(p).splitlines()
    at = next((i for i, line in enumerate(lines) if line.startswith(MARK)), None)
    if at is None or at + 1 >= len(lines):
        raise BundleError(f"{p}: not a Lake Shore export (no {MARK!r} line followed by a column header)")
    meta: dict[str, Any] = {}
    for line in lines[:at]:
        m = re.match(r"^([^#:][^:]*?)\s*:\s*(.+)$", line.strip())
        if m:
            meta[m.group(1).strip()] = m.group(2).strip()
    heads = [h.strip() for h in lines[at + 1].split(",")]
    parsed = [_column(h) for h in heads]
    rows: list[list[str]] = []
    starts: list[int] = []  # row index where each blank-line separated segment starts
    blank = True
    for n, line in enumerate(lines[at + 2:], start=at + 3):
        if not line.strip():
            blank = True
            continue
        fields = [x.strip() for x in line.split(",")]
        if len(fields) != len(heads):
            raise BundleError(f"{p}: line {n} has {len(fields)} fields, the header {len(heads)}")
        if blank:
            starts.append(len(rows))
            blank = False
        rows.append(fields)
    if not rows:
        raise BundleError(f"{p}: the table has a header but no rows (truncated file?)")
    columns: dict[str, np.ndarray] = {}
    units: dict[str, str] = {}
    aliases: dict[str, list[str]] = {}
    for k, (short, u, full) in enumerate(parsed):
        try:
            values = np.array([float(r[k]) for r in rows])
        except ValueError:
            continue  # status flags ("GOOD") are not measurements
        columns[short] = values
        if u is not None:
            units[short] = unit(u).symbol
        for alias in {full, heads[k]} - {short}:
            aliases.setdefault(alias.lower(), []).append(short)
    for need in ("Field", "Moment"):
        if need not in columns:
            raise BundleError(f"{p}: no numeric {need!r} column (columns: {', '.join(columns)})")
    time = "Time Stamp" if "Time Stamp" in columns else None
    bounds = [*starts, len(rows)]
    segments = [Segment({k: v[a:b] for k, v in columns.items()}) for a, b in zip(bounds[:-1], bounds[1:])]
    forc = any("forc" in key.lower() for key in meta) or any("FORC" in line for line in lines[:at])
    try:
        return forc_tables(p, segments, forc=forc, field="Field", moment="Moment", units=units, time_column=time,
                           meta=meta, aliases=aliases)
    except BmrError as exc:
        raise BundleError(str(exc)) from None
