"""A stand-in servo board speaking the blade protocol on a pseudo-terminal.

``ros2 run blade_driver fake_board`` opens a pseudo-terminal, prints its path, and answers
the driver as the robot's board would: the servo slews towards its set-point at
``--speed`` degrees per second, and the load cell reads a spring-like soil force that grows
as the blade edge goes below the soil surface. Point the driver at the printed path::

    ros2 run blade_driver fake_board            # prints e.g. /dev/pts/5
    ros2 run blade_driver driver --ros-args -p backend:=serial -p port:=/dev/pts/5

The tests run it in a thread on ``os.openpty()``; faults (dropped answers, bad checksums)
can be injected to exercise the driver's error handling.
"""

from __future__ import annotations

import argparse
import os
import select
import sys
import threading
import time
from dataclasses import dataclass, field

import numpy as np

from blade_driver.errors import BoardError
from blade_driver.protocol import ServoCalibration, decode, encode


@dataclass
class FakeBoard:
    """Servo and load-cell model behind the protocol.

    Attributes:
        calibration: Angle <-> blade position, as the driver's.
        speed: Servo slew rate (deg/s); ``inf`` moves at once.
        soil_surface: Blade position (m) at which the edge touches the soil.
        stiffness: Force per metre the edge is below the surface (N/m).
        noise: Standard deviation of the load-cell noise (N).
        seed: Seed of the noise.
        drop_every: Leave every n-th request unanswered (0: never).
        corrupt_every: Answer every n-th request with a wrong checksum (0: never).
        home_deg: The angle a set-point timeout sends the servo to (the blade home).
        timeout: The set-point timeout the host armed (``TIMEOUT``), s; 0: off.
        timeouts: Set-point timeouts that fired.
        timed_out: Set each time the set-point timeout fires (what a test waits on).
    """

    calibration: ServoCalibration = field(default_factory=ServoCalibration)
    speed: float = float("inf")
    soil_surface: float = 0.0
    stiffness: float = 400.0
    noise: float = 0.0
    seed: int = 0
    drop_every: int = 0
    corrupt_every: int = 0
    angle: float = 150.0
    target: float = 150.0
    home_deg: float = 150.0
    timeout: float = 0.0
    timeouts: int = 0
    timed_out: threading.Event = field(default_factory=threading.Event)
    requests: int = 0
    set_points: list[float] = field(default_factory=list)
    _rng: np.random.Generator | None = None
    _last: float | None = None
    _last_set: float | None = None

    def __post_init__(self) -> None:
        self._rng = np.random.default_rng(self.seed)

    def _advance(self, now: float) -> None:
        self.check_timeout(now)
        if self._last is not None:
            step = self.speed * (now - self._last)
            self.angle = min(self.angle + step, max(self.angle - step, self.target))
        self._last = now

    def check_timeout(self, now: float) -> None:
        """The set-point timeout: no ``SET`` for ``timeout`` s sends the servo home."""
        if not self.timeout or self._last_set is None or now - self._last_set <= self.timeout:
            return
        if self.target != self.home_deg:
            self.timeouts += 1
        self.target = self.home_deg
        self.timed_out.set()
        if self.speed == float("inf"):
            self.angle = self.home_deg
        self._last_set = None  # fired: the next SET takes over again

    def force(self) -> float:
        """The load-cell reading for the current blade position (N, never negative)."""
        depth = self.soil_surface - self.calibration.position(self.angle)
        noise = float(self._rng.normal(0.0, self.noise)) if self.noise else 0.0
        return max(0.0, self.stiffness * max(0.0, depth) + noise)

    def handle(self, line: bytes, now: float) -> bytes:
        """The answer to one request line (``b""`` when this request is dropped)."""
        self.requests += 1
        self._advance(now)
        if self.drop_every and self.requests % self.drop_every == 0:
            return b""
        try:
            request = decode(line, "fake_board")
        except BoardError as exc:
            return encode("ERR", "1", str(exc).split(": ", 1)[-1].replace("*", ""))
        if request == ["PING"]:
            reply = encode("PONG", "fake_board/1")
        elif request == ["READ"]:
            reply = encode("STATE", f"{self.angle:.2f}", f"{self.force():.3f}")
        elif len(request) == 2 and request[0] == "SET":
            try:
                angle = float(request[1])
            except ValueError:
                return encode("ERR", "2", "angle is not a number")
            c = self.calibration
            if not c.min_deg <= angle <= c.max_deg:
                return encode("ERR", "3", f"angle {angle} outside [{c.min_deg}, {c.max_deg}]")
            self.target = angle
            self.set_points.append(angle)
            self._last_set = now
            if self.speed == float("inf"):
                self.angle = angle
            reply = encode("ACK", "SET", request[1])
        elif len(request) == 2 and request[0] == "TIMEOUT":
            if not request[1].isdigit():
                return encode("ERR", "2", "timeout is not a whole number of ms")
            self.timeout = int(request[1]) / 1000.0
            self._last_set = now if self.timeout else None
            reply = encode("ACK", "TIMEOUT", request[1])
        else:
            return encode("ERR", "4", "unknown request")
        if self.corrupt_every and self.requests % self.corrupt_every == 0:
            reply = reply[:-3] + b"00\n" if not reply.endswith(b"00\n") else reply[:-3] + b"01\n"
        return reply

    def serve(self, fd: int, stop=lambda: False) -> None:
        """Answer requests arriving on file descriptor ``fd`` until ``stop()`` is true."""
        buffer = b""
        while not stop():
            ready, _, _ = select.select([fd], [], [], 0.05)
            if not ready:
                self.check_timeout(time.monotonic())
                continue
            try:
                chunk = os.read(fd, 1024)
            except OSError:
                return
            if not chunk:
                return
            buffer += chunk
            while b"\n" in buffer:
                line, buffer = buffer.split(b"\n", 1)
                reply = self.handle(line + b"\n", time.monotonic())
                if reply:
                    os.write(fd, reply)


def open_pty() -> tuple[int, str]:
    """A raw pseudo-terminal pair: ``(master fd, slave path)``."""
    import tty

    master, slave = os.openpty()
    tty.setraw(slave)
    tty.setraw(master)
    return master, os.ttyname(slave)


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ros2 run blade_driver fake_board``."""
    p = argparse.ArgumentParser(prog="fake_board", description=__doc__.split("\n\n")[0])
    p.add_argument("--speed", type=float, default=120.0, help="servo slew rate, deg/s")
    p.add_argument("--soil-surface", type=float, default=0.0, help="m")
    p.add_argument("--stiffness", type=float, default=400.0, help="N/m")
    p.add_argument("--noise", type=float, default=0.1, help="load-cell noise, N")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    board = FakeBoard(
        speed=args.speed,
        soil_surface=args.soil_surface,
        stiffness=args.stiffness,
        noise=args.noise,
        seed=args.seed,
    )
    master, path = open_pty()
    print(path, flush=True)
    try:
        board.serve(master)
    except KeyboardInterrupt:
        pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
