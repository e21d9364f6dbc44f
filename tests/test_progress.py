"""Progress bars: redrawn on a terminal, whole lines at intervals in a log."""

from __future__ import annotations

import io

from excavation_common.progress import tqdm


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_log_gets_plain_lines_and_the_last_one():
    log = io.StringIO()
    for _ in tqdm(range(1000), file=log, unit="step", mininterval=0.0):
        pass
    text = log.getvalue()
    assert "\r" not in text
    lines = text.splitlines()
    assert lines and all(line.strip() for line in lines)
    assert "1000/1000" in lines[-1] and "step/s" in lines[-1]


def test_a_log_gets_a_line_per_interval_not_per_update():
    log = io.StringIO()
    for _ in tqdm(range(100_000), file=log):
        pass
    assert len(log.getvalue().splitlines()) <= 3  # the first, perhaps one more, the last


def test_a_terminal_keeps_the_redrawn_bar():
    term = _Terminal()
    for _ in tqdm(range(1000), file=term, mininterval=0.0):
        pass
    assert "\r" in term.getvalue()
