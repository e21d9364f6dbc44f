"""``ros2 run overhead_localizer localizer``: robot poses from the overhead camera's LEDs.

Subscribes ``image_topic`` (``/overhead/image_raw``: sensor_msgs/Image in bgr8, rgb8,
bgra8, rgba8, mono8, packed YUV 4:2:2 (yuv422/uyvy, yuv422_yuy2/yuyv) or an 8-bit Bayer
encoding; with ``compressed``, sensor_msgs/CompressedImage jpeg or png, conventionally
``/overhead/image_raw/compressed``) with queue depth 1 (the newest frame only), with
``camera_info_topic`` the driver's sensor_msgs/CameraInfo (frames wait for the first one;
its K and D are used when they agree with the calibration file's, which its camera pose
was fitted with; otherwise, or when K is zero, as an uncalibrated driver sends it, the
file's are used and the camera's status is WARN saying why), and, with
``use_height_map``, ``/worksite/height_map`` + ``/worksite/map_info`` (the soil height under
a robot sets the plane of its LEDs). Publishes for every robot k < ``robots`` it is sure of
``/robot_k/pose`` (PoseWithCovarianceStamped in ``map``, stamped with the frame's stamp,
covariance from the detection) and the same as ``map`` -> ``robot_k/base_link`` on ``/tf``;
``map`` -> ``overhead_camera`` (the calibration's camera pose, optical axes) on
``/tf_static``; with ``annotated_period`` > 0,
``/overhead/image_annotated`` (CompressedImage jpeg: detected LEDs and poses drawn); and,
every ``diagnostics_period``, ``/diagnostics``: the camera's status, named after the node
(``/localizer``; ERROR on a frame of the wrong encoding or size, or colourless mono8
frames; WARN while the CameraInfo's intrinsics are not used), and one per robot
(``/localizer: robot_k``; OK seen, WARN coasting / lost / ambiguous, ERROR when two
robots share LED colours). Bad input never stops the node and never produces a pose.

With ``retakes`` > 0, a frame in which a robot the node was tracking is not seen (a glare
spot washing out one of its LEDs) publishes nothing yet: the node asks for another frame of
the same instant on ``retake_topic`` (excavation_interfaces/Retake: the frame's stamp and
the robots not seen), up to ``retakes`` times, and publishes the poses of the first frame
that shows every tracked robot, or of the last one. The trials' synthetic camera
(``excavation_sim sensors``) answers, so a lockstep team does not wait a whole tick
timeout for a pose that one frame's glare hid.

The node refuses to start (one line on stderr, exit code 2) without ``calibration``, or
with a calibration or LED table file it cannot use: it never falls back to another camera.

Parameters: :class:`overhead_localizer.params.LocalizerNodeParams` (topics, files, QoS)
and :class:`overhead_localizer.localize.LocalizerParams` (detection, pairing, tracking),
declared with descriptors and ranges; every default is in ``config/localizer.yaml``.
"""

from __future__ import annotations

import math
import sys

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from excavation_interfaces.msg import Retake
from geometry_msgs.msg import PoseWithCovarianceStamped
from nav_msgs.msg import MapMetaData
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CameraInfo, CompressedImage, Image

from excavation_common.errors import FieldError
from excavation_common.messages import MessageError, image_to_grid
from excavation_common.params import ParameterError
from excavation_common.ros import LATCHED, LATEST_FRAME, declare_params, diagnostics, spin_node
from excavation_common.tf import (
    CAMERA,
    MAP,
    TfBroadcaster,
    base_frame,
    pose_transform,
    quaternion,
    transform,
)
from overhead_localizer.annotate import annotate
from overhead_localizer.beacons import CONFIG_DIR, load_beacons
from overhead_localizer.camera_info import choose_model
from overhead_localizer.camera_model import load_model
from overhead_localizer.errors import LocalizerConfigError
from overhead_localizer.images import (
    COLOURLESS,
    frame_from_compressed,
    frame_from_message,
    frame_to_compressed,
)
from overhead_localizer.localize import (
    COASTING,
    DUPLICATE,
    LOST,
    SEEN,
    Localizer,
    LocalizerParams,
    RobotEstimate,
    check_image,
)
from overhead_localizer.params import LocalizerNodeParams

ANNOTATED_TOPIC = "/overhead/image_annotated"
"""The annotated camera frame (CompressedImage jpeg)."""

UNESTIMATED = 1e6
"""Variance of the axes a pose does not estimate (z, roll, pitch), as in docs/interfaces.md."""


def pose_with_covariance(estimate: RobotEstimate, stamp) -> PoseWithCovarianceStamped:
    """A ``map`` pose message from an estimate (x, y, yaw and their 3 x 3 covariance)."""
    msg = PoseWithCovarianceStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = "map"
    msg.pose.pose.position.x = float(estimate.x)
    msg.pose.pose.position.y = float(estimate.y)
    msg.pose.pose.orientation.z = math.sin(estimate.yaw / 2)
    msg.pose.pose.orientation.w = math.cos(estimate.yaw / 2)
    cov = np.zeros((6, 6))
    idx = [0, 1, 5]
    cov[np.ix_(idx, idx)] = estimate.covariance
    cov[2, 2] = cov[3, 3] = cov[4, 4] = UNESTIMATED
    msg.pose.covariance = cov.ravel().tolist()
    return msg


