"""Diagnosis of real data: the SLAC LCLS-II quadrupole 4194 (current → integrated gradient), runs 3-6 for
identification, runs 7 and 8 held out (their samples cut into blocked folds).

    python examples/slac_diagnosis.py [--data DIR] [--json OUT] [--figure OUT.png]

Prints what the diagnosis names (or learns), the held-out RMS before and after in T and in measurement sigmas
(the RMS of the sigmas the measurement system reports), the residual structure no effect explains, and writes a
figure of the held-out runs: measured vs predicted integrated gradient and the residual in sigmas. The data are
not part of the repository (see the data folder's README); DIR defaults to ``$BMR_SLAC_DATA``, else
../shared/data/slac-quad-4194 beside the repository.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

DEFAULT_DATA = Path(os.environ.get("BMR_SLAC_DATA")
                    or Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "slac-quad-4194")


def run(data_dir: Path, folds: int = 5) -> tuple[dict, object]:
    from bmr.data.importing import import_logs
    from bmr.diagnosis.procedure import diagnose

    res = import_logs([data_dir / f"strplt.ru{k}" for k in range(3, 9)], input="MAIN:A", output="BL:T",
                      output_sigma="sigBL", output_name="integrated gradient", holdout=["run7", "run8"])
    d = diagnose(res.bundle, folds=folds, progress=False, closed_loop=False)
    sigma = d.noise_floor
    out = {"named": [e["name"] for e in d.effects], "cause": d.cause,
           "learned": d.learned["equation"] if d.learned and d.learned["accepted"] else None,
           "learned_tried": d.learned["equation"] if d.learned else None,
           "heldout_rms_before_t": d.nominal_heldout_rms, "heldout_rms_after_t": d.residual_rms,
           "sigma_t": sigma, "noise_method": d.noise["method"],
           "heldout_rms_before_sigmas": d.nominal_heldout_rms / sigma,
           "heldout_rms_after_sigmas": d.residual_rms / sigma,
           "unexplained": d.unexplained,
           "rejected": {r["name"]: {"gain": r["gain"], "folds_positive": r["folds_positive"],
                                    "heldout_rms_after_t": r["heldout_rms_after_nmm"]} for r in d.rejected},
           "folds": folds, "noise_samples": d.noise.get("samples"), "wall_time_s": d.wall_time_s}
    return out, d


def figure(d: object, path: Path) -> None:
    from bmr import plot

    runs = d.signals["runs"]  # type: ignore[attr-defined]
    sigma = d.noise_floor  # type: ignore[attr-defined]
    with plot.style():
        fig, axes = plot.figure("wide", nrows=2, height=5.2)
        for name, t, rn, re in runs:
            t = t - t[0]
            axes[0].plot(t, rn / sigma, "o-", ms=3, lw=0.8, label=f"{name}, nominal")
            axes[0].plot(t, re / sigma, "s--", ms=3, lw=0.8, label=f"{name}, extended")
        axes[0].axhspan(-1, 1, color="0.85", zorder=0, label="±1 measurement sigma")
        axes[0].set_ylabel("residual (sigmas)")
        axes[0].set_xlabel("time in the run (s)")
        plot.legend_outside(axes[0])
        names = [k for k in d.structure_nominal]  # type: ignore[attr-defined]
        axes[1].bar(np.arange(len(names)) - 0.2, [d.structure_nominal[k] / sigma for k in names], 0.4,
                    label="nominal")  # type: ignore[attr-defined]
        axes[1].bar(np.arange(len(names)) + 0.2, [d.structure_extended[k] / sigma for k in names], 0.4,
                    label="extended")  # type: ignore[attr-defined]
        axes[1].set_xticks(np.arange(len(names)))
        axes[1].set_xticklabels([n.replace("_", " ") for n in names], rotation=15)
        axes[1].set_ylabel("structure (sigmas RMS)")
        axes[1].legend()
        fig.suptitle("SLAC quadrupole 4194, held-out runs 7 and 8: residual and the signals it depends on")
        plot.save(fig, path)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", type=Path, default=DEFAULT_DATA)
    p.add_argument("--json", type=Path)
    p.add_argument("--figure", type=Path)
    p.add_argument("--folds", type=int, default=5)
    args = p.parse_args(argv)
    if not (args.data / "strplt.ru3").is_file():
        print(f"slac_diagnosis: SLAC data not found in {args.data}", file=sys.stderr)
        return 2
    out, d = run(args.data, args.folds)
    print(f"SLAC quadrupole 4194, held-out runs 7-8: named {out['named'] or 'nothing'}; learned "
          f"{out['learned'] or 'nothing'} (tried: {out['learned_tried']})")
    print(f"  held-out RMS {out['heldout_rms_before_t']:.3g} T ({out['heldout_rms_before_sigmas']:.1f} sigma) -> "
          f"{out['heldout_rms_after_t']:.3g} T ({out['heldout_rms_after_sigmas']:.1f} sigma); sigma "
          f"{out['sigma_t']:.2g} T ({out['noise_method']})")
    for u in out["unexplained"]:
        print(f"  unexplained against {u['signal']}: {u['strength']:.3g} T ({u['strength'] / out['sigma_t']:.1f} "
              "sigma)")
    if args.json:
        args.json.write_text(json.dumps(out, indent=1, default=float) + "\n")
    if args.figure:
        figure(d, args.figure)
    return 0


if __name__ == "__main__":
    sys.exit(main())
