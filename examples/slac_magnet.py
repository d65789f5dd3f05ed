"""Hysteresis identification on real measured data: SLAC LCLS-II quadrupole 4194 (current -> integrated gradient).

Identifies a Preisach (Everett-table) model by regularised nonnegative least squares (``bmr.fit_everett``, the
``lstsq`` path) from runs 3-6, with one free output offset per run (each run starts from an unknown remanent
state), then predicts the held-out runs 7 and 8 (nested reversals 0.9/0.1/0.8/... and 0.5/0.4/0.6/...). A held-out
run's own offset is estimated from its first sample only (at 0 A, before any reversal). A single-valued
(non-hysteretic) polynomial fit of BL(I) on the same training runs, with the same offset handling, is the
baseline. The congruency check compares runs 4 and 6, which reach the same 40 %/60 % extremes in opposite order:
a Preisach model predicts identical branch increments from the same reversal points.

Initial state: the table spans 0 A to the largest current, so every run starts at the bottom of the input range,
where a Preisach model's memory is empty whatever came before; what differs from run to run (remanence left by
earlier excitation beyond this range, drift) is a constant output offset, fitted per training run and taken from
the first sample of a held-out run. ``rms_over_sigma`` divides the held-out RMS error by the RMS of the reported
measurement sigmas of the same samples.

Usage: python examples/slac_magnet.py [--data DIR] [--json OUT] [--intervals N] [--smoothing S]
The data are not part of the repository (see the data folder's README); DIR defaults to ../shared/data/... .
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

import bmr

DEFAULT_DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "slac-quad-4194"
TRAIN_RUNS = (3, 4, 5, 6)
HELDOUT_RUNS = (7, 8)


def read_run(data_dir: Path, run: int) -> dict[str, np.ndarray]:
    """Samples of ``strdat.ru<run>``: current (A), its sigma, BL (T), its sigma, from the table after the dashes."""
    path = data_dir / f"strdat.ru{run}"
    if not path.is_file():
        raise bmr.BmrError(f"{path} does not exist")
    rows, in_table = [], False
    for line in path.read_text().splitlines():
        if line.strip().startswith("---"):
            in_table = True
            continue
        if in_table:
            parts = line.split()
            if len(parts) >= 8:
                try:
                    rows.append([float(p) for p in parts[:4]])
                except ValueError:
                    continue
    if len(rows) < 2:
        raise bmr.BmrError(f"{path}: no sample table found after the dashed line")
    a = np.asarray(rows)
    return {"current_a": a[:, 0], "sigma_current_a": a[:, 1], "bl_t": a[:, 2], "sigma_bl_t": a[:, 3]}


def fit_preisach(train: dict[int, dict[str, np.ndarray]], n_intervals: int, smoothing: float, hi_a: float):
    grid = np.linspace(0.0, hi_a, n_intervals + 1)
    runs = [(r["current_a"], r["bl_t"], np.ones(r["current_a"].size), k) for k, r in enumerate(train.values())]
    return bmr.fit_everett(grid, runs, len(runs), smoothing=smoothing)


def predict_preisach(model, run: dict[str, np.ndarray]) -> np.ndarray:
    """Prediction with the run's offset taken from its first sample (the only use of held-out outputs)."""
    y = model.simulate(run["current_a"], offset=0.0)
    return y + (run["bl_t"][0] - y[0])


def predict_cbh(hysteresis, run: dict[str, np.ndarray]) -> np.ndarray:
    """The same prediction through the CBH operator built from the identified table's first-order curves."""
    hysteresis.reset("negative")
    y = hysteresis.run(run["current_a"])
    return y + (run["bl_t"][0] - y[0])


