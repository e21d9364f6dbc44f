"""The executor node: lifecycle, the drive action (results, preemption, cancel, rejection,
feedback), the team gate over real topics, the override, diagnostics, the stamp and type of
``cmd_vel``, the final stop."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time

import pytest
from diagnostic_msgs.msg import DiagnosticStatus
from excavation_interfaces.action import Drive
from excavation_interfaces.msg import DriveStatus as GoalStatus
from excavation_interfaces.msg import TeamArmed, TeamState
from geometry_msgs.msg import PoseWithCovarianceStamped, Twist, TwistStamped
from helpers.diagnostics import DiagnosticsProbe, values
from rclpy.action import ActionClient
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.time import Time
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Bool

from ant_controller.layout import MOVE_FORWARD, TURN_RIGHT
from drive_executor.executor_node import ExecutorNode
from drive_executor.goals import DriveGoal, goal_message
from excavation_common.frames import robot_center
from excavation_common.ros import LATCHED
from excavation_common.safety import ARMED, DISARMED


class Base(Node):
    """The test's robot base and team supervisor: a plant on cmd_vel, poses, team state."""

    def __init__(self, context):
        super().__init__("base", context=context)
        self.x, self.y = robot_center(4, 4, 0.25)
        self.yaw = math.pi / 2
        self.twists: list[tuple[float, TwistStamped]] = []
        self.statuses: list[int] = []
        self.pose_pub = self.create_publisher(PoseWithCovarianceStamped, "/robot_0/pose", 10)
        self.drive = ActionClient(self, Drive, "/robot_0/drive")
        self.handles: dict[int, object] = {}  # tick -> the client's goal handle
        self.results: dict[int, tuple] = {}  # tick -> (status, stuck, reason); None: rejected
        self.feedback: list[tuple[int, int, int]] = []  # (tick, done, total)
        self.override_pub = self.create_publisher(TwistStamped, "/robot_0/drive/override", 10)
        self.estop_pub = self.create_publisher(Bool, "/team/estop", LATCHED)
        self.enabled_pub = self.create_publisher(Bool, "/robot_0/enabled", LATCHED)
        self.heart_pub = self.create_publisher(TeamState, "/team/heartbeat", 10)
        self.create_subscription(TwistStamped, "/robot_0/cmd_vel", self.on_twist, 10)
        self.create_subscription(
            GoalStatus, "/robot_0/drive/status", lambda m: self.statuses.append(m.status), 10
        )
        self.stuck: list[bool] = []  # U1, once per goal that ended
        self.throttle: list[bool] = []  # the power mode of every goal started
        self.create_subscription(Bool, "/robot_0/stuck", lambda m: self.stuck.append(m.data), 10)
        self.create_subscription(
            Bool, "/robot_0/drive/throttle", lambda m: self.throttle.append(m.data), LATCHED
        )
        self.beating = True
        self.posing = True  # False: the localiser stops reporting (the pose goes stale)
        self.state = ARMED  # what the heartbeat says
        self.create_timer(0.05, self.tick)

    def on_twist(self, msg):
        self.twists.append((time.monotonic(), msg))

    def send(self, tick: int, word: int = 1 << MOVE_FORWARD) -> None:
        """The team tick's goal for robot 0 (the drive action)."""
        goal = Drive.Goal(goal=goal_message(DriveGoal(tick, 0, 0, 0, (tick, 0))))
        goal.goal.word = word  # unchecked: a bad word reaches the server as sent
        sent = self.drive.send_goal_async(
            goal,
            feedback_callback=lambda m: self.feedback.append(
                (m.feedback.tick, m.feedback.done, m.feedback.total)
            ),
        )
        sent.add_done_callback(lambda f: self.on_response(tick, f.result()))

    def on_response(self, tick: int, handle) -> None:
        self.handles[tick] = handle
        if not handle.accepted:
            self.results[tick] = None
            return
        handle.get_result_async().add_done_callback(
            lambda f: self.results.__setitem__(
                tick, (f.result().status, f.result().result.stuck, f.result().result.reason)
            )
        )

    def tick(self):
        if self.twists:
            tw = self.twists[-1][1].twist
            self.x += tw.linear.x * math.cos(self.yaw) * 0.05
            self.y += tw.linear.x * math.sin(self.yaw) * 0.05
            self.yaw += tw.angular.z * 0.05
        msg = PoseWithCovarianceStamped()
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = "map"
        msg.pose.pose.position.x, msg.pose.pose.position.y = self.x, self.y
        msg.pose.pose.orientation.z = math.sin(self.yaw / 2)
        msg.pose.pose.orientation.w = math.cos(self.yaw / 2)
        if self.posing:
            self.pose_pub.publish(msg)
        if self.beating:
            self.heart_pub.publish(TeamState(stamp=msg.header.stamp, state=self.state))

    def moving(self) -> bool:
        return bool(self.twists) and abs(self.twists[-1][1].twist.linear.x) > 1e-6

    def stopped_after(self, t0: float) -> bool:
        return any(t >= t0 and m.twist.linear.x == 0.0 for t, m in self.twists)

    def first_zero_after(self, t0: float) -> int:
        """Index of the first zero twist received at or after ``t0`` (one must exist)."""
        return next(
            i for i, (t, m) in enumerate(self.twists) if t >= t0 and m.twist.linear.x == 0.0
        )


