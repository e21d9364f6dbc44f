"""The drive executor's logic without ROS: a behaviour word as a queue of motion primitives.

A goal (one tick's word, :class:`~drive_executor.goals.DriveGoal`) becomes primitives in
Table 2 order (the world model's order, ``excavation_sim.world.apply_behaviours``):

1. Move Forward: :class:`~drive_executor.primitives.DriveCells` ``+1``;
2. Move Backward: ``DriveCells(-1)``;
3. Random Turn, Turn Right, Turn Left: their net rotation as quarter turns (right is
   ``+1``, a net half turn is two right turns, opposite turns cancel). Turns never fail in
   the world model and touch no soil, so the net rotation ends where the three would.

Throttle Up raises the speed limits of the goal's primitives. Blade and memory behaviours
are not the executor's (the blade driver and the controller own them).

A primitive that fails (time allowance, no progress: the robot is blocked or stalled)
stops the robot; a failed drive is followed by a settle back to the centre of the cell
the robot stands on, and the goal goes on with its remaining primitives, as the world
model goes on after a refused move. The goal then ends ``ABORTED`` and the robot reports
``stuck`` (U1); otherwise ``SUCCEEDED`` and not stuck.

Safety (docs/architecture.md, "Operator oversight and safety"): every twist passes
:class:`excavation_common.safety.MotionGate`; a closed gate (not active, e-stop, pause,
disable, heartbeat lost) or a pose older than ``pose_timeout`` by its stamp (or stamped more
than ``future_tolerance`` ahead of the node's clock) gives a zero twist at once and aborts
the goal; nothing moves until a new goal arrives with the gate
open. A pause alone *suspends* the goal instead: the robot stops at once, the goal stays
executing, and on resume the running primitive carries on toward its target with its time
allowance and progress window moved on by the time paused (a paused and resumed trial
ends as an uninterrupted one). A drive override (``drive/override``) wins over the goal
while younger than ``override_timeout`` (the goal aborts: the operator has taken the
robot), clamped to the throttle limits; the gate still wins over the override.

What the node must send besides the twists (which :meth:`DriveExecutorCore.on_pose` and
:meth:`DriveExecutorCore.check` return) comes out of :meth:`DriveExecutorCore.drain` as
events (:data:`ExecutorEvent`: one frozen dataclass per kind), in the order they happened.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import assert_never

import numpy as np

from drive_executor.errors import GoalError
from drive_executor.goals import ABORTED, EXECUTING, LEFT, RIGHT, SUCCEEDED, DriveGoal
from drive_executor.params import ExecutorParams
from drive_executor.primitives import (
    STOP,
    DriveCells,
    Limits,
    Pose2D,
    Primitive,
    Status,
    Turn,
    Twist2D,
)
from excavation_common.behaviour import (
    MOVE_BACKWARD,
    MOVE_FORWARD,
    RANDOM_TURN,
    THROTTLE_UP,
    TURN_LEFT,
    TURN_RIGHT,
)
from excavation_common.safety import MotionGate

MOTION_BITS = sum(1 << b for b in (MOVE_FORWARD, MOVE_BACKWARD, RANDOM_TURN, TURN_RIGHT, TURN_LEFT))
OVERRIDE_IN_CHARGE = "drive override in charge"
"""The stop reason while the operator's drive override drives the robot."""
"""The behaviours the executor carries out (Table 2, 2-6)."""


# --- events: what the node must send besides the twists ----------------------------------------


@dataclass(frozen=True)
class SetThrottle:
    """A goal starts: the base's power mode (``drive/throttle``): Throttle Up when ``on``."""

    on: bool


@dataclass(frozen=True)
class ReportStatus:
    """The status of ``goal`` changed to ``code`` (``drive/status``, the drive action).

    ``stuck`` is the goal's U1: true when it ended aborted; the node sends it on ``stuck``
    once the code is terminal (succeeded or aborted). ``reason`` says why it was aborted
    (the action's result; not compared).
    """

    goal: DriveGoal
    code: int
    stuck: bool
    reason: str = field(default="", compare=False)


ExecutorEvent = SetThrottle | ReportStatus
"""Every event :meth:`DriveExecutorCore.drain` returns (``typing.get_args`` lists them)."""


# --- a word's primitives ------------------------------------------------------------------------


@dataclass(frozen=True)
class DriveStep:
    """Drive ``cells`` cells on the heading (forward > 0, backward < 0; 0: settle in the cell)."""

    cells: int