def fit_baseline(train: dict[int, dict[str, np.ndarray]], hi_a: float, degree: int = 7) -> np.ndarray:
    """Single-valued BL(I) polynomial (in I/hi) with one offset per training run; returns the polynomial."""
    cols, y = [], []
    n_runs = len(train)
    for k, r in enumerate(train.values()):
        x = r["current_a"] / hi_a
        dummies = np.zeros((x.size, n_runs))
        dummies[:, k] = 1.0
        cols.append(np.hstack([np.vander(x, degree + 1, increasing=True)[:, 1:], dummies]))
        y.append(r["bl_t"])
    coef, *_ = np.linalg.lstsq(np.vstack(cols), np.concatenate(y), rcond=None)
    return coef[:degree]


def predict_baseline(poly: np.ndarray, run: dict[str, np.ndarray], hi_a: float) -> np.ndarray:
    x = run["current_a"] / hi_a
    y = np.vander(x, poly.size + 1, increasing=True)[:, 1:] @ poly
    return y + (run["bl_t"][0] - y[0])


def _branch(run: dict[str, np.ndarray], start: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
    """Increment of BL from sample ``start`` along samples start..stop (inclusive)."""
    i = run["current_a"][start:stop + 1]
    b = run["bl_t"][start:stop + 1]
    return i, b - b[0]


def congruency_mismatch(r4: dict[str, np.ndarray], r6: dict[str, np.ndarray]) -> dict[str, float]:
    """RMS difference of branch increments measured from the same reversal points in runs 4 and 6.

    Run 4: up to 60 %, down to 40 %, up to 50 %. Run 6: down to 40 %, up to 60 %, down to 50 %. In a Preisach
    model the rise from the 40 % minimum and the fall from the 60 % maximum depend only on those reversals, so the
    increments must agree where both runs cover them.
    """
    def extremes(r: dict[str, np.ndarray]) -> tuple[int, int]:
        i = r["current_a"]
        return 1 + int(np.argmin(i[1:])), int(np.argmax(i))  # skip the 0 A start

    lo4, hi4 = extremes(r4)
    lo6, hi6 = extremes(r6)
    if not (hi4 < lo4 and lo6 < hi6):
        raise bmr.BmrError("runs 4 and 6 do not reach their 60 %/40 % extremes in the documented orders")
    n4, n6 = r4["current_a"].size - 1, r6["current_a"].size - 1
    diffs = []
    # Ascending from the 40 % minimum: run 4 to its end, run 6 up to its 60 % maximum.
    i4, d4 = _branch(r4, lo4, n4)
    i6, d6 = _branch(r6, lo6, hi6)
    top = min(i4.max(), i6.max())
    keep = i4 <= top
    asc = d4[keep] - np.interp(i4[keep], i6, d6)
    diffs.append(asc)
    # Descending from the 60 % maximum: run 4 down to its 40 % minimum, run 6 to its end.
    i4, d4 = _branch(r4, hi4, lo4)
    i6, d6 = _branch(r6, hi6, n6)
    bottom = max(i4.min(), i6.min())
    keep = i6 >= bottom
    desc = d6[keep] - np.interp(i6[keep], i4[::-1], d4[::-1])
    diffs.append(desc)
    all_d = np.concatenate(diffs)
    return {"rms_t": float(np.sqrt(np.mean(all_d ** 2))), "max_abs_t": float(np.max(np.abs(all_d))),
            "ascending_rms_t": float(np.sqrt(np.mean(asc ** 2))),
            "descending_rms_t": float(np.sqrt(np.mean(desc ** 2)))}


def run(data_dir: Path, n_intervals: int = 40, smoothing: float = 1e-3) -> dict:
    data = {k: read_run(data_dir, k) for k in (*TRAIN_RUNS, *HELDOUT_RUNS)}
    train = {k: data[k] for k in TRAIN_RUNS}
    hi_a = max(float(r["current_a"].max()) for r in data.values())
    t0 = time.perf_counter()
    fit = fit_preisach(train, n_intervals, smoothing, hi_a)
    fit_s = time.perf_counter() - t0
    model = fit["model"]
    poly = fit_baseline(train, hi_a)
    cbh = bmr.Hysteresis.from_curves(*model.first_order_curves(subdivisions=4))
    out: dict = {"data": str(data_dir), "train_runs": list(TRAIN_RUNS), "heldout_runs": list(HELDOUT_RUNS),
                 "n_intervals": n_intervals, "smoothing": smoothing, "fit_time_s": fit_s,
                 "train_rms_t": fit["rms"], "per_run": {}}
    err_m, err_b, err_c, sig = [], [], [], []
    for k in HELDOUT_RUNS:
        r = data[k]
        em = (r["bl_t"] - predict_preisach(model, r))[1:]
        eb = (r["bl_t"] - predict_baseline(poly, r, hi_a))[1:]
        err_c.append((r["bl_t"] - predict_cbh(cbh, r))[1:])
        s = r["sigma_bl_t"][1:]
        err_m.append(em)
        err_b.append(eb)
        sig.append(s)
        out["per_run"][str(k)] = {"rms_t": float(np.sqrt(np.mean(em ** 2))),
                                  "baseline_rms_t": float(np.sqrt(np.mean(eb ** 2))),
                                  "sigma_t": float(np.sqrt(np.mean(s ** 2)))}
    em, eb, s = np.concatenate(err_m), np.concatenate(err_b), np.concatenate(sig)
    sigma = float(np.sqrt(np.mean(s ** 2)))
    out["sigma_t"] = sigma
    out["rms_t"] = float(np.sqrt(np.mean(em ** 2)))
    out["baseline_rms_t"] = float(np.sqrt(np.mean(eb ** 2)))
    out["cbh_rms_t"] = float(np.sqrt(np.mean(np.concatenate(err_c) ** 2)))
    out["rms_over_sigma"] = out["rms_t"] / sigma
    out["baseline_rms_over_sigma"] = out["baseline_rms_t"] / sigma
    cong = congruency_mismatch(data[4], data[6])
    out["congruency_mismatch_t"] = cong["rms_t"]
    out["congruency"] = cong
    sigma46 = float(np.sqrt(np.mean(np.concatenate([data[4]["sigma_bl_t"], data[6]["sigma_bl_t"]]) ** 2)))
    out["congruency_mismatch_over_sigma"] = cong["rms_t"] / sigma46
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", type=Path, default=DEFAULT_DATA, help="folder with strdat.ru3..ru8")
    p.add_argument("--json", type=Path, help="write the figures as JSON here")
    p.add_argument("--intervals", type=int, default=40, help="Everett grid intervals over 0..max current")
    p.add_argument("--smoothing", type=float, default=1e-3, help="density smoothness weight")
    args = p.parse_args(argv)
    if not args.data.is_dir():
        print(f"slac_magnet: data folder {args.data} not found (see the README of slac-quad-4194)", file=sys.stderr)
        return 2
    res = run(args.data, args.intervals, args.smoothing)
    print(f"SLAC quadrupole 4194: Preisach (lstsq) from runs {res['train_runs']}, "
          f"{res['n_intervals']} intervals, fit {res['fit_time_s'] * 1e3:.0f} ms, train RMS {res['train_rms_t']:.2e} T")
    for k, v in res["per_run"].items():
        print(f"  run {k}: RMS {v['rms_t']:.2e} T vs single-valued {v['baseline_rms_t']:.2e} T "
              f"(sigma {v['sigma_t']:.1e} T)")
    print(f"  held-out RMS {res['rms_t']:.2e} T = {res['rms_over_sigma']:.1f} sigma; "
          f"single-valued baseline {res['baseline_rms_t']:.2e} T = {res['baseline_rms_over_sigma']:.1f} sigma")
    print(f"  the same table as a CBH operator (bmr.Hysteresis from its first-order curves): {res['cbh_rms_t']:.2e} T")
    print(f"  congruency runs 4 vs 6: RMS mismatch {res['congruency_mismatch_t']:.2e} T "
          f"({res['congruency_mismatch_over_sigma']:.1f} sigma), max {res['congruency']['max_abs_t']:.2e} T")
    if args.json:
        args.json.write_text(json.dumps(res, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
