"""Measurement tables read from lab files, before they become bundle runs, and the generic readers.

A :class:`Table` is one measurement as a file holds it: named numeric columns of equal length, the unit the file
states for each column (if any), the column the format designates as time (if any), where it came from and the
file's metadata. A file may hold several tables (an analyzer export with one table per measurement, a capture
with several rasters). The generic readers here (CSV, Parquet, TDMS, MATLAB variables) and the instrument formats
are registered in :mod:`bmr.data.formats`, whose ``read_tables`` picks the reader for a file.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np
import pandas as pd

from bmr._core import BmrError, BundleError
from bmr.data.units import unit as parse_unit

__all__ = ["Recorded", "Table", "read_text", "split_name_unit", "read_csv", "read_parquet",
           "read_tdms", "read_mat", "load_mat"]


@dataclass(frozen=True)
class Recorded:
    """Where a table stands in a measurement history: the recordings made one after the other on one device, each
    starting from the state the previous one left. ``history`` names the sequence (the same for every table of it),
    ``order`` sorts its tables in recording order (a time stamp in s, or a position in the file)."""

    history: str
    order: float


@dataclass
class Table:
    """One measurement from a lab file. ``columns`` maps names to equal-length float arrays, ``units`` a column to
    the unit the file states for it, ``time_column`` the format's time axis (None: find it by name), ``source``
    names the file (and the table inside it) in messages, ``aliases`` maps other spellings (lower case) to
    column names, ``not_numbers`` names the file's columns that hold something other than real numbers (date-times,
    durations, booleans, complex numbers) and what they hold: naming one is an error that says so. ``recorded``:
    its place in a measurement history, when the format knows the recording order (None otherwise)."""

    name: str
    columns: dict[str, np.ndarray]
    source: str
    units: dict[str, str] = field(default_factory=dict)
    time_column: str | None = None
    meta: dict[str, Any] = field(default_factory=dict)
    aliases: dict[str, list[str]] = field(default_factory=dict)
    not_numbers: dict[str, str] = field(default_factory=dict)
    recorded: Recorded | None = None

    def __post_init__(self) -> None:
        if not self.columns:
            raise BundleError(f"{self.source}: no numeric columns")
        lengths = {k: len(v) for k, v in self.columns.items()}
        if len(set(lengths.values())) > 1:
            raise BundleError(f"{self.source}: columns have different lengths: "
                           + ", ".join(f"{k}={n}" for k, n in lengths.items()))
        if self.n_samples == 0:
            raise BundleError(f"{self.source}: the table has a header but no samples (empty or truncated file)")

    @property
    def n_samples(self) -> int:
        return len(next(iter(self.columns.values())))

    def find(self, name: str) -> str | None:
        """The column spelled ``name``: exactly, ignoring case, or through an alias (e.g. the last part of a
        ControlDesk signal path). Ambiguous aliases are an error."""
        if name in self.columns:
            return name
        low = name.strip().lower()
        hits = [k for k in self.columns if k.lower() == low]
        if len(hits) == 1:
            return hits[0]
        targets = sorted(set(hits) | set(self.aliases.get(low, [])))
        if len(targets) > 1:
            raise BundleError(f"{self.source}: column {name!r} is ambiguous ({', '.join(targets)}); use the full name")
        if not targets:
            for key, what in self.not_numbers.items():
                if key.lower() == low:
                    raise BundleError(f"{self.source}: column {key!r} holds {what}")
        return targets[0] if targets else None

    def column(self, name: str, role: str = "column") -> tuple[str, np.ndarray]:
        """``(column name, values)`` for ``name``; a ``BundleError`` naming the file, the role (e.g. "input") and the
        available columns when it is missing."""
        key = self.find(name)
        if key is None:
            raise BundleError(f"{self.source}: no column {name!r} for the {role} (columns: "
                              f"{', '.join(self.columns)})")
        return key, self.columns[key]

    def unit_of(self, name: str) -> str | None:
        return self.units.get(name) or None


def split_name_unit(header: str) -> tuple[str, str | None]:
    """``"Time [s]"``, ``"Time (s)"`` and ``"Time s"`` are the column ``Time`` in ``s``; a trailing word or
    bracket is taken as a unit only when it is a registered unit (``"Force (filtered)"`` stays one name)."""
    h = header.strip()
    m = re.match(r"^(.*?)\s*[\[(]([^\[\]()]+)[\])]\s*$", h)
    candidates = []
    if m and m.group(1):
        candidates.append((m.group(1).strip(), m.group(2).strip()))
    parts = h.rsplit(None, 1)
    if len(parts) == 2:
        candidates.append((parts[0].strip(), parts[1].strip()))
    for name, u in candidates:
        try:
            parse_unit(u)
        except BmrError:
            continue
        return name, u
    return h, None


def read_text(path: Path) -> str:
    """A text file's content: UTF-8 (with or without BOM), UTF-16 with BOM, otherwise Windows-1252 (what
    instrument software on Windows writes)."""
    raw = _read_bytes(path)
    if raw[:2] in (b"\xff\xfe", b"\xfe\xff"):
        try:
            return raw.decode("utf-16")
        except UnicodeDecodeError as exc:
            raise BundleError(f"{path}: not valid UTF-16 text ({exc})") from None
    if b"\x00" in raw[:4096]:
        raise BundleError(f"{path}: binary content, not a text table")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        return raw.decode("cp1252", errors="replace")


def _read_bytes(path: Path) -> bytes:
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise BundleError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    if not raw.strip():
        raise BundleError(f"{path}: the file is empty")
    return raw


# ------------------------------------------------------------------------------------------ generic readers
# Column kinds that are not measurements, and what to do about them: naming such a column is an error saying so.
_NOT_NUMBERS = {
    "M": "date-times; convert them to seconds (e.g. (t - t[0]).dt.total_seconds()) before reading",
    "m": "durations; convert them to seconds (e.g. .dt.total_seconds()) before reading",
    "b": "booleans, not measurements",
    "c": "complex numbers; keep the real-valued measurement",
}


def _frame_table(path: Path, df: pd.DataFrame, units: Mapping[str, str] | None = None) -> Table:
    columns: dict[str, np.ndarray] = {}
    found_units: dict[str, str] = dict(units or {})
    aliases: dict[str, list[str]] = {}
    not_numbers: dict[str, str] = {}
    for c in df.columns:
        series = df[c]
        if series.dtype.kind not in "iuf":
            what = _NOT_NUMBERS.get(series.dtype.kind)
            if what is not None:
                not_numbers[split_name_unit(str(c))[0]] = what
            continue  # text, dates and flags are not signals
        name, u = split_name_unit(str(c))
        if name in columns:
            name = str(c).strip()
        columns[name] = series.to_numpy(dtype=float)
        if u is not None:
            found_units[name] = u
            aliases.setdefault(str(c).strip().lower(), []).append(name)
    if not columns:
        raise BundleError(f"{path}: no numeric columns (columns: {', '.join(map(str, df.columns))})")
    return Table(path.stem, columns, str(path), found_units, aliases=aliases, not_numbers=not_numbers)


@dataclass(frozen=True)
class _TextLayout:
    """Where a delimited text table's header is and how its fields are written."""

    delimiter: str | None  # None: runs of whitespace
    header_line: int | None  # 0-based; the lines before it are a preamble (comments, metadata); None: no header
    decimal: str
    # A row of units under the header (0-based line; None: the header states them, if at all), and the first row
    # of numbers.
    units_line: int | None = None
    data_line: int = 0