@dataclass(frozen=True)
class TurnStep:
    """A quarter turn in place: ``RIGHT`` (+1) or ``LEFT`` (-1)."""

    direction: int


Step = DriveStep | TurnStep
"""One primitive of a goal's queue, before it runs."""


def primitive(step: Step, params: ExecutorParams, limits: Limits) -> Primitive:
    """The motion primitive that carries out ``step``."""
    match step:
        case DriveStep(cells):
            return DriveCells(cells, params, limits)
        case TurnStep(direction):
            return Turn(direction, params, limits)
        case _:
            assert_never(step)


def plan(word: int, turn: int) -> list[Step]:
    """The primitives of a word: :class:`DriveStep` and :class:`TurnStep` steps.

    Args:
        word: Behaviour word (12 bits).
        turn: Direction of the random turn if the word has one: ``RIGHT`` or ``LEFT``.

    Raises:
        GoalError: A word beyond 12 bits, or a random turn without a direction.
    """
    if not 0 <= word <= 0xFFF:
        raise GoalError("<goal>", "word", word, "must be a 12-bit behaviour word")
    steps: list[Step] = []
    if (word >> MOVE_FORWARD) & 1:
        steps.append(DriveStep(1))
    if (word >> MOVE_BACKWARD) & 1:
        steps.append(DriveStep(-1))
    quarter = 0
    if (word >> RANDOM_TURN) & 1:
        if turn not in (RIGHT, LEFT):
            raise GoalError("<goal>", "turn", turn, "a random turn needs a direction")
        quarter += turn
    quarter += (word >> TURN_RIGHT) & 1
    quarter -= (word >> TURN_LEFT) & 1
    quarter %= 4
    steps += {0: [], 1: [TurnStep(RIGHT)], 2: [TurnStep(RIGHT)] * 2, 3: [TurnStep(LEFT)]}[quarter]
    return steps


@dataclass
class Counters:
    """What the executor has done (for ``/diagnostics`` and the trial's result)."""

    goals: int = 0
    """Goals started."""
    goals_aborted: int = 0
    """Goals that ended aborted."""
    primitives: int = 0
    """Primitives started."""
    primitives_aborted: int = 0
    """Primitives that failed or were cut short."""
    cycles: int = 0
    """Control steps (poses taken)."""
    last_failure: str = ""
    """The newest failure."""
    failures: list[str] = field(default_factory=list)
    """The last 20 aborted goals: ``tick t: why``."""


