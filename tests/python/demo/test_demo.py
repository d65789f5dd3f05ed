"""`bmr demo --quick`: every output exists, figures are real PNGs with data, the report embeds them, numbers are
honest and deterministic for a seed."""
import json
import subprocess
import sys

import numpy as np
import pytest

CASES = {
    "triangle_current_without_friction_compensation",
    "triangle_current_with_friction_compensation",
    "triangle_hysteresis_compensation",
    "multipeak_uncompensated",
    "multipeak_hysteresis_compensation",
    "multipeak_both_compensations",
    "multipeak_both_paper_inverse",
    "multipeak_heating_open_loop",
    "multipeak_heating_controller",
}


def _demo(out):
    r = subprocess.run([sys.executable, "-m", "bmr.cli", "demo", "--quick", "--out", str(out), "--seed", "3"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    return r


@pytest.fixture(scope="module")
def demo_dirs(tmp_path_factory):
    a, b = tmp_path_factory.mktemp("demo_a"), tmp_path_factory.mktemp("demo_b")
    return _demo(a), a, b


def test_outputs_exist_and_metrics_cover_every_case(demo_dirs):
    r, out, _ = demo_dirs
    m = json.loads((out / "metrics.json").read_text())
    assert set(m["cases"]) == CASES
    for c in m["cases"].values():
        for k in ("rms_nmm", "max_abs_nmm", "rms_pct_fs", "max_pct_fs", "samples", "seed"):
            assert k in c
        assert c["samples"] > 1000 and c["seed"] == 3 and np.isfinite(c["rms_nmm"])
    assert (out / "model.json").is_file() and (out / "bundle" / "manifest.json").is_file()
    assert "multipeak_both_compensations" in r.stdout


def test_figures_are_png_with_data_and_embedded_in_report(demo_dirs):
    import matplotlib.image as mpimg

    _, out, _ = demo_dirs
    pngs = sorted(out.glob("*.png"))
    assert {p.name.split("_")[0] for p in pngs} >= {f"fig{n}" for n in (11, 12, 13, 14, 15, 16, 17, 18, 19, 21, 22,
                                                                       24, 25)}
    for p in pngs:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        img = mpimg.imread(p)
        assert img.shape[0] > 100 and img[..., :3].std() > 0.05, f"{p.name} looks empty"
    import base64

    html = (out / "report.html").read_text()
    for p in pngs:
        assert base64.b64encode(p.read_bytes()).decode("ascii") in html, p.name + " is not embedded"
    assert "fig 25" in html and "N·mm" in html
    assert (out / "closed_loop_heating.png").is_file()


def test_the_controller_beats_the_open_loop_compensator_on_the_heating_actuator(demo_dirs):
    r, out, _ = demo_dirs
    c = json.loads((out / "metrics.json").read_text())["cases"]
    ol, cl = c["multipeak_heating_open_loop"]["rms_nmm"], c["multipeak_heating_controller"]["rms_nmm"]
    print(f"multi-peak, coils heating: open loop {ol:.2f} N·mm, Controller {cl:.2f} N·mm")
    assert cl < 0.8 * ol
    assert f"{ol:.2f} N·mm open loop -> {cl:.2f} N·mm with bmr.Controller" in r.stdout


def test_compensation_is_far_better_than_the_uncompensated_baseline(demo_dirs):
    _, out, _ = demo_dirs
    c = json.loads((out / "metrics.json").read_text())["cases"]
    both, none = c["multipeak_both_compensations"]["rms_nmm"], c["multipeak_uncompensated"]["rms_nmm"]
    print(f"multi-peak RMS error: both compensations {both:.2f} N·mm, uncompensated {none:.2f} N·mm")
    assert none / both > 3.0
    assert c["multipeak_both_compensations"]["rms_nmm"] < c["multipeak_hysteresis_compensation"]["rms_nmm"]
    assert c["triangle_current_with_friction_compensation"]["rms_nmm"] < \
        c["triangle_current_without_friction_compensation"]["rms_nmm"]


def test_same_seed_same_figures_and_metrics(demo_dirs):
    _, a, b = demo_dirs
    _demo(b)
    ma, mb = (json.loads((d / "metrics.json").read_text()) for d in (a, b))
    ma.pop("timing_s"), mb.pop("timing_s")  # wall-clock timings differ; everything else must not
    assert ma == mb
    for p in a.glob("*.png"):
        assert p.read_bytes() == (b / p.name).read_bytes(), p.name
