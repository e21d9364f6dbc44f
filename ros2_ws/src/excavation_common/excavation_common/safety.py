"""The team's safety state as every moving node sees it (docs/operator.md).

The supervisor (``team_supervisor``) owns the team state and announces it on two topics:

* ``/team/estop`` (``std_msgs/Bool``, reliable, transient local): ``True`` from an e-stop
  until a reset; latched, so a node that starts late still sees it;
* ``/team/heartbeat`` (``excavation_interfaces/TeamState``, 10 Hz): ``stamp`` = the
  supervisor's clock, ``state`` = the team state (:data:`TEAM_STATES`, the message's
  constants);
* ``/team/armed`` (``excavation_interfaces/TeamArmed``, reliable, transient local): stamped
  at the newest arming on the supervisor's clock, ``armings`` = the count of armings (a
  re-arm of an armed team counts);

and, per robot, ``/robot_k/enabled`` (``std_msgs/Bool``, reliable, transient local).

:class:`MotionGate` is the pure rule a drive executor or a blade driver applies before it
moves anything: motion is allowed only while the node is active (lifecycle), no e-stop is
latched, the last heartbeat is younger than the deadman limit and says ``armed``, and the
robot is enabled. Everything else means: zero twist, blade home. The gate starts closed:
nothing moves before the first ``armed`` heartbeat.

On a robot's own computer (``rearm_after_loss``) a lost heartbeat is a link that dropped
as often as a supervisor that died, and the supervisor, on the other side of the link,
may still say ``armed`` when the link returns. There the gate latches the loss: it stays
closed, whatever the heartbeats say, until an arming newer than the loss comes on
``/team/armed`` (the operator re-arms, having seen why the robot stopped).

A ROS-level stop is not a safety function: a dome still needs a hardware e-stop that cuts
motor power (docs/operator.md).
"""

from __future__ import annotations

from dataclasses import dataclass

ESTOP_TOPIC = "/team/estop"
HEARTBEAT_TOPIC = "/team/heartbeat"
ARMED_TOPIC = "/team/armed"
ENABLED_TOPIC = "enabled"
"""Relative: ``/robot_k/enabled`` in robot k's namespace."""

DISARMED, ARMED, PAUSED, ESTOPPED = "disarmed", "armed", "paused", "estop"
TEAM_STATES = (DISARMED, ARMED, PAUSED, ESTOPPED)

DEADMAN_TIMEOUT = 0.5
"""Seconds without a heartbeat after which every robot stops (as ``cmd_vel_timeout``)."""


@dataclass
class MotionGate:
    """Whether a robot may move now, and if not, why.

    Times are seconds on the node's clock (sim time in CI). Feed it every message; ask
    :meth:`allowed` (or :meth:`reason`) before publishing anything that moves the robot.

    Attributes:
        deadman: Heartbeat age limit, seconds.
        active: The node is in the lifecycle ``active`` state.
        estop: An e-stop is latched on ``/team/estop``.
        enabled: The robot is enabled (``/robot_k/enabled``); ``None`` = never heard.
        team_state: The state the last heartbeat said (``None`` = never heard).
        heartbeat_time: Local time of the last heartbeat, seconds.
        rearm_after_loss: A lost heartbeat keeps the gate closed until a newer arming
            (module docstring): set on a robot's own computer.
        arming: The newest arming heard on ``/team/armed`` (its stamp as ``(sec, nanosec)``
            and count), or ``None``.
        link_lost: A lost heartbeat is latched (``rearm_after_loss``).
        lost_arming: :attr:`arming` when the loss was latched.
    """

    deadman: float = DEADMAN_TIMEOUT
    active: bool = False
    estop: bool = False
    enabled: bool | None = None
    team_state: str | None = None
    heartbeat_time: float | None = None
    rearm_after_loss: bool = False
    arming: tuple[int, int, int] | None = None
    link_lost: bool = False
    lost_arming: tuple[int, int, int] | None = None

    def on_heartbeat(self, state: str, now: float) -> None:
        """A heartbeat arrived at local time ``now``."""
        self.team_state = state
        self.heartbeat_time = now

    def on_armed(self, sec: int, nanosec: int, count: int) -> None:
        """``/team/armed``: an arming (stamp and count); one newer than a latched loss clears it."""
        self.arming = (int(sec), int(nanosec), int(count))
        if self.link_lost and self.arming != self.lost_arming:
            self.link_lost = False

    def on_estop(self, latched: bool) -> None:
        """``/team/estop`` changed."""
        self.estop = bool(latched)

    def on_enabled(self, enabled: bool) -> None:
        """``/robot_k/enabled`` changed."""
        self.enabled = bool(enabled)

    def reason(self, now: float) -> str | None:
        """Why the robot must stand still at ``now``, or ``None`` when it may move.

        With ``rearm_after_loss``, the first call that finds the heartbeat lost latches the
        loss (:attr:`link_lost`); the nodes ask at least every safety-loop period.
        """
        if not self.active:
            return "not active (lifecycle)"
        if self.estop:
            return "e-stop latched"
        if self.heartbeat_time is None:
            return "no heartbeat yet"
        age = now - self.heartbeat_time
        if age > self.deadman or age < -self.deadman:
            if self.rearm_after_loss and not self.link_lost:
                self.link_lost, self.lost_arming = True, self.arming
            return f"heartbeat lost ({age:.2f} s old)"
        if self.link_lost:
            return "heartbeat lost earlier: waiting for the operator to re-arm"
        if self.team_state != ARMED:
            return f"team {self.team_state}"
        if self.enabled is not True:
            return "robot disabled" if self.enabled is False else "no enable state yet"
        return None

    @staticmethod
    def kind(reason: str | None) -> str | None:
        """A reason without its details: ``"heartbeat lost (0.61 s old)"`` -> ``"heartbeat lost"``.

        What a caller compares to tell a change of state from a growing age.
        """
        return None if reason is None else reason.split(" (")[0]

    def allowed(self, now: float) -> bool:
        """True when nothing stops the robot at ``now``."""
        return self.reason(now) is None

    def paused(self, now: float) -> bool:
        """True when a pause is what closes the gate (a resume carries on where it stopped).

        An e-stop, a lost heartbeat or an inactive node come first: each of them is never
        merely a pause.
        """
        return self.reason(now) == f"team {PAUSED}"