class DriveExecutorCore:
    """One robot's executor: goals in, twists and statuses out (pure, no ``rclpy``).

    Feed it poses (:meth:`on_pose`, which returns the twist of this control step), goals
    (:meth:`submit`), overrides (:meth:`on_override`) and the gate's inputs (through
    :attr:`gate`); call :meth:`check` from the safety loop and after every gate change.
    Events (:data:`ExecutorEvent`) collect in :attr:`events` until :meth:`drain`:
    :class:`ReportStatus` for every status change, :class:`SetThrottle` for the power mode of
    the goal starting. Times are seconds on one clock (the pose stamps' clock: sim time in
    CI).
    """

    def __init__(self, params: ExecutorParams, gate: MotionGate | None = None) -> None:
        self.params: ExecutorParams = params
        """The node's parameters."""
        self.gate: MotionGate = gate if gate is not None else MotionGate(deadman=params.deadman)
        """Whether the robot may move (the node feeds its inputs)."""
        self.rng: np.random.Generator = np.random.default_rng(params.seed)
        """Random-turn directions of goals that come without one (free mode)."""
        self.goal: DriveGoal | None = None
        """The goal running (``None``: idle)."""
        self.queue: deque[Step] = deque()
        """The running goal's steps not started yet."""
        self.planned = 0
        """Primitives the running goal planned (its feedback's total)."""
        self.current: Primitive | None = None
        """The primitive running (``None``: the next step starts on the next pose)."""
        self.limits: Limits = Limits.of(params, False)
        """Speed limits of the running goal's primitives (Throttle Up raises them)."""
        self.goal_failures: list[str] = []
        """Why the running goal's primitives failed (any: it ends aborted)."""
        self.pose: Pose2D | None = None
        """The newest pose."""
        self.pose_stamp: float | None = None
        """The newest pose's stamp (``pose_timeout`` counts from it)."""
        self.override: tuple[Twist2D, float] | None = None
        """The operator's newest drive override and the time it came."""
        self.events: list[ExecutorEvent] = []
        """Events not yet taken by :meth:`drain`, oldest first."""
        self.counters: Counters = Counters()
        """What the executor has done."""
        self.stop_reason: str | None = "no goal yet"
        self.operator = False
        """The operator's override is in charge (the last :meth:`check` forced it)."""
        """Why the robot is held still (``None``: the control loop may act)."""
        self.free_ticks: int = 0
        """Goals started from free-mode words (their tick numbers)."""
        self.suspended_at: float | None = None
        """Time the running goal was suspended by a pause (``None``: not suspended)."""
        self.sent: Twist2D = STOP
        """The twist of the last control step (what :meth:`predict` advances a pose by)."""

    # --- inputs -----------------------------------------------------------------------------

    def submit(self, goal: DriveGoal, now: float) -> None:
        """Start a goal (a running one is aborted first: superseded)."""
        if self.goal is not None:
            self.abort(f"superseded by tick {goal.tick}")
        turn = goal.turn
        if (goal.word >> RANDOM_TURN) & 1 and turn == 0:
            turn = RIGHT if self.rng.integers(0, 2) else LEFT
        try:
            steps = plan(goal.word, turn)
        except GoalError as exc:
            self.goal, self.planned = goal, 0
            self.counters.goals += 1
            self.goal_failures = [str(exc)]
            self._finish()
            return
        self.goal = goal
        self.counters.goals += 1
        self.queue = deque(steps)
        self.planned = len(steps)
        self.current = None
        self.goal_failures = []
        throttle = bool((goal.word >> THROTTLE_UP) & 1)
        self.limits = Limits.of(self.params, throttle)
        self.events.append(SetThrottle(throttle))
        self.events.append(ReportStatus(goal, EXECUTING, False))
        if not self.queue:
            self._finish()
            return
        why = self.gate.reason(now)
        if why is not None:
            self.stop(why, now)

    def on_word(self, word: int, now: float) -> None:
        """Free mode: run a behaviour word when idle (a word while busy is dropped)."""
        if self.goal is None:
            self.free_ticks += 1
            self.submit(DriveGoal(self.free_ticks, int(word) & 0xFFFF), now)

    def on_override(self, twist: Twist2D, now: float) -> None:
        """An operator's twist (``drive/override``)."""
        if math.isfinite(twist.linear) and math.isfinite(twist.angular):
            self.override = (twist, now)

    def predict(self, pose: Pose2D, stamp: float, now: float) -> tuple[Pose2D, float]:
        """``pose`` (stamped ``stamp``) advanced to ``now`` along the twist last sent.

        A camera's pose is a frame's latency old when it arrives (0.13 s median in a
        rehearsal, docs/benchmarks.md); meanwhile the robot went on at the speed last
        commanded. A unicycle step over the pose's age (at most ``pose_timeout``; none for a
        pose from the future) gives where it is now, stamped ``now``.
        """
        age = min(max(now - stamp, 0.0), self.params.pose_timeout)
        if age <= 0.0:
            return pose, stamp
        v, w = self.sent.linear, self.sent.angular
        mid = pose.yaw + 0.5 * w * age
        moved = Pose2D(
            pose.x + v * age * math.cos(mid),
            pose.y + v * age * math.sin(mid),
            math.atan2(math.sin(pose.yaw + w * age), math.cos(pose.yaw + w * age)),
        )
        return moved, stamp + age

    def on_pose(self, pose: Pose2D, stamp: float, now: float) -> Twist2D:
        """A new pose (stamped ``stamp``): one control step; returns the twist to send."""
        twist = self._control(pose, stamp, now)
        self.sent = twist
        return twist

    def _control(self, pose: Pose2D, stamp: float, now: float) -> Twist2D:
        self.counters.cycles += 1
        self.pose, self.pose_stamp = pose, stamp
        forced = self.check(now)
        if forced is not None:
            return forced
        if self.params.predict_pose:
            pose, stamp = self.predict(pose, stamp, now)
        if self.goal is None:
            return STOP
        while True:
            if self.current is None:
                if not self.queue:
                    self._finish()
                    return STOP
                self.current = primitive(self.queue.popleft(), self.params, self.limits)
                self.counters.primitives += 1
                try:
                    self.current.on_run(pose, stamp)
                except GoalError as exc:
                    self.abort(str(exc))
                    return STOP
            status, twist = self.current.on_cycle_update(pose, stamp)
            if status is Status.RUNNING:
                return twist
            if status is Status.FAILED:
                self.counters.primitives_aborted += 1
                self.counters.last_failure = self.current.failure
                self.goal_failures.append(self.current.failure)
                if isinstance(self.current, DriveCells) and self.current.cells != 0:
                    self.queue.appendleft(DriveStep(0))
                self.current = None
                return STOP
            self.current = None  # succeeded: start the next primitive on this pose

    def check(self, now: float) -> Twist2D | None:
        """The safety check: the twist to force now, or ``None`` when the loop may act.

        Runs in the safety loop (>= 20 Hz) and at once after every gate input. A closed
        gate gives zero; a fresh override, clamped, when the gate is open; a stale pose
        zero. A running goal is aborted in each case.
        """
        forced = self._forced(now)
        if forced is not None:
            self.sent = forced
        self.operator = self.stop_reason == OVERRIDE_IN_CHARGE
        return forced

    def _forced(self, now: float) -> Twist2D | None:
        why = self.gate.reason(now)
        if why is not None:
            self.stop_reason = why
            self.stop(why, now)
            return STOP
        if self.suspended_at is not None:
            self.resume(now)
        if self.override is not None and now - self.override[1] <= self.params.override_timeout:
            if self.goal is not None:
                self.abort(OVERRIDE_IN_CHARGE)
            self.stop_reason = OVERRIDE_IN_CHARGE
            return self.clamp(self.override[0])
        if self.goal is not None:
            stale = self.stale(now)
            if stale is not None:
                self.abort(stale)
                return STOP
        elif self.stale(now) is not None:
            return STOP
        self.stop_reason = None
        return None

    # --- helpers ------------------------------------------------------------------------------

    def stale(self, now: float) -> str | None:
        """Why the pose cannot be used at ``now``.

        None yet; older than ``pose_timeout``; or stamped more than ``future_tolerance``
        ahead of ``now`` (the pose's clock runs ahead of this node's: its age would read
        young for as long as the offset lasts, so a localiser that stopped would not be
        noticed in time).
        """
        if self.pose_stamp is None:
            return "no pose yet"
        age = now - self.pose_stamp
        if age > self.params.pose_timeout:
            return f"pose stale ({age:.2f} s old)"
        if -age > self.params.future_tolerance:
            return f"pose from the future ({-age:.3f} s ahead of this node's clock)"
        return None

    def clamp(self, twist: Twist2D) -> Twist2D:
        """An override clamped to the throttle-up limits."""
        v, w = self.params.throttle_speed, self.params.throttle_turn_rate
        return Twist2D(max(-v, min(v, twist.linear)), max(-w, min(w, twist.angular)))

    def stop(self, why: str, now: float) -> None:
        """The gate closed: suspend the goal on a pause, abort it otherwise."""
        if self.goal is None:
            return
        if self.gate.paused(now):
            if self.suspended_at is None:
                self.suspended_at = now
        else:
            self.abort(why)

    def resume(self, now: float) -> None:
        """The gate opened after a pause: the suspended primitive's clock moves on."""
        if self.current is not None and self.suspended_at is not None:
            self.current.shift(now - self.suspended_at)
        self.suspended_at = None

    def abort(self, why: str) -> None:
        """Stop the running goal: zero twist, goal aborted, robot stuck."""
        if self.goal is None:
            return
        if self.current is not None:
            self.counters.primitives_aborted += 1
        self.counters.last_failure = why
        self.goal_failures.append(why)
        self.current = None
        self.queue.clear()
        self._finish()

    def _finish(self) -> None:
        goal, failed = self.goal, bool(self.goal_failures)
        if goal is None:
            return
        if failed:
            self.counters.goals_aborted += 1
            self.counters.failures.append(f"tick {goal.tick}: " + "; ".join(self.goal_failures))
            del self.counters.failures[:-20]
        code = ABORTED if failed else SUCCEEDED
        self.events.append(ReportStatus(goal, code, failed, "; ".join(self.goal_failures)))
        self.goal = None
        self.current = None
        self.queue.clear()
        self.suspended_at = None

    def drain(self) -> list[ExecutorEvent]:
        """The events since the last call, oldest first."""
        out, self.events = self.events, []
        return out

    @property
    def busy(self) -> bool:
        """True while a goal runs."""
        return self.goal is not None

    @property
    def progress(self) -> tuple[int, int]:
        """``(done, total)``: primitives of the running goal completed, and planned."""
        if self.goal is None:
            return (0, 0)
        return (self.planned - len(self.queue) - (self.current is not None), self.planned)