def _number_text(x: str, decimal: str) -> bool:
    x = x.strip()
    if decimal == ",":
        x = x.replace(",", ".")
    try:
        float(x)
    except ValueError:
        return False
    return bool(x)


def units_row(row: list[str]) -> bool:
    """Every field a registered unit (or empty, ``-``), at least one given: the row under a header that plotting
    and logging programs write (``Time,Voltage`` then ``s,V``; also followed by a row of comments)."""
    given = [x.strip() for x in row if x.strip()]
    if not given:
        return False
    for x in given:
        try:
            parse_unit(x)
        except BmrError:
            return False
    return True


def _rows_layout(fields: list[list[str]], decimal: str) -> tuple[int | None, int | None, int] | None:
    """``(header row, units row, first row of numbers)`` of a table whose rows are split into ``fields``: the first
    header row (no field a number) followed by rows with as many fields (at least half of them numbers: label
    columns may sit beside the signals), directly or after a row of units (and a comment row under it, as plotting
    programs export); else, without any header, the first of at least two rows whose fields are all numbers
    (header None). None if no row fits."""
    def data(row: list[str], width: int) -> bool:
        return len(row) == width and 2 * sum(_number_text(x, decimal) for x in row) >= width

    def label(i: int, width: int) -> bool:
        return i < len(fields) and len(fields[i]) == width and not any(_number_text(x, decimal) for x in fields[i])

    def numbers_from(i: int, width: int) -> bool:
        rows = fields[i:i + 2]
        return bool(rows) and all(data(r, width) for r in rows)

    for i in range(len(fields) - 1):
        width = len(fields[i])
        if width < 2 or not label(i, width):
            continue  # a header names its columns
        if numbers_from(i + 1, width):
            return i, None, i + 1
        if label(i + 1, width) and units_row(fields[i + 1]):
            for first in (i + 2, i + 3):  # the numbers, after a comment row or not
                if (first == i + 2 or label(i + 2, width)) and numbers_from(first, width):
                    return i, i + 1, first
    numbers = [len(f) >= 2 and all(_number_text(x, decimal) for x in f) for f in fields]
    for i in range(len(fields)):
        rows = range(i, min(i + 3, len(fields)))
        if numbers[i] and all(numbers[k] and len(fields[k]) == len(fields[i]) for k in rows):
            return None, None, i
    return None


