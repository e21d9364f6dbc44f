"""The controller node: acts on fresh inputs, holds still and says why otherwise."""

from __future__ import annotations

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseWithCovarianceStamped
from helpers.diagnostics import DiagnosticsProbe, values
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import Image, Imu, JointState
from std_msgs.msg import Bool, UInt16

from ant_controller.controller import Controller, ControllerCore
from ant_controller.controller_node import ControllerNode, main
from ant_controller.layout import BLADE_HOME, R1
from blueprint_server.blueprint import default_blueprint
from blueprint_server.server_node import BlueprintServer
from excavation_common.constants import BladeGeometry
from excavation_common.messages import blade_joint, grid_to_image, imu_message, pose_message
from excavation_common.ros import LATCHED

POSES = [(5, 5, 0), (10, 3, 1)]  # robot 0 faces north into the pit, robot 1 east


class FakeRobots(Node):
    """Publishes what the simulator would: poses, height map, blade state, stuck flag."""

    def __init__(self, context):
        super().__init__("fake_robots", context=context)
        self.pose_pubs = [
            self.create_publisher(PoseWithCovarianceStamped, f"/robot_{j}/pose", 10)
            for j in range(2)
        ]
        self.heights_pub = self.create_publisher(Image, "/worksite/height_map", LATCHED)
        self.joint_pub = self.create_publisher(JointState, "/robot_0/blade/joint_states", 10)
        self.stuck_pub = self.create_publisher(Bool, "/robot_0/stuck", 10)
        self.imu_pub = self.create_publisher(Imu, "/robot_0/imu", 10)
        self.robots = [0, 1]
        self.pitch: float | None = None  # None: the IMU is silent
        self.heights = grid_to_image(np.zeros((16, 16), dtype=np.float32), "32FC1")

    def publish(self):
        for j in self.robots:
            self.pose_pubs[j].publish(pose_message(*POSES[j], 0.25, 0.01, 0.01))
        self.heights_pub.publish(self.heights)
        self.joint_pub.publish(blade_joint(BLADE_HOME, 0.0, BladeGeometry()))
        self.stuck_pub.publish(Bool(data=False))
        if self.pitch is not None:
            self.imu_pub.publish(imu_message(0.0, self.pitch, "robot_0/base_link"))


def start(ros, **params):
    ros.add(BlueprintServer(context=ros.context))
    overrides = [
        Parameter("robots", value=2),
        Parameter("rate", value=20.0),
        Parameter("pose_timeout", value=0.3),
    ]
    overrides += [Parameter(k, value=v) for k, v in params.items()]
    node = ros.add(
        ControllerNode(
            Controller.hand_coded(),
            context=ros.context,
            namespace="/robot_0",
            parameter_overrides=overrides,
        )
    )
    fake = ros.add(FakeRobots(ros.context))
    seen = {"behaviour": []}
    fake.create_subscription(
        UInt16, "/robot_0/behaviour", lambda m: seen["behaviour"].append(m.data), 10
    )
    seen["diag"] = DiagnosticsProbe(fake).named("/robot_0/controller")
    return node, fake, seen


def test_holds_still_until_inputs_arrive_then_acts(ros):
    node, fake, seen = start(ros)
    assert ros.spin_until(lambda: seen["diag"] and seen["behaviour"])
    assert seen["behaviour"][-1] == 0
    assert seen["diag"][-1].level == DiagnosticStatus.WARN
    assert "holding still" in seen["diag"][-1].message
    bp = default_blueprint(1)
    expected = ControllerCore(Controller.hand_coded()).decide(
        np.zeros((16, 16)), bp.zones, bp.goal, np.array(POSES), 0, BLADE_HOME, 0, False
    )
    assert expected != 0

    def acting():
        fake.publish()
        return seen["diag"][-1].level == DiagnosticStatus.OK

    assert ros.spin_until(acting)
    assert seen["behaviour"][-1] == expected
    # Robot 1 goes silent: robot 0 stops within the pose timeout and says why.
    fake.robots = [0]

    def stale():
        fake.publish()
        return "pose of robot 1 is stale" in seen["diag"][-1].message

    assert ros.spin_until(stale)
    assert seen["behaviour"][-1] == 0


def test_malformed_height_map_is_reported_and_dropped(ros):
    node, fake, seen = start(ros)
    fake.heights = grid_to_image(np.zeros((16, 16)), "mono8")

    def error():
        fake.publish()
        return seen["diag"] and seen["diag"][-1].level == DiagnosticStatus.ERROR

    assert ros.spin_until(error)
    assert "encoding" in seen["diag"][-1].message
    assert seen["behaviour"][-1] == 0


def test_bad_genome_exits_2_with_the_loaders_message(tmp_path, capsys):
    bad = tmp_path / "best.json"
    bad.write_text('{"format": "ant-genome/0"}')
    assert main(["controller", "--genome", str(bad)]) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "format" in err


def test_a_disabled_robot_is_absent_and_does_not_freeze_the_controller(ros):
    from excavation_common.safety import ENABLED_TOPIC

    node, fake, seen = start(ros)
    fake.robots = [0]  # robot 1 is never seen (the localiser lost it)
    enabled = fake.create_publisher(Bool, f"/robot_1/{ENABLED_TOPIC}", LATCHED)

    def waiting():
        fake.publish()
        return seen["diag"] and "no pose of robot 1" in seen["diag"][-1].message

    assert ros.spin_until(waiting)
    enabled.publish(Bool(data=False))  # the supervisor disables it
    bp = default_blueprint(1)
    alone = ControllerCore(Controller.hand_coded()).decide(
        np.zeros((16, 16)),
        bp.zones,
        bp.goal,
        np.array([POSES[0], (0, 0, 0)]),
        0,
        BLADE_HOME,
        0,
        False,
        active=np.array([True, False]),
    )

    def acting():
        fake.publish()
        return seen["diag"][-1].level == DiagnosticStatus.OK

    assert ros.spin_until(acting)
    assert seen["behaviour"][-1] == alone
    said = values(seen["diag"][-1])
    assert said["absent_robots"] == "[1]"


def test_bad_parameters_exit_2_with_one_line(capsys):
    for bad in (["-p", "rate:=0.0"], ["-p", "robots:=2", "-p", "robot_id:=2"]):
        assert main(["controller", "--hand-coded", "--ros-args", *bad]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
        assert ("rate" in err) if "rate" in bad[1] else ("outside the team of 2" in err)


def test_r1_from_the_imu_and_a_stale_imu_holds_the_robot_still(ros):
    """On flat ground the height map says R1 = 0: with ``tilt_source: imu`` the IMU decides."""
    node, fake, seen = start(ros, tilt_source="imu", imu_timeout=0.3)

    def waiting():
        fake.publish()
        return seen["diag"] and "no IMU reading" in seen["diag"][-1].message

    assert ros.spin_until(waiting)
    assert seen["behaviour"][-1] == 0
    for pitch, r1 in ((0.2, 1), (0.0, 0)):
        fake.pitch = pitch

        def acting(r1=r1):
            fake.publish()
            return seen["diag"][-1].level == DiagnosticStatus.OK and node.core.codes[R1] == r1

        assert ros.spin_until(acting)
    fake.pitch = None  # the IMU falls silent, every other input stays fresh

    def stale():
        fake.publish()
        return "IMU reading is stale" in seen["diag"][-1].message

    assert ros.spin_until(stale)
    assert seen["behaviour"][-1] == 0
