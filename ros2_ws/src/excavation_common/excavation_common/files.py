"""Small file helpers shared by every package."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


_UMASK = _umask()


def write_text_atomic(path: str | Path, text: str) -> Path:
    """Write ``text`` so that readers see the old file or the new one, never a mix.

    A temporary file in the same folder is written, flushed and fsynced, then renamed over
    ``path``. A crash (even ``kill -9``) leaves the previous file intact. The new file gets
    the permissions ``open()`` would give it (``0666`` less the umask at import).
    """
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=p.parent, prefix=f".{p.name}.", suffix=".tmp")
    try:
        os.fchmod(fd, 0o666 & ~_UMASK)
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, p)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return p
