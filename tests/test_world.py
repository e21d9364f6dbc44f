"""World model: blade equations, moves, sensors, fitness, conservation and determinism."""

from __future__ import annotations

import numpy as np
import pytest
from helpers.worlds import make_world
from hypothesis import given, settings
from hypothesis import strategies as st

from ant_controller.layout import (
    B1,
    BLADE_ABOVE,
    BLADE_BELOW,
    BLADE_HOME,
    BLADE_LEVEL,
    D1,
    E1,
    E2,
    E_ABOVE,
    E_BELOW,
    E_LEVEL,
    EAST,
    H1,
    L1,
    M1,
    NORTH,
    R1,
    S1,
    SOUTH,
    U1,
    WEST,
    Z1,
    Z2,
    Z3,
    Z4,
    Z_ABOVE,
    Z_BELOW,
    Z_DONT_CARE,
    Z_DUMP,
    Z_LEVEL,
    mask_of,
)
from ant_controller.sensing import load_code
from blueprint_server.blueprint import default_blueprint
from excavation_sim.world import (
    BLADE,
    COL,
    HEADING,
    MEMORY,
    ROW,
    STUCK,
    PlacementError,
    World,
    place_robots,
)

FORWARD = mask_of(2)
BACKWARD = mask_of(3)
THROTTLE = mask_of(1)


# --- blade equations, robot at (2, 2) facing north: wheels row 3, blade row 4, next row 5 ---


@pytest.mark.parametrize(
    ("blade", "blade_row", "expect_blade_row", "expect_next_row"),
    [
        # level blade, no soil: nothing moves
        (BLADE_LEVEL, (0, 0), (0, 0), (0, 0)),
        # level blade pushes everything above the wheels into the next cells
        (BLADE_LEVEL, (3, 1), (0, 0), (3, 1)),
        # blade below cuts one unit under the wheels (eps = 1 always)
        (BLADE_BELOW, (0, 0), (-1, -1), (1, 1)),
        (BLADE_BELOW, (2, 0), (-1, -1), (3, 1)),
        # blade above with nothing against it: eps = 0, behaves as level
        (BLADE_ABOVE, (0, 0), (0, 0), (0, 0)),
        (BLADE_ABOVE, (1, 1), (0, 0), (1, 1)),
        # blade above with soil against it (V = 2 > 0): leaves one unit above the wheels
        (BLADE_ABOVE, (3, 1), (1, 1), (2, 0)),
        # blade home: no contact
        (BLADE_HOME, (1, 0), (1, 0), (0, 0)),
    ],
)
def test_blade_equations(blade, blade_row, expect_blade_row, expect_next_row):
    w = make_world([(2, 2, NORTH, blade)])
    w.heights[4, 2:4] = blade_row
    total = w.heights.sum()
    w.step([FORWARD])
    assert tuple(w.robots[0, [ROW, COL]]) == (3, 2)
    assert w.robots[0, STUCK] == 0
    assert tuple(w.heights[4, 2:4]) == expect_blade_row
    assert tuple(w.heights[5, 2:4]) == expect_next_row
    assert w.heights.sum() == total


def test_blade_cuts_relative_to_wheels_giving_a_slope():
    """Repeated cut-dig deepens one unit per cell: the paper's discretised sloped cut."""
    w = make_world([(0, 2, NORTH, BLADE_BELOW)], size=10)
    for _ in range(3):
        w.step([FORWARD | THROTTLE])
        assert w.robots[0, STUCK] == 0
    assert list(w.heights[2:5, 2]) == [-1, -2, -3]
    assert w.heights[5, 2] == 6  # the cut soil, piled against the blade
    # The next cut would hold 2 x 15 units against the blade: over 24, the robot is stuck.
    w.step([FORWARD | THROTTLE])
    assert w.robots[0, STUCK] == 1 and w.robots[0, ROW] == 3
    assert w.heights.sum() == 0


