"""Progress bars that suit both a terminal and a log file.

:class:`tqdm` is ``tqdm.tqdm`` with one change: when its output is not a terminal (a CI
log, ``make demo > demo.log``, a background run), it writes one plain line per
``LOG_INTERVAL`` seconds (and the last), instead of redrawing one line with carriage
returns, which a log keeps as a single line of thousands of characters. Rate and ETA are
tqdm's own. Every long-running command of the project takes its bar from here.
"""

from __future__ import annotations

import sys

from tqdm import tqdm as _tqdm

LOG_INTERVAL = 30.0
"""Seconds between a bar's lines when its output is not a terminal."""


class _Lines:
    """A stream that turns tqdm's redraws (a carriage return, then the bar) into lines."""

    def __init__(self, stream) -> None:
        self.stream = stream

    def write(self, text: str) -> None:
        for part in text.replace("\r", "\n").split("\n"):
            if part.strip():
                self.stream.write(part.rstrip() + "\n")

    def flush(self) -> None:
        self.stream.flush()


class tqdm(_tqdm):  # noqa: N801 - a drop-in for tqdm.tqdm
    """``tqdm.tqdm`` that writes plain lines, at most every ``LOG_INTERVAL`` s, to a log."""

    def __init__(self, *args, **kwargs) -> None:
        stream = kwargs.get("file") or sys.stderr
        if not _isatty(stream):
            kwargs["file"] = _Lines(stream)
            kwargs.setdefault("mininterval", LOG_INTERVAL)
            kwargs["maxinterval"] = max(kwargs.get("maxinterval", 10.0), kwargs["mininterval"])
            kwargs.setdefault("ascii", True)
            kwargs.setdefault("ncols", 100)
        super().__init__(*args, **kwargs)


def _isatty(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False
