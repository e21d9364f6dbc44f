"""When to try the servo board's serial port again (pure; no rclpy, no pyserial).

A port that is absent (the board unplugged, the USB adapter not enumerated yet) or that
failed mid-run is reopened with exponential back-off: the first retry after ``initial``
seconds, each failure doubling the wait up to ``maximum``; a success resets it. The node
reports the attempts, the last error and the next retry on ``/diagnostics``.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class Backoff:
    """Exponential back-off between attempts to open a port.

    Attributes:
        initial: Seconds before the first retry.
        maximum: Longest wait between two attempts.
        factor: Growth of the wait per failure.
        failures: Failed attempts since the last success.
        next_attempt: Time of the next attempt (``None``: now).
    """

    initial: float = 0.5
    maximum: float = 5.0
    factor: float = 2.0
    failures: int = 0
    next_attempt: float | None = None

    def __post_init__(self) -> None:
        if not 0 < self.initial <= self.maximum:
            raise ValueError(f"back-off: need 0 < initial ({self.initial}) <= maximum")
        if self.factor < 1:
            raise ValueError(f"back-off: factor = {self.factor}: must be >= 1")

    def due(self, now: float) -> bool:
        """An attempt may be made at ``now``."""
        return self.next_attempt is None or now >= self.next_attempt

    def wait(self) -> float:
        """Seconds the next failure will make the driver wait."""
        return min(self.maximum, self.initial * self.factor**self.failures)

    def failed(self, now: float) -> float:
        """An attempt at ``now`` failed; returns the seconds until the next one."""
        delay = self.wait()
        self.failures += 1
        self.next_attempt = now + delay
        return delay

    def succeeded(self) -> None:
        """The port is open: the next failure starts from ``initial`` again."""
        self.failures = 0
        self.next_attempt = None