def test_level_dig_keeps_the_cut_level():
    w = make_world([(0, 2, NORTH, BLADE_BELOW)], size=10)
    w.step([FORWARD | mask_of(9)])  # cut, then set the blade level
    for _ in range(3):
        w.step([FORWARD])
    assert list(w.heights[2:6, 2]) == [-1, -1, -1, -1]


def test_push_capacity_and_throttle():
    w = make_world([(2, 2, NORTH, BLADE_LEVEL)])
    w.heights[4, 2:4] = (10, 3)  # 13 units would be pushed: above 12, below 24
    w.step([FORWARD])
    assert w.robots[0, STUCK] == 1
    assert tuple(w.robots[0, [ROW, COL]]) == (2, 2)
    assert tuple(w.heights[4, 2:4]) == (10, 3)
    w.step([FORWARD | THROTTLE])
    assert w.robots[0, STUCK] == 0
    assert tuple(w.robots[0, [ROW, COL]]) == (3, 2)
    assert tuple(w.heights[5, 2:4]) == (10, 3)


def test_climb_limit_with_blade_home():
    w = make_world([(2, 2, NORTH, BLADE_HOME)])
    w.heights[4, 2] = 2
    w.step([FORWARD])
    assert w.robots[0, STUCK] == 1 and w.robots[0, ROW] == 2
    w.step([FORWARD | THROTTLE])
    assert w.robots[0, STUCK] == 0 and w.robots[0, ROW] == 3
    assert w.heights[4, 2] == 2  # no contact: soil untouched


def test_backward_leaves_soil_and_clears_stuck():
    w = make_world([(3, 2, NORTH, BLADE_LEVEL)])
    w.heights[5, 2:4] = 2
    w.step([BACKWARD])
    assert w.robots[0, ROW] == 2
    assert w.heights[5, 2] == 2 and w.heights.sum() == 4


@pytest.mark.parametrize("heading", [NORTH, EAST, SOUTH, WEST])
def test_grid_edges_block_moves(heading):
    # A robot in the corner facing outward in each direction is blocked, both ways.
    corner = {NORTH: (6, 6), EAST: (6, 6), SOUTH: (0, 0), WEST: (0, 0)}[heading]
    w = make_world([(*corner, heading, BLADE_LEVEL)])
    w.step([FORWARD])
    assert w.robots[0, STUCK] == 1
    assert tuple(w.robots[0, [ROW, COL]]) == corner
    assert w.sense()[0, S1] == 1


def test_robots_block_each_other_and_soil_is_not_pushed_into_a_robot():
    w = make_world([(2, 2, NORTH, BLADE_LEVEL), (5, 2, SOUTH, BLADE_HOME)])
    w.heights[4, 2] = 1
    w.step([FORWARD, 0])  # the blade would push into robot 1 at row 5
    assert w.robots[0, STUCK] == 1 and w.robots[0, ROW] == 2
    assert w.heights[4, 2] == 1
    w.robots[0, BLADE] = BLADE_HOME
    w.step([FORWARD, 0])  # with the blade home the robot may close up
    assert w.robots[0, ROW] == 3
    w.step([FORWARD, 0])
    assert w.robots[0, STUCK] == 1 and w.robots[0, ROW] == 3


def test_robots_act_in_index_order():
    # Both want the same free cells; robot 0 acts first and wins, robot 1 is stuck.
    w = make_world([(0, 2, NORTH, BLADE_HOME), (3, 2, SOUTH, BLADE_HOME)])
    w.step([FORWARD, FORWARD])  # both want row 2
    assert w.robots[0, ROW] == 1 and w.robots[0, STUCK] == 0
    assert w.robots[1, ROW] == 3 and w.robots[1, STUCK] == 1


