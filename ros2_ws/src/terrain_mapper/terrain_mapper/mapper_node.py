"""``ros2 run terrain_mapper mapper``: the worksite height map from the overhead laser.

Subscribes ``/worksite/scan`` (sensor_msgs/LaserScan) and ``/worksite/laser_mount/joint_states``
(sensor_msgs/JointState with joints ``laser_pan``, ``laser_tilt``, radians; a scan is paired
with the mount state of the same stamp) and every robot's ``/robot_k/pose`` (k <
``robots``; their footprints are masked). Every ``sweep_scans`` scans it bins and fuses the
sweep (:class:`terrain_mapper.mapper.TerrainMapper`) and publishes ``/worksite/height_map``
(sensor_msgs/Image 32FC1, one pixel per cell, metres, NaN unknown, latched QoS) stamped
with the sweep's first scan, and, with ``publish_map_info``, ``/worksite/map_info``.

A scan that turns the tilt back against the sweep's direction ends a sweep early (one of
its scans was lost), so the count never drifts out of step. A sweep is fused once every
robot's pose is at least as new as the sweep's first scan (so
the masks are where the robots were), or ``pose_wait`` seconds after its last scan with the
poses it has. A scan with no valid return, a malformed scan or mount state, or a sweep that
measured no cell is reported on ``/diagnostics`` (``mapper``, WARN or ERROR) and publishes
nothing; the node keeps running.

Parameters: every field of :class:`terrain_mapper.mapper.MapperParams` (grid, mount,
estimation; ``config/mapper.yaml``), ``robots`` (4), ``sweep_scans`` (64),
``pose_wait`` (0.5 s), ``publish_map_info`` (true), ``reliable`` (false: sensor-data QoS
for scans; true: reliable with ``queue`` depth), ``queue`` (200),
``diagnostics_period`` (1.0 s).
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import fields

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseWithCovarianceStamped
from nav_msgs.msg import MapMetaData
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import Image, JointState, LaserScan

from excavation_common.messages import grid_to_image, map_info
from excavation_common.ros import LATCHED, spin_node
from terrain_mapper.errors import MapperError
from terrain_mapper.geometry import PAN_JOINT, TILT_JOINT, yaw_of
from terrain_mapper.mapper import MapperParams, TerrainMapper, scan_ranges_check

SCAN_TOPIC = "/worksite/scan"
MOUNT_TOPIC = "/worksite/laser_mount/joint_states"


def mount_angles(msg: JointState, topic: str = MOUNT_TOPIC) -> tuple[float, float]:
    """``(pan, tilt)`` from the mount's joint state.

    Raises:
        MapperError: A joint is missing or its position is not finite.
    """
    names = list(msg.name)
    out = []
    for joint in (PAN_JOINT, TILT_JOINT):
        if joint not in names:
            raise MapperError(topic, "name", names, f"has no {joint!r} joint")
        i = names.index(joint)
        if i >= len(msg.position) or not math.isfinite(msg.position[i]):
            shown = msg.position[i] if i < len(msg.position) else None
            raise MapperError(topic, f"position[{i}]", shown, f"{joint} needs a finite angle")
        out.append(float(msg.position[i]))
    return out[0], out[1]


def _key(stamp) -> tuple[int, int]:
    return (int(stamp.sec), int(stamp.nanosec))


class MapperNode(Node):
    """Thin ROS plumbing around :class:`TerrainMapper`."""

    def __init__(self, **kwargs) -> None:
        super().__init__("mapper", **kwargs)
        p = self.declare_parameter
        values = {}
        for f in fields(MapperParams):
            default = getattr(MapperParams(), f.name)
            values[f.name] = type(default)(p(f.name, default).value)
        self.params = MapperParams(**values)
        self.n = int(p("robots", 4).value)
        self.sweep_scans = int(p("sweep_scans", 64).value)
        self.pose_wait = float(p("pose_wait", 0.5).value)
        publish_info = bool(p("publish_map_info", True).value)
        reliable = bool(p("reliable", False).value)
        queue = int(p("queue", 200).value)
        period = float(p("diagnostics_period", 1.0).value)

        self.core = TerrainMapper(self.params)
        self.scans: dict[tuple[int, int], LaserScan] = {}
        self.mounts: dict[tuple[int, int], tuple[float, float]] = {}
        self.poses: dict[int, tuple[tuple[int, int], tuple[float, float, float]]] = {}
        self.in_sweep = 0
        self.last_tilt: float | None = None
        self.sweep_direction = 0.0
        self.short_sweeps = 0
        self.sweep_stamp = None
        self.pending = None  # (first stamp, wall time of the last scan)
        self.problems: dict[str, tuple[int, str]] = {}
        self.published = 0
        self.last_stats = None

        self.map_pub = self.create_publisher(Image, "/worksite/height_map", LATCHED)
        self.info_pub = (
            self.create_publisher(MapMetaData, "/worksite/map_info", LATCHED)
            if publish_info
            else None
        )
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        qos = (
            QoSProfile(depth=queue, reliability=ReliabilityPolicy.RELIABLE)
            if reliable
            else qos_profile_sensor_data
        )
        self.create_subscription(LaserScan, SCAN_TOPIC, self.on_scan, qos)
        self.create_subscription(JointState, MOUNT_TOPIC, self.on_mount, qos)
        for k in range(self.n):
            self.create_subscription(
                PoseWithCovarianceStamped,
                f"/robot_{k}/pose",
                lambda m, k=k: self.on_pose(k, m),
                10,
            )
        if self.info_pub is not None:
            self.info_pub.publish(
                map_info(self.params.rows, self.params.cols, self.params.cell_size)
            )
        self.create_timer(0.05, self.check_pending)
        self.create_timer(period, self.publish_diagnostics)

    # --- inputs -----------------------------------------------------------------------------

    def problem(self, key: str, level: int, text: str) -> None:
        """Record a problem for diagnostics (and the log)."""
        self.problems[key] = (level, text)
        self.get_logger().warning(text, throttle_duration_sec=5.0)

    def on_mount(self, msg: JointState) -> None:
        """The mount's pan and tilt at a stamp."""
        try:
            self.mounts[_key(msg.header.stamp)] = mount_angles(msg)
        except MapperError as exc:
            self.problem("mount", DiagnosticStatus.ERROR, str(exc))
            return
        self.problems.pop("mount", None)
        self.match()

    def on_scan(self, msg: LaserScan) -> None:
        """A scan, kept until its mount state arrives."""
        self.scans[_key(msg.header.stamp)] = msg
        self.match()

    def on_pose(self, k: int, msg: PoseWithCovarianceStamped) -> None:
        """A robot's pose (for the footprint mask)."""
        q, pos = msg.pose.pose.orientation, msg.pose.pose.position
        yaw = yaw_of(q)
        if msg.header.frame_id != "map" or not all(map(math.isfinite, (pos.x, pos.y, yaw))):
            return
        self.poses[k] = (_key(msg.header.stamp), (pos.x, pos.y, yaw))
        self.check_pending()

    # --- scans and sweeps -------------------------------------------------------------------

    def match(self) -> None:
        """Integrate every scan whose mount state has arrived, in stamp order."""
        for key in sorted(set(self.scans) & set(self.mounts)):
            self.integrate(self.scans.pop(key), *self.mounts.pop(key))
        for store in (self.scans, self.mounts):  # unmatched leftovers never grow unbounded
            for key in sorted(store)[: max(len(store) - 4 * self.sweep_scans, 0)]:
                del store[key]

    def integrate(self, msg: LaserScan, pan: float, tilt: float) -> None:
        """Project one scan; after ``sweep_scans`` scans, the sweep waits for poses."""
        if self.pending is not None:
            self.fuse()  # a new sweep began: the last one goes with the poses there are
        try:
            scan_ranges_check(
                len(msg.ranges), msg.angle_min, msg.angle_max, msg.angle_increment, SCAN_TOPIC
            )
            if not (0 <= msg.range_min < msg.range_max):
                raise MapperError(
                    SCAN_TOPIC, "range_min/range_max", (msg.range_min, msg.range_max), "bad"
                )
        except MapperError as exc:
            self.problem("scan", DiagnosticStatus.ERROR, str(exc))
            return
        step = tilt - self.last_tilt if self.last_tilt is not None else 0.0
        if self.in_sweep >= 2 and step * self.sweep_direction < 0:
            # the tilt turned back: a new sweep began before this one had all its scans
            # (one was lost); close the short sweep so the count is in step again
            self.problem(
                "sweep_size",
                DiagnosticStatus.WARN,
                f"a sweep ended after {self.in_sweep} of {self.sweep_scans} scans",
            )
            self.short_sweeps += 1
            self.in_sweep = 0
            self.pending = (self.sweep_stamp, time.monotonic())
            self.fuse()
        if self.in_sweep == 1:
            self.sweep_direction = 1.0 if step >= 0 else -1.0
        self.last_tilt = tilt
        if self.in_sweep == 0:
            self.sweep_stamp = msg.header.stamp
        valid = self.core.add_scan(
            msg.ranges,
            msg.angle_min,
            msg.angle_increment,
            msg.range_min,
            msg.range_max,
            pan,
            tilt,
        )
        if valid == 0:
            self.problem(
                "scan",
                DiagnosticStatus.WARN,
                f"{SCAN_TOPIC}: scan at tilt {tilt:.3f} rad has no valid return",
            )
        else:
            self.problems.pop("scan", None)
        self.in_sweep += 1
        if self.in_sweep >= self.sweep_scans:
            self.problems.pop("sweep_size", None)
            self.in_sweep = 0
            self.pending = (self.sweep_stamp, time.monotonic())
            self.check_pending()

    def check_pending(self) -> None:
        """Fuse the finished sweep once the poses are current (or ``pose_wait`` passed)."""
        if self.pending is None:
            return
        stamp, finished = self.pending
        key = _key(stamp)
        current = all(k in self.poses and self.poses[k][0] >= key for k in range(self.n))
        if current or time.monotonic() - finished >= self.pose_wait:
            if not current:
                stale = [k for k in range(self.n) if k not in self.poses or self.poses[k][0] < key]
                self.problem(
                    "poses",
                    DiagnosticStatus.WARN,
                    f"no current pose of robots {stale}: masked where last seen",
                )
            else:
                self.problems.pop("poses", None)
            self.fuse()

    def fuse(self) -> None:
        """Fuse the pending sweep and publish the map (unless it measured nothing)."""
        stamp, _ = self.pending
        self.pending = None
        robots = [self.poses[k][1] for k in range(self.n) if k in self.poses]
        stats = self.core.finish_sweep(robots)
        self.last_stats = stats
        if stats.measured == 0:
            self.problem(
                "sweep", DiagnosticStatus.WARN, "sweep measured no cell: height map not updated"
            )
            return
        self.problems.pop("sweep", None)
        self.map_pub.publish(grid_to_image(self.core.height_map(), "32FC1", stamp=stamp))
        self.published += 1

    def publish_diagnostics(self) -> None:
        """``mapper``: OK with sweep figures, or the worst recorded problem."""
        status = DiagnosticStatus(name="mapper", hardware_id="overhead_laser")
        if self.problems:
            status.level = max(level for level, _ in self.problems.values())
            status.message = "; ".join(text for _, text in self.problems.values())
        else:
            status.level = DiagnosticStatus.OK
            status.message = f"{self.published} maps published"
        if self.last_stats is not None:
            s = self.last_stats
            status.values = [
                KeyValue(key=name, value=str(getattr(s, name)))
                for name in ("points", "invalid", "masked", "measured")
            ] + [KeyValue(key="short_sweeps", value=str(self.short_sweeps))]
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = self.get_clock().now().to_msg()
        self.diag_pub.publish(msg)


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run terrain_mapper mapper``."""
    return spin_node(MapperNode, args)


if __name__ == "__main__":
    sys.exit(main())
