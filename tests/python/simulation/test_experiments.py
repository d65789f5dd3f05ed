"""Experiment protocols, simulated bundles, `bmr simulate`, and bundle validation on bad files."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import bmr
from bmr.simulation import experiments as ex
from bmr.cli import main

FS = 500.0
FULL = ex.FULL_CURRENT_A


def _act(**kw):
    return bmr.VirtualActuator("bmr2013", seed=0, sample_rate_hz=FS, **kw)


def _body(run):
    return run.data[run.data.t_s >= run.meta["opening_end_s"]]


def _assert_opening(run):
    head = run.data[run.data.t_s < run.meta["opening_end_s"]].current_a.to_numpy()
    assert head.max() == FULL and head.min() == -FULL
    assert np.argmax(head) < np.argmin(head), "positive saturation first, then negative"


def test_ramp_path_reaches_each_vertex_exactly_and_stays_on_grid():
    p = ex.ramp_path(0.0, [1.0, -0.5, -0.5, 0.25], 0.125)
    assert p[0] == 0.125 and p[7] == 1.0 and p[-1] == 0.25
    np.testing.assert_allclose(p / 0.125, np.round(p / 0.125), atol=1e-12)
    assert np.all(np.abs(np.diff(np.r_[0.0, p])) <= 0.125 + 1e-12)
    with pytest.raises(bmr.BmrError, match="step"):
        ex.ramp_path(0.0, [1.0], 0.0)


def test_off_state_and_multi_step():
    act = _act()
    off = ex.off_state(act, duration_s=4.0)
    assert off.kind == "off_state"
    _assert_opening(off)
    assert np.all(_body(off).current_a == 0.0) and len(_body(off)) == 4 * FS
    ms = ex.multi_step(act, duration_s=21.0)
    _assert_opening(ms)
    levels = np.unique(_body(ms).current_a.round(12))
    np.testing.assert_allclose(np.sort(levels), np.arange(-5, 6) * 0.25)
    assert ms.meta["hold_s"] == pytest.approx(1.0)
    assert set(ms.data.columns) == {"t_s", "current_a", "theta_rad", "torque_nmm", "coil1_a", "coil2_a"}


@pytest.mark.parametrize("fn, rising", [(ex.first_order_ascending, True), (ex.first_order_descending, False)])
def test_first_order_runs_visit_every_reversal_of_the_grid(fn, rising):
    run = fn(_act(), reversals=11, rate_a_per_s=2.0)
    _assert_opening(run)
    u = _body(run).current_a.to_numpy()
    d = np.diff(u)
    turns = np.flatnonzero(np.sign(d[1:]) != np.sign(d[:-1])) + 1
    extremes = u[turns]
    grid = np.linspace(-FULL, FULL, 11)
    if rising:
        minima = np.sort(extremes[extremes < FULL])
        np.testing.assert_array_equal(minima, grid[:-1])
    else:
        maxima = np.sort(extremes[extremes > -FULL])
        np.testing.assert_array_equal(maxima, grid[1:])
    assert np.max(np.abs(np.diff(u))) <= 2.0 / FS + 1e-12
    with pytest.raises(bmr.BmrError, match="reversals"):
        fn(_act(), reversals=1)


def test_triangle_and_multipeak():
    act = _act()
    tri = ex.triangle(act, amplitude_a=1.0, rate_a_per_s=0.5, duration_s=16.0)
    u = _body(tri).current_a.to_numpy()
    assert u.max() == 1.0 and u.min() == -1.0 and len(u) == 16 * FS
    np.testing.assert_allclose(np.abs(np.diff(u)), 0.5 / FS, rtol=1e-6, atol=1e-12)
    mp1 = ex.multipeak(act, duration_s=30.0, seed=5)
    mp2 = ex.multipeak(_act(), duration_s=30.0, seed=5)
    mp3 = ex.multipeak(_act(), duration_s=30.0, seed=6)
    b1 = _body(mp1).current_a.to_numpy()
    np.testing.assert_array_equal(b1, _body(mp2).current_a.to_numpy())
    assert not np.array_equal(b1, _body(mp3).current_a.to_numpy())
    assert np.max(np.abs(b1)) <= FULL
    rates = np.abs(np.diff(b1)) * FS
    moving = rates[rates > 0]
    assert moving.min() >= 0.05 * 0.999 and moving.max() <= 2.5 * 1.001
    assert moving.max() / moving.min() > 5.0, "a range of rates"
    turns = np.sum(np.sign(np.diff(b1))[1:] != np.sign(np.diff(b1))[:-1])
    assert turns >= 6


def test_reference_generators():
    tri = ex.reference_triangle(amplitude_nmm=400.0, rate_nmm_per_s=100.0, duration_s=20.0, sample_rate_hz=100.0)
    assert tri.size == 2000 and tri.max() == 400.0 and tri.min() == -400.0
    mp = ex.reference_multipeak(3, amplitude_nmm=450.0, duration_s=50.0, sample_rate_hz=100.0)
    assert mp.size == 5000 and np.max(np.abs(mp)) <= 450.0
    np.testing.assert_array_equal(mp, ex.reference_multipeak(3, amplitude_nmm=450.0, duration_s=50.0,
                                                             sample_rate_hz=100.0))
    assert not np.array_equal(mp, ex.reference_multipeak(4, amplitude_nmm=450.0, duration_s=50.0,
                                                         sample_rate_hz=100.0))


class LinearCompensator:
    """Stand-in compensator: friction feed-forward and a linear current map (no hysteresis model)."""

    def __init__(self, actuator):
        self.friction = actuator.true_friction
        self.calls = []

    def run(self, torque_ref_nmm, theta_rad):
        self.calls.append((np.array(torque_ref_nmm), np.array(theta_rad)))
        return {"current_a": np.clip((torque_ref_nmm - self.friction(theta_rad)) / 480.0, -FULL, FULL)}


def test_tracking_drives_the_reference_through_the_compensator():
    act = _act()
    comp = LinearCompensator(act)
    ref = ex.reference_multipeak(1, amplitude_nmm=400.0, duration_s=20.0, sample_rate_hz=FS)
    run = ex.tracking(act, comp, ref, opening_duration_s=4.0)
    assert run.kind == "tracking" and "reference_nmm" in run.data
    body = _body(run)
    np.testing.assert_array_equal(body.reference_nmm.to_numpy(), ref)
    _assert_opening(run)  # the opening reference is beyond reach: the current saturates both ways
    # The compensator saw the very encoder angles of the samples it commanded.
    np.testing.assert_array_equal(comp.calls[0][1], run.data.theta_rad.to_numpy())
    err = body.torque_nmm.to_numpy() - ref
    assert np.sqrt(np.mean(err ** 2)) < 80.0  # a linear map misses the hysteresis but tracks

    class Broken:
        def run(self, r, th):
            return {"current": r}

    with pytest.raises(bmr.BmrError, match="current_a"):
        ex.tracking(act, Broken(), ref)
    with pytest.raises(bmr.BmrError, match="not finite"):
        ex.tracking(act, comp, np.r_[ref[:10], np.nan])


def test_simulate_bundle_quick_is_complete():
    b = ex.simulate_bundle(quick=True)
    kinds = [r.kind for r in b.runs]
    assert kinds == ["off_state", "multi_step", "first_order_ascending", "first_order_descending", "triangle",
                     "multipeak"]
    assert {r.kind for r in b.identification_runs()} == {"off_state", "first_order_ascending",
                                                         "first_order_descending"}
    assert b.sample_rate_hz == ex.BUNDLE_SAMPLE_RATE_HZ
    assert b.meta["simulator"]["effects"] == {"coil_lag": {"tau_s": 0.008}}
    for r in b.runs:
        _assert_opening(r)
    with_comp = ex.simulate_bundle(quick=True, compensator=LinearCompensator(_act()))
    assert [r.name for r in with_comp.by_kind("tracking")] == ["tracking_triangle", "tracking_multipeak"]


def _files(root: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(root.iterdir())}


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_same_seed_gives_a_byte_identical_bundle(tmp_path, fmt):
    for name in ("a", "b"):
        bmr.write_bundle(ex.simulate_bundle(quick=True, seed=4, effects=["time_delay"]), tmp_path / name, fmt=fmt)
    fa, fb = _files(tmp_path / "a"), _files(tmp_path / "b")
    assert fa.keys() == fb.keys() and len(fa) == 7
    for k in fa:
        assert fa[k] == fb[k], k
    back = bmr.read_bundle(tmp_path / "a")
    orig = ex.simulate_bundle(quick=True, seed=4, effects=["time_delay"])
    for r, o in zip(back.runs, orig.runs):
        assert r.data.to_numpy().tobytes() == o.data.to_numpy().tobytes()


def test_different_seeds_differ_only_in_noise():
    a = ex.simulate_bundle(quick=True, seed=1)
    b = ex.simulate_bundle(quick=True, seed=2)
    diffs = []
    for ra, rb in zip(a.runs, b.runs):
        for col in ra.data.columns:
            if col != "torque_nmm":
                np.testing.assert_array_equal(ra.data[col], rb.data[col], err_msg=f"{ra.name}.{col}")
        diffs.append(ra.torque - rb.torque)
    d = np.concatenate(diffs)
    assert abs(d.mean()) < 0.05
    assert d.std() == pytest.approx(np.sqrt(2) * 1.5, rel=0.05)


def test_cli_simulate_writes_a_bundle(tmp_path, capsys):
    out = tmp_path / "sim"
    code = main(["simulate", "--quick", "--seed", "3", "--effect", "friction_harmonics:order=6,amplitude_nmm=3",
                 "--effect", "coil_lag:off", "--format", "parquet", "-o", str(out)])
    assert code == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["simulator"]["effects"] == {
        "friction_harmonics": {"order": 6.0, "amplitude_nmm": 3.0, "phase_rad": 0.0}}
    assert manifest["simulator"]["seed"] == 3
    assert len(bmr.read_bundle(out)) == 6
    err = capsys.readouterr().err
    assert "bmr simulate" in err and "wrote 6 runs" in err
    assert main(["simulate", "--quick", "--effect", "coil_lagg", "-o", str(tmp_path / "x")]) == 2
    assert "unknown effect" in capsys.readouterr().err


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    root = tmp_path_factory.mktemp("bundle") / "good"
    bmr.write_bundle(ex.simulate_bundle(quick=True), root)
    return root


def _copy(written, tmp_path):
    dst = tmp_path / "b"
    shutil.copytree(written, dst)
    return dst


def test_bad_bundle_missing_manifest(written, tmp_path):
    b = _copy(written, tmp_path)
    (b / "manifest.json").unlink()
    with pytest.raises(bmr.BmrError, match="no manifest.json"):
        bmr.read_bundle(b)


def test_bad_bundle_unknown_format_version(written, tmp_path):
    b = _copy(written, tmp_path)
    m = json.loads((b / "manifest.json").read_text())
    m["format"] = "bmr-bundle/9"
    (b / "manifest.json").write_text(json.dumps(m))
    with pytest.raises(bmr.BmrError, match="bmr-bundle/9.*not supported"):
        bmr.read_bundle(b)


def test_bad_bundle_missing_column(written, tmp_path):
    b = _copy(written, tmp_path)
    df = pd.read_csv(b / "triangle.csv").drop(columns=["theta_rad"])
    df.to_csv(b / "triangle.csv", index=False)
    with pytest.raises(bmr.BmrError, match="'triangle'.*missing required column.*theta_rad"):
        bmr.read_bundle(b)


def test_bad_bundle_nan_rows(written, tmp_path):
    b = _copy(written, tmp_path)
    df = pd.read_csv(b / "multipeak.csv")
    df.loc[123, "torque_nmm"] = np.nan
    df.to_csv(b / "multipeak.csv", index=False)
    with pytest.raises(bmr.BmrError, match="'multipeak'.*torque_nmm.*row 123"):
        bmr.read_bundle(b)


def test_bad_bundle_non_monotonic_time(written, tmp_path):
    b = _copy(written, tmp_path)
    df = pd.read_csv(b / "off_state.csv")
    df.loc[50, "t_s"] = df.loc[10, "t_s"]
    df.to_csv(b / "off_state.csv", index=False)
    with pytest.raises(bmr.BmrError, match="'off_state'.*strictly increase.*row 50"):
        bmr.read_bundle(b)


def test_tracking_with_the_identified_compensator_opens_from_saturation():
    from bmr.identification.procedure import identify

    model = identify(ex.simulate_bundle(quick=True))
    act = _act()
    ref = ex.reference_multipeak(ex.MULTIPEAK_SEED, amplitude_nmm=450.0, duration_s=20.0, sample_rate_hz=FS)
    run = ex.tracking(act, model.compensator(), ref, opening_duration_s=4.0)
    _assert_opening(run)
    err = _body(run).torque_nmm.to_numpy() - ref
    # Paper fig 25: about ±60 N·mm with both compensations.
    assert np.max(np.abs(err)) < 60.0


def test_custom_run_and_parameters():
    act = _act()
    run = ex.custom(act, np.linspace(0.0, 0.7, 300), name="ramp")
    assert run.kind == "custom" and run.name == "ramp"
    _assert_opening(run)
    np.testing.assert_array_equal(_body(run).current_a, np.linspace(0.0, 0.7, 300))
    with pytest.raises(bmr.BmrError, match=r"current_a\[1\]"):
        ex.custom(act, [0.0, np.inf])
    p = act.parameters
    assert p["converter"]["gain_a_per_v"] == 0.125
    assert p["fluid"]["yield_stress"] == "MRF-132DG cubic"
    assert len(p["friction"]["amplitude_nmm"]) == 3
    assert p["steel1"]["saturation_t"] < p["steel2"]["saturation_t"]


def test_simulate_bundle_with_overrides_records_them():
    b = ex.simulate_bundle(quick=True, overrides={"sensor.noise_n": 0.0})
    assert b.meta["simulator"]["overrides"] == {"sensor.noise_n": 0.0}
    assert b.meta["simulator"]["noise_nmm"] == 0.0
    off = _body(b.run("off_state")).iloc[50:]  # after the coil field lag has settled
    q = bmr.VirtualActuator().resolution_nmm
    truth = bmr.VirtualActuator().true_friction(off.theta_rad.to_numpy())
    assert np.max(np.abs(off.torque_nmm.to_numpy() - truth)) < 2.0 + q


def test_simulate_cli_overrides(tmp_path):
    import json

    from bmr.cli import main

    assert main(["simulate", "--quick", "--override", "sensor.noise_n=0", "-o", str(tmp_path / "b")]) == 0
    manifest = json.loads((tmp_path / "b" / "manifest.json").read_text())
    assert manifest["simulator"]["overrides"] == {"sensor.noise_n": 0.0}
    assert main(["simulate", "--quick", "--override", "junk", "-o", str(tmp_path / "c")]) == 2
