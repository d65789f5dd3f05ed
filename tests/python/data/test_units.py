"""The unit registry: spellings, conversions, errors that name the column, unit-aware formatting."""
from __future__ import annotations

import math

import numpy as np
import pytest

import bmr
from bmr.data.quantities import ACTUATOR, Quantities, Quantity, column_name
from bmr.data.units import UNITS, convert, format_number, format_value, unit


@pytest.mark.parametrize("spelling, symbol", [
    ("V", "V"), ("mV", "mV"), ("kV", "kV"), ("A", "A"), ("mA", "mA"), ("T", "T"), ("mT", "mT"),
    ("um", "µm"), ("µm", "µm"), ("micron", "µm"), ("nm", "nm"), ("mm", "mm"), ("m", "m"),
    ("N*m", "N·m"), ("Nm", "N·m"), ("N.mm", "N·mm"), ("Nmm", "N·mm"), ("N·mm", "N·mm"),
    ("uC_per_cm2", "µC/cm²"), ("uC/cm2", "µC/cm²"), ("C/m^2", "C/m²"), ("s", "s"), ("ms", "ms"),
    ("rad", "rad"), ("deg", "deg"), ("[V]", "V"), ("(mT)", "mT"), ("a", "A"), ("degC", "°C"),
])
def test_spellings_name_one_unit(spelling, symbol):
    assert unit(spelling).symbol == symbol


@pytest.mark.parametrize("frm, to, value, expected", [
    ("V", "mV", 1.5, 1500.0), ("kV", "V", 0.2, 200.0), ("mA", "A", 250.0, 0.25), ("mT", "T", 5.0, 0.005),
    ("mm", "um", 0.02, 20.0), ("um", "nm", 1.0, 1000.0), ("m", "um", 1e-6, 1.0),
    ("N*m", "N*mm", 0.6, 600.0), ("uC_per_cm2", "C/m2", 25.0, 0.25), ("ms", "s", 2.0, 0.002),
    ("deg", "rad", 180.0, math.pi), ("degC", "K", 20.0, 293.15), ("G", "mT", 10.0, 1.0),
])
def test_conversions(frm, to, value, expected):
    assert convert(value, frm, to) == pytest.approx(expected, rel=1e-12)
    assert convert(convert(value, frm, to), to, frm) == pytest.approx(value, rel=1e-12)


def test_units_that_do_not_convert_name_the_column():
    with pytest.raises(bmr.BmrError, match=r"column 'P1': unit V \(voltage\) does not convert to µC/cm² "
                                           r"\(polarization\)"):
        convert([1.0], "V", "uC_per_cm2", what="column 'P1'")
    with pytest.raises(bmr.BmrError, match="column 'x': unknown unit 'furlong'"):
        convert([1.0], "furlong", "m", what="column 'x'")


def test_case_is_ignored_except_for_the_prefix():
    # "MV" is neither mV nor a registered megavolt: an error, not a silent factor of 1e9.
    with pytest.raises(bmr.BmrError, match="unknown unit 'MV'"):
        unit("MV")
    with pytest.raises(bmr.BmrError, match="unknown unit 'mpa'"):
        unit("mpa")  # MPa or mPa? neither is guessed
    assert unit("NM", dimension="torque").symbol == "N·m"  # within one dimension the spelling is unambiguous


def test_every_registered_spelling_is_unique():
    seen = {}
    for u in UNITS:
        for n in (u.symbol, *u.aliases):
            assert seen.setdefault(n, u.symbol) == u.symbol, n


def test_formatting():
    assert format_value(1.37e-3, "T") == "1.37e-3 T"
    assert format_value(2.364, "N·mm") == "2.36 N·mm"
    assert format_value(14321.7, "V") == "14300 V"
    assert format_value(0.5, "1") == "0.5"
    assert format_number(float("nan")) == "nan"
    assert format_number(123456.0) == "1.23e5"


def test_quantities_labels_columns_and_dict_round_trip():
    q = Quantities(Quantity.declare("V"), Quantity.declare("um"))
    assert q.input.name == "voltage" and q.input.column == "voltage_v"
    assert q.output.label == "displacement (µm)" and q.output.column == "displacement_um"
    assert q.output.format(0.25) == "0.25 µm"
    assert q.describe() == "voltage (V) → displacement (µm)"
    assert Quantities.from_dict(q.to_dict(), "q") == q
    assert ACTUATOR.is_actuator and not q.is_actuator
    assert ACTUATOR.columns == ["t_s", "current_a", "torque_nmm", "theta_rad"]
    assert column_name("integrated gradient", "T") == "integrated_gradient_t"
    assert column_name("polarization", "uC_per_cm2") == "polarization_uc_per_cm2"
    with pytest.raises(bmr.BmrError, match="distinct columns"):
        Quantities(Quantity("a", "V", "x"), Quantity("b", "um", "x"))
    with pytest.raises(bmr.BmrError, match=r"quantities.output: quantity 'x': unknown unit 'parsec'"):
        Quantities.from_dict({"input": q.input.to_dict(), "output": {"name": "x", "unit": "parsec",
                                                                      "column": "x_pc"}}, "quantities")
    np.testing.assert_allclose(q.output.from_unit([1.0, 2.0], "mm"), [1000.0, 2000.0])
