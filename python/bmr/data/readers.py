"""Lab-data readers: CSV, Parquet, NI TDMS (npTDMS) and MATLAB ``.mat`` (scipy) into bmr runs and bundles.

A file's columns (or TDMS channels, or MAT variables) are mapped onto the bundle's unit-named columns
(``t_s``, ``current_a``, ``theta_rad``, ``torque_nmm`` and the optional ones) with ``mapping`` and converted to the
bundle's units with ``units``::

    df = read_table("run1.tdms", mapping={"current_a": "Data/I_cmd", "torque_nmm": "Data/Torque",
                                          "theta_rad": "Data/Encoder", "t_s": "Data/Time"},
                    units={"current_a": "0.125A", "torque_nmm": "N*m", "theta_rad": "deg"})

``"0.125A"`` (alias ``"V"``) is the paper's current unit: converter volts at 0.125 A/V.
"""
from __future__ import annotations

import math
import numbers
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping

import numpy as np
import pandas as pd

from bmr._core import BmrError
from bmr.data.bundle import OPTIONAL_COLUMNS, REQUIRED_COLUMNS, Bundle, Run, nominal_sample_rate

__all__ = ["UNITS", "convert_units", "read_table", "bundle_from_files", "supported_units"]

_PAPER_CURRENT_UNIT_A = 0.125

# Quantity of each bundle column and the factor (or affine map) from each accepted unit to the column's unit.
_QUANTITY = {
    "t_s": "time",
    "current_a": "current",
    "coil1_a": "current",
    "coil2_a": "current",
    "theta_rad": "angle",
    "torque_nmm": "torque",
    "reference_nmm": "torque",
    "temperature_c": "temperature",
    "speed_rad_s": "speed",
}
UNITS: dict[str, dict[str, float | Callable[[np.ndarray], np.ndarray]]] = {
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "min": 60.0, "h": 3600.0},
    "current": {"a": 1.0, "ma": 1e-3, "0.125a": _PAPER_CURRENT_UNIT_A, "v": _PAPER_CURRENT_UNIT_A},
    "angle": {"rad": 1.0, "deg": math.pi / 180.0, "rev": 2.0 * math.pi, "mrad": 1e-3},
    "torque": {"n*mm": 1.0, "nmm": 1.0, "n.mm": 1.0, "mnm": 1.0, "n*m": 1000.0, "nm": 1000.0, "n.m": 1000.0,
               "n*cm": 10.0, "ncm": 10.0},
    "temperature": {"c": 1.0, "degc": 1.0, "k": lambda x: x - 273.15, "f": lambda x: (x - 32.0) * 5.0 / 9.0},
    "speed": {"rad/s": 1.0, "rpm": 2.0 * math.pi / 60.0, "deg/s": math.pi / 180.0, "rev/s": 2.0 * math.pi},
}


def supported_units(column: str) -> list[str]:
    """Units accepted for a bundle column (case-insensitive, spaces ignored)."""
    return list(UNITS[_quantity(column)])


def _quantity(column: str) -> str:
    if column not in _QUANTITY:
        raise BmrError(f"unknown bundle column {column!r}; known: {', '.join(_QUANTITY)}")
    return _QUANTITY[column]


def convert_units(column: str, values: np.ndarray, unit: str) -> np.ndarray:
    """Convert ``values`` given in ``unit`` to the unit of bundle column ``column``."""
    table = UNITS[_quantity(column)]
    key = str(unit).strip().lower().replace(" ", "").replace("·", "*")
    if key not in table:
        raise BmrError(f"column {column!r}: unknown unit {unit!r}; use one of {', '.join(table)}")
    conv = table[key]
    x = np.asarray(values, dtype=float)
    return conv(x) if callable(conv) else x * conv