def _text_layout(lines: list[str]) -> _TextLayout | None:
    """The layout (:func:`_rows_layout`) of the first delimiter (comma, semicolon, tab, whitespace) and decimal mark
    that give one, tables with a header before those without; None if none does. A table without a header has
    its columns numbered from 1."""
    options = [(d, m) for d in (",", ";", "\t", None) for m in (".", ",") if not (d == "," and m == ",")]
    headless = None
    for delimiter, decimal in options:
        found = _rows_layout([(line.split(delimiter) if delimiter else line.split()) for line in lines], decimal)
        if found is None:
            continue
        header, units, first = found
        layout = _TextLayout(delimiter, header, decimal, units_line=units, data_line=first)
        if header is not None:
            return layout
        headless = headless or layout
    return headless


def _preamble(lines: list[str]) -> dict[str, Any]:
    """``key: value`` (or ``key = value``, ``key,value``) lines before a table's header, without comment marks."""
    meta: dict[str, Any] = {}
    for line in lines:
        text = line.strip().lstrip("#%;").strip()
        m = re.match(r"^([^:=,;\t]+?)\s*[:=,;\t]\s*(.+)$", text)
        if m:
            meta[m.group(1).strip()] = m.group(2).strip().strip('"')
    return meta


def read_csv(path: str | Path) -> list[Table]:
    """A delimited text table: comma, semicolon, tab or whitespace, decimal point or comma, one header line
    (optionally a row of units under it, and a comment row under that), and any preamble before it (comment or
    ``key: value`` lines, kept as the table's metadata); all found from the first lines. A table without a header
    has its columns numbered ``1``, ``2``, ... (they state no unit)."""
    p = Path(path)
    raw = _read_bytes(p)
    head = raw[:65536].decode("utf-8", errors="replace").splitlines()[:200]
    layout = _text_layout([line.rstrip("\r\n") for line in head])
    if layout is None:
        raise BundleError(f"{p}: cannot be read as CSV: no rows of numbers under a header line (or without one) "
                          f"in its first {len(head)} line(s) (empty, truncated or not a delimited table)")
    sep = layout.delimiter or r"\s+"
    try:
        if layout.header_line is None:
            df = pd.read_csv(p, sep=sep, skiprows=layout.data_line, header=None, decimal=layout.decimal,
                             encoding_errors="replace")
            df.columns = [str(k + 1) for k in range(df.shape[1])]
        else:
            # The preamble, and the units and comment rows under the header (the units are read below).
            skipped = list(range(layout.header_line)) + list(range(layout.header_line + 1, layout.data_line))
            df = pd.read_csv(p, sep=sep, skiprows=skipped, header=0,
                             decimal=layout.decimal, encoding_errors="replace")
    except Exception as exc:  # noqa: BLE001 - any parser failure is a clear file error
        raise BundleError(f"{p}: cannot be read as CSV ({exc})") from None
    if len(df) == 0:
        raise BundleError(f"{p}: the CSV has a header but no samples (empty or truncated file)")
    units: dict[str, str] = {}
    if layout.units_line is not None and layout.header_line is not None:
        # The header as the parser read it (quotes, a byte-order mark), the units row beside it.
        row = _split_fields(head[layout.units_line], layout.delimiter)
        units = {split_name_unit(str(n))[0]: u for n, u in zip(df.columns, row) if u and u != "-"}
    table = _frame_table(p, df, units)
    preamble_end = layout.header_line if layout.header_line is not None else layout.data_line
    table.meta.update(_preamble(head[:preamble_end]))
    return [table]


