"""A blade servo board, as the blade driver's ``serial`` backend talks to it (pure).

:class:`ServoBoard` answers the wire protocol of docs/blade-driver.md ("Wire protocol"),
encoded and decoded by the blade driver's own :mod:`blade_driver.protocol` (one
definition of the protocol), with the board-side behaviour of
:class:`blade_driver.fake_board.FakeBoard`:

* ``PING`` -> ``PONG <firmware>``; ``SET <deg>`` -> ``ACK SET <deg>`` (echoing the text);
  ``READ`` -> ``STATE <deg> <N>``; a bad checksum, a bad number, an angle outside the
  servo's range and an unknown request -> ``ERR 1..4 <text>``;
* the servo slews towards its set-point at ``speed`` degrees per second (0: at once);
* ``TIMEOUT <ms>`` -> ``ACK TIMEOUT <ms>`` arms the set-point timeout: no ``SET`` for that
  long sends the servo to ``start_angle`` (the blade home), as the firmware must;
* the load cell reads the push force of the simulated world's blade (``force_source:
  world``) or the fake board's spring-like soil force below ``soil_surface``
  (``spring``), plus seeded Gaussian noise, never below zero;
* faults on demand: every ``drop_every``-th request unanswered, every
  ``corrupt_every``-th answer with a wrong checksum.

Unlike the fake board, its servo moves the simulated world's blade: :meth:`world_command`
returns the blade position the servo is at (:class:`MoveBlade`) whenever it changed, and
every ``refresh`` seconds anyway, for the node to send to ``dynamics``. Times are seconds
of one monotonic clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from blade_driver.errors import BoardError
from blade_driver.protocol import ServoCalibration, decode, encode
from excavation_common.params import param

WORLD = "world"
SPRING = "spring"


@dataclass(frozen=True)
class ServoBoardParams:
    """The emulated board's parameters (the servo calibration is the blade driver's)."""

    joint: str = param("blade", "the blade joint's name in world/plant_state")
    firmware: str = param("dome_emulator/1", "the firmware name PING is answered with")
    speed: float = param(120.0, "servo slew rate, deg/s (0: at once)", low=0.0, high=1e5)
    start_angle: float = param(
        150.0, "servo angle at power-up, deg (150: the blade home)", low=-360.0, high=360.0
    )
    servo_zero_deg: float = param(90.0, "servo angle of the blade level, deg", low=-360.0)
    servo_deg_per_m: float = param(600.0, "servo degrees per metre of blade travel")
    servo_min_deg: float = param(0.0, "lowest angle the board accepts, deg", low=-360.0)
    servo_max_deg: float = param(180.0, "highest angle the board accepts, deg", high=360.0)
    force_source: str = param(
        WORLD,
        "load cell: world (the simulated blade's push force, world/plant_state) or spring "
        "(the fake board's soil spring below soil_surface)",
        choices=(WORLD, SPRING),
    )
    soil_surface: float = param(
        0.0, "spring: blade position where the edge meets the soil, m", low=-1.0, high=1.0
    )
    stiffness: float = param(400.0, "spring: force per metre below the surface, N/m", low=0.0)
    noise: float = param(0.1, "load-cell noise (std), N", low=0.0, high=100.0)
    seed: int = param(0, "seed of the load-cell noise", low=0, high=2**63 - 1)
    drop_every: int = param(
        0, "leave every n-th request unanswered (0: never)", low=0, high=10**9, read_only=False
    )
    corrupt_every: int = param(
        0,
        "answer every n-th request with a wrong checksum (0: never)",
        low=0,
        high=10**9,
        read_only=False,
    )
    rate: float = param(50.0, "servo model updates per second", low=1.0, high=1000.0)
    refresh: float = param(
        1.0, "s between world/servo_command messages while the servo stands", low=0.01
    )
    path_file: str = param("", "file the pseudo-terminal's path is written to (empty: none)")
    link: str = param("", "a symlink to the pseudo-terminal, as a stable port name (empty: none)")
    diagnostics_period: float = param(1.0, "s between diagnostics", low=0.05, high=3600.0)

    def calibration(self) -> ServoCalibration:
        """The servo's angle <-> blade position map."""
        return ServoCalibration(
            self.servo_zero_deg, self.servo_deg_per_m, self.servo_min_deg, self.servo_max_deg
        )

    def check(self) -> None:
        """A servo range that holds the power-up angle; a non-zero calibration slope."""
        if self.servo_deg_per_m == 0.0:
            raise ValueError("servo_deg_per_m must not be 0")
        if not self.servo_min_deg <= self.start_angle <= self.servo_max_deg:
            raise ValueError(
                f"start_angle {self.start_angle} outside [servo_min_deg {self.servo_min_deg}, "
                f"servo_max_deg {self.servo_max_deg}]"
            )


@dataclass(frozen=True)
class Reply:
    """The bytes the board writes back for one request (a whole protocol line)."""

    data: bytes


@dataclass(frozen=True)
class Dropped:
    """The request is left unanswered (``drop_every``)."""


