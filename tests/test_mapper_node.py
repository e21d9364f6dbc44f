"""The mapper node: sweeps in, latched height map out; bad scans are reported."""

from __future__ import annotations

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Image, JointState, LaserScan

from excavation_common.messages import image_to_grid
from excavation_common.ros import LATCHED
from excavation_sim.laser import LaserParams, OverheadLaser
from terrain_mapper.geometry import PAN_JOINT, TILT_JOINT
from terrain_mapper.mapper_node import MOUNT_TOPIC, SCAN_TOPIC, MapperNode

LASER = LaserParams(sweep_scans=16)


class Rig:
    """A mapper node (sweeps of 16 scans, no robots) and a probe that feeds it."""

    def __init__(self, ros):
        from rclpy.node import Node

        self.ros = ros
        self.mapper = ros.add(
            MapperNode(
                context=ros.context,
                parameter_overrides=[
                    Parameter("robots", value=0),
                    Parameter("sweep_scans", value=LASER.sweep_scans),
                    Parameter("reliable", value=True),
                    Parameter("diagnostics_period", value=0.1),
                ],
            )
        )
        node = self.node = ros.add(Node("probe", context=ros.context))
        qos = QoSProfile(depth=200, reliability=ReliabilityPolicy.RELIABLE)
        self.scan_pub = node.create_publisher(LaserScan, SCAN_TOPIC, qos)
        self.mount_pub = node.create_publisher(JointState, MOUNT_TOPIC, qos)
        self.maps: list[Image] = []
        node.create_subscription(Image, "/worksite/height_map", self.maps.append, LATCHED)
        self.status: DiagnosticStatus | None = None
        node.create_subscription(DiagnosticArray, "/diagnostics", self.on_diag, 10)
        ros.spin_until(
            lambda: (
                self.scan_pub.get_subscription_count() > 0
                and self.mount_pub.get_subscription_count() > 0
            ),
            5.0,
        )

    def on_diag(self, msg):
        for s in msg.status:
            if s.name == "/mapper":
                self.status = s

    def send(self, sec, ranges, tilt, joints=(PAN_JOINT, TILT_JOINT), n=None):
        stamp = Time(sec=sec, nanosec=0)
        mount = JointState(name=list(joints), position=[0.0, tilt][: len(joints)])
        mount.header.stamp = stamp
        scan = LaserScan()
        scan.header.stamp = stamp
        scan.angle_min, scan.angle_max = LASER.angle_min, LASER.angle_max
        scan.angle_increment = LASER.angle_increment
        scan.range_min, scan.range_max = LASER.range_min, LASER.range_max
        scan.ranges = [float(r) for r in ranges][:n]
        self.mount_pub.publish(mount)
        self.scan_pub.publish(scan)

    def sweep(self, sec0, heights, rng):
        laser = OverheadLaser(LASER, 0.25)
        for i, (_, tilt, ranges) in enumerate(laser.sweep(heights, rng)):
            self.send(sec0 + i, ranges, tilt)

    def reported(self, level, text):
        return lambda: (
            self.status is not None and self.status.level == level and (text in self.status.message)
        )


def test_a_sweep_gives_a_map_stamped_with_its_first_scan(ros):
    rig = Rig(ros)
    heights = np.random.default_rng(0).integers(-3, 4, (16, 16)) * 0.05
    rig.sweep(100, heights, np.random.default_rng(1))
    assert ros.spin_until(lambda: rig.maps)
    msg = rig.maps[0]
    assert msg.header.stamp.sec == 100 and msg.encoding == "32FC1"
    grid = image_to_grid(msg, "32FC1", shape=(16, 16))
    known = np.isfinite(grid)
    assert known.mean() > 0.5
    assert np.sqrt(np.mean((grid[known] - heights[known]) ** 2)) < 0.25 * 0.05


def test_scans_without_valid_returns_publish_nothing(ros):
    rig = Rig(ros)
    for i, tilt in enumerate(LASER.tilts()):
        rig.send(10 + i, [np.inf] * LASER.beams, tilt)
    assert ros.spin_until(rig.reported(DiagnosticStatus.WARN, "has no valid return"))
    assert ros.spin_until(rig.reported(DiagnosticStatus.WARN, "sweep measured no cell"))
    assert not rig.maps
    rig.sweep(50, np.zeros((16, 16)), np.random.default_rng(0))  # still running
    assert ros.spin_until(lambda: rig.maps)


def test_malformed_scan_and_mount_are_reported(ros):
    rig = Rig(ros)
    rig.send(1, [1.0] * LASER.beams, 0.0, n=10)
    assert ros.spin_until(rig.reported(DiagnosticStatus.ERROR, "ranges = '10 values'"))
    rig.send(2, [1.0] * LASER.beams, 0.0, joints=(PAN_JOINT,))
    assert ros.spin_until(rig.reported(DiagnosticStatus.ERROR, "has no 'laser_tilt' joint"))
    ros.spin_until(lambda: False, 0.3)
    assert not rig.maps and rig.mapper.core.scans == 0


def test_a_lost_scan_does_not_shift_later_sweeps(ros):
    rig = Rig(ros)
    laser = OverheadLaser(LASER, 0.25)
    scans = laser.sweep(np.zeros((16, 16)), np.random.default_rng(0))
    for i, (_, tilt, ranges) in enumerate(scans):
        if i != 5:  # scan 5 of the first sweep is lost
            rig.send(200 + i, ranges, tilt)
    for i, (_, tilt, ranges) in enumerate(scans):
        rig.send(300 + i, ranges, tilt)
    assert ros.spin_until(lambda: len(rig.maps) == 2)
    assert [m.header.stamp.sec for m in rig.maps] == [200, 300]
    assert rig.mapper.short_sweeps == 1
