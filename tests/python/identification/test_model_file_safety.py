"""Model files under hostile content and failing disks: atomic saves, every model that saves loads (and saves
again to the same bytes), every problem a ``ModelFileError`` (or ``ResourceLimitError``) naming the field."""
from __future__ import annotations

import json
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import bmr
from bmr.identification.friction import FrictionFit


def _curves(n: int = 4, samples: int = 7):
    asc, desc = [], []
    for k in range(n):
        r = -1.0 + 2.0 * k / n
        u = np.linspace(r, 1.0, samples)
        asc.append((u, 100.0 * (u + 1.0)))
        u = np.linspace(-r, -1.0, samples)
        desc.append((u, 100.0 * (u + 1.0)))
    return asc, desc


def _model(friction: FrictionFit | None = None, meta: dict | None = None) -> bmr.Model:
    asc, desc = _curves()
    return bmr.Model.from_curves(asc, desc, friction, meta=meta or {})


def _content(path) -> dict:
    return json.loads(path.read_text())


def test_a_failed_save_leaves_the_previous_file_intact(tmp_path, monkeypatch):
    # Model.save used to write in place: a failure mid-write (disk full) left a truncated, unreadable file.
    path = _model().save(tmp_path / "m.json")
    before = path.read_bytes()

    def full_disk(fd):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "fsync", full_disk)
    with pytest.raises(bmr.ModelFileError, match="No space left on device"):
        _model(meta={"run": 2}).save(path)
    monkeypatch.undo()
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["m.json"], "no temporary file left behind"
    bmr.Model.load(path)


def test_a_holdout_score_of_infinity_round_trips(tmp_path):
    # fit_friction(..., criterion="holdout") can score an order inf; it was saved as null and Model.load raised
    # TypeError (and `bmr diagnose --model` printed a traceback).
    fit = FrictionFit.from_coefficients(1.5, [0.5, 0.1], [0.2, -0.3])
    fit.criterion = "holdout"
    fit.scores = {0: 3.5, 1: 2.0, 2: float("inf")}
    path = _model(fit).save(tmp_path / "m.json")
    assert _content(path)["friction"]["scores"]["2"] is None
    back = bmr.Model.load(path)
    assert back.friction.scores == {0: 3.5, 1: 2.0, 2: float("inf")}
    assert back.save(tmp_path / "m2.json").read_bytes() == path.read_bytes()


_finite = st.floats(allow_nan=False, allow_infinity=False, min_value=-1e6, max_value=1e6)
_any_float = st.floats(allow_nan=True, allow_infinity=True, width=64)
_meta = st.recursive(
    st.none() | st.booleans() | st.integers(-10**6, 10**6) | _any_float | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=6), inner, max_size=3),
    max_leaves=12,
)


@st.composite
def _friction(draw) -> FrictionFit | None:
    if draw(st.booleans()):
        return None
    k = draw(st.integers(0, 4))
    fit = FrictionFit.from_coefficients(draw(_finite), draw(st.lists(_finite, min_size=k, max_size=k)),
                                        draw(st.lists(_finite, min_size=k, max_size=k)))
    fit.c0_stderr = draw(_any_float)
    fit.a_stderr = np.array(draw(st.lists(_any_float, min_size=k, max_size=k)), dtype=float)
    fit.b_stderr = np.array(draw(st.lists(_any_float, min_size=k, max_size=k)), dtype=float)
    fit.residual_rms_nmm = draw(_any_float)
    fit.n = draw(st.integers(0, 10**9))
    fit.criterion = draw(st.sampled_from(["bic", "holdout", "given"]))
    # Orders a criterion could not score (inf) are common in holdout fits.
    score = st.just(float("inf")) | st.floats(min_value=0, allow_nan=False)
    fit.scores = draw(st.dictionaries(st.integers(0, 12), score, max_size=4))
    return fit


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(friction=_friction(), meta=st.dictionaries(st.text(max_size=6), _meta, max_size=4),
       gain=st.floats(min_value=1e-3, max_value=10.0), low=_finite, width=st.floats(min_value=1e-3, max_value=1e3))
def test_every_model_that_saves_loads_and_saves_to_the_same_bytes(tmp_path, friction, meta, gain, low, width):
    asc, desc = _curves()
    model = bmr.Model.from_curves(asc, desc, friction, meta=meta, converter_gain_a_per_v=gain,
                                  limits={"current_a": [low, low + width]})
    first = model.save(tmp_path / "a.json").read_bytes()
    back = bmr.Model.load(tmp_path / "a.json")
    assert back.save(tmp_path / "b.json").read_bytes() == first


