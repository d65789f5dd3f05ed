"""Diagnosis cost: CPU time, wall time and peak memory of ``bmr diagnose`` (each in a fresh process, as a user
runs it), next to ``bmr identify`` on the same bundle, for a quick diagnosis bundle, the diagnosis protocol of the
independently written plant at 1500 Hz (327 k samples; ``tests/python/independent_plant.py`` with its coil circuit
and seal lobes) and the full ``bmr2013`` experiment set. CPU time is the stable figure on a shared machine; wall
time is reported next to it.

Each bundle is also diagnosed once in this process to count the least-squares re-identifications of the core
tables and the input histories whose regressions were prepared (the figures the search's cost follows, free of the
machine's load).

Usage: ``python benches/diagnosis_speed.py [--full] [--record]`` (``--record`` stores the figures for the README,
``docs/measurements.json``, section ``diagnosis_speed``).
"""
from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))


def _run(cmd: list[str]) -> dict[str, float]:
    """CPU (user + system of the child), wall time and peak resident memory of one command."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(["/usr/bin/time", "-f", "%M", *cmd], capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{proc.stderr[-2000:]}")
    peak_kb = int(proc.stderr.strip().splitlines()[-1])
    return {"cpu_s": (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), "wall_s": wall,
            "peak_mb": peak_kb / 1024.0}


def count_fits(bundle: Path) -> dict[str, int]:
    """Re-identifications of the core tables and input histories prepared by one diagnosis of ``bundle``."""
    import bmr
    from bmr.diagnosis import selection

    fitters: list[selection.Fitter] = []
    original = selection.Fitter.__init__

    def keep(self: selection.Fitter, *args: object, **kwargs: object) -> None:
        original(self, *args, **kwargs)
        fitters.append(self)

    selection.Fitter.__init__ = keep  # type: ignore[method-assign]
    try:
        bmr.diagnose(bundle, progress=False, closed_loop=False)
    finally:
        selection.Fitter.__init__ = original  # type: ignore[method-assign]
    return {"reidentifications": sum(f.reidentifier.fits for f in fitters),
            "regressions": sum(f.reidentifier.regressions for f in fitters)}


def measure(bundle: Path, label: str) -> dict[str, object]:
    with tempfile.TemporaryDirectory() as tmp:
        diag = _run(["bmr", "diagnose", str(bundle), "--json", f"{tmp}/d.json"])
        ident = _run(["bmr", "identify", str(bundle), "-o", f"{tmp}/m.json"])
        doc = json.loads(Path(f"{tmp}/d.json").read_text())
    samples = json.loads((bundle / "manifest.json").read_text())
    return {"bundle": label, "diagnose": diag, "identify": ident,
            "ratio_cpu": diag["cpu_s"] / max(ident["cpu_s"], 1e-9), "cause": doc["cause"],
            "effects": [e["name"] for e in doc["effects"]], "n_runs": len(samples.get("runs", [])),
            **count_fits(bundle)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--full", action="store_true", help="also the full bmr2013 set (1.07 M samples)")
    ap.add_argument("--record", action="store_true", help="store the figures in docs/measurements.json")
    args = ap.parse_args(argv)
    from bmr.data.bundle import write_bundle
    from bmr.simulation.excitation import diagnosis_bundle

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        quick = Path(tmp) / "quick"
        write_bundle(diagnosis_bundle("rig_preisach", effects={"coil_lag": {"tau_s": 0.02}}, seed=1000), quick)
        rows.append(measure(quick, "quick diagnosis bundle (rig_preisach + coil_lag, 99 k samples)"))
        sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "python"))
        from independent_plant import independent_bundle

        independent = Path(tmp) / "independent"
        write_bundle(independent_bundle({"coil_eddy_circuit": {}, "seal_lobes": {}}, seed=1000,
                                        sample_rate_hz=1500.0), independent)
        rows.append(measure(independent, "independent plant, coil circuit + seal lobes (327 k samples)"))
        if args.full:
            full = Path(tmp) / "full"
            subprocess.run(["bmr", "simulate", "--preset", "bmr2013", "-o", str(full)], check=True,
                           capture_output=True)
            rows.append(measure(full, "full bmr2013 set (1.07 M samples)"))
    for r in rows:
        d, i = r["diagnose"], r["identify"]
        print(f"{r['bundle']}: diagnose {d['cpu_s']:.1f} CPU-s, {d['wall_s']:.1f} s wall, {d['peak_mb']:.0f} MB "
              f"peak; identify {i['cpu_s']:.1f} CPU-s ({r['ratio_cpu']:.1f}x); cause {r['cause']}; "
              f"{r['reidentifications']} re-identifications, {r['regressions']} input histories prepared")
    if args.record:
        from measurements import record

        command = f"python benches/diagnosis_speed.py{' --full' if args.full else ''} --record"
        record("diagnosis_speed", command, {"rows": rows})
    return 0


if __name__ == "__main__":
    sys.exit(main())
