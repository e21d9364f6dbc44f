"""Waiting on something outside ROS (a file, a process, a server) without spinning a node."""

from __future__ import annotations

import time
from collections.abc import Callable


def poll_until(condition: Callable[[], object], timeout: float, period: float = 0.2) -> bool:
    """Call ``condition`` every ``period`` s until it is true; its last answer after
    ``timeout`` s (so a condition met just at the deadline still counts)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(period)
    return bool(condition())
