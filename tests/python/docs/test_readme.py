"""The README says what was measured: its generated sections equal the record in docs/measurements.json (written
by the bench scripts), and every figure section names the command that measures it."""
from __future__ import annotations

import re

from repo_scripts import load_script


def _script():
    return load_script("benches/readme_figures.py")


def test_generated_sections_match_the_measurements():
    assert _script().main(["check"]) == 0


def test_generated_sections_are_closed_and_known():
    script = _script()
    seen: list[str] = []
    for doc in script.DOCUMENTS:
        text = doc.read_text()
        opened = re.findall(r"<!-- generated: (\w+) -->", text)
        closed = re.findall(r"<!-- end: (\w+) -->", text)
        assert opened == closed, doc
        assert set(opened) <= set(script.RENDER), doc
        seen += opened
    assert len(seen) == len(set(seen)), "a generated section stands in two documents"
