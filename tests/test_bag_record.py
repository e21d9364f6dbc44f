"""Recording: ant-trial --record; a recorder killed (SIGKILL) or stopped (SIGINT, SIGTERM)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest
from ruamel.yaml import YAML

from excavation_bags.metadata import PRODUCER, latched
from excavation_bags.reader import open_bag
from excavation_bags.recover import recover_bag
from excavation_bringup.deployment import Deployment
from excavation_bringup.graph import build
from excavation_bringup.launch import ProcessLauncher
from excavation_bringup.trial import run_trial


def test_trial_records_every_tick(tmp_path, domain):
    steps, robots = 12, 2
    bag_dir = tmp_path / "trial"
    result = run_trial(
        "hand-coded",
        robots,
        steps,
        1,
        "default:1",
        domain=domain,
        command_timeout=30.0,
        record=str(bag_dir),
    )
    bag = open_bag(bag_dir)
    assert bag.truncated is None and bag.warnings == []
    assert bag.producer == PRODUCER and bag.custom_data["height_unit"] == "0.05"
    counts = {t.name: t.count for t in bag.topics.values()}
    for topic in ["/clock", "/worksite/height_map", "/worksite/fitness"] + [
        f"/robot_{k}/{kind}" for k in range(robots) for kind in ("pose", "behaviour", "stuck")
    ]:
        assert counts[topic] == steps + 1, topic
    for topic in ("/blueprint/goal", "/blueprint/zones", "/worksite/map_info"):
        assert counts[topic] == 1 and latched(bag.topics[topic].qos), topic
    assert latched(bag.topics["/worksite/height_map"].qos)
    assert not latched(bag.topics["/robot_0/pose"].qos)
    fitness = [bag.decode(t, raw).data for t, _, raw in bag.messages(["/worksite/fitness"])]
    assert fitness[-1] == pytest.approx(result.fitness, abs=1e-6)
    for k in range(robots):
        topic = f"/robot_{k}/behaviour"
        recorded = [bag.decode(topic, raw).data for _, _, raw in bag.messages([topic])]
        assert recorded[:steps] == [tick[k] for tick in result.commands]
    # /tf is recorded with its definition: a foreign reader (mcap_ros2, no package of
    # ours) finds each robot's base_link at its pose of the same stamp, and its blade
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    poses = {
        (m.header.stamp.sec, m.header.stamp.nanosec): m.pose.pose.position
        for m in (bag.decode("/robot_0/pose", raw) for _, _, raw in bag.messages(["/robot_0/pose"]))
    }
    (mcap_file,) = bag_dir.glob("*.mcap")
    frames: dict[str, int] = {}
    with open(mcap_file, "rb") as f:
        for _, _, _, m in make_reader(
            f, decoder_factories=[DecoderFactory()]
        ).iter_decoded_messages(topics=["/tf"]):
            for t in m.transforms:
                frames[t.child_frame_id] = frames.get(t.child_frame_id, 0) + 1
                if t.child_frame_id == "robot_0/base_link":
                    p = poses[(t.header.stamp.sec, t.header.stamp.nanosec)]
                    assert (t.transform.translation.x, t.transform.translation.y) == (p.x, p.y)
    for k in range(robots):  # tick 0's may precede the recorder's finding /tf (a 0.1 s look)
        assert frames[f"robot_{k}/base_link"] >= steps
        assert frames[f"robot_{k}/blade"] >= steps


def _recorder(out, domain, *extra):
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain))
    cmd = [sys.executable, "-m", "excavation_bags.cli", "record", "--out", str(out)]
    return subprocess.Popen(
        [*cmd, "--topics", "/count", "/latched", *extra],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )


def _metadata_count(bag_dir) -> int:
    try:
        info = YAML(typ="safe").load((bag_dir / "metadata.yaml").read_text())
        return int(info["rosbag2_bagfile_information"]["message_count"])
    except (OSError, TypeError, KeyError):
        return 0


def _run_with_a_late_recorder(trial: ProcessLauncher) -> dict:
    """Start every node but the recorder, the recorder 5 s later; the trial's result."""
    for name in trial.specs:
        if name != "recorder":
            trial.start(name)
    time.sleep(5.0)  # the team is up long before the recorder
    assert not trial.graph.files.result.exists()
    trial.start("recorder")
    return trial.wait(300.0)


