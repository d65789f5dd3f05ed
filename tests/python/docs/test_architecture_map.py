"""docs/architecture.md is the one map of the tree: every Rust and Python module has its row, under its folder."""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]


def _sections() -> dict[str, str]:
    text = (ROOT / "docs" / "architecture.md").read_text()
    parts = re.split(r"^### `([^`]+)/`\s*$", text, flags=re.M)
    return {parts[i]: parts[i + 1] for i in range(1, len(parts), 2)}


def test_every_module_of_the_tree_is_on_the_map():
    sections = _sections()
    missing = []
    for pattern, root in (("*.rs", "src"), ("*.py", "python/bmr")):
        for path in sorted((ROOT / root).rglob(pattern)):
            folder = path.parent.relative_to(ROOT).as_posix()
            if f"| `{path.name}` |" not in sections.get(folder, ""):
                missing.append(path.relative_to(ROOT).as_posix())
    assert not missing, f"modules without a row in docs/architecture.md §8: {missing}"


def test_the_map_names_no_module_that_is_gone():
    gone = []
    for folder, body in _sections().items():
        for name in re.findall(r"^\| `([^`/]+\.(?:rs|py))` \|", body, flags=re.M):
            if not (ROOT / folder / name).is_file():
                gone.append(f"{folder}/{name}")
    assert not gone, f"docs/architecture.md §8 names modules that do not exist: {gone}"


def test_the_readme_serves_its_reader():
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) <= 250
    for link in re.findall(r"\]\(((?:docs/)?[\w./-]+\.(?:md|png))(?:#[\w-]+)?\)", readme):
        assert (ROOT / link).is_file(), link
    for doc in (ROOT / "docs").glob("*.md"):
        for link in re.findall(r"\]\(([\w./-]+\.(?:md|png))(?:#[\w-]+)?\)", doc.read_text()):
            assert (doc.parent / link).is_file(), f"{doc.name}: {link}"
