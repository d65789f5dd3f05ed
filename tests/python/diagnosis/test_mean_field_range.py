"""``non_congruent``'s mean field is physical only while the loop stays single-valued: the feedback times the
core's steepest normalised slope below 1 (the vocabulary says so, the diagnosis checks it where it accepts a
candidate)."""
from __future__ import annotations

import numpy as np

import bmr
from bmr.diagnosis.effects import NonCongruent
from bmr.diagnosis.field import FieldPath, steepest_slope

S = 600.0  # full-scale output (N·mm)
WIDTH_A = 0.25  # the branches' tanh width: steepest slope S/WIDTH_A, normalised 1/WIDTH_A = 4 per A


def _tables() -> tuple[list, list]:
    u = np.linspace(-1.25, 1.25, 201)
    asc = [(u, S * np.tanh((u - 0.1) / WIDTH_A))]
    desc = [(u, S * np.tanh((u + 0.1) / WIDTH_A))]
    return asc, desc


def _path(feedback: float) -> FieldPath:
    return FieldPath(model=None, tables=_tables(), scale_nmm=S, feedback=feedback)


def test_the_steepest_slope_is_the_tables_largest():
    assert abs(steepest_slope(_tables()) - S / WIDTH_A) < 0.01 * S / WIDTH_A


def test_a_mean_field_that_would_make_the_loop_multivalued_is_unphysical():
    eff = NonCongruent()
    assert eff.outside_physics(_path(0.0)) == []
    # 0.2 A × 4/A = 0.8: single-valued; 0.3 A × 4/A = 1.2: the output would jump.
    assert eff.outside_physics(_path(0.2)) == []
    why = eff.outside_physics(_path(0.3))
    assert len(why) == 1 and "single-valued" in why[0] and "feedback=0.3" in why[0], why
    # Demagnetizing feedback shears the loop: always single-valued.
    assert eff.outside_physics(_path(-5.0)) == []


def test_the_vocabulary_documents_the_feedback_and_its_bound():
    spec = bmr.effect_parameters()["non_congruent"]["params"]["feedback"]
    assert spec["default"] == 0.0 and spec["min"] < 0.0 < spec["max"]
    assert "single-valued" in spec["doc"]
