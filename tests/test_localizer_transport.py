"""The localizer on what real camera drivers send: encodings, CompressedImage, CameraInfo."""

from __future__ import annotations

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseWithCovarianceStamped
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CameraInfo, CompressedImage, Image

from excavation_sim.camera import CameraParams, RobotView
from overhead_localizer.beacons import CONFIG_DIR
from overhead_localizer.camera_info import camera_info_fields, with_camera_info
from overhead_localizer.camera_model import CameraModel, load_model
from overhead_localizer.errors import ImageError
from overhead_localizer.images import (
    ENCODINGS,
    frame_from_compressed,
    frame_from_message,
    frame_to_compressed,
    frame_to_message,
)
from overhead_localizer.localizer_node import LocalizerNode

VIEWS = [RobotView(1.0, 1.0, 0.0), RobotView(3.0, 3.0, np.pi / 2), RobotView(2.2, 1.4, -2.0)]
CALIBRATION = CONFIG_DIR / "camera_sim.yaml"

TOLERANCE_M = 0.005
"""Largest position difference between a raw frame and its jpeg (quality 90), metres."""
TOLERANCE_RAD = 0.02
"""... and of heading, radians."""


@pytest.fixture(scope="module")
def frame(camera):
    return camera.render(VIEWS, np.zeros((16, 16)), np.random.default_rng(0))[0]


def _mosaic(bgr: np.ndarray, pattern: str) -> np.ndarray:
    """The raw Bayer plane a sensor with ``pattern`` (e.g. ``rggb``) gives for ``bgr``."""
    idx = {"r": 2, "g": 1, "b": 0}
    out = np.empty(bgr.shape[:2], dtype=np.uint8)
    for k, ch in enumerate(pattern):
        dy, dx = divmod(k, 2)
        out[dy::2, dx::2] = bgr[dy::2, dx::2, idx[ch]]
    return out


def _with_alpha(bgr: np.ndarray, order: str) -> np.ndarray:
    """``bgra`` or ``rgba`` pixels of a BGR frame (alpha: a pattern, it must be ignored)."""
    colour = bgr if order == "bgra" else bgr[:, :, ::-1]
    alpha = (np.arange(bgr.shape[1]) * 7 % 256).astype(np.uint8)[None, :, None]
    return np.concatenate([colour, np.broadcast_to(alpha, (*bgr.shape[:2], 1))], axis=2)


def _yuv422(bgr: np.ndarray, order: str) -> np.ndarray:
    """Packed YUV 4:2:2 as a camera sends it (BT.601, Y 16..235, U V 16..240), ``order``
    ``yuyv`` (Y0 U Y1 V) or ``uyvy`` (U Y0 V Y1); U and V averaged over each pixel pair.
    Written out here, not with OpenCV, so the decoder's byte order is checked on its own."""
    b, g, r = (bgr[:, :, i].astype(np.float64) for i in range(3))
    y = 16 + (65.481 * r + 128.553 * g + 24.966 * b) / 255
    u = 128 + (-37.797 * r - 74.203 * g + 112.0 * b) / 255
    v = 128 + (112.0 * r - 93.786 * g - 18.214 * b) / 255
    u = (u[:, 0::2] + u[:, 1::2]) / 2
    v = (v[:, 0::2] + v[:, 1::2]) / 2
    y0, y1 = y[:, 0::2], y[:, 1::2]
    quads = [y0, u, y1, v] if order == "yuyv" else [u, y0, v, y1]
    packed = np.stack(quads, axis=2).reshape(bgr.shape[0], bgr.shape[1] * 2)
    return np.clip(np.rint(packed), 0, 255).astype(np.uint8)


YUV_ORDER = {"yuv422": "uyvy", "uyvy": "uyvy", "yuv422_yuy2": "yuyv", "yuyv": "yuyv"}
"""sensor_msgs/image_encodings.hpp: yuv422 is UYVY (deprecated name of uyvy), yuv422_yuy2
is YUYV (deprecated name of yuyv; what usb_cam sends for pixel_format yuyv)."""


def _raw(bgr: np.ndarray, encoding: str) -> Image:
    """An Image message of a BGR frame in ``encoding`` (bgra8, rgba8 or YUV 4:2:2)."""
    if encoding in YUV_ORDER:
        data = _yuv422(bgr, YUV_ORDER[encoding])
    else:
        data = _with_alpha(bgr, encoding[:4])
    msg = Image(height=bgr.shape[0], width=bgr.shape[1], encoding=encoding)
    msg.step, msg.data = data.size // bgr.shape[0], data.tobytes()
    return msg


