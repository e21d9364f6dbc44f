r"""``ros2 run drive_executor executor``: one robot's drive executor, a lifecycle node.

Run one per robot in its namespace, then configure and activate it (nothing moves before)::

    ros2 run drive_executor executor --ros-args -r __ns:=/robot_0 \\
        --params-file config/executor.yaml -p cell_size:=0.25

Subscribes (relative names resolve in the robot's namespace): ``pose``
(PoseWithCovarianceStamped in ``map``; parameter ``pose_topic``) which closes the loop: each
pose runs one control step and is answered by one ``cmd_vel``; ``drive/goal``
(excavation_interfaces/DriveGoal, :mod:`drive_executor.goals`: the team tick's word for a tick);
``behaviour`` (std_msgs/UInt16, ``mode: free`` only); ``drive/override`` (TwistStamped, the
operator's drive); ``/team/estop`` (Bool, latched), ``/team/heartbeat`` (TeamState), ``/team/armed``
(TeamArmed, latched), ``enabled`` (Bool, latched).

Publishes: ``cmd_vel`` (parameter ``drive_type``: geometry_msgs/TwistStamped, frame
``robot_k/base_link``, as Jazzy's diff_drive_controller takes it, or geometry_msgs/Twist),
stamped with the node clock when it is sent (``cmd_vel_stamp: now``: a base's
``cmd_vel_timeout`` then counts from the command, not from the camera frame behind it; the
continuous simulator's lockstep takes ``pose``, the stamp of the pose answered),
``drive/status`` (excavation_interfaces/DriveStatus, with the goal), ``stuck`` (std_msgs/Bool,
U1, once per goal), ``drive/throttle`` (Bool, latched: the power mode of the running goal,
for the base), ``drive/operator`` (Bool, latched: the operator's override drives the
robot; the team tick records the ticks it spent so) and ``/diagnostics`` (every wall
second, also while a simulator's clock stands still; WARN when poses come stamped more
than ``clock_offset_limit`` ahead of the node's clock, naming the offset, or when every
pose of the last second was older than
``pose_timeout``, naming the youngest: a lagging localiser or a clock that runs ahead).

Lifecycle (ros2/demos ``lifecycle_py``): ``on_configure`` builds the core, publishers,
subscriptions and timers; ``on_activate`` opens the gate's ``active`` input and starts
publishing; ``on_deactivate`` sends a zero twist, aborts the goal and stops publishing.
The safety loop (``rate`` Hz on the node clock) and every e-stop, heartbeat, enable and
override message run :meth:`DriveExecutorCore.check` at once, so a stop reaches
``cmd_vel`` without waiting for the next pose. The last ``cmd_vel`` an executor sends is a
stop: on deactivation, on shutdown, when the node is destroyed, and when its program gets
SIGINT or SIGTERM (it handles both itself, so that ROS is still up to send the stop).
"""

from __future__ import annotations

import math
import signal
import sys
from typing import assert_never

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from excavation_interfaces.msg import DriveGoal as DriveGoalMsg
from excavation_interfaces.msg import DriveStatus, TeamArmed, TeamState
from geometry_msgs.msg import PoseWithCovarianceStamped, Twist, TwistStamped
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from std_msgs.msg import Bool, UInt16

from drive_executor.core import DriveExecutorCore, ReportStatus, SetThrottle
from drive_executor.errors import GoalError
from drive_executor.goals import TERMINAL, goal_from_message, status_message
from drive_executor.params import ExecutorParams
from drive_executor.primitives import Pose2D, Twist2D
from excavation_common.errors import FieldError
from excavation_common.ros import LATCHED, declare_params, diagnostics, init_rclpy
from excavation_common.safety import (
    ARMED_TOPIC,
    ENABLED_TOPIC,
    ESTOP_TOPIC,
    HEARTBEAT_TOPIC,
    MotionGate,
)

STEADY = ClockType.STEADY_TIME

STOP_DELIVERY = Duration(seconds=1.0)
"""Longest wait, at shutdown, for the base to acknowledge the final zero twist."""