def make_rig(ros, **params):
    """The test's base and supervisor, and robot 0's executor with ``params``."""
    base = ros.add(Base(ros.context))
    overrides = {"progress_window": 5.0} | params
    node = ros.add(
        ExecutorNode(
            context=ros.context,
            namespace="/robot_0",
            parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()],
        )
    )
    base.estop_pub.publish(Bool(data=False))
    base.enabled_pub.publish(Bool(data=True))
    return ros, base, node


@pytest.fixture
def rig(ros):
    return make_rig(ros)


def wait_matched(ros, base, node):
    assert ros.spin_until(
        lambda: (
            node.cmd_pub.get_subscription_count() > 0
            and base.drive.server_is_ready()
            and base.override_pub.get_subscription_count() > 0
            and node.gate.allowed(node.get_clock().now().nanoseconds * 1e-9)
        ),
        5,
    )


def send_goal(base, tick):
    base.send(tick)


def driving(rig):
    """The rig's executor configured, active and armed, driving its goal of tick 0."""
    ros, base, node = rig
    node.trigger_configure()
    node.trigger_activate()
    wait_matched(ros, base, node)
    send_goal(base, 0)
    assert ros.spin_until(base.moving, 5)
    return ros, base, node


def test_nothing_moves_before_activation_then_the_goal_drives(rig):
    ros, base, node = rig
    node.trigger_configure()
    ros.spin_until(lambda: node.cmd_pub.get_subscription_count() > 0, 5)
    assert ros.spin_until(base.drive.server_is_ready, 5)
    send_goal(base, 0)
    assert ros.spin_until(lambda: 0 in base.results, 5)
    assert base.twists == []  # configured, not active: the lifecycle publisher is silent
    assert base.results[0] == (GoalStatus.STATUS_ABORTED, True, "not active (lifecycle)")
    node.trigger_activate()
    wait_matched(ros, base, node)  # armed, enabled, heard (a goal before would abort)
    send_goal(base, 1)
    assert ros.spin_until(base.moving, 5)
    assert base.twists[-1][1].header.frame_id == "robot_0/base_link"
    done = ros.spin_until(lambda: GoalStatus.STATUS_SUCCEEDED in base.statuses, 10)
    assert done, (base.statuses, node.core.counters, base.x, base.y)
    # each event as its message: the goal's power mode, its statuses, U1 once it ended
    assert ros.spin_until(lambda: base.stuck and base.throttle, 5)
    assert base.statuses == [GoalStatus.STATUS_EXECUTING, GoalStatus.STATUS_SUCCEEDED]
    assert base.stuck == [False] and base.throttle == [False]
    # the action's result and feedback: the moves done of the goal's total
    assert ros.spin_until(lambda: 1 in base.results, 5)
    assert base.results[1] == (GoalStatus.STATUS_SUCCEEDED, False, "")
    assert base.feedback and base.feedback[0] == (1, 0, base.feedback[0][2])
    assert base.feedback[0][2] >= 1 and all(t == 1 for t, _, _ in base.feedback)


