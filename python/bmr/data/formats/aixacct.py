"""Tab-separated measurement tables as ferroelectric analyzers (aixACCT TF Analyzer "Export as ASCII") write them.

A file holds one table per measurement, each with its own header line, possibly with a title (``Table 3``) and
metadata lines (``SampleName: C12``, ``Hysteresis Frequency [Hz]: 100``) before it::

    DynamicHysteresisResult
    SampleName: C12
    Table 1
    Hysteresis Amplitude [V]: 10
    Time s<TAB>Vplus V<TAB>Vminus V<TAB>I1 A<TAB>P1 uC_per_cm2
    0.000000e+000<TAB>0.0<TAB>0.0<TAB>1.2e-7<TAB>-21.3
    ...

Each header field is a name followed by its unit (``P1 uC_per_cm2``, or bracketed: ``P1 [uC/cm2]``). Numbers may
use a decimal comma (as exports in European locales do). A table ends at a blank or non-numeric line. Metadata lines become the table's ``meta`` (those before the first table are
shared by all). Lines of numbers that do not match their header (a truncated last line) are errors naming the line.
"""
from __future__ import annotations

import io
import re
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from bmr._core import BmrError, BundleError
from bmr.data.tables import Table, read_text, split_name_unit, units_row

__all__ = ["read", "looks_like"]

_TITLE = re.compile(r"^(Result\s+|Data\s+)?Table\b.*$", re.IGNORECASE)
_META = re.compile(r"^([^:\t]+):\s*(.*)$")


def _fields(line: str) -> list[str]:
    f = line.rstrip("\r\n").split("\t")
    while f and not f[-1].strip():
        f.pop()
    return [x.strip() for x in f]


def _number(text: str, decimal: str = ".") -> float | None:
    try:
        return float(text.replace(",", ".") if decimal == "," else text)
    except ValueError:
        return None


def _numeric(fields: list[str], decimal: str = ".") -> bool:
    return bool(fields) and all(_number(x, decimal) is not None for x in fields)


def _decimal(fields: list[str]) -> str | None:
    """The decimal mark of a row of numbers (``"."``, or ``","`` as European locales write them), or None."""
    return "." if _numeric(fields) else "," if _numeric(fields, ",") else None


def _header(fields: list[str]) -> bool:
    return (len(fields) >= 2 and all(fields) and not any(_number(x) is not None for x in fields)
            and not fields[0].endswith(":"))


def _starts_numeric(line: str) -> bool:
    """Cheap test for a data row: its first character can start a number."""
    head = line.lstrip()[:1]
    return bool(head) and (head in "0123456789+-.," or line.lstrip()[:3].lower() in ("nan", "inf"))


def _rows(lines: list[str], start: int, stop: int, header: list[str], last: int, source: str,
          decimal: str = ".") -> np.ndarray:
    """Rows ``start:stop`` as floats (parsed in C by pandas); a row whose field count differs from the header's,
    or a field that is not a number, is an error naming its line."""
    width = len(header)
    block = [line.rstrip("\r\n").rstrip("\t ") for line in lines[start:stop]]
    counts = np.fromiter((b.count("\t") + 1 for b in block), dtype=int, count=len(block))
    bad = np.flatnonzero(counts != width)
    if bad.size:
        k = int(bad[0])
        truncated = " (truncated file?)" if start + k == last else ""
        raise BundleError(f"{source}, line {start + k + 1}: {int(counts[k])} values under a header of {width} "
                          f"({', '.join(header)}){truncated}")
    try:
        frame = pd.read_csv(io.StringIO("\n".join(block)), sep="\t", header=None, dtype=float, decimal=decimal)
    except ValueError as exc:
        for k, b in enumerate(block):
            if not _numeric(_fields(b), decimal):
                raise BundleError(f"{source}, line {start + k + 1}: not a row of numbers: {b.strip()[:60]!r}") from None
        # Each row reads as numbers alone but not together (a line break the rows were split on inside one).
        raise BundleError(f"{source}, lines {start + 1}-{stop}: not a table of numbers ({exc})") from None
    return frame.to_numpy(dtype=float)


