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


def replace_marked(path: str | Path, body: str, mark: str, end: str | None = None) -> Path:
    """Put ``body`` between the markers ``mark`` and ``end`` (default ``mark``) of a file.

    The rest of the file is left alone; a file without the markers (or none at all) gets
    the body appended with them. Written atomically (:func:`write_text_atomic`).

    This is how the benchmarks and studies keep their tables in docs/benchmarks.md and
    docs/world-model.md beside the hand-written text.
    """
    p = Path(path)
    end = end or mark
    text = p.read_text(encoding="utf-8") if p.exists() else ""
    block = f"{mark}\n{body.strip(chr(10))}\n{end}"
    start = text.find(mark)
    stop = text.find(end, start + len(mark)) if start >= 0 else -1
    if stop >= 0:
        text = text[:start] + block + text[stop + len(end) :]
    else:
        text = (text.rstrip("\n") + "\n\n" if text.strip() else "") + block + "\n"
    return write_text_atomic(p, text)