@pytest.mark.parametrize(
    "stop", ["estop", "disable", "heartbeat", "disarmed", "stale_pose", "deactivate"]
)
def test_stops_at_once_and_stays_stopped(rig, stop):
    """Every stop the executor node owns zeroes ``cmd_vel`` and keeps it at zero.

    Order, not wall-clock margins: after the event the test waits for the first zero twist;
    every twist after that one must be zero too, and a new goal must not move the robot.
    """
    ros, base, node = driving(rig)
    t0 = time.monotonic()
    if stop == "estop":
        base.estop_pub.publish(Bool(data=True))
    elif stop == "disable":
        base.enabled_pub.publish(Bool(data=False))
    elif stop == "heartbeat":
        base.beating = False
    elif stop == "disarmed":
        base.state = DISARMED
    elif stop == "stale_pose":
        base.posing = False
    else:
        node.trigger_deactivate()
    assert ros.spin_until(lambda: base.stopped_after(t0), 5)
    first = base.first_zero_after(t0)
    print(f"{stop}: zero cmd_vel {(base.twists[first][0] - t0) * 1000:.1f} ms after the event")
    assert ros.spin_until(lambda: GoalStatus.STATUS_ABORTED in base.statuses, 5)
    # the action goal ends aborted, with why
    assert ros.spin_until(lambda: 0 in base.results, 5)
    status, stuck, reason = base.results[0]
    assert status == GoalStatus.STATUS_ABORTED and stuck and reason, base.results
    send_goal(base, 1)  # still stopped: the new goal is refused, nothing moves
    count = len(base.twists)
    if stop != "deactivate":  # inactive: silent (the base's cmd_vel_timeout is the rest)
        # Live: the safety loop keeps sending (zero) twists after the refused goal.
        assert ros.spin_until(lambda: len(base.twists) >= count + 5, 5)
    else:
        ros.spin_until(lambda: False, 0.5)
        assert len(base.twists) == count
    assert all(m.twist.linear.x == 0.0 and m.twist.angular.z == 0.0 for _, m in base.twists[first:])


def test_a_newer_goal_preempts_the_running_one(rig):
    """A newer tick's goal supersedes the running one: aborted (stuck, with why), then the
    new one runs to its end."""
    ros, base, node = driving(rig)
    base.send(1, 1 << TURN_RIGHT)
    assert ros.spin_until(lambda: 0 in base.results and 1 in base.results, 15), base.results
    assert base.results[0] == (GoalStatus.STATUS_ABORTED, True, "superseded by tick 1")
    assert base.results[1] == (GoalStatus.STATUS_SUCCEEDED, False, "")
    assert base.stuck == [True, False]


def test_a_cancelled_goal_stops_the_robot_and_ends_cancelled(rig):
    """The client cancels: zero twist, result CANCELED (stuck), drive/status says so too."""
    ros, base, node = driving(rig)
    assert ros.spin_until(lambda: 0 in base.handles, 5)
    t0 = time.monotonic()
    base.handles[0].cancel_goal_async()
    assert ros.spin_until(lambda: 0 in base.results, 5)
    assert base.results[0] == (GoalStatus.STATUS_CANCELED, True, "canceled by the client")
    assert ros.spin_until(lambda: base.stopped_after(t0), 5)
    assert base.statuses[-1] == GoalStatus.STATUS_CANCELED and base.stuck == [True]
    count = len(base.twists)
    ros.spin_until(lambda: len(base.twists) > count + 3, 1.0)
    assert all(m.twist.linear.x == 0.0 for _, m in base.twists[count - 1 :])


