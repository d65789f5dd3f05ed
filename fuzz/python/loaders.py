"""Coverage-guided fuzzing (atheris) of the Python loaders: bundle manifests and model files.

    python fuzz/python/loaders.py bundle_manifest CORPUS_DIR [SEED_DIR] -max_total_time=60
    python fuzz/python/loaders.py model_file CORPUS_DIR [SEED_DIR] -max_total_time=60

Each input is written as the file the loader reads (a manifest next to a valid run file, or a model file) and
loaded. A ``bmr.BmrError`` is a correct answer; any other exception is a finding (atheris stops and writes the
input as ``crash-*``).
"""
from __future__ import annotations

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


def main() -> None:
    targets = {"bundle_manifest": _bundle_target, "model_file": _model_target}
    if len(sys.argv) < 2 or sys.argv[1] not in targets:
        sys.exit(f"usage: {sys.argv[0]} {{{'|'.join(targets)}}} [libFuzzer options and corpus folders]")
    name = sys.argv.pop(1)
    with tempfile.TemporaryDirectory(prefix=f"bmr-fuzz-{name}-") as tmp:
        one = targets[name](Path(tmp))
        atheris.Setup(sys.argv, one)
        atheris.Fuzz()


if __name__ == "__main__":
    main()