def _split_fields(line: str, delimiter: str | None) -> list[str]:
    """A text line's fields, stripped of blanks and quotes."""
    parts = line.rstrip("\r\n").split(delimiter) if delimiter else line.split()
    return [x.strip().strip('"').strip() for x in parts]


# Spreadsheet files and the package pandas reads each with.
SPREADSHEET_ENGINES = {".xlsx": "openpyxl", ".xlsm": "openpyxl", ".ods": "odf", ".xls": "xlrd"}
_ENGINE_PACKAGES = {"openpyxl": "openpyxl", "odf": "odfpy", "xlrd": "xlrd"}


def _cell_text(x: Any) -> str:
    if x is None or (isinstance(x, float) and np.isnan(x)):
        return ""
    return repr(float(x)) if isinstance(x, (int, float, np.number)) and not isinstance(x, bool) else str(x).strip()


def read_spreadsheet(path: str | Path) -> list[Table]:
    """Every sheet of a spreadsheet (``.xlsx``, ``.xlsm``, ``.ods``; ``.xls`` with ``xlrd``) that holds a table, laid
    out as in a text table (:func:`_rows_layout`: a preamble, a header, a row of units, or no header), one table per
    sheet (named ``<file>-<sheet>`` when the file has several). Its rows end at the first row that is not a row of
    numbers (notes under a table); columns of text beside the numbers are left out."""
    p = Path(path)
    _read_bytes(p)
    engine = SPREADSHEET_ENGINES.get(p.suffix.lower(), "openpyxl")
    try:
        sheets = pd.read_excel(p, sheet_name=None, header=None, engine=engine)
    except ImportError:
        raise BundleError(f"{p}: reading {p.suffix} files needs the package {_ENGINE_PACKAGES[engine]!r} "
                          f"(pip install {_ENGINE_PACKAGES[engine]})") from None
    except Exception as exc:  # noqa: BLE001 - any parser failure is a clear file error
        raise BundleError(f"{p}: cannot be read as a spreadsheet ({type(exc).__name__}: {exc})") from None
    tables = []
    for sheet, frame in sheets.items():
        frame = frame.dropna(axis=1, how="all").dropna(axis=0, how="all")
        if frame.shape[0] < 2 or frame.shape[1] < 2:
            continue
        cells = [[_cell_text(x) for x in row] for row in frame.itertuples(index=False)]
        found = _rows_layout(cells, ".")
        if found is None:
            continue
        header, units, first = found
        last = first
        while last < len(cells) and 2 * sum(_number_text(x, ".") for x in cells[last]) >= len(cells[last]):
            last += 1
        body = frame.iloc[first:last]
        names = ([str(x) if x else f"{k + 1}" for k, x in enumerate(cells[header])] if header is not None
                 else [str(k + 1) for k in range(frame.shape[1])])
        data = pd.DataFrame({n: pd.to_numeric(body.iloc[:, k], errors="coerce").to_numpy()
                             for k, n in enumerate(names) if _mostly_numbers(body.iloc[:, k])})
        stated = ({split_name_unit(n)[0]: u for n, u in zip(names, cells[units]) if u and u != "-"}
                  if units is not None else {})
        if data.empty:
            continue
        table = _frame_table(p, data, stated)
        table.name = f"{p.stem}-{sheet}" if len(sheets) > 1 else p.stem
        table.source = f"{p} (sheet {sheet!r})" if len(sheets) > 1 else str(p)
        preamble = cells[:header if header is not None else first]
        table.meta.update(_preamble([",".join(x for x in r if x) for r in preamble]))
        tables.append(table)
    if not tables:
        raise BundleError(f"{p}: no sheet holds rows of numbers under a header row (or without one)")
    return tables


