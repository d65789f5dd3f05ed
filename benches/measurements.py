"""The measurements behind every figure in the README, in one file (``docs/measurements.json``).

Each bench script that measures something a user reads records it here with :func:`record`: the section name,
the exact command that measured it, the values, the machine and the date. ``benches/readme_figures.py render``
turns the file into the README's generated sections and ``... check`` (run by the tests) fails when the README
no longer says what the file holds, so a figure cannot be edited by hand or drift from its measurement.
"""
from __future__ import annotations

import datetime as _dt
import json
import os
import platform
import tempfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
FILE = ROOT / "docs" / "measurements.json"

__all__ = ["FILE", "ROOT", "load", "machine", "record"]


def machine() -> dict[str, Any]:
    """What the figures were measured on (timings depend on it; instruction counts do not)."""
    cpu = ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"cpus": os.cpu_count(), "cpu": cpu or platform.processor(), "system": platform.system(),
            "python": platform.python_version()}


def load() -> dict[str, Any]:
    if not FILE.is_file():
        return {}
    return json.loads(FILE.read_text())


def record(section: str, command: str, values: dict[str, Any]) -> None:
    """Store one section's measurement (replacing the previous one), written atomically."""
    data = load()
    data[section] = {"command": command, "measured": _dt.date.today().isoformat(), "machine": machine(),
                     "values": values}
    text = json.dumps(data, indent=1, sort_keys=True) + "\n"
    FILE.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".measurements.", dir=FILE.parent)
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, FILE)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
