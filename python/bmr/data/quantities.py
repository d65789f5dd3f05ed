"""What a device's signals are: the input and output quantity of a bundle or model, their units and columns.

A hysteretic device maps one input to one output: coil current (A) → torque (N·mm) for the BMR actuator, drive
voltage (V) → displacement (µm) for a piezo stack, current (A) → integrated gradient (T) for a magnet, voltage
(V) → polarization (µC/cm²) for a ferroelectric capacitor. ``Quantities`` declares them; everything a user sees
(tables, figures, reports, JSON) takes names and units from here:

    q = Quantities(Quantity.declare("V", "voltage"), Quantity.declare("um"))
    q.input.label          # 'voltage (V)'
    q.output.format(0.5)   # '0.5 µm'
    q.describe()           # 'voltage (V) → displacement (µm)'

Time is always seconds in column ``t_s``; an angle (the actuator's rotor angle, needed for seal friction) is
optional and always radians in ``theta_rad``. ``output_sigma`` optionally names a column with the standard
uncertainty of each output sample (same unit as the output). ``ACTUATOR`` is the mapping of ``bmr-bundle/1``.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from bmr._core import BmrError
from bmr.data.units import DIMENSION_QUANTITY, Unit, convert, format_value, unit

__all__ = ["Quantity", "Quantities", "ACTUATOR", "TIME", "ANGLE", "column_name"]

_COLUMN = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


def column_name(name: str, unit_symbol: str) -> str:
    """The bundle column of a quantity: its name and unit as an identifier, e.g. ``displacement_um``,
    ``integrated_gradient_t``, ``torque_nmm``."""
    base = re.sub(r"[^a-z0-9]+", "_", name.lower()).strip("_") or "value"
    slug = unit(unit_symbol).slug
    return f"{base}_{slug}" if slug != "1" else base


@dataclass(frozen=True)
class Quantity:
    """A named physical quantity in one unit, stored in one bundle column."""

    name: str
    unit: str
    column: str

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.strip():
            raise BmrError(f"a quantity needs a name, got {self.name!r}")
        canonical = unit(self.unit, what=f"quantity {self.name!r}").symbol
        object.__setattr__(self, "unit", canonical)
        if not isinstance(self.column, str) or not _COLUMN.match(self.column):
            raise BmrError(f"quantity {self.name!r}: column {self.column!r} must be an identifier "
                           "(letters, digits, underscores)")

    @classmethod
    def declare(cls, unit_text: str, name: str | None = None, column: str | None = None) -> "Quantity":
        """A quantity in ``unit_text``; ``name`` defaults to the dimension's usual name (V → voltage, µm →
        displacement), ``column`` to :func:`column_name`."""
        u = unit(unit_text, what=f"quantity {name!r}" if name else None)
        name = name or DIMENSION_QUANTITY[u.dimension]
        return cls(name, u.symbol, column or column_name(name, u.symbol))

    @property
    def dimension(self) -> str:
        return unit(self.unit).dimension

    @property
    def label(self) -> str:
        """Axis label and table heading: ``"displacement (µm)"``."""
        return f"{self.name} ({self.unit})"

    def format(self, x: float, digits: int = 3) -> str:
        """A value of this quantity with its unit: ``"1.37e-3 T"``."""
        return format_value(x, self.unit, digits)

    def from_unit(self, values: Any, source_unit: str | Unit, *, what: str | None = None) -> np.ndarray:
        """``values`` given in ``source_unit`` expressed in this quantity's unit."""
        return convert(values, source_unit, self.unit, what=what or f"{self.name} ({self.column})")

    def to_dict(self) -> dict[str, str]:
        return {"name": self.name, "unit": self.unit, "column": self.column}

    @classmethod
    def from_dict(cls, value: Any, where: str) -> "Quantity":
        if not isinstance(value, dict) or not all(isinstance(value.get(k), str) for k in ("name", "unit", "column")):
            raise BmrError(f"{where} must be an object with string 'name', 'unit' and 'column'")
        try:
            return cls(value["name"], value["unit"], value["column"])
        except BmrError as exc:
            raise BmrError(f"{where}: {exc}") from None


TIME = Quantity("time", "s", "t_s")
ANGLE = Quantity("angle", "rad", "theta_rad")


@dataclass(frozen=True)
class Quantities:
    """A device's input and output (and optionally its rotor angle and the output's per-sample sigma)."""

    input: Quantity
    output: Quantity
    angle: Quantity | None = None
    output_sigma: Quantity | None = None

    def __post_init__(self) -> None:
        if self.angle is not None and self.angle != ANGLE:
            raise BmrError(f"the angle is stored in radians in column 'theta_rad', got {self.angle}")
        if self.output_sigma is not None and self.output_sigma.unit != self.output.unit:
            raise BmrError(f"output sigma must be in the output's unit {self.output.unit}, "
                           f"got {self.output_sigma.unit}")
        cols = self.columns
        dupes = sorted({c for c in cols if cols.count(c) > 1})
        if dupes:
            raise BmrError(f"quantities share column(s) {', '.join(dupes)}: input, output, sigma, time and angle "
                           "need distinct columns")

    @property
    def time(self) -> Quantity:
        return TIME

    @property
    def columns(self) -> list[str]:
        """The columns every run of a bundle with these quantities has."""
        cols = [TIME.column, self.input.column, self.output.column]
        if self.angle is not None:
            cols.append(self.angle.column)
        if self.output_sigma is not None:
            cols.append(self.output_sigma.column)
        return cols

    @property
    def is_actuator(self) -> bool:
        """The BMR actuator's mapping (current A → torque N·mm, angle rad): what ``bmr-bundle/1`` stores."""
        return self == ACTUATOR

    def describe(self) -> str:
        """``"voltage (V) → displacement (µm)"``."""
        return f"{self.input.label} → {self.output.label}"

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"input": self.input.to_dict(), "output": self.output.to_dict()}
        if self.output_sigma is not None:
            out["output_sigma"] = self.output_sigma.to_dict()
        out["angle"] = self.angle.to_dict() if self.angle is not None else None
        return out

    @classmethod
    def from_dict(cls, value: Any, where: str) -> "Quantities":
        if not isinstance(value, dict):
            raise BmrError(f"{where} must be an object with 'input' and 'output'")
        for key in ("input", "output"):
            if key not in value:
                raise BmrError(f"{where} has no {key!r}")
        angle = value.get("angle")
        sigma = value.get("output_sigma")
        try:
            return cls(Quantity.from_dict(value["input"], f"{where}.input"),
                       Quantity.from_dict(value["output"], f"{where}.output"),
                       Quantity.from_dict(angle, f"{where}.angle") if angle is not None else None,
                       Quantity.from_dict(sigma, f"{where}.output_sigma") if sigma is not None else None)
        except BmrError as exc:
            msg = str(exc)
            raise BmrError(msg if msg.startswith(where) else f"{where}: {msg}") from None


ACTUATOR = Quantities(Quantity("current", "A", "current_a"), Quantity("torque", "N·mm", "torque_nmm"), ANGLE)