def _mostly_numbers(column: pd.Series) -> bool:
    """At least half the cells numbers (the rest empty or notes): a signal, not a label column."""
    values = pd.to_numeric(column, errors="coerce")
    return bool(values.notna().sum() * 2 >= len(values) and values.notna().any())


def read_parquet(path: str | Path) -> list[Table]:
    p = Path(path)
    _read_bytes(p)
    try:
        df = pd.read_parquet(p)
    except Exception as exc:  # noqa: BLE001
        raise BundleError(f"{p}: cannot be read as Parquet ({exc})") from None
    return [_frame_table(p, df)]


def read_tdms(path: str | Path) -> list[Table]:
    """NI TDMS: every numeric channel as ``group/channel`` (and as ``channel`` when that name is unique); the
    ``unit_string`` property is the channel's unit."""
    p = Path(path)
    _read_bytes(p)
    try:
        from nptdms import TdmsFile
    except ImportError:  # pragma: no cover - npTDMS is a dependency
        raise BundleError("reading .tdms needs the npTDMS package (pip install npTDMS)") from None
    try:
        tdms = TdmsFile.read(p)
    except Exception as exc:  # noqa: BLE001
        raise BundleError(f"{p}: cannot be read as TDMS ({exc})") from None
    columns: dict[str, np.ndarray] = {}
    units: dict[str, str] = {}
    aliases: dict[str, list[str]] = {}
    for group in tdms.groups():
        for channel in group.channels():
            data = np.asarray(channel[:])
            if data.dtype.kind not in "iuf":
                continue
            key = f"{group.name}/{channel.name}"
            columns[key] = data.astype(float)
            u = channel.properties.get("unit_string")
            if isinstance(u, str) and u.strip():
                units[key] = u.strip()
            aliases.setdefault(channel.name.lower(), []).append(key)
    if not columns:
        raise BundleError(f"{p}: no numeric TDMS channels")
    return _split_by_length(p, columns, units, aliases)


def load_mat(path: Path) -> dict[str, Any]:
    """``scipy.io.loadmat`` with MATLAB structs as attribute objects and 1×N arrays squeezed; v7.3 (HDF5) files
    through ``mat73`` in the same shapes; damaged files are clear errors."""
    _read_bytes(path)
    try:
        from scipy.io import loadmat
    except ImportError:  # pragma: no cover - scipy is a dependency
        raise BundleError("reading .mat needs scipy") from None
    try:
        return loadmat(path, squeeze_me=True, struct_as_record=False)
    except NotImplementedError:
        return _load_mat_v73(path)
    except Exception as exc:  # noqa: BLE001
        raise BundleError(f"{path}: cannot be read as a MATLAB file ({exc})") from None


