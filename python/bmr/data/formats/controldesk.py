"""dSPACE ControlDesk captures saved as MATLAB files.

ControlDesk (and its predecessor's TRACE export) saves a capture as one variable, usually named after the file,
holding a struct::

    capture.X         time axis: struct (or struct array, one per raster) with Name, Data (1×N, s), Unit
    capture.Y(k)      channels: Name (e.g. "Model Root/Plant/Out1", ``"Model Root"/"Plant"/"Out1"`` or "Out1"),
                      Path, Data (1×N), Unit, XIndex
    capture.Description, capture.Capture, capture.RTProgram   (kept as metadata when present)

Each raster (time axis) becomes one table. Names are kept as a user types them: the double quotes ControlDesk
puts around every path segment and the control bytes it leaves in a block label that held a line break (0x1A)
are removed. A channel is found by its plain name, its ``Path/Name``, the last part of its name, or its block
name (the part before the port, ``Pdrag`` in ``"Model Root"/"Pdrag"/"In1"``) when that is unique. MATLAB v7.3
(HDF5) files are not read (save as v7).
"""
from __future__ import annotations

import unicodedata
from pathlib import Path
from typing import Any

import numpy as np

from bmr._core import BmrError, BundleError
from bmr.data.tables import Table, load_mat

__all__ = ["read", "looks_like"]


def _is_capture(value: Any) -> bool:
    names = getattr(value, "_fieldnames", None)
    return bool(names) and "X" in names and "Y" in names


def _as_list(value: Any) -> list[Any]:
    if isinstance(value, np.ndarray):
        return list(value.ravel())
    return [value]


def _text(value: Any) -> str:
    if isinstance(value, np.ndarray):
        if value.size == 0:
            return ""
        value = value.ravel()[0] if value.dtype.kind == "O" else "".join(map(str, value.ravel()))
    return str(value).strip().strip('"').strip()


def _plain(text: str) -> str:
    """A signal path as a user types it: ``"Model Root"/"P\x1adrag"/"In1"`` is ``Model Root/Pdrag/In1`` (quotes
    around segments and control bytes dropped, backslashes read as slashes)."""
    text = "".join(c for c in text if unicodedata.category(c) != "Cc")
    segments = [seg.strip().strip('"').strip() for seg in text.replace("\\", "/").split("/")]
    return "/".join(seg for seg in segments if seg)


def _vector(value: Any, where: str) -> np.ndarray:
    arr = np.atleast_1d(np.asarray(value))
    if arr.dtype.kind not in "iufb" or (arr.ndim != 1 and not (arr.ndim == 2 and 1 in arr.shape)):
        raise BundleError(f"{where}: Data is not a numeric vector (shape {arr.shape}, type {arr.dtype})")
    return arr.ravel().astype(float)


def looks_like(path: Path) -> bool:
    """True when the MAT file holds a variable with ``X`` and ``Y`` fields (unreadable files: False)."""
    try:
        mat = load_mat(path)
    except BmrError:
        return False
    return any(_is_capture(v) for k, v in mat.items() if not k.startswith("__"))


def _short_names(name: str) -> set[str]:
    """The last part of a plain signal path and its block name (the part before the port)."""
    parts = name.split("/")
    return {parts[-1]} | ({parts[-2]} if len(parts) > 1 else set())


def read(path: str | Path) -> list[Table]:
    """One table per capture variable and raster."""
    p = Path(path)
    mat = load_mat(p)
    variables = {k: v for k, v in mat.items() if not k.startswith("__")}
    captures = {k: v for k, v in variables.items() if _is_capture(v)}
    if not captures:
        raise BundleError(f"{p}: not a dSPACE ControlDesk capture: no variable is a struct with X (time) and Y "
                          f"(channels) (variables: {', '.join(variables) or 'none'})")
    tables = []
    for var, cap in captures.items():
        axes = _as_list(cap.X)
        channels = _as_list(cap.Y)
        meta = {f: _text(getattr(cap, f)) for f in ("Description", "Capture", "RTProgram")
                if f in cap._fieldnames and isinstance(getattr(cap, f), (str, np.ndarray))}
        groups: dict[int, list[tuple[str, str, np.ndarray, str]]] = {}
        for k, ch in enumerate(channels):
            where = f"{p}: {var}.Y({k + 1})"
            fields = getattr(ch, "_fieldnames", None) or []
            if "Data" not in fields or "Name" not in fields:
                raise BundleError(f"{where} has no Name/Data (fields: {', '.join(fields) or 'none'})")
            xi = int(np.asarray(getattr(ch, "XIndex", 1)).ravel()[0]) if "XIndex" in fields else 1
            if not 1 <= xi <= len(axes):
                raise BundleError(f"{where}: XIndex {xi} names no time axis (the capture has {len(axes)})")
            path_text = _plain(_text(getattr(ch, "Path", ""))) if "Path" in fields else ""
            unit = _text(getattr(ch, "Unit", "")) if "Unit" in fields else ""
            name = _plain(_text(ch.Name))
            if not name:
                raise BundleError(f"{where} has an empty Name")
            groups.setdefault(xi, []).append((name, path_text, _vector(ch.Data, where), unit))
        for xi, chans in sorted(groups.items()):
            axis = axes[xi - 1]
            where = f"{p}: {var}.X({xi})"
            if "Data" not in (getattr(axis, "_fieldnames", None) or []):
                raise BundleError(f"{where} has no Data (the capture's time axis)")
            t = _vector(axis.Data, where)
            columns: dict[str, np.ndarray] = {}
            units: dict[str, str] = {}
            aliases: dict[str, list[str]] = {}
            time_name = "time"
            columns[time_name] = t
            x_unit = _text(getattr(axis, "Unit", "")) if "Unit" in axis._fieldnames else ""
            units[time_name] = x_unit or "s"
            x_name = _text(getattr(axis, "Name", "")) if "Name" in axis._fieldnames else ""
            if x_name:
                aliases.setdefault(x_name.lower(), []).append(time_name)
            counts: dict[str, int] = {}
            for name, *_ in chans:
                counts[name.lower()] = counts.get(name.lower(), 0) + 1
            for name, path_text, data, unit in chans:
                # A name that several channels share is keyed by its path (the bare name then is ambiguous).
                key = f"{path_text}/{name}" if counts[name.lower()] > 1 or name == time_name else name
                if data.size != t.size:
                    raise BundleError(f"{p}: {var}: channel {name!r} has {data.size} samples but its time axis "
                                      f"X({xi}) has {t.size} (truncated capture?)")
                columns[key] = data
                if unit:
                    units[key] = unit
                for alias in _short_names(name) | {f"{path_text}/{name}" if path_text else name}:
                    if alias and alias.lower() != key.lower():
                        aliases.setdefault(alias.lower(), []).append(key)
            name = var if len(groups) == 1 else f"{var}-x{xi}"
            source = f"{p} ({var})" if len(groups) == 1 else f"{p} ({var}, raster X({xi}))"
            tables.append(Table(name, columns, source, units, time_column=time_name, meta=meta, aliases=aliases))
    return tables
