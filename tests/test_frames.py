"""Grid <-> map frame convention (row = north = +y, column = east = +x)."""

from __future__ import annotations

import math

import pytest

from ant_controller.layout import EAST, NORTH, SOUTH, WEST
from ant_controller.sensing import FORWARD
from excavation_common.frames import (
    cell_center,
    heading_to_yaw,
    map_to_cell,
    robot_anchor,
    robot_center,
    yaw_to_heading,
)


def test_rows_go_north_columns_go_east():
    assert cell_center(0, 0, 0.5) == (0.25, 0.25)
    assert cell_center(3, 1, 0.5) == (0.75, 1.75)  # row 3 is 1.5-2.0 m north
    assert map_to_cell(0.75, 1.75, 0.5) == (3, 1)
    assert map_to_cell(-0.01, 0.2, 0.5) == (0, -1)


@pytest.mark.parametrize(("heading", "yaw"), [(NORTH, 90), (EAST, 0), (SOUTH, -90), (WEST, 180)])
def test_headings_and_forward_steps_match_yaw(heading, yaw):
    assert heading_to_yaw(heading) == pytest.approx(math.radians(yaw))
    assert yaw_to_heading(math.radians(yaw) + 0.3) == heading
    # The grid's forward step (d_row, d_col) points along the yaw: d_col = cos, d_row = sin.
    assert FORWARD[heading][1] == round(math.cos(math.radians(yaw)))
    assert FORWARD[heading][0] == round(math.sin(math.radians(yaw)))


def test_robot_centre_round_trip():
    for r in range(5):
        for c in range(5):
            x, y = robot_center(r, c, 0.25)
            assert robot_anchor(x + 0.05, y - 0.05, 0.25) == (r, c)


@pytest.mark.parametrize("heading", [NORTH, EAST, SOUTH, WEST])
def test_heading_arithmetic_matches_the_tables(heading):
    from ant_controller.sensing import (
        FRONT_LEFT,
        RIGHT_STEP,
        forward_step,
        front_left,
        right_step,
    )

    assert tuple(forward_step(heading)) == tuple(FORWARD[heading])
    assert tuple(front_left(heading)) == tuple(FRONT_LEFT[heading])
    assert tuple(right_step(heading)) == tuple(RIGHT_STEP[heading])
