"""The continuous simulator's step barrier: when ``dynamics`` starts and takes its next step.

What :class:`excavation_sim.lockstep.TickClock` is to the grid simulator, :class:`StepClock`
is to ``dynamics``: pure (no ``rclpy``), fed the wall time (seconds, monotonic) and each
robot's commands, answering what to do next; the node moves messages and integrates.

* **Start**: once every robot's executor is present for ``startup_period`` wall seconds.
* **Step**: when every robot waited for has answered the current step (a command stamped
  with it or later) and the time factors allow (:meth:`StepClock.due`); or, when one has
  not answered within ``command_timeout``, as a late step: the silent robots are *lagging*
  and are not waited for until a command of theirs arrives.
* **Time factors**: ``time_factor`` puts the steps on a fixed schedule of wall time (step
  ``i`` after the schedule's origin is due ``i * dt / factor`` after it, so the time a step
  takes does not add up; more than :data:`SCHEDULE_SLACK` behind, the schedule starts over
  rather than bursting); ``max_time_factor`` (robots moving) and ``idle_time_factor`` (all
  standing) hold each step at least ``dt / factor`` after the last.
* **Silent robots**: a robot whose last command is older than ``cmd_vel_timeout`` of sim
  time is stopped (the base's deadman, as diff_drive_controller's ``cmd_vel_timeout``) and
  not waited for until it commands again (:meth:`StepClock.silent`).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

SCHEDULE_SLACK = 0.05
"""Wall seconds a ``time_factor`` step may fall behind its schedule before the schedule
starts over from it: small, so that catching up never bursts more than a step or two of sim
time past nodes that judge heartbeats on it."""


class Next(enum.Enum):
    """What :meth:`StepClock.poll` asks of the node."""

    WAIT = "wait"
    START = "start"  # publish the state of step 0
    STEP = "step"  # integrate one step and publish its state


@dataclass
class StepClock:
    """The step barrier of ``dynamics`` (module docstring).

    Attributes:
        robots: Team size.
        dt_ns: Sim nanoseconds per step.
        command_timeout: Wall seconds a step waits for every robot's command.
        cmd_vel_timeout: Sim seconds after a robot's last command when it is stopped.
        startup_period: Wall seconds the team must be present before step 0.
        time_factor, max_time_factor, idle_time_factor: The clock's limits against real
            time (0: none).
        now_ns: Sim time of the current step.
        steps: Steps taken.
        late: Steps taken without every robot's answer.
        started: Step 0 was published.
    """

    robots: int
    dt_ns: int
    command_timeout: float
    cmd_vel_timeout: float
    startup_period: float
    time_factor: float = 0.0
    max_time_factor: float = 0.0
    idle_time_factor: float = 0.0
    now_ns: int = 0
    steps: int = 0
    late: int = 0
    started: bool = False
    ready_since: float | None = None
    wait_started: float = 0.0
    schedule: tuple[float, int] | None = None  # (wall, sim ns): time_factor's origin
    answered: set[int] = field(default_factory=set)
    lagging: set[int] = field(default_factory=set)  # silent past a step's command_timeout
    timed_out: set[int] = field(default_factory=set)  # stopped for silence
    command_ns: list[int | None] = field(default_factory=list)  # sim time of each last command

    def __post_init__(self) -> None:
        if not self.command_ns:
            self.command_ns = [None] * self.robots

    def poll(self, wall: float, present: bool, moving: bool) -> Next:
        """Start once the team has been ``present``; step when due or when a robot is late.

        Args:
            wall: Wall seconds now.
            present: Every robot's executor is on the graph (read before the start only).
            moving: Some robot is commanded to move (the time factors' choice).
        """
        if not self.started:
            if not present:
                self.ready_since = None
                return Next.WAIT
            if self.ready_since is None:
                self.ready_since = wall
            if wall - self.ready_since >= self.startup_period:
                self.started = True
                return Next.START
            return Next.WAIT
        if self.all_answered() and self.due(wall, moving):
            return Next.STEP
        if wall - self.wait_started > self.command_timeout:
            self.late += 1
            self.lagging |= set(range(self.robots)) - self.answered - self.timed_out
            return Next.STEP
        return Next.WAIT

    def on_command(self, k: int, stamp_ns: int, wall: float, moving: bool) -> tuple[bool, bool]:
        """Robot k commanded (stamped ``stamp_ns``): ``(heard again, step now)``.

        ``heard again``: it had been stopped for silence; ``step now``: its answer was the
        last the current step waited for and the step is due.
        """
        self.command_ns[k] = self.now_ns
        self.lagging.discard(k)
        again = k in self.timed_out
        self.timed_out.discard(k)
        if self.started and stamp_ns >= self.now_ns:
            self.answered.add(k)
            return again, self.all_answered() and self.due(wall, moving)
        return again, False

    def all_answered(self) -> bool:
        """Every robot answered this step, except those not waited for (silent or lagging)."""
        return len(self.answered | self.timed_out | self.lagging) >= self.robots

    def due(self, wall: float, moving: bool) -> bool:
        """False while a time factor holds the clock back (module docstring)."""
        factors = [
            self.time_factor,
            self.max_time_factor if moving else self.idle_time_factor,
        ]
        factors = [f for f in factors if f > 0]
        if not factors:
            return True
        factor = min(factors)
        if factor == self.time_factor:
            return self._on_schedule(wall, factor)
        self.schedule = None
        return wall - self.wait_started >= self.dt_ns * 1e-9 / factor

    def _on_schedule(self, wall: float, factor: float) -> bool:
        """``time_factor`` governs: the next step is due on a fixed schedule of wall time."""
        origin = self.schedule
        if origin is None:
            self.schedule = origin = (self.wait_started, self.now_ns)
        due = origin[0] + (self.now_ns + self.dt_ns - origin[1]) * 1e-9 / factor
        if wall - due > SCHEDULE_SLACK:
            self.schedule = (wall, self.now_ns + self.dt_ns)
        return wall >= due

    def silent(self) -> list[int]:
        """Robots to stop now: silent for more than ``cmd_vel_timeout`` of sim time.

        Each is reported once, and not waited for until it commands again.
        """
        limit = int(round(self.cmd_vel_timeout * 1e9))
        out = []
        for k, at in enumerate(self.command_ns):
            if at is None or k in self.timed_out or self.now_ns - at <= limit:
                continue
            self.timed_out.add(k)
            out.append(k)
        return out

    def stepped(self) -> None:
        """One step was integrated."""
        self.now_ns += self.dt_ns
        self.steps += 1

    def published(self, wall: float) -> None:
        """The current step's state went out: its answers start again from none."""
        self.answered.clear()
        self.wait_started = wall