def _rows_under_header(lines: list[str], i: int, header: list[str]) -> tuple[int, list[str] | None] | None:
    """Where the numbers under the header line ``i`` start and the row of units between them (None: the header
    states its units), when a row of numbers follows the header directly or after a row of units (and a comment
    row under it, as plotting programs export); None when line ``i`` heads no table."""
    def at(k: int) -> list[str]:
        return _fields(lines[k]) if k < len(lines) else []

    if _decimal(at(i + 1)) is not None:
        return i + 1, None
    units = at(i + 1)
    if len(units) != len(header) or not units_row(units):
        return None
    for first in (i + 2, i + 3):
        if first == i + 3 and not _header(at(i + 2)):
            break
        if _decimal(at(first)) is not None and len(at(first)) == len(header):
            return first, units
    return None


def _tables(text: str, source: str) -> list[tuple[int, list[str], np.ndarray, dict[str, Any], str | None]]:
    """``(header line number, header fields, rows, metadata, title)`` of every table."""
    lines = text.splitlines()
    last = max((i for i, line in enumerate(lines) if line.strip()), default=-1)
    out = []
    shared: dict[str, Any] = {}
    pending: dict[str, Any] = {}
    title: str | None = None
    seen_table = False
    i = 0
    while i < len(lines):
        fields = _fields(lines[i])
        stripped = lines[i].strip()
        if not stripped:
            i += 1
            continue
        under = _rows_under_header(lines, i, fields) if "\t" in lines[i] and _header(fields) else None
        if under is not None:
            first, units = under
            decimal = _decimal(_fields(lines[first]))
            j = first
            while j < len(lines) and _starts_numeric(lines[j]):
                j += 1
            if j == first:  # what follows parses as numbers but does not start like a row of them
                i += 1
                continue
            rows = _rows(lines, first, j, fields, last, source, decimal or ".")
            if units is not None:
                fields = [f"{name} [{unit}]" if unit and unit != "-" and split_name_unit(name)[1] is None else name
                          for name, unit in zip(fields, units)]
            out.append((i + 1, fields, rows, {**shared, **pending}, title))
            pending, title, seen_table = {}, None, True
            i = j
            continue
        if _decimal(fields) is not None and len(fields) >= 2:
            raise BundleError(f"{source}, line {i + 1}: numbers without a header line of column names")
        m = _META.match(stripped)
        if _TITLE.match(stripped):
            title = stripped
        elif m:
            (pending if seen_table or title else shared)[m.group(1).strip()] = m.group(2).strip()
        elif not seen_table and not shared:
            shared["section"] = stripped
        i += 1
    return out


def looks_like(path: Path) -> bool:
    """True when the text file holds at least one tab-separated header line followed by a row of numbers."""
    try:
        text = read_text(path)
    except BmrError:
        return False
    lines = text.splitlines()
    return any("\t" in a and _header(_fields(a)) and _rows_under_header(lines, i, _fields(a)) is not None
               for i, a in enumerate(lines))


def read(path: str | Path) -> list[Table]:
    """One table per measurement in the file."""
    p = Path(path)
    found = _tables(read_text(p), str(p))
    if not found:
        raise BundleError(f"{p}: no tab-separated table found (expected a header line of names with units, e.g. "
                          "'Time s<TAB>Vplus V<TAB>P1 uC_per_cm2', followed by rows of numbers)")
    tables = []
    for k, (line, header, rows, meta, title) in enumerate(found):
        columns: dict[str, np.ndarray] = {}
        units: dict[str, str] = {}
        aliases: dict[str, list[str]] = {}
        for j, field in enumerate(header):
            name, unit = split_name_unit(field)
            if name in columns:
                name = f"{name}.{j}"
            columns[name] = rows[:, j]
            if unit is not None:
                units[name] = unit
                aliases.setdefault(field.lower(), []).append(name)
        many = len(found) > 1
        name = f"{p.stem}-{k + 1}" if many else p.stem
        where = f"{p} (table {k + 1}{', ' + title if title else ''}, header at line {line})" if many else str(p)
        tables.append(Table(name, columns, where, units, meta={**meta, **({"table": title} if title else {})},
                            aliases=aliases))
    return tables
