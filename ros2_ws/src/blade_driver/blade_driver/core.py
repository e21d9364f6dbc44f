"""The blade driver's logic, without ROS: behaviours to servo set-points (paper, sections 3 and 6).

A robot's controller sends one behaviour word per tick (bit i = behaviour i+1 of Table 2).
Four of the twelve behaviours set the bulldozer blade: above, below, level and home (7-10).
They run in table order within a tick, so the last blade bit set wins, and a word with no
blade bit leaves the blade where it is: the rule the simulator's world model follows.

On top of that nominal setting the driver adds what a real blade needs:

* **Constant-force pushing.** The dome robots trim the blade height with a PID loop so that the
  push force stays constant while they cut or push (blade below or level, moving forward).
  The trim is bounded by ``trim_limit``, less than half the step between two settings, so a
  trimmed blade still reads as the setting the controller chose.
* **Limits.** Set-points are clipped to ``[position_min, position_max]`` and move at most
  ``max_speed`` per second.
* **Watchdog.** No behaviour word for ``watchdog_timeout`` seconds: the blade goes home (no
  soil contact) and stays there until commands return. In a ticked team the seconds are
  the team's tick time (tick ``t`` is stamped ``t`` s), given as ``tick`` to
  :meth:`BladeDriverCore.command` and :meth:`BladeDriverCore.update`: a controller answers
  once per tick, and a dome tick lasts many wall seconds (the drive, the snapshot), so a
  wall-clock watchdog would home the blade in every tick; on tick time it trips after two
  ticks without a word, as in a lockstep trial.
* **Operator override.** A set-point from ``blade/commands`` wins over the controller while it
  is younger than ``override_timeout``.
* **After the drive.** In the field a word's moves take seconds; with ``blade_after_motion``
  the driver keeps the world model's Table 2 order (moves, then the blade: see
  :class:`AfterDrive`) by applying a tick's blade bits only once that tick's drive has
  ended.
* **Hold.** While the team's :class:`~excavation_common.safety.MotionGate` is closed (e-stop,
  pause, disabled robot, lost heartbeat, inactive node) the caller passes the reason as
  ``hold`` and the blade goes home at once (no slew ramp), whatever the controller or the
  operator asks.

Time is whatever the caller passes: wall-clock seconds on hardware, simulated seconds in a
lockstep trial, so the same core is deterministic in both. Time that goes back (a restarted
simulator, a clock reset) starts the core afresh (:meth:`BladeDriverCore.restart`): the old
setting, set-point, override and watchdog belong to another run, so the blade goes home and
waits for new commands, as at start.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

from blade_driver.errors import DriverConfigError
from excavation_common.behaviour import (
    BLADE_ABOVE_CMD,
    BLADE_BELOW_CMD,
    BLADE_HOME_CMD,
    BLADE_LEVEL_CMD,
    MOVE_FORWARD,
)
from excavation_common.constants import (
    BLADE_ABOVE,
    BLADE_BELOW,
    BLADE_HOME,
    BLADE_LEVEL,
    BladeGeometry,
)

BLADE_NAMES = {BLADE_BELOW: "below", BLADE_LEVEL: "level", BLADE_ABOVE: "above", BLADE_HOME: "home"}

# Table 2 order: the last blade behaviour executed in a tick decides the setting.
_BLADE_BITS = (
    (BLADE_ABOVE_CMD, BLADE_ABOVE),
    (BLADE_BELOW_CMD, BLADE_BELOW),
    (BLADE_LEVEL_CMD, BLADE_LEVEL),
    (BLADE_HOME_CMD, BLADE_HOME),
)


def blade_setting(word: int, current: int) -> int:
    """The blade setting after a behaviour word.

    The word's last blade bit in Table 2 order, or ``current`` when it has none.
    """
    setting = current
    for bit, code in _BLADE_BITS:
        if (word >> bit) & 1:
            setting = code
    return setting


Stamp = tuple[int, int]
"""A tick's stamp ``(sec, nanosec)``: the team tick's, on drive goals and statuses alike."""


@dataclass
class AfterDrive:
    """Holds a tick's blade bits until that tick's drive has ended.

    Why this order: the world model (``excavation_sim.world.step_robot``) runs a word's
    behaviours in Table 2 order, Move Forward and Move Backward (the blade cuts and pushes
    with the setting it had when the tick began), then the turns, then the blade commands,
    whose setting the *next* tick's moves use. The continuous simulator commits each move
    through that same model (``excavation_sim.dynamics``). So a blade that moved as soon as
    the word came would cut this tick's move at next tick's setting; moving it once the
    executor reports the tick's drive terminal (``drive/status`` SUCCEEDED, ABORTED or
    CANCELED, stamped with the tick) reproduces the model. A word of a tick whose drive has
    already ended (a word without motion: the executor answers at once) applies at once.

    Words are released in their order: a later tick's end releases the held words of
    earlier ticks too (an executor that never reported a tick does not lose its blade bits
    for good, and they still apply before the later word's). Pure: no ``rclpy``.
    """

    done: Stamp | None = None
    held: list[tuple[Stamp, int]] = field(default_factory=list)

    def word(self, tick: Stamp, word: int) -> list[int]:
        """The controller's word of ``tick``: the words to apply now (oldest first).

        Several words of one tick (a controller that repeats itself) hold as one: the last
        with blade bits, as applying them all in order would leave it.
        """
        word = int(word)
        if self.held and self.held[-1][0] == tick:
            if blade_setting(word, -1) == -1:
                word = self.held[-1][1]  # no blade bits: the held word still decides
            self.held[-1] = (tick, word)
        else:
            self.held.append((tick, word))
        return self._release()

    def drive_ended(self, tick: Stamp) -> list[int]:
        """The drive goal of ``tick`` ended: the words now released (oldest first)."""
        if self.done is None or tick > self.done:
            self.done = tick
        return self._release()

    def holding(self) -> bool:
        """A word's blade bits wait for their tick's drive."""
        return bool(self.held)

    def _release(self) -> list[int]:
        out = []
        while self.held and self.done is not None and self.held[0][0] <= self.done:
            out.append(self.held.pop(0)[1])
        return out


@dataclass(frozen=True)
class DriverParams:
    """Parameters of the blade driver (ROS parameters of the same names).

    Attributes:
        depth: Blade edge below / above the wheels for the "below" / "above" settings (m).
        home: Blade edge height when retracted (m).
        max_force: Push force (N) of a full blade (24 soil units; the dome robots: 10 N).
        position_min: Lowest set-point the blade mechanism allows (m).
        position_max: Highest set-point (m).
        max_speed: Largest set-point change per second (m/s).
        push_force: Force the constant-force loop holds while pushing (N).
        kp: Proportional gain of the force loop (m per N).
        ki: Integral gain (m per N s).
        kd: Derivative gain (m s per N).
        trim_limit: Largest trim the force loop may add to a setting (m); must stay below
            half the distance between neighbouring settings.
        watchdog_timeout: Seconds without a behaviour word before the blade goes home.
        override_timeout: Seconds an operator set-point stays in charge.
    """

    depth: float = 0.02
    home: float = 0.10
    max_force: float = 10.0
    position_min: float = -0.03
    position_max: float = 0.12
    max_speed: float = 0.25
    push_force: float = 6.0
    kp: float = 0.0008
    ki: float = 0.002
    kd: float = 0.0
    trim_limit: float = 0.008
    watchdog_timeout: float = 1.5
    override_timeout: float = 0.5

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not math.isfinite(value):
                raise DriverConfigError("<parameters>", f.name, value, "must be finite")
        positive = ("depth", "home", "max_force", "max_speed", "watchdog_timeout")
        for name in positive + ("override_timeout",):
            if getattr(self, name) <= 0:
                raise DriverConfigError("<parameters>", name, getattr(self, name), "must be > 0")
        for name in ("push_force", "kp", "ki", "kd", "trim_limit"):
            if getattr(self, name) < 0:
                raise DriverConfigError("<parameters>", name, getattr(self, name), "must be >= 0")
        if self.home <= self.depth:
            raise DriverConfigError("<parameters>", "home", self.home, "must be above `depth`")
        if not self.position_min <= -self.depth or not self.position_max >= self.home:
            raise DriverConfigError(
                "<parameters>",
                "position_min/position_max",
                (self.position_min, self.position_max),
                f"must include every setting, [-{self.depth}, {self.home}]",
            )
        if self.trim_limit >= self.depth / 2:
            raise DriverConfigError(
                "<parameters>",
                "trim_limit",
                self.trim_limit,
                f"must be below half the step between settings ({self.depth / 2})",
            )

    @property
    def geometry(self) -> BladeGeometry:
        """The joint positions of the four settings, as the message conventions define them."""
        return BladeGeometry(self.depth, self.home, self.max_force)


@dataclass
class Pid:
    """A PID loop with a clamped output and a clamped integrator (no wind-up).

    ``update(error, dt)`` returns ``kp e + ki sum(e dt) + kd de/dt`` clipped to
    ``[-limit, limit]``; the integral term alone is held within the same bounds, so it never
    winds up beyond what the output can use.
    """

    kp: float
    ki: float
    kd: float
    limit: float
    integral: float = 0.0
    previous: float | None = None

    def update(self, error: float, dt: float) -> float:
        """One step of the loop; ``dt`` in seconds (0 skips the integral and derivative)."""
        derivative = 0.0
        if dt > 0 and self.previous is not None:
            derivative = (error - self.previous) / dt
        self.previous = error
        self.integral += error * dt
        if self.ki > 0:
            bound = self.limit / self.ki
            self.integral = min(bound, max(-bound, self.integral))
        out = self.kp * error + self.ki * self.integral + self.kd * derivative
        return min(self.limit, max(-self.limit, out))

    def reset(self) -> None:
        """Forget the integral and the last error."""
        self.integral = 0.0
        self.previous = None


@dataclass
class DriverState:
    """What the driver is doing now (reported on ``/diagnostics``)."""

    setting: int = BLADE_HOME
    setpoint: float = 0.10
    trim: float = 0.0
    source: str = "startup"
    watchdog_tripped: bool = False
    last_command: float | None = None
    last_command_tick: float | None = None
    override: float | None = None
    override_time: float | None = None
    clipped: int = 0


@dataclass
class BladeDriverCore:
    """Turns behaviour words, operator set-points and force readings into blade set-points.

    Call ``command(word, now)`` for each behaviour word, ``override(position, now)`` for each
    operator set-point, and ``update(now, force)`` once per control step; ``update`` returns
    the set-point to send to the servo. ``now`` is in seconds (wall or simulated).
    """

    params: DriverParams = field(default_factory=DriverParams)
    state: DriverState = field(default_factory=DriverState)
    pushing: bool = False
    restarts: int = 0
    _pid: Pid | None = None
    _last_update: float | None = None

    def __post_init__(self) -> None:
        p = self.params
        self._pid = Pid(p.kp, p.ki, p.kd, p.trim_limit)
        self.state.setpoint = p.home

    def set_params(self, params: DriverParams) -> None:
        """New parameters at run time (the force loop's gains and limit take effect now)."""
        self.params = params
        pid = self._pid
        pid.kp, pid.ki, pid.kd, pid.limit = params.kp, params.ki, params.kd, params.trim_limit

    def went_back(self, now: float) -> bool:
        """``now`` is earlier than a time the core has already seen."""
        s = self.state
        seen = (self._last_update, s.last_command, s.override_time)
        return any(t is not None and now < t for t in seen)

    def restart(self) -> None:
        """Start afresh, as at construction (time went back: another run begins).

        The setting and the set-point go home, the watchdog and the override are forgotten,
        the force loop resets and the next :meth:`update` has no rate limit; only the
        ``clipped`` count survives. ``restarts`` counts the restarts.
        """
        self.state = DriverState(setpoint=self.params.home, clipped=self.state.clipped)
        self.pushing = False
        self._pid.reset()
        self._last_update = None
        self.restarts += 1

    def _follow(self, now: float) -> None:
        if self.went_back(now):
            self.restart()

    def command(self, word: int, now: float, blade: bool = True, tick: float | None = None) -> None:
        """A behaviour word from the controller.

        ``blade=False``: the word's blade bits wait (:class:`AfterDrive`; apply them later
        with :meth:`apply_blade`); the word still feeds the watchdog and says whether the
        robot pushes (the force loop runs while it drives). ``tick``: the team's tick time
        of the word (s), which the watchdog then counts in (module docstring).
        """
        self._follow(now)
        if blade:
            self.apply_blade(word)
        self.pushing = bool((int(word) >> MOVE_FORWARD) & 1)
        self.state.last_command = now
        self.state.last_command_tick = tick
        self.state.watchdog_tripped = False

    def apply_blade(self, word: int) -> None:
        """Set the blade as the word's blade bits say (none: the blade stays)."""
        self.state.setting = blade_setting(int(word), self.state.setting)

    def override(self, position: float, now: float) -> None:
        """An operator set-point (m); clipped to the limits (counted in ``state.clipped``)."""
        p = self.params
        if not math.isfinite(position):
            raise DriverConfigError("blade/commands", "data[0]", position, "must be finite")
        self._follow(now)
        clipped = min(p.position_max, max(p.position_min, float(position)))
        if clipped != position:
            self.state.clipped += 1
        self.state.override = clipped
        self.state.override_time = now

    def override_active(self, now: float) -> bool:
        """An operator set-point younger than ``override_timeout``."""
        t = self.state.override_time
        return t is not None and now - t <= self.params.override_timeout

    def watchdog_due(self, now: float, tick: float | None = None) -> bool:
        """Commands stopped for longer than ``watchdog_timeout`` (none yet does not count).

        On tick time when both the last word and ``tick`` (the team's current tick) have
        one; on ``now`` otherwise.
        """
        s = self.state
        if tick is not None and s.last_command_tick is not None:
            return tick - s.last_command_tick > self.params.watchdog_timeout
        return s.last_command is not None and now - s.last_command > self.params.watchdog_timeout

    def needs_no_controller(self, now: float) -> bool:
        """The set-point at ``now`` does not wait for a behaviour word (override or watchdog)."""
        return self.override_active(now) or self.watchdog_due(now)

    def update(
        self, now: float, force: float | None, hold: str | None = None, tick: float | None = None
    ) -> float:
        """Advance to time ``now`` with the measured push force (N, None if unknown).

        Args:
            now: Seconds (wall or simulated).
            force: Measured push force, N, or ``None``.
            hold: Why the robot must stand still (the MotionGate's reason), or ``None``.
                A hold sends the blade home at once (no ``max_speed`` ramp: the servo moves
                at its own speed); it beats the operator and the controller.
            tick: The team's current tick time (s), or ``None``: what the watchdog counts
                in (:meth:`watchdog_due`).

        Returns:
            The servo set-point (m), within the limits; after the first call and unless
            held it moves at most ``max_speed * (now - previous now)``. A ``now`` earlier
            than the core has seen restarts it first (:meth:`restart`).
        """
        self._follow(now)
        p, s = self.params, self.state
        first = self._last_update is None
        dt = 0.0 if first else now - self._last_update
        self._last_update = now
        if hold is not None:
            target, s.source, s.trim = p.home, f"hold: {hold}", 0.0
            self._pid.reset()
        elif self.override_active(now):
            target, s.source, s.trim = s.override, "operator override", 0.0
            self._pid.reset()
        else:
            if self.watchdog_due(now, tick):
                s.watchdog_tripped = True
                s.setting = BLADE_HOME
                s.source = "watchdog: blade home, no command"
            elif s.last_command is None:
                s.source = "no command yet"
            else:
                s.source = "controller"
            nominal = p.geometry.position(s.setting)
            if (
                s.source == "controller"
                and self.pushing
                and s.setting in (BLADE_BELOW, BLADE_LEVEL)
                and force is not None
            ):
                # More force than wanted: raise the blade (positive trim) to cut less.
                s.trim = self._pid.update(force - p.push_force, dt)
            else:
                s.trim = 0.0
                self._pid.reset()
            target = nominal + s.trim
            s.source = s.source if not s.trim else s.source + " (constant force)"
        target = min(p.position_max, max(p.position_min, target))
        if not first and hold is None:
            step = p.max_speed * dt
            target = min(s.setpoint + step, max(s.setpoint - step, target))
        s.setpoint = target
        return target


@dataclass
class TickSetpoints:
    """One set-point per simulator tick: the ``sim`` backend's schedule, without ROS.

    Each tick gets one set-point, computed once: at once when the watchdog or an operator
    set-point is in charge, otherwise once the controller's word of that tick is in (and,
    with the blade after the drive, once its blade bits are released). An operator
    set-point waits in :attr:`pending_override` for the next set-point computed, so every
    tick of a streamed override gets it. A closed gate sends home marked ``held`` without
    touching the core; when the gate opens the tick's own set-point follows.

    Attributes:
        word_tick: The tick of the controller's latest word.
        open_setpoint: ``(tick, value)`` computed for a tick with the gate open.
        pending_override: An operator set-point not yet given to the core.
        last_sent: ``(tick, held)`` of the last set-point handed out.
    """

    word_tick: Stamp | None = None
    open_setpoint: tuple[Stamp, float] | None = None
    pending_override: float | None = None
    last_sent: tuple[Stamp, bool] | None = None

    def next(
        self,
        core: BladeDriverCore,
        tick: Stamp,
        now: float,
        force: float | None,
        held: bool,
        waiting_for_drive: bool,
    ) -> tuple[float, bool] | None:
        """``(value, held)`` to send for ``tick`` now, or ``None`` (not due, or already sent)."""
        if held:
            value = core.params.home
        else:
            if self.open_setpoint is None or self.open_setpoint[0] != tick:
                if self.pending_override is not None:
                    core.override(self.pending_override, now)
                    self.pending_override = None
                if not core.needs_no_controller(now):
                    if self.word_tick != tick:
                        return None  # wait for the controller's word of this tick
                    if waiting_for_drive:
                        return None  # its blade bits wait for the end of its drive
                self.open_setpoint = (tick, core.update(now, force))
            value = self.open_setpoint[1]
        if self.last_sent == (tick, held):
            return None
        self.last_sent = (tick, held)
        return value, held
