"""The localizer on what real camera drivers send: encodings, CompressedImage, CameraInfo.

Day-one drivers (usb_cam, v4l2_camera, camera_ros): an uncalibrated one sends K = 0, a
calibrated one intrinsics other than those the calibration file's pose was fitted with,
and frames in bgra8, rgba8 or packed YUV 4:2:2.
"""

from __future__ import annotations

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseWithCovarianceStamped
from helpers.diagnostics import DiagnosticsProbe
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CameraInfo, CompressedImage, Image

from excavation_sim.camera import CameraParams, RobotView
from overhead_localizer.beacons import CONFIG_DIR
from overhead_localizer.camera_info import (
    ZERO_K,
    camera_info_fields,
    choose_model,
    with_camera_info,
)
from overhead_localizer.camera_model import (
    FROM_CAMERA_INFO,
    CameraModel,
    fit_pose,
    load_model,
    save_model,
)
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
        self.status = DiagnosticsProbe(self.node).latest
        self.ros = ros

    def camera(self, level) -> DiagnosticStatus | None:
        """The localizer's camera status once it is at ``level``."""
        s = self.status.get("/localizer")
        return s if s is not None and s.level == level else None


def run_localizer(ros, frame, compressed: str | None, info: CameraInfo | None, calibration=None):
    """Start a localizer; with ``info``, show that frames wait for it, then send it; then
    one frame. Returns the first pose of each robot, the node and the probe."""
    params = [
        Parameter("calibration", value=str(calibration or CALIBRATION)),
        Parameter("robots", value=len(VIEWS)),
        Parameter("reliable", value=True),
        Parameter("use_height_map", value=False),
        Parameter("annotated_period", value=0.01),
        Parameter("diagnostics_period", value=0.1),
    ]
    if compressed:
        params += [
            Parameter("compressed", value=True),
            Parameter("image_topic", value="/overhead/image_raw/compressed"),
        ]
    if info is not None:
        params.append(Parameter("camera_info_topic", value="/overhead/camera_info"))
    node = ros.add(LocalizerNode(context=ros.context, parameter_overrides=params))
    probe = Probe(ros, bool(compressed))
    ros.spin_until(lambda: probe.pub.get_subscription_count() > 0)
    if info is not None:
        msg = frame_to_message(frame, Image(), stamp=Time(sec=5))
        probe.pub.publish(
            msg if not compressed else frame_to_compressed(frame, CompressedImage(), compressed)
        )
        ros.spin_until(lambda: node.image_error is not None)
        assert "waiting for /overhead/camera_info" in node.image_error  # no model yet
        ros.spin_until(lambda: probe.info_pub.get_subscription_count() > 0)
        probe.info_pub.publish(info)
        assert ros.spin_until(lambda: node.info_received)
    if compressed:
        out = frame_to_compressed(frame, CompressedImage(), compressed, stamp=Time(sec=6))
    else:
        out = frame_to_message(frame, Image(), stamp=Time(sec=6))
    probe.pub.publish(out)
    assert ros.spin_until(lambda: all(probe.poses.values()) and probe.annotated)
    return [p[0].pose.pose for _, p in sorted(probe.poses.items())], node, probe


def restart(ros) -> None:
    """Take every node of the context down (the next run starts fresh)."""
    for node in list(ros.executor.get_nodes()):
        ros.executor.remove_node(node)
        node.destroy_node()


def _xy_yaw(pose):
    yaw = 2 * np.arctan2(pose.orientation.z, pose.orientation.w)
    return np.array([pose.position.x, pose.position.y]), yaw


@pytest.mark.parametrize("compressed", ["png", "jpeg"])
def test_camera_info_and_compressed_frames_give_the_raw_poses(ros, frame, compressed):
    raw, _, _ = run_localizer(ros, frame, None, None)
    restart(ros)
    info = CameraInfo(**camera_info_fields(load_model(CALIBRATION)))
    got, _, probe = run_localizer(ros, frame, compressed, info)
    assert ros.spin_until(lambda: probe.camera(DiagnosticStatus.OK))  # the same intrinsics
    for a, b in zip(raw, got, strict=True):
        (pa, ya), (pb, yb) = _xy_yaw(a), _xy_yaw(b)
        if compressed == "png":  # lossless, and the same intrinsics: the same poses
            assert np.allclose(pa, pb, atol=1e-9) and abs(ya - yb) < 1e-9
        else:
            assert np.abs(pa - pb).max() < TOLERANCE_M
            assert abs((ya - yb + np.pi) % (2 * np.pi) - np.pi) < TOLERANCE_RAD


def _same_poses(a, b) -> None:
    for pa, pb in zip(a, b, strict=True):
        (xa, ya), (xb, yb) = _xy_yaw(pa), _xy_yaw(pb)
        assert np.array_equal(xa, xb) and ya == yb