@dataclass(frozen=True)
class MoveBlade:
    """The simulated world's blade goes to ``position`` metres (where the servo is)."""

    position: float


Answer = Reply | Dropped


class ServoBoard:
    """The board's state machine (module docstring)."""

    def __init__(self, params: ServoBoardParams, now: float) -> None:
        """A board powered up at ``now`` with its servo at ``start_angle``."""
        self.params = params
        self.calibration = params.calibration()
        self.rng = np.random.default_rng(params.seed)
        self.angle = float(params.start_angle)  # where the servo is, deg
        self.target = float(params.start_angle)  # its set-point, deg
        self.last = now  # when the servo was last moved on
        self.now = now  # the time of the request being answered
        self.world_force: float | None = None  # the simulated blade's push force, N
        self.sent: tuple[float, float] | None = None  # (position, time) last sent to the world
        self.timeout = 0.0  # the set-point timeout the host armed, s (0: off)
        self.last_set: float | None = None  # when the last SET came (None: none pending)
        self.timeouts = 0
        self.requests = 0
        self.set_points = 0
        self.refused = 0
        self.dropped = 0
        self.corrupted = 0

    def set_params(self, params: ServoBoardParams) -> None:
        """New parameters at runtime (only the faults are settable: the rest is unchanged)."""
        self.params = params

    def advance(self, now: float) -> None:
        """Move the servo on towards its set-point until ``now`` (the timeout first)."""
        if self.timeout and self.last_set is not None and now - self.last_set > self.timeout:
            if self.target != self.params.start_angle:
                self.timeouts += 1
            self.target = float(self.params.start_angle)
            self.last_set = None
        speed = self.params.speed
        if speed == 0.0:
            self.angle = self.target
        elif now > self.last:
            step = speed * (now - self.last)
            self.angle = min(self.angle + step, max(self.angle - step, self.target))
        self.last = max(self.last, now)

    def position(self) -> float:
        """The blade position the servo is at, metres."""
        return self.calibration.position(self.angle)

    def force(self) -> float:
        """The load cell's reading, N (never negative)."""
        p = self.params
        if p.force_source == WORLD:
            value = self.world_force or 0.0
        else:
            value = p.stiffness * max(0.0, p.soil_surface - self.position())
        if p.noise:
            value += float(self.rng.normal(0.0, p.noise))
        return max(0.0, value)

    def handle(self, line: bytes, now: float) -> Answer:
        """The answer to one request line (with its newline)."""
        self.requests += 1
        self.advance(now)
        self.now = now
        p = self.params
        if p.drop_every and self.requests % p.drop_every == 0:
            self.dropped += 1
            return Dropped()
        try:
            request = decode(line, "servo_board")
        except BoardError as exc:
            self.refused += 1
            return Reply(encode("ERR", "1", str(exc).split(": ", 1)[-1].replace("*", "")))
        reply = self._answer(request)
        if p.corrupt_every and self.requests % p.corrupt_every == 0:
            self.corrupted += 1
            good = reply[-3:-1]
            reply = reply[:-3] + (b"01" if good == b"00" else b"00") + b"\n"
        return Reply(reply)

    def _answer(self, request: list[str]) -> bytes:
        """The answer line to a decoded request."""
        if request == ["PING"]:
            return encode("PONG", self.params.firmware)
        if request == ["READ"]:
            return encode("STATE", f"{self.angle:.2f}", f"{self.force():.3f}")
        if len(request) == 2 and request[0] == "SET":
            try:
                angle = float(request[1])
            except ValueError:
                self.refused += 1
                return encode("ERR", "2", "angle is not a number")
            c = self.calibration
            if not (math.isfinite(angle) and c.min_deg <= angle <= c.max_deg):
                self.refused += 1
                return encode("ERR", "3", f"angle {angle} outside [{c.min_deg}, {c.max_deg}]")
            self.target = angle
            self.set_points += 1
            self.last_set = self.now
            if self.params.speed == 0.0:
                self.angle = angle
            return encode("ACK", "SET", request[1])
        if len(request) == 2 and request[0] == "TIMEOUT":
            if not request[1].isdigit():
                self.refused += 1
                return encode("ERR", "2", "timeout is not a whole number of ms")
            self.timeout = int(request[1]) / 1000.0
            self.last_set = self.now if self.timeout else None
            return encode("ACK", "TIMEOUT", request[1])
        self.refused += 1
        return encode("ERR", "4", "unknown request")

    def set_world_force(self, force: float) -> None:
        """The simulated blade's push force (``world/plant_state`` effort), N."""
        if math.isfinite(force):
            self.world_force = float(force)

    def world_command(self, now: float) -> MoveBlade | None:
        """Where the world's blade must go, when the servo moved or ``refresh`` has passed."""
        self.advance(now)
        position = self.position()
        if self.sent is not None:
            last_position, last_time = self.sent
            if position == last_position and now - last_time < self.params.refresh:
                return None
        self.sent = (position, now)
        return MoveBlade(position)
