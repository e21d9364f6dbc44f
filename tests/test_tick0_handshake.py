"""Tick 0 of a full-perception lockstep trial: nothing of it may be lost to a connection the
middleware has not made yet.

* The synthetic sensors hold a frame (a sweep) until a subscriber of the camera (the laser)
  is matched: a lockstep tick has exactly one frame, and a frame nobody hears is lost.
* A controller publishes a latched ``ready`` once every input has a connected publisher.
* The simulator with ``wait_for_ready`` starts tick 0 only when every controller is ready.
"""

from __future__ import annotations

import time

import numpy as np
from builtin_interfaces.msg import Time as TimeMsg
from geometry_msgs.msg import PoseWithCovarianceStamped
from helpers.rigs import controller_node
from nav_msgs.msg import MapMetaData
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import Image, JointState, LaserScan
from std_msgs.msg import Bool, UInt16

from excavation_common.messages import grid_to_image, pose_message
from excavation_common.ros import LATCHED

ROWS = COLS = 16
CELL = 0.25


def reports_from(ros, node: Node, count: int = 2) -> None:
    """Spin until ``node`` has published ``count`` more ``/diagnostics`` statuses.

    The proof that a negative check ("nothing happened") was made while the node was live:
    every node here shares one executor, so by the time a node's periodic status (once a
    second or more often) came twice, its fast timers ran many times too. A fixed wait
    would pass trivially on a machine too slow to run the node at all.
    """
    from helpers.diagnostics import DiagnosticsProbe

    name = node.get_fully_qualified_name()
    probe = ros.add(Node(f"probe_{time.monotonic_ns()}", context=ros.context))
    heard = DiagnosticsProbe(probe).named(name)
    assert ros.spin_until(lambda: len(heard) >= count, timeout=60), f"{name} reported {heard}"
    ros.executor.remove_node(probe)
    probe.destroy_node()


def test_sensors_hold_a_frame_until_someone_listens(ros):
    from excavation_sim.sensors_node import SensorsNode

    sensors = ros.add(
        SensorsNode(
            context=ros.context,
            parameter_overrides=[
                Parameter("robots", value=1),
                Parameter("reliable", value=True),
            ],
        )
    )
    truth = ros.add(Node("truth", context=ros.context))
    stamp = TimeMsg(sec=0)
    pose_pub = truth.create_publisher(PoseWithCovarianceStamped, "/truth/robot_0/pose", 10)
    map_pub = truth.create_publisher(Image, "/truth/worksite/height_map", LATCHED)
    map_pub.publish(grid_to_image(np.zeros((ROWS, COLS)), "32FC1", stamp=stamp))
    assert ros.spin_until(lambda: pose_pub.get_subscription_count() > 0)
    assert ros.spin_until(lambda: sensors.heights is not None)
    pose_pub.publish(pose_message(5, 5, 0, CELL, 1e-4, 1e-3, stamp=stamp))
    assert ros.spin_until(lambda: sensors.ready is not None)  # the instant is rendered ...
    reports_from(ros, sensors)
    assert sensors.frames == 0 and sensors.ready is not None  # ... and held: nobody listens

    heard: dict[str, list] = {"image": [], "scan": [], "mount": []}
    listener = ros.add(Node("listener", context=ros.context))
    listener.create_subscription(Image, "/overhead/image_raw", heard["image"].append, 10)
    listener.create_subscription(LaserScan, "/worksite/scan", heard["scan"].append, 200)
    # a sweep also waits for the mount's listener: a scan without its mount state is lost
    mount = "/worksite/laser_mount/joint_states"
    listener.create_subscription(JointState, mount, heard["mount"].append, 200)
    scans = sensors.laser_params.sweep_scans
    assert ros.spin_until(
        lambda: heard["image"] and len(heard["scan"]) == len(heard["mount"]) == scans
    )
    assert sensors.frames == 1 and sensors.ready is None
    assert heard["image"][0].header.stamp.sec == 0


def controller_inputs(node: Node) -> list:
    """Publishers of every input of robot 0's controller in a one-robot team."""
    return [
        node.create_publisher(PoseWithCovarianceStamped, "/robot_0/pose", 10),
        node.create_publisher(Image, "/worksite/height_map", LATCHED),
        node.create_publisher(Image, "/blueprint/goal", LATCHED),
        node.create_publisher(Image, "/blueprint/zones", LATCHED),
        node.create_publisher(MapMetaData, "/worksite/map_info", LATCHED),
        node.create_publisher(JointState, "/robot_0/blade/joint_states", 10),
    ]


def test_controller_is_ready_once_every_input_is_connected(ros):
    controller = controller_node(ros, 0, 1)
    said: list[bool] = []
    inputs = ros.add(Node("inputs", context=ros.context))
    inputs.create_subscription(Bool, "/robot_0/ready", lambda m: said.append(m.data), LATCHED)
    pubs = controller_inputs(inputs)  # all but the stuck flag
    assert ros.spin_until(lambda: all(p.get_subscription_count() > 0 for p in pubs))
    reports_from(ros, controller)  # it checked its inputs since (its timer reports each time)
    assert not controller.ready and True not in said
    pubs.append(inputs.create_publisher(Bool, "/robot_0/stuck", 10))
    assert ros.spin_until(lambda: said and said[-1])  # latched: a late listener hears it too
    assert controller.ready
    inputs.destroy_publisher(pubs[0])  # the pose's publisher goes away
    assert ros.spin_until(lambda: said[-1] is False)
    assert not controller.ready


