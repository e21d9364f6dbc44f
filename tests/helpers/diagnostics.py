"""A probe of ``/diagnostics``: every status a test's node hears, in order and by name."""

from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus


class DiagnosticsProbe:
    """Subscribes ``/diagnostics`` on ``node``.

    Attributes:
        statuses: Every status heard, in the order heard.
        latest: The newest status of each name (``/localizer``, ``/robot_0/executor``, ...).
    """

    def __init__(self, node, depth: int = 50) -> None:
        self.statuses: list[DiagnosticStatus] = []
        self.latest: dict[str, DiagnosticStatus] = {}
        node.create_subscription(DiagnosticArray, "/diagnostics", self.on_message, depth)

    def on_message(self, msg: DiagnosticArray) -> None:
        """Keep each status of one message."""
        for s in msg.status:
            self.statuses.append(s)
            self.latest[s.name] = s