class LocalizerNode(Node):
    """Thin ROS plumbing around :class:`overhead_localizer.localize.Localizer`.

    Raises:
        excavation_common.params.ParameterError: A bad parameter, or no ``calibration``.
        overhead_localizer.errors.LocalizerConfigError: The calibration or LED table file
            cannot be used (the node refuses to start: ``spin_node`` exits with code 2).
    """

    def __init__(self, **kwargs) -> None:
        super().__init__("localizer", **kwargs)
        self.config = declare_params(self, LocalizerNodeParams)
        self.params = declare_params(self, LocalizerParams)
        c = self.config
        if not c.calibration:
            raise ParameterError(
                self.get_fully_qualified_name(),
                "calibration",
                "",
                "required: the camera calibration YAML (`ros2 run overhead_localizer calibrate`)",
            )
        self.n = c.robots
        self.use_height_map = c.use_height_map
        self.file_model = load_model(c.calibration)
        beacons = load_beacons(c.beacons or str(CONFIG_DIR / "beacons.yaml"))
        try:
            self.localizer = Localizer(self.file_model, beacons, self.n, self.params)
        except ValueError as exc:
            raise LocalizerConfigError(
                c.beacons or "beacons.yaml", "robots", self.n, str(exc)
            ) from None

        self.camera_warning: str | None = None
        self.info_key: tuple | None = None
        self.image_error: str | None = None
        self.estimates: list[RobotEstimate] = []
        self.blobs: list = []
        self.frames = 0
        self.heights: np.ndarray | None = None
        self.cell_size: float | None = None
        self.info_received = not c.camera_info_topic
        self.encoding = ""
        self.last_annotated = -math.inf
        self.retake_stamp: tuple[int, int] | None = None
        self.retakes_asked = 0
        self.retakes_total = 0
        self.retake_pub = (
            self.create_publisher(Retake, c.retake_topic, 10) if c.retakes > 0 else None
        )

        self.pose_pubs = [
            self.create_publisher(PoseWithCovarianceStamped, f"/robot_{k}/pose", 10)
            for k in range(self.n)
        ]
        self.tf = TfBroadcaster(self, static=True)
        model = self.file_model
        self.tf.send_static([transform(MAP, CAMERA, model.centre, quaternion(model.rotation.T))])
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.annotated_pub = (
            self.create_publisher(CompressedImage, ANNOTATED_TOPIC, 1)
            if c.annotated_period > 0
            else None
        )
        qos = (
            QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)
            if c.reliable
            else LATEST_FRAME
        )
        if c.compressed:
            self.create_subscription(CompressedImage, c.image_topic, self.on_compressed, qos)
        else:
            self.create_subscription(Image, c.image_topic, self.on_image, qos)
        if c.camera_info_topic:
            self.create_subscription(CameraInfo, c.camera_info_topic, self.on_camera_info, qos)
        if self.use_height_map:
            self.create_subscription(Image, "/worksite/height_map", self.on_heights, LATCHED)
            self.create_subscription(MapMetaData, "/worksite/map_info", self.on_info, LATCHED)
        self.create_timer(c.diagnostics_period, self.publish_diagnostics)

    def on_camera_info(self, msg: CameraInfo) -> None:
        """The driver's intrinsics, when they agree with the file's; else the file's (WARN).

        A driver sends the same CameraInfo with every frame: only a changed one is looked
        at, and a warning is logged once, when it first appears (``/diagnostics`` carries
        it while it holds).
        """
        key = (msg.width, msg.height, msg.distortion_model, tuple(msg.k), tuple(msg.d))
        if key == self.info_key:
            return
        self.info_key = key
        model, warning = choose_model(self.file_model, msg, self.config.camera_info_topic)
        if warning is not None and warning != self.camera_warning:
            self.get_logger().warning(warning)
        self.camera_warning = warning
        self.info_received = True
        self.localizer.model = model

    def on_info(self, msg: MapMetaData) -> None:
        """Cell size of the worksite."""
        self.cell_size = float(msg.resolution) if msg.resolution > 0 else None

    def on_heights(self, msg: Image) -> None:
        """Soil heights (m) for the LED planes; a malformed map is ignored (and logged)."""
        try:
            self.heights = image_to_grid(msg, "32FC1", "/worksite/height_map")
        except MessageError as exc:
            self.get_logger().warning(str(exc), throttle_duration_sec=5.0)

    def on_image(self, msg: Image) -> None:
        """One raw frame."""
        self.encoding = msg.encoding
        self.process(msg, lambda: frame_from_message(msg, self.config.image_topic))

    def on_compressed(self, msg: CompressedImage) -> None:
        """One jpeg or png frame."""
        self.encoding = msg.format
        self.process(msg, lambda: frame_from_compressed(msg, self.config.image_topic))

    def process(self, msg, decode) -> None:
        """Decode a frame and publish the poses of the robots the localizer is sure of."""
        if not self.info_received:
            self.image_error = f"waiting for {self.config.camera_info_topic}: frame skipped"
            return
        try:
            frame = decode()
            check_image(frame, self.localizer.model, self.config.image_topic)
            heights = self.heights if self.cell_size is not None else None
            stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
            tracked = set(self.localizer.tracks)
            self.blobs = self.localizer.detect(frame)
            self.estimates = self.localizer.associate(
                self.blobs, heights, self.cell_size or 0.25, stamp
            )
        except FieldError as exc:
            self.image_error = str(exc)
            self.get_logger().warning(self.image_error, throttle_duration_sec=5.0)
            return
        self.image_error = None
        self.frames += 1
        if self.retake(msg.header.stamp, tracked):
            return
        frames = []
        for k, estimate in enumerate(self.estimates):
            if estimate.reportable:
                pose = pose_with_covariance(estimate, msg.header.stamp)
                self.pose_pubs[k].publish(pose)
                frames.append(pose_transform(pose, base_frame(k)))
        if frames:
            self.tf.send(frames)
        if self.annotated_pub is not None:
            now = self.get_clock().now().nanoseconds * 1e-9
            if now - self.last_annotated >= self.config.annotated_period:
                self.last_annotated = now
                image = annotate(frame, self.blobs, self.estimates, self.localizer)
                out = frame_to_compressed(
                    image, CompressedImage(), "jpeg", 80, stamp=msg.header.stamp
                )
                self.annotated_pub.publish(out)

    def retake(self, stamp, tracked: set[int]) -> bool:
        """Ask for another frame of ``stamp`` when a tracked robot was not seen in this one.

        True: asked (this frame's poses are held back); False: publish this frame's poses
        (every tracked robot seen, retakes off, or this instant's retakes spent).
        """
        if self.retake_pub is None:
            return False
        unseen = [k for k in sorted(tracked) if self.estimates[k].status == LOST]
        key = (stamp.sec, stamp.nanosec)
        if key != self.retake_stamp:
            self.retake_stamp, self.retakes_asked = key, 0
        if not unseen or self.retakes_asked >= self.config.retakes:
            return False
        self.retakes_asked += 1
        self.retakes_total += 1
        self.retake_pub.publish(Retake(stamp=stamp, unseen=unseen))
        return True

    def camera_status(self) -> tuple[bytes, str]:
        """The camera's level and message."""
        if self.image_error:
            return DiagnosticStatus.ERROR, self.image_error
        if self.encoding in COLOURLESS:
            return DiagnosticStatus.ERROR, (
                f"{self.encoding} frames carry no colour: the LED pairs cannot be told apart "
                "(set the camera to a colour or Bayer encoding)"
            )
        if self.camera_warning:
            return DiagnosticStatus.WARN, self.camera_warning
        return DiagnosticStatus.OK, f"{self.frames} frames"

    def robot_statuses(self) -> list[DiagnosticStatus]:
        """One status per robot, named ``<node>: robot_k``."""
        out = []
        for k in range(self.n):
            s = DiagnosticStatus(
                name=f"{self.get_fully_qualified_name()}: robot_{k}", hardware_id=f"robot_{k}"
            )
            if k < len(self.estimates):
                e = self.estimates[k]
                s.level = {
                    SEEN: DiagnosticStatus.OK,
                    DUPLICATE: DiagnosticStatus.ERROR,
                }.get(e.status, DiagnosticStatus.WARN)
                s.message = e.status if not e.detail else f"{e.status}: {e.detail}"
                if e.status in (SEEN, COASTING):
                    s.values = [
                        KeyValue(key="x", value=f"{e.x:.4f}"),
                        KeyValue(key="y", value=f"{e.y:.4f}"),
                        KeyValue(key="yaw", value=f"{e.yaw:.4f}"),
                        KeyValue(key="sigma_xy", value=f"{math.sqrt(e.covariance[0, 0]):.4f}"),
                    ]
            else:
                s.level = DiagnosticStatus.WARN
                s.message = "no frame yet"
            out.append(s)
        return out

    def publish_diagnostics(self) -> None:
        """The camera's status (named after the node) and one per robot."""
        level, message = self.camera_status()
        values = {
            "frames": self.frames,
            "encoding": self.encoding or "none yet",
            "retakes": self.retakes_total,
        }
        msg = diagnostics(self, level, message, values, hardware_id="overhead_camera")
        msg.status += self.robot_statuses()
        self.diag_pub.publish(msg)


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run overhead_localizer localizer``."""
    return spin_node(LocalizerNode, args)


if __name__ == "__main__":
    sys.exit(main())
