"""The supervisor node over ROS, and ant-operator against it and against nothing."""

from __future__ import annotations

import re
import threading

from excavation_interfaces.msg import TeamState
from helpers.operator import operator
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import Bool

from excavation_common.messages import pose_message
from excavation_common.ros import LATCHED
from team_supervisor.supervisor_node import SupervisorNode


def watch(ros, robots=2):
    from geometry_msgs.msg import PoseWithCovarianceStamped

    node = ros.add(Node("watch", context=ros.context))
    node.heartbeats, node.estop, node.enabled = [], [], {k: [] for k in range(robots)}
    node.create_subscription(TeamState, "/team/heartbeat", node.heartbeats.append, 10)
    node.create_subscription(Bool, "/team/estop", lambda m: node.estop.append(m.data), LATCHED)
    for k in range(robots):
        node.create_subscription(
            Bool, f"/robot_{k}/enabled", lambda m, k=k: node.enabled[k].append(m.data), LATCHED
        )
    node.poses = [
        node.create_publisher(PoseWithCovarianceStamped, f"/robot_{k}/pose", 10)
        for k in range(robots)
    ]
    return node


def test_heartbeat_estop_and_enables_over_ros(ros):
    from std_srvs.srv import SetBool, Trigger

    sup = ros.add(
        SupervisorNode(
            context=ros.context,
            parameter_overrides=[
                Parameter("robots", value=2),
                Parameter("lost_timeout", value=1.5),
                Parameter("lost_grace", value=2.0),
            ],
        )
    )
    w = watch(ros)
    assert ros.spin_until(lambda: len(w.heartbeats) >= 3 and w.estop and all(w.enabled.values()))
    assert w.heartbeats[-1].state == "disarmed" and w.estop[-1] is False
    assert w.enabled[0][-1] and w.enabled[1][-1]

    def call(kind, name, request):
        client = w.create_client(kind, name)
        assert client.wait_for_service(timeout_sec=10)
        future = client.call_async(request)
        assert ros.spin_until(future.done)
        return future.result()

    assert call(Trigger, "/supervisor/arm", Trigger.Request()).success
    assert ros.spin_until(lambda: w.heartbeats[-1].state == "armed")
    assert call(Trigger, "/supervisor/estop", Trigger.Request()).success
    assert ros.spin_until(lambda: w.estop[-1] is True and w.heartbeats[-1].state == "estop")
    refused = call(Trigger, "/supervisor/arm", Trigger.Request())
    assert not refused.success and "reset first" in refused.message
    assert call(Trigger, "/supervisor/reset", Trigger.Request()).success
    # The latched e-stop topic changes at once, the heartbeat with its next beat (seen in a
    # rehearsal: the last heartbeat still said "estop" when the e-stop said false).
    assert ros.spin_until(lambda: w.estop[-1] is False and w.heartbeats[-1].state == "disarmed")
    assert call(SetBool, "/robot_1/enable", SetBool.Request(data=False)).success
    assert ros.spin_until(lambda: w.enabled[1][-1] is False)
    assert (
        "robot 1: disabled (operator)"
        in call(Trigger, "/supervisor/status", Trigger.Request()).message
    )
    assert call(SetBool, "/robot_1/enable", SetBool.Request(data=True)).success
    # Robot 1's poses stop while robot 0's keep coming: stopped at once, then disabled.
    for t in range(6):
        w.poses[0].publish(pose_message(2, 2, 0, 0.25, 0.01, 0.01, stamp=_stamp(t)))
        if t == 0:
            w.poses[1].publish(pose_message(5, 5, 0, 0.25, 0.01, 0.01, stamp=_stamp(t)))
        ros.spin_until(lambda t=t: sup.team.members[0].last_stamp == t, timeout=5)
    assert ros.spin_until(lambda: w.enabled[1][-1] is False)
    assert sup.team.members[1].disabled_reason == "lost" and w.enabled[0][-1] is True


def _stamp(t):
    from builtin_interfaces.msg import Time

    return Time(sec=t)


