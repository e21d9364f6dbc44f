"""The team's safety state as a pure state machine (no rclpy): DESIGN.md "Operator oversight".

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
A robot is *lost* when the team's previous frame (the newest pose stamp before the newest
one) is more than ``lost_timeout`` seconds (pose header stamps) ahead of the robot's own
newest pose; a robot never seen counts from the team's first pose. The newest stamp itself
is not the reference: the poses of one frame arrive one after another, and after a gap in
which no robot was seen (a camera stall, a localiser restart) the first pose of the next
frame would make every other robot lost (and, past the grace, disabled) before its own pose
of that frame came in. A lost robot is stopped at once (its ``enabled`` goes false, which closes
its own MotionGate and makes it absent to the other robots' controllers); seen again
within ``lost_grace`` it rejoins by itself; lost for longer, it is disabled and rejoins only
when it is seen again and the operator enables it. Stamps, not arrival times, make the rule
independent of how loaded the machine is, and in a lockstep trial (one pose per tick,
stamped with sim time) the same in every run. A robot's pose stamped more than
``lost_timeout`` before its own newest means the clock went back (a restarted simulator):
the stamps are forgotten and counted afresh (:meth:`Team.restart_stamps`), so the policy
follows the new clock instead of waiting for it to catch up with the old one.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from excavation_common.safety import ARMED, DISARMED, ESTOPPED, PAUSED


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
        lost: No pose for longer than ``lost_timeout`` (stamps).
    """

    operator_enabled: bool = True
    disabled_reason: str | None = None
    last_stamp: float | None = None
    lost: bool = False

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
        state: One of ``disarmed``, ``armed``, ``paused``, ``estop``.
        estop_reason: What latched the e-stop.
        members: One :class:`RobotState` per robot.
    """

    robots: int
    lost_timeout: float = 1.0
    lost_grace: float = 5.0
    enabled_at_start: bool = True
    state: str = DISARMED
    estop_reason: str = ""
    members: list[RobotState] = field(default_factory=list)
    _first_stamp: float | None = None
    _newest_stamp: float | None = None
    _previous_stamp: float | None = None

    def __post_init__(self) -> None:
        if self.robots < 1:
            raise ValueError(f"robots = {self.robots}: must be >= 1")
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
        """Allow motion (from ``disarmed`` only)."""
        if self.state == ARMED:
            return Reply(True, "team already armed")
        if self.state == ESTOPPED:
            return Reply(False, f"e-stop latched ({self.estop_reason}): reset first")
        if self.state == PAUSED:
            return Reply(False, "team is paused: resume it")
        self.state = ARMED
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

    def on_pose(self, k: int, stamp: float) -> None:
        """A pose of robot ``k`` stamped ``stamp`` (s) arrived."""
        self._check(k)
        member = self.members[k]
        if member.last_stamp is not None and stamp < member.last_stamp - self.lost_timeout:
            self.restart_stamps()
        if member.last_stamp is None or stamp > member.last_stamp:
            member.last_stamp = stamp
        if self._first_stamp is None:
            self._first_stamp = stamp
        if self._newest_stamp is None or stamp > self._newest_stamp:
            self._previous_stamp, self._newest_stamp = self._newest_stamp, stamp
        self.update_lost()

    def restart_stamps(self) -> None:
        """Forget every pose stamp (the clock went back): no robot is lost until counted anew.

        The operator's disables stay, and so does a disable by the policy (the robot rejoins
        only when the operator enables it).
        """
        for member in self.members:
            member.last_stamp, member.lost = None, False
        self._first_stamp = self._newest_stamp = self._previous_stamp = None

    def pose_age(self, k: int) -> float:
        """Seconds (stamps) robot ``k``'s newest pose lags the team's previous frame.

        0 (or less) while the team has fewer than two frames, or the robot is up to date.
        """
        if self._previous_stamp is None:
            return 0.0
        last = self.members[k].last_stamp
        return self._previous_stamp - (last if last is not None else self._first_stamp)

    def update_lost(self) -> list[int]:
        """Apply the lost-robot policy; returns the robots whose ``enabled`` changed."""
        changed = []
        for k, member in enumerate(self.members):
            before = member.enabled
            age = self.pose_age(k)
            member.lost = age > self.lost_timeout
            if member.lost and age > self.lost_timeout + self.lost_grace:
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