@pytest.mark.parametrize(
    "encoding",
    ["rgb8", "bgra8", "rgba8", "bayer_rggb8", "bayer_bggr8", "bayer_gbrg8", "bayer_grbg8"],
)
def test_encodings_decode_to_the_bgr_frame(frame, encoding):
    msg = Image(height=frame.shape[0], width=frame.shape[1], encoding=encoding)
    if encoding == "rgb8":
        msg.step, msg.data = frame.shape[1] * 3, frame[:, :, ::-1].tobytes()
    elif encoding in ("bgra8", "rgba8"):
        msg = _raw(frame, encoding)
    else:
        plane = _mosaic(frame, encoding[6:10])
        msg.step, msg.data = frame.shape[1], plane.tobytes()
    got = frame_from_message(msg)
    assert got.shape == frame.shape
    if encoding in ("rgb8", "bgra8", "rgba8"):
        assert np.array_equal(got, frame)
    else:  # demosaicing blurs edges; flat areas and the colour of big patches survive
        flat = np.full((8, 8, 3), (30, 90, 200), dtype=np.uint8)
        patch = Image(height=8, width=8, encoding=encoding, step=8)
        patch.data = _mosaic(flat, encoding[6:10]).tobytes()
        centre = frame_from_message(patch)[2:6, 2:6].reshape(-1, 3)
        assert np.abs(centre.astype(int) - (30, 90, 200)).max() <= 2


@pytest.mark.parametrize("encoding", list(YUV_ORDER))
def test_yuv422_decodes_in_its_byte_order_and_gives_the_poses(frame, encoding):
    """usb_cam's yuyv (yuv422_yuy2), and UYVY (yuv422, uyvy): colours survive the 4:2:2
    chroma, and the localizer places every robot where the bgr8 frame puts it."""
    from excavation_sim.camera import default_beacons
    from overhead_localizer.localize import Localizer

    flat = np.full((8, 8, 3), (30, 90, 200), dtype=np.uint8)
    assert np.abs(frame_from_message(_raw(flat, encoding)).astype(int) - flat).max() <= 2
    got = frame_from_message(_raw(frame, encoding))
    assert got.shape == frame.shape and got.dtype == np.uint8
    model = load_model(CALIBRATION)
    want = Localizer(model, default_beacons(), len(VIEWS)).update(frame)
    seen = Localizer(model, default_beacons(), len(VIEWS)).update(got)
    for a, b in zip(want, seen, strict=True):
        assert a.reportable and b.reportable
        assert np.hypot(a.x - b.x, a.y - b.y) < TOLERANCE_M
        assert abs((a.yaw - b.yaw + np.pi) % (2 * np.pi) - np.pi) < TOLERANCE_RAD
    odd = _raw(frame[:, :-2], encoding)
    odd.width, odd.step = odd.width - 1, odd.step - 2
    odd.data = np.frombuffer(bytes(odd.data), np.uint8).reshape(odd.height, -1)[:, :-2].tobytes()
    with pytest.raises(ImageError, match="needs an even width"):
        frame_from_message(odd)


def test_site_files_accept_every_encoding_the_localizer_decodes():
    from excavation_bringup.site import RAW_ENCODINGS

    assert sorted(RAW_ENCODINGS) == sorted(ENCODINGS)


def test_mono8_decodes_and_unknown_encodings_are_refused(frame):
    grey = frame[:, :, 1].copy()
    msg = Image(height=grey.shape[0], width=grey.shape[1], encoding="mono8", step=grey.shape[1])
    msg.data = grey.tobytes()
    assert np.array_equal(frame_from_message(msg)[:, :, 0], grey)
    msg.encoding = "16UC1"
    with pytest.raises(ImageError, match="encoding = '16UC1'"):
        frame_from_message(msg)


def test_compressed_round_trip_and_bad_data(frame):
    png = frame_to_compressed(frame, CompressedImage(), "png")
    assert png.format == "bgr8; png compressed bgr8"
    assert np.array_equal(frame_from_compressed(png), frame)
    jpeg = frame_to_compressed(frame, CompressedImage(), "jpeg")
    assert np.abs(frame_from_compressed(jpeg).astype(int) - frame).mean() < 3
    bad = CompressedImage(format="jpeg", data=b"not a jpeg")
    with pytest.raises(ImageError, match="do not decode as jpeg"):
        frame_from_compressed(bad)
    with pytest.raises(ImageError, match="expected jpeg or png"):
        frame_from_compressed(CompressedImage(format="theora", data=b"x"))


