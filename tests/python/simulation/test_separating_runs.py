"""The runs that separate effects one bundle's excitation cannot tell apart: every effect of the vocabulary names
one that ``bmr simulate --separate`` records on the virtual actuator, the command appends them as evaluation runs,
and the run a diagnosis asks for settles what it could not tell apart before."""
from __future__ import annotations

import numpy as np
import pytest

import bmr
from bmr.cli import main
from bmr.data.bundle import read_bundle
from bmr.diagnosis.effects import LIBRARY, PHYSICAL
from bmr.simulation.excitation import SEPARATING_RUNS, separating_run
from bmr.simulation.experiments import simulate_bundle


def test_every_physical_effect_names_a_run_the_simulator_records():
    named = {e.name: e.separating_run for e in LIBRARY if e.name in PHYSICAL}
    assert all(kind in SEPARATING_RUNS for kind in named.values()), named
    # No run is recorded that no effect asks for.
    assert set(SEPARATING_RUNS) == set(named.values())


def test_simulate_appends_the_runs_asked_for(tmp_path, capsys):
    out = tmp_path / "bundle"
    assert main(["simulate", "--quick", "--separate", "dwell", "--separate", "second_speed", "--separate", "dwell",
                 "-o", str(out)]) == 0
    bundle = read_bundle(out)
    names = [r.name for r in bundle.runs]
    # The set first, each separating run once, in the order asked.
    assert names[-2:] == ["separate_dwell", "separate_second_speed"] and names.count("separate_dwell") == 1
    assert {r.name for r in bundle.roles().evaluation} >= {"separate_dwell", "separate_second_speed"}
    fast = bundle.run("separate_second_speed")
    assert fast.kind == "triangle" and fast.meta["rate_a_per_s"] == 8 * bundle.run("triangle").meta["rate_a_per_s"]
    dwell = bundle.run("separate_dwell")
    held = np.diff(dwell.data["current_a"].to_numpy()[int(dwell.meta["opening_end_s"] * bundle.sample_rate_hz):])
    # Steps, each level held: the input moves on one sample in a thousand at most.
    assert np.count_nonzero(held) <= len(dwell.meta["levels_a"]) and np.count_nonzero(held) >= 5


def test_an_unknown_run_is_a_clear_error(tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        main(["simulate", "--quick", "--separate", "sweep", "-o", str(tmp_path / "b")])
    assert e.value.code == 2
    assert "invalid choice: 'sweep'" in capsys.readouterr().err
    with pytest.raises(bmr.BmrError, match="unknown separating run 'sweep'"):
        separating_run("sweep")
    assert main(["simulate", "--quick", "--forc-reversals", "1", "-o", str(tmp_path / "c")]) == 2
    assert "--forc-reversals 1" in capsys.readouterr().err


@pytest.mark.slow
def test_the_run_a_diagnosis_asks_for_settles_what_it_could_not_tell_apart():
    # Creep on the paper's quick set, whose actuator has its own coil lag (8 ms): the lag cannot be told from a
    # dynamic field there, and the report asks for a dwell. Recorded, it settles the lag.
    creep = {"creep": {"fraction": 0.02, "tau_min_s": 0.1, "tau_max_s": 100.0}}
    before = bmr.diagnose(simulate_bundle("bmr2013", effects=creep, seed=1, quick=True), progress=False,
                          closed_loop=False)
    asked = [a for a in before.alternatives if {a.chosen, a.other} == {"coil_lag", "rate_dependence"}]
    assert asked and "bmr simulate --separate dwell" in asked[0].message, [a.message for a in before.alternatives]
    runs = [separating_run(kind, quick=True) for kind in asked[0].separating_runs]
    after = bmr.diagnose(simulate_bundle("bmr2013", effects=creep, seed=1, quick=True, extra_runs=runs),
                         progress=False, closed_loop=False)
    assert not after.alternatives, [a.message for a in after.alternatives]
    assert {e["name"] for e in after.effects} >= {"coil_lag", "creep"}
