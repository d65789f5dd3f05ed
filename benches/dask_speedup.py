"""Many bundles on Dask against the serial loop: wall and CPU time of ``bmr.diagnose_many`` on the same bundles
with ``workers=0`` (one process, one bundle after the other) and with a local cluster of 2 worker processes.

Usage: ``python benches/dask_speedup.py [--bundles N] [--record]`` (``--record`` stores the figures in
``docs/measurements.json``, section ``dask_speedup``). The bundles are small quick diagnosis bundles (250 Hz),
made on the workers; CPU time counts this process and its children.
"""
from __future__ import annotations

import argparse
import functools
import resource
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from measurements import record  # noqa: E402

from bmr.diagnosis.many import diagnose_many  # noqa: E402
from bmr.simulation.excitation import diagnosis_bundle  # noqa: E402


def _cpu() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--bundles", type=int, default=6)
    ap.add_argument("--record", action="store_true")
    args = ap.parse_args()
    bundles = {f"lag{k}": functools.partial(diagnosis_bundle, "rig_preisach", effects={"coil_lag": {"tau_s": 0.02}},
                                            seed=k, sample_rate_hz=250.0) for k in range(args.bundles)}
    out = {}
    for label, workers in (("serial", 0), ("dask_2_workers", 2)):
        c0, t0 = _cpu(), time.perf_counter()
        table = diagnose_many(bundles, workers=workers, folds=3, progress=False)
        out[label] = {"wall_s": time.perf_counter() - t0, "cpu_s": _cpu() - c0,
                      "ok": int((table["status"] == "ok").sum())}
    out["bundles"] = args.bundles
    out["speedup"] = out["serial"]["wall_s"] / out["dask_2_workers"]["wall_s"]
    print(f"{args.bundles} bundles: serial {out['serial']['wall_s']:.1f} s wall; Dask, 2 workers "
          f"{out['dask_2_workers']['wall_s']:.1f} s wall: {out['speedup']:.2f}x")
    if args.record:
        record("dask_speedup", "python benches/dask_speedup.py --record", out)


if __name__ == "__main__":
    main()
