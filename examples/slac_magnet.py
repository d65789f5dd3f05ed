"""Real measured hysteresis from the command line: SLAC LCLS-II quadrupole 4194 (coil current -> integrated
gradient), raw magnetic-measurement tables -> bundle -> model -> held-out prediction.

The walk-through is three commands (what this script runs, through ``bmr.cli.main``)::

    D=../shared/data/slac-quad-4194
    bmr import $D/strplt.ru3 $D/strplt.ru4 $D/strplt.ru5 $D/strplt.ru6 $D/strplt.ru7 $D/strplt.ru8 \\
        --input MAIN:A --output BL:T --output-name "integrated gradient" --output-sigma sigBL \\
        --holdout run7,run8 --device "LCLS-II quadrupole 4194" -o slac-bundle
    bmr identify slac-bundle -o slac-model.json
    bmr predict slac-model.json slac-bundle --json slac-prediction.json --figure slac-prediction.png

Runs 3-6 (major loop, minor loops) identify the model (``auto`` chooses least squares: there are no first-order
curves); runs 7 and 8 (nested reversals 0.9/0.1/0.8/... and 0.5/0.4/0.6/... of the maximum current) are held
out. Every run starts at 0 A, the bottom of the input range, from a remanent field the previous run left: the
least-squares fit gives each training run its own offset and estimates its initial state; a held-out run is
predicted with the model's common offset (``--offset first`` or ``shrunk`` take it from the run's first sample,
which is then not scored). Every setting is bmr's default: nothing was tuned on the held-out runs. Errors are in T
and in measurement sigmas (the RMS of the files' per-sample BL sigma over the same samples), next to the
single-valued baseline (the middle of the model's major loop) and to 1.37e-3 T, the held-out RMS of the earlier
hand-written Preisach fit of these runs (40 intervals, one free offset per training run, each held-out run's
offset from its first sample).

A data check rides along: runs 4 and 6 reach the same 40 % / 60 % extremes in opposite order, so a Preisach
(congruent) device gives identical branch increments from those reversals; their RMS mismatch is reported.

Usage: python examples/slac_magnet.py [--data DIR] [--out DIR] [--json OUT]
The data are not part of the repository (see the data folder's README); DIR defaults to ../shared/data/... .
"""
from __future__ import annotations

import argparse
import json
import shlex
import sys
import tempfile
from pathlib import Path

import numpy as np

import bmr
from bmr.cli import main as bmr_main
from bmr.data.units import format_value

DEFAULT_DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "slac-quad-4194"
RUNS = (3, 4, 5, 6, 7, 8)
HELDOUT = ("run7", "run8")
EARLIER_HELDOUT_RMS_T = 1.37e-3


def tesla(x: float, digits: int = 3) -> str:
    return format_value(x, "T", digits)


def commands(data: Path, out: Path) -> list[list[str]]:
    """The three ``bmr`` command lines of the walk-through."""
    bundle, model = str(out / "slac-bundle"), str(out / "slac-model.json")
    return [
        ["import", *[str(data / f"strplt.ru{k}") for k in RUNS], "--input", "MAIN:A", "--output", "BL:T",
         "--output-name", "integrated gradient", "--output-sigma", "sigBL", "--holdout", ",".join(HELDOUT),
         "--device", "LCLS-II quadrupole 4194", "-o", bundle],
        ["identify", bundle, "-o", model],
        ["predict", model, bundle, "--json", str(out / "slac-prediction.json"),
         "--figure", str(out / "slac-prediction.png")],
    ]


