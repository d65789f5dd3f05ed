"""SLAC magnetic-measurement tables (``strdat.ruN`` and ``strplt.ruN``).

``strdat.ruN`` opens with a header (``Run Number: 4``, ``Comment: ...``, the commanded currents), then the
quantity's title, a line of column names, a line of units and a dashed line; the samples follow::

         MAIN   +/- sigma         BL         sigBL           TF        sigTF         THsp       sigTHsp
                (A)                     (T)                       (T/A)                     (deg)
     ------------+----------  -----------+-----------   ------------+------------  -----------+---------
          0.0001     0.0000     0.034289    0.000007       0.000000    0.000000     45.5168    0.0095

``strplt.ruN`` holds the same samples with their time, under one header line::

      Time       MAIN  +/- sigma         BL    +/-   sigBL         TF    +/-  sigTF      THsp  +/-sigThsp

Columns are named as in the header with every uncertainty as ``sig<NAME>`` (``MAIN``, ``sigMAIN``, ``BL``,
``sigBL``, ``TF``, ``sigTF``, ``THsp``, ``sigTHsp``; ``Time`` in s). Units come from the ``strdat`` units line
(for a ``strplt`` file, from the ``strdat`` file of the same run beside it; otherwise from the layout: A, T, T/A,
deg). The run's header lines (comment, date, run number) are the table's metadata; its name is ``runN``.

The runs of one magnet were measured one after the other, each starting from the field the previous one left: the
table is placed in the magnet's measurement history (``SLAC magnet <name> <serial>``) at the header's date and time
(``MM-DD-YYYY``, ``HH:MM:SS``, as the run log ``index.dat`` lists them), or at its run number without a date.
"""
from __future__ import annotations

import re
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

from bmr._core import BundleError
from bmr.data.tables import Recorded, Table, read_text

__all__ = ["read", "looks_like"]

_NAME = re.compile(r"^str(dat|plt)\.ru(\d+)$", re.IGNORECASE)
_LAYOUT_UNITS = {"main": "A", "bl": "T", "gl": "T", "tf": "T/A", "thsp": "deg", "time": "s"}
_SIGNATURE = "SLAC Magnetic Measurements"


def looks_like(path: Path) -> bool:
    if _NAME.match(path.name):
        return True
    try:
        with open(path, "rb") as fh:
            head = fh.read(512).decode("utf-8", errors="replace")
    except OSError:
        return False
    first = head.lstrip().splitlines()[0] if head.strip() else ""
    return first.strip() == _SIGNATURE or (first.split()[:2] == ["Time", "MAIN"] and "+/-" in first)


def _names(header: str) -> list[str]:
    """Column names from a header line: ``+/- sigma`` after ``X`` is ``sigX``; ``+/- sigX`` and ``+/-sigX``
    are ``sigX``."""
    names: list[str] = []
    tokens = header.split()
    k = 0
    while k < len(tokens):
        tok = tokens[k]
        if tok.startswith("+/-"):
            rest = tok[3:]
            if not rest and k + 1 < len(tokens):
                k += 1
                rest = tokens[k]
            if not names:
                raise BundleError(f"header {header.strip()!r}: an uncertainty before any column")
            names.append(f"sig{names[-1]}" if rest.lower() in ("", "sigma") else rest)
        else:
            names.append(tok)
        k += 1
    return names


def _value_columns(names: list[str]) -> list[str]:
    return [n for n in names if not n.lower().startswith("sig") and n.lower() != "time"]


def _units(names: list[str], units_line: str | None) -> dict[str, str]:
    """Units from the ``(A) (T) ...`` line (one per value column, shared with its sigma) or from the layout."""
    values = _value_columns(names)
    given = re.findall(r"\(([^)]*)\)", units_line) if units_line else []
    by_value = dict(zip(values, given)) if len(given) == len(values) else {
        v: _LAYOUT_UNITS[v.lower()] for v in values if v.lower() in _LAYOUT_UNITS}
    out = {}
    for n in names:
        if n.lower() == "time":
            out[n] = "s"
        elif n in by_value:
            out[n] = by_value[n]
        elif n.lower().startswith("sig"):
            base = next((v for v in values if v.lower() == n[3:].lower()), None)
            if base in by_value:
                out[n] = by_value[base]
    return out


def _sigma_case(names: list[str]) -> list[str]:
    """``sigThsp`` (strplt) and ``sigTHsp`` (strdat) are one column: spell every sigma like its value."""
    values = _value_columns(names)
    out = []
    for n in names:
        base = next((v for v in values if n.lower().startswith("sig") and v.lower() == n[3:].lower()), None)
        out.append(f"sig{base}" if base else n)
    return out