class MatStruct:
    """A MATLAB struct read from a v7.3 file, shaped like ``scipy.io.loadmat``'s (``_fieldnames`` and one attribute
    per field), so that every reader walks v7 and v7.3 files alike."""

    def __init__(self, fields: Mapping[str, Any]) -> None:
        self._fieldnames = list(fields)
        for name, value in fields.items():
            setattr(self, name, value)


def _as_loadmat(value: Any) -> Any:
    """A value of ``mat73.loadmat`` (dicts for structs, lists for cells and struct arrays) in ``loadmat``'s shapes."""
    if isinstance(value, dict):
        return MatStruct({k: _as_loadmat(v) for k, v in value.items()})
    if isinstance(value, list):
        items = [_as_loadmat(v) for v in value]
        out = np.empty(len(items), dtype=object)
        out[:] = items
        return out
    return value


def _load_mat_v73(path: Path) -> dict[str, Any]:
    """A MATLAB v7.3 (HDF5) file through ``mat73``, its variables in ``loadmat``'s shapes."""
    try:
        import mat73
    except ImportError:  # pragma: no cover - a dependency
        raise BundleError(f"{path}: reading MATLAB v7.3 (HDF5) files needs the package 'mat73' (pip install mat73)"
                          ) from None
    try:
        raw = mat73.loadmat(str(path), verbose=False)
    except Exception as exc:  # noqa: BLE001 - any parser failure is a clear file error
        raise BundleError(f"{path}: cannot be read as a MATLAB v7.3 (HDF5) file ({type(exc).__name__}: {exc})"
                          ) from None
    return {k: _as_loadmat(v) for k, v in raw.items()}


def read_mat(path: str | Path) -> list[Table]:
    """MATLAB variables: numeric vectors by name, struct fields as ``struct.field``, and each column of a matrix
    as ``name[k]`` (1-based: one loop per column, as hysteresisgraphs store concentric loops)."""
    p = Path(path)
    mat = load_mat(p)
    columns: dict[str, np.ndarray] = {}

    def add(name: str, value: Any) -> None:
        if hasattr(value, "_fieldnames"):
            for f in value._fieldnames:
                add(f"{name}.{f}", getattr(value, f))
            return
        arr = np.asarray(value)
        if arr.dtype.kind not in "iuf" or arr.size <= 1:
            return
        if arr.ndim == 1 or (arr.ndim == 2 and 1 in arr.shape):
            columns[name] = arr.ravel().astype(float)
        elif arr.ndim == 2:
            matrix = arr if arr.shape[0] >= arr.shape[1] else arr.T  # samples along the longer side
            for k in range(matrix.shape[1]):
                columns[f"{name}[{k + 1}]"] = matrix[:, k].astype(float)

    for key, value in mat.items():
        if not key.startswith("__"):
            add(key, value)
    if not columns:
        raise BundleError(f"{p}: no numeric vectors among the MATLAB variables "
                          f"({', '.join(k for k in mat if not k.startswith('__')) or 'none'})")
    return _split_by_length(p, columns, {}, {})


def _split_by_length(path: Path, columns: dict[str, np.ndarray], units: dict[str, str],
                     aliases: dict[str, list[str]]) -> list[Table]:
    """One table if every column has the same length, otherwise one per length (named by it)."""
    by_len: dict[int, list[str]] = {}
    for k, v in columns.items():
        by_len.setdefault(len(v), []).append(k)
    if len(by_len) == 1:
        return [Table(path.stem, columns, str(path), units, aliases=aliases)]
    out = []
    for n, keys in sorted(by_len.items(), key=lambda kv: -kv[0]):
        keep = set(keys)
        al = {a: [k for k in ks if k in keep] for a, ks in aliases.items()}
        out.append(Table(f"{path.stem}-{n}", {k: columns[k] for k in keys}, f"{path} ({n}-sample columns)",
                         {k: u for k, u in units.items() if k in keep}, aliases={a: v for a, v in al.items() if v}))
    return out
