"""Camera frames in bags: recorded as CompressedImage, decoded by player, report and readers."""

from __future__ import annotations

import numpy as np
import pytest
from helpers.figures import assert_figure
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile
from rclpy.serialization import serialize_message
from sensor_msgs.msg import CompressedImage, Image

from excavation_bags.errors import BagError
from excavation_bags.images import (
    ImageDataError,
    compress,
    compressed_array,
    compressed_topic,
    fill_raw,
    raw_array,
    raw_topic,
)
from excavation_bags.metadata import qos_from_profile
from excavation_bags.reader import open_bag
from excavation_bags.writer import BagWriter

CAMERA = "/overhead/image_raw"


def frame(seed: int, height: int = 48, width: int = 64) -> np.ndarray:
    """A BGR test frame: smooth gradients with a few sharp squares (JPEG-friendly, not flat)."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:height, 0:width]
    img = np.stack([x * 255 // width, y * 255 // height, (x + y) * 127 // (width + height)], -1)
    for _ in range(3):
        r, c = rng.integers(0, height - 8), rng.integers(0, width - 8)
        img[r : r + 8, c : c + 8] = rng.integers(0, 256, 3)
    return img.astype(np.uint8)


def raw_message(image: np.ndarray, encoding: str = "bgr8", sec: int = 0) -> Image:
    msg = fill_raw(image, Image(), Image().header)
    msg.header.stamp.sec = sec
    msg.header.frame_id = "overhead_camera"
    if encoding == "rgb8":
        msg.encoding, msg.data = "rgb8", np.ascontiguousarray(image[..., ::-1]).tobytes()
    return msg


@pytest.mark.parametrize("encoding", ["bgr8", "rgb8", "mono8"])
def test_png_is_lossless_and_jpeg_is_close(encoding):
    image = frame(1)
    if encoding == "mono8":
        image = image[..., 1].copy()
    msg = raw_message(image, "rgb8" if encoding == "rgb8" else "bgr8")
    assert np.array_equal(raw_array(msg), image)
    png = compress(msg, CompressedImage(), "png")
    target = "mono8" if encoding == "mono8" else "bgr8"
    assert png.format == f"{msg.encoding}; png compressed {target}"
    assert png.header.frame_id == "overhead_camera"
    assert np.array_equal(compressed_array(png), image)
    jpeg = compress(msg, CompressedImage(), "jpeg", jpeg_quality=95)
    back = compressed_array(jpeg).astype(int)
    assert back.shape == image.shape
    assert np.abs(back - image).mean() < 4.0
    assert len(jpeg.data) < len(msg.data)


def test_bad_frames_name_the_field():
    msg = raw_message(frame(2))
    msg.step = 10
    with pytest.raises(ImageDataError, match="step = 10"):
        raw_array(msg, CAMERA)
    msg = raw_message(frame(2))
    msg.encoding = "16UC1"
    with pytest.raises(ImageDataError, match="encoding = '16UC1'"):
        raw_array(msg, CAMERA)
    bad = CompressedImage(format="jpeg", data=b"\xff\xd8 not a jpeg")
    with pytest.raises(ImageDataError, match="does not decode"):
        compressed_array(bad, CAMERA)
    assert compressed_topic(CAMERA) == CAMERA + "/compressed"
    assert raw_topic(CAMERA + "/compressed") == CAMERA and raw_topic(CAMERA) is None


def compressed_bag(path, frames: int = 6, period_ns: int = 12 * 10**9, codec: str = "png"):
    """A bag of ``frames`` compressed frames, ``period_ns`` apart; returns the images."""
    images = [frame(i) for i in range(frames)]
    with BagWriter(path) as w:
        w.add_topic(
            CAMERA + "/compressed",
            "sensor_msgs/msg/CompressedImage",
            [qos_from_profile(QoSProfile(depth=10))],  # reliable: no frame lost in the tests
        )
        for i, image in enumerate(images):
            msg = compress(raw_message(image, sec=i), CompressedImage(), codec)
            w.write(CAMERA + "/compressed", 10**9 + i * period_ns, serialize_message(msg))
    return images


def test_compressed_bag_reads_everywhere_and_reports_size_per_minute(tmp_path, capsys):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    from excavation_bags.cli import main as ant_bag

    images = compressed_bag(tmp_path / "cam")  # 6 frames over exactly 60 s
    bag = open_bag(tmp_path / "cam")
    assert bag.duration_s == pytest.approx(60.0)
    assert bag.bytes_per_minute == pytest.approx(bag.size_bytes)
    store = get_typestore(Stores.ROS2_JAZZY)
    with Reader(tmp_path / "cam") as reader:
        got = [store.deserialize_cdr(raw, c.msgtype) for c, _, raw in reader.messages()]
    assert [compressed_array(m).tolist() for m in got] == [i.tolist() for i in images]
    with open(tmp_path / "cam" / "cam.mcap", "rb") as f:
        decoded = [
            m
            for *_, m in make_reader(
                f, decoder_factories=[DecoderFactory()]
            ).iter_decoded_messages()
        ]
    assert [m.format for m in decoded] == ["bgr8; png compressed bgr8"] * 6
    assert ant_bag(["info", str(tmp_path / "cam"), "--sizes"]) == 0
    out = capsys.readouterr().out
    assert f"{bag.size_bytes / 1e6:.2f} MB/min" in out
    assert "duration:  60.000 s" in out


def test_report_and_trial_data_decode_compressed_frames(tmp_path):
    from excavation_bags.report import make_report
    from excavation_bags.trial_data import read_trial

    images = compressed_bag(tmp_path / "cam", frames=9, period_ns=10**9)
    data = read_trial(open_bag(tmp_path / "cam"))
    assert data.camera_topic == CAMERA + "/compressed"
    assert len(data.camera_times) == 9
    assert [i for i, _, _ in data.camera_frames] == [0, 2, 4, 6, 8]
    for i, _, image in data.camera_frames:
        assert np.array_equal(image, images[i])
    report = make_report(open_bag(tmp_path / "cam"), tmp_path / "r", gif=False)
    assert "camera.png" in report.files
    assert_figure(tmp_path / "r" / "camera.png", min_width=100, min_height=100)
    assert report.numbers["camera"]["frames"] == 9
    assert report.numbers["camera"]["frames_per_s"] == pytest.approx(1.0)
    summary = (tmp_path / "r" / "summary.md").read_text()
    assert "MB per minute" in summary and "9 frames on" in summary


def test_recorder_stores_raw_frames_compressed(ros, tmp_path):
    from excavation_bags.recorder_node import RecorderNode

    sent = [frame(i) for i in range(4)]
    node = ros.add(__import__("rclpy").create_node("camera", context=ros.context))
    pub = node.create_publisher(Image, CAMERA, 10)
    recorder = ros.add(
        RecorderNode(
            context=ros.context,
            parameter_overrides=[
                Parameter("out", value=str(tmp_path / "rec")),
                Parameter("topics", value=[CAMERA]),
                Parameter("image_codec", value="png"),
            ],
        )
    )
    assert ros.spin_until(lambda: CAMERA in recorder._subs, timeout=10.0)
    assert ros.spin_until(lambda: pub.get_subscription_count() > 0, timeout=10.0)
    for i, image in enumerate(sent):
        pub.publish(raw_message(image, sec=i))
        ros.spin_until(lambda i=i: recorder.frames["compressed"] > i, timeout=5.0)
    recorder.close()
    bag = open_bag(tmp_path / "rec")
    assert CAMERA not in bag.topics
    info = bag.topics[CAMERA + "/compressed"]
    assert info.msgtype == "sensor_msgs/msg/CompressedImage" and info.count == len(sent)
    got = [bag.decode(t, raw) for t, _, raw in bag.messages()]
    assert [m.header.stamp.sec for m in got] == [0, 1, 2, 3]
    assert all(np.array_equal(compressed_array(m), s) for m, s in zip(got, sent, strict=True))
    assert "png" in bag.custom_data[f"compressed:{CAMERA}"]


def test_camera_compressed_topic_is_recorded_instead_of_compressing(ros, tmp_path):
    from excavation_bags.recorder_node import RecorderNode

    node = ros.add(__import__("rclpy").create_node("camera", context=ros.context))
    raw_pub = node.create_publisher(Image, CAMERA, 10)
    jpeg_pub = node.create_publisher(CompressedImage, CAMERA + "/compressed", 10)
    recorder = ros.add(
        RecorderNode(
            context=ros.context,
            parameter_overrides=[Parameter("out", value=str(tmp_path / "rec"))],
        )
    )
    assert ros.spin_until(lambda: CAMERA + "/compressed" in recorder._subs, timeout=10.0)
    assert ros.spin_until(lambda: CAMERA in recorder.skipped, timeout=10.0)
    assert "the camera publishes" in recorder.skipped[CAMERA]
    assert ros.spin_until(lambda: jpeg_pub.get_subscription_count() > 0, timeout=10.0)
    camera_msg = compress(raw_message(frame(5)), CompressedImage(), "jpeg")
    jpeg_pub.publish(camera_msg)
    raw_pub.publish(raw_message(frame(6)))
    assert ros.spin_until(lambda: recorder.received >= 1, timeout=10.0)
    recorder.close()
    bag = open_bag(tmp_path / "rec")
    ((topic, _, raw),) = list(bag.messages())
    assert topic == CAMERA + "/compressed"
    assert bytes(bag.decode(topic, raw).data) == bytes(camera_msg.data)  # stored as it came


def test_player_publishes_decoded_frames_beside_the_compressed_ones(ros, tmp_path):
    from excavation_bags.player_node import PlayerNode

    images = compressed_bag(tmp_path / "cam", frames=4, period_ns=20_000_000)
    probe = ros.add(__import__("rclpy").create_node("probe", context=ros.context))
    raw, packed = [], []
    probe.create_subscription(Image, CAMERA, raw.append, 10)
    probe.create_subscription(CompressedImage, CAMERA + "/compressed", packed.append, 10)
    player = ros.add(PlayerNode(open_bag(tmp_path / "cam"), context=ros.context))
    assert ros.spin_until(lambda: player.finished and len(raw) == 4 and len(packed) == 4)
    assert [m.encoding for m in raw] == ["bgr8"] * 4
    for msg, image in zip(raw, images, strict=True):
        assert np.array_equal(raw_array(msg), image)
    assert [m.header.stamp.sec for m in raw] == [0, 1, 2, 3]
    # asking for the raw name alone plays only the decoded frames
    only_raw = ros.add(
        PlayerNode(
            open_bag(tmp_path / "cam"),
            context=ros.context,
            node_name="player2",
            parameter_overrides=[Parameter("topics", value=[CAMERA])],
        )
    )
    assert set(only_raw.publishers_) == set() and set(only_raw.decoded) == {CAMERA + "/compressed"}
    with pytest.raises(BagError, match="no playable topic"):
        PlayerNode(
            open_bag(tmp_path / "cam"),
            context=ros.context,
            node_name="player3",
            parameter_overrides=[
                Parameter("topics", value=[CAMERA]),
                Parameter("decode_images", value=False),
            ],
        )