def _seconds(stamp) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def pose_of(msg: PoseWithCovarianceStamped) -> Pose2D:
    """Centre and yaw of a pose message.

    Raises:
        GoalError: A frame other than ``map``.
    """
    if msg.header.frame_id != "map":
        raise GoalError("pose", "header.frame_id", msg.header.frame_id, "expected 'map'")
    p, q = msg.pose.pose.position, msg.pose.pose.orientation
    yaw = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))
    return Pose2D(p.x, p.y, yaw)


class ExecutorNode(LifecycleNode):
    """Thin lifecycle plumbing around :class:`DriveExecutorCore`."""

    def __init__(self, **kwargs) -> None:
        super().__init__("executor", **kwargs)
        self.params = declare_params(self, ExecutorParams)
        self.frame = f"{self.get_namespace().strip('/') or 'robot'}/base_link"
        self.gate = MotionGate(
            deadman=self.params.deadman, rearm_after_loss=self.params.rearm_after_loss
        )
        self.core = DriveExecutorCore(self.params, self.gate)
        self.errors: dict[str, str] = {}
        self._entities: list = []
        self.cmd_pub = None
        self.pose_lead: float | None = None  # most any pose was ahead of our clock (window)
        self.stamped = self.params.drive_type == "twist_stamped"

    # --- lifecycle --------------------------------------------------------------------------

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Allocate publishers, subscriptions and timers (nothing is published yet)."""
        self.core = DriveExecutorCore(self.params, self.gate)
        lp = self.create_lifecycle_publisher
        self.cmd_pub = lp(TwistStamped if self.stamped else Twist, "cmd_vel", 10)
        self.status_pub = lp(DriveStatus, "drive/status", 10)
        self.stuck_pub = lp(Bool, "stuck", 10)
        self.throttle_pub = lp(Bool, "drive/throttle", LATCHED)
        self.operator_pub = self.create_publisher(Bool, "drive/operator", LATCHED)
        self._operator_sent: bool | None = None
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        sub = self.create_subscription
        self._entities = [
            self.diag_pub,
            self.operator_pub,
            sub(PoseWithCovarianceStamped, self.params.pose_topic, self.on_pose, 10),
            sub(DriveGoalMsg, "drive/goal", self.on_goal, 10),
            sub(UInt16, "behaviour", self.on_behaviour, 10),
            sub(TwistStamped, "drive/override", self.on_override, 10),
            sub(Bool, ESTOP_TOPIC, self.on_estop, LATCHED),
            sub(TeamState, HEARTBEAT_TOPIC, self.on_heartbeat, 10),
            sub(TeamArmed, ARMED_TOPIC, self.on_armed, LATCHED),
            sub(Bool, ENABLED_TOPIC, self.on_enabled, LATCHED),
            self.create_timer(1.0 / self.params.rate, self.enforce),
            # wall clock: a node on use_sim_time reports even while the simulator waits
            # for the team (ant-dome up --sim starts the executors before the clock runs)
            self.create_timer(1.0, self.publish_diagnostics, clock=Clock(clock_type=STEADY)),
        ]
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Start publishing; the gate's ``active`` input opens."""
        result = super().on_activate(state)
        self.gate.active = True
        self.publish_diagnostics()
        return result

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Zero twist, abort the goal, stop publishing."""
        self.gate.active = False
        self.enforce()
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Release what ``on_configure`` allocated."""
        self._release()
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Stop (a zero twist, delivered) and release everything."""
        self.stop_base()
        self._release()
        return TransitionCallbackReturn.SUCCESS

    def stop_base(self) -> None:
        """While ``cmd_vel`` is live: close the gate, send the zero twist, wait for delivery.

        The executor's last command is then a stop, whatever ends it (shutdown, the node
        destroyed, SIGINT): the base need not wait out its ``cmd_vel_timeout`` on the last
        moving command. Nothing is sent while inactive (deactivation already sent one).
        """
        if self.cmd_pub is None or not self.gate.active or not self.context.ok():
            return
        self.gate.active = False
        self.enforce()
        self.cmd_pub.wait_for_all_acked(STOP_DELIVERY)

    def destroy_node(self) -> None:
        """The final zero twist (:meth:`stop_base`), then the node."""
        self.stop_base()
        super().destroy_node()

    def _release(self) -> None:
        for entity in self._entities:
            if hasattr(entity, "cancel"):
                entity.cancel()
                self.destroy_timer(entity)
            elif hasattr(entity, "publish"):
                self.destroy_publisher(entity)
            else:
                self.destroy_subscription(entity)
        self._entities = []
        for pub in (self.cmd_pub, self.status_pub, self.stuck_pub, self.throttle_pub):
            if pub is not None:
                self.destroy_lifecycle_publisher(pub)
        self.cmd_pub = None

    # --- inputs -----------------------------------------------------------------------------

    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def on_pose(self, msg: PoseWithCovarianceStamped) -> None:
        """One control step on a new pose; answered by one ``cmd_vel``.

        The answer is stamped with the node clock as it is sent (``cmd_vel_stamp: now``), or
        with the pose's stamp (``pose``: the continuous simulator, which waits for a command
        stamped with its step, while this node's reading of ``/clock`` may lag the pose).
        """
        try:
            pose = pose_of(msg)
        except GoalError as exc:
            self.errors["pose"] = str(exc)
            return
        self.errors.pop("pose", None)
        stamp, now = _seconds(msg.header.stamp), self._now()
        lead = stamp - now
        self.pose_lead = lead if self.pose_lead is None else max(self.pose_lead, lead)
        twist = self.core.on_pose(pose, stamp, now)
        if self.params.cmd_vel_stamp == "pose":
            self.publish_twist(twist, msg.header.stamp)
        else:
            self.publish_twist(twist, self.get_clock().now().to_msg())
        self.publish_events()

    def on_goal(self, msg: DriveGoalMsg) -> None:
        """The team tick's word for this robot."""
        try:
            goal = goal_from_message(msg)
        except GoalError as exc:
            self.errors["drive/goal"] = str(exc)
            self.get_logger().error(str(exc))
            self.status_pub.publish(DriveStatus(goal=msg, status=DriveStatus.STATUS_ABORTED))
            self.stuck_pub.publish(Bool(data=True))
            return
        self.errors.pop("drive/goal", None)
        self.core.submit(goal, self._now())
        self.publish_events()
        self.enforce()

    def on_behaviour(self, msg: UInt16) -> None:
        """``mode: free``: the controller's word, run when idle."""
        if self.params.mode == "free":
            self.core.on_word(int(msg.data), self._now())
            self.publish_events()

    def on_override(self, msg: TwistStamped) -> None:
        """The operator's drive: in charge while fresh."""
        self.core.on_override(Twist2D(msg.twist.linear.x, msg.twist.angular.z), self._now())
        self.enforce()

    def on_estop(self, msg: Bool) -> None:
        """``/team/estop``: stop at once when latched."""
        self.gate.on_estop(msg.data)
        self.enforce()

    def on_heartbeat(self, msg: TeamState) -> None:
        """``/team/heartbeat``: the team state."""
        self.gate.on_heartbeat(msg.state, self._now())
        self.enforce()

    def on_enabled(self, msg: Bool) -> None:
        """``enabled``: this robot may move."""
        self.gate.on_enabled(msg.data)
        self.enforce()

    def on_armed(self, msg: TeamArmed) -> None:
        """``/team/armed``: an arming (a re-arm ends a latched link loss)."""
        self.gate.on_armed(msg.stamp.sec, msg.stamp.nanosec, msg.armings)
        self.enforce()

    # --- outputs ----------------------------------------------------------------------------

    def enforce(self) -> None:
        """The safety check: publish the forced twist (zero, or the override) if any."""
        if self.cmd_pub is None:
            return
        twist = self.core.check(self._now())
        if twist is not None:
            self.publish_twist(twist, self.get_clock().now().to_msg())
        if self.core.operator != self._operator_sent:
            self._operator_sent = self.core.operator
            self.operator_pub.publish(Bool(data=self.core.operator))
        self.publish_events()

    def publish_twist(self, twist: Twist2D, stamp) -> None:
        """``cmd_vel`` in the robot's body frame (``drive_type``: stamped or plain)."""
        body = Twist()
        body.linear.x = float(twist.linear)
        body.angular.z = float(twist.angular)
        if not self.stamped:
            self.cmd_pub.publish(body)
            return
        msg = TwistStamped(twist=body)
        msg.header.stamp = stamp
        msg.header.frame_id = self.frame
        self.cmd_pub.publish(msg)

    def publish_events(self) -> None:
        """Statuses, U1 and the power mode the core reported."""
        for event in self.core.drain():
            match event:
                case SetThrottle(on):
                    self.throttle_pub.publish(Bool(data=on))
                case ReportStatus(goal, code, stuck):
                    self.status_pub.publish(status_message(goal, code))
                    if code in TERMINAL:
                        self.stuck_pub.publish(Bool(data=bool(stuck)))
                case _:
                    assert_never(event)

    def publish_diagnostics(self) -> None:
        """OK while driving or ready; WARN while stopped (with why); ERROR on bad input.

        Also WARN when a pose of the last second came stamped more than
        ``clock_offset_limit`` ahead of this node's clock: the pose's clock runs ahead by at
        least that much (latency only makes a stamp older), which the message names.
        """
        c = self.core.counters
        lead, self.pose_lead = self.pose_lead, None
        if self.errors:
            level, message = DiagnosticStatus.ERROR, "; ".join(self.errors.values())
        elif self.core.stop_reason is not None:
            level, message = DiagnosticStatus.WARN, f"stopped: {self.core.stop_reason}"
        else:
            level = DiagnosticStatus.OK
            message = f"driving tick {self.core.goal.tick}" if self.core.busy else "ready"
        if lead is not None and lead > self.params.clock_offset_limit:
            level = max(level, DiagnosticStatus.WARN)
            message += (
                f"; pose clock offset: poses stamped {lead:.3f} s ahead of this node's clock "
                "(synchronise the clocks)"
            )
        elif lead is not None and -lead > self.params.pose_timeout:
            level = max(level, DiagnosticStatus.WARN)
            message += (
                f"; poses arrive but the youngest of the last second was {-lead:.3f} s old "
                f"(pose_timeout {self.params.pose_timeout:g} s): the localiser lags, or this "
                "node's clock runs ahead of the pose's (synchronise the clocks)"
            )
        self.diag_pub.publish(
            diagnostics(
                self,
                level,
                message,
                {
                    "goals": c.goals,
                    "goals_aborted": c.goals_aborted,
                    "primitives": c.primitives,
                    "primitives_aborted": c.primitives_aborted,
                    "control_cycles": c.cycles,
                    "last_failure": c.last_failure,
                    "active": self.gate.active,
                    "pose_clock_ahead": "" if lead is None else f"{lead:.3f}",
                },
                hardware_id=self.frame.split("/")[0],
            )
        )


_STOP: list[int] = []
"""Signals received: the spin loop ends at the next wake-up (raising from the handler could
land inside a middleware call and turn into a RuntimeError there)."""


def _interrupt(signum, frame) -> None:
    _STOP.append(signum)


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run drive_executor executor`` (configured and activated at start).

    There is no lifecycle manager in this environment: the program configures and activates
    its node itself; the gate still keeps the robot still until the team is armed.

    As ``excavation_common.ros.spin_node`` (a bad parameter: one line, exit code 2), except
    that SIGINT and SIGTERM are this program's, not rclpy's: rclpy's handlers shut ROS down
    before Python hears of the signal, and the node could no longer send its final zero
    twist (:meth:`ExecutorNode.destroy_node`).
    """
    from rclpy.executors import ExternalShutdownException
    from rclpy.signals import SignalHandlerOptions

    init_rclpy(args=args, signal_handler_options=SignalHandlerOptions.NO)
    signal.signal(signal.SIGINT, _interrupt)
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        node = ExecutorNode()
    except FieldError as exc:
        print(f"error: {exc}", file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    try:
        node.trigger_configure()
        node.trigger_activate()
        while not _STOP and rclpy.ok():
            rclpy.spin_once(node, timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