def unready_controller(ros, publishes: list, subscribes: list):
    """A stand-in for robot 0's controller: on the graph and connected, but not ready.

    Returns its latched ``/robot_0/ready`` publisher (``false`` sent).
    """
    robot = ros.add(Node("robot", context=ros.context))
    for msg_type, topic in publishes:
        robot.create_publisher(msg_type, topic, 10)
    for msg_type, topic in subscribes:
        robot.create_subscription(msg_type, topic, lambda m: None, 10)
    ready = robot.create_publisher(Bool, "/robot_0/ready", LATCHED)
    ready.publish(Bool(data=False))
    return ready


def test_simulator_waits_for_every_controller_to_be_ready(ros):
    from excavation_sim.sim_node import SimNode

    sim = ros.add(
        SimNode(
            context=ros.context,
            parameter_overrides=[
                Parameter("robots", value=1),
                Parameter("steps", value=3),
                Parameter("supervised", value=False),
                Parameter("startup_period", value=0.0),
                Parameter("wait_for_ready", value=True),
            ],
        )
    )
    ready = unready_controller(
        ros,
        [(UInt16, "/robot_0/behaviour")],
        [
            (PoseWithCovarianceStamped, "/robot_0/pose"),
            (Bool, "/robot_0/stuck"),
            (JointState, "/robot_0/blade/joint_states"),
        ],
    )
    reports_from(ros, sim)
    assert not sim.clock.started  # present and connected, but not ready: tick 0 waits
    ready.publish(Bool(data=True))
    assert ros.spin_until(lambda: sim.clock.started)


def test_simulator_waits_until_its_tick_reaches_each_controller(ros):
    """Another reader of a robot's topics (a recorder, a view) does not stand in for the
    robot's controller: tick 0 waits until the writers reach the controller itself."""
    from excavation_sim.sim_node import SimNode

    sim = ros.add(
        SimNode(
            context=ros.context,
            parameter_overrides=[
                Parameter("robots", value=1),
                Parameter("steps", value=3),
                Parameter("supervised", value=False),
                Parameter("startup_period", value=0.0),
            ],
        )
    )
    recorder = ros.add(Node("recorder", context=ros.context))
    for msg_type, topic in (
        (PoseWithCovarianceStamped, "/robot_0/pose"),
        (Bool, "/robot_0/stuck"),
        (JointState, "/robot_0/blade/joint_states"),
    ):
        recorder.create_subscription(msg_type, topic, lambda m: None, 10)
    # the controller: publishes its word and reads its pose and joint state, not yet U1
    controller = ros.add(Node("controller", namespace="/robot_0", context=ros.context))
    controller.create_publisher(UInt16, "behaviour", 10)
    controller.create_subscription(PoseWithCovarianceStamped, "pose", lambda m: None, 10)
    controller.create_subscription(JointState, "blade/joint_states", lambda m: None, 10)
    reports_from(ros, sim)
    assert not sim.clock.started  # the recorder reads /robot_0/stuck, the controller not yet
    controller.create_subscription(Bool, "stuck", lambda m: None, 10)
    assert ros.spin_until(lambda: sim.clock.started)


def test_team_tick_waits_for_every_controller_to_be_ready(ros):
    """The continuous trial's tick 0 as the lockstep simulator's: a recorder (or any other
    node) subscribed to the tick topics must not stand in for a controller that is not yet
    connected (seen: robot 1 missed tick 0 of a recorded process trial)."""
    from excavation_interfaces.action import Drive
    from excavation_interfaces.msg import DriveStatus
    from rclpy.action import ActionServer
    from team_tick.core import Phase
    from team_tick.node import TeamTickNode

    tick = ros.add(
        TeamTickNode(
            context=ros.context,
            parameter_overrides=[
                Parameter("robots", value=1),
                Parameter("steps", value=2),
                Parameter("startup_period", value=0.0),
                Parameter("wait_for_ready", value=True),
            ],
        )
    )
    ready = unready_controller(
        ros,
        [(UInt16, "/robot_0/behaviour"), (DriveStatus, "/robot_0/drive/status")],
        [
            (PoseWithCovarianceStamped, "/tick/robot_0/pose"),
            (Bool, "/tick/robot_0/stuck"),
            (JointState, "/robot_0/blade/servo_state"),
        ],
    )
    executor = ros.add(Node("executor", context=ros.context))  # the drive action's server
    ActionServer(executor, Drive, "/robot_0/drive", execute_callback=lambda h: Drive.Result())
    reports_from(ros, tick)
    assert tick.core.phase is Phase.WAITING  # present and connected, but not ready
    ready.publish(Bool(data=True))
    assert ros.spin_until(lambda: tick.core.phase is not Phase.WAITING)


