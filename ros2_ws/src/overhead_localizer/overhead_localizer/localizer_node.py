"""``ros2 run overhead_localizer localizer``: robot poses from the overhead camera's LEDs.

Subscribes ``/overhead/image_raw`` (sensor_msgs/Image ``bgr8``) and, with
``use_height_map``, ``/worksite/height_map`` + ``/worksite/map_info`` (the soil height
under a robot sets the plane of its LEDs). Publishes for every robot k < ``robots`` it is
sure of ``/robot_k/pose`` (PoseWithCovarianceStamped in ``map``, stamped with the frame's
stamp, covariance from the detection) and, every ``diagnostics_period``, ``/diagnostics``:
one status per robot (OK seen, WARN coasting / lost / ambiguous, ERROR when two robots
share LED colours) and one for the camera (ERROR on a missing calibration or a frame of the
wrong encoding or size). Bad input never stops the node and never produces a pose.

Parameters: ``calibration`` (YAML written by ``calibrate``; empty: the simulator's camera,
``config/camera_sim.yaml``), ``beacons`` (LED table; empty: ``config/beacons.yaml``),
``robots`` (4), ``use_height_map`` (true), ``reliable`` (false: sensor-data QoS for the
image; true: reliable, depth 10), ``diagnostics_period`` (1.0 s), and every field of
:class:`overhead_localizer.localize.LocalizerParams` (defaults in ``config/localizer.yaml``).
"""

from __future__ import annotations

import math
import sys
from dataclasses import fields

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseWithCovarianceStamped
from nav_msgs.msg import MapMetaData
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import Image

from excavation_common.errors import FieldError
from excavation_common.messages import MessageError, image_to_grid
from excavation_common.ros import LATCHED, spin_node
from overhead_localizer.beacons import CONFIG_DIR, load_beacons
from overhead_localizer.camera_model import load_model
from overhead_localizer.images import frame_from_message
from overhead_localizer.localize import (
    COASTING,
    DUPLICATE,
    SEEN,
    Localizer,
    LocalizerParams,
    RobotEstimate,
)

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
    """Thin ROS plumbing around :class:`overhead_localizer.localize.Localizer`."""

    def __init__(self, **kwargs) -> None:
        super().__init__("localizer", **kwargs)
        p = self.declare_parameter
        self.n = int(p("robots", 4).value)
        self.use_height_map = bool(p("use_height_map", True).value)
        calibration = str(p("calibration", "").value) or str(CONFIG_DIR / "camera_sim.yaml")
        beacons_file = str(p("beacons", "").value) or str(CONFIG_DIR / "beacons.yaml")
        values = {}
        for f in fields(LocalizerParams):
            default = getattr(LocalizerParams(), f.name)
            values[f.name] = type(default)(p(f.name, default).value)
        self.params = LocalizerParams(**values)
        period = float(p("diagnostics_period", 1.0).value)
        reliable = bool(p("reliable", False).value)

        self.camera_error: str | None = None
        self.image_error: str | None = None
        self.localizer: Localizer | None = None
        self.estimates: list[RobotEstimate] = []
        self.frames = 0
        self.heights: np.ndarray | None = None
        self.cell_size: float | None = None
        try:
            self.localizer = Localizer(
                load_model(calibration), load_beacons(beacons_file), self.n, self.params
            )
        except (FieldError, ValueError) as exc:
            self.camera_error = str(exc)
            self.get_logger().error(f"localizer not ready: {exc}")

        self.pose_pubs = [
            self.create_publisher(PoseWithCovarianceStamped, f"/robot_{k}/pose", 10)
            for k in range(self.n)
        ]
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        qos = (
            QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
            if reliable
            else qos_profile_sensor_data
        )
        self.create_subscription(Image, "/overhead/image_raw", self.on_image, qos)
        if self.use_height_map:
            self.create_subscription(Image, "/worksite/height_map", self.on_heights, LATCHED)
            self.create_subscription(MapMetaData, "/worksite/map_info", self.on_info, LATCHED)
        self.create_timer(period, self.publish_diagnostics)

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
        """One frame: poses of the robots the localizer is sure of."""
        if self.localizer is None:
            return
        try:
            frame = frame_from_message(msg)
            heights = self.heights if self.cell_size is not None else None
            stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
            self.estimates = self.localizer.update(frame, heights, self.cell_size or 0.25, stamp)
        except FieldError as exc:
            self.image_error = str(exc)
            self.get_logger().warning(self.image_error, throttle_duration_sec=5.0)
            return
        self.image_error = None
        self.frames += 1
        for k, estimate in enumerate(self.estimates):
            if estimate.reportable:
                self.pose_pubs[k].publish(pose_with_covariance(estimate, msg.header.stamp))

    def statuses(self) -> list[DiagnosticStatus]:
        """Camera status plus one per robot."""
        camera = DiagnosticStatus(name="localizer: camera", hardware_id="overhead_camera")
        if self.camera_error or self.image_error:
            camera.level = DiagnosticStatus.ERROR
            camera.message = self.camera_error or self.image_error
        else:
            camera.level = DiagnosticStatus.OK
            camera.message = f"{self.frames} frames"
        out = [camera]
        for k in range(self.n):
            s = DiagnosticStatus(name=f"localizer: robot_{k}", hardware_id=f"robot_{k}")
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
                s.message = "no frame yet" if self.localizer else "localizer not ready"
            out.append(s)
        return out

    def publish_diagnostics(self) -> None:
        """Publish the statuses now."""
        msg = DiagnosticArray(status=self.statuses())
        msg.header.stamp = self.get_clock().now().to_msg()
        self.diag_pub.publish(msg)


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run overhead_localizer localizer``."""
    return spin_node(LocalizerNode, args)


if __name__ == "__main__":
    sys.exit(main())
