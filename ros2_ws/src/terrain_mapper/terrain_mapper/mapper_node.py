"""``ros2 run terrain_mapper mapper``: the worksite height map from the overhead laser.

Subscribes ``scan_topic`` (``/worksite/scan``, sensor_msgs/LaserScan), ``mount_topic``
(``/worksite/laser_mount/joint_states``, sensor_msgs/JointState with joints ``pan_joint``
and ``tilt_joint``, by default ``laser_pan``, ``laser_tilt``, radians; a state without
them is an ERROR on ``/diagnostics`` naming the joint) and every robot's ``/robot_k/pose``
(k < ``robots``; their footprints are masked). Each scan is projected with the mount's
angles at the scan's own stamp (plus ``scan_stamp_offset``, the scanner's clock against
the mount's), interpolated between the mount states that bracket it
(:class:`terrain_mapper.mount_sync.MountSync`): the laser and the mount are separate
drivers and never stamp alike. A scan with ``time_increment`` (seconds between beams) is
projected beam by beam, each with the mount's angles at ``stamp + i * time_increment``
(a nodding mount moves while the scan is taken; ``scan_time``, the time from one scan to
the next, must hold all its beams). A scan waits for a later mount state (that of its last
beam); a scan no pair of states brackets (or across a gap wider than ``mount_max_gap``) is
dropped, counted
(``unbracketed_scans``) and reported as a WARN on ``/diagnostics``. A scan still waiting is
given up for want of a mount state only once the node has taken every scan and mount state
already queued for it, and then only when the laser's own stream has gone on more than
``mount_wait`` seconds of stamps past it, or when it has waited ``mount_wait`` wall seconds
with both streams quiet: a mapper held up by a loaded machine takes the mount state that
came meanwhile instead of dropping the scan it describes. The mount's
orientation errors (``pan_offset``, ``tilt_offset``, ``roll_offset``; fitted by
``calibrate_mount``), the scanner's lever arm (``laser_offset_x/y/z``) and an upside-down
scanner (``scanner_flip``) are applied to every beam.

Every ``sweep_scans`` scans it bins and fuses the sweep
(:class:`terrain_mapper.mapper.TerrainMapper`) and publishes ``/worksite/height_map``
(sensor_msgs/Image 32FC1, one pixel per cell, metres, NaN unknown, latched QoS) stamped
with the sweep's first scan (its stamp plus ``scan_stamp_offset``), and with every mount
state the laser's frame, ``map`` -> ``overhead_laser`` on ``/tf`` (the optical centre and
the scanner's axes at that pan and tilt: :func:`terrain_mapper.geometry.laser_pose`).
``/worksite/map_info``
is the blueprint server's: the mapper publishes it only with ``publish_map_info`` (off by
default; for a mapper run alone).

A scan that turns the tilt back against the sweep's direction ends a sweep early (one of
its scans was lost), so the count never drifts out of step. A sweep is fused once every
robot's pose is at least as new as the sweep's first scan (so the masks are where the
robots were), or ``pose_wait`` seconds after its last scan with the poses it has; a robot
the team supervisor has disabled or lost (``/robot_k/enabled`` false, latched) is not
waited for, and stays masked where it was last seen. A scan
with no valid return, a malformed scan or mount state, or a sweep that measured no cell is
reported on ``/diagnostics`` (status ``/mapper``, WARN or ERROR) and publishes nothing; the node
keeps running.

Parameters: :class:`terrain_mapper.params.MapperNodeParams` (topics, sweeps, mount
synchronisation, QoS) and :class:`terrain_mapper.mapper.MapperParams` (grid, mount,
estimation), declared with descriptors and ranges; every default is in
``config/mapper.yaml``.
"""

from __future__ import annotations

import bisect
import math
import sys
import time

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseWithCovarianceStamped
from nav_msgs.msg import MapMetaData
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Image, JointState, LaserScan
from std_msgs.msg import Bool

