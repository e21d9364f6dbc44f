"""Plain-Python reference of the sensor vector (paper, Table 1), written for reading.

:func:`sense_reference` computes what :func:`ant_controller.sensing.sense` computes, the
slow way: robot geometry from the heading tables (``FORWARD``, ``FRONT_LEFT``,
``RIGHT_STEP``) instead of the kernels' branch-free arithmetic, Python integers and
lists instead of numba scalars, one rule per sensor in Table 1 order. The tests hold the
numba kernel to it on random states (``tests/test_world_reference.py``), as
:func:`ant_controller.tissue.decide_reference` does for the network.
"""

from __future__ import annotations

from collections.abc import Sequence

from ant_controller import layout
from ant_controller.readings import H1_ABSOLUTE, H1_RELATIVE
from ant_controller.sensing import FORWARD, FRONT_LEFT, RIGHT_STEP, SENSE_RANGE
from excavation_common.constants import EAST, MAX_LOAD, NORTH, SOUTH, WEST, ZONE_DIG, ZONE_DUMP

Cell = tuple[int, int]


def front_wheel_cell(pose: Sequence[int], i: int) -> Cell:
    """Cell under front wheel ``i`` (0 left, 1 right) of a robot at ``(row, col, heading)``."""
    row, col, h = (int(v) for v in pose[:3])
    return (
        row + int(FRONT_LEFT[h, 0]) + i * int(RIGHT_STEP[h, 0]),
        col + int(FRONT_LEFT[h, 1]) + i * int(RIGHT_STEP[h, 1]),
    )


def rear_wheel_cell(pose: Sequence[int], i: int) -> Cell:
    """Cell under rear wheel ``i``: one step behind the front wheel."""
    r, c = front_wheel_cell(pose, i)
    h = int(pose[2])
    return r - int(FORWARD[h, 0]), c - int(FORWARD[h, 1])


def front_row_cell(pose: Sequence[int], j: int) -> Cell:
    """Cell ``j = -1 .. 2`` of the row ahead (0, 1: the blade cells Z2, Z3)."""
    r, c = front_wheel_cell(pose, j)
    h = int(pose[2])
    return r + int(FORWARD[h, 0]), c + int(FORWARD[h, 1])


def on_grid(heights, cell: Cell) -> bool:
    """The cell lies on the grid."""
    return 0 <= cell[0] < heights.shape[0] and 0 <= cell[1] < heights.shape[1]


def under_other_robot(poses, active, k: int, cell: Cell) -> bool:
    """An active robot other than k covers the cell with its 2 x 2 footprint."""
    for j in range(len(poses)):
        if j != k and active[j]:
            if 0 <= cell[0] - int(poses[j][0]) <= 1 and 0 <= cell[1] - int(poses[j][1]) <= 1:
                return True
    return False


def blade_height_offset(blade: int) -> int:
    """``b_h``: -1 below, +1 above, 0 level (and home)."""
    return {layout.BLADE_BELOW: -1, layout.BLADE_ABOVE: 1}.get(int(blade), 0)


def blade_volume_reference(heights, pose: Sequence[int], blade: int) -> int:
    """``V_blade``: soil above the cutting level in the on-grid blade cells (home: 0)."""
    if blade == layout.BLADE_HOME:
        return 0
    volume = 0
    for i in range(2):
        b = front_row_cell(pose, i)
        if on_grid(heights, b):
            w = front_wheel_cell(pose, i)
            volume += max(0, int(heights[b]) - int(heights[w]) - blade_height_offset(blade))
    return volume


def tilted_down_reference(heights, pose: Sequence[int]) -> bool:
    """R1: the front wheels stand lower than the rear wheels, summed over both sides."""
    front = sum(int(heights[front_wheel_cell(pose, i)]) for i in range(2))
    rear = sum(int(heights[rear_wheel_cell(pose, i)]) for i in range(2))
    return front < rear


