"""Playback: lockstep replay into fresh controllers, recorded timing, latching, loop."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from helpers.rigs import controller_node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile
from rclpy.serialization import serialize_message
from std_msgs.msg import UInt16

from ant_controller.controller import Controller
from excavation_bags.cli import main as ant_bag
from excavation_bags.errors import MissingTopicError
from excavation_bags.metadata import qos_from_profile
from excavation_bags.player_node import PlayerNode
from excavation_bags.reader import open_bag
from excavation_bags.writer import BagWriter
from excavation_common.params import ParameterError
from excavation_common.ros import LATCHED

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "bags" / "sample"
INPUTS = [
    "/blueprint/*",
    "/worksite/map_info",
    "/worksite/height_map",
    "/robot_*/pose",
    "/robot_*/blade/joint_states",
    "/robot_*/stuck",
]


def test_lockstep_replay_into_fresh_controllers_reproduces_behaviours(ros):
    bag = open_bag(SAMPLE)
    recorded = {
        t: [bag.decode(t, raw).data for _, _, raw in bag.messages([t])]
        for t in bag.topics
        if t.endswith("/behaviour")
    }
    robots = len(recorded)
    assert robots == 4
    ctl = Controller.from_file(ROOT / "genomes" / "best.json")
    for k in range(robots):
        controller_node(ros, k, robots, ctl, height_unit=0.05)
    replayed = {t: [] for t in recorded}
    probe = ros.add(__import__("rclpy").create_node("probe", context=ros.context))
    for t in recorded:
        probe.create_subscription(UInt16, t, lambda m, t=t: replayed[t].append(m.data), 200)
    player = ros.add(
        PlayerNode(
            bag,
            context=ros.context,
            parameter_overrides=[
                Parameter("lockstep", value=True),
                Parameter("topics", value=INPUTS),
                Parameter("lockstep_timeout", value=30.0),
            ],
        )
    )
    assert sorted(player.wait_for) == sorted(recorded)
    assert "/robot_0/behaviour" not in player.publishers_
    assert ros.spin_until(lambda: player.finished, timeout=300.0)
    assert ros.spin_until(lambda: all(len(replayed[t]) >= len(recorded[t]) for t in recorded))
    for t in recorded:
        assert replayed[t] == recorded[t], t
    assert len(player.ticks) == len(recorded["/robot_0/behaviour"]) + 1


def small_bag(path):
    with BagWriter(path) as w:
        w.add_topic("/latched", "std_msgs/msg/UInt16", [qos_from_profile(LATCHED)])
        w.add_topic("/count", "std_msgs/msg/UInt16", [qos_from_profile(QoSProfile(depth=10))])
        w.write("/latched", 0, serialize_message(UInt16(data=42)))
        for i in range(20):
            w.write("/count", (i + 1) * 10_000_000, serialize_message(UInt16(data=i)))
    return open_bag(path)


@pytest.mark.parametrize("rate", [1.0, 4.0])
def test_recorded_timing_order_and_latching(ros, tmp_path, rate):
    bag = small_bag(tmp_path / "b")
    probe = ros.add(__import__("rclpy").create_node("probe", context=ros.context))
    got = []
    probe.create_subscription(
        UInt16, "/count", lambda m: got.append((time.monotonic(), m.data)), 100
    )
    player = ros.add(
        PlayerNode(bag, context=ros.context, parameter_overrides=[Parameter("rate", value=rate)])
    )
    assert ros.spin_until(lambda: player.finished and len(got) == 20, timeout=20.0)
    assert [d for _, d in got] == list(range(20))
    span = got[-1][0] - got[0][0]
    # recorded timing, not a flood (which takes about a millisecond); lower bound only
    assert span >= 0.19 / rate * 0.5
    late = []  # a subscriber that joins after the player published: latched replay
    probe.create_subscription(UInt16, "/latched", lambda m: late.append(m.data), LATCHED)
    assert ros.spin_until(lambda: late == [42], timeout=10.0)


def test_loop_and_topic_selection(ros, tmp_path):
    bag = small_bag(tmp_path / "b")
    probe = ros.add(__import__("rclpy").create_node("probe", context=ros.context))
    got = []
    probe.create_subscription(UInt16, "/count", lambda m: got.append(m.data), 100)
    player = ros.add(
        PlayerNode(
            bag,
            context=ros.context,
            parameter_overrides=[
                Parameter("rate", value=10.0),
                Parameter("loop", value=True),
                Parameter("topics", value=["/count"]),
            ],
        )
    )
    assert set(player.publishers_) == {"/count"}
    assert ros.spin_until(lambda: len(got) >= 45, timeout=20.0)
    assert got[:45] == (list(range(20)) * 3)[:45]
    with pytest.raises(MissingTopicError, match="no playable topic"):
        PlayerNode(
            bag, context=ros.context, parameter_overrides=[Parameter("topics", value=["/nope"])]
        )
    from rosbags.rosbag2 import StoragePlugin, Writer

    with Writer(tmp_path / "odd", version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conn = w.add_connection("/odd", "my_pkg/msg/Odd", msgdef="", rihs01="RIHS01_x")
        w.write(conn, 1, b"\x00\x01\x00\x00")
    with pytest.raises(MissingTopicError, match="not playing /odd: unknown type my_pkg/msg/Odd"):
        PlayerNode(open_bag(tmp_path / "odd"), context=ros.context)
    with pytest.raises(MissingTopicError, match="/clock"):
        PlayerNode(
            bag, context=ros.context, parameter_overrides=[Parameter("lockstep", value=True)]
        )


def test_clock_start_offset_and_exclude(ros, tmp_path):
    """``clock``: /clock carries the bag time, rising from the first played message to the
    last; ``start_offset``: 0.1 s in, the latched topic's message still goes first;
    ``exclude``: a topic not played."""
    from rosgraph_msgs.msg import Clock

    bag = small_bag(tmp_path / "b")
    probe = ros.add(__import__("rclpy").create_node("probe", context=ros.context))
    got, clocks, latched_seen = [], [], []
    probe.create_subscription(UInt16, "/count", lambda m: got.append(m.data), 100)
    probe.create_subscription(
        Clock, "/clock", lambda m: clocks.append(m.clock.sec * 10**9 + m.clock.nanosec), 100
    )
    probe.create_subscription(UInt16, "/latched", lambda m: latched_seen.append(m.data), LATCHED)
    overrides = [
        Parameter("rate", value=0.5),
        Parameter("clock", value=True),
        Parameter("clock_rate", value=100.0),
        Parameter("start_offset", value=0.1),
    ]
    player = ros.add(PlayerNode(bag, context=ros.context, parameter_overrides=overrides))
    assert ros.spin_until(lambda: player.finished and len(got) == 11, timeout=20.0)
    assert got == list(range(9, 20))  # /count i at (i + 1) 10 ms; the bag starts at 0
    assert ros.spin_until(lambda: latched_seen == [42], timeout=10.0)
    assert clocks == sorted(clocks) and len(set(clocks)) > 3
    assert clocks[0] >= 100_000_000 and clocks[-1] <= 200_000_000
    assert player.bag_time == 200_000_000
    excluded = ros.add(
        PlayerNode(
            bag,
            context=ros.context,
            parameter_overrides=[Parameter("exclude", value=["/count"])],
            node_name="player_2",
        )
    )
    assert set(excluded.publishers_) == {"/latched"}
    with pytest.raises(ParameterError, match="recorded timing only"):
        PlayerNode(
            bag,
            context=ros.context,
            parameter_overrides=[Parameter("lockstep", value=True), Parameter("clock", value=True)],
            node_name="player_3",
        )


def test_cli_play_errors(tmp_path, capsys, domain):
    small_bag(tmp_path / "b")
    args = ["play", str(tmp_path / "b"), "--topics", "/nope", "--domain", str(domain)]
    assert ant_bag(args) == 2
    assert "no playable topic" in capsys.readouterr().err


@pytest.mark.parametrize("kind", ["recorder", "player"])
def test_config_files_set_every_parameter(ros, tmp_path, kind):
    import yaml

    from excavation_bags.recorder_node import RecorderNode

    path = ROOT / "ros2_ws" / "src" / "excavation_bags" / "config" / f"bag_{kind}.yaml"
    values = yaml.safe_load(path.read_text())["/**"]["ros__parameters"]
    values["depth" if kind == "recorder" else "rate"] = 3 if kind == "recorder" else 2.5
    if kind == "recorder":
        values["out"] = str(tmp_path / "rec")
    else:
        values["bag"] = str(small_bag(tmp_path / "b").path)
    changed = tmp_path / "params.yaml"
    changed.write_text(yaml.safe_dump({"/**": {"ros__parameters": values}}))
    args = ["--ros-args", "--params-file", str(changed)]
    make = RecorderNode if kind == "recorder" else PlayerNode
    node = make(context=ros.context, cli_args=args)
    try:
        declared = set(node._parameters) - {"use_sim_time", "start_type_description_service"}
        assert declared == set(values)
        if kind == "recorder":
            assert node.depth == 3 and (tmp_path / "rec" / "metadata.yaml").exists()
            node.close()
        else:
            assert node.rate == 2.5 and set(node.publishers_) == {"/latched", "/count"}
    finally:
        node.destroy_node()


def test_a_tick_splits_at_its_last_recorded_reply():
    """Tick replay: what came after the controllers answered goes out after the fresh ones
    answer; a tick nobody answered goes out whole before the wait."""
    from excavation_bags.player_node import split_at_replies

    tick = [
        ("/team/tick", 1, b"t"),
        ("/tick/robot_0/pose", 2, b"p"),
        ("/robot_0/imu", 3, b"i1"),
        ("/robot_0/behaviour", 4, b"w0"),
        ("/robot_1/behaviour", 5, b"w1"),
        ("/robot_0/imu", 6, b"i2"),
    ]
    replies = {"/robot_0/behaviour", "/robot_1/behaviour"}
    before, after = split_at_replies(tick, replies)
    assert [m[2] for m in before] == [b"t", b"p", b"i1"]
    assert [m[2] for m in after] == [b"i2"]
    unanswered = [m for m in tick if m[0] not in replies]
    assert split_at_replies(unanswered, replies) == (unanswered, [])
