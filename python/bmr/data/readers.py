"""Actuator lab logs with a column mapping: CSV, Parquet, NI TDMS, MATLAB ``.mat`` (plain variables or dSPACE
ControlDesk captures) into ``bmr-bundle/1`` runs and bundles. (Logs of any device, with declared quantities and
units: :func:`bmr.data.importing.import_logs`.)

A file's columns (or TDMS channels, or MAT variables) are mapped onto the bundle's unit-named columns
(``t_s``, ``current_a``, ``theta_rad``, ``torque_nmm`` and the optional ones) with ``mapping`` and converted to the
bundle's units with ``units`` (any unit of the column's dimension in :mod:`bmr.data.units`)::

    df = read_table("run1.tdms", mapping={"current_a": "Data/I_cmd", "torque_nmm": "Data/Torque",
                                          "theta_rad": "Data/Encoder", "t_s": "Data/Time"},
                    units={"current_a": "0.125A", "torque_nmm": "N*m", "theta_rad": "deg"})

``"0.125A"`` (alias ``"V"`` for current columns) is the paper's current unit: converter volts at 0.125 A/V.
"""
from __future__ import annotations

import math
import numbers
from pathlib import Path
from typing import Any, Iterable, Mapping

import numpy as np
import pandas as pd

from bmr._core import BundleError
from bmr.data.bundle import OPTIONAL_COLUMNS, REQUIRED_COLUMNS, Bundle, Run
from bmr.data.formats import read_tables
from bmr.data.signals import nominal_sample_rate
from bmr.data.tables import Table
from bmr.data.units import convert, unit, units_of

__all__ = ["COLUMN_UNITS", "convert_units", "read_table", "bundle_from_files", "supported_units"]

# Unit of each bundle column (its dimension is the unit's).
COLUMN_UNITS = {
    "t_s": "s",
    "current_a": "A",
    "coil1_a": "A",
    "coil2_a": "A",
    "theta_rad": "rad",
    "torque_nmm": "N·mm",
    "reference_nmm": "N·mm",
    "temperature_c": "°C",
    "speed_rad_s": "rad/s",
}
# Spellings these columns accepted before the unit registry, kept: converter volts for currents, bare C/F.
_LEGACY = {"current": {"v": "0.125 A"}, "temperature": {"c": "°C", "f": "°F"}}
_SUFFIXES = (".csv", ".txt", ".parquet", ".pq", ".tdms", ".mat", ".xlsx", ".xlsm", ".ods", ".xls")


def _column_unit(column: str) -> str:
    if column not in COLUMN_UNITS:
        raise BundleError(f"unknown bundle column {column!r}; known: {', '.join(COLUMN_UNITS)}")
    return COLUMN_UNITS[column]


def supported_units(column: str) -> list[str]:
    """Units accepted for a bundle column (those of its dimension)."""
    return units_of(unit(_column_unit(column)).dimension)


def convert_units(column: str, values: np.ndarray, unit_text: str) -> np.ndarray:
    """Convert ``values`` given in ``unit_text`` to the unit of bundle column ``column``."""
    target = unit(_column_unit(column))
    legacy = _LEGACY.get(target.dimension, {}).get(str(unit_text).strip().lower())
    src = unit(legacy or unit_text, dimension=target.dimension, what=f"column {column!r}")
    return convert(values, src, target, what=f"column {column!r}")


