"""Closed-loop motion primitives, in the manner of nav2's DriveOnHeading and Spin behaviours.

A primitive is a small object: :meth:`Primitive.on_run` takes the pose at its start,
computes the target (the next cell centre, or the next cardinal heading) and rejects a bad
start; :meth:`Primitive.on_cycle_update` runs one control step on a new pose and returns
``RUNNING``, ``SUCCEEDED`` or ``FAILED`` with the twist to send. Before each step the
primitive checks its time allowance and its progress (the remaining error must shrink by
``min_progress`` every ``progress_window`` seconds): a stalled or blocked robot fails the
primitive instead of pushing forever.

Geometry follows :mod:`excavation_common.frames`: a robot's pose is its centre (the shared
corner of its 2 x 2 footprint) and yaw in ``map``; grid headings 0 N, 1 E, 2 S, 3 W.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

from drive_executor.errors import GoalError
from drive_executor.params import ExecutorParams
from excavation_common.constants import HEADING_STEPS
from excavation_common.frames import heading_to_yaw, robot_anchor, robot_center, yaw_to_heading


class Status(Enum):
    """Result of one control step (nav2's ``Status``)."""

    RUNNING = "running"
    SUCCEEDED = "succeeded"
    FAILED = "failed"


@dataclass(frozen=True)
class Pose2D:
    """A robot pose in ``map``: centre (m) and yaw (rad)."""

    x: float
    y: float
    yaw: float

    def finite(self) -> bool:
        """True when every field is finite."""
        return all(math.isfinite(v) for v in (self.x, self.y, self.yaw))


@dataclass(frozen=True)
class Twist2D:
    """A body-frame command: forward speed (m/s) and yaw rate (rad/s, counter-clockwise)."""

    linear: float = 0.0
    angular: float = 0.0


STOP = Twist2D()


@dataclass(frozen=True)
class Limits:
    """Speed and acceleration limits of one primitive (throttle-up raises the speeds)."""

    speed: float
    accel: float
    turn_rate: float
    turn_accel: float

    @classmethod
    def of(cls, params: ExecutorParams, throttle: bool) -> Limits:
        """The limits for the normal or the high-power (Throttle Up) mode."""
        return cls(
            params.throttle_speed if throttle else params.max_speed,
            params.max_accel,
            params.throttle_turn_rate if throttle else params.max_turn_rate,
            params.max_turn_accel,
        )


def wrap(angle: float) -> float:
    """An angle in ``(-pi, pi]``."""
    return math.atan2(math.sin(angle), math.cos(angle))


def _ramp(target: float, previous: float, accel: float, dt: float, limit: float) -> float:
    """``target`` clipped to ``+-limit`` and to ``accel * dt`` away from ``previous``."""
    target = max(-limit, min(limit, target))
    step = accel * dt
    return max(previous - step, min(previous + step, target))


def _brake(error: float, accel: float, limit: float) -> float:
    """The speed toward ``error`` that can still stop in time (trapezoidal profile)."""
    return math.copysign(min(limit, math.sqrt(2.0 * accel * abs(error))), error)


class Primitive:
    """Base class: time allowance, progress check, twist continuity.

    Subclasses implement :meth:`_start` (the target) and :meth:`_step` (one control step
    returning the remaining error and the twist, or ``None`` when done).
    """

    name = "primitive"

    def __init__(self, params: ExecutorParams, limits: Limits) -> None:
        self.params: ExecutorParams = params
        """The executor's parameters (tolerances, gains, time allowance)."""
        self.limits: Limits = limits
        """Speed and acceleration limits."""
        self.started: float | None = None
        """Time :meth:`on_run` started it (moved on by a pause; ``None``: not started)."""
        self.check_time: float = 0.0
        """Time the progress window began."""
        self.check_error: float = math.inf
        """The error left when the progress window began."""
        self.last_time: float | None = None
        """Time of the last control step."""
        self.last_twist: Twist2D = STOP
        """The twist of the last control step (the ramps start from it)."""
        self.failure: str = ""
        """Why it failed (empty: it has not)."""

    def on_run(self, pose: Pose2D, now: float) -> None:
        """Start from ``pose`` at time ``now`` (s).

        Raises:
            GoalError: A non-finite pose.
        """
        if not pose.finite():
            raise GoalError("<pose>", self.name, (pose.x, pose.y, pose.yaw), "must be finite")
        self.started = now
        self.check_time = now
        self.last_time = now
        self.last_twist = STOP
        self._start(pose)
        self.check_error = self.remaining(pose)

    def on_cycle_update(self, pose: Pose2D, now: float) -> tuple[Status, Twist2D]:
        """One control step on a new pose: the status and the twist to send."""
        if self.started is None:
            raise RuntimeError(f"{self.name}: on_cycle_update before on_run")
        if not pose.finite():
            return self._fail(f"{self.name}: non-finite pose")
        error = self.remaining(pose)
        if self.done(pose):
            self.last_twist = STOP
            return Status.SUCCEEDED, STOP
        if now - self.started > self.params.time_allowance:
            return self._fail(
                f"{self.name}: time allowance {self.params.time_allowance} s exceeded"
            )
        if now - self.check_time >= self.params.progress_window:
            if self.check_error - error < self.progress_needed():
                return self._fail(
                    f"{self.name}: no progress in {self.params.progress_window} s "
                    f"({error:.4f} left)"
                )
            self.check_time, self.check_error = now, error
        dt = max(0.0, min(now - self.last_time, 0.2)) if self.last_time is not None else 0.0
        self.last_time = now
        twist = self._step(pose, dt or 1.0 / self.params.rate)
        self.last_twist = twist
        return Status.RUNNING, twist

    def shift(self, seconds: float) -> None:
        """Move the primitive's clock on by ``seconds`` (it was suspended: a pause).

        The time allowance and the progress window count only the time it ran; it starts
        again from standstill (the robot was stopped).
        """
        if self.started is None:
            return
        self.started += seconds
        self.check_time += seconds
        if self.last_time is not None:
            self.last_time += seconds
        self.last_twist = STOP

    def _fail(self, why: str) -> tuple[Status, Twist2D]:
        self.failure = why
        self.last_twist = STOP
        return Status.FAILED, STOP

    # --- subclass interface ------------------------------------------------------------------

    def _start(self, pose: Pose2D) -> None:
        raise NotImplementedError

    def remaining(self, pose: Pose2D) -> float:
        """The error left (m or rad, >= 0)."""
        raise NotImplementedError

    def done(self, pose: Pose2D) -> bool:
        """True within tolerance of the target."""
        raise NotImplementedError

    def progress_needed(self) -> float:
        """Error reduction required per progress window."""
        raise NotImplementedError

    def _step(self, pose: Pose2D, dt: float) -> Twist2D:
        raise NotImplementedError


class DriveCells(Primitive):
    """Drive forward (``cells`` > 0) or backward (< 0) to a cell centre on the same heading.

    ``cells`` = 0 returns to the centre of the cell the robot stands on (the settle after
    a refused move). The target is fixed at :meth:`on_run`: the footprint anchor nearest
    to the pose plus ``cells`` steps along the nearest cardinal heading. The loop holds the
    heading and steers out cross-track error; speed follows a trapezoidal profile.
    """

    def __init__(self, cells: int, params: ExecutorParams, limits: Limits) -> None:
        super().__init__(params, limits)
        self.cells: int = int(cells)
        """Cells to drive (negative: backward; 0: settle)."""
        self.name: str = {1: "forward", -1: "backward", 0: "settle"}.get(self.cells, "drive")
        """The primitive's name in failures."""
        self.target: tuple[float, float] = (0.0, 0.0)
        """The cell centre to reach (set by :meth:`on_run`)."""
        self.axis: tuple[float, float] = (1.0, 0.0)
        """Unit vector of the heading held."""
        self.yaw: float = 0.0
        """The heading held (rad)."""

    def _start(self, pose: Pose2D) -> None:
        cell = self.params.cell_size
        row, col = robot_anchor(pose.x, pose.y, cell)
        heading = yaw_to_heading(pose.yaw)
        dr, dc = HEADING_STEPS[heading]
        self.target = robot_center(row + self.cells * dr, col + self.cells * dc, cell)
        self.yaw = heading_to_yaw(heading)
        self.axis = (math.cos(self.yaw), math.sin(self.yaw))

    def _errors(self, pose: Pose2D) -> tuple[float, float]:
        """``(along, cross)``: target ahead along the heading; robot left of the line."""
        dx, dy = self.target[0] - pose.x, self.target[1] - pose.y
        ux, uy = self.axis
        return dx * ux + dy * uy, -(-dx * uy + dy * ux)

    def remaining(self, pose: Pose2D) -> float:  # noqa: D102
        return abs(self._errors(pose)[0])

    def done(self, pose: Pose2D) -> bool:  # noqa: D102
        return self.remaining(pose) <= self.params.position_tolerance

    def progress_needed(self) -> float:  # noqa: D102
        return self.params.min_progress

    def _step(self, pose: Pose2D, dt: float) -> Twist2D:
        along, cross = self._errors(pose)
        lim = self.limits
        v = _ramp(
            _brake(along, lim.accel, lim.speed), self.last_twist.linear, lim.accel, dt, lim.speed
        )
        direction = 1.0 if v >= 0 else -1.0
        w = self.params.heading_gain * wrap(self.yaw - pose.yaw) - (
            self.params.cross_track_gain * cross * direction * abs(v) / max(lim.speed, 1e-9)
        )
        w = max(-lim.turn_rate, min(lim.turn_rate, w))
        return Twist2D(v, w)


class Turn(Primitive):
    """Turn in place a quarter turn to the next cardinal heading (right: ``+1``, left: ``-1``)."""

    def __init__(self, direction: int, params: ExecutorParams, limits: Limits) -> None:
        super().__init__(params, limits)
        if direction not in (1, -1):
            raise GoalError("<goal>", "turn", direction, "must be +1 (right) or -1 (left)")
        self.direction: int = direction
        """+1: right, -1: left."""
        self.name: str = "turn right" if direction == 1 else "turn left"
        """The primitive's name in failures."""
        self.target: float = 0.0
        """The yaw to reach (set by :meth:`on_run`)."""

    def _start(self, pose: Pose2D) -> None:
        self.target = heading_to_yaw((yaw_to_heading(pose.yaw) + self.direction) % 4)

    def remaining(self, pose: Pose2D) -> float:  # noqa: D102
        return abs(wrap(self.target - pose.yaw))

    def done(self, pose: Pose2D) -> bool:  # noqa: D102
        return self.remaining(pose) <= self.params.heading_tolerance

    def progress_needed(self) -> float:  # noqa: D102
        return self.params.min_progress * 10.0

    def _step(self, pose: Pose2D, dt: float) -> Twist2D:
        lim = self.limits
        error = wrap(self.target - pose.yaw)
        w = _ramp(
            _brake(error, lim.turn_accel, lim.turn_rate),
            self.last_twist.angular,
            lim.turn_accel,
            dt,
            lim.turn_rate,
        )
        return Twist2D(0.0, w)
