"""The team's safety state as a pure state machine (no rclpy); docs/operator.md.

The paper (section 1) asks that ground operators keep total oversight of the robot team and
can intervene and recover from mishaps. :class:`Team` is what the ``supervisor`` node runs:

Team state (:data:`excavation_common.safety.TEAM_STATES`)::

    disarmed --arm--> armed --pause--> paused --resume--> armed
        ^                                   any --estop--> estop --reset--> disarmed

* ``estop`` is accepted in every state and latches; only ``reset`` clears it, and a reset
  team is ``disarmed``: nothing moves until an explicit ``arm``.
* ``arm`` only from ``disarmed``; ``resume`` only from ``paused`` (so a resume can never
  clear an e-stop or arm a team that was never armed).

Per robot: the operator's wish (``enable K`` / ``disable K``) and the lost-robot policy.
The policy reads the pose stream (every ``/robot_k/pose``: the localiser's, one message per
robot per camera frame, or a simulator's) by its header stamps, which are sim time in a
simulated trial. A robot is *lost* when both hold:

* its pose **age** is more than ``lost_timeout``: the newest stamp of the stream (any robot's)
  is that far ahead of its own newest pose (a robot never seen counts from the stream's
  first stamp);
* it has **missed** at least ``lost_frames`` frames: that many distinct stamps of the stream
  are newer than its own newest pose. The poses of one frame arrive one after another, and
  a frame may come seconds of sim time after the last (the continuous trial renders one per
  tick, once the robots stand still), so one late or missing pose is never enough;

and its drive executor is not **busy**: an executor that reports a goal executing on
``/robot_k/drive/status`` is closing its loop on the robot's pose, and stops the robot by
itself (its ``pose_timeout``) and aborts the goal when that pose goes stale, so a late frame
while it drives does not make the robot lost; this holds for at most ``busy_timeout``
seconds of the stream (an executor that died mid-goal). When the goal ends, the rule
applies again with the age the robot has by then.

A lost robot is stopped at once (its ``enabled`` goes false, which closes its own MotionGate
and makes it absent to the other robots' controllers and to the team tick); seen again
within ``lost_grace`` it rejoins by itself; lost for longer (age beyond ``lost_timeout +
lost_grace``, and at least one frame missed since it was lost, so that a frame can still
find it however far apart frames come), it is disabled and rejoins only when it is seen
again and the operator enables it. Stamps, not arrival times, make the rule independent
of how loaded the machine is, and in a lockstep trial (one pose per tick, stamped with sim
time) the same in every run. The stream itself is the reference: while no frame comes (a
camera that stopped, a team standing still between snapshots) nobody is declared lost by
the supervisor; the executors' own pose timeout stops a robot whose pose goes stale.
A robot's pose stamped more than ``lost_timeout`` before its own newest means the clock
went back (a restarted simulator): the stamps are forgotten and counted afresh
(:meth:`Team.restart_stamps`), so the policy follows the new clock instead of waiting for
it to catch up with the old one.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field

from excavation_common.safety import ARMED, DISARMED, ESTOPPED, PAUSED

FRAMES_KEPT = 64
"""Distinct stamps the policy remembers (enough to count ``lost_frames`` missed frames)."""


@dataclass(frozen=True)
class Reply:
    """The outcome of one operator request (a ``std_srvs`` response).

    Attributes:
        success: The request was carried out (or there was nothing to do).
        message: One line for the operator.
    """

    success: bool
    message: str


@dataclass
class RobotState:
    """What the supervisor knows of one robot.

    Attributes:
        operator_enabled: The operator's wish (and the lost policy's disable after grace).
        disabled_reason: Why it is disabled (``"operator"`` or ``"lost"``), if it is.
        last_stamp: Stamp (s) of its newest pose, ``None`` before the first.
        lost: No pose for longer than ``lost_timeout`` (stamps) and ``lost_frames`` frames.
        busy: Its executor reports a goal executing.
        busy_since: The stream's newest stamp when the goal started (``None``: no stamp yet).
    """

    operator_enabled: bool = True
    disabled_reason: str | None = None
    last_stamp: float | None = None
    lost: bool = False
    busy: bool = False
    busy_since: float | None = None

    @property
    def enabled(self) -> bool:
        """What ``/robot_k/enabled`` says: enabled by the operator and not lost."""
        return self.operator_enabled and not self.lost


@dataclass
class Team:
    """The team state, the per-robot enables and the lost-robot policy.

    Attributes:
        robots: Team size (robots ``0 .. robots - 1``).
        lost_timeout: Seconds of pose stamps after which a silent robot is lost (stopped).
        lost_grace: Further seconds after which a lost robot is disabled.
        lost_frames: Frames of the stream (distinct stamps) a robot must miss to be lost.
        busy_timeout: Seconds of the stream an executing goal keeps its robot from being lost.
        state: One of ``disarmed``, ``armed``, ``paused``, ``estop``.
        estop_reason: What latched the e-stop.
        members: One :class:`RobotState` per robot.
    """

    robots: int
    lost_timeout: float = 1.0
    lost_grace: float = 5.0
    enabled_at_start: bool = True
    lost_frames: int = 2
    busy_timeout: float = 60.0
    state: str = DISARMED
    estop_reason: str = ""
    armings: int = 0
    """Successful :meth:`arm` calls, re-arms included (the node announces each on
    ``/team/armed``)."""
    members: list[RobotState] = field(default_factory=list)
    _first_stamp: float | None = None
    _newest_stamp: float | None = None
    _frames: list[float] = field(default_factory=list)
    """The stream's newest distinct stamps, ascending (at most :data:`FRAMES_KEPT`)."""

    def __post_init__(self) -> None:
        if self.robots < 1:
            raise ValueError(f"robots = {self.robots}: must be >= 1")
        if not 1 <= self.lost_frames <= FRAMES_KEPT:
            raise ValueError(f"lost_frames = {self.lost_frames}: must be 1..{FRAMES_KEPT}")
        if not self.members:
            self.members = [
                RobotState(
                    operator_enabled=self.enabled_at_start,
                    disabled_reason=None if self.enabled_at_start else "operator",
                )
                for _ in range(self.robots)
            ]

    # --- team state -------------------------------------------------------------------------

    @property
    def estopped(self) -> bool:
        """An e-stop is latched."""
        return self.state == ESTOPPED

    def estop(self, reason: str = "operator") -> Reply:
        """Latch the e-stop (accepted in every state)."""
        if self.state == ESTOPPED:
            return Reply(True, f"e-stop already latched ({self.estop_reason})")
        self.state, self.estop_reason = ESTOPPED, reason
        return Reply(True, f"e-stop latched ({reason}): every robot stops; reset, then arm")

    def reset(self) -> Reply:
        """Clear a latched e-stop; the team is then disarmed."""
        if self.state != ESTOPPED:
            return Reply(False, f"no e-stop to reset: team is {self.state}")
        self.state, self.estop_reason = DISARMED, ""
        return Reply(True, "e-stop reset: team disarmed; arm to move")

    def arm(self) -> Reply:
        """Allow motion (from ``disarmed``), or re-arm an armed team.

        A re-arm is the operator's word that robots whose link to the dome PC dropped may
        move again (robot-side nodes with ``rearm_after_loss`` wait for a new arming after
        they lost the heartbeat; :class:`excavation_common.safety.MotionGate`).
        """
        if self.state == ESTOPPED:
            return Reply(False, f"e-stop latched ({self.estop_reason}): reset first")
        if self.state == PAUSED:
            return Reply(False, "team is paused: resume it")
        again = self.state == ARMED
        self.state = ARMED
        self.armings += 1
        if again:
            return Reply(True, "team re-armed: robots that lost the link may move again")
        return Reply(True, "team armed: robots enabled and seen may move")

    def pause(self) -> Reply:
        """Stop every robot, keeping the team armed for a resume."""
        if self.state == PAUSED:
            return Reply(True, "team already paused")
        if self.state != ARMED:
            return Reply(False, f"cannot pause: team is {self.state}")
        self.state = PAUSED
        return Reply(True, "team paused: every robot stops; resume to continue")

    def resume(self) -> Reply:
        """Continue after a pause (never clears an e-stop)."""
        if self.state == ARMED:
            return Reply(True, "team already armed")
        if self.state != PAUSED:
            return Reply(False, f"cannot resume: team is {self.state} (resume follows a pause)")
        self.state = ARMED
        return Reply(True, "team resumed: armed")

    # --- robots -----------------------------------------------------------------------------

    def _check(self, k: int) -> None:
        if not 0 <= k < self.robots:
            raise IndexError(f"robot {k}: the team has robots 0..{self.robots - 1}")

    def enable(self, k: int, on: bool) -> Reply:
        """The operator enables or disables robot ``k``.

        A lost robot cannot be enabled: it rejoins once it is seen again.
        """
        if not 0 <= k < self.robots:
            return Reply(False, f"no robot {k}: the team has robots 0..{self.robots - 1}")
        member = self.members[k]
        if not on:
            member.operator_enabled, member.disabled_reason = False, "operator"
            return Reply(True, f"robot {k} disabled: it stops and is absent to the others")
        if member.lost:
            return Reply(False, f"robot {k} is lost ({self.pose_age(k):.1f} s without a pose)")
        member.operator_enabled, member.disabled_reason = True, None
        return Reply(True, f"robot {k} enabled")

    def enabled(self, k: int) -> bool:
        """Whether robot ``k`` may move (as ``/robot_k/enabled`` says)."""
        self._check(k)
        return self.members[k].enabled

    def on_pose(self, k: int, stamp: float) -> list[int]:
        """A pose of robot ``k`` stamped ``stamp`` (s) arrived; returns :meth:`update_lost`."""
        self._check(k)
        member = self.members[k]
        if member.last_stamp is not None and stamp < member.last_stamp - self.lost_timeout:
            self.restart_stamps()
        if member.last_stamp is None or stamp > member.last_stamp:
            member.last_stamp = stamp
        if self._first_stamp is None:
            self._first_stamp = stamp
        if self._newest_stamp is None or stamp > self._newest_stamp:
            self._newest_stamp = stamp
        i = bisect.bisect_left(self._frames, stamp)
        if i == len(self._frames) or self._frames[i] != stamp:
            self._frames.insert(i, stamp)
            del self._frames[:-FRAMES_KEPT]
        return self.update_lost()

    def on_drive(self, k: int, executing: bool) -> list[int]:
        """Robot ``k``'s executor reports a goal executing (or ended): :meth:`update_lost`."""
        self._check(k)
        member = self.members[k]
        if executing and not member.busy:
            member.busy, member.busy_since = True, self._newest_stamp
        elif not executing:
            member.busy, member.busy_since = False, None
        return self.update_lost()

    def restart_stamps(self) -> None:
        """Forget every pose stamp (the clock went back): no robot is lost until counted anew.

        The operator's disables stay, and so does a disable by the policy (the robot rejoins
        only when the operator enables it).
        """
        for member in self.members:
            member.last_stamp, member.lost, member.busy_since = None, False, None
        self._first_stamp = self._newest_stamp = None
        self._frames.clear()

    def pose_age(self, k: int) -> float:
        """Seconds (stamps) robot ``k``'s newest pose lags the team's newest (0: none yet)."""
        if self._newest_stamp is None:
            return 0.0
        last = self.members[k].last_stamp
        return self._newest_stamp - (last if last is not None else self._first_stamp)

    def missed_frames(self, k: int) -> int:
        """Frames of the stream (distinct stamps) newer than robot ``k``'s newest pose."""
        last = self.members[k].last_stamp
        if last is None:
            return len(self._frames)
        return len(self._frames) - bisect.bisect_right(self._frames, last)

    def busy(self, k: int) -> bool:
        """Robot ``k``'s executor runs a goal that started within ``busy_timeout``."""
        member = self.members[k]
        if not member.busy:
            return False
        if member.busy_since is None or self._newest_stamp is None:
            return True
        return self._newest_stamp - member.busy_since <= self.busy_timeout

    def update_lost(self) -> list[int]:
        """Apply the lost-robot policy; returns the robots whose ``enabled`` changed."""
        changed = []
        for k, member in enumerate(self.members):
            before = member.enabled
            age = self.pose_age(k)
            # A goal that starts once the robot is lost does not bring it back (its executor
            # is stopped by the closed gate); only a pose does.
            member.lost = (
                age > self.lost_timeout
                and self.missed_frames(k) >= self.lost_frames
                and (member.lost or not self.busy(k))
            )
            if (
                member.lost
                and age > self.lost_timeout + self.lost_grace
                and self.missed_frames(k) > self.lost_frames
            ):
                if member.operator_enabled:
                    member.operator_enabled, member.disabled_reason = False, "lost"
            if member.enabled != before:
                changed.append(k)
        return changed

    def describe(self, k: int) -> str:
        """One line on robot ``k`` for diagnostics and ``ant-operator status``."""
        member = self.members[k]
        age = self.pose_age(k)
        if member.lost and member.operator_enabled:
            return (
                f"lost ({age:.1f} s without a pose): stopped, disabled after "
                f"{self.lost_timeout + self.lost_grace:.1f} s"
            )
        if member.lost:
            return f"disabled ({member.disabled_reason}); lost ({age:.1f} s without a pose)"
        if not member.operator_enabled:
            return f"disabled ({member.disabled_reason})"
        return "enabled" if member.last_stamp is not None else "enabled (no pose yet)"
