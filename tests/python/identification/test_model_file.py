"""The ``bmr-model/1`` file: round trip, and clear errors for corrupted, wrong-format and newer files."""
from __future__ import annotations

import json

import numpy as np
import pytest

import bmr
from bmr.identification.model import FORMAT

from identify_synthetic import synthetic_bundle


@pytest.fixture(scope="module")
def model():
    return bmr.identify(synthetic_bundle(), method="lstsq")


def test_round_trip_reproduces_the_model(model, tmp_path):
    path = model.save(tmp_path / "m.json")
    back = bmr.Model.load(path)
    u = np.concatenate([np.linspace(-1.25, 1.25, 300), np.linspace(1.25, -0.3, 200), np.linspace(-0.3, 0.7, 100)])
    theta = np.linspace(0, 20, u.size)
    np.testing.assert_allclose(back.simulate(u, theta), model.simulate(u, theta), rtol=0, atol=1e-9)
    assert back.friction.order == model.friction.order
    np.testing.assert_array_equal(back.friction.a, model.friction.a)
    assert back.friction.c0_stderr == model.friction.c0_stderr
    assert back.limits == model.limits
    assert back.converter_gain_a_per_v == 0.125
    assert back.meta["identification"]["method"] == "lstsq"
    # Saving the loaded model gives the same file.
    assert back.save(tmp_path / "m2.json").read_text() == path.read_text()


def test_simulate_checks_its_input(model):
    with pytest.raises(bmr.BmrError, match="sample 2"):
        model.simulate([0.0, 0.1, float("nan")])
    with pytest.raises(bmr.BmrError, match="theta"):
        model.simulate([0.0, 0.1], [0.0])


def _write(path, content):
    path.write_text(json.dumps(content))
    return path


def test_corrupted_files_are_rejected(model, tmp_path):
    good = model.save(tmp_path / "good.json")
    text = good.read_text()
    (tmp_path / "cut.json").write_text(text[: len(text) // 2])
    with pytest.raises(bmr.BmrError, match="not a valid model file"):
        bmr.Model.load(tmp_path / "cut.json")
    content = json.loads(text)
    content["friction"]["c0"] += 1.0
    with pytest.raises(bmr.BmrError, match="sha256"):
        bmr.Model.load(_write(tmp_path / "edited.json", content))
    # Without the digest an edit is accepted, but broken tables are still named.
    del content["sha256"]
    assert bmr.Model.load(_write(tmp_path / "edited2.json", content)).friction.c0 == pytest.approx(
        model.friction.c0 + 1.0)
    content["hysteresis"]["ascending"][2][1][3] = "x"
    with pytest.raises(bmr.BmrError, match=r"ascending\[2\]"):
        bmr.Model.load(_write(tmp_path / "bad_value.json", content))
    content = json.loads(text)
    del content["sha256"]
    content["hysteresis"]["descending"] = "nope"
    with pytest.raises(bmr.BmrError, match="descending"):
        bmr.Model.load(_write(tmp_path / "no_desc.json", content))
    (tmp_path / "bin.json").write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(bmr.BmrError, match="not a valid model file"):
        bmr.Model.load(tmp_path / "bin.json")
    with pytest.raises(bmr.BmrError, match="does not exist"):
        bmr.Model.load(tmp_path / "nothing.json")


def test_wrong_and_newer_formats_are_rejected(model, tmp_path):
    content = json.loads(model.save(tmp_path / "m.json").read_text())
    del content["sha256"]
    content["format"] = "bmr-model/3"
    with pytest.raises(bmr.BmrError, match="newer"):
        bmr.Model.load(_write(tmp_path / "v3.json", content))
    content["format"] = "bmr-bundle/1"
    with pytest.raises(bmr.BmrError, match="unknown 'format'"):
        bmr.Model.load(_write(tmp_path / "other.json", content))
    del content["format"]
    with pytest.raises(bmr.BmrError, match=FORMAT):
        bmr.Model.load(_write(tmp_path / "none.json", content))
    with pytest.raises(bmr.BmrError, match="JSON object"):
        bmr.Model.load(_write(tmp_path / "list.json", [1, 2]))


def test_model_with_given_friction_round_trips(model, tmp_path):
    given = bmr.FrictionFit.from_coefficients(5.0, [1.0, 0.5], [0.0, -0.25])
    m = bmr.Model(model.hysteresis, given, extensions=[{"name": "coil_lag", "params": {"tau_s": 0.008}}])
    back = bmr.Model.load(m.save(tmp_path / "given.json"))
    assert back.friction.c0 == 5.0 and np.isnan(back.friction.c0_stderr)
    assert back.extensions == [{"name": "coil_lag", "params": {"tau_s": 0.008}}]
    theta = np.linspace(0, 7, 50)
    np.testing.assert_allclose(back.friction_torque(theta), given(theta))
    np.testing.assert_allclose(back.friction.to_friction()(theta), given(theta), atol=1e-12)


def test_model_files_are_written_atomically(model, tmp_path, monkeypatch):
    path = model.save(tmp_path / "m.json")
    before = path.read_bytes()
    # A write that fails half-way leaves the previous file as it was and no temporary file behind.
    import os

    def broken_fsync(fd):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "fsync", broken_fsync)
    with pytest.raises(bmr.BmrError, match="cannot write model file .*No space left"):
        model.save(path)
    monkeypatch.undo()
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.json"]
    with pytest.raises(bmr.BmrError, match="cannot write model file"):
        model.save(tmp_path / "missing-folder" / "m.json")
