"""The emulated overhead camera: frames of the world's current truth on its own clock, its
camera_info (calibrated or not) and encodings the localizer reads, and the node."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from dome_emulator.camera import (
    YUV422,
    CameraCore,
    CameraEmulatorParams,
    Frame,
    Waiting,
    yuv422_message,
)
from dome_emulator.errors import TruthError
from helpers.diagnostics import DiagnosticsProbe

from excavation_common.params import ParameterError, validate

S = 1_000_000_000


def camera(**changes) -> CameraCore:
    return CameraCore(dataclasses.replace(CameraEmulatorParams(), robots=2, **changes))


def place(core: CameraCore, poses) -> None:
    for k, (x, y, yaw) in enumerate(poses):
        core.truth.set_pose(k, x, y, yaw)


def test_a_frame_waits_for_every_pose_and_carries_its_own_stamp():
    core = camera(stamp_offset=-0.25, latency=0.1)
    core.truth.set_pose(0, 1.0, 1.0, 0.0)
    assert core.capture(5 * S, 10.0) == Waiting("no pose yet of robot(s) 1")
    core.truth.set_pose(1, 3.0, 3.0, math.pi / 2)
    frame = core.capture(5 * S, 10.0)
    assert isinstance(frame, Frame)
    assert frame.stamp_ns == 5 * S - S // 4 and frame.due == pytest.approx(10.1)
    assert frame.image.shape == (720, 1280, 3) and frame.image.dtype == np.uint8
    assert (core.frames, core.waited) == (1, 1)


def test_frames_show_the_truth_of_the_moment_they_are_taken():
    core = camera(noise=0.0, glare=0.0)
    place(core, [(1.5, 2.0, 0.0), (2.5, 2.0, 0.0)])
    first = core.capture(S, 0.0)
    place(core, [(1.5, 2.5, 0.0), (2.5, 2.0, 0.0)])  # robot 0 drove half a metre north
    second = core.capture(2 * S, 0.1)
    moved = second.leds[0, :, :2] - first.leds[0, :, :2]
    assert np.all(np.abs(moved[:, 1]) > 50)  # its LEDs moved across the image
    assert np.all(np.abs(second.leds[1, :, :2] - first.leds[1, :, :2]) < 5)  # jitter only
    for frame in (first, second):  # each LED is drawn where the frame says it is
        for u, v, seen in frame.leds.reshape(-1, 3):
            assert seen == 1.0
            assert frame.image[int(round(v)), int(round(u))].max() > 150


def test_same_seed_same_frames_and_heights_shade_the_floor():
    a, b = camera(), camera()
    for core in (a, b):
        place(core, [(1.5, 2.0, 0.0), (2.5, 2.0, 0.0)])
    flat_a, flat_b = a.capture(S, 0.0), b.capture(S, 0.0)
    assert np.array_equal(flat_a.image, flat_b.image)
    heights = np.zeros((16, 16))
    heights[:8] = 0.3
    a.truth.set_heights(heights)
    b.capture(2 * S, 0.0)  # the two generators in step again
    raised = a.capture(2 * S, 0.0)
    assert np.abs(raised.image.astype(int) - flat_a.image.astype(int)).mean() > 1.0
    with pytest.raises(TruthError, match="16 x 16"):
        a.truth.set_heights(np.zeros((8, 8)))
    with pytest.raises(TruthError, match="finite"):
        a.truth.set_pose(0, math.nan, 0.0, 0.0)


def test_camera_info_calibrated_or_not_as_the_localizer_reads_it():
    from overhead_localizer.camera_info import ZERO_K, choose_model, intrinsics
    from overhead_localizer.camera_model import CameraModel

    core = camera()
    v = core.camera_info()
    msg = SimpleNamespace(**dataclasses.asdict(v))
    width, height, k, d = intrinsics(msg)
    assert (width, height) == (1280, 720) and v.distortion_model == "plumb_bob"
    np.testing.assert_allclose(k, core.model.camera_matrix())
    np.testing.assert_allclose(d, core.model.dist_coeffs())
    assert v.p[:3] == v.k[:3] and v.p[3] == 0.0
    rvec, tvec = core.model.extrinsics()
    truth = CameraModel(1280, 720, k, d, rvec, tvec)
    assert choose_model(truth, msg)[1] is None  # the driver's intrinsics are taken
    bare = SimpleNamespace(**dataclasses.asdict(camera(uncalibrated=True).camera_info()))
    assert choose_model(truth, bare) == (truth, ZERO_K)
    assert bare.width == 1280 and not any(bare.k) and not any(bare.p) and bare.d == ()


def test_yuv422_frames_decode_as_the_localizer_decodes_them():
    from overhead_localizer.images import frame_from_message

    core = camera(width=320, height=180, encoding=YUV422)
    place(core, [(1.8, 2.0, 0.0), (2.2, 2.0, 0.0)])
    frame = core.capture(S, 0.0)
    msg = SimpleNamespace(header=SimpleNamespace())
    yuv422_message(frame.image, msg, "overhead_camera", stamp="t")
    assert (msg.encoding, msg.step, len(msg.data)) == ("yuv422", 640, 640 * 180)
    assert msg.header.frame_id == "overhead_camera" and msg.header.stamp == "t"
    back = frame_from_message(msg)
    error = np.abs(back.astype(int) - frame.image.astype(int))
    assert np.median(error) <= 3 and error.mean() < 6


def test_parameters_are_checked():
    validate(CameraEmulatorParams, {})
    with pytest.raises(ParameterError, match="even width"):
        validate(CameraEmulatorParams, {"encoding": "yuv422", "width": 321})
    with pytest.raises(ParameterError, match="encoding"):
        validate(CameraEmulatorParams, {"encoding": "png"})
    with pytest.raises(dataclasses.FrozenInstanceError):
        Waiting("x").reason = "y"


@pytest.mark.parametrize("encoding", ["jpeg", "yuv422"])
def test_camera_node_publishes_late_stamped_frames_of_the_world(ros, encoding):
    from dome_emulator.camera_node import CameraNode
    from geometry_msgs.msg import PoseWithCovarianceStamped
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from rclpy.time import Time
    from sensor_msgs.msg import CameraInfo, CompressedImage, Image

    from excavation_common.messages import grid_to_image
    from excavation_common.ros import LATCHED, SENSOR_DATA
    from overhead_localizer.images import frame_from_compressed, frame_from_message

    overrides = {
        "robots": 2,
        "width": 320,
        "height": 180,
        "frame_rate": 20.0,
        "encoding": encoding,
        "latency": 0.2,
        "stamp_offset": -0.5,
        "diagnostics_period": 0.1,
    }
    ros.add(
        CameraNode(
            context=ros.context,
            namespace="/overhead",
            parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()],
        )
    )
    probe = ros.add(Node("probe", context=ros.context))
    images, infos = [], []
    kind, topic = (
        (CompressedImage, "/overhead/image_raw/compressed")
        if encoding == "jpeg"
        else (Image, "/overhead/image_raw")
    )

    def on_image(msg):
        images.append((msg, probe.get_clock().now().nanoseconds))

    probe.create_subscription(kind, topic, on_image, SENSOR_DATA)
    probe.create_subscription(CameraInfo, "/overhead/camera_info", infos.append, SENSOR_DATA)
    diags = DiagnosticsProbe(probe).named("/overhead/camera")
    assert ros.spin_until(lambda: any("no pose yet" in s.message for s in diags))
    assert not images
    poses = [
        probe.create_publisher(PoseWithCovarianceStamped, f"/truth/robot_{k}/pose", 10)
        for k in range(2)
    ]
    heights = probe.create_publisher(Image, "/truth/worksite/height_map", LATCHED)
    heights.publish(grid_to_image(np.zeros((16, 16), dtype=np.float32), "32FC1"))

    def world():
        for k, pub in enumerate(poses):
            msg = PoseWithCovarianceStamped()
            msg.pose.pose.position.x, msg.pose.pose.position.y = 1.8 + 0.4 * k, 2.0
            msg.pose.pose.orientation.w = 1.0
            pub.publish(msg)
        return len(images) >= 3

    assert ros.spin_until(world, 30.0)
    msg, received = images[-1]
    frame = frame_from_compressed(msg) if encoding == "jpeg" else frame_from_message(msg)
    assert frame.shape == (180, 320, 3) and msg.header.frame_id == "overhead_camera"
    # Stamped at capture minus 0.5 s, sent 0.2 s after the capture.
    stamp = Time.from_msg(msg.header.stamp).nanoseconds
    assert received - stamp >= int(0.7 * S)
    assert ros.spin_until(lambda: any(i.header.stamp == msg.header.stamp for i in infos))
    info = next(i for i in infos if i.header.stamp == msg.header.stamp)
    assert (info.width, info.height, info.distortion_model) == (320, 180, "plumb_bob")
    assert info.k[0] == pytest.approx(1050.0) and info.k[2] == pytest.approx(159.5)
    assert ros.spin_until(lambda: diags[-1].level == b"\x00")  # OK: frames go out


def test_the_emulated_sensors_take_the_newest_truth_not_a_queue(ros):
    """A sensor busy rendering for longer than the world's 20 Hz step must not fall behind.

    With a queue of 10 poses the first rehearsal's frames showed the world as it was 0.5 s
    before their stamps (the localiser's poses matched the truth best 0.5 s back), and the
    executors, trusting the stamps, overshot every cell by 5 to 8 cm.
    """
    from dome_emulator.camera_node import CameraNode
    from dome_emulator.laser_node import LaserNode
    from rclpy.qos import HistoryPolicy

    for kind in (CameraNode, LaserNode):
        node = ros.add(kind(context=ros.context))
        truth = [s for s in node.subscriptions if s.topic_name.startswith("/truth/robot_")]
        assert len(truth) == node.params.robots > 0
        for sub in truth:
            assert sub.qos_profile.history == HistoryPolicy.KEEP_LAST
            assert sub.qos_profile.depth == 1, sub.topic_name


def test_the_emulated_sensors_keep_their_truth_through_bad_messages(ros):
    """A non-finite pose or a height map of the wrong size or type changes nothing the
    sensors render; the feed keeps what was wrong (what the node's ``/diagnostics`` WARN
    says), and a good height map clears it. The camera and the laser share this feed
    (:class:`TruthFeed`)."""
    from dome_emulator.camera_node import CameraNode
    from dome_emulator.laser_node import LaserNode
    from geometry_msgs.msg import PoseWithCovarianceStamped

    from excavation_common.messages import grid_to_image

    for kind in (CameraNode, LaserNode):
        node = ros.add(kind(context=ros.context))
        feed, truth = node.feed, node.core.truth
        assert feed.truth is truth and feed.heights_topic == "/truth/worksite/height_map"
        good = PoseWithCovarianceStamped()
        good.pose.pose.position.x, good.pose.pose.position.y = 1.0, 2.0
        good.pose.pose.orientation.w = 1.0
        feed.on_pose(0, good)
        assert truth.poses[0] == (1.0, 2.0, 0.0) and feed.problem == ""
        bad = PoseWithCovarianceStamped()
        bad.pose.pose.position.x = math.nan
        feed.on_pose(0, bad)
        assert truth.poses[0] == (1.0, 2.0, 0.0)
        assert "robot_0" in feed.problem and "finite" in feed.problem
        rows, cols = truth.rows, truth.cols
        heights = np.full((rows, cols), 0.1, dtype=np.float32)
        feed.on_heights(grid_to_image(heights, "32FC1"))
        assert feed.problem == "" and truth.heights[0, 0] == pytest.approx(0.1)
        feed.on_heights(grid_to_image(np.zeros((rows + 1, cols), np.float32), "32FC1"))
        assert "/truth/worksite/height_map" in feed.problem and "shape" in feed.problem
        feed.on_heights(grid_to_image(np.zeros((rows, cols), np.uint8), "mono8"))
        assert "/truth/worksite/height_map" in feed.problem
        assert truth.heights.shape == (rows, cols) and truth.heights[0, 0] == pytest.approx(0.1)
        feed.on_heights(grid_to_image(heights * 2, "32FC1"))
        assert feed.problem == "" and truth.heights[0, 0] == pytest.approx(0.2)


CONFIG = Path(__file__).resolve().parents[1] / "ros2_ws/src/excavation_bringup/config"
SITE, SIM_SITE = CONFIG / "site_rehearsal.yaml", CONFIG / "site_sim.yaml"


def test_the_rehearsal_calibration_agrees_with_the_emulated_driver_camera_info(tmp_path):
    """The emulated camera publishes its intrinsics (as a dome camera driver does); the
    rehearsal's calibration is fitted under them (``calibrate --camera-info``), so the
    localiser takes the driver's CameraInfo at start without a warning. The ``--sim``
    calibration, whose intrinsics are fitted too, differs from them by more than the
    tolerance: that is the start-up WARN a rehearsal used to log."""
    from dome_emulator.camera import CameraCore, CameraEmulatorParams
    from sensor_msgs.msg import CameraInfo

    from blueprint_server.blueprint import resolve_blueprint
    from excavation_bringup.deployment import Deployment
    from excavation_bringup.graph import prepare
    from excavation_bringup.site import load_site
    from overhead_localizer.camera_info import choose_model
    from overhead_localizer.camera_model import FROM_CAMERA_INFO, load_model

    site = load_site(SITE, emulated=True)
    blueprint = resolve_blueprint(site.worksite.blueprint)
    dep = Deployment.from_site(site, "emulated")
    files = prepare(dep, tmp_path / "run")
    model = load_model(files.calibration)
    assert model.intrinsics == FROM_CAMERA_INFO
    rows, cols = blueprint.shape
    camera = CameraCore(
        CameraEmulatorParams(
            robots=site.n_robots, rows=rows, cols=cols, cell_size=blueprint.cell_size
        )
    )
    values = camera.camera_info()
    msg = CameraInfo(
        width=values.width, height=values.height, distortion_model=values.distortion_model,
        d=list(values.d), k=list(values.k), r=list(values.r), p=list(values.p),
    )  # fmt: skip
    _, warning = choose_model(model, msg)
    assert warning is None and model.rms_px < 1.0
    sim = Deployment.from_site(load_site(SIM_SITE, sim=True), "sim")
    fitted = load_model(prepare(sim, tmp_path / "sim").calibration)
    assert choose_model(fitted, msg)[1] is not None
