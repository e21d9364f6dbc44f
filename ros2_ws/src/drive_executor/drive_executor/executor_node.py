r"""``ros2 run drive_executor executor``: one robot's drive executor, a lifecycle node.

Run one per robot in its namespace, then configure and activate it (nothing moves before)::

    ros2 run drive_executor executor --ros-args -r __ns:=/robot_0 \\
        --params-file config/executor.yaml -p cell_size:=0.25

Serves the action ``drive`` (excavation_interfaces/action/Drive, in the robot's namespace:
``/robot_k/drive``) with ``rclpy.action``, as nav2's behaviour server serves ``Spin`` or
``BackUp``: the team tick's goal for a tick (:mod:`drive_executor.goals`) runs at once, a
newer goal preempts the running one (aborted, "superseded by tick t"), a cancel request ends
it at the next safety check (canceled, stuck), and an e-stop, a lost heartbeat, disarming,
the robot disabled or the node deactivated abort it, as the core decides
(:class:`DriveExecutorCore`; a pause suspends it until the team resumes). Feedback: the
primitives done of the goal's total; result: how it ended, U1 (``stuck``) and why. A goal
with bits beyond the 12 behaviours or an unknown turn is rejected.

Subscribes (relative names resolve in the robot's namespace): ``pose``
(PoseWithCovarianceStamped in ``map``; parameter ``pose_topic``) which closes the loop: each
pose runs one control step and is answered by one ``cmd_vel``; ``behaviour``
(std_msgs/UInt16, ``mode: free`` only); ``drive/override`` (TwistStamped, the
operator's drive); ``/team/estop`` (Bool, latched), ``/team/heartbeat`` (TeamState), ``/team/armed``
(TeamArmed, latched), ``enabled`` (Bool, latched).

Publishes: ``cmd_vel`` (parameter ``drive_type``: geometry_msgs/TwistStamped, frame
``robot_k/base_link``, as Jazzy's diff_drive_controller takes it, or geometry_msgs/Twist),
stamped with the node clock when it is sent (``cmd_vel_stamp: now``: a base's
``cmd_vel_timeout`` then counts from the command, not from the camera frame behind it; the
continuous simulator's lockstep takes ``pose``, the stamp of the pose answered),
``drive/status`` (excavation_interfaces/DriveStatus, with the goal: every change of every
goal's status, for the nodes that watch the drive without being its client: the blade
driver, the simulator, the supervisor, the bag), ``stuck`` (std_msgs/Bool,
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
from excavation_interfaces.action import Drive
from excavation_interfaces.msg import DriveStatus, TeamArmed, TeamState
from geometry_msgs.msg import PoseWithCovarianceStamped, Twist, TwistStamped
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from std_msgs.msg import Bool, UInt16

from drive_executor.core import DriveExecutorCore, ReportStatus, SetThrottle
from drive_executor.errors import GoalError
from drive_executor.goals import (
    CANCELED,
    TERMINAL,
    DriveGoal,
    goal_from_message,
    status_message,
)
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
        self.action_server: ActionServer | None = None
        self.handles: dict[int, tuple[DriveGoal, ServerGoalHandle]] = {}
        """The action's goals the core runs, by ``id`` of the core's goal (a goal object is
        the core's event's own, so a tick sent twice is still two goals)."""
        self.cancels: list[ServerGoalHandle] = []  # cancels accepted, ended at the next check
        self.feedback_sent: tuple[int, tuple[int, int]] | None = None  # (goal id, progress)
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
        self.action_server = ActionServer(
            self,
            Drive,
            "drive",
            execute_callback=self.refuse_execution,
            goal_callback=self.accept_goal,
            handle_accepted_callback=self.start_goal,
            cancel_callback=self.cancel_goal,
        )
        self._entities = [
            self.diag_pub,
            self.operator_pub,
            sub(PoseWithCovarianceStamped, self.params.pose_topic, self.on_pose, 10),
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
        if self.action_server is not None:
            self.action_server.destroy()
            self.action_server = None
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

    # --- the drive action ---------------------------------------------------------------------

    def accept_goal(self, request: Drive.Goal) -> GoalResponse:
        """Accept a readable goal; reject one the executor cannot run (and say why)."""
        try:
            goal_from_message(request.goal, "drive")
        except GoalError as exc:
            self.errors["drive"] = str(exc)
            self.get_logger().error(str(exc))
            if self.status_pub is not None:
                self.status_pub.publish(
                    DriveStatus(goal=request.goal, status=DriveStatus.STATUS_ABORTED)
                )
                self.stuck_pub.publish(Bool(data=True))
            return GoalResponse.REJECT
        self.errors.pop("drive", None)
        return GoalResponse.ACCEPT

    def start_goal(self, handle: ServerGoalHandle) -> None:
        """Run an accepted goal now (a running one is aborted first: superseded).

        The goal stays ``ACCEPTED`` while the core runs it and is executed (``EXECUTING``,
        then its terminal state) when the core ends it (:meth:`end_goal`): an execute
        coroutine waiting on the core would keep rclpy's single-threaded executor spinning
        without sleep for as long as the goal runs.
        """
        goal = goal_from_message(handle.request.goal, "drive")
        self.handles[id(goal)] = (goal, handle)
        self.core.submit(goal, self._now())
        self.publish_events()
        self.enforce()

    def refuse_execution(self, handle: ServerGoalHandle) -> Drive.Result:
        """Every goal is executed with its own result (:meth:`end_goal`); never called."""
        handle.abort()
        return Drive.Result(status=DriveStatus.STATUS_ABORTED, stuck=True, reason="not run")

    def cancel_goal(self, handle: ServerGoalHandle) -> CancelResponse:
        """Accept a cancel of a running goal; the next safety check stops it."""
        self.cancels.append(handle)
        return CancelResponse.ACCEPT

    def end_goal(self, goal: DriveGoal, code: int, stuck: bool, reason: str) -> int:
        """Give the action goal the core ended its terminal state and result.

        Returns the code to report: ``CANCELED`` where the client asked for the cancel.
        """
        entry = self.handles.pop(id(goal), None)
        if entry is None:
            return code  # a free-mode goal: no client
        handle = entry[1]
        if handle.is_cancel_requested:
            code, reason = CANCELED, reason or "canceled by the client"
        result = Drive.Result(status=code, stuck=stuck, reason=reason)

        def finish(h: ServerGoalHandle) -> Drive.Result:
            if code == CANCELED:
                h.canceled()
            elif code == DriveStatus.STATUS_SUCCEEDED:
                h.succeed()
            else:
                h.abort()
            return result

        handle.execute(finish)
        return code

    def run_cancels(self) -> None:
        """Stop the goals whose cancel was accepted (their state is now CANCELING)."""
        cancels, self.cancels = self.cancels, []
        # only the core's running goal has a handle (end_goal drops a goal's once it ends)
        goal = self.core.goal
        entry = self.handles.get(id(goal)) if goal is not None else None
        if entry is not None and any(handle is entry[1] for handle in cancels):
            self.core.abort("canceled by the client")
        self.publish_events()

    def publish_feedback(self) -> None:
        """The running action goal's progress, when it changed."""
        goal = self.core.goal
        entry = self.handles.get(id(goal)) if goal is not None else None
        progress = self.core.progress
        if entry is None or (id(goal), progress) == self.feedback_sent:
            return
        self.feedback_sent = (id(goal), progress)
        done, total = progress
        entry[1].publish_feedback(Drive.Feedback(tick=goal.tick, done=done, total=total))

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
        if self.cancels:
            self.run_cancels()
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
                case ReportStatus(goal, code, stuck, reason):
                    if code in TERMINAL:
                        code = self.end_goal(goal, code, bool(stuck), reason)
                    self.status_pub.publish(status_message(goal, code))
                    if code in TERMINAL:
                        self.stuck_pub.publish(Bool(data=bool(stuck)))
                case _:
                    assert_never(event)
        self.publish_feedback()

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