@pytest.mark.parametrize(("edit", "match"), [
    (lambda c: c.__setitem__("limits", {"current_a": [1, 0]}), "low < high"),
    (lambda c: c.__setitem__("limits", {"current_a": ["a", 1]}), "limits.current_a"),
    (lambda c: c.__setitem__("limits", [1, 2]), "'limits' must be an object"),
    (lambda c: c.__setitem__("converter_gain_a_per_v", "0.125"), "converter_gain_a_per_v"),
    (lambda c: c.__setitem__("converter_gain_a_per_v", True), "converter_gain_a_per_v"),
    (lambda c: c["friction"].__setitem__("c0", "x"), "friction c0, a and b must be numbers"),
    (lambda c: c["friction"].__setitem__("a", [True]), "friction c0, a and b must be numbers"),
    (lambda c: c["friction"].__setitem__("stderr", {"c0": "x"}), "friction.stderr"),
    (lambda c: c["friction"].__setitem__("scores", {"x": 1.0}), "friction.scores"),
    (lambda c: c["friction"].__setitem__("scores", {"1": "bad"}), "friction.scores"),
    (lambda c: c["friction"].__setitem__("n", 1.5), "friction.n"),
    (lambda c: c["friction"].__setitem__("residual_rms_nmm", [1]), "residual_rms_nmm"),
    (lambda c: c["hysteresis"].__setitem__("initial", 3), "hysteresis.initial"),
    (lambda c: c["hysteresis"]["ascending"][0].__setitem__(0, [0, "1"]), "not numbers"),
    (lambda c: c["hysteresis"]["ascending"][0].__setitem__(0, [True, 1.0]), "not numbers"),
    (lambda c: c.__setitem__("extensions", [{"name": 5}]), "extensions"),
    (lambda c: c.__setitem__("meta", [1]), "'meta' must be an object"),
])
def test_wrong_field_types_are_model_file_errors(tmp_path, edit, match):
    # Model.load leaked ValueError / TypeError for wrong field types.
    fit = FrictionFit.from_coefficients(1.0, [0.5], [0.2])
    content = _model(fit).to_dict()
    edit(content)
    (tmp_path / "m.json").write_text(json.dumps(content))
    with pytest.raises(bmr.ModelFileError, match=match):
        bmr.Model.load(tmp_path / "m.json")


@pytest.mark.parametrize("encoding", ["latin-1", "utf-16"])
def test_encodings_and_deep_nesting_are_model_file_errors(tmp_path, encoding):
    content = _model(meta={"operator": "Ünal"}).to_dict()
    (tmp_path / "m.json").write_bytes(json.dumps(content, ensure_ascii=False).encode(encoding))
    if encoding == "latin-1":
        with pytest.raises(bmr.ModelFileError, match="not UTF-8"):
            bmr.Model.load(tmp_path / "m.json")
    else:
        assert bmr.Model.load(tmp_path / "m.json").meta["operator"] == "Ünal"
    (tmp_path / "deep.json").write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(bmr.ModelFileError, match="deep.json"):
        bmr.Model.load(tmp_path / "deep.json")
    nested: object = {}
    for _ in range(5000):
        nested = {"x": nested}
    with pytest.raises(bmr.ModelFileError, match="nested too deeply"):
        bmr.Model.from_dict({**content, "meta": nested, "sha256": "0"})
    with pytest.raises(bmr.ModelFileError, match="nested too deeply"):
        _model(meta=nested).save(tmp_path / "m.json")


def test_an_oversized_model_file_is_a_resource_limit_error(tmp_path):
    # A 10 MB hand-made file without a digest asked for 80 GB in Model.load and aborted the interpreter.
    content = _model().to_dict()
    curve = [[0.0, 1.0], [0.0, 1.0]]
    content["hysteresis"]["ascending"] = [curve] * 100_001
    content["hysteresis"]["descending"] = [curve] * 3
    (tmp_path / "big.json").write_text(json.dumps(content))
    with pytest.raises(bmr.ResourceLimitError, match="big.json"):
        bmr.Model.load(tmp_path / "big.json")


def test_saving_to_an_unwritable_place_and_loading_a_folder_are_clear(tmp_path):
    (tmp_path / "file").write_text("x")
    with pytest.raises(bmr.ModelFileError, match="file"):
        _model().save(tmp_path / "file" / "m.json")
    with pytest.raises(bmr.ModelFileError, match="is a folder"):
        bmr.Model.load(tmp_path)


def test_simulate_refuses_complex_and_boolean_input():
    model = _model()
    with pytest.raises(TypeError, match="current"):
        model.simulate(np.array([0.1 + 1j, 0.2]))
    with pytest.raises(TypeError, match="current"):
        model.simulate(np.array([True, False]))