def test_operator_against_a_running_supervisor(ros):
    from helpers.diagnostics import DiagnosticsProbe

    ros.add(SupervisorNode(context=ros.context, parameter_overrides=[Parameter("robots", value=2)]))
    probe = DiagnosticsProbe(ros.add(Node("probe", context=ros.context)))
    results = {}

    def run():
        results["arm"] = operator(ros.domain, "arm")
        results["pause"] = operator(ros.domain, "pause")
        results["arm again"] = operator(ros.domain, "arm")
        results["disable"] = operator(ros.domain, "disable", "1")
        results["status"] = operator(ros.domain, "status")
        results["blade"] = operator(ros.domain, "blade", "0", "0.05", "--for", "0.3", timeout="2")

    thread = threading.Thread(target=run)
    thread.start()
    ros.spin_until(lambda: not thread.is_alive(), timeout=120)
    thread.join()
    assert results["arm"].returncode == 0 and "armed" in results["arm"].stdout
    # each action is named on /diagnostics with its origin (ant-dome's events log takes it)
    said = [v.value for st in probe.statuses for v in st.values if v.key == "last_control"]
    assert any(a.startswith("arm from the command line: done") for a in said), said
    assert any(a.startswith("disable 1 from the command line: done") for a in said), said
    assert not any(a.startswith("status") for a in said)
    assert results["pause"].returncode == 0
    assert results["arm again"].returncode == 1
    assert "paused: resume it" in results["arm again"].stderr
    assert results["disable"].returncode == 0
    status = results["status"].stdout
    assert "team paused" in status and "robot 1: disabled (operator)" in status
    # Nobody listens to robot 0's blade override here: a clear error, exit code 3.
    assert results["blade"].returncode == 3
    assert "no node subscribes to /robot_0/blade/commands" in results["blade"].stderr


def test_operator_against_nothing_is_a_clear_error(domains):
    result = operator(domains(), "estop", timeout="1")
    assert result.returncode == 3
    assert "no supervisor answers /supervisor/estop within 1 s" in result.stderr
    assert "Traceback" not in result.stderr
    bad = operator(domains(), "enable", "-1", timeout="1")
    assert bad.returncode == 2


def test_bad_parameter_is_one_line_and_exit_2(capsys):
    from team_supervisor.supervisor_node import main

    assert main(["supervisor", "--ros-args", "-p", "robots:=0"]) == 2
    err = capsys.readouterr().err
    assert "robots" in err and len(err.strip().splitlines()) == 1


def test_operator_drive_and_blade_overrides_stream_at_10_hz(ros):
    from geometry_msgs.msg import TwistStamped
    from std_msgs.msg import Float64MultiArray

    node = ros.add(Node("robot", context=ros.context))
    twists, blades = [], []
    node.create_subscription(TwistStamped, "/robot_1/drive/override", twists.append, 50)
    node.create_subscription(Float64MultiArray, "/robot_1/blade/commands", blades.append, 50)
    results = {}

    def run():
        results["drive"] = operator(ros.domain, "drive", "1", "0.2", "-0.5", "--for", "1.0")
        results["blade"] = operator(ros.domain, "blade", "1", "0.04", "--for", "0.5")

    thread = threading.Thread(target=run)
    thread.start()
    ros.spin_until(lambda: not thread.is_alive(), timeout=120)
    thread.join()
    assert results["drive"].returncode == 0, results["drive"].stderr
    sent = int(re.search(r"(\d+) drive overrides sent", results["drive"].stdout)[1])
    assert ros.spin_until(lambda: len(twists) >= sent, timeout=10)  # the operator saw acks
    assert len(twists) == sent  # every twist arrived, none twice
    # At most 10 Hz on the sender's clock (the stamps at least 0.1 s apart: a descheduled
    # sender sends fewer, never more), a stream that lasts, then one zero twist. Counts in
    # wall time are not asserted.
    stamps = [t.header.stamp.sec + t.header.stamp.nanosec * 1e-9 for t in twists]
    assert all(b - a >= 0.099 for a, b in zip(stamps[:-2], stamps[1:-1], strict=True))
    assert stamps[-2] - stamps[0] >= 0.5
    assert twists[0].header.frame_id == "robot_1/base_link"
    assert all((t.twist.linear.x, t.twist.angular.z) == (0.2, -0.5) for t in twists[:-1])
    assert (twists[-1].twist.linear.x, twists[-1].twist.angular.z) == (0.0, 0.0)
    assert results["blade"].returncode == 0, results["blade"].stderr
    assert ros.spin_until(lambda: blades and list(blades[-1].data) == [0.04], timeout=10)