def congruency_mismatch(bundle: bmr.Bundle) -> dict[str, float]:
    """RMS difference of the branch increments from the same reversal points in runs 4 and 6 (run 4: up to 60 %,
    down to 40 %, up to 50 %; run 6: down to 40 %, up to 60 %, down to 50 %), and that in measurement sigmas."""
    r4, r6 = bundle.run("run4"), bundle.run("run6")

    def extremes(u: np.ndarray) -> tuple[int, int]:
        return 1 + int(np.argmin(u[1:])), int(np.argmax(u))  # skip the 0 A start

    u4, y4, u6, y6 = r4.input, r4.output, r6.input, r6.output
    lo4, hi4 = extremes(u4)
    lo6, hi6 = extremes(u6)
    if not (hi4 < lo4 and lo6 < hi6):
        raise bmr.BmrError("runs 4 and 6 do not reach their 60 %/40 % extremes in the documented orders")

    def branch(u: np.ndarray, y: np.ndarray, a: int, b: int) -> tuple[np.ndarray, np.ndarray]:
        return u[a:b + 1], y[a:b + 1] - y[a]

    # Rising from the 40 % minimum: run 4 to its end, run 6 up to its 60 % maximum.
    ia, da = branch(u4, y4, lo4, u4.size - 1)
    ib, db = branch(u6, y6, lo6, hi6)
    keep = ia <= min(ia.max(), ib.max())
    rising = da[keep] - np.interp(ia[keep], ib, db)
    # Falling from the 60 % maximum: run 4 down to its 40 % minimum, run 6 to its end.
    ia, da = branch(u4, y4, hi4, lo4)
    ib, db = branch(u6, y6, hi6, u6.size - 1)
    keep = ib >= max(ia.min(), ib.min())
    falling = db[keep] - np.interp(ib[keep], ia[::-1], da[::-1])
    d = np.concatenate([rising, falling])
    sigma = np.concatenate([r4.output_sigma, r6.output_sigma])
    rms = float(np.sqrt(np.mean(d ** 2)))
    return {"rms_t": rms, "max_abs_t": float(np.max(np.abs(d))),
            "rms_sigmas": rms / float(np.sqrt(np.mean(sigma ** 2)))}


def run(data: Path, out: Path) -> dict:
    """Run the three commands into ``out``; the prediction's figures plus the congruency check."""
    for argv in commands(data, out):
        print("$ bmr " + " ".join(shlex.quote(a) for a in argv))
        if bmr_main(argv) != 0:
            raise bmr.BmrError(f"bmr {argv[0]} failed")
    pred = json.loads((out / "slac-prediction.json").read_text())
    total = pred["total"]
    return {"data": str(data), "heldout_runs": list(HELDOUT), "prediction": pred,
            "rms_t": total["rms"], "max_t": total["max_abs"], "rms_sigmas": total["rms_sigmas"],
            "max_sigmas": total["max_abs_sigmas"], "baseline_rms_t": total["baseline_rms"],
            "baseline_rms_sigmas": total["baseline_rms_sigmas"], "sigma_t": total["sigma_rms"],
            "earlier_heldout_rms_t": EARLIER_HELDOUT_RMS_T,
            "congruency": congruency_mismatch(bmr.read_bundle(out / "slac-bundle"))}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", type=Path, default=DEFAULT_DATA, help="folder with strplt.ru3..ru8 (and strdat.ru*)")
    p.add_argument("--out", type=Path, help="folder for the bundle, model, JSON and figure (default: temporary)")
    p.add_argument("--json", type=Path, help="write the figures as JSON here")
    args = p.parse_args(argv)
    if not (args.data / "strplt.ru3").is_file():
        print(f"slac_magnet: data folder {args.data} not found (see the README of slac-quad-4194)", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        out = args.out or Path(tmp)
        out.mkdir(parents=True, exist_ok=True)
        res = run(args.data, out)
    c = res["congruency"]
    print(f"SLAC quadrupole 4194, held-out runs 7 and 8: RMS {tesla(res['rms_t'])} = {res['rms_sigmas']:.1f} sigma, "
          f"max {tesla(res['max_t'])} = {res['max_sigmas']:.1f} sigma (sigma {tesla(res['sigma_t'], 2)})")
    print(f"  single-valued baseline: RMS {tesla(res['baseline_rms_t'])} = {res['baseline_rms_sigmas']:.1f} sigma; "
          f"earlier hand-written fit: {tesla(EARLIER_HELDOUT_RMS_T)}")
    print(f"  congruency runs 4 vs 6: RMS mismatch {tesla(c['rms_t'])} ({c['rms_sigmas']:.1f} sigma), "
          f"max {tesla(c['max_abs_t'])}")
    if args.json:
        args.json.write_text(json.dumps(res, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
