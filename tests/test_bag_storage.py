"""Bag files: rosbag2 v9 metadata, MCAP readable by rosbags and mcap, truncation, bad bags."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from rclpy.serialization import serialize_message
from ruamel.yaml import YAML
from std_msgs.msg import UInt16

from excavation_bags.cli import main as ant_bag
from excavation_bags.errors import BagExistsError, BagFormatError, BagNotFoundError
from excavation_bags.metadata import PRODUCER, latched, qos_from_profile
from excavation_bags.reader import open_bag
from excavation_bags.recover import recover_bag
from excavation_bags.writer import BagWriter
from excavation_common.messages import grid_to_image
from excavation_common.ros import LATCHED

SAMPLE = Path(__file__).resolve().parents[1] / "bags" / "sample"


def write_counter_bag(path: Path, n: int = 300, flush_every: int = 50) -> list[int]:
    """A bag with a latched image and ``n`` UInt16 counter messages; flushed every few."""
    from rclpy.qos import QoSProfile

    with BagWriter(path, {"height_unit": "0.05"}) as w:
        w.add_topic("/blueprint/zones", "sensor_msgs/msg/Image", [qos_from_profile(LATCHED)])
        w.add_topic("/count", "std_msgs/msg/UInt16", [qos_from_profile(QoSProfile(depth=10))])
        zones = np.arange(12, dtype=np.uint8).reshape(3, 4)
        w.write("/blueprint/zones", 1_000, serialize_message(grid_to_image(zones, "mono8")))
        for i in range(n):
            w.write("/count", 2_000 + i * 1_000_000, serialize_message(UInt16(data=i)))
            if i % flush_every == flush_every - 1:
                w.flush()
    return list(range(n))


def counts_in(bag) -> list[int]:
    return [int(bag.decode(t, raw).data) for t, _, raw in bag.messages(["/count"])]


def test_metadata_is_rosbag2_version_9(tmp_path):
    write_counter_bag(tmp_path / "b")
    info = YAML(typ="safe").load((tmp_path / "b" / "metadata.yaml").read_text())
    info = info["rosbag2_bagfile_information"]
    assert info["version"] == 9
    assert info["storage_identifier"] == "mcap"
    assert info["ros_distro"] == "jazzy"
    assert info["relative_file_paths"] == ["b.mcap"]
    assert info["message_count"] == 301
    assert info["custom_data"]["producer"] == PRODUCER
    topics = {t["topic_metadata"]["name"]: t for t in info["topics_with_message_count"]}
    zones = topics["/blueprint/zones"]["topic_metadata"]
    assert zones["type"] == "sensor_msgs/msg/Image"
    assert zones["serialization_format"] == "cdr"
    assert zones["type_description_hash"].startswith("RIHS01_")
    (qos,) = zones["offered_qos_profiles"]  # v9: a list, not a YAML string
    assert (qos["durability"], qos["reliability"], qos["depth"]) == (
        "transient_local",
        "reliable",
        1,
    )
    assert topics["/count"]["topic_metadata"]["offered_qos_profiles"][0]["durability"] == "volatile"
    assert topics["/count"]["message_count"] == 300


def test_rosbags_and_mcap_read_what_was_written(tmp_path):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    expected = write_counter_bag(tmp_path / "b")
    store = get_typestore(Stores.ROS2_JAZZY)
    with Reader(tmp_path / "b") as reader:
        conns = {c.topic: c for c in reader.connections}
        assert latched(conns["/blueprint/zones"].ext.offered_qos_profiles)
        got = [
            store.deserialize_cdr(raw, c.msgtype).data
            for c, _, raw in reader.messages(connections=[conns["/count"]])
        ]
    assert got == expected
    with open(tmp_path / "b" / "b.mcap", "rb") as f:
        mcap = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = mcap.get_summary()
        channels = {c.topic: c for c in summary.channels.values()}
        assert "transient_local" in channels["/blueprint/zones"].metadata["offered_qos_profiles"]
        decoded = {}
        for _, channel, _, msg in mcap.iter_decoded_messages():
            decoded.setdefault(channel.topic, []).append(msg)
    assert [m.data for m in decoded["/count"]] == expected
    (img,) = decoded["/blueprint/zones"]
    assert (img.height, img.width, img.encoding) == (3, 4, "mono8")
    assert bytes(img.data) == bytes(range(12))


@pytest.mark.parametrize("cut", [1, 700, 5_000])
def test_truncated_bag_reads_back_complete_chunks_and_recovers(tmp_path, cut):
    expected = write_counter_bag(tmp_path / "b")
    bad = tmp_path / "bad"
    bad.mkdir()
    shutil.copy(tmp_path / "b" / "metadata.yaml", bad / "metadata.yaml")
    data = (tmp_path / "b" / "b.mcap").read_bytes()
    (bad / "bad.mcap").write_bytes(data[: len(data) - cut])
    bag = open_bag(bad)
    assert bag.truncated and "footer" in bag.truncated
    assert any("truncated" in w and "ant-bag recover" in w for w in bag.warnings)
    got = counts_in(bag)
    assert got == expected[: len(got)]  # a prefix, nothing invented or reordered
    assert len(got) >= 250  # only the last chunk (50 messages) may be lost
    fixed = recover_bag(bad, tmp_path / "fixed")
    assert fixed.truncated is None and not fixed.warnings
    assert counts_in(fixed) == got
    assert "recovered_from" in fixed.custom_data

    from rosbags.rosbag2 import Reader

    with Reader(tmp_path / "fixed") as reader:
        assert sum(1 for _ in reader.messages()) == len(got) + 1


def test_missing_metadata_is_read_from_the_mcap(tmp_path):
    expected = write_counter_bag(tmp_path / "b")
    (tmp_path / "b" / "metadata.yaml").unlink()
    bag = open_bag(tmp_path / "b")
    assert any("no metadata.yaml" in w for w in bag.warnings)
    assert counts_in(bag) == expected


def test_unknown_producer_and_unknown_type(tmp_path):
    from rosbags.rosbag2 import StoragePlugin, Writer

    path = tmp_path / "foreign"
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conn = w.add_connection(
            "/custom", "my_pkg/msg/Thing", msgdef="int32 x\n", rihs01="RIHS01_" + "0" * 64
        )
        w.write(conn, 5, b"\x00\x01\x00\x00\x07\x00\x00\x00")
    bag = open_bag(path)
    assert any("producer" in w and "not recorded by ant-bag" in w for w in bag.warnings)
    # the type is not a common_interfaces type, but the bag carries its definition
    assert bag.decode("/custom", next(iter(bag.messages()))[2]).x == 7


def test_bad_paths(tmp_path):
    with pytest.raises(BagNotFoundError, match="no such bag directory"):
        open_bag(tmp_path / "nothing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(BagNotFoundError, match="no .mcap file"):
        open_bag(tmp_path / "empty")
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "junk.mcap").write_bytes(b"not an mcap file at all")
    with pytest.raises(BagFormatError, match="not an MCAP file"):
        open_bag(tmp_path / "junk")
    (tmp_path / "yaml").mkdir()
    (tmp_path / "yaml" / "metadata.yaml").write_text("rosbag2_bagfile_information: [1, 2\n")
    shutil.copy(SAMPLE / "sample.mcap", tmp_path / "yaml" / "yaml.mcap")
    with pytest.raises(BagFormatError, match="metadata.yaml"):
        open_bag(tmp_path / "yaml")
    write_counter_bag(tmp_path / "b", n=3)
    with pytest.raises(BagExistsError, match="not overwritten"):
        BagWriter(tmp_path / "b")


def test_cli_errors_are_messages_not_tracebacks(tmp_path, capsys):
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "junk.mcap").write_bytes(b"\x00" * 100)
    assert ant_bag(["info", str(tmp_path / "junk")]) == 2
    err = capsys.readouterr().err
    assert "ant-bag: error:" in err and "junk.mcap" in err and "Traceback" not in err
    assert ant_bag(["report", str(tmp_path / "none"), "--out", str(tmp_path / "r")]) == 2
    assert "no such bag directory" in capsys.readouterr().err


def test_info_of_the_sample(capsys):
    assert ant_bag(["info", str(SAMPLE)]) == 0
    out = capsys.readouterr().out
    assert "producer:  ant-bag" in out
    assert "/worksite/height_map" in out and "latched" in out
