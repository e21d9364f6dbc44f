"""``ros2 run dome_emulator laser``: the dome's tilting laser and its mount, emulated.

Stands in for the scanner driver and the pan/tilt mount driver of a dome
(:mod:`dome_emulator.laser`): scans at ``scan_rate`` and mount states at ``mount_rate``, on
the wall clock, each stamped with its own instant, the mount nodding continuously; the
scans render the world's current heights with the simulator's laser model. Run it in
``/worksite`` to get the site file's topics::

    ros2 run dome_emulator laser --ros-args -r __ns:=/worksite

Subscribes ``{truth_prefix}/robot_k/pose`` (PoseWithCovarianceStamped, k < ``robots``)
and ``{truth_prefix}/worksite/height_map`` (Image 32FC1 metres, latched): ``dynamics``'
per-step poses under its ``pose_prefix`` and its height map under ``snapshot_prefix``.

Publishes, best effort (sensor data QoS): ``scan`` (sensor_msgs/LaserScan, frame
``frame_id``, with ``time_increment`` and ``scan_time``) and ``laser_mount/joint_states``
(sensor_msgs/JointState, joints ``pan_joint`` and ``tilt_joint``); ``/diagnostics``
(``/worksite/laser``: OK with the counts, WARN while no height map has come: the mount
nods, no scans).
"""

from __future__ import annotations

import sys

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.time import Time
from sensor_msgs.msg import JointState, LaserScan

from dome_emulator.laser import LaserCore, LaserEmulatorParams, MountState, Scan
from dome_emulator.truth_feed import TruthFeed
from excavation_common.ros import (
    SENSOR_DATA,
    declare_params,
    diagnostics,
    spin_node,
)


class LaserNode(Node):
    """Thin ROS plumbing around :class:`LaserCore`."""

    def __init__(self, **kwargs) -> None:
        super().__init__("laser", **kwargs)
        self.params = p = declare_params(self, LaserEmulatorParams)
        self.core = LaserCore(p, self.get_clock().now().nanoseconds)
        self.scan_pub = self.create_publisher(LaserScan, "scan", SENSOR_DATA)
        self.mount_pub = self.create_publisher(JointState, "laser_mount/joint_states", SENSOR_DATA)
        self.feed = TruthFeed(self, self.core.truth, p.truth_prefix, p.robots)
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        period = min(p.scan_period, 1.0 / p.mount_rate)
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(period, self.step, clock=steady)
        self.create_timer(p.diagnostics_period, self.publish_diagnostics)

    def step(self) -> None:
        """Send every scan and mount state the device has finished by now."""
        for item in self.core.due(self.get_clock().now().nanoseconds):
            match item:
                case Scan():
                    self.scan_pub.publish(self.scan_message(item))
                case MountState():
                    self.mount_pub.publish(self.mount_message(item))

    def scan_message(self, scan: Scan) -> LaserScan:
        """The LaserScan of one scan."""
        p = self.params
        model = self.core.lasers[True].params
        msg = LaserScan()
        msg.header.stamp = Time(nanoseconds=scan.stamp_ns).to_msg()
        msg.header.frame_id = p.frame_id
        msg.angle_min, msg.angle_max = p.angle_min, p.angle_max
        msg.angle_increment = model.angle_increment
        msg.time_increment = p.time_increment
        msg.scan_time = p.scan_period
        msg.range_min, msg.range_max = p.range_min, p.range_max
        msg.ranges = scan.ranges.tolist()
        return msg

    def mount_message(self, state: MountState) -> JointState:
        """The mount's JointState."""
        msg = JointState()
        msg.header.stamp = Time(nanoseconds=state.stamp_ns).to_msg()
        msg.name = [self.params.pan_joint, self.params.tilt_joint]
        msg.position = [state.pan, state.tilt]
        return msg

    def publish_diagnostics(self) -> None:
        """OK while scans go out; WARN without a height map or with a bad one."""
        c = self.core
        if self.feed.problem:
            level, message = DiagnosticStatus.WARN, self.feed.problem
        elif c.truth.heights is None:
            level = DiagnosticStatus.WARN
            message = f"no height map on {self.feed.heights_topic} yet: the mount nods, no scans"
        else:
            level, message = DiagnosticStatus.OK, f"{c.scans} scans"
        values = {
            "scans": c.scans,
            "mount_states": c.mount_states,
            "waiting": c.waiting,
            "dropped": c.dropped,
            "scan_rate": self.params.scan_rate,
            "sweep_scans": self.params.sweep_scans,
            "time_increment": self.params.time_increment,
        }
        self.diag_pub.publish(diagnostics(self, level, message, values, hardware_id="laser"))


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run dome_emulator laser``."""
    return spin_node(LaserNode, args)


if __name__ == "__main__":
    sys.exit(main())