def test_a_goal_it_cannot_run_is_rejected_and_said_why(rig):
    """A word with bits beyond the 12 behaviours: rejected, reported stuck, nothing moves."""
    ros, base, node = rig
    node.trigger_configure()
    node.trigger_activate()
    wait_matched(ros, base, node)
    base.send(0, 0x1000 | 1 << MOVE_FORWARD)
    assert ros.spin_until(lambda: 0 in base.results, 5)
    assert base.results[0] is None and base.stuck == [True]
    assert "beyond the 12 behaviours" in node.errors["drive"]
    assert not base.moving()


def test_override_wins_while_fresh_clamped_estop_wins_over_it(rig):
    ros, base, node = rig
    node.trigger_configure()
    node.trigger_activate()
    wait_matched(ros, base, node)
    operator: list[bool] = []  # drive/operator: latched, false until the override drives
    base.create_subscription(
        Bool, "/robot_0/drive/operator", lambda m: operator.append(m.data), LATCHED
    )
    assert ros.spin_until(lambda: operator == [False], 5)
    override = TwistStamped()
    override.twist.linear.x, override.twist.angular.z = 9.0, 0.0
    base.override_pub.publish(override)
    limit = node.params.throttle_speed
    assert ros.spin_until(
        lambda: base.twists and base.twists[-1][1].twist.linear.x == pytest.approx(limit), 3
    )
    assert ros.spin_until(lambda: operator[-1] is True, 5)
    # Stale (no new override within override_timeout): back to zero, and it stays there.
    assert ros.spin_until(lambda: base.twists[-1][1].twist.linear.x == 0.0, 5)
    assert ros.spin_until(lambda: operator == [False, True, False], 5)  # handed back
    count = len(base.twists)
    assert ros.spin_until(lambda: len(base.twists) >= count + 5, 5)
    assert all(m.twist.linear.x == 0.0 for _, m in base.twists[count - 1 :])
    base.override_pub.publish(override)
    assert ros.spin_until(lambda: base.twists[-1][1].twist.linear.x == pytest.approx(limit), 3)
    t0 = time.monotonic()
    base.estop_pub.publish(Bool(data=True))
    assert ros.spin_until(lambda: base.stopped_after(t0), 5)
    first = base.first_zero_after(t0)
    for _ in range(5):  # the operator keeps streaming: the e-stop still wins
        base.override_pub.publish(override)
        count = len(base.twists)
        assert ros.spin_until(lambda count=count: len(base.twists) > count, 5)
    assert all(m.twist.linear.x == 0.0 for _, m in base.twists[first:])


def test_bad_parameter_is_one_clear_error(ros):
    from excavation_common.params import ParameterError

    with pytest.raises(ParameterError, match="max_speed"):
        ExecutorNode(context=ros.context, parameter_overrides=[Parameter("max_speed", value=-1.0)])


def test_the_last_command_is_a_stop_when_the_node_is_destroyed(rig):
    """Destroyed while driving (its process ends): a zero twist is its last ``cmd_vel``."""
    ros, base, node = driving(rig)
    ros.executor.remove_node(node)
    node.destroy_node()
    assert ros.spin_until(lambda: base.twists[-1][1].twist.linear.x == 0.0, 5)
    count = len(base.twists)
    ros.spin_until(lambda: len(base.twists) > count, 0.5)  # nothing comes after it
    assert len(base.twists) == count


