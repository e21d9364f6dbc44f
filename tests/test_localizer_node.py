"""The localizer node: poses from frames; bad frames and configurations are reported."""

from __future__ import annotations

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseWithCovarianceStamped
from helpers.diagnostics import DiagnosticsProbe
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Image

from excavation_sim.camera import RobotView
from overhead_localizer.beacons import CONFIG_DIR
from overhead_localizer.errors import LocalizerConfigError
from overhead_localizer.images import frame_to_message
from overhead_localizer.localizer_node import LocalizerNode

VIEWS = [RobotView(1.0, 1.0, 0.0), RobotView(3.0, 3.0, np.pi / 2)]


@pytest.fixture(scope="module")
def frame(camera):
    return camera.render(VIEWS, np.zeros((16, 16)), np.random.default_rng(0))[0]


class Probe:
    """Publishes frames, collects poses and the latest diagnostics of each status."""

    def __init__(self, ros, robots=2):
        from rclpy.node import Node

        self.node = ros.add(Node("probe", context=ros.context))
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self.pub = self.node.create_publisher(Image, "/overhead/image_raw", qos)
        self.poses = {k: [] for k in range(robots)}
        for k in range(robots):
            self.node.create_subscription(
                PoseWithCovarianceStamped,
                f"/robot_{k}/pose",
                lambda m, k=k: self.poses[k].append(m),
                10,
            )
        self.status = DiagnosticsProbe(self.node).latest
        self.ros = ros

    def send(self, image_msg, sec):
        image_msg.header.stamp = Time(sec=sec)
        self.ros.spin_until(lambda: self.pub.get_subscription_count() > 0, 5.0)
        self.pub.publish(image_msg)


class Counted:
    """A publisher that also keeps what the node published (read in the node's own thread:
    a negative check on it is exact once the node has processed the frame)."""

    def __init__(self, publisher):
        self.publisher, self.sent = publisher, []

    def publish(self, msg) -> None:
        self.sent.append(msg)
        self.publisher.publish(msg)

    def __getattr__(self, name):
        return getattr(self.publisher, name)


def counted(node) -> tuple[list[Counted], Counted]:
    """Count ``node``'s pose publications per robot and its retake requests."""
    node.pose_pubs = [Counted(p) for p in node.pose_pubs]
    if node.retake_pub is not None:
        node.retake_pub = Counted(node.retake_pub)
    return node.pose_pubs, node.retake_pub


def localizer(ros, **params):
    overrides = [
        Parameter("calibration", value=str(CONFIG_DIR / "camera_sim.yaml")),
        Parameter("robots", value=2),
        Parameter("reliable", value=True),
        Parameter("use_height_map", value=False),
        Parameter("diagnostics_period", value=0.1),
    ] + [Parameter(k, value=v) for k, v in params.items()]
    return ros.add(LocalizerNode(context=ros.context, parameter_overrides=overrides))


def test_good_frame_gives_poses_with_covariance(ros, frame):
    localizer(ros)
    probe = Probe(ros)
    probe.send(frame_to_message(frame, Image()), 7)
    assert ros.spin_until(lambda: all(probe.poses.values()))
    for k, view in enumerate(VIEWS):
        pose = probe.poses[k][0]
        assert pose.header.stamp.sec == 7 and pose.header.frame_id == "map"
        assert abs(pose.pose.pose.position.x - view.x) < 0.04
        assert abs(pose.pose.pose.position.y - view.y) < 0.04
        cov = np.array(pose.pose.covariance).reshape(6, 6)
        assert 0 < cov[0, 0] < 0.01 and 0 < cov[5, 5] < 0.05 and cov[2, 2] == 1e6
    assert ros.spin_until(lambda: "/localizer: robot_1" in probe.status)
    assert probe.status["/localizer: robot_1"].level == DiagnosticStatus.OK


@pytest.mark.parametrize(
    "bad, match",
    [
        ("size", "height x width x channels = (480, 640, 3)"),
        ("encoding", "encoding = 'nv21': expected one of bgr8"),
        ("data", "data = "),
    ],
)
def test_bad_frames_are_reported_and_give_no_pose(ros, frame, bad, match):
    node = localizer(ros)
    probe = Probe(ros)
    if bad == "size":
        msg = frame_to_message(np.zeros((480, 640, 3), dtype=np.uint8), Image())
    else:
        msg = frame_to_message(frame, Image())
        if bad == "encoding":
            msg.encoding = "nv21"  # YUV 4:2:0: not a camera encoding the localizer reads
        else:
            msg.data = bytes(msg.data)[:-5]
    probe.send(msg, 3)

    def reported():
        s = probe.status.get("/localizer")
        return s is not None and s.level == DiagnosticStatus.ERROR and match in s.message

    assert ros.spin_until(reported)
    assert not any(probe.poses.values())
    probe.send(frame_to_message(frame, Image()), 4)  # still running
    assert ros.spin_until(lambda: all(probe.poses.values()))
    assert node.image_error is None


