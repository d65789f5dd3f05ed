"""Bundles and lab readers under hostile files: paths that leave the bundle, encodings, nesting, wrong types,
silent misreads (date-times, booleans, complex numbers), atomic writes, and hypothesis-generated manifests."""
from __future__ import annotations

import json
import os

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import bmr
from bmr.data.bundle import FORMAT_V1 as FORMAT


def _frame(n: int = 20, **extra) -> pd.DataFrame:
    t = np.arange(n) / 500.0
    data = {"t_s": t, "current_a": np.sin(t), "theta_rad": 3.0 * t, "torque_nmm": 10.0 * np.sin(t)}
    data.update(extra)
    return pd.DataFrame(data)


def _bundle_folder(tmp_path, runs=None, **manifest_extra):
    root = tmp_path / "b"
    root.mkdir(exist_ok=True)
    _frame().to_csv(root / "run.csv", index=False)
    manifest = {"format": FORMAT, "actuator": "a", "sample_rate_hz": 500.0,
                "runs": runs if runs is not None else [{"name": "r", "kind": "custom", "file": "run.csv"}],
                **manifest_extra}
    (root / "manifest.json").write_text(json.dumps(manifest))
    return root


@pytest.mark.parametrize("outside", ["../secret.csv", "ABSOLUTE", "sub/../../secret.csv", "../missing.csv"])
def test_run_files_outside_the_bundle_are_refused_without_saying_whether_they_exist(tmp_path, outside):
    # A manifest "file" of "../x.csv", an absolute path or a symlink that leaves the folder used to be read.
    _frame().to_csv(tmp_path / "secret.csv", index=False)
    name = str(tmp_path / "secret.csv") if outside == "ABSOLUTE" else outside
    root = _bundle_folder(tmp_path, runs=[{"name": "r", "kind": "custom", "file": name}])
    with pytest.raises(bmr.BundleError) as info:
        bmr.read_bundle(root)
    assert "not a path inside the folder" in str(info.value)
    assert "does not exist" not in str(info.value)


def test_a_symlink_leaving_the_bundle_is_refused(tmp_path):
    _frame().to_csv(tmp_path / "secret.csv", index=False)
    root = _bundle_folder(tmp_path, runs=[{"name": "r", "kind": "custom", "file": "link.csv"}])
    os.symlink(tmp_path / "secret.csv", root / "link.csv")
    with pytest.raises(bmr.BundleError, match="not a path inside the folder"):
        bmr.read_bundle(root)
    # A symlink that stays inside the bundle is fine.
    os.remove(root / "link.csv")
    os.symlink(root / "run.csv", root / "link.csv")
    assert len(bmr.read_bundle(root)) == 1


def test_a_file_given_as_the_bundle_folder_says_so(tmp_path):
    (tmp_path / "notes.txt").write_text("x")
    with pytest.raises(bmr.BundleError, match="is a file"):
        bmr.read_bundle(tmp_path / "notes.txt")


@pytest.mark.parametrize("encoding", ["latin-1", "utf-16", "utf-8-sig"])
def test_manifest_encodings(tmp_path, encoding):
    # Latin-1 and UTF-16 manifests leaked UnicodeDecodeError.
    root = _bundle_folder(tmp_path, actuator="Prüfstand")
    text = (root / "manifest.json").read_text()
    (root / "manifest.json").write_bytes(json.dumps(json.loads(text), ensure_ascii=False).encode(encoding))
    if encoding == "latin-1":
        with pytest.raises(bmr.BundleError, match="not UTF-8"):
            bmr.read_bundle(root)
    else:
        assert bmr.read_bundle(root).actuator == "Prüfstand"


@pytest.mark.parametrize(("manifest", "match"), [
    ("[" * 100_000 + "]" * 100_000, "manifest"),
    (json.dumps({"format": FORMAT, "sample_rate_hz": 500.0, "runs": [{"name": "r", "kind": "custom", "file": 5}]}),
     r"runs\[0\].file must be a string"),
    (json.dumps({"format": FORMAT, "sample_rate_hz": True,
                 "runs": [{"name": "r", "kind": "custom", "file": "run.csv"}]}), "sample_rate_hz"),
    (json.dumps({"format": FORMAT, "sample_rate_hz": 500.0,
                 "runs": [{"name": ["r"], "kind": "custom", "file": "run.csv"}]}), "name must be a string"),
    # A file name longer than the file system takes leaked OSError (ENAMETOOLONG) from the existence check.
    (json.dumps({"format": FORMAT, "sample_rate_hz": 500.0,
                 "runs": [{"name": "r", "kind": "custom", "file": "爀" * 200 + "run.csv"}]}), "cannot be opened"),
])
def test_hostile_manifests_are_bundle_errors(tmp_path, manifest, match):
    # Deep nesting leaked RecursionError; "file": 5 leaked TypeError; `sample_rate_hz: true` read as 1 Hz.
    root = _bundle_folder(tmp_path)
    (root / "manifest.json").write_text(manifest)
    with pytest.raises(bmr.BundleError, match=match):
        bmr.read_bundle(root)


