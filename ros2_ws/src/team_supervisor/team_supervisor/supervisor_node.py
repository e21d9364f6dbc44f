r"""``ros2 run team_supervisor supervisor``: the team's e-stop, heartbeat, arm and enables.

::

    ros2 run team_supervisor supervisor --ros-args -p robots:=4
    ros2 run team_supervisor supervisor --ros-args --params-file config/supervisor.yaml

Publishes ``/team/estop`` (std_msgs/Bool, reliable, transient local: ``True`` from an e-stop
until a reset), ``/team/heartbeat`` (excavation_interfaces/TeamState at ``heartbeat_rate``:
stamp = this node's clock, ``state`` = the team state), ``/team/armed``
(excavation_interfaces/TeamArmed, latched: stamped at the newest arming, ``armings`` = the
count of armings; a re-arm of an armed team counts, which robot-side nodes wait for after
their link dropped), ``/robot_k/enabled``
(std_msgs/Bool, latched) and ``/diagnostics`` (the team state and one value per robot).
Every change goes out at once, not at the next heartbeat. Services (std_srvs/Trigger):
``~/estop``, ``~/reset``, ``~/arm``, ``~/pause``, ``~/resume`` and ``~/status`` (the state
in words); per robot ``/robot_k/enable`` (std_srvs/SetBool). With ``watch_poses`` it
subscribes every ``/robot_k/pose`` (best effort, newest only) and ``/robot_k/drive/status``
(excavation_interfaces/DriveStatus: a robot whose executor runs a goal is not lost for a late frame)
and applies the lost-robot policy of :class:`team_supervisor.team.Team`.

The logic is :class:`team_supervisor.team.Team`; this node moves messages.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from excavation_interfaces.msg import DriveStatus, TeamArmed, TeamState
from geometry_msgs.msg import PoseWithCovarianceStamped
from rclpy.node import Node
from std_msgs.msg import Bool
from std_srvs.srv import SetBool, Trigger

from excavation_common.params import param
from excavation_common.ros import LATCHED, LATEST_FRAME, declare_params, diagnostics, spin_node
from excavation_common.safety import (
    ARMED,
    ARMED_TOPIC,
    ENABLED_TOPIC,
    ESTOP_TOPIC,
    ESTOPPED,
    HEARTBEAT_TOPIC,
)
from team_supervisor.team import Reply, Team

LEVELS = {ARMED: DiagnosticStatus.OK, ESTOPPED: DiagnosticStatus.ERROR}

NEWEST_POSE = LATEST_FRAME
"""QoS of the pose subscriptions: best effort, depth 1. The policy needs each robot's newest
pose only; a deeper queue let a busy supervisor compare one robot's newest pose with another's
from ticks ago (in a faster-than-real-time lockstep trial: a robot "lost" that was not)."""


@dataclass(frozen=True)
class SupervisorParams:
    """Parameters of the supervisor node (``config/supervisor.yaml``)."""

    robots: int = param(4, "team size: robots 0 .. robots-1", low=1, high=64)
    heartbeat_rate: float = param(10.0, "heartbeat rate, Hz", low=1.0, high=200.0)
    watch_poses: bool = param(True, "apply the lost-robot policy to /robot_k/pose")
    lost_timeout: float = param(
        1.0, "s of pose stamps without a pose: the robot is lost (stopped)", low=0.05, high=600.0
    )
    lost_grace: float = param(
        5.0, "further s lost before the robot is disabled", low=0.0, high=3600.0
    )
    lost_frames: int = param(
        2, "frames of the pose stream (distinct stamps) a lost robot has missed", low=1, high=64
    )
    busy_timeout: float = param(
        60.0, "s of the pose stream a goal executing keeps its robot from being lost", low=0.0
    )
    enabled_at_start: bool = param(True, "robots start enabled (the team still starts disarmed)")
    arm_at_start: bool = param(False, "arm the team at start (unattended simulated trials only)")
    diagnostics_period: float = param(1.0, "s between diagnostics", low=0.05, high=60.0)


class SupervisorNode(Node):
    """Thin ROS plumbing around :class:`Team` (one per team)."""

    def __init__(self, **kwargs) -> None:
        super().__init__("supervisor", **kwargs)
        self.params = declare_params(self, SupervisorParams)
        p = self.params
        self.team = Team(
            p.robots,
            p.lost_timeout,
            p.lost_grace,
            p.enabled_at_start,
            lost_frames=p.lost_frames,
            busy_timeout=p.busy_timeout,
        )
        self.estop_pub = self.create_publisher(Bool, ESTOP_TOPIC, LATCHED)
        self.heartbeat_pub = self.create_publisher(TeamState, HEARTBEAT_TOPIC, 10)
        self.armed_pub = self.create_publisher(TeamArmed, ARMED_TOPIC, LATCHED)
        self.published_armings = 0
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.enabled_pubs = [
            self.create_publisher(Bool, f"/robot_{k}/{ENABLED_TOPIC}", LATCHED)
            for k in range(p.robots)
        ]
        for name in ("estop", "reset", "arm", "pause", "resume", "status"):
            self.create_service(
                Trigger, f"~/{name}", lambda req, res, n=name: self.on_trigger(n, res)
            )
        for k in range(p.robots):
            self.create_service(
                SetBool, f"/robot_{k}/enable", lambda req, res, k=k: self.on_enable(k, req, res)
            )
            if p.watch_poses:
                self.create_subscription(
                    PoseWithCovarianceStamped,
                    f"/robot_{k}/pose",
                    lambda m, k=k: self.on_pose(k, m),
                    NEWEST_POSE,
                )
                self.create_subscription(
                    DriveStatus,
                    f"/robot_{k}/drive/status",
                    lambda m, k=k: self.on_drive(k, m),
                    10,
                )
        self.published_enabled: list[bool | None] = [None] * p.robots
        self.published_estop: bool | None = None
        if p.arm_at_start:
            self.team.arm()
        self.announce()
        self.create_timer(1.0 / p.heartbeat_rate, self.publish_heartbeat)
        self.create_timer(p.diagnostics_period, self.publish_diagnostics)

    # --- outputs ----------------------------------------------------------------------------

    def publish_heartbeat(self) -> None:
        """One heartbeat: this node's time and the team state."""
        msg = TeamState(state=self.team.state)
        msg.stamp = self.get_clock().now().to_msg()
        self.heartbeat_pub.publish(msg)

    def announce(self) -> None:
        """Publish what changed (e-stop, enables) and a heartbeat with the new state, at once."""
        if self.team.estopped != self.published_estop:
            self.published_estop = self.team.estopped
            self.estop_pub.publish(Bool(data=self.team.estopped))
        if self.team.armings != self.published_armings:
            self.published_armings = self.team.armings
            msg = TeamArmed(armings=self.team.armings)
            msg.stamp = self.get_clock().now().to_msg()
            self.armed_pub.publish(msg)
        for k in range(self.team.robots):
            enabled = self.team.enabled(k)
            if enabled != self.published_enabled[k]:
                self.published_enabled[k] = enabled
                self.enabled_pubs[k].publish(Bool(data=enabled))
        self.publish_heartbeat()
        self.publish_diagnostics()

    def status_text(self) -> str:
        """The team state and every robot's, one line each."""
        t = self.team
        head = f"team {t.state}" + (f" ({t.estop_reason})" if t.estopped else "")
        return "\n".join([head] + [f"robot {k}: {t.describe(k)}" for k in range(t.robots)])

    def publish_diagnostics(self) -> None:
        """The team state (OK armed, WARN disarmed or paused, ERROR e-stop) and every robot."""
        t = self.team
        level = LEVELS.get(t.state, DiagnosticStatus.WARN)
        stopped = [k for k in range(t.robots) if not t.enabled(k)]
        message = f"team {t.state}" + (f" ({t.estop_reason})" if t.estopped else "")
        if stopped:
            message += f"; robots stopped: {stopped}"
            if level == DiagnosticStatus.OK:
                level = DiagnosticStatus.WARN
        values = {"state": t.state} | {f"robot_{k}": t.describe(k) for k in range(t.robots)}
        self.diag_pub.publish(diagnostics(self, level, message, values))

    # --- inputs -----------------------------------------------------------------------------

    def on_trigger(self, name: str, response: Trigger.Response) -> Trigger.Response:
        """``~/estop``, ``~/reset``, ``~/arm``, ``~/pause``, ``~/resume``, ``~/status``."""
        if name == "status":
            reply = Reply(True, self.status_text())
        elif name == "estop":
            reply = self.team.estop("operator")
        else:
            reply = getattr(self.team, name)()
        if name == "estop":
            self.get_logger().warning(f"estop: {reply.message}")
        elif name != "status":
            self.get_logger().info(f"{name}: {reply.message}")
        if name != "status":
            self.announce()
        response.success, response.message = reply.success, reply.message
        return response

    def on_enable(self, k: int, request: SetBool.Request, response: SetBool.Response):
        """``/robot_k/enable``: the operator enables or disables one robot."""
        reply = self.team.enable(k, bool(request.data))
        self.get_logger().info(
            f"robot {k} {'enable' if request.data else 'disable'}: {reply.message}"
        )
        self.announce()
        response.success, response.message = reply.success, reply.message
        return response

    def on_pose(self, k: int, msg: PoseWithCovarianceStamped) -> None:
        """A robot's pose: feeds the lost-robot policy."""
        stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        self.report_lost(self.team.on_pose(k, stamp))

    def on_drive(self, k: int, msg: DriveStatus) -> None:
        """A robot's executor status: a goal executing keeps it from being lost."""
        self.report_lost(self.team.on_drive(k, msg.status == DriveStatus.STATUS_EXECUTING))

    def report_lost(self, changed: list[int]) -> None:
        """Log and announce the robots the lost-robot policy stopped or let rejoin."""
        if changed:
            for j in changed:
                self.get_logger().warning(f"robot {j}: {self.team.describe(j)}")
            self.announce()


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run team_supervisor supervisor``."""
    return spin_node(SupervisorNode, args)


if __name__ == "__main__":
    sys.exit(main())
