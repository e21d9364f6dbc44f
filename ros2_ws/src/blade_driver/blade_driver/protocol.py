"""The wire protocol between the blade driver and the servo board (docs/blade-driver.md).

ASCII lines at 115200 baud, 8N1, each ``BODY*CS`` plus a newline, where ``CS`` is the XOR
of the body's bytes as two upper-case hex digits (the NMEA 0183 checksum). The host sends
one request and waits for its answer before the next:

=================  =======================  ==========================================
host               board                    meaning
=================  =======================  ==========================================
``PING``           ``PONG <firmware>``      link check
``SET <deg>``      ``ACK SET <deg>``        servo angle set-point, degrees, 2 decimals
``READ``           ``STATE <deg> <N>``      measured servo angle and load-cell force
``TIMEOUT <ms>``   ``ACK TIMEOUT <ms>``     set-point timeout: no ``SET`` for ``<ms>``
                                            sends the servo to its home angle (0: off)
(any)              ``ERR <code> <text>``    the board refused the request
=================  =======================  ==========================================

The set-point timeout is the board's own stop: the driver sends ``SET`` every control
step, so a board that hears none for the timeout has lost its host (a crashed driver, a
dead robot computer, a cut cable) and retracts the blade by itself. Firmware that does
not know ``TIMEOUT`` answers ``ERR 4``; the driver then reports that the board has no
timeout and runs on.

This module is pure: it turns requests and replies into bytes and back.
"""

from __future__ import annotations

from dataclasses import dataclass

from blade_driver.errors import BoardError


def checksum(body: bytes) -> str:
    """The two-digit XOR checksum of a line body."""
    value = 0
    for b in body:
        value ^= b
    return f"{value:02X}"


def encode(*fields: object) -> bytes:
    """One protocol line from its fields, with its checksum and newline."""
    body = " ".join(str(f) for f in fields).encode("ascii")
    return body + b"*" + checksum(body).encode("ascii") + b"\n"


def decode(line: bytes, source: str = "<serial>") -> list[str]:
    """The fields of one received line, after checking its checksum.

    Raises:
        BoardError: An empty line (timeout), a missing or wrong checksum, or non-ASCII bytes.
    """
    if not line:
        raise BoardError(f"{source}: no answer from the servo board (timeout)")
    if not line.endswith(b"\n"):
        raise BoardError(f"{source}: incomplete line {line!r} (timeout mid-line)")
    text = line.rstrip(b"\r\n")
    body, star, cs = text.rpartition(b"*")
    if not star:
        raise BoardError(f"{source}: line {line!r} has no checksum")
    if cs.decode("ascii", "replace").upper() != checksum(body):
        raise BoardError(
            f"{source}: line {line!r}: checksum {cs.decode('ascii', 'replace')} != {checksum(body)}"
        )
    try:
        return body.decode("ascii").split()
    except UnicodeDecodeError as exc:
        raise BoardError(f"{source}: line {line!r} is not ASCII") from exc


@dataclass(frozen=True)
class ServoCalibration:
    """Linear map between blade position (m, as on ``blade/joint_states``) and servo angle.

    Attributes:
        zero_deg: Servo angle with the blade edge level with the wheels.
        deg_per_m: Servo degrees per metre of blade travel (negative if the horn is reversed).
        min_deg: Lowest angle the board accepts.
        max_deg: Highest angle the board accepts.
    """

    zero_deg: float = 90.0
    deg_per_m: float = 600.0
    min_deg: float = 0.0
    max_deg: float = 180.0

    def angle(self, position: float) -> float:
        """Servo angle (deg) for a blade position, clipped to the servo's range."""
        return min(self.max_deg, max(self.min_deg, self.zero_deg + self.deg_per_m * position))

    def position(self, angle: float) -> float:
        """Blade position (m) for a servo angle."""
        return (angle - self.zero_deg) / self.deg_per_m
