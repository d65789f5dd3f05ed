"""The README's lab-log example, run on files written in a lab's own layout (names, units): the mapped and
converted bundle identifies like the simulator's own bundle."""
from __future__ import annotations

import numpy as np
import pandas as pd

import bmr
from bmr.simulation.experiments import simulate_bundle


def _write_lab_files(folder) -> tuple[dict[str, str], bmr.Bundle]:
    """The quick experiment set, logged the way a lab would: converter volts, degrees, N·m, own column names."""
    sim = simulate_bundle("ideal", quick=True, seed=3)
    paths = {}
    for run in sim.runs:
        df = pd.DataFrame({"Time": run.t, "I_cmd": run.current / 0.125, "Encoder": np.degrees(run.theta),
                           "Torque": run.torque / 1000.0})
        paths[run.name] = str(folder / f"{run.name}.csv")
        df.to_csv(paths[run.name], index=False)
    return paths, sim


def test_readme_lab_log_example(tmp_path):
    paths, sim = _write_lab_files(tmp_path)
    mapping = {"t_s": "Time", "current_a": "I_cmd", "theta_rad": "Encoder", "torque_nmm": "Torque"}
    units = {"current_a": "0.125A", "theta_rad": "deg", "torque_nmm": "N*m"}
    bundle = bmr.bundle_from_files(
        [{"path": paths["off_state"], "name": "off", "kind": "off_state"},
         {"path": paths["first_order_ascending"], "name": "up", "kind": "first_order_ascending"},
         {"path": paths["first_order_descending"], "name": "down", "kind": "first_order_descending"},
         {"path": paths["multipeak"], "name": "random", "kind": "multipeak"}],
        actuator="rig 2, coil pair B", mapping=mapping, units=units)
    assert bundle.sample_rate_hz == sim.sample_rate_hz
    np.testing.assert_allclose(bundle.run("random").torque, sim.run("multipeak").torque, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(bundle.run("up").current, sim.run("first_order_ascending").current, atol=1e-12)
    out = bmr.write_bundle(bundle, tmp_path / "rig2")
    again = bmr.read_bundle(out)
    model = bmr.identify(again, method="both")
    rms = model.meta["identification"]["heldout_rms"][model.meta["identification"]["chosen"]]["random"]
    assert rms < 5.0  # the ideal preset with 1.5 N·mm sensor noise: a few N·mm with the quick set's tables