from excavation_common.messages import grid_to_image, map_info
from excavation_common.params import ParameterError
from excavation_common.ros import LATCHED, SENSOR_DATA, declare_params, diagnostics, spin_node
from excavation_common.safety import ENABLED_TOPIC
from excavation_common.tf import LASER, MAP, TfBroadcaster, quaternion, transform
from terrain_mapper.errors import MapperError
from terrain_mapper.geometry import PAN_JOINT, TILT_JOINT, laser_pose, yaw_of
from terrain_mapper.mapper import (
    MapperParams,
    TerrainMapper,
    scan_ranges_check,
    scan_timing_check,
)
from terrain_mapper.mount_sync import MISS, TOO_OLD, WAIT, Lookup, MountSync
from terrain_mapper.params import MapperNodeParams

SCAN_TOPIC = MapperNodeParams().scan_topic
MOUNT_TOPIC = MapperNodeParams().mount_topic


def mount_angles(
    msg: JointState, topic: str = MOUNT_TOPIC, joints: tuple[str, str] = (PAN_JOINT, TILT_JOINT)
) -> tuple[float, float]:
    """``(pan, tilt)`` from the mount's joint state, joints named ``joints`` (pan, tilt).

    Raises:
        MapperError: A joint is missing or its position is not finite.
    """
    names = list(msg.name)
    out = []
    for joint, param in zip(joints, ("pan_joint", "tilt_joint"), strict=True):
        if joint not in names:
            raise MapperError(topic, "name", names, f"has no {joint!r} joint (the {param})")
        i = names.index(joint)
        if i >= len(msg.position) or not math.isfinite(msg.position[i]):
            shown = msg.position[i] if i < len(msg.position) else None
            raise MapperError(topic, f"position[{i}]", shown, f"{joint} needs a finite angle")
        out.append(float(msg.position[i]))
    return out[0], out[1]


def _key(stamp) -> tuple[int, int]:
    return (int(stamp.sec), int(stamp.nanosec))


def _ns(stamp) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def _stamp(ns: int) -> Time:
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


