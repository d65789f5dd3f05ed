"""The file formats ``bmr import`` reads, and the registry that picks one for a file.

| format | files | reader |
|---|---|---|
| ``csv`` | ``.csv`` (any delimiter), headers ``Name``, ``Name [unit]`` or ``Name (unit)`` | :func:`bmr.data.tables.read_csv` |
| ``parquet`` | ``.parquet``, ``.pq`` | :func:`bmr.data.tables.read_parquet` |
| ``tdms`` | NI TDMS (``group/channel``; ``unit_string`` property) | :func:`bmr.data.tables.read_tdms` |
| ``mat`` | MATLAB v5/v7 variables, ``struct.field`` and matrix columns | :func:`bmr.data.tables.read_mat` |
| ``spreadsheet`` | ``.xlsx``, ``.xlsm``, ``.ods`` (``.xls`` with ``xlrd``): one table per sheet | :func:`bmr.data.tables.read_spreadsheet` |
| ``controldesk`` | dSPACE ControlDesk captures (``.mat``) | :mod:`~bmr.data.formats.controldesk` |
| ``aixacct`` | tab-separated analyzer exports (``.dat``, ``.txt``, ``.tsv``) | :mod:`~bmr.data.formats.aixacct` |
| ``slac`` | SLAC magnetic-measurement tables (``strdat.ruN``, ``strplt.ruN``) | :mod:`~bmr.data.formats.slac` |
| ``micromag`` | Princeton Measurements MicroMag VSM/AGM text (FORC, hysteresis) | :mod:`~bmr.data.formats.micromag` |
| ``lakeshore`` | Lake Shore VSM CSV exports (``##DATA TABLE``) | :mod:`~bmr.data.formats.lakeshore` |
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable

from bmr._core import BundleError
from bmr.data.formats import aixacct, controldesk, lakeshore, micromag, slac
from bmr.data.tables import SPREADSHEET_ENGINES, Table, read_csv, read_mat, read_parquet, read_spreadsheet, read_tdms

__all__ = ["FORMATS", "READERS", "detect_format", "read_tables"]

READERS: dict[str, Callable[[Path], list[Table]]] = {
    "csv": read_csv, "parquet": read_parquet, "tdms": read_tdms, "mat": read_mat, "spreadsheet": read_spreadsheet,
    "controldesk": controldesk.read, "aixacct": aixacct.read, "slac": slac.read,
    "micromag": micromag.read, "lakeshore": lakeshore.read,
}
FORMATS = tuple(READERS)


def detect_format(path: Path) -> str:
    """The reader for ``path`` from its extension and, for ``.mat`` and text files, its content."""
    suffix = path.suffix.lower()
    if suffix in (".parquet", ".pq"):
        return "parquet"
    if suffix == ".tdms":
        return "tdms"
    if suffix in SPREADSHEET_ENGINES:
        return "spreadsheet"
    if suffix == ".mat":
        return "controldesk" if controldesk.looks_like(path) else "mat"
    if micromag.looks_like(path):
        return "micromag"
    if lakeshore.looks_like(path):
        return "lakeshore"
    if slac.looks_like(path):
        return "slac"
    if suffix == ".csv":
        return "csv"
    return "aixacct" if aixacct.looks_like(path) else "csv"


def read_tables(path: str | Path, format: str | None = None) -> list[Table]:
    """Every measurement table in ``path``, read with the reader named by ``format`` (one of ``FORMATS``) or the
    one its extension and content call for."""
    p = Path(path)
    if not p.is_file():
        raise BundleError(f"{str(p)!r} does not exist" if not p.exists() else f"{str(p)!r} is not a file")
    if format is None:
        format = detect_format(p)
    if format not in READERS:
        raise BundleError(f"unknown file format {format!r}; use one of {', '.join(FORMATS)}")
    return READERS[format](p)
