"""Least-squares Preisach tables: the output of a Preisach model is linear in its Everett table given the input
history, so the table is identified by nonnegative, smoothness-regularised least squares from any excitation
(``bmr._core.fit_everett``)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Iterable

import numpy as np

from bmr import _core
from bmr._core import BmrError
from bmr.data.bundle import Run
from bmr.identification.forc import Curve
from bmr.identification.spans import SATURATION_TOL, evaluation_start, input_range_of

__all__ = ["LstsqTables", "fit_tables_lstsq"]


@dataclass
class LstsqTables:
    """Result of the least-squares table identification: the Everett model, its first-order curves and fit
    statistics (``rms`` in output units over the regression rows)."""

    everett: Any
    offsets: np.ndarray
    rms: float
    n_rows: int
    iterations: int
    ascending: list[Curve]
    descending: list[Curve]
    input_range: tuple[float, float]


def fit_tables_lstsq(
    runs: Iterable[Run],
    friction: Any = None,
    *,
    n_intervals: int = 48,
    input_range: tuple[float, float] | None = None,
    smoothing: float = 1e-4,
    ridge: float = 1e-9,
    per_run_offset: bool = False,
    max_rows: int = 200_000,
    start_at_saturation: bool = True,
    curve_subdivisions: int = 4,
) -> LstsqTables:
    """Identify an Everett table (Preisach model) from any runs by regularised nonnegative least squares.

    The memory of each run starts at negative saturation; rows before the run's first saturation are left out
    (``start_at_saturation``). Rows are thinned uniformly to at most ``max_rows``. ``per_run_offset`` fits one
    free output offset per run (sensor offsets, unknown remanence) instead of one shared offset. The returned
    first-order curves start at every grid node and at ``curve_subdivisions − 1`` points inside each interval, so a
    CBH operator built from them follows the table between grid reversals too.
    """
    runs = list(runs)
    if not runs:
        raise BmrError("fit_tables_lstsq needs at least one run")
    if n_intervals < 2:
        raise BmrError(f"n_intervals must be at least 2, got {n_intervals}")
    us = [r.current for r in runs]
    ys = [r.torque - (friction(r.theta) if friction is not None else 0.0) for r in runs]
    lo, hi = input_range if input_range is not None else input_range_of([r.current for r in runs])
    if not hi > lo:
        raise BmrError("the current never varies in the training runs; nothing to identify")
    grid = np.linspace(lo, hi, n_intervals + 1)
    tol = SATURATION_TOL * (hi - lo)
    total = sum(u.size for u in us)
    stride = max(1, math.ceil(total / max_rows))
    packed = []
    for k, (r, u, y) in enumerate(zip(runs, us, ys)):
        w = np.zeros(u.size)
        s = evaluation_start(u, lo, hi, tol) if start_at_saturation else 0
        w[s::stride] = 1.0
        packed.append((np.ascontiguousarray(u), np.ascontiguousarray(y), w, k if per_run_offset else 0))
    res = _core.fit_everett(grid, packed, len(runs) if per_run_offset else 1, smoothing=smoothing, ridge=ridge)
    model = res["model"]
    asc, desc = model.first_order_curves(subdivisions=curve_subdivisions)
    return LstsqTables(everett=model, offsets=np.asarray(res["offsets"]), rms=float(res["rms"]),
                       n_rows=int(res["n_rows"]), iterations=int(res["iterations"]),
                       ascending=[(np.asarray(u), np.asarray(y)) for u, y in asc],
                       descending=[(np.asarray(u), np.asarray(y)) for u, y in desc], input_range=(lo, hi))
