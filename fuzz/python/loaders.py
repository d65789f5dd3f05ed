"""Coverage-guided fuzzing (atheris) of the Python loaders: bundle manifests, bundle run files and model files.

    python fuzz/python/loaders.py bundle_manifest CORPUS_DIR [SEED_DIR] -max_total_time=60
    python fuzz/python/loaders.py run_file CORPUS_DIR [SEED_DIR] -max_total_time=60
    python fuzz/python/loaders.py model_file CORPUS_DIR [SEED_DIR] -max_total_time=60
    python fuzz/python/loaders.py lab_table CORPUS_DIR [SEED_DIR] -max_total_time=60

Each input is written as the file the loader reads (a manifest next to a valid run file, a CSV run file named by a
valid manifest, a model file, or a lab log as ``.csv`` and as ``.txt`` for ``bmr import``) and loaded. A ``bmr.BmrError`` is a correct answer; any other exception is a finding (atheris stops and writes the
input as ``crash-*``).
"""
from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

import atheris

with atheris.instrument_imports():
    import numpy as np
    import pandas as pd

    import bmr
    import bmr.data.bundle
    import bmr.data.files
    import bmr.identification.model
    from bmr.data.formats import read_tables


def _bundle_target(work: Path):
    root = work / "bundle"
    root.mkdir()
    t = np.arange(50) / 500.0
    pd.DataFrame({"t_s": t, "current_a": np.sin(t), "theta_rad": 3 * t, "torque_nmm": np.cos(t)}).to_csv(
        root / "run.csv", index=False)
    manifest = root / "manifest.json"

    def one(data: bytes) -> None:
        manifest.write_bytes(data)
        try:
            bmr.read_bundle(root)
        except bmr.BmrError:
            pass

    return one


def _run_file_target(work: Path):
    root = work / "bundle"
    root.mkdir()
    (root / "manifest.json").write_text(json.dumps({
        "format": bmr.data.bundle.FORMAT_V1, "actuator": "fuzz", "sample_rate_hz": 500.0,
        "runs": [{"name": "r", "kind": "custom", "file": "run.csv"}]}))
    run = root / "run.csv"

    def one(data: bytes) -> None:
        run.write_bytes(data)
        try:
            bundle = bmr.read_bundle(root)
        except bmr.BmrError:
            return
        # What reads is measurements: every column numeric (no dates, booleans, text or complex numbers).
        for r in bundle.runs:
            for column in r.data.columns:
                values = r.data[column].to_numpy()
                if values.dtype.kind not in "fiu":
                    raise AssertionError(f"column {column!r} read as {values.dtype}")

    return one


def _model_target(work: Path):
    path = work / "model.json"

    def one(data: bytes) -> None:
        path.write_bytes(data)
        try:
            model = bmr.Model.load(path)
        except bmr.BmrError:
            return
        # A model that loads saves, and loads again.
        saved = model.save(work / "again.json")
        bmr.Model.load(saved)

    return one


def _lab_table_target(work: Path):
    def one(data: bytes) -> None:
        for name in ("log.csv", "log.txt"):
            path = work / name
            path.write_bytes(data)
            try:
                tables = read_tables(path)
            except bmr.BmrError:
                continue
            for t in tables:
                for column, values in t.columns.items():
                    if values.dtype.kind != "f":
                        raise AssertionError(f"column {column!r} read as {values.dtype}")
            # What reads imports, or says why not.
            names = list(tables[0].columns)
            if len(names) >= 2:
                try:
                    bmr.import_logs([path], input=f"{names[0]}:V", output=f"{names[1]}:V", sample_rate_hz=100.0)
                except bmr.BmrError:
                    pass

    return one


def main() -> None:
    targets = {"bundle_manifest": _bundle_target, "run_file": _run_file_target, "model_file": _model_target,
               "lab_table": _lab_table_target}
    if len(sys.argv) < 2 or sys.argv[1] not in targets:
        sys.exit(f"usage: {sys.argv[0]} {{{'|'.join(targets)}}} [libFuzzer options and corpus folders]")
    name = sys.argv.pop(1)
    with tempfile.TemporaryDirectory(prefix=f"bmr-fuzz-{name}-") as tmp:
        one = targets[name](Path(tmp))
        atheris.Setup(sys.argv, one)
        atheris.Fuzz()


if __name__ == "__main__":
    main()
