"""Files written atomically, output paths checked before work starts, JSON read with clear errors, and paths
contained in a folder. Every file bmr writes goes through :func:`write_atomic`: a reader (or a crash, a full disk,
a file-size limit) never leaves a half-written file in place of the previous one.
"""
from __future__ import annotations

import dataclasses
import json
import math
import os
import tempfile
from pathlib import Path
from typing import IO, Any, Callable

import numpy as np

from bmr._core import BmrError

__all__ = ["check_output_file", "check_output_folder", "contained", "jsonable", "read_json", "write_atomic", "write_json",
           "write_text"]


def write_atomic(path: str | Path, write: Callable[[IO[bytes]], None], *, what: str = "file",
                 error: type[BmrError] = BmrError) -> Path:
    """Call ``write(fh)`` on a temporary file in ``path``'s folder, flush and fsync it, then rename it over
    ``path``. On any failure the temporary file is removed, the previous ``path`` (if any) is untouched, and an
    ``OSError`` becomes ``error`` naming ``what`` and the file."""
    p = Path(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent if str(p.parent) else ".")
    except OSError as exc:
        raise error(f"cannot write {what} {str(p)!r}: {exc.strerror or exc}") from None
    try:
        with os.fdopen(fd, "wb") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, p)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise error(f"cannot write {what} {str(p)!r}: {exc.strerror or exc}") from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return p


def write_text(path: str | Path, text: str, *, what: str = "file", error: type[BmrError] = BmrError) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically (see :func:`write_atomic`)."""
    data = text.encode("utf-8")
    return write_atomic(path, lambda fh: fh.write(data), what=what, error=error)


def jsonable(x: Any) -> Any:
    """``x`` made JSON-safe, the one rule for every file bmr writes: dataclasses and mappings to objects with string
    keys, tuples and numpy arrays to lists, numpy scalars to Python numbers, non-finite floats to ``None`` (files
    say "not computed" as null; readers turn it back into NaN or infinity where the field documents it)."""
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        return {f.name: jsonable(getattr(x, f.name)) for f in dataclasses.fields(x)}
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (np.floating, float)):
        v = float(x)
        return v if math.isfinite(v) else None
    if isinstance(x, np.integer):
        return int(x)
    return x


def write_json(path: str | Path, content: Any, *, what: str = "file", error: type[BmrError] = BmrError) -> Path:
    """Write ``content`` (made :func:`jsonable`) as indented JSON, atomically."""
    return write_text(path, json.dumps(jsonable(content), indent=1, allow_nan=False) + "\n", what=what, error=error)


def path_kind(path: str | Path, what: str, *, error: type[BmrError] = BmrError) -> str:
    """``"folder"``, ``"file"``, ``"other"`` (a device, a socket) or ``"missing"`` for ``path``; a name the file
    system refuses (too long for it, ...) is an ``error`` naming ``what``, not an ``OSError``."""
    p = Path(path)
    try:
        if p.is_dir():
            return "folder"
        if p.is_file():
            return "file"
        return "other" if p.exists() else "missing"
    except OSError as exc:
        raise error(f"{what} {str(p)!r} cannot be opened: {exc.strerror or exc}") from None


def _writable_folder(folder: Path, shown: Path, what: str, error: type[BmrError]) -> None:
    # The nearest existing ancestor must be a folder we may write into (the rest is created).
    existing = folder
    while not existing.exists():
        if existing.parent == existing:
            break
        existing = existing.parent
    if existing.exists() and not existing.is_dir():
        raise error(f"{what} {str(shown)!r}: {str(existing)!r} is a file, not a folder")
    if existing.exists() and not os.access(existing, os.W_OK | os.X_OK):
        raise error(f"{what} {str(shown)!r}: no permission to write in {str(existing)!r}")


def check_output_file(path: str | Path, what: str = "output file", *, error: type[BmrError] = BmrError) -> Path:
    """Fail now (not after the work) if ``path`` cannot be written: it is a folder, its folder is a file, or the
    folder is not writable. Nothing is created."""
    p = Path(path)
    if path_kind(p, what, error=error) == "folder":
        raise error(f"{what} {str(p)!r} is a folder, not a file")
    _writable_folder(p.parent if str(p.parent) else Path("."), p, what, error)
    if p.exists() and not os.access(p, os.W_OK):
        raise error(f"{what} {str(p)!r}: no permission to overwrite it")
    return p


def check_output_folder(path: str | Path, what: str = "output folder", *,
                        error: type[BmrError] = BmrError) -> Path:
    """Fail now if ``path`` cannot be an output folder: it is a file, an ancestor is a file, or the nearest
    existing ancestor is not writable. Nothing is created."""
    p = Path(path)
    if path_kind(p, what, error=error) not in ("folder", "missing"):
        raise error(f"{what} {str(p)!r} is a file, not a folder")
    _writable_folder(p, p, what, error)
    return p


def read_json(path: str | Path, what: str, *, error: type[BmrError] = BmrError) -> Any:
    """Parse the JSON file ``path``; every problem (unreadable, not UTF-8, invalid JSON, nested too deeply) is an
    ``error`` naming the file. UTF-8 with or without a byte-order mark is read; UTF-16/32 files (with a BOM) are
    decoded as such."""
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise error(f"{what} {str(p)!r} cannot be read: {exc.strerror or exc}") from None
    try:
        text = _decode(raw)
    except UnicodeDecodeError as exc:
        raise error(f"{what} {str(p)!r} is not UTF-8 text (byte {exc.start}: {raw[exc.start:exc.start + 1]!r}); "
                    "save it as UTF-8") from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise error(f"{str(p)!r}: not a valid {what} (JSON error: {exc})") from None
    except RecursionError:
        raise error(f"{what} {str(p)!r}: JSON nested too deeply to be a {what}") from None


def _decode(raw: bytes) -> str:
    for bom, codec in ((b"\xef\xbb\xbf", "utf-8-sig"), (b"\xff\xfe\x00\x00", "utf-32"), (b"\x00\x00\xfe\xff", "utf-32"),
                       (b"\xff\xfe", "utf-16"), (b"\xfe\xff", "utf-16")):
        if raw.startswith(bom):
            return raw.decode(codec)
    return raw.decode("utf-8")


def contained(root: str | Path, relative: Any, what: str, *, error: type[BmrError] = BmrError) -> Path:
    """``root / relative`` if it stays inside ``root`` after resolving ``..`` and symbolic links; otherwise an
    ``error`` that does not say whether the outside file exists. ``relative`` must be a relative path string."""
    if not isinstance(relative, str) or not relative:
        raise error(f"{what}: expected a file name (a string), got {relative!r}")
    if "\x00" in relative or Path(relative).is_absolute() or Path(relative).drive:
        raise error(f"{what} {relative!r} is not a path inside the folder")
    base = Path(root).resolve()
    try:
        target = (base / relative).resolve()
    except (OSError, RuntimeError):  # symlink loops
        raise error(f"{what} {relative!r} is not a path inside the folder") from None
    if target != base and base not in target.parents:
        raise error(f"{what} {relative!r} is not a path inside the folder")
    return target
