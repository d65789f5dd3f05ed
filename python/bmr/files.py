"""Writing files atomically: the text goes to a temporary file in the same folder, which is then renamed over the
target, so that a reader (or a firmware build) never sees a half-written model, export or report."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

from bmr._core import BmrError

__all__ = ["write_text_atomic"]


def write_text_atomic(path: str | Path, text: str, *, what: str = "file") -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically; an OS error is a ``BmrError`` naming ``what`` and the path."""
    p = Path(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent)
    except OSError as exc:
        raise BmrError(f"cannot write {what} {str(p)!r}: {exc.strerror or exc}") from None
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, p)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise BmrError(f"cannot write {what} {str(p)!r}: {exc.strerror or exc}") from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return p
