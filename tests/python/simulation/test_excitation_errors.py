"""Invalid protocol and excitation parameters are ``bmr.ExcitationError``s (a ``bmr.BmrError``) naming the
parameter."""
from __future__ import annotations

import pytest

import bmr
from bmr.simulation import excitation, experiments


@pytest.mark.parametrize(("call", "match"), [
    (lambda a: experiments.custom(a, []), "current_a"),
    (lambda a: experiments.custom(a, [0.0, float("nan")]), r"current_a\[1\]"),
    (lambda a: experiments.first_order_ascending(a, reversals=1), "reversals"),
    (lambda a: experiments.triangle(a, rate_a_per_s=-1.0), "rate"),
])
def test_protocol_parameters(call, match):
    with pytest.raises(bmr.ExcitationError, match=match):
        call(bmr.VirtualActuator())
    assert issubclass(bmr.ExcitationError, bmr.BmrError)


@pytest.mark.parametrize(("kwargs", "match"), [
    (dict(centres=0), "centres and depth"),
    (dict(depth=1.5), "centres and depth"),
    (dict(swing_a=5.0), "swing_a"),
])
def test_excitation_parameters(kwargs, match):
    with pytest.raises(bmr.ExcitationError, match=match):
        excitation.minor_loop_vertices(**kwargs)
    with pytest.raises(bmr.ExcitationError, match="rate_a_per_s"):
        excitation.minor_loops(bmr.VirtualActuator(), rate_a_per_s=0.0)