def test_no_calibration_refuses_to_start(ros, tmp_path):
    from excavation_common.params import ParameterError

    with pytest.raises(ParameterError, match="calibration = '': required"):
        LocalizerNode(context=ros.context)
    missing = [Parameter("calibration", value=str(tmp_path / "nowhere.yaml"))]
    with pytest.raises(LocalizerConfigError, match="does not exist"):
        LocalizerNode(context=ros.context, parameter_overrides=missing)


def test_no_calibration_is_one_line_and_exit_code_2(domain):
    import os
    import subprocess
    import sys

    env = dict(os.environ, ROS_DOMAIN_ID=str(domain))
    cmd = [sys.executable, "-m", "overhead_localizer.localizer_node"]
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "calibration = '': required" in lines[0]


def test_two_robots_with_the_same_colours(ros, frame, tmp_path):
    table = tmp_path / "beacons.yaml"
    table.write_text(
        "colours: {red: [0, 0, 255], green: [0, 255, 0], blue: [255, 40, 0],"
        " yellow: [0, 230, 255]}\n"
        "robots:\n  - {front: red, rear: green}\n  - {front: red, rear: green}\n"
    )
    node = localizer(ros, beacons=str(table))
    poses, _ = counted(node)
    probe = Probe(ros)
    probe.send(frame_to_message(frame, Image()), 2)

    def reported():
        s = probe.status.get("/localizer: robot_1")
        return s is not None and s.level == DiagnosticStatus.ERROR

    assert ros.spin_until(reported)
    assert "shares LED colours" in probe.status["/localizer: robot_0"].message
    assert ros.spin_until(lambda: node.frames == 1)  # the frame was processed ...
    assert not any(p.sent for p in poses)  # ... and gave no pose


def test_a_tracked_robot_unseen_asks_for_a_retake_and_holds_the_frame(ros, camera):
    """Frame 1 tracks both robots; frame 2 (glare over robot 1's front LED, here: hidden)
    publishes nothing and asks for the instant again; the retake shows both: its poses go out.
    With the retakes spent, the incomplete frame's poses go out as they are."""
    from excavation_interfaces.msg import Retake

    rng = np.random.default_rng(1)

    def render(hidden=frozenset()):
        return frame_to_message(camera.render(VIEWS, np.zeros((16, 16)), rng, hidden)[0], Image())

    node = localizer(ros, retakes=1)
    poses, retakes = counted(node)
    probe = Probe(ros)
    asked = []
    probe.node.create_subscription(Retake, "/overhead/retake", asked.append, 10)
    probe.send(render(), 7)
    assert ros.spin_until(lambda: all(probe.poses.values()))
    probe.send(render({(1, "front")}), 8)
    assert ros.spin_until(lambda: asked and node.frames == 2)
    assert asked[0].stamp.sec == 8 and list(asked[0].unseen) == [1]
    assert [len(p.sent) for p in poses] == [1, 1]  # frame 2 held back whole
    probe.send(render(), 8)  # the retake: same instant, its own noise
    assert ros.spin_until(lambda: all(len(p) == 2 for p in probe.poses.values()))
    assert [p[-1].header.stamp.sec for p in probe.poses.values()] == [8, 8]
    # the next instant: hidden in its frame and in the one retake allowed
    probe.send(render({(1, "front")}), 9)
    assert ros.spin_until(lambda: len(asked) == 2)
    probe.send(render({(1, "front")}), 9)
    assert ros.spin_until(lambda: len(probe.poses[0]) == 3 and node.frames == 5)
    assert len(retakes.sent) == 2 and len(poses[1].sent) == 2  # no third ask; robot 1 not sent
    assert len(asked) == 2 and len(probe.poses[1]) == 2
    assert probe.poses[0][-1].header.stamp.sec == 9


def test_retakes_off_never_ask(ros, frame, camera):
    from excavation_interfaces.msg import Retake

    node = localizer(ros)
    poses, retakes = counted(node)
    assert retakes is None  # retakes off: the node has no retake publisher at all
    probe = Probe(ros)
    asked = []
    probe.node.create_subscription(Retake, "/overhead/retake", asked.append, 10)
    probe.send(frame_to_message(frame, Image()), 7)
    assert ros.spin_until(lambda: all(probe.poses.values()))
    hidden = camera.render(VIEWS, np.zeros((16, 16)), np.random.default_rng(2), {(1, "front")})
    probe.send(frame_to_message(hidden[0], Image()), 8)
    assert ros.spin_until(lambda: len(probe.poses[0]) == 2 and node.frames == 2)
    assert [len(p.sent) for p in poses] == [2, 1]  # the frame went out without robot 1
    assert not asked
