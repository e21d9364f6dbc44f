"""``ros2 run dome_emulator camera``: the dome's overhead camera driver, emulated.

Stands in for the camera driver a dome runs (a vendor's GigE or USB camera node): frames at
``frame_rate`` on the wall clock, each rendering the world's current truth with the
simulator's camera model (:mod:`dome_emulator.camera`), published under the node's
namespace as a camera driver does. Run it in ``/overhead`` to get the site file's topics::

    ros2 run dome_emulator camera --ros-args -r __ns:=/overhead -p encoding:=jpeg

Subscribes ``{truth_prefix}/robot_k/pose`` (PoseWithCovarianceStamped, k < ``robots``)
and ``{truth_prefix}/worksite/height_map`` (Image 32FC1 metres, latched): ``dynamics``'
per-step poses under its ``pose_prefix`` (``/truth`` in a continuous trial with full
perception) and its height map under ``snapshot_prefix``.

Publishes, best effort (sensor data QoS), ``image_raw/compressed``
(sensor_msgs/CompressedImage, ``encoding: jpeg``) or ``image_raw`` (sensor_msgs/Image,
``bgr8`` or ``yuv422``), and ``camera_info`` (sensor_msgs/CameraInfo) with the same stamp:
the node clock at capture plus ``stamp_offset``, published ``latency`` seconds after the
capture. ``/diagnostics``: ``/overhead/camera``, OK with the frames sent, WARN while a
robot's pose has not come (no frame) or the height map is bad or missing (flat floor).
"""

from __future__ import annotations

import sys
import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.time import Time
from sensor_msgs.msg import CameraInfo, CompressedImage, Image

from dome_emulator.camera import (
    BGR8,
    JPEG,
    CameraCore,
    CameraEmulatorParams,
    Frame,
    Waiting,
    yuv422_message,
)
from dome_emulator.truth_feed import TruthFeed
from excavation_common.ros import (
    SENSOR_DATA,
    declare_params,
    diagnostics,
    spin_node,
)
from overhead_localizer.images import frame_to_compressed, frame_to_message


class CameraNode(Node):
    """Thin ROS plumbing around :class:`CameraCore`."""

    def __init__(self, **kwargs) -> None:
        super().__init__("camera", **kwargs)
        self.params = p = declare_params(self, CameraEmulatorParams)
        self.core = CameraCore(p)
        self.waiting = ""
        self.steady = Clock(clock_type=ClockType.STEADY_TIME)
        if p.encoding == JPEG:
            self.image_pub = self.create_publisher(
                CompressedImage, "image_raw/compressed", SENSOR_DATA
            )
        else:
            self.image_pub = self.create_publisher(Image, "image_raw", SENSOR_DATA)
        self.info_pub = self.create_publisher(CameraInfo, "camera_info", SENSOR_DATA)
        self.info = self.core.camera_info()
        self.feed = TruthFeed(self, self.core.truth, p.truth_prefix, p.robots)
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.pending: list[object] = []  # the one-shot timers of frames in their latency
        self.create_timer(1.0 / p.frame_rate, self.capture, clock=self.steady)
        self.create_timer(p.diagnostics_period, self.publish_diagnostics)

    def capture(self) -> None:
        """Capture a frame of the truth; publish it now or after the latency."""
        clock_ns = self.get_clock().now().nanoseconds
        match self.core.capture(clock_ns, time.monotonic()):
            case Waiting(reason):
                self.waiting = reason
            case Frame() as frame:
                self.waiting = ""
                if self.params.latency <= 0.0:
                    self.publish(frame)
                else:
                    self.later(frame)

    def later(self, frame: Frame) -> None:
        """Publish ``frame`` once its latency has passed (a one-shot timer)."""
        holder: list = []

        def fire() -> None:
            self.destroy_timer(holder[0])
            self.pending.remove(holder[0])
            self.publish(frame)

        delay = max(frame.due - time.monotonic(), 1e-4)
        holder.append(self.create_timer(delay, fire, clock=self.steady))
        self.pending.append(holder[0])

    def publish(self, frame: Frame) -> None:
        """The frame and its camera_info, with the frame's stamp."""
        p = self.params
        stamp = Time(nanoseconds=frame.stamp_ns).to_msg()
        if p.encoding == JPEG:
            msg = frame_to_compressed(
                frame.image, CompressedImage(), JPEG, p.jpeg_quality, p.frame_id, stamp
            )
        elif p.encoding == BGR8:
            msg = frame_to_message(frame.image, Image(), p.frame_id, stamp)
        else:
            msg = yuv422_message(frame.image, Image(), p.frame_id, stamp)
        self.image_pub.publish(msg)
        self.info_pub.publish(self.camera_info(stamp))

    def camera_info(self, stamp) -> CameraInfo:
        """The CameraInfo message of the core's values."""
        v = self.info
        msg = CameraInfo()
        msg.header.stamp = stamp
        msg.header.frame_id = self.params.frame_id
        msg.width, msg.height = v.width, v.height
        msg.distortion_model = v.distortion_model
        msg.d = list(v.d)
        msg.k, msg.r, msg.p = list(v.k), list(v.r), list(v.p)
        return msg

    def publish_diagnostics(self) -> None:
        """OK while frames go out; WARN while waiting for poses or with a bad height map."""
        c = self.core
        if self.waiting:
            level, message = DiagnosticStatus.WARN, f"waiting for the world: {self.waiting}"
        elif self.feed.problem:
            level, message = DiagnosticStatus.WARN, self.feed.problem
        elif c.truth.heights is None:
            level = DiagnosticStatus.WARN
            message = f"no height map on {self.feed.heights_topic} yet: rendering a flat floor"
        else:
            level, message = DiagnosticStatus.OK, f"{c.frames} frames"
        values = {
            "frames": c.frames,
            "frame_rate": self.params.frame_rate,
            "encoding": self.params.encoding,
            "stamp_offset": self.params.stamp_offset,
            "latency": self.params.latency,
            "uncalibrated": self.params.uncalibrated,
        }
        self.diag_pub.publish(diagnostics(self, level, message, values, hardware_id="camera"))


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run dome_emulator camera``."""
    return spin_node(CameraNode, args)


if __name__ == "__main__":
    sys.exit(main())
