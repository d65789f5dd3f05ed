"""Princeton Measurements MicroMag 2900/3900 (VSM and AGM) text exports: FORC and hysteresis measurements.

The file starts with ``MicroMag 2900/3900 Data File``, the measurement's name (``First-order reversal curves``,
``Hysteresis loop``, ...), ``key : value`` and ``key = value`` header lines (``Units of measure: cgs``, ``SI`` or
``Hybrid SI``, ``HCal``, ``Averaging time``, ``NData`` ...), optionally a column header (``Field, Moment``) and a
units line (``(Oe), (emu)``; Latin-1 bytes such as ``²`` in it), then comma-separated numbers in blank-line
separated segments (CRLF line ends) and a closing ``MicroMag 2900/3900 Data File ends``.

Units by system: cgs — field Oe, moment emu; SI — field A/m, moment A·m²; Hybrid SI — field T (µ0H), moment
A·m². The columns are ``Field`` and ``Moment``; ``time`` is the sample index times the averaging time (the file
holds no time stamps: the points are one sequence in file order). A FORC file becomes one table per curve led by
its calibration point (:mod:`bmr.data.formats.forc_sequence`); a hysteresis file the initial curve and the loop.
"""
from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

from bmr._core import BmrError, BundleError
from bmr.data.formats.forc_sequence import Segment, forc_tables
from bmr.data.tables import Table, read_text
from bmr.data.units import unit

__all__ = ["read", "looks_like", "UNIT_SYSTEMS"]

MAGIC = "MicroMag 2900/3900 Data File"
UNIT_SYSTEMS = {"cgs": ("Oe", "emu"), "si": ("A/m", "A·m²"), "hybrid si": ("T", "A·m²")}
_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")


def looks_like(path: Path) -> bool:
    try:
        with open(path, "rb") as f:
            return f.read(len(MAGIC) + 3).lstrip(b"\xef\xbb\xbf").startswith(MAGIC.encode())
    except OSError:
        return False


def _numbers(line: str) -> list[float] | None:
    fields = [x.strip() for x in line.split(",")]
    if len(fields) < 2 or not all(_NUMBER.match(x) for x in fields):
        return None
    return [float(x) for x in fields]


def _header_value(text: str) -> Any:
    try:
        return float(text)
    except ValueError:
        return text.strip().strip('"')


def read(path: str | Path) -> list[Table]:
    p = Path(path)
    lines = read_text(p).splitlines()
    if not lines or not lines[0].strip().startswith(MAGIC):
        raise BundleError(f"{p}: not a MicroMag data file (its first line is not {MAGIC!r})")
    kind = lines[1].strip() if len(lines) > 1 else ""
    meta: dict[str, Any] = {"instrument": lines[0].strip(), "measurement": kind}
    first_data = next((i for i, line in enumerate(lines) if _numbers(line) is not None), None)
    if first_data is None:
        raise BundleError(f"{p}: a MicroMag header but no data points (truncated file?)")
    text_lines = [line.strip() for line in lines[2:first_data] if line.strip()]
    for line in text_lines:
        m = re.match(r"^([^:=]+?)\s*[:=]\s*(.*)$", line)
        if m:
            meta[m.group(1).strip()] = _header_value(m.group(2))
    system = str(meta.get("Units of measure", "")).strip().lower()
    if system not in UNIT_SYSTEMS:
        raise BundleError(f"{p}: unknown 'Units of measure' {meta.get('Units of measure')!r} (MicroMag writes "
                          f"cgs, SI or Hybrid SI)")
    names, units = ["Field", "Moment"], list(UNIT_SYSTEMS[system])
    # A column header and a units line, when the export has them: the last two text lines before the data.
    if len(text_lines) >= 2 and "(" in text_lines[-1] and not re.search(r"[:=]", text_lines[-2] + text_lines[-1]):
        heads = [h.strip().strip('"') for h in re.split(r",|\s{2,}|\t", text_lines[-2]) if h.strip()]
        stated = [u.strip().strip('"').strip("()") for u in re.split(r",|\s{2,}|\t", text_lines[-1]) if u.strip()]
        if len(heads) >= 2:
            names = heads[:2]
        for k, u in enumerate(stated[:2]):
            try:
                units[k] = unit(u).symbol
            except BmrError:
                pass  # an unregistered spelling: the unit system's unit stands
    segments: list[list[list[float]]] = [[]]
    for n, line in enumerate(lines[first_data:], start=first_data + 1):
        text = line.strip()
        if not text:
            if segments[-1]:
                segments.append([])
            continue
        if text.startswith("MicroMag"):
            break  # "... Data File ends"
        row = _numbers(text)
        if row is None:
            last = n == len(lines)
            raise BundleError(f"{p}: line {n} is not a row of numbers: {text[:60]!r}"
                              + (" (truncated file?)" if last else ""))
        segments[-1].append(row)
    width = min(len(r) for s in segments for r in s)
    avg = meta.get("Averaging time")
    dt = float(avg) if isinstance(avg, float) and avg > 0 else 1.0
    meta["time"] = (f"sample index × the averaging time ({dt:g} s): the file holds no time stamps" if dt != 1.0
                    else "sample index × 1 s: the file holds no time stamps")
    field, moment = names
    out: list[Segment] = []
    count = 0
    for rows in segments:
        if not rows:
            continue
        arr = np.array([r[:width] for r in rows], dtype=float)
        cols = {field: arr[:, 0], moment: arr[:, 1], "time": dt * (count + np.arange(len(rows)))}
        count += len(rows)
        out.append(Segment(cols))
    h_cal = meta.get("HCal")
    return forc_tables(p, out, forc="first-order" in kind.lower() or "forc" in kind.lower(), field=field,
                       moment=moment, units={field: units[0], moment: units[1], "time": "s"}, time_column="time",
                       meta=meta, calibration_field=float(h_cal) if isinstance(h_cal, float) else None)
