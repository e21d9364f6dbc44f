"""``ros2 run excavation_sim sensors``: the dome's overhead camera and laser, from sim truth.

Listens to the simulator's truth (``sim`` with ``truth_prefix:=/truth`` publishes
``/truth/robot_k/pose`` and ``/truth/worksite/height_map`` instead of the standard names)
and, once per new stamp for which every robot's pose and the height map have arrived,
publishes what the field sensors would give for that instant:

* ``/overhead/image_raw`` (sensor_msgs/Image ``bgr8``, :mod:`excavation_sim.camera`),
  stamped with the truth's stamp;
* one laser sweep (:mod:`excavation_sim.laser`): ``sweep_scans`` pairs of
  ``/worksite/laser_mount/joint_states`` (JointState ``laser_pan``, ``laser_tilt``) and
  ``/worksite/scan`` (LaserScan, frame ``overhead_laser``), scan i stamped ``i *
  scan_period`` after the truth's stamp.

The truth height map may be finer than the grid by a whole factor S (``rows * S`` x
``cols * S``: the fine field of ``dynamics`` with physical soil): the laser then traces
the fine field, and the camera (which needs only each robot's ground) the cell means.

The localizer and the mapper turn these back into ``/robot_k/pose`` and
``/worksite/height_map`` (``ant-trial --perception full``). All noise comes from one
generator seeded by ``seed``.

Parameters: ``robots`` (4), ``seed`` (0), ``truth_prefix`` (``/truth``); the site's
``rows`` (16), ``cols`` (16) and ``cell_size`` (0.25 m): camera and laser are placed over
its centre (:meth:`CameraParams.for_site`, :meth:`LaserParams.for_site`); camera
``width`` (1280), ``height`` (720), ``light`` (0.25), ``noise`` (3.0), ``glare`` (1.5),
``dropout`` (0.0), ``occlude`` (e.g. ``"0:front,2:rear"``), ``k1`` (-0.08); laser
``range_noise`` (0.008 m), ``laser_dropout`` (0.01), ``sweep_scans`` (64),
``scan_period`` (0.01 s); ``reliable`` (false: sensor-data QoS; true: reliable with
``queue`` depth, which the lockstep trial uses so that no scan of a sweep is lost),
``queue`` (200).

Faults, settable at runtime (``tests/test_faults.py``): ``paused`` (no camera frames while
true), ``laser_paused`` (no laser sweeps while true), ``frame_period`` (at least this many
wall-clock seconds between frames: 0.2 is a 5 Hz camera), ``dropout`` and ``occlude``. A
frame or sweep held back goes out when the fault ends, showing the latest truth. Frames
(sweeps) also wait, rendered, until some node subscribes to ``/overhead/image_raw``
(``/worksite/scan`` and ``/worksite/laser_mount/joint_states``: a scan without its mount
state cannot be placed): a lockstep tick's only frame is not lost to a localizer whose
subscription the middleware has not matched yet, and the noise drawn does not depend on
when the listeners came.

An ``excavation_interfaces/Retake`` on ``/overhead/retake`` stamped with the last frame sent (the
localizer's ``retakes``: a robot it tracks was not seen, most often under a glare spot)
renders that instant again with the generator's next draws and sends it, as a camera's next
frame of a scene that has not moved; a request for any other stamp, or while ``paused``, is
ignored. The requests depend only on the frames, so the noise stream stays deterministic.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, replace

import numpy as np
from builtin_interfaces.msg import Time as TimeMsg
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from excavation_interfaces.msg import Retake
from geometry_msgs.msg import PoseWithCovarianceStamped
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import Image, JointState, LaserScan

from excavation_common.frames import robot_anchor
from excavation_common.messages import MessageError, image_to_grid
from excavation_common.params import param
from excavation_common.ros import LATCHED, declare_params, diagnostics, spin_node
from excavation_sim.camera import CameraParams, OverheadCamera, RobotView, default_beacons
from excavation_sim.laser import LaserParams, OverheadLaser, surface_with_robots
from overhead_localizer.images import frame_to_message
from overhead_localizer.params import RETAKE_TOPIC
from terrain_mapper.geometry import PAN_JOINT, TILT_JOINT, yaw_of


def parse_occlude(text: str) -> frozenset[tuple[int, str]]:
    """``"0:front,2:rear"`` -> ``{(0, "front"), (2, "rear")}``.

    Raises:
        ValueError: An entry that is not ``K:front`` or ``K:rear``.
    """
    out = set()
    for item in filter(None, (s.strip() for s in text.split(","))):
        robot, _, side = item.partition(":")
        if not robot.isdigit() or side not in ("front", "rear"):
            raise ValueError(f"occlude: {item!r} is not K:front or K:rear")
        out.add((int(robot), side))
    return frozenset(out)


def _add(stamp: TimeMsg, seconds: float) -> TimeMsg:
    total = stamp.sec * 1_000_000_000 + stamp.nanosec + int(round(seconds * 1e9))
    return TimeMsg(sec=total // 1_000_000_000, nanosec=total % 1_000_000_000)


@dataclass(frozen=True)
class SensorsParams:
    """Parameters of the synthetic camera and laser (``config/sensors.yaml`` of the trial).

    The camera's and the laser's own settings default to :class:`CameraParams` and
    :class:`LaserParams` (one place for each default); the site geometry places them.
    """

    robots: int = param(4, "team size", low=1, high=64)
    seed: int = param(0, "noise seed", low=0, high=2**63 - 1)
    truth_prefix: str = param("/truth", "prefix of the simulator's true poses and heights")
    cell_size: float = param(0.25, "m per grid cell", low=1e-3, high=100.0)
    rows: int = param(16, "grid rows", low=2, high=4096)
    cols: int = param(16, "grid columns", low=2, high=4096)
    width: int = param(CameraParams.width, "camera image width, px", low=16, high=8192)
    height: int = param(CameraParams.height, "camera image height, px", low=16, high=8192)
    light: float = param(CameraParams.light, "ambient light level", low=0.0, high=1.0)
    noise: float = param(CameraParams.noise, "pixel noise (std, grey levels)", low=0.0, high=255.0)
    glare: float = param(CameraParams.glare, "glare strength", low=0.0, high=100.0)
    dropout: float = param(
        CameraParams.dropout,
        "probability an LED is missing from a frame (settable at runtime)",
        low=0.0,
        high=1.0,
        read_only=False,
    )
    k1: float = param(CameraParams.k1, "radial lens distortion", low=-1.0, high=1.0)
    occlude: str = param(
        "", "LEDs hidden from the camera: K:front,K:rear (settable at runtime)", read_only=False
    )
    range_noise: float = param(
        LaserParams.range_noise, "laser range noise (std, m)", low=0.0, high=10.0
    )
    laser_dropout: float = param(
        LaserParams.dropout, "share of laser beams lost", low=0.0, high=1.0
    )
    sweep_scans: int = param(LaserParams.sweep_scans, "scans per laser sweep", low=1, high=100_000)
    scan_period: float = param(0.01, "s of sim time between scans", low=1e-6, high=60.0)
    reliable: bool = param(False, "reliable QoS for frames and scans (bags, tests)")
    paused: bool = param(
        False, "no camera frames while true (settable at runtime)", read_only=False
    )
    laser_paused: bool = param(
        False, "no laser sweeps while true (settable at runtime)", read_only=False
    )
    frame_period: float = param(
        0.0,
        "min wall-clock s between frames, 0: none (settable at runtime)",
        low=0.0,
        high=3600.0,
        read_only=False,
    )
    queue: int = param(200, "queue depth with reliable QoS", low=1, high=100_000)

    def check(self) -> None:
        """``occlude`` must parse."""
        parse_occlude(self.occlude)


class SensorsNode(Node):
    """Renders camera frames and laser sweeps from the simulator's truth."""

    def __init__(self, **kwargs) -> None:
        super().__init__("sensors", **kwargs)
        self.params = p = declare_params(self, SensorsParams, on_change=self.on_params)
        self.n = p.robots
        self.rng = np.random.default_rng(p.seed)
        prefix = p.truth_prefix.rstrip("/")
        self.cell_size = p.cell_size
        self.rows = p.rows
        self.cols = p.cols
        self.camera_params = CameraParams.for_site(
            self.cols * self.cell_size,
            self.rows * self.cell_size,
            width=p.width,
            height=p.height,
            light=p.light,
            noise=p.noise,
            glare=p.glare,
            dropout=p.dropout,
            k1=p.k1,
        )
        self.hidden = parse_occlude(p.occlude)
        self.laser_params = LaserParams.for_site(
            self.rows,
            self.cols,
            self.cell_size,
            range_noise=p.range_noise,
            dropout=p.laser_dropout,
            sweep_scans=p.sweep_scans,
        )
        self.scan_period = p.scan_period
        reliable = p.reliable
        queue = p.queue
        qos = (
            QoSProfile(depth=queue, reliability=ReliabilityPolicy.RELIABLE)
            if reliable
            else qos_profile_sensor_data
        )
        self.camera: OverheadCamera | None = None
        self.laser: OverheadLaser | None = None
        self.poses: dict[int, tuple[tuple[int, int], tuple[float, float, float]]] = {}
        self.heights: tuple[tuple[int, int], np.ndarray] | None = None
        self.last: tuple[int, int] | None = None
        self.ready: tuple | None = None  # (stamp, heights, views, anchors, fine) to send
        self.frame: tuple | None = None  # (stamp key, rendered Image) not sent yet
        self.sweep_msgs: tuple | None = None  # (stamp key, [(mount, scan)]) not sent yet
        self.camera_done: tuple[int, int] | None = None
        self.laser_done: tuple[int, int] | None = None
        self.frame_time = -float("inf")  # time.monotonic() of the last frame
        self.sent: tuple | None = None  # (stamp key, stamp, heights, views) of the last frame
        self.frames = 0
        self.retakes = 0
        self.problem = ""

        self.image_pub = self.create_publisher(Image, "/overhead/image_raw", qos)
        self.scan_pub = self.create_publisher(LaserScan, "/worksite/scan", qos)
        self.mount_pub = self.create_publisher(
            JointState, "/worksite/laser_mount/joint_states", qos
        )
        for k in range(self.n):
            self.create_subscription(
                PoseWithCovarianceStamped,
                f"{prefix}/robot_{k}/pose",
                lambda m, k=k: self.on_pose(k, m),
                10,
            )
        self.create_subscription(Image, f"{prefix}/worksite/height_map", self.on_heights, LATCHED)
        self.create_subscription(Retake, RETAKE_TOPIC, self.on_retake, 10)
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.create_timer(1.0, self.publish_diagnostics)
        self.create_timer(0.01, self.send_ready)  # what a fault held back, once it ends

    def on_params(self, params: SensorsParams) -> None:
        """Runtime changes: the fault knobs, ``occlude`` and ``dropout``."""
        self.params = params
        self.hidden = parse_occlude(params.occlude)
        if params.dropout != self.camera_params.dropout:
            self.camera_params = replace(self.camera_params, dropout=params.dropout)
            self.camera = None  # rebuilt with the new dropout at the next frame
        self.send_ready()

    def publish_diagnostics(self) -> None:
        """OK while frames and sweeps go out; WARN with the last skipped input."""
        level = DiagnosticStatus.WARN if self.problem else DiagnosticStatus.OK
        message = self.problem or (
            f"rendered {self.frames} frames and sweeps" if self.frames else "waiting for truth"
        )
        values = {"frames": self.frames, "retakes": self.retakes}
        self.diag_pub.publish(diagnostics(self, level, message, values))

    def on_pose(self, k: int, msg: PoseWithCovarianceStamped) -> None:
        """A robot's true pose."""
        q, pos = msg.pose.pose.orientation, msg.pose.pose.position
        yaw = yaw_of(q)
        key = (msg.header.stamp.sec, msg.header.stamp.nanosec)
        self.poses[k] = (key, (pos.x, pos.y, yaw))
        self.maybe_render(msg.header.stamp)

    def on_heights(self, msg: Image) -> None:
        """The true height map (metres)."""
        try:
            grid = image_to_grid(msg, "32FC1", "truth height map")
        except MessageError as exc:
            self.get_logger().warning(str(exc), throttle_duration_sec=5.0)
            self.problem = str(exc)
            return
        self.problem = ""
        self.heights = ((msg.header.stamp.sec, msg.header.stamp.nanosec), grid)
        self.maybe_render(msg.header.stamp)

    def maybe_render(self, stamp: TimeMsg) -> None:
        """Render once every input of a new stamp is in."""
        key = (stamp.sec, stamp.nanosec)
        if self.heights is None or self.heights[0] != key or (self.last and key <= self.last):
            return
        if any(k not in self.poses or self.poses[k][0] != key for k in range(self.n)):
            return
        self.last = key
        self.prepare(stamp, self.heights[1].astype(np.float64))

    def prepare(self, stamp: TimeMsg, heights: np.ndarray) -> None:
        """Make this instant the one to render; send what no fault holds back."""
        rows, cols = heights.shape
        scale = rows // self.rows
        if scale < 1 or (rows, cols) != (self.rows * scale, self.cols * scale):
            self.problem = (
                f"truth height map is {rows} x {cols} cells, the sensors are set up for "
                f"{self.rows} x {self.cols} (parameters rows, cols) or a whole multiple: "
                "frame skipped"
            )
            self.get_logger().error(self.problem, throttle_duration_sec=5.0)
            return
        fine = heights
        if scale > 1:
            heights = fine.reshape(self.rows, scale, self.cols, scale).mean(axis=(1, 3))
        if self.laser is None or self.laser.cell_size != self.cell_size / scale:
            self.laser = OverheadLaser(self.laser_params, self.cell_size / scale)
        views, anchors = [], []
        for k in range(self.n):
            x, y, yaw = self.poses[k][1]
            r, c = robot_anchor(x, y, self.cell_size)
            anchors.append((r, c))
            block = heights[max(r, 0) : r + 2, max(c, 0) : c + 2]
            views.append(RobotView(x, y, yaw, float(block.mean()) if block.size else 0.0))
        self.ready = (stamp, heights, views, anchors, fine)
        self.send_ready()

    def send_ready(self) -> None:
        """Publish the ready instant's frame and sweep unless a fault holds them back.

        A frame (sweep) is rendered as soon as no fault holds it, so the noise stream does
        not depend on who listens; it goes out once some node subscribes to the camera (the
        laser), and is dropped unsent if a newer instant comes first.
        """
        if self.ready is None:
            return
        stamp, heights, views, anchors, fine = self.ready
        key = (stamp.sec, stamp.nanosec)
        p = self.params
        now = time.monotonic()
        if self.camera_done != key and not p.paused and now - self.frame_time >= p.frame_period:
            if self.frame is None or self.frame[0] != key:
                if self.camera is None:
                    self.camera = OverheadCamera(
                        self.camera_params, default_beacons(), self.rows, self.cols, self.cell_size
                    )
                image, _ = self.camera.render(views, heights, self.rng, self.hidden)
                self.frame = (key, frame_to_message(image, Image(), stamp=stamp))
            # Held until the localizer's subscription is matched: a lockstep tick has one
            # frame, and one sent before would be lost (the whole team would miss the tick).
            if self.image_pub.get_subscription_count() > 0:
                self.image_pub.publish(self.frame[1])
                self.sent = (key, stamp, heights, views)
                self.frame = None
                self.camera_done, self.frame_time = key, now
        if self.laser_done != key and not p.laser_paused:
            if self.sweep_msgs is None or self.sweep_msgs[0] != key:
                self.sweep_msgs = (key, self.sweep(stamp, fine, anchors))
            if (
                self.scan_pub.get_subscription_count() > 0
                and self.mount_pub.get_subscription_count() > 0
            ):
                for mount, scan in self.sweep_msgs[1]:
                    self.mount_pub.publish(mount)
                    self.scan_pub.publish(scan)
                self.sweep_msgs = None
                self.laser_done = key
        if self.camera_done == key and self.laser_done == key:
            self.ready = None
            self.frames += 1

    def on_retake(self, msg: Retake) -> None:
        """Render the last frame's instant again (a localizer missed a robot in it)."""
        key = (msg.stamp.sec, msg.stamp.nanosec)
        if self.sent is None or self.sent[0] != key or self.params.paused:
            return
        _, stamp, heights, views = self.sent
        image, _ = self.camera.render(views, heights, self.rng, self.hidden)
        self.image_pub.publish(frame_to_message(image, Image(), stamp=stamp))
        self.retakes += 1

    def sweep(self, stamp: TimeMsg, heights: np.ndarray, anchors: list) -> list[tuple]:
        """One laser sweep of this instant: (mount joint state, scan) pairs to publish.

        ``heights``: the truth map, cells or a whole multiple finer.
        """
        lp = self.laser_params
        scale = heights.shape[0] // self.rows
        surface = surface_with_robots(heights, np.array(anchors) * scale, lp.robot_height, scale)
        out = []
        for i, (pan, tilt, ranges) in enumerate(self.laser.sweep(surface, self.rng)):
            scan_stamp = _add(stamp, i * self.scan_period)
            mount = JointState(name=[PAN_JOINT, TILT_JOINT], position=[pan, tilt])
            mount.header.stamp = scan_stamp
            scan = LaserScan()
            scan.header.stamp = scan_stamp
            scan.header.frame_id = "overhead_laser"
            scan.angle_min = lp.angle_min
            scan.angle_max = lp.angle_max
            scan.angle_increment = lp.angle_increment
            scan.scan_time = self.scan_period
            scan.range_min = lp.range_min
            scan.range_max = lp.range_max
            scan.ranges = ranges.tolist()
            out.append((mount, scan))
        return out


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run excavation_sim sensors``."""
    return spin_node(SensorsNode, args)


if __name__ == "__main__":
    sys.exit(main())