@pytest.mark.system  # every node its own process
def test_process_trial_waits_for_a_late_recorder(tmp_path, domain):
    """Tick 0 waits for the recorder process, even one that starts after every other node."""
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    steps, bag_dir = 6, tmp_path / "bag"
    spec = Deployment(
        "hand-coded", 2, steps, 1, "default:1", 0, domain, 30.0, 300.0, False,
        str(bag_dir), "truth", processes=True,
    )  # fmt: skip
    with ProcessLauncher(build(spec, tmp_path / "nodes")) as trial:
        result = _run_with_a_late_recorder(trial)
    assert result["missed"] == {"0": 0, "1": 0}
    bag = open_bag(bag_dir)
    ticks = [bag.decode("/clock", raw).clock.sec for _, _, raw in bag.messages(["/clock"])]
    assert ticks == list(range(steps + 1))


@pytest.mark.system  # every node its own process
def test_continuous_process_trial_waits_for_a_late_recorder(tmp_path, domain):
    """The continuous trial's tick 0 waits for the recorder too (the team tick's
    ``wait_for_recorder``): the bag has every tick although the recorder starts last."""
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    steps, bag_dir = 4, tmp_path / "bag"
    spec = Deployment(
        "hand-coded", 2, steps, 1, "default:1", 0, domain, 30.0, 300.0, True,
        str(bag_dir), "truth", drive="continuous", exact=True, processes=True,
    )  # fmt: skip
    graph = build(spec, tmp_path / "nodes")
    assert graph.spec(graph.final).params["wait_for_recorder"] is True
    with ProcessLauncher(graph) as trial:
        result = _run_with_a_late_recorder(trial)
    assert len(result["tick_wall"]) == steps
    bag = open_bag(bag_dir)
    ticks = [int(bag.decode("/team/tick", raw).tick) for _, _, raw in bag.messages(["/team/tick"])]
    assert ticks == list(range(steps))


@pytest.mark.parametrize("stop", ["SIGKILL", "SIGINT", "SIGTERM"])
def test_recorder_stopped_mid_recording(ros, tmp_path, stop):
    from rosbags.rosbag2 import Reader
    from std_msgs.msg import UInt16

    from excavation_common.ros import LATCHED

    node = ros.add(__import__("rclpy").create_node("counter", context=ros.context))
    pub = node.create_publisher(UInt16, "/count", 100)
    node.create_publisher(UInt16, "/latched", LATCHED).publish(UInt16(data=7))
    sent = []
    node.create_timer(0.005, lambda: (pub.publish(UInt16(data=len(sent))), sent.append(0)))
    bag_dir = tmp_path / "rec"
    # a deep queue: a recorder slowed down by a loaded machine must not drop messages here
    proc = _recorder(
        bag_dir, ros.domain, "--flush-period", "0.2", "--ros-args", "-p", "depth:=2000"
    )
    try:
        assert ros.spin_until(lambda: _metadata_count(bag_dir) >= 60, timeout=60.0)
        flushed = _metadata_count(bag_dir)  # metadata is rewritten after each chunk is synced
        proc.send_signal(getattr(signal, stop))
        assert proc.wait(timeout=20) == (-signal.SIGKILL if stop == "SIGKILL" else 0)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    bag = open_bag(bag_dir)
    counts = [int(bag.decode(t, raw).data) for t, _, raw in bag.messages(["/count"])]
    latched_msgs = [bag.decode(t, raw).data for t, _, raw in bag.messages(["/latched"])]
    assert latched_msgs == [7]
    assert len(counts) + 1 >= flushed  # everything flushed before the stop reads back
    assert counts == list(range(counts[0], counts[0] + len(counts)))  # no gap, in order
    if stop != "SIGKILL":
        assert bag.truncated is None  # a clean stop finishes the file
        complete = bag_dir
    else:
        assert bag.truncated is not None and "footer" in bag.truncated
        complete = tmp_path / "recovered"
        recover_bag(bag_dir, complete)
    with Reader(complete) as reader:
        assert reader.message_count == len(counts) + 1
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    (mcap_file,) = complete.glob("*.mcap")
    with open(mcap_file, "rb") as f:
        got = [
            m.data
            for _, ch, _, m in make_reader(
                f, decoder_factories=[DecoderFactory()]
            ).iter_decoded_messages()
            if ch.topic == "/count"
        ]
    assert got == counts
    time.sleep(0)  # keep the node alive until here