def test_uncalibrated_driver_k_zero_uses_the_file_and_warns(ros, frame):
    """usb_cam, v4l2_camera and camera_ros without a calibration send K = 0: the file's
    intrinsics are used (WARN, named once), and every frame gives poses."""
    raw, _, _ = run_localizer(ros, frame, None, None)
    restart(ros)
    zero = CameraInfo(width=1280, height=720, distortion_model="plumb_bob", d=[0.0] * 5)
    got, node, probe = run_localizer(ros, frame, None, zero)
    _same_poses(raw, got)
    assert ros.spin_until(lambda: probe.camera(DiagnosticStatus.WARN))
    assert probe.camera(DiagnosticStatus.WARN).message == ZERO_K
    assert ZERO_K == (
        "camera_info K is zero (uncalibrated driver): using the calibration file's intrinsics"
    )
    # the driver sends it again with the next frame: still poses, still the one warning
    probe.info_pub.publish(zero)
    probe.pub.publish(frame_to_message(frame, Image(), stamp=Time(sec=7)))
    assert ros.spin_until(lambda: all(len(p) == 2 for p in probe.poses.values()))
    assert node.image_error is None and node.camera_warning == ZERO_K


def test_calibrated_driver_with_other_intrinsics_warns_and_keeps_the_file(ros, frame):
    """A pose fitted under the file's intrinsics (from marks) with a driver's other K and
    D would be biased (up to 9 mm here): the file's are kept, and the WARN says so."""
    raw, _, _ = run_localizer(ros, frame, None, None)
    restart(ros)
    driver = CameraInfo(**camera_info_fields(CameraParams_model()))  # the lens's true K, D
    got, node, probe = run_localizer(ros, frame, None, driver)
    _same_poses(raw, got)
    assert ros.spin_until(lambda: probe.camera(DiagnosticStatus.WARN))
    message = probe.camera(DiagnosticStatus.WARN).message
    assert "camera_info K/D differ from the calibration file's by up to" in message
    assert "using the calibration file's intrinsics" in message
    assert "calibrate --camera-info" in message
    assert node.localizer.model is node.file_model


def test_calibration_fitted_with_the_driver_intrinsics_uses_them(ros, frame, camera, tmp_path):
    """``calibrate --camera-info``: the pose is fitted under the driver's K and D, so its
    CameraInfo agrees with the file: no warning, the driver's intrinsics, accurate poses."""
    from excavation_sim.camera import calibration_marks

    truth = CameraParams_model()
    pixels, points = calibration_marks(camera, np.random.default_rng(1))
    size = (truth.width, truth.height)
    fitted = fit_pose(pixels, points, size, truth.camera_matrix, truth.dist_coeffs, "ost.yaml")
    path = tmp_path / "camera.yaml"
    save_model(fitted, path)
    driver = CameraInfo(**camera_info_fields(truth))
    got, node, probe = run_localizer(ros, frame, None, driver, calibration=path)
    assert ros.spin_until(lambda: probe.camera(DiagnosticStatus.OK))
    assert node.camera_warning is None and node.file_model.intrinsics == FROM_CAMERA_INFO
    assert np.array_equal(node.localizer.model.camera_matrix, truth.camera_matrix)
    for pose, view in zip(got, VIEWS, strict=True):
        xy, _ = _xy_yaw(pose)
        assert np.hypot(xy[0] - view.x, xy[1] - view.y) < 0.04


def test_choose_model_takes_the_driver_intrinsics_only_when_they_agree(camera):
    from excavation_sim.camera import calibration_marks

    marks_file = load_model(CALIBRATION)  # intrinsics fitted to the marks
    truth = CameraParams_model()
    model, warning = choose_model(marks_file, CameraInfo(width=1280, height=720))
    assert model is marks_file and warning == ZERO_K
    fisheye = CameraInfo(**camera_info_fields(truth))
    fisheye.distortion_model = "fisheye"
    model, warning = choose_model(marks_file, fisheye)
    assert model is marks_file and "distortion_model = 'fisheye'" in warning
    assert warning.endswith("using the calibration file's intrinsics")
    small = CameraInfo(**camera_info_fields(truth))
    small.width, small.height = 640, 360
    model, warning = choose_model(marks_file, small)
    assert model is marks_file and "640 x 360 images" in warning
    model, warning = choose_model(marks_file, CameraInfo(**camera_info_fields(truth)))
    assert model is marks_file and "differ from the calibration file's" in warning
    same = CameraInfo(**camera_info_fields(marks_file))
    model, warning = choose_model(marks_file, same)
    assert warning is None and np.array_equal(model.camera_matrix, marks_file.camera_matrix)
    # fitted with the driver's K, D: they agree; a driver calibrated again afterwards does not
    pixels, points = calibration_marks(camera, np.random.default_rng(1))
    fitted = fit_pose(pixels, points, (1280, 720), truth.camera_matrix, truth.dist_coeffs)
    model, warning = choose_model(fitted, CameraInfo(**camera_info_fields(truth)))
    assert warning is None and model.intrinsics == FROM_CAMERA_INFO
    model, warning = choose_model(fitted, same)
    assert model is fitted and "changed since `calibrate --camera-info`" in warning