class MapperNode(Node):
    """Thin ROS plumbing around :class:`TerrainMapper`.

    Raises:
        excavation_common.params.ParameterError: A bad parameter value.
    """

    def __init__(self, **kwargs) -> None:
        super().__init__("mapper", **kwargs)
        self.config = c = declare_params(self, MapperNodeParams)
        self.params = declare_params(self, MapperParams)
        self.n = c.robots
        self.sweep_scans = c.sweep_scans
        self.pose_wait = c.pose_wait
        self.scan_topic = c.scan_topic
        name = self.get_fully_qualified_name()
        for key in ("pan_joint", "tilt_joint"):
            if not getattr(c, key):
                raise ParameterError(name, key, "", "names no joint")
        if c.pan_joint == c.tilt_joint:
            raise ParameterError(name, "tilt_joint", c.tilt_joint, "is also the pan_joint")
        self.joints = (c.pan_joint, c.tilt_joint)
        self.stamp_offset_ns = int(round(c.scan_stamp_offset * 1e9))

        self.core = TerrainMapper(self.params)
        self.sync = MountSync(int(c.mount_max_gap * 1e9), keep=max(8 * c.sweep_scans, 64))
        # (stamp ns + scan_stamp_offset, arrival, scan, beam times after the stamp or None)
        self.scans: list[tuple[int, float, LaserScan, np.ndarray | None]] = []
        self.newest_scan: int | None = None  # stamp (ns) of the newest scan taken
        self.mount_wait_ns = int(round(c.mount_wait * 1e9))
        self.unbracketed = 0
        self.unbracketed_seen = 0
        self.bracketed = 0  # scans matched to mount states so far
        self.sweeps = 0  # sweeps closed so far, full or short
        self.early = 0  # scans dropped at start, older than the mount's first state
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
        self.tf = TfBroadcaster(self)
        self.info_pub = (
            self.create_publisher(MapMetaData, "/worksite/map_info", LATCHED)
            if c.publish_map_info
            else None
        )
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        qos = (
            QoSProfile(depth=c.queue, reliability=ReliabilityPolicy.RELIABLE)
            if c.reliable
            else SENSOR_DATA
        )
        self.scan_sub = self.create_subscription(LaserScan, c.scan_topic, self.on_scan, qos)
        self.mount_sub = self.create_subscription(JointState, c.mount_topic, self.on_mount, qos)
        self.disabled: set[int] = set()
        for k in range(self.n):
            self.create_subscription(
                PoseWithCovarianceStamped,
                f"/robot_{k}/pose",
                lambda m, k=k: self.on_pose(k, m),
                10,
            )
            self.create_subscription(
                Bool, f"/robot_{k}/{ENABLED_TOPIC}", lambda m, k=k: self.on_enabled(k, m), LATCHED
            )
        if self.info_pub is not None:
            self.info_pub.publish(
                map_info(self.params.rows, self.params.cols, self.params.cell_size)
            )
        self.create_timer(0.05, self.on_timer)
        self.create_timer(c.diagnostics_period, self.publish_diagnostics)

    # --- inputs -----------------------------------------------------------------------------

    def problem(self, key: str, level: int, text: str) -> None:
        """Record a problem for diagnostics (and the log)."""
        self.problems[key] = (level, text)
        self.get_logger().warning(text, throttle_duration_sec=5.0)

    def on_mount(self, msg: JointState) -> None:
        """The mount's pan and tilt at a stamp."""
        self.add_mount(msg)
        self.match()

    def add_mount(self, msg: JointState) -> None:
        """Keep a mount state for interpolation."""
        try:
            pan, tilt = mount_angles(msg, self.config.mount_topic, self.joints)
        except MapperError as exc:
            self.problem("mount", DiagnosticStatus.ERROR, str(exc))
            return
        self.problems.pop("mount", None)
        self.sync.add(_ns(msg.header.stamp), pan, tilt)
        p = self.params
        origin, rot = laser_pose(pan, tilt, self.core.mount, p.offsets, p.lever, p.scanner_flip)
        self.tf.send([transform(MAP, LASER, origin, quaternion(rot), msg.header.stamp)])

    def on_scan(self, msg: LaserScan) -> None:
        """A scan, kept until the mount states around its stamp have arrived."""
        self.add_scan(msg)
        self.match()

    def add_scan(self, msg: LaserScan) -> None:
        """Keep a scan, in stamp order, with the wall time it came.

        Its stamp is corrected by ``scan_stamp_offset``; a scan whose beam timing is
        malformed (:func:`terrain_mapper.mapper.scan_timing_check`) is reported and dropped.
        """
        try:
            beams = scan_timing_check(
                len(msg.ranges), msg.time_increment, msg.scan_time, self.scan_topic
            )
        except MapperError as exc:
            self.problem("scan", DiagnosticStatus.ERROR, str(exc))
            return
        stamp = _ns(msg.header.stamp) + self.stamp_offset_ns
        bisect.insort(self.scans, (stamp, self.wall(), msg, beams), key=lambda e: e[0])
        if self.newest_scan is None or stamp > self.newest_scan:
            self.newest_scan = stamp

    def wall(self) -> float:
        """Wall-clock seconds (monotonic): how long a scan has waited."""
        return time.monotonic()

    def on_enabled(self, k: int, msg: Bool) -> None:
        """Robot k enabled (waited for) or disabled or lost (not waited for)."""
        if msg.data:
            self.disabled.discard(k)
        else:
            self.disabled.add(k)

    def on_pose(self, k: int, msg: PoseWithCovarianceStamped) -> None:
        """A robot's pose (for the footprint mask)."""
        q, pos = msg.pose.pose.orientation, msg.pose.pose.position
        yaw = yaw_of(q)
        if msg.header.frame_id != "map" or not all(map(math.isfinite, (pos.x, pos.y, yaw))):
            return
        self.poses[k] = (_key(msg.header.stamp), (pos.x, pos.y, yaw))
        self.check_pending()

    # --- scans and sweeps -------------------------------------------------------------------

    def on_timer(self) -> None:
        """Give up on scans whose mount state never came; fuse a sweep whose poses are in."""
        if self.scans:
            self.match(quiet=True)
        self.check_pending()

    def take_queued(self) -> bool:
        """Take every mount state and scan already queued for this node; True if any.

        The executor runs a due timer before the subscriptions of the same round, and one
        message per subscription per round, so after the node was held up (a loaded
        machine) the mount state of a waiting scan may sit in the queue while the scan's
        wait is judged: taken here first, it is used, not missed. (rclpy's own
        ``wait_for_message`` takes messages the same way.)
        """
        taken_any = False
        for sub, add in ((self.mount_sub, self.add_mount), (self.scan_sub, self.add_scan)):
            while True:
                with sub.handle:
                    taken = sub.handle.take_message(sub.msg_type, sub.raw)
                if taken is None:
                    break
                add(taken[0])
                taken_any = True
        return taken_any

    def match(self, quiet: bool = False) -> None:
        """Integrate, in stamp order, every scan whose mount angles are known now.

        A scan still waiting for a later mount state holds back the scans after it. It is
        given up only once nothing is queued any more (:meth:`take_queued`) and either the
        laser has sent a scan stamped more than ``mount_wait`` after it (stamps: the mount's
        stream has fallen that far behind, however loaded the machine is) or, with
        ``quiet`` (the timer), it has waited ``mount_wait`` wall seconds (both streams have
        stopped). A scan no states bracket is dropped and counted.
        """
        now = self.wall()
        while self.scans:
            stamp, arrived, msg, beams = self.scans[0]
            if beams is None:
                found = self.sync.lookup(stamp)
            else:
                found = self.sync.lookup_beams(stamp + beams)
            if found.status == WAIT:
                behind = self.newest_scan - stamp > self.mount_wait_ns
                if not behind and not (quiet and now - arrived >= self.config.mount_wait):
                    break
                if self.take_queued():
                    continue  # what came meanwhile first
                reason = "the laser went on" if behind else "it waited mount_wait"
                found = Lookup(MISS, reason=f"no mount state after it ({reason})")
            self.scans.pop(0)
            if found.status == MISS and found.reason == TOO_OLD and not self.bracketed:
                # Start-up: the laser came up before the mount's first state. Not a fault.
                if not self.early:
                    self.get_logger().info(
                        "scans from before the mount's first state are dropped (start-up)"
                    )
                self.early += 1
                continue
            if found.status == MISS:
                self.unbracketed += 1
                self.problem(
                    "mount_sync",
                    DiagnosticStatus.WARN,
                    f"{self.unbracketed} scans dropped: no mount state brackets their stamp "
                    f"(last: {found.reason})",
                )
                continue
            self.bracketed += 1
            self.integrate(msg, found.pan, found.tilt, stamp)

    def integrate(
        self,
        msg: LaserScan,
        pan: float | np.ndarray,
        tilt: float | np.ndarray,
        stamp_ns: int | None = None,
    ) -> None:
        """Project one scan; after ``sweep_scans`` scans, the sweep waits for poses.

        ``pan`` and ``tilt`` are the mount's angles for the scan, or per beam (arrays);
        ``stamp_ns`` is the scan's corrected stamp (its own stamp when None).
        """
        if self.pending is not None:
            self.fuse()  # a new sweep began: the last one goes with the poses there are
        try:
            scan_ranges_check(
                len(msg.ranges),
                msg.angle_min,
                msg.angle_max,
                msg.angle_increment,
                self.scan_topic,
            )
            if not (0 <= msg.range_min < msg.range_max):
                raise MapperError(
                    self.scan_topic, "range_min/range_max", (msg.range_min, msg.range_max), "bad"
                )
        except MapperError as exc:
            self.problem("scan", DiagnosticStatus.ERROR, str(exc))
            return
        pan_tilt = (pan, tilt)
        if np.ndim(tilt):  # per beam: the sweep follows the scan's mean tilt
            tilt = float(np.mean(tilt))
        step = tilt - self.last_tilt if self.last_tilt is not None else 0.0
        if self.in_sweep >= 2 and step * self.sweep_direction < 0:
            # the tilt turned back: a new sweep began before this one had all its scans
            # (one was lost); close the short sweep so the count is in step again
            if self.sweeps == 0:  # start-up: the mapper came up mid-sweep
                self.get_logger().info(
                    f"the first sweep was joined mid-way ({self.in_sweep} of "
                    f"{self.sweep_scans} scans)"
                )
            else:
                self.problem(
                    "sweep_size",
                    DiagnosticStatus.WARN,
                    f"a sweep ended after {self.in_sweep} of {self.sweep_scans} scans",
                )
                self.short_sweeps += 1
            first = self.sweeps == 0
            self.sweeps += 1
            self.in_sweep = 0
            self.pending = (self.sweep_stamp, time.monotonic())
            self.fuse(start_up=first)
        if self.in_sweep == 1:
            self.sweep_direction = 1.0 if step >= 0 else -1.0
        self.last_tilt = tilt
        if self.in_sweep == 0:
            corrected = stamp_ns is not None and stamp_ns != _ns(msg.header.stamp)
            self.sweep_stamp = _stamp(stamp_ns) if corrected else msg.header.stamp
        valid = self.core.add_scan(
            msg.ranges,
            msg.angle_min,
            msg.angle_increment,
            msg.range_min,
            msg.range_max,
            *pan_tilt,
        )
        if valid == 0:
            self.problem(
                "scan",
                DiagnosticStatus.WARN,
                f"{self.scan_topic}: scan at tilt {tilt:.3f} rad has no valid return",
            )
        else:
            self.problems.pop("scan", None)
        self.in_sweep += 1
        if self.in_sweep >= self.sweep_scans:
            self.sweeps += 1
            self.problems.pop("sweep_size", None)
            if self.unbracketed == self.unbracketed_seen:  # a whole sweep without a miss
                self.problems.pop("mount_sync", None)
            self.unbracketed_seen = self.unbracketed
            self.in_sweep = 0
            self.pending = (self.sweep_stamp, time.monotonic())
            self.check_pending()

    def check_pending(self) -> None:
        """Fuse the finished sweep once the poses are current (or ``pose_wait`` passed)."""
        if self.pending is None:
            return
        stamp, finished = self.pending
        key = _key(stamp)
        current = all(
            k in self.poses and self.poses[k][0] >= key
            for k in range(self.n)
            if k not in self.disabled
        )
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

    def fuse(self, start_up: bool = False) -> None:
        """Fuse the pending sweep and publish the map (unless it measured nothing).

        ``start_up``: the first sweep, joined mid-way; measuring nothing is no fault then.
        """
        stamp, _ = self.pending
        self.pending = None
        robots = [self.poses[k][1] for k in range(self.n) if k in self.poses]
        stats = self.core.finish_sweep(robots)
        self.last_stats = stats
        if stats.measured == 0 and start_up:
            self.get_logger().info("the first sweep measured no cell (joined mid-way)")
            return
        if stats.measured == 0:
            self.problem(
                "sweep", DiagnosticStatus.WARN, "sweep measured no cell: height map not updated"
            )
            return
        self.problems.pop("sweep", None)
        self.map_pub.publish(grid_to_image(self.core.height_map(), "32FC1", stamp=stamp))
        self.published += 1

    def publish_diagnostics(self) -> None:
        """The node's status: OK with sweep figures, or the worst recorded problem."""
        if self.problems:
            level = max(level for level, _ in self.problems.values())
            message = "; ".join(text for _, text in self.problems.values())
        else:
            level, message = DiagnosticStatus.OK, f"{self.published} maps published"
        values = {}
        if self.last_stats is not None:
            values = {
                n: getattr(self.last_stats, n) for n in ("points", "invalid", "masked", "measured")
            }
        values.update(short_sweeps=self.short_sweeps, unbracketed_scans=self.unbracketed)
        self.diag_pub.publish(diagnostics(self, level, message, values, "overhead_laser"))


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run terrain_mapper mapper``."""
    return spin_node(MapperNode, args)


if __name__ == "__main__":
    sys.exit(main())
