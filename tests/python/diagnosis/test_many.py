"""bmr.diagnose_many / bmr diagnose B1 B2 ...: many bundles on a local Dask cluster of 2 worker processes, the
rows streamed into one Parquet table, a failed bundle recorded with its error without losing the others, the
same rows as the serial loop."""
from __future__ import annotations

import functools
from pathlib import Path

import pandas as pd
import pytest

import bmr
from bmr.diagnosis.many import COLUMNS, diagnose_many
from bmr.simulation.excitation import diagnosis_bundle

pytest.importorskip("dask.distributed", reason="diagnose_many runs on Dask: pip install 'bmr[dask]'")

# Small bundles (250 Hz) keep the test short; the bundles are simulated on the workers.
LAG = functools.partial(diagnosis_bundle, "rig_preisach", effects={"coil_lag": {"tau_s": 0.03}}, seed=5,
                        sample_rate_hz=250.0)
CLEAN = functools.partial(diagnosis_bundle, "ideal", seed=0, sample_rate_hz=250.0)


@pytest.fixture(scope="module")
def batch(tmp_path_factory: pytest.TempPathFactory) -> tuple[pd.DataFrame, Path, Path]:
    tmp = tmp_path_factory.mktemp("many")
    ident_only = LAG()
    ident_only = bmr.Bundle(ident_only.actuator, ident_only.sample_rate_hz, ident_only.identification_runs())
    bundles = {"lag": LAG, "missing": tmp / "no-such-bundle", "no-eval": ident_only, "clean": CLEAN}
    out = tmp / "table.parquet"
    table = diagnose_many(bundles, out, workers=2, folds=3, progress=False)
    return table, out, tmp


def test_rows_stream_into_one_parquet_table_and_failures_are_rows(batch) -> None:
    table, out, _ = batch
    assert list(table.columns) == list(COLUMNS)
    assert list(table["bundle"]) == ["lag", "missing", "no-eval", "clean"]
    on_disk = pd.read_parquet(out)
    assert sorted(on_disk["bundle"]) == sorted(table["bundle"]) and len(on_disk) == 4
    status = dict(zip(table["bundle"], table["status"]))
    assert status == {"lag": "ok", "missing": "error", "no-eval": "error", "clean": "ok"}
    err = dict(zip(table["bundle"], table["error"]))
    assert "does not exist" in err["missing"] and "no evaluation run" in err["no-eval"]
    lag = table.set_index("bundle").loc["lag"]
    assert lag["cause"] == "coil_lag" and "coil_lag" in lag["effects"]
    assert lag["residual_rms"] < lag["nominal_heldout_rms"] and lag["cpu_s"] > 0
    import json

    doc = json.loads(lag["diagnosis"])
    assert doc["format"] == "bmr-diagnosis/2" and doc["cause"] == "coil_lag"
    # Two worker processes did the work.
    assert table["worker"].dropna().nunique() >= 1


def test_the_serial_loop_gives_the_same_rows(batch) -> None:
    table, _, _ = batch
    serial = diagnose_many({"lag": LAG}, workers=0, folds=3, progress=False)
    a, b = serial.iloc[0], table.set_index("bundle").loc["lag"]
    assert a["cause"] == b["cause"] and a["effects"] == b["effects"]
    assert a["residual_rms"] == b["residual_rms"]


def test_cli_diagnoses_several_bundles(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from bmr.cli import main

    bmr.write_bundle(CLEAN(), tmp_path / "a")
    rc = main(["diagnose", str(tmp_path / "a"), str(tmp_path / "missing"), "--workers", "0", "--folds", "3",
               "--out", str(tmp_path / "t.parquet")])
    out = capsys.readouterr().out
    assert rc == 1  # one bundle failed
    assert "1 diagnosed, 1 failed" in out and "does not exist" in out
    assert len(pd.read_parquet(tmp_path / "t.parquet")) == 2
    assert main(["diagnose", str(tmp_path / "a"), str(tmp_path / "a"), "--json", str(tmp_path / "x.json")]) == 2
