"""Message <-> array conversions, built in memory (no rclpy.init)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ant_controller.layout import BLADE_ABOVE, BLADE_BELOW, BLADE_HOME, BLADE_LEVEL
from excavation_common.constants import BladeGeometry
from excavation_common.messages import (
    MessageError,
    blade_from_joint,
    blade_joint,
    grid_to_image,
    heights_to_units,
    image_to_grid,
    map_info,
    pose_message,
    pose_to_grid,
)


def test_grid_image_round_trip_keeps_row_zero_south():
    grid = np.arange(12, dtype=np.float32).reshape(3, 4)
    grid[1, 2] = np.nan
    msg = grid_to_image(grid, "32FC1")
    assert (msg.height, msg.width, msg.step, msg.encoding) == (3, 4, 16, "32FC1")
    back = image_to_grid(msg, "32FC1", shape=(3, 4))
    assert np.array_equal(back, grid, equal_nan=True)
    assert back[0, 1] == 1.0  # first row of the image = grid row 0 (south)
    zones = np.array([[0, 1], [2, 1]], dtype=np.uint8)
    assert np.array_equal(image_to_grid(grid_to_image(zones, "mono8"), "mono8"), zones)


@pytest.mark.parametrize(
    ("mutate", "field"),
    [
        (lambda m: setattr(m, "encoding", "rgb8"), "encoding"),
        (lambda m: setattr(m, "step", 3), "step"),
        (lambda m: setattr(m, "data", bytes(5)), "data"),
        (lambda m: setattr(m, "is_bigendian", 1), "is_bigendian"),
    ],
)
def test_bad_images_name_the_field(mutate, field):
    msg = grid_to_image(np.zeros((2, 2)), "32FC1")
    mutate(msg)
    with pytest.raises(MessageError) as exc:
        image_to_grid(msg, "32FC1", topic="/worksite/height_map")
    assert exc.value.field == field and "/worksite/height_map" in str(exc.value)
    with pytest.raises(MessageError, match="16 x 16"):
        image_to_grid(grid_to_image(np.zeros((2, 2)), "32FC1"), "32FC1", shape=(16, 16))


@pytest.mark.parametrize("heading", range(4))
def test_pose_round_trip_and_covariance(heading):
    msg = pose_message(3, 5, heading, 0.25, 0.01, 0.05)
    assert msg.header.frame_id == "map"
    assert (msg.pose.pose.position.x, msg.pose.pose.position.y) == (1.5, 1.0)
    assert msg.pose.covariance[0] == 0.01 and msg.pose.covariance[35] == 0.05
    assert pose_to_grid(msg, 0.25) == (3, 5, heading)
    msg.pose.pose.position.x += 0.05  # small noise snaps back
    assert pose_to_grid(msg, 0.25) == (3, 5, heading)


def test_bad_poses():
    msg = pose_message(1, 1, 0, 0.25, 0.01, 0.05)
    msg.header.frame_id = "odom"
    with pytest.raises(MessageError, match="header.frame_id"):
        pose_to_grid(msg, 0.25)
    msg = pose_message(1, 1, 0, 0.25, 0.01, 0.05)
    msg.pose.pose.position.x = math.nan
    with pytest.raises(MessageError, match="finite"):
        pose_to_grid(msg, 0.25)


@pytest.mark.parametrize("blade", [BLADE_BELOW, BLADE_LEVEL, BLADE_ABOVE, BLADE_HOME])
def test_blade_joint_round_trip(blade):
    g = BladeGeometry()
    assert blade_from_joint(blade_joint(blade, 5.0, g), g) == (blade, 12)
    assert blade_from_joint(blade_joint(blade, -1.0, g), g) == (blade, 0)


def test_bad_joint_states():
    g = BladeGeometry()
    msg = blade_joint(BLADE_LEVEL, 1.0, g)
    msg.name = ["arm"]
    with pytest.raises(MessageError, match="no 'blade' joint"):
        blade_from_joint(msg, g)
    msg = blade_joint(BLADE_LEVEL, math.inf, g)
    with pytest.raises(MessageError, match="finite"):
        blade_from_joint(msg, g)


def test_map_info_and_units():
    info = map_info(16, 12, 0.25)
    assert (info.height, info.width, info.resolution) == (16, 12, 0.25)
    units = heights_to_units(np.array([[0.049, -0.1, np.nan]]), 0.05)
    assert units[0, 0] == 1 and units[0, 1] == -2 and units[0, 2] == np.iinfo(np.int32).min
