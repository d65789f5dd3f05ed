"""Sample accounting: every fit says how many samples of each run it used and why it did not use the others, so
that nothing is ever dropped silently."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from bmr._core import BmrError

__all__ = ["AT_RANGE_END", "RunSamples", "SampleAccount"]

# Samples an output sensor held at its range end (``bmr.data.signals.output_rails``): no measurement, not fitted.
AT_RANGE_END = "held at the output's range end (the sensor's limit: no measurement)"


@dataclass
class RunSamples:
    """One run: its sample count, how many a fit used, and the others by reason."""

    total: int
    used: int = 0
    dropped: dict[str, int] = field(default_factory=dict)

    @property
    def counted(self) -> int:
        return self.used + sum(self.dropped.values())

    def to_dict(self) -> dict[str, Any]:
        return {"total": self.total, "used": self.used, "dropped": dict(self.dropped)}


@dataclass
class SampleAccount:
    """Samples used and not used, per run and in total. ``check()`` proves that every sample is counted exactly
    once (used, or dropped for a named reason)."""

    runs: dict[str, RunSamples] = field(default_factory=dict)

    def add_run(self, name: str, total: int) -> RunSamples:
        if name in self.runs:
            raise BmrError(f"run {name!r} counted twice")
        self.runs[name] = RunSamples(int(total))
        return self.runs[name]

    def use(self, name: str, n: int) -> None:
        self.runs[name].used += int(n)

    def drop(self, name: str, reason: str, n: int) -> None:
        if n:
            d = self.runs[name].dropped
            d[reason] = d.get(reason, 0) + int(n)

    def merge(self, other: "SampleAccount") -> "SampleAccount":
        """Both accounts together (runs must not overlap)."""
        out = SampleAccount(dict(self.runs))
        for name, r in other.runs.items():
            if name in out.runs:
                raise BmrError(f"run {name!r} counted twice")
            out.runs[name] = r
        return out

    @property
    def total(self) -> int:
        return sum(r.total for r in self.runs.values())

    @property
    def used(self) -> int:
        return sum(r.used for r in self.runs.values())

    @property
    def dropped(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for r in self.runs.values():
            for k, v in r.dropped.items():
                out[k] = out.get(k, 0) + v
        return out

    def check(self) -> "SampleAccount":
        """Raise if any run's samples are not all counted exactly once."""
        for name, r in self.runs.items():
            if r.counted != r.total:
                raise BmrError(f"run {name!r}: {r.total} samples but {r.used} used and "
                               f"{r.counted - r.used} dropped are counted")
        return self

    def to_dict(self) -> dict[str, Any]:
        return {"total": self.total, "used": self.used, "dropped": self.dropped,
                "runs": {k: v.to_dict() for k, v in self.runs.items()}}

    def __repr__(self) -> str:
        drops = ", ".join(f"{v} {k}" for k, v in sorted(self.dropped.items(), key=lambda kv: -kv[1]))
        return (f"SampleAccount({self.used} of {self.total} samples used in {len(self.runs)} runs"
                + (f"; not used: {drops}" if drops else "") + ")")