def test_team_tick_node_sends_each_action_as_its_message(ros, tmp_path):
    """The node's dispatch on the core's action classes: each becomes its message."""
    import json

    from excavation_interfaces.action import Drive
    from excavation_interfaces.msg import Snapshot as SnapshotMsg
    from excavation_interfaces.msg import Tick
    from rclpy.action import ActionServer, GoalResponse
    from team_tick.core import (
        Finished,
        PublishTick,
        Report,
        RequestSnapshot,
        SendGoal,
        Snapshot,
        TickRecord,
    )
    from team_tick.node import TeamTickNode

    from drive_executor.goals import DriveGoal, goal_from_message

    result = tmp_path / "result.json"
    tick = ros.add(
        TeamTickNode(
            context=ros.context,
            parameter_overrides=[
                Parameter("robots", value=1),
                Parameter("result_file", value=str(result)),
            ],
        )
    )
    heard: dict[str, list] = {}
    probe = ros.add(Node("probe_actions", context=ros.context))
    for msg_type, topic, qos in [
        (SnapshotMsg, "/team/snapshot", 10),
        (Tick, "/team/tick", 10),
        (PoseWithCovarianceStamped, "/tick/robot_0/pose", 10),
        (Bool, "/tick/robot_0/stuck", 10),
        (Image, "/tick/worksite/height_map", LATCHED),
        (JointState, "/robot_0/blade/servo_state", 10),
    ]:
        heard[topic] = []
        probe.create_subscription(msg_type, topic, heard[topic].append, qos)
    heard["/robot_0/drive"] = []  # the goals the drive action's server is asked to run

    def on_goal(request):
        heard["/robot_0/drive"].append(request.goal)
        return GoalResponse.REJECT

    ActionServer(probe, Drive, "/robot_0/drive", lambda h: Drive.Result(), goal_callback=on_goal)
    sent = [tick.request_pub, tick.tick_pub, tick.heights_pub]
    sent += [tick.pose_pubs[0], tick.stuck_pubs[0], tick.blade_pubs[0]]
    assert ros.spin_until(
        lambda: (
            all(p.get_subscription_count() > 0 for p in sent) and tick.drives[0].server_is_ready()
        )
    )
    pose, blade, heights = PoseWithCovarianceStamped(), JointState(), Image()
    tick.core.records.append(TickRecord(3, [0x21], [-1], [True], [], 0.0, 0.5, 1.0))  # summary
    tick.execute(
        [
            RequestSnapshot(3, 2.5),
            PublishTick(3, 3.0, Snapshot((pose,), heights, (blade,), (True,))),
            SendGoal(robot=0, tick=3, stamp=3.0, word=0x21, turn=-1),
            Report("tick 3: a report"),
            Finished(),
        ]
    )
    assert ros.spin_until(lambda: all(heard.values()))
    stamp = TimeMsg(sec=3, nanosec=0)
    (request,) = heard["/team/snapshot"]
    assert request.tick == 3 and request.stamp == TimeMsg(sec=2, nanosec=500_000_000)
    (begun,) = heard["/team/tick"]
    assert begun.tick == 3 and begun.stamp == stamp
    assert [m.data for m in heard["/tick/robot_0/stuck"]] == [True]
    for topic in ("/tick/robot_0/pose", "/tick/worksite/height_map", "/robot_0/blade/servo_state"):
        assert [m.header.stamp for m in heard[topic]] == [stamp], topic
    (goal,) = heard["/robot_0/drive"]
    assert goal_from_message(goal) == DriveGoal(3, 0x21, -1, 0, (3, 0))
    assert tick.reports == ["tick 3: a report"]
    summary = json.loads(result.read_text())
    assert summary["reports"] == ["tick 3: a report"] and summary["commands"] == [[0x21]]


def test_a_recorded_dome_has_every_tick_topic_in_the_bag(ros):
    """In the dome the team tick republishes each blade state on ``blade/tick_state``; a
    recorder that leaves it out holds a recorded dome at tick 0 for ever (seen in the first
    recorded rehearsal: "waiting for the team"), so the suite's topics include it."""
    from team_tick.node import TeamTickNode

    from excavation_bags.topics import SUITE_TOPICS, topic_selected
    from excavation_bringup.nodes import DOME_BLADE_IN, DOME_BLADE_OUT

    tick = ros.add(
        TeamTickNode(
            context=ros.context,
            parameter_overrides=[
                Parameter("robots", value=2),
                Parameter("steps", value=1),
                Parameter("blade_in", value=DOME_BLADE_IN),
                Parameter("blade_out", value=DOME_BLADE_OUT),
                Parameter("snapshot_ack", value=False),
            ],
        )
    )
    from excavation_common.ros import UNRECORDED

    topics = [p.topic_name for p in tick.publishers if p.topic_name not in UNRECORDED]
    assert "/robot_1/blade/tick_state" in topics
    assert [t for t in topics if not topic_selected(t, SUITE_TOPICS)] == []
