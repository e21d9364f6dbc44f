"""A probe of ``/diagnostics``: every status a test's node hears, in order and by name."""

from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus


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
        node.create_subscription(DiagnosticArray, "/diagnostics", self.on_message, depth)

    def named(self, name: str) -> list[DiagnosticStatus]:
        """Every status of ``name`` heard, in order: a live list that grows as they come."""
        if name not in self._by_name:  # the statuses heard so far, then each as it comes
            self._by_name[name] = [s for s in self.statuses if s.name == name]
        return self._by_name[name]

    def on_message(self, msg: DiagnosticArray) -> None:
        """Keep each status of one message."""
        self.arrays.append(msg)
        for s in msg.status:
            self.statuses.append(s)
            self.latest[s.name] = s
            if s.name in self._by_name:
                self._by_name[s.name].append(s)