def test_turns_blade_and_memory_commands_in_table_order():
    w = make_world([(2, 2, NORTH, BLADE_HOME)])
    w.step([mask_of(5)])
    assert w.robots[0, HEADING] == EAST
    w.step([mask_of(6, 6)])
    assert w.robots[0, HEADING] == NORTH
    w.step([mask_of(7, 8)])  # above then below: below wins
    assert w.robots[0, BLADE] == BLADE_BELOW
    w.step([mask_of(11)])
    assert w.robots[0, MEMORY] == 1
    w.step([mask_of(11, 12)])  # set then clear: cleared
    assert w.robots[0, MEMORY] == 0
    headings = set()
    for _ in range(40):
        before = w.robots[0, HEADING]
        w.step([mask_of(4)])
        turn = (w.robots[0, HEADING] - before) % 4
        assert turn in (1, 3)
        headings.add(turn)
    assert headings == {1, 3}


# --- sensors on hand-built scenes ----------------------------------------------------------


def test_depth_sensors_against_the_blueprint():
    zones = np.zeros((8, 8))
    goal = np.zeros((8, 8))
    zones[4, 1] = 2  # Z1: dump
    zones[4, 2:5] = 1
    goal[4, 2:5] = -1
    heights = np.zeros((8, 8))
    heights[4, 3] = -1  # Z3 level with the goal
    heights[4, 4] = -2  # Z4 below the goal
    w = make_world([(2, 2, NORTH, BLADE_LEVEL)], heights=heights, zones=zones, goal=goal)
    s = w.sense()[0]
    assert [s[Z1], s[Z2], s[Z3], s[Z4]] == [Z_DUMP, Z_ABOVE, Z_LEVEL, Z_BELOW]
    assert [s[E1], s[E2]] == [E_LEVEL, E_BELOW]


@pytest.mark.parametrize(
    ("heading", "cells"),
    [
        (NORTH, [(4, 1), (4, 2), (4, 3), (4, 4)]),
        (EAST, [(4, 4), (3, 4), (2, 4), (1, 4)]),
        (SOUTH, [(1, 4), (1, 3), (1, 2), (1, 1)]),
        (WEST, [(1, 1), (2, 1), (3, 1), (4, 1)]),
    ],
)
def test_front_row_runs_left_to_right(heading, cells):
    zones = np.zeros((8, 8))
    for i, (r, c) in enumerate(cells):
        zones[r, c] = 2 if i % 2 == 0 else 0
    w = make_world([(2, 2, heading, BLADE_HOME)], zones=zones)
    s = w.sense()[0]
    assert [s[Z1], s[Z2], s[Z3], s[Z4]] == [Z_DUMP, Z_DONT_CARE, Z_DUMP, Z_DONT_CARE]


def test_blade_state_load_tilt_stuck_memory():
    heights = np.zeros((8, 8))
    heights[4, 2:4] = (5, 3)  # 8 units above the wheels
    heights[2, 2:4] = 1  # rear wheels higher than front wheels
    w = make_world([(2, 2, NORTH, BLADE_LEVEL)], heights=heights)
    w.robots[0, MEMORY] = 1
    s = w.sense()[0]
    assert s[B1] == BLADE_LEVEL
    assert s[E1] == E_ABOVE and s[E2] == E_ABOVE
    assert s[L1] == load_code(8) == 2
    assert s[R1] == 1
    assert s[M1] == 1 and s[U1] == 0
    w.robots[0, BLADE] = BLADE_HOME
    assert w.sense()[0, L1] == 0  # a home blade holds nothing


@pytest.mark.parametrize(
    ("volume", "code"),
    [(0, 0), (1, 1), (6, 1), (7, 2), (12, 2), (13, 3), (19, 4), (24, 4), (99, 4)],
)
def test_load_code(volume, code):
    assert load_code(volume) == code


@pytest.mark.parametrize(
    ("other", "distance", "bearing"),
    [
        ((9, 2), 3, 0),  # far ahead: saturates at 3
        ((5, 2), 1, 0),  # ahead, one free cell between
        ((2, 5), 1, 1),  # right (east, facing north)
        ((2, 0), 0, 3),  # left, touching
        ((0, 0), 0, 2),  # behind-left corner, behind dominates ties
    ],
)
def test_nearest_robot_distance_and_bearing(other, distance, bearing):
    w = make_world([(2, 2, NORTH, BLADE_HOME), (*other, NORTH, BLADE_HOME)], size=12)
    s = w.sense()[0]
    assert s[D1] == distance
    assert s[H1] == bearing


