"""Units: a small explicit registry, conversions between units of one dimension, and unit-aware formatting.

Each unit has a canonical symbol (what reports print: ``"µm"``, ``"N·mm"``, ``"µC/cm²"``), an ASCII slug for
column names (``"um"``, ``"nmm"``, ``"uc_per_cm2"``), a dimension and its value in SI base units. Symbols are
matched exactly, then through their aliases (``"um"``, ``"micron"`` for ``µm``; ``"uC_per_cm2"`` for ``µC/cm²``;
``"N*mm"`` for ``N·mm``), then ignoring case when that is unambiguous and leaves the prefix alone (``"a"`` is
``A``, but ``"MV"`` is not ``mV``: megavolts are not registered, so it is an error, not a silent factor of 10⁹).
Temperatures are affine.

    >>> convert([1.0, 2.0], "mm", "um")
    array([1000., 2000.])
    >>> format_value(1.37e-3, "T")
    '1.37e-3 T'
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Iterable

import numpy as np

from bmr._core import BmrError

__all__ = ["Unit", "UNITS", "DIMENSION_QUANTITY", "unit", "convert", "units_of", "format_number", "format_value"]


@dataclass(frozen=True)
class Unit:
    """One unit: ``si = value * scale + offset`` in the SI base unit of ``dimension``."""

    symbol: str
    slug: str
    dimension: str
    scale: float
    offset: float = 0.0
    aliases: tuple[str, ...] = ()

    def to_si(self, values: Any) -> np.ndarray:
        return np.asarray(values, dtype=float) * self.scale + self.offset

    def from_si(self, values: Any) -> np.ndarray:
        return (np.asarray(values, dtype=float) - self.offset) / self.scale

    def __str__(self) -> str:
        return self.symbol


def _u(symbol: str, slug: str, dimension: str, scale: float, *aliases: str, offset: float = 0.0) -> Unit:
    return Unit(symbol, slug, dimension, scale, offset, aliases)


# Dimension -> the quantity name a bundle uses when the user names none.
DIMENSION_QUANTITY = {
    "time": "time",
    "voltage": "voltage",
    "current": "current",
    "magnetic flux density": "field",
    "magnetic field strength": "field strength",
    "length": "displacement",
    "angle": "angle",
    "angular speed": "speed",
    "torque": "torque",
    "force": "force",
    "pressure": "pressure",
    "polarization": "polarization",
    "charge": "charge",
    "magnetic moment": "moment",
    "temperature": "temperature",
    "dimensionless": "value",
}

UNITS: tuple[Unit, ...] = (
    _u("s", "s", "time", 1.0, "sec"),
    _u("ms", "ms", "time", 1e-3),
    _u("µs", "us", "time", 1e-6, "us", "μs"),
    _u("ns", "ns", "time", 1e-9),
    _u("min", "min", "time", 60.0),
    _u("h", "h", "time", 3600.0),
    _u("V", "v", "voltage", 1.0),
    _u("mV", "mv", "voltage", 1e-3),
    _u("µV", "uv", "voltage", 1e-6, "uV", "μV"),
    _u("kV", "kv", "voltage", 1e3),
    _u("A", "a", "current", 1.0),
    _u("mA", "ma", "current", 1e-3),
    _u("µA", "ua", "current", 1e-6, "uA", "μA"),
    _u("kA", "ka", "current", 1e3),
    # The BMR paper's current unit: converter volts at 0.125 A/V (±10 units = ±1.25 A).
    _u("0.125 A", "0p125a", "current", 0.125, "0.125A"),
    _u("T", "t", "magnetic flux density", 1.0),
    _u("mT", "mt", "magnetic flux density", 1e-3),
    _u("µT", "ut", "magnetic flux density", 1e-6, "uT", "μT"),
    _u("G", "g", "magnetic flux density", 1e-4, "gauss"),
    _u("A/m", "a_per_m", "magnetic field strength", 1.0, "A_per_m"),
    _u("kA/m", "ka_per_m", "magnetic field strength", 1e3, "kA_per_m"),
    _u("Oe", "oe", "magnetic field strength", 1e3 / (4.0 * math.pi)),
    _u("m", "m", "length", 1.0),
    _u("cm", "cm", "length", 1e-2),
    _u("mm", "mm", "length", 1e-3),
    _u("µm", "um", "length", 1e-6, "um", "μm", "micron"),
    _u("nm", "nm", "length", 1e-9),
    _u("rad", "rad", "angle", 1.0),
    _u("mrad", "mrad", "angle", 1e-3),
    _u("deg", "deg", "angle", math.pi / 180.0, "°", "degree"),
    _u("rev", "rev", "angle", 2.0 * math.pi, "turn"),
    _u("rad/s", "rad_per_s", "angular speed", 1.0, "rad_per_s"),
    _u("deg/s", "deg_per_s", "angular speed", math.pi / 180.0, "deg_per_s"),
    _u("rpm", "rpm", "angular speed", 2.0 * math.pi / 60.0, "1/min"),
    _u("rev/s", "rev_per_s", "angular speed", 2.0 * math.pi, "rev_per_s"),
    _u("N·m", "nm", "torque", 1.0, "N*m", "N.m", "Nm", "N m"),
    _u("N·cm", "ncm", "torque", 1e-2, "N*cm", "N.cm", "Ncm"),
    _u("N·mm", "nmm", "torque", 1e-3, "N*mm", "N.mm", "Nmm", "mN·m", "mN*m", "mNm"),
    _u("N", "n", "force", 1.0),
    _u("mN", "mn", "force", 1e-3),
    _u("kN", "kn", "force", 1e3),
    _u("Pa", "pa", "pressure", 1.0),
    _u("kPa", "kpa", "pressure", 1e3),
    _u("MPa", "mpa", "pressure", 1e6),
    _u("bar", "bar", "pressure", 1e5),
    _u("C/m²", "c_per_m2", "polarization", 1.0, "C/m2", "C/m^2", "C_per_m2"),
    _u("mC/m²", "mc_per_m2", "polarization", 1e-3, "mC/m2", "mC/m^2", "mC_per_m2"),
    _u("µC/cm²", "uc_per_cm2", "polarization", 1e-2, "uC_per_cm2", "uC/cm2", "uC/cm^2", "µC/cm2", "µC/cm^2",
       "μC/cm²", "μC/cm2"),
    _u("C", "c", "charge", 1.0),
    _u("mC", "mc", "charge", 1e-3),
    _u("µC", "uc", "charge", 1e-6, "uC", "μC"),
    _u("nC", "nc", "charge", 1e-9),
    _u("pC", "pc", "charge", 1e-12),
    # Magnetometers write the moment in SI (A·m²) or cgs (emu = 1e-3 A·m²).
    _u("A·m²", "am2", "magnetic moment", 1.0, "A*m^2", "A*m2", "A·m2", "A.m2", "Am2", "Am^2", "Am²", "A m2",
       "A m^2", "J/T"),
    _u("emu", "emu", "magnetic moment", 1e-3),
    _u("K", "k", "temperature", 1.0),
    _u("°C", "degc", "temperature", 1.0, "degC", "deg C", offset=273.15),
    _u("°F", "degf", "temperature", 5.0 / 9.0, "degF", "deg F", offset=273.15 - 32.0 * 5.0 / 9.0),
    _u("1", "1", "dimensionless", 1.0, "-"),
    _u("%", "pct", "dimensionless", 1e-2, "percent"),
    _u("ppm", "ppm", "dimensionless", 1e-6),
)


def _normal(text: str) -> str:
    """Spelling variants that never change a unit's meaning: brackets around it, surrounding blanks, the
    multiplication dot written as ``*`` or ``·``."""
    s = str(text).strip()
    if len(s) >= 2 and s[0] + s[-1] in ("[]", "()", "{}"):
        s = s[1:-1].strip()
    return s.replace("⋅", "·")


def _names(u: Unit) -> tuple[str, ...]:
    return (u.symbol, *u.aliases)


def _same_prefix(spelling: str, name: str) -> bool:
    """Case may be ignored except where it is the prefix: m (milli) and M (mega) are not the same."""
    return spelling[:1] == name[:1] or spelling[:1] not in "mM"


def unit(text: str | Unit, *, dimension: str | None = None, what: str | None = None) -> Unit:
    """The registered unit spelled ``text`` (optionally restricted to ``dimension``). ``what`` names the column
    or quantity in the error message. Unknown or ambiguous spellings are a ``BmrError``."""
    if isinstance(text, Unit):
        return text
    if not isinstance(text, str):
        raise TypeError(f"unit must be a string, got {type(text).__name__}")
    s = _normal(text)
    pool = [u for u in UNITS if dimension is None or u.dimension == dimension]
    exact = [u for u in pool if s in _names(u)]
    if not exact:
        low = s.lower()
        exact = list({u.symbol: u for u in pool
                      if any(low == n.lower() and _same_prefix(s, n) for n in _names(u))}.values())
    where = f"{what}: " if what else ""
    if len(exact) == 1:
        return exact[0]
    if len(exact) > 1:
        raise BmrError(f"{where}unit {text!r} is ambiguous ({', '.join(u.symbol for u in exact)}); "
                       "write it with its exact case")
    if dimension is not None:
        raise BmrError(f"{where}unknown {dimension} unit {text!r}; use one of {', '.join(units_of(dimension))}")
    raise BmrError(f"{where}unknown unit {text!r}; known units: {', '.join(u.symbol for u in UNITS)}")


def units_of(dimension: str) -> list[str]:
    """Symbols of the registered units of ``dimension``."""
    out = [u.symbol for u in UNITS if u.dimension == dimension]
    if not out:
        raise BmrError(f"unknown dimension {dimension!r}; known: {', '.join(DIMENSION_QUANTITY)}")
    return out


def convert(values: Any, from_unit: str | Unit, to_unit: str | Unit, *, what: str | None = None) -> np.ndarray:
    """``values`` given in ``from_unit`` expressed in ``to_unit`` (same dimension). ``what`` (e.g. the column)
    is named in the error when the units do not convert."""
    a = unit(from_unit, what=what)
    b = unit(to_unit, what=what)
    x = np.asarray(values, dtype=float)
    if a == b:
        return x
    if a.dimension != b.dimension:
        where = f"{what}: " if what else ""
        raise BmrError(f"{where}unit {a.symbol} ({a.dimension}) does not convert to {b.symbol} ({b.dimension})")
    if a.offset == 0.0 and b.offset == 0.0:
        return x * (a.scale / b.scale)
    return b.from_si(a.to_si(x))


def format_number(x: float, digits: int = 3) -> str:
    """``x`` with ``digits`` significant digits: plain between 0.01 and 1e5, otherwise ``1.37e-3`` (no padded
    exponent)."""
    if not math.isfinite(x):
        return str(x)
    if x == 0 or 1e-2 <= abs(x) < 1e5:
        exponent = math.floor(math.log10(abs(x))) if x else 0
        if exponent >= digits:  # 14300, not 1.43e+04
            return f"{round(x, digits - 1 - exponent):.0f}"
        return f"{x:.{digits}g}"
    mantissa, exponent = f"{x:.{max(digits - 1, 0)}e}".split("e")
    if "." in mantissa:
        mantissa = mantissa.rstrip("0").rstrip(".")
    return f"{mantissa}e{int(exponent)}"


def format_value(x: float, unit_symbol: str | Unit | None, digits: int = 3) -> str:
    """``x`` and its unit, e.g. ``"2.36 N·mm"``, ``"1.37e-3 T"``, ``"0.45 %"``."""
    text = format_number(float(x), digits)
    if unit_symbol is None:
        return text
    sym = unit_symbol.symbol if isinstance(unit_symbol, Unit) else str(unit_symbol)
    return text if sym == "1" else f"{text} {sym}"


def _check_registry(units: Iterable[Unit]) -> None:
    """Every spelling names one unit (import-time guard against registry typos)."""
    seen: dict[str, str] = {}
    for u in units:
        for n in _names(u):
            if n in seen and seen[n] != u.symbol:
                raise AssertionError(f"unit spelling {n!r} names both {seen[n]} and {u.symbol}")
            seen[n] = u.symbol


_check_registry(UNITS)