def test_sigint_to_the_executor_program_sends_a_stop_before_it_exits(rig):
    """``ros2 run drive_executor executor`` stopped with Ctrl-C (the dome's shutdown) while its
    robot drives: its last ``cmd_vel`` is a stop, sent while ROS is still up."""
    ros, base, _ = rig  # the rig's in-process executor stays unconfigured: silent
    diagnostics = DiagnosticsProbe(base).statuses
    env = dict(os.environ, ROS_DOMAIN_ID=str(ros.domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    cmd = [sys.executable, "-m", "drive_executor.executor_node", "--ros-args"]
    cmd += ["-r", "__ns:=/robot_0", "-r", "__node:=program", "-p", "progress_window:=5.0"]
    proc = subprocess.Popen(cmd, env=env, stderr=subprocess.PIPE, text=True)
    try:
        # ready: active, armed, enabled and on fresh poses (it says so once a second)
        assert ros.spin_until(
            lambda: any(d.name == "/robot_0/program" and d.message == "ready" for d in diagnostics),
            60,
        ), diagnostics[-3:]
        send_goal(base, 0)
        assert ros.spin_until(base.moving, 10)
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=30) == 0, proc.stderr.read()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert ros.spin_until(lambda: base.twists[-1][1].twist.linear.x == 0.0, 5)


class Clocked(Node):
    """The node clock in the test's hand (``/clock``), poses, and what the executor sends."""

    def __init__(self, context, cmd_type=TwistStamped):
        super().__init__("clocked", context=context)
        self.clock_pub = self.create_publisher(Clock, "/clock", 10)
        self.pose_pub = self.create_publisher(PoseWithCovarianceStamped, "/robot_0/pose", 10)
        self.cmds: list = []
        self.create_subscription(cmd_type, "/robot_0/cmd_vel", self.cmds.append, 10)
        self.diagnostics = DiagnosticsProbe(self).statuses

    def pose(self, seconds: float) -> None:
        msg = PoseWithCovarianceStamped()
        msg.header.stamp = Time(seconds=seconds).to_msg()
        msg.header.frame_id = "map"
        msg.pose.pose.position.x, msg.pose.pose.position.y = robot_center(4, 4, 0.25)
        msg.pose.pose.orientation.w = 1.0
        self.pose_pub.publish(msg)


NOW = 100.0


def clocked_executor(ros, cmd_type=TwistStamped, **params):
    """An active executor whose clock reads :data:`NOW` and stands still.

    Its safety loop is created at ``NOW`` and never comes due, so every ``cmd_vel`` it
    sends answers a pose the test sent.
    """
    probe = ros.add(Clocked(ros.context, cmd_type))
    overrides = [Parameter("use_sim_time", value=True)]
    overrides += [Parameter(k, value=v) for k, v in params.items()]
    node = ros.add(
        ExecutorNode(context=ros.context, namespace="/robot_0", parameter_overrides=overrides)
    )
    assert ros.spin_until(lambda: probe.clock_pub.get_subscription_count() > 0, 5)
    probe.clock_pub.publish(Clock(clock=Time(seconds=NOW).to_msg()))
    assert ros.spin_until(lambda: node._now() == NOW, 5)
    node.trigger_configure()
    node.trigger_activate()
    assert ros.spin_until(
        lambda: (
            probe.pose_pub.get_subscription_count() > 0
            and node.cmd_pub.get_subscription_count() > 0
        ),
        5,
    )
    return probe, node


def test_cmd_vel_is_stamped_when_sent_not_with_the_pose_it_answers(ros):
    """A pose 0.2 s old (camera, localiser) is answered by a command stamped now: a base's
    ``cmd_vel_timeout`` (diff_drive_controller) must not count the pose's latency."""
    probe, node = clocked_executor(ros)
    probe.pose(NOW - 0.2)
    assert ros.spin_until(lambda: probe.cmds, 5)
    assert node.core.counters.cycles == 1
    assert Time.from_msg(probe.cmds[0].header.stamp).nanoseconds == Time(seconds=NOW).nanoseconds
    assert probe.cmds[0].header.frame_id == "robot_0/base_link"


def test_the_simulators_lockstep_keeps_the_pose_stamp(ros):
    """``cmd_vel_stamp: pose`` (simulated runs): the step answered, ahead of ``/clock``."""
    probe, _ = clocked_executor(ros, cmd_vel_stamp="pose")
    probe.pose(NOW + 0.05)  # the step's /clock not taken yet
    assert ros.spin_until(lambda: probe.cmds, 5)
    stamp = Time.from_msg(probe.cmds[0].header.stamp)
    assert stamp.nanoseconds == Time(seconds=NOW + 0.05).nanoseconds


def test_drive_type_twist_publishes_a_plain_twist(ros):
    probe, node = clocked_executor(ros, Twist, drive_type="twist")
    probe.pose(NOW)
    assert ros.spin_until(lambda: probe.cmds, 5)
    assert isinstance(probe.cmds[0], Twist) and probe.cmds[0].linear.x == 0.0


def test_a_pose_clock_ahead_is_reported_with_its_offset(ros):
    """Poses stamped 30 ms ahead of the node's clock: WARN on /diagnostics naming 0.030 s."""
    probe, node = clocked_executor(ros)
    name = node.get_fully_qualified_name()

    def warned():
        probe.pose(NOW + 0.03)
        return any(d.name == name and "0.030 s ahead" in d.message for d in probe.diagnostics)

    assert ros.spin_until(warned, 5), [d.message for d in probe.diagnostics]
    status = next(d for d in probe.diagnostics if "0.030 s ahead" in d.message)
    assert status.level == DiagnosticStatus.WARN and "pose clock offset" in status.message
    assert values(status)["pose_clock_ahead"] == "0.030"


def test_poses_all_older_than_the_timeout_are_reported_as_a_lag_or_a_clock_ahead(ros):
    """Every pose 1 s old (this node's clock 1 s ahead of the localiser's): the robot stays
    still and /diagnostics names the youngest pose's age and both causes."""
    probe, node = clocked_executor(ros)
    name = node.get_fully_qualified_name()

    def warned():
        probe.pose(NOW - 1.0)
        return any(d.name == name and "youngest" in d.message for d in probe.diagnostics)

    assert ros.spin_until(warned, 5), [d.message for d in probe.diagnostics]
    status = next(d for d in probe.diagnostics if "youngest" in d.message)
    assert status.level == DiagnosticStatus.WARN
    assert "1.000 s old" in status.message and "clock runs ahead" in status.message
    assert all(c.twist.linear.x == 0.0 and c.twist.angular.z == 0.0 for c in probe.cmds)


def test_on_a_robot_host_a_returning_link_moves_nothing_until_a_re_arm(ros):
    """``rearm_after_loss``: the heartbeat stops (the link dropped) and comes back armed."""
    _, base, node = make_rig(ros, rearm_after_loss=True)
    armed_pub = base.create_publisher(TeamArmed, "/team/armed", LATCHED)
    armed_pub.publish(TeamArmed(stamp=Time(seconds=100).to_msg(), armings=1))
    node.trigger_configure()
    node.trigger_activate()
    wait_matched(ros, base, node)
    send_goal(base, 0)
    assert ros.spin_until(base.moving, 5)
    t0 = time.monotonic()
    base.beating = False  # the link drops
    assert ros.spin_until(lambda: base.stopped_after(t0), 5)
    first = base.first_zero_after(t0)
    base.beating = True  # it returns: armed heartbeats again
    seen = node.gate.heartbeat_time
    assert ros.spin_until(lambda: node.gate.heartbeat_time != seen, 5)
    assert node.gate.link_lost
    send_goal(base, 1)
    count = len(base.twists)
    assert ros.spin_until(lambda: len(base.twists) >= count + 5, 5)
    assert all(m.twist.linear.x == 0.0 for _, m in base.twists[first:])
    now = node.get_clock().now().nanoseconds * 1e-9
    assert node.gate.reason(now) == "heartbeat lost earlier: waiting for the operator to re-arm"
    armed_pub.publish(TeamArmed(stamp=Time(seconds=200).to_msg(), armings=2))  # re-armed
    assert ros.spin_until(lambda: not node.gate.link_lost, 5)
    send_goal(base, 2)
    assert ros.spin_until(base.moving, 5)
