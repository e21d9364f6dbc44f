"""A probe of ``/diagnostics``: every status a test's node hears, in order and by name."""

from __future__ import annotations

import time
from typing import NamedTuple

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus


def values(status: DiagnosticStatus) -> dict[str, str]:
    """A status's key-value pairs as a dict."""
    return {v.key: v.value for v in status.values}


class Heard(NamedTuple):
    """One status as heard: when it arrived, its message's stamp and its values."""

    wall: float
    """``time.monotonic()`` when the message arrived."""
    stamp: float
    """The message header's stamp, seconds (the sender's clock: sim time on a sim clock)."""
    values: dict[str, str]


class DiagnosticsProbe:
    """Subscribes ``/diagnostics`` on ``node``.

    Attributes:
        statuses: Every status heard, in the order heard.
        latest: The newest status of each name (``/localizer``, ``/robot_0/executor``, ...).
        arrays: Every message heard (each a ``DiagnosticArray``), in order.
    """

    def __init__(self, node, depth: int = 50) -> None:
        self.statuses: list[DiagnosticStatus] = []
        self.latest: dict[str, DiagnosticStatus] = {}
        self.arrays: list[DiagnosticArray] = []
        self._by_name: dict[str, list[DiagnosticStatus]] = {}
        self._heard: list[Heard] = []  # parallel to ``statuses``
        node.create_subscription(DiagnosticArray, "/diagnostics", self.on_message, depth)

    def named(self, name: str) -> list[DiagnosticStatus]:
        """Every status of ``name`` heard, in order: a live list that grows as they come."""
        if name not in self._by_name:  # the statuses heard so far, then each as it comes
            self._by_name[name] = [s for s in self.statuses if s.name == name]
        return self._by_name[name]

    def heard(self, match) -> list[Heard]:
        """Every status whose name ``match(name)`` accepts, as :class:`Heard`, in order."""
        return [h for s, h in zip(self.statuses, self._heard, strict=True) if match(s.name)]

    def on_message(self, msg: DiagnosticArray) -> None:
        """Keep each status of one message."""
        wall = time.monotonic()
        stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        self.arrays.append(msg)
        for s in msg.status:
            self.statuses.append(s)
            self._heard.append(Heard(wall, stamp, values(s)))
            self.latest[s.name] = s
            if s.name in self._by_name:
                self._by_name[s.name].append(s)
