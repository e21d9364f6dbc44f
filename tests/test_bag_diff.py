"""``ant-bag diff``: poses by stamp, height maps by cell, words by tick, the rest by bytes."""

from __future__ import annotations

import numpy as np
from geometry_msgs.msg import PoseWithCovarianceStamped
from rclpy.qos import QoSProfile
from rclpy.serialization import serialize_message
from std_msgs.msg import UInt16

from excavation_bags.cli import main as ant_bag
from excavation_bags.diff import diff_bags
from excavation_bags.metadata import qos_from_profile
from excavation_bags.reader import open_bag
from excavation_bags.writer import BagWriter
from excavation_common.messages import grid_to_image

QOS = [qos_from_profile(QoSProfile(depth=10))]


def _pose(t: int, x: float) -> bytes:
    msg = PoseWithCovarianceStamped()
    msg.header.frame_id = "map"
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t, 1_000_000_000)
    msg.pose.pose.position.x, msg.pose.pose.position.y = x, 1.0
    msg.pose.pose.orientation.w = 1.0
    return serialize_message(msg)


def _bag(path, shift=0.0, cell=0.0, word=None, extra=False):
    heights = np.zeros((4, 4), dtype=np.float32)
    with BagWriter(path) as w:
        w.add_topic("/robot_0/pose", "geometry_msgs/msg/PoseWithCovarianceStamped", QOS)
        w.add_topic("/worksite/height_map", "sensor_msgs/msg/Image", QOS)
        w.add_topic("/robot_0/behaviour", "std_msgs/msg/UInt16", QOS)
        if extra:
            w.add_topic("/extra", "std_msgs/msg/UInt16", QOS)
        for i in range(5):
            t = (i + 1) * 100_000_000
            w.write("/robot_0/pose", t, _pose(t, 0.5 + 0.25 * i + (shift if i == 2 else 0.0)))
            grid = heights.copy()
            if i == 3:
                grid[1, 2] += cell
            image = grid_to_image(grid, "32FC1")
            image.header.stamp.nanosec = t
            w.write("/worksite/height_map", t, serialize_message(image))
            data = word if (word is not None and i == 4) else 259
            w.write("/robot_0/behaviour", t, serialize_message(UInt16(data=data)))
    return open_bag(path)


def test_a_bag_against_itself_is_the_same_and_exits_0(tmp_path, capsys):
    a = _bag(tmp_path / "a")
    assert diff_bags(a, a)["same"]
    assert ant_bag(["diff", str(tmp_path / "a"), str(tmp_path / "a")]) == 0
    assert "the bags are the same" in capsys.readouterr().out


def test_a_shifted_pose_a_changed_cell_and_word_and_a_new_topic_are_named(tmp_path, capsys):
    a = _bag(tmp_path / "a")
    b = _bag(tmp_path / "b", shift=0.03, cell=0.5, word=267, extra=True)
    result = diff_bags(a, b)
    assert not result["same"] and result["only_in_b"] == ["/extra"]
    pose = result["topics"]["/robot_0/pose"]
    assert pose["matched"] == 5 and abs(pose["position_cm_max"] - 3.0) < 1e-6
    assert abs(pose["position_cm_mean"] - 0.6) < 1e-6
    maps = result["topics"]["/worksite/height_map"]
    assert maps["maps_differing"] == 1 and maps["most_cells_differing"] == 1
    assert maps["largest_difference"] == 0.5
    assert result["topics"]["/robot_0/behaviour"]["ticks_differing"] == [4]
    assert ant_bag(["diff", str(tmp_path / "a"), str(tmp_path / "b")]) == 1
    out = capsys.readouterr().out
    assert "/extra: only in B" in out and "4 ticks" not in out and "first 4" in out