def test_camera_info_replaces_the_intrinsics_only():
    model = load_model(CALIBRATION)
    info = CameraInfo(**camera_info_fields(CameraParams_model()))
    got = with_camera_info(model, info)
    assert np.array_equal(got.rvec, model.rvec) and np.array_equal(got.tvec, model.tvec)
    assert np.allclose(got.camera_matrix, CameraParams().camera_matrix())
    info.distortion_model = "fisheye"
    with pytest.raises(ImageError, match="distortion_model = 'fisheye'"):
        with_camera_info(model, info)
    info.distortion_model, info.k = "plumb_bob", [0.0] * 9
    with pytest.raises(ImageError, match="expected a camera matrix"):
        with_camera_info(model, info)


def CameraParams_model() -> CameraModel:  # noqa: N802 - the true camera's intrinsics
    p = CameraParams()
    rvec, tvec = p.extrinsics()
    return CameraModel(p.width, p.height, p.camera_matrix(), p.dist_coeffs(), rvec, tvec)


class Probe:
    def __init__(self, ros, compressed: bool):
        from rclpy.node import Node

        self.node = ros.add(Node("probe", context=ros.context))
        qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)
        if compressed:
            self.pub = self.node.create_publisher(
                CompressedImage, "/overhead/image_raw/compressed", qos
            )
        else:
            self.pub = self.node.create_publisher(Image, "/overhead/image_raw", qos)
        self.info_pub = self.node.create_publisher(CameraInfo, "/overhead/camera_info", qos)
        self.poses = {k: [] for k in range(len(VIEWS))}
        for k in self.poses:
            self.node.create_subscription(
                PoseWithCovarianceStamped,
                f"/robot_{k}/pose",
                lambda m, k=k: self.poses[k].append(m),
                10,
            )
        self.annotated = []
        self.node.create_subscription(
            CompressedImage, "/overhead/image_annotated", self.annotated.append, 10
        )
        self.ros = ros


def run_localizer(ros, frame, compressed: str | None, camera_info: bool):
    params = [
        Parameter("calibration", value=str(CALIBRATION)),
        Parameter("robots", value=len(VIEWS)),
        Parameter("reliable", value=True),
        Parameter("use_height_map", value=False),
        Parameter("annotated_period", value=0.01),
    ]
    if compressed:
        params += [
            Parameter("compressed", value=True),
            Parameter("image_topic", value="/overhead/image_raw/compressed"),
        ]
    if camera_info:
        params.append(Parameter("camera_info_topic", value="/overhead/camera_info"))
    node = ros.add(LocalizerNode(context=ros.context, parameter_overrides=params))
    probe = Probe(ros, bool(compressed))
    ros.spin_until(lambda: probe.pub.get_subscription_count() > 0)
    if camera_info:
        msg = frame_to_message(frame, Image(), stamp=Time(sec=5))
        probe.pub.publish(
            msg if not compressed else frame_to_compressed(frame, CompressedImage(), compressed)
        )
        ros.spin_until(lambda: node.image_error is not None)
        assert "waiting for /overhead/camera_info" in node.image_error  # no model yet
        ros.spin_until(lambda: probe.info_pub.get_subscription_count() > 0)
        info = CameraInfo(**camera_info_fields(load_model(CALIBRATION)))
        probe.info_pub.publish(info)
        assert ros.spin_until(lambda: node.info_received)
    if compressed:
        out = frame_to_compressed(frame, CompressedImage(), compressed, stamp=Time(sec=6))
    else:
        out = frame_to_message(frame, Image(), stamp=Time(sec=6))
    probe.pub.publish(out)
    assert ros.spin_until(lambda: all(probe.poses.values()) and probe.annotated)
    return [p[0].pose.pose for _, p in sorted(probe.poses.items())]


def _xy_yaw(pose):
    yaw = 2 * np.arctan2(pose.orientation.z, pose.orientation.w)
    return np.array([pose.position.x, pose.position.y]), yaw


@pytest.mark.parametrize("compressed", ["png", "jpeg"])
def test_camera_info_and_compressed_frames_give_the_raw_poses(ros, frame, compressed):
    raw = run_localizer(ros, frame, None, camera_info=False)
    for node in list(ros.executor.get_nodes()):
        ros.executor.remove_node(node)
        node.destroy_node()
    got = run_localizer(ros, frame, compressed, camera_info=True)
    for a, b in zip(raw, got, strict=True):
        (pa, ya), (pb, yb) = _xy_yaw(a), _xy_yaw(b)
        if compressed == "png":  # lossless, and the same intrinsics: the same poses
            assert np.allclose(pa, pb, atol=1e-9) and abs(ya - yb) < 1e-9
        else:
            assert np.abs(pa - pb).max() < TOLERANCE_M
            assert abs((ya - yb + np.pi) % (2 * np.pi) - np.pi) < TOLERANCE_RAD