def read_table(
    path: str | Path,
    mapping: Mapping[str, str] | None = None,
    units: Mapping[str, str] | None = None,
    *,
    defaults: Mapping[str, float] | None = None,
    sample_rate_hz: float | None = None,
) -> pd.DataFrame:
    """Read one lab file into a DataFrame with bundle columns.

    ``path``: ``.csv``/``.txt``, ``.parquet``/``.pq``, ``.tdms`` or ``.mat`` (read by
    :func:`bmr.data.formats.read_tables`).
    ``mapping``: bundle column -> source name (CSV/Parquet column; TDMS ``"group/channel"`` or a channel name unique
    across groups; MAT variable, ``"struct.field"`` or ControlDesk channel). Unmapped bundle columns are taken from
    a source of the same name when present.
    ``units``: bundle column -> unit of the source (any unit of the column's dimension in :mod:`bmr.data.units`);
    unmapped columns are taken as already in the bundle's units.
    ``defaults``: constant values for columns the file lacks (e.g. ``{"theta_rad": 0.0}`` for a test rig
    without an encoder). ``sample_rate_hz``: builds ``t_s`` from the sample index when the file has no time.
    Missing required columns, unknown units, unknown names and unequal lengths are ``BmrError``s.
    """
    _check_arguments(mapping, units, defaults, sample_rate_hz)
    file = Path(path)
    if not file.is_file():
        raise BundleError(f"{str(file)!r} does not exist")
    mapping = dict(mapping or {})
    units = dict(units or {})
    for col in (*mapping, *units):
        _column_unit(col)
    suffix = file.suffix.lower()
    if suffix not in _SUFFIXES:
        raise BundleError(f"{file}: unsupported file type {suffix!r} (read .csv, .txt, .parquet, .tdms, .mat, .xlsx, .ods)")
    tables = read_tables(file)

    out: dict[str, np.ndarray] = {}
    for col in (*REQUIRED_COLUMNS, *OPTIONAL_COLUMNS):
        name = mapping.get(col, col)
        values = _lookup(tables, name)
        if values is None:
            if col in mapping:
                available = sorted({c for t in tables for c in t.columns})
                raise BundleError(f"{file}: mapped source {name!r} for column {col!r} not found "
                                  f"(available: {', '.join(available)})")
            continue
        out[col] = convert_units(col, values, units[col]) if col in units else np.asarray(values, dtype=float)
    n = max((len(v) for v in out.values()), default=0)
    for col, value in (defaults or {}).items():
        _column_unit(col)
        if col not in out:
            out[col] = np.full(n, float(value))
    if "t_s" not in out and sample_rate_hz is not None:
        if not (sample_rate_hz > 0 and math.isfinite(sample_rate_hz)):
            raise BundleError(f"sample_rate_hz must be positive and finite, got {sample_rate_hz!r}")
        out["t_s"] = np.arange(n) / float(sample_rate_hz)
    missing = [c for c in REQUIRED_COLUMNS if c not in out]
    if missing:
        available = sorted({c for t in tables for c in t.columns})
        raise BundleError(f"{file}: no source for required column(s) {', '.join(missing)}; map them with "
                          f"mapping={{'{missing[0]}': '<name>'}} (available: {', '.join(available)})")
    lengths = {c: len(v) for c, v in out.items()}
    if len(set(lengths.values())) > 1:
        raise BundleError(f"{file}: columns have different lengths: "
                       + ", ".join(f"{c}={k}" for c, k in lengths.items()))
    return pd.DataFrame(out)


def bundle_from_files(
    files: Iterable[Mapping[str, Any]],
    *,
    actuator: str = "",
    sample_rate_hz: float | None = None,
    mapping: Mapping[str, str] | None = None,
    units: Mapping[str, str] | None = None,
    defaults: Mapping[str, float] | None = None,
) -> Bundle:
    """Build a bundle from lab files. Each item of ``files`` is a dict with ``path``, ``name`` and ``kind`` and
    optionally its own ``mapping``/``units``/``defaults`` (overriding the shared ones) and ``meta``.

    ``sample_rate_hz`` defaults to the median sample rate of the first run's time column.
    """
    runs = []
    for k, spec in enumerate(files):
        if not all(key in spec for key in ("path", "name", "kind")):
            raise BundleError(f"files[{k}] needs 'path', 'name' and 'kind'")
        df = read_table(spec["path"], {**(mapping or {}), **spec.get("mapping", {})},
                        {**(units or {}), **spec.get("units", {})},
                        defaults={**(defaults or {}), **spec.get("defaults", {})}, sample_rate_hz=sample_rate_hz)
        runs.append(Run(str(spec["name"]), str(spec["kind"]), df, dict(spec.get("meta", {}))))
    if not runs:
        raise BundleError("bundle_from_files needs at least one file")
    if sample_rate_hz is None:
        sample_rate_hz = nominal_sample_rate(runs[0].t)
    return Bundle(actuator=actuator, sample_rate_hz=float(sample_rate_hz), runs=runs)


def _check_arguments(mapping: Any, units: Any, defaults: Any, sample_rate_hz: Any) -> None:
    """Wrong argument types are TypeErrors naming the argument; values out of range are BmrErrors."""
    for arg, value in (("mapping", mapping), ("units", units), ("defaults", defaults)):
        if value is not None and not isinstance(value, Mapping):
            raise TypeError(f"{arg}: expected a dict {{bundle column: ...}}, got {type(value).__name__}")
    for arg, value in (("mapping", mapping), ("units", units)):
        for k, v in (value or {}).items():
            if not isinstance(k, str) or not isinstance(v, str):
                raise TypeError(f"{arg}: expected bundle column names mapped to strings, got {k!r}: {v!r}")
    for k, v in (defaults or {}).items():
        if not isinstance(k, str) or isinstance(v, bool) or not isinstance(v, numbers.Real):
            raise TypeError(f"defaults[{k!r}]: expected a number in the column's unit, got {v!r}")
        if not math.isfinite(v):
            raise BundleError(f"defaults[{k!r}] must be finite, got {v!r}")
    if sample_rate_hz is not None:
        if isinstance(sample_rate_hz, bool) or not isinstance(sample_rate_hz, numbers.Real):
            raise TypeError(f"sample_rate_hz: expected a number of Hz, got {sample_rate_hz!r}")
        if not (math.isfinite(sample_rate_hz) and sample_rate_hz > 0):
            raise BundleError(f"sample_rate_hz must be positive and finite, got {sample_rate_hz!r}")


def _lookup(tables: list[Table], name: str) -> np.ndarray | None:
    """The column spelled ``name`` in the first table that has it."""
    for t in tables:
        key = t.find(name)
        if key is not None:
            return t.columns[key]
    return None