def test_obstacle_sensor_sees_robots_in_front():
    w = make_world([(2, 2, NORTH, BLADE_HOME), (4, 3, NORTH, BLADE_HOME)])
    assert w.sense()[0, S1] == 1
    w.robots[1, COL] = 5
    assert w.sense()[0, S1] == 0


def test_lone_robot_reads_far_and_ahead():
    w = make_world([(2, 2, EAST, BLADE_HOME)])
    s = w.sense()[0]
    assert s[D1] == 3 and s[H1] == 0


# --- fitness -------------------------------------------------------------------------------


def test_fitness_is_one_exactly_when_the_dig_area_matches():
    bp = default_blueprint(2)
    w = make_world([(0, 0, NORTH, BLADE_HOME)], size=16, zones=bp.zones, goal=bp.goal)
    assert w.fitness() == pytest.approx(np.exp(-4.0))
    w.heights[:] = bp.goal
    assert w.fitness() == 1.0
    w.heights[0, 0] = 5  # outside the dig area: ignored
    assert w.fitness() == 1.0
    w.heights[5, 5] -= 1  # one cell too deep
    expected = (63 + np.exp(-2.0)) / 64
    assert w.fitness() == pytest.approx(expected)
    assert w.fitness() < 1.0


# --- invariants over random runs -----------------------------------------------------------


def footprint_ok(w):
    taken = np.zeros(w.heights.shape, dtype=int)
    for r, c in w.robots[:, [ROW, COL]]:
        if r < 0 or c < 0 or r + 2 > w.heights.shape[0] or c + 2 > w.heights.shape[1]:
            return False
        taken[r : r + 2, c : c + 2] += 1
    return taken.max() <= 1


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n_robots=st.integers(1, 8),
    rows=st.integers(6, 16),
    cols=st.integers(6, 16),
)
def test_soil_is_conserved_and_robots_never_overlap(seed, n_robots, rows, cols):
    rng = np.random.default_rng(seed)
    zones = rng.integers(0, 3, (rows, cols))
    goal = -rng.integers(1, 4, (rows, cols))
    heights = rng.integers(-3, 4, (rows, cols))
    try:
        w = World.create(zones, goal, n_robots, rng, heights=heights)
    except PlacementError:
        return
    total = int(w.heights.sum())
    for _ in range(100):
        w.step(rng.integers(0, 1 << 12, n_robots))
        assert int(w.heights.sum()) == total
        assert footprint_ok(w)


def test_same_seed_same_run_and_different_seed_differs():
    bp = default_blueprint(1)

    def run(seed):
        rng = np.random.default_rng(seed)
        w = World.create(bp.zones, bp.goal, 4, rng)
        masks = rng.integers(0, 1 << 12, (200, 4))
        trace = []
        for m in masks:
            w.step(m)
            trace.append((w.heights.copy(), w.robots.copy()))
        return trace

    a, b, c = run(7), run(7), run(8)
    for (ha, ra), (hb, rb) in zip(a, b, strict=True):
        assert np.array_equal(ha, hb) and np.array_equal(ra, rb)
    assert any(not np.array_equal(ha, hc) for (ha, _), (hc, _) in zip(a, c, strict=True))


def test_placement_is_random_but_valid_and_errors_when_full():
    rng = np.random.default_rng(0)
    robots = place_robots((16, 16), 10, rng)
    w = make_world([tuple(r[[ROW, COL, HEADING, BLADE]]) for r in robots], size=16)
    assert footprint_ok(w)
    with pytest.raises(PlacementError, match="could not place robot"):
        place_robots((4, 4), 5, rng)