def read_table(
    path: str | Path,
    mapping: Mapping[str, str] | None = None,
    units: Mapping[str, str] | None = None,
    *,
    defaults: Mapping[str, float] | None = None,
    sample_rate_hz: float | None = None,
) -> pd.DataFrame:
    """Read one lab file into a DataFrame with bundle columns.

    ``path``: ``.csv``/``.txt``, ``.parquet``/``.pq``, ``.tdms`` or ``.mat``.
    ``mapping``: bundle column -> source name (CSV/Parquet column; TDMS ``"group/channel"`` or a channel name unique
    across groups; MAT variable or ``"struct.field"``). Unmapped bundle columns are taken from a source of the
    same name when present.
    ``units``: bundle column -> unit of the source (see ``UNITS``); unmapped columns are taken as already in the
    bundle's units.
    ``defaults``: constant values for columns the file lacks (e.g. ``{"theta_rad": 0.0}`` for a test rig
    without an encoder). ``sample_rate_hz``: builds ``t_s`` from the sample index when the file has no time.
    Missing required columns, unknown units, unknown names and unequal lengths are ``BmrError``s.
    """
    _check_arguments(mapping, units, defaults, sample_rate_hz)
    file = Path(path)
    if not file.is_file():
        raise BmrError(f"{str(file)!r} does not exist")
    mapping = dict(mapping or {})
    units = dict(units or {})
    for col in (*mapping, *units):
        _quantity(col)
    suffix = file.suffix.lower()
    if suffix in (".csv", ".txt"):
        source = _columns_from_frame(file, _read_csv(file))
    elif suffix in (".parquet", ".pq"):
        source = _columns_from_frame(file, _read_parquet(file))
    elif suffix == ".tdms":
        source = _columns_from_tdms(file)
    elif suffix == ".mat":
        source = _columns_from_mat(file)
    else:
        raise BmrError(f"{file}: unsupported file type {suffix!r} (read .csv, .parquet, .tdms, .mat)")
    if not source:
        kind = {".tdms": "TDMS channels", ".mat": "MATLAB variables"}.get(suffix, "columns")
        raise BmrError(f"{file}: no numeric {kind} found (empty or not a {suffix[1:]} file)")

    out: dict[str, np.ndarray] = {}
    for col in (*REQUIRED_COLUMNS, *OPTIONAL_COLUMNS):
        name = mapping.get(col, col)
        values = _lookup(source, name)
        if isinstance(values, _NotNumbers):
            raise BmrError(f"{file}: source {name!r} for column {col!r} holds {values.what}")
        if values is None:
            if col in mapping:
                raise BmrError(f"{file}: mapped source {name!r} for column {col!r} not found "
                               f"(available: {', '.join(sorted(source))})")
            continue
        out[col] = convert_units(col, values, units[col]) if col in units else np.asarray(values, dtype=float)
    n = max((len(v) for v in out.values()), default=0)
    for col, value in (defaults or {}).items():
        _quantity(col)
        if col not in out:
            out[col] = np.full(n, float(value))
    if "t_s" not in out and sample_rate_hz is not None:
        if not (sample_rate_hz > 0 and math.isfinite(sample_rate_hz)):
            raise BmrError(f"sample_rate_hz must be positive and finite, got {sample_rate_hz!r}")
        out["t_s"] = np.arange(n) / float(sample_rate_hz)
    missing = [c for c in REQUIRED_COLUMNS if c not in out]
    if missing:
        raise BmrError(f"{file}: no source for required column(s) {', '.join(missing)}; map them with "
                       f"mapping={{'{missing[0]}': '<name>'}} (available: {', '.join(sorted(source))})")
    lengths = {c: len(v) for c, v in out.items()}
    if len(set(lengths.values())) > 1:
        raise BmrError(f"{file}: columns have different lengths: "
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
            raise BmrError(f"files[{k}] needs 'path', 'name' and 'kind'")
        df = read_table(spec["path"], {**(mapping or {}), **spec.get("mapping", {})},
                        {**(units or {}), **spec.get("units", {})},
                        defaults={**(defaults or {}), **spec.get("defaults", {})}, sample_rate_hz=sample_rate_hz)
        runs.append(Run(str(spec["name"]), str(spec["kind"]), df, dict(spec.get("meta", {}))))
    if not runs:
        raise BmrError("bundle_from_files needs at least one file")
    if sample_rate_hz is None:
        sample_rate_hz = nominal_sample_rate(runs[0].t)
    return Bundle(actuator=actuator, sample_rate_hz=float(sample_rate_hz), runs=runs)


def _read_csv(file: Path) -> pd.DataFrame:
    try:
        return pd.read_csv(file, sep=None, engine="python")
    except Exception as exc:  # noqa: BLE001 - any parser failure is a clear file error
        raise BmrError(f"{file}: cannot be read as CSV ({exc})") from None


def _read_parquet(file: Path) -> pd.DataFrame:
    try:
        return pd.read_parquet(file)
    except Exception as exc:  # noqa: BLE001
        raise BmrError(f"{file}: cannot be read as Parquet ({exc})") from None


class _NotNumbers:
    """A source column that holds something other than real numbers: naming it is an error saying what it holds."""

    def __init__(self, what: str) -> None:
        self.what = what


_NOT_NUMBERS = {
    "M": "date-times; convert them to seconds (e.g. (t - t[0]).dt.total_seconds()) before reading",
    "m": "durations; convert them to seconds (e.g. .dt.total_seconds()) before reading",
    "b": "booleans, not measurements",
    "c": "complex numbers; keep the real-valued measurement",
}


def _columns_from_frame(file: Path, df: pd.DataFrame) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for c in df.columns:
        what = _NOT_NUMBERS.get(df[c].dtype.kind)
        if what is not None:
            out[str(c).strip()] = _NotNumbers(what)
            continue
        try:
            out[str(c).strip()] = df[c].to_numpy(dtype=float)
        except (TypeError, ValueError):
            continue  # non-numeric columns (comments, labels) cannot be mapped
    return out


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
            raise BmrError(f"defaults[{k!r}] must be finite, got {v!r}")
    if sample_rate_hz is not None:
        if isinstance(sample_rate_hz, bool) or not isinstance(sample_rate_hz, numbers.Real):
            raise TypeError(f"sample_rate_hz: expected a number of Hz, got {sample_rate_hz!r}")
        if not (math.isfinite(sample_rate_hz) and sample_rate_hz > 0):
            raise BmrError(f"sample_rate_hz must be positive and finite, got {sample_rate_hz!r}")


def _columns_from_tdms(file: Path) -> dict[str, np.ndarray]:
    try:
        from nptdms import TdmsFile
    except ImportError:  # pragma: no cover - npTDMS is a dependency
        raise BmrError("reading .tdms needs the npTDMS package (pip install npTDMS)") from None
    try:
        tdms = TdmsFile.read(file)
    except Exception as exc:  # noqa: BLE001
        raise BmrError(f"{file}: cannot be read as TDMS ({exc})") from None
    out: dict[str, np.ndarray] = {}
    counts: dict[str, int] = {}
    for group in tdms.groups():
        for channel in group.channels():
            data = np.asarray(channel[:])
            if data.dtype.kind not in "iuf":
                continue
            out[f"{group.name}/{channel.name}"] = data.astype(float)
            counts[channel.name] = counts.get(channel.name, 0) + 1
            out.setdefault(channel.name, data.astype(float))
    for name, c in counts.items():
        if c > 1:
            out.pop(name, None)  # ambiguous bare name: require "group/channel"
    return out


def _columns_from_mat(file: Path) -> dict[str, np.ndarray]:
    try:
        from scipy.io import loadmat
    except ImportError:  # pragma: no cover - scipy is a dependency
        raise BmrError("reading .mat needs scipy") from None
    try:
        mat = loadmat(file, squeeze_me=True, struct_as_record=False)
    except NotImplementedError:
        raise BmrError(f"{file}: MATLAB v7.3 (HDF5) files are not supported; save with -v7 or export CSV") from None
    except Exception as exc:  # noqa: BLE001
        raise BmrError(f"{file}: cannot be read as a MATLAB file ({exc})") from None
    out: dict[str, np.ndarray] = {}

    def add(name: str, value: Any) -> None:
        if hasattr(value, "_fieldnames"):
            for f in value._fieldnames:
                add(f"{name}.{f}", getattr(value, f))
            return
        arr = np.asarray(value)
        if arr.dtype.kind in "iuf" and arr.ndim == 1:
            out[name] = arr.astype(float)
        elif arr.dtype.kind in "iuf" and arr.ndim == 2 and 1 in arr.shape:
            out[name] = arr.ravel().astype(float)

    for key, value in mat.items():
        if not key.startswith("__"):
            add(key, value)
    return out


def _lookup(source: Mapping[str, Any], name: str) -> Any:
    if name in source:
        return source[name]
    lowered = {k.lower(): k for k in source}
    key = lowered.get(name.lower())
    return source[key] if key is not None else None
