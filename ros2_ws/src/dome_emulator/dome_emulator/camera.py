"""An overhead camera driver on its own clock, rendering the world's truth (pure).

A real dome camera (a GigE or USB camera and its ROS driver) captures at its frame rate
whatever the dome looks like at that moment, stamps each frame with its clock, and hands
it on some time later (exposure, transfer, encoding). :class:`CameraCore` does that with
the simulator's camera model (:class:`excavation_sim.camera.OverheadCamera`): at each
capture it renders the world's current truth (:class:`dome_emulator.truth.Truth`: the
latest poses, the latest height map or a flat floor until one has come), stamped with the
node clock at capture plus ``stamp_offset`` (a camera clock that is off), and due for
publication ``latency`` seconds later. Its ``camera_info`` carries the model's intrinsics
(K, ``plumb_bob`` D, P = [K | 0]), or, with ``uncalibrated``, what a driver without a
calibration file publishes: the image size with K, R, P all zero and no distortion model.

Encodings: ``jpeg`` (``sensor_msgs/CompressedImage`` on ``image_raw/compressed``, written
as ``image_transport``'s compressed plugin writes it), raw ``bgr8`` and ``yuv422`` (packed
U Y0 V Y1, ``sensor_msgs/image_encodings``' ``yuv422``, OpenCV's BT.601 conversion, as
``cv_bridge`` converts it) on ``image_raw``. All noise comes from one generator seeded by
``seed``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from dome_emulator.truth import Truth
from excavation_common.params import param
from excavation_sim.camera import CameraParams, OverheadCamera, default_beacons

JPEG = "jpeg"
BGR8 = "bgr8"
YUV422 = "yuv422"


@dataclass(frozen=True)
class CameraEmulatorParams:
    """The emulated camera's parameters (the scene's default to :class:`CameraParams`)."""

    robots: int = param(4, "team size (robots rendered)", low=1, high=64)
    truth_prefix: str = param(
        "/truth", "prefix of the world's poses (robot_k/pose) and height map (worksite/height_map)"
    )
    rows: int = param(16, "grid rows", low=2, high=4096)
    cols: int = param(16, "grid columns", low=2, high=4096)
    cell_size: float = param(0.25, "m per grid cell", low=1e-3, high=100.0)
    width: int = param(CameraParams.width, "image width, px", low=16, high=8192)
    height: int = param(CameraParams.height, "image height, px", low=16, high=8192)
    light: float = param(CameraParams.light, "ambient light level", low=0.0, high=1.0)
    noise: float = param(CameraParams.noise, "pixel noise (std, grey levels)", low=0.0, high=255.0)
    glare: float = param(CameraParams.glare, "glare blobs per frame (mean)", low=0.0, high=100.0)
    dropout: float = param(
        CameraParams.dropout, "probability an LED is missing from a frame", low=0.0, high=1.0
    )
    k1: float = param(CameraParams.k1, "radial lens distortion", low=-1.0, high=1.0)
    seed: int = param(0, "noise seed", low=0, high=2**63 - 1)
    frame_rate: float = param(10.0, "frames per second (wall clock)", low=0.1, high=120.0)
    encoding: str = param(
        JPEG,
        "jpeg (CompressedImage on image_raw/compressed), bgr8 or yuv422 (Image on image_raw)",
        choices=(JPEG, BGR8, YUV422),
    )
    jpeg_quality: int = param(90, "JPEG quality", low=1, high=100)
    stamp_offset: float = param(
        0.0,
        "s added to the node clock in every stamp (a camera clock off)",
        low=-3600.0,
        high=3600.0,
    )
    latency: float = param(0.0, "s from capture to publication", low=0.0, high=10.0)
    uncalibrated: bool = param(False, "camera_info without a calibration: K, R, P all zero")
    frame_id: str = param("overhead_camera", "frame of the images and camera_info")
    diagnostics_period: float = param(1.0, "s between diagnostics", low=0.05, high=3600.0)

    def check(self) -> None:
        """Packed YUV 4:2:2 needs an even width (two pixels share U and V)."""
        if self.encoding == YUV422 and self.width % 2:
            raise ValueError(f"encoding yuv422 needs an even width, got width {self.width}")

    def camera_params(self) -> CameraParams:
        """The camera model over the site's centre (as the simulator's ``sensors`` places it)."""
        return CameraParams.for_site(
            self.cols * self.cell_size,
            self.rows * self.cell_size,
            width=self.width,
            height=self.height,
            light=self.light,
            noise=self.noise,
            glare=self.glare,
            dropout=self.dropout,
            k1=self.k1,
        )


@dataclass(frozen=True)
class Frame:
    """A captured frame: BGR pixels, its stamp and when it is due for publication.

    Attributes:
        stamp_ns: The frame's stamp (node clock at capture plus ``stamp_offset``), ns.
        due: When to publish it, seconds of the capture clock.
        image: ``uint8 [height, width, 3]`` BGR.
        leds: The true pixel positions ``[robots, 2, (u, v, visible)]`` (for tests).
    """

    stamp_ns: int
    due: float
    image: np.ndarray
    leds: np.ndarray


@dataclass(frozen=True)
class Waiting:
    """No frame: ``reason`` (robots without a pose yet)."""

    reason: str


@dataclass(frozen=True)
class CameraInfoValues:
    """What ``sensor_msgs/CameraInfo`` carries, row-major."""

    width: int
    height: int
    distortion_model: str
    d: tuple[float, ...]
    k: tuple[float, ...]
    r: tuple[float, ...]
    p: tuple[float, ...]


Capture = Frame | Waiting


class CameraCore:
    """Captures frames of the world's truth (module docstring)."""

    def __init__(self, params: CameraEmulatorParams) -> None:
        """A camera over the site of ``params``; nothing seen yet."""
        self.params = params
        self.model = params.camera_params()
        self.camera = OverheadCamera(
            self.model, default_beacons(), params.rows, params.cols, params.cell_size
        )
        self.rng = np.random.default_rng(params.seed)
        self.truth = Truth(params.robots, params.rows, params.cols, params.cell_size)
        self.frames = 0
        self.waited = 0

    def capture(self, clock_ns: int, now: float) -> Capture:
        """A frame of the truth now, or why none can be taken.

        It is stamped ``clock_ns + stamp_offset`` and due at ``now + latency`` (``now`` in
        seconds of the clock that times the publication).
        """
        missing = self.truth.missing()
        if missing:
            self.waited += 1
            return Waiting(f"no pose yet of robot(s) {', '.join(map(str, missing))}")
        image, leds = self.camera.render(self.truth.views(), self.truth.ground(), self.rng)
        self.frames += 1
        p = self.params
        stamp_ns = clock_ns + int(round(p.stamp_offset * 1e9))
        return Frame(stamp_ns, now + p.latency, image, leds)

    def camera_info(self) -> CameraInfoValues:
        """The driver's CameraInfo: the model's intrinsics, or all zero when uncalibrated."""
        p = self.params
        if p.uncalibrated:
            zero9, zero12 = (0.0,) * 9, (0.0,) * 12
            return CameraInfoValues(p.width, p.height, "", (), zero9, zero9, zero12)
        k = self.model.camera_matrix()
        proj = np.hstack([k, np.zeros((3, 1))])
        return CameraInfoValues(
            p.width,
            p.height,
            "plumb_bob",
            tuple(float(v) for v in self.model.dist_coeffs()),
            tuple(float(v) for v in k.ravel()),
            tuple(float(v) for v in np.eye(3).ravel()),
            tuple(float(v) for v in proj.ravel()),
        )


def yuv422_message(image: np.ndarray, msg, frame_id: str, stamp=None):
    """Fill ``msg`` (a fresh ``sensor_msgs/Image``) with a BGR frame as packed ``yuv422``.

    ``yuv422`` is U Y0 V Y1 (``sensor_msgs/image_encodings``; OpenCV's UYVY).
    """
    packed = cv2.cvtColor(np.ascontiguousarray(image, dtype=np.uint8), cv2.COLOR_BGR2YUV_UYVY)
    if stamp is not None:
        msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.height, msg.width = image.shape[:2]
    msg.encoding = YUV422
    msg.is_bigendian = 0
    msg.step = image.shape[1] * 2
    msg.data = packed.tobytes()
    return msg