def sense_reference(
    heights,
    zones,
    goal,
    poses,
    active,
    k: int,
    blade: int,
    load_volume: int,
    stuck: bool,
    tilted: bool,
    memory: bool,
    h1_frame: int = H1_RELATIVE,
) -> list[int]:
    """Robot k's 14 sensor codes, one Table 1 rule after another (see the module docstring).

    ``h1_frame``: H1 relative to the robot's heading (``H1_RELATIVE``) or as a compass
    bearing (``H1_ABSOLUTE``), :mod:`ant_controller.readings`.
    """
    pose = poses[k]
    out = [0] * layout.N_SENSORS
    # Z1..Z4: the row of four cells ahead, against the blueprint.
    for j in range(4):
        cell = front_row_cell(pose, j - 1)
        if not on_grid(heights, cell):
            out[layout.Z1 + j] = layout.Z_DONT_CARE
        elif zones[cell] == ZONE_DUMP:
            out[layout.Z1 + j] = layout.Z_DUMP
        elif zones[cell] != ZONE_DIG:
            out[layout.Z1 + j] = layout.Z_DONT_CARE
        elif heights[cell] > goal[cell]:
            out[layout.Z1 + j] = layout.Z_ABOVE
        elif heights[cell] < goal[cell]:
            out[layout.Z1 + j] = layout.Z_BELOW
        else:
            out[layout.Z1 + j] = layout.Z_LEVEL
    # E1, E2: each blade cell against the front wheel behind it; S1: something in the way.
    obstacle = False
    for i in range(2):
        b = front_row_cell(pose, i)
        if not on_grid(heights, b):
            out[layout.E1 + i] = layout.E_LEVEL
            obstacle = True
            continue
        obstacle = obstacle or under_other_robot(poses, active, k, b)
        d = int(heights[b]) - int(heights[front_wheel_cell(pose, i)])
        out[layout.E1 + i] = (
            layout.E_ABOVE if d > 0 else layout.E_BELOW if d < 0 else layout.E_LEVEL
        )
    out[layout.B1] = int(blade)
    # L1: 0 for no load, else the sixth of the push capacity it reaches, at most 4.
    out[layout.L1] = 0 if load_volume <= 0 else min(4, -(-4 * int(load_volume) // MAX_LOAD))
    out[layout.S1] = int(obstacle)
    # D1, H1: the nearest other active robot (Chebyshev gap between footprints, ties to
    # the lowest index) and its bearing, from this robot's heading or on the compass.
    nearest, gap = -1, SENSE_RANGE
    best: int | None = None
    for j in range(len(poses)):
        if j == k or not active[j]:
            continue
        g = max(
            0, max(abs(int(poses[j][0]) - int(pose[0])), abs(int(poses[j][1]) - int(pose[1]))) - 2
        )
        if best is None or g < best:
            best, nearest = g, j
    if nearest >= 0:
        gap = best
    out[layout.D1] = min(gap, SENSE_RANGE)
    out[layout.H1] = layout.AHEAD if h1_frame == H1_RELATIVE else NORTH  # alone: code 0 either way
    if nearest >= 0 and h1_frame == H1_ABSOLUTE:
        dr = int(poses[nearest][0]) - int(pose[0])
        dc = int(poses[nearest][1]) - int(pose[1])
        if abs(dr) >= abs(dc):  # the dominant axis; ties to north / south
            out[layout.H1] = NORTH if dr >= 0 else SOUTH
        else:
            out[layout.H1] = EAST if dc > 0 else WEST
    elif nearest >= 0:
        h = int(pose[2])
        dr = int(poses[nearest][0]) - int(pose[0])
        dc = int(poses[nearest][1]) - int(pose[1])
        ahead = dr * int(FORWARD[h, 0]) + dc * int(FORWARD[h, 1])
        right = dr * int(RIGHT_STEP[h, 0]) + dc * int(RIGHT_STEP[h, 1])
        if abs(ahead) >= abs(right):
            out[layout.H1] = layout.AHEAD if ahead > 0 else layout.BEHIND
        else:
            out[layout.H1] = layout.RIGHT if right > 0 else layout.LEFT
    out[layout.R1] = int(bool(tilted))
    out[layout.U1] = int(bool(stuck))
    out[layout.M1] = int(bool(memory))
    return out
