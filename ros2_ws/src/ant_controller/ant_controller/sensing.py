"""Robot geometry and the sensor vector of Table 1 (paper, section 4.1).

This is the one place that turns a picture of the worksite (soil heights, blueprint,
robot poses) into the 14 discrete sensor values a controller sees. The simulator calls it
every step; the ROS controller node calls it with arrays decoded from its messages, so a
genome sees the same inputs offline and in the field.

Grid convention (see ``docs/world-model.md``): ``heights[row, col]``, row ``r`` grows to
the north (+y of the ``map`` frame) and column ``c`` to the east (+x). A robot's pose is
``(row, col, heading)`` where ``(row, col)`` is the south-west cell of its 2 x 2 footprint
and heading is 0 N, 1 E, 2 S, 3 W.

All functions are numba kernels over plain arrays; they import no ``rclpy``.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from ant_controller.layout import (
    AHEAD,
    B1,
    BEHIND,
    BLADE_ABOVE,
    BLADE_BELOW,
    BLADE_HOME,
    D1,
    E1,
    E_ABOVE,
    E_BELOW,
    E_LEVEL,
    H1,
    L1,
    LEFT,
    M1,
    N_SENSORS,
    R1,
    RIGHT,
    S1,
    U1,
    Z1,
    Z_ABOVE,
    Z_BELOW,
    Z_DONT_CARE,
    Z_DUMP,
    Z_LEVEL,
)
from ant_controller.readings import H1_ABSOLUTE, H1_RELATIVE
from excavation_common.constants import (  # noqa: F401 (re-exported for the kernels)
    EAST,
    MAX_LOAD,
    NORTH,
    SOUTH,
    WEST,
    ZONE_DIG,
    ZONE_DONT_CARE,
    ZONE_DUMP,
)

# Pose columns.
POSE_ROW, POSE_COL, POSE_HEADING = 0, 1, 2


SENSE_RANGE = 3
"""D1 saturates at this many free cells between two footprints."""

# Per heading: forward step, offset of the front-left wheel from the anchor, and the
# step from the left front wheel to the right one.
FORWARD = np.array([[1, 0], [0, 1], [-1, 0], [0, -1]], dtype=np.int64)
FRONT_LEFT = np.array([[1, 0], [1, 1], [0, 1], [0, 0]], dtype=np.int64)
RIGHT_STEP = np.array([[0, 1], [-1, 0], [0, -1], [1, 0]], dtype=np.int64)


@nb.njit(cache=True, inline="always")
def in_grid(rows, cols, r, c):
    """True when cell ``(r, c)`` lies on a ``rows`` x ``cols`` grid."""
    return (r >= 0) & (r < rows) & (c >= 0) & (c < cols)


# The same tables as arithmetic on the heading, for the kernels (branch-free, no array
# loads); tests/test_world.py checks them against the tables.
@nb.njit(cache=True, inline="always")
def forward_step(h):
    """``FORWARD[h]``: the (d_row, d_col) of one step ahead."""
    return int(h == 0) - int(h == 2), int(h == 1) - int(h == 3)


@nb.njit(cache=True, inline="always")
def right_step(h):
    """``RIGHT_STEP[h]``: the (d_row, d_col) from the left front wheel to the right one."""
    return int(h == 3) - int(h == 1), int(h == 0) - int(h == 2)


@nb.njit(cache=True, inline="always")
def front_left(h):
    """``FRONT_LEFT[h]``: offset of the left front wheel from the footprint anchor."""
    return int(h <= 1), int((h == 1) | (h == 2))


@nb.njit(cache=True, inline="always")
def front_wheel(row, col, h, i):
    """Cell under front wheel ``i`` (0 left, 1 right) of a robot at ``(row, col, h)``."""
    flr, flc = front_left(h)
    rsr, rsc = right_step(h)
    return row + flr + i * rsr, col + flc + i * rsc


@nb.njit(cache=True, inline="always")
def rear_wheel(row, col, h, i):
    """Cell under rear wheel ``i`` (0 left, 1 right)."""
    r, c = front_wheel(row, col, h, i)
    fr, fc = forward_step(h)
    return r - fr, c - fc


@nb.njit(cache=True, inline="always")
def front_cell(row, col, h, j):
    """Cell ``j`` of the row in front of the robot, ``j = -1 .. 2`` from left to right.

    ``j = 0, 1`` are the two blade cells (Z2, Z3); ``j = -1, 2`` are Z1 and Z4.
    """
    r, c = front_wheel(row, col, h, j)
    fr, fc = forward_step(h)
    return r + fr, c + fc


@nb.njit(cache=True, inline="always")
def occupied_by_other(poses, active, k, r, c):
    """True when cell ``(r, c)`` is under the footprint of an active robot other than k."""
    for j in range(poses.shape[0]):
        if j == k or not active[j]:
            continue
        dr = r - poses[j, POSE_ROW]
        dc = c - poses[j, POSE_COL]
        if 0 <= dr <= 1 and 0 <= dc <= 1:
            return True
    return False


@nb.njit(cache=True, inline="always")
def blade_offset(blade):
    """``b_h`` of the blade equations: -1 below, 0 level, +1 above (home: 0, unused)."""
    if blade == BLADE_BELOW:
        return -1
    if blade == BLADE_ABOVE:
        return 1
    return 0


@nb.njit(cache=True, inline="always")
def blade_volume(heights, row, col, h, blade):
    """Soil held against the blade, ``V_blade`` of the paper, in soil units.

    Sum over the two blade cells of the soil above the cutting level (front wheel height
    plus ``b_h``), each cell clipped at zero. A home blade holds nothing; a blade cell off
    the grid holds nothing.
    """
    if blade == BLADE_HOME:
        return 0
    bh = blade_offset(blade)
    volume = 0
    for i in range(2):
        br, bc = front_cell(row, col, h, i)
        wr, wc = front_wheel(row, col, h, i)
        if in_grid(heights.shape[0], heights.shape[1], br, bc):
            v = heights[br, bc] - heights[wr, wc] - bh
            if v > 0:
                volume += v
    return volume


@nb.njit(cache=True, inline="always")
def load_code(volume):
    """L1 from a blade volume: 0 for none, then 1..4 for each sixth of ``MAX_LOAD``."""
    if volume <= 0:
        return 0
    code = (volume * 4 + MAX_LOAD - 1) // MAX_LOAD
    return code if code < 4 else 4


@nb.njit(cache=True, inline="always")
def is_tilted_down(heights, row, col, h):
    """R1: the front wheels stand lower than the rear wheels (summed over both sides)."""
    front = 0
    rear = 0
    for i in range(2):
        fr, fc = front_wheel(row, col, h, i)
        rr, rc = rear_wheel(row, col, h, i)
        front += heights[fr, fc]
        rear += heights[rr, rc]
    return front < rear


@nb.njit(cache=True, inline="always")
def zone_code(zone, height, goal_height):
    """Z code of one on-grid cell from its zone, soil height and goal height.

    Cells off the grid read ``Z_DONT_CARE`` (the caller checks). Scalar arguments on
    purpose: these helpers run several times per robot and step, and numba helpers that
    take arrays cost far more per call than the arithmetic (see docs/benchmarks.md).
    """
    if zone == ZONE_DUMP:
        return Z_DUMP
    if zone != ZONE_DIG:
        return Z_DONT_CARE
    if height > goal_height:
        return Z_ABOVE
    if height < goal_height:
        return Z_BELOW
    return Z_LEVEL


@nb.njit(cache=True, inline="always")
def nearest_robot(poses, active, k):
    """Index of the nearest other active robot and the free cells between the footprints.

    Distance is the Chebyshev gap between the 2 x 2 footprints; ties go to the lowest
    index. Returns ``(-1, SENSE_RANGE)`` when robot k is alone.
    """
    best = -1
    best_gap = 1 << 30
    for j in range(poses.shape[0]):
        if j == k or not active[j]:
            continue
        dr = abs(poses[j, POSE_ROW] - poses[k, POSE_ROW])
        dc = abs(poses[j, POSE_COL] - poses[k, POSE_COL])
        gap = max(dr, dc) - 2
        if gap < 0:
            gap = 0
        if gap < best_gap:
            best_gap = gap
            best = j
    if best < 0:
        return -1, SENSE_RANGE
    return best, best_gap


@nb.njit(cache=True, inline="always")
def relative_bearing(poses, k, j):
    """H1: where robot j lies as seen from robot k (0 ahead, 1 right, 2 behind, 3 left)."""
    h = poses[k, POSE_HEADING]
    dr = poses[j, POSE_ROW] - poses[k, POSE_ROW]
    dc = poses[j, POSE_COL] - poses[k, POSE_COL]
    ahead = dr * FORWARD[h, 0] + dc * FORWARD[h, 1]
    right = dr * RIGHT_STEP[h, 0] + dc * RIGHT_STEP[h, 1]
    if abs(ahead) >= abs(right):
        return AHEAD if ahead > 0 else BEHIND
    return RIGHT if right > 0 else LEFT


@nb.njit(cache=True, inline="always")
def absolute_bearing(poses, k, j):
    """H1, paper reading: the compass bearing of robot j from robot k (0 N, 1 E, 2 S, 3 W).

    The dominant axis of the anchor offset wins; ties go to north / south.
    """
    dr = poses[j, POSE_ROW] - poses[k, POSE_ROW]
    dc = poses[j, POSE_COL] - poses[k, POSE_COL]
    if abs(dr) >= abs(dc):
        return NORTH if dr >= 0 else SOUTH
    return EAST if dc > 0 else WEST


@nb.njit(cache=True, inline="always")
def bearing_code(poses, k, j, h1_frame):
    """H1 of robot k for nearest robot j (-1: alone) in the frame ``h1_frame``.

    A robot alone reads ahead (relative frame) or north (absolute frame), code 0 in both.
    """
    if j < 0:
        return AHEAD if h1_frame == H1_RELATIVE else NORTH
    if h1_frame == H1_ABSOLUTE:
        return absolute_bearing(poses, k, j)
    return relative_bearing(poses, k, j)


@nb.njit(cache=True, inline="always")
def sense(
    heights, zones, goal, poses, active, k, blade, load_volume, stuck, tilted, memory, out, h1_frame
):
    """Fill ``out`` (length 14, integer) with robot k's sensor vector (Table 1).

    Args:
        heights: Soil height per cell, integer soil units (``[rows, cols]``).
        zones: Blueprint zone per cell (0 don't care, 1 dig, 2 dump).
        goal: Goal height per cell (used on dig cells only).
        poses: ``[n_robots, 3]`` rows of ``(row, col, heading)``.
        active: ``[n_robots]`` flags; inactive robots are invisible.
        k: Index of the sensing robot.
        blade: Blade state of robot k (``BLADE_*`` code), B1.
        load_volume: Soil units against the blade (simulator: ``blade_volume``; field:
            the blade force rescaled), gives L1.
        stuck: U1 flag.
        tilted: R1 flag.
        memory: M1 bit.
        out: Output array, length ``N_SENSORS``.
        h1_frame: ``H1_RELATIVE`` or ``H1_ABSOLUTE`` (:mod:`ant_controller.readings`).
    """
    row = poses[k, POSE_ROW]
    col = poses[k, POSE_COL]
    h = poses[k, POSE_HEADING]
    rows = heights.shape[0]
    cols = heights.shape[1]
    for j in range(4):
        r, c = front_cell(row, col, h, j - 1)
        if in_grid(rows, cols, r, c):
            out[Z1 + j] = zone_code(zones[r, c], heights[r, c], goal[r, c])
        else:
            out[Z1 + j] = Z_DONT_CARE
    obstacle = 0
    for i in range(2):
        br, bc = front_cell(row, col, h, i)
        wr, wc = front_wheel(row, col, h, i)
        if not in_grid(rows, cols, br, bc):
            out[E1 + i] = E_LEVEL
            obstacle = 1
            continue
        if occupied_by_other(poses, active, k, br, bc):
            obstacle = 1
        d = heights[br, bc] - heights[wr, wc]
        out[E1 + i] = E_ABOVE if d > 0 else (E_BELOW if d < 0 else E_LEVEL)
    out[B1] = blade
    out[L1] = load_code(load_volume)
    out[S1] = obstacle
    j, gap = nearest_robot(poses, active, k)
    out[D1] = gap if gap < SENSE_RANGE else SENSE_RANGE
    out[H1] = bearing_code(poses, k, j, h1_frame)
    out[R1] = 1 if tilted else 0
    out[U1] = 1 if stuck else 0
    out[M1] = 1 if memory else 0


def sensor_vector(
    heights: np.ndarray,
    zones: np.ndarray,
    goal: np.ndarray,
    poses: np.ndarray,
    k: int,
    *,
    blade: int,
    load_volume: int,
    stuck: bool,
    tilted: bool,
    memory: bool,
    active: np.ndarray | None = None,
    h1_frame: int = H1_RELATIVE,
) -> np.ndarray:
    """Convenience wrapper around :func:`sense` that allocates and returns the vector."""
    out = np.zeros(N_SENSORS, dtype=np.int64)
    if active is None:
        active = np.ones(len(poses), dtype=np.bool_)
    sense(
        np.ascontiguousarray(heights, dtype=np.int32),
        np.ascontiguousarray(zones, dtype=np.uint8),
        np.ascontiguousarray(goal, dtype=np.int32),
        np.ascontiguousarray(poses, dtype=np.int64),
        np.ascontiguousarray(active, dtype=np.bool_),
        k,
        blade,
        load_volume,
        stuck,
        tilted,
        memory,
        out,
        h1_frame,
    )
    return out