def _rows(lines: list[str], start: int, width: int, source: str) -> np.ndarray:
    rows = []
    last = max((i for i, line in enumerate(lines) if line.strip()), default=-1)
    for i in range(start, len(lines)):
        parts = lines[i].split()
        if not parts:
            continue
        try:
            values = [float(x) for x in parts]
        except ValueError:
            raise BundleError(f"{source}, line {i + 1}: not a row of numbers: {lines[i].strip()[:60]!r}") from None
        if len(values) != width:
            truncated = " (truncated file?)" if i == last else ""
            raise BundleError(f"{source}, line {i + 1}: {len(values)} values where the header names {width}{truncated}")
        rows.append(values)
    if not rows:
        raise BundleError(f"{source}: no samples after the header (empty or truncated file)")
    return np.asarray(rows, dtype=float)


def _strdat(text: str, source: str) -> tuple[dict[str, Any], list[str], str | None, int]:
    """Metadata, column names, units line and the index of the first sample line of a strdat file."""
    lines = text.splitlines()
    meta: dict[str, Any] = {}
    dash = next((i for i, line in enumerate(lines) if line.strip().startswith("---")), None)
    if dash is None or dash < 2:
        raise BundleError(f"{source}: not a SLAC strdat table: no dashed line under a header of column names")
    for line in lines[:dash]:
        m = re.match(r"^\s*([A-Za-z][A-Za-z ]*?):\s*(.*)$", line)
        if m and m.group(2).strip():
            meta[m.group(1).strip()] = m.group(2).strip()
    units_line = lines[dash - 1] if "(" in lines[dash - 1] else None
    header = lines[dash - 2] if units_line is not None else lines[dash - 1]
    return meta, _sigma_case(_names(header)), units_line, dash + 1


def _recorded(meta: dict[str, Any], run: str | None) -> Recorded | None:
    """The run's place in its magnet's measurement history (None when the header names no magnet)."""
    magnet = " ".join(str(meta.get(k, "")).strip() for k in ("Magnet Name", "Serial Number")).strip()
    if not magnet:
        return None
    try:
        # The header's local time, read as UTC: only the order of one magnet's runs matters.
        stamp = datetime.strptime(f"{meta.get('Date', '')} {meta.get('Time', '')}", "%m-%d-%Y %H:%M:%S")
        order = stamp.replace(tzinfo=timezone.utc).timestamp()
    except ValueError:
        if run is None or not str(run).isdigit():
            return None
        order = float(run)
    return Recorded(f"SLAC magnet {magnet}", order)


def read(path: str | Path) -> list[Table]:
    """The run's samples as one table named ``runN``."""
    p = Path(path)
    text = read_text(p)
    m = _NAME.match(p.name)
    lines = text.splitlines()
    first = next((line for line in lines if line.strip()), "")
    if first.strip() == _SIGNATURE:
        meta, names, units_line, start = _strdat(text, str(p))
    elif first.split()[:1] == ["Time"] and "MAIN" in first.split():
        names = _sigma_case(_names(first))
        start = lines.index(first) + 1
        meta, units_line = {}, None
        sibling = p.with_name(re.sub(r"(?i)^strplt", "strdat", p.name)) if m else None
        if sibling is not None and sibling != p and sibling.is_file():
            meta, dat_names, units_line, _ = _strdat(read_text(sibling), str(sibling))
            if _value_columns(dat_names) != _value_columns(names):
                units_line = None  # a different layout: the units line does not apply
            meta = {**meta, "metadata_from": sibling.name}
    else:
        raise BundleError(f"{p}: not a SLAC magnetic-measurement table (a strdat file opens with {_SIGNATURE!r}, "
                          "a strplt file with a 'Time MAIN ...' header)")
    rows = _rows(lines, start, len(names), str(p))
    columns = {n: rows[:, j] for j, n in enumerate(names)}
    units = _units(names, units_line)
    run = meta.get("Run Number") or (m.group(2) if m else None)
    name = f"run{run}" if run else p.name
    aliases = {}
    value_names = _value_columns(names)
    if value_names and f"sig{value_names[0]}" in columns:
        aliases["sigma"] = [f"sig{value_names[0]}"]  # the header calls the first uncertainty just "sigma"
    return [Table(name, columns, str(p), units, time_column="Time" if "Time" in columns else None, meta=meta,
                  aliases=aliases, recorded=_recorded(meta, run))]