@pytest.mark.parametrize(("column", "values", "match"), [
    ("t_s", pd.date_range("2024-01-01", periods=20, freq="2ms"), "date-times"),
    ("t_s", pd.to_timedelta(np.arange(20), unit="ms"), "durations"),
    ("current_a", np.arange(20) % 2 == 0, "booleans"),
    ("temperature_c", np.arange(20) > 3, "booleans"),
    ("torque_nmm", np.arange(20) * (1 + 1j), "complex"),
])
def test_columns_that_are_not_measurements_are_refused(tmp_path, column, values, match):
    # A Parquet t_s stored as datetime became ~1.6e15 "seconds"; booleans became 0/1; complex lost its imaginary part.
    frame = _frame()
    frame[column] = values
    with pytest.raises(bmr.BundleError, match=match):
        bmr.Run("r", "custom", frame)
    if values.dtype.kind != "c":  # Parquet holds no complex numbers
        root = _bundle_folder(tmp_path, runs=[{"name": "r", "kind": "custom", "file": "run.parquet"}])
        frame.to_parquet(root / "run.parquet", index=False)
        with pytest.raises(bmr.BundleError, match=match):
            bmr.read_bundle(root)


def test_write_bundle_is_atomic_and_checks_its_folder_first(tmp_path, monkeypatch):
    bundle = bmr.Bundle("a", 500.0, [bmr.Run("r", "custom", _frame())])
    root = bmr.write_bundle(bundle, tmp_path / "b")
    before = {p.name: p.read_bytes() for p in root.iterdir()}
    bigger = bmr.Bundle("a", 500.0, [bmr.Run("r", "custom", _frame(50))])

    def full_disk(fd):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "fsync", full_disk)
    with pytest.raises(bmr.BundleError, match="No space left"):
        bmr.write_bundle(bigger, root)
    monkeypatch.undo()
    assert {p.name: p.read_bytes() for p in root.iterdir()} == before
    (tmp_path / "file").write_text("x")
    with pytest.raises(bmr.BundleError, match="is a file"):
        bmr.write_bundle(bundle, tmp_path / "file")
    with pytest.raises(bmr.BundleError, match="file name"):
        bmr.write_bundle(bmr.Bundle("a", 500.0, [bmr.Run("../evil", "custom", _frame())]), tmp_path / "c")
    assert not (tmp_path / "evil.csv").exists()


@pytest.mark.parametrize(("kwargs", "error", "match"), [
    (dict(mapping=["t_s"]), TypeError, "mapping"),
    (dict(mapping={"t_s": 3}), TypeError, "mapping"),
    (dict(units="V"), TypeError, "units"),
    (dict(defaults={"theta_rad": "zero"}), TypeError, r"defaults\['theta_rad'\]"),
    (dict(defaults={"theta_rad": True}), TypeError, r"defaults\['theta_rad'\]"),
    (dict(defaults={"theta_rad": float("nan")}), bmr.BmrError, "finite"),
    (dict(sample_rate_hz="500"), TypeError, "sample_rate_hz"),
    (dict(sample_rate_hz=-1.0), bmr.BmrError, "sample_rate_hz"),
    (dict(sample_rate_hz=True), TypeError, "sample_rate_hz"),
])
def test_read_table_arguments(tmp_path, kwargs, error, match):
    # read_table leaked AttributeError / TypeError / ValueError for a bad mapping, defaults or sample rate.
    frame = _frame().drop(columns=["t_s", "theta_rad"])
    frame.to_csv(tmp_path / "log.csv", index=False)
    with pytest.raises(error, match=match):
        bmr.read_table(tmp_path / "log.csv", **kwargs)


def test_read_table_names_a_date_time_source(tmp_path):
    frame = _frame()
    frame["stamp"] = pd.date_range("2024-01-01", periods=len(frame), freq="2ms")
    frame.drop(columns=["t_s"]).to_parquet(tmp_path / "log.parquet", index=False)
    with pytest.raises(bmr.BmrError, match="column 'stamp' holds date-times"):
        bmr.read_table(tmp_path / "log.parquet", mapping={"t_s": "stamp"})


_json_leaf = st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=12)
_json = st.recursive(_json_leaf, lambda inner: st.lists(inner, max_size=4)
                     | st.dictionaries(st.text(max_size=8), inner, max_size=4), max_leaves=20)
_run_spec = st.fixed_dictionaries({}, optional={
    "name": st.text(max_size=6) | _json_leaf, "kind": st.sampled_from(["custom", "triangle", "nope"]) | _json_leaf,
    "file": st.sampled_from(["run.csv", "../run.csv", "/etc/passwd", "sub/x.csv", "", ".", "run.csv\x00"])
    | _json_leaf})
_manifest = st.fixed_dictionaries({}, optional={
    "format": st.just(FORMAT) | _json_leaf, "sample_rate_hz": st.floats() | _json_leaf,
    "actuator": _json_leaf, "runs": st.lists(_run_spec, max_size=3) | _json})


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(manifest=_manifest | _json, encoding=st.sampled_from(["utf-8", "utf-16", "latin-1"]))
def test_any_manifest_reads_or_raises_a_bundle_error(tmp_path, manifest, encoding):
    root = _bundle_folder(tmp_path)
    (root / "manifest.json").write_bytes(json.dumps(manifest, ensure_ascii=False).encode(encoding, "replace"))
    try:
        bmr.read_bundle(root)
    except bmr.BundleError:
        pass


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(content=st.binary(max_size=400) | st.text(max_size=400).map(str.encode))
def test_any_run_file_bytes_read_or_raise_a_bundle_error(tmp_path, content):
    root = _bundle_folder(tmp_path)
    (root / "run.csv").write_bytes(content)
    try:
        bmr.read_bundle(root)
    except bmr.BundleError:
        pass


@pytest.mark.parametrize("read", [bmr.read_bundle, bmr.Model.load], ids=["bundle", "model"])
def test_a_path_the_file_system_refuses_is_a_bmr_error(read):
    # A name longer than the file system takes raised OSError (ENAMETOOLONG) from the existence checks.
    with pytest.raises(bmr.BmrError, match="cannot be opened"):
        read("a" * 5000)
