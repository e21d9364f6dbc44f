"""Grid cells and headings <-> the ``map`` frame (REP-103/105: x east, y north, z up).

The one place that converts between grid indices and metres, so that every node agrees:
cell ``(row, col)`` covers ``x in [col, col + 1) * cell_size`` and
``y in [row, row + 1) * cell_size``; the ``map`` origin is the south-west corner of cell
(0, 0). Headings 0 N, 1 E, 2 S, 3 W are yaws pi/2, 0, -pi/2, pi. A robot pose
``(row, col, heading)`` names the south-west cell of its 2 x 2 footprint, so the robot's
centre is the shared corner of its four cells.
"""

from __future__ import annotations

import math

_YAW = (math.pi / 2, 0.0, -math.pi / 2, math.pi)


def cell_center(row: int, col: int, cell_size: float) -> tuple[float, float]:
    """``(x, y)`` in metres of the centre of a cell."""
    return (col + 0.5) * cell_size, (row + 0.5) * cell_size


def map_to_cell(x: float, y: float, cell_size: float) -> tuple[int, int]:
    """The ``(row, col)`` of the cell containing the point ``(x, y)`` (may lie off the grid)."""
    return math.floor(y / cell_size), math.floor(x / cell_size)


def robot_center(row: int, col: int, cell_size: float) -> tuple[float, float]:
    """``(x, y)`` of the centre of a robot whose footprint's south-west cell is ``(row, col)``."""
    return (col + 1) * cell_size, (row + 1) * cell_size


def robot_anchor(x: float, y: float, cell_size: float) -> tuple[int, int]:
    """Footprint anchor ``(row, col)`` of a robot centred nearest to ``(x, y)``."""
    return round(y / cell_size) - 1, round(x / cell_size) - 1


def heading_to_yaw(heading: int) -> float:
    """Yaw in radians (counter-clockwise from +x) of a grid heading."""
    return _YAW[heading % 4]


def yaw_to_heading(yaw: float) -> int:
    """The grid heading nearest to a yaw in radians."""
    quadrant = round(yaw / (math.pi / 2)) % 4  # 0 east, 1 north, 2 west, 3 south
    return (1, 0, 3, 2)[quadrant]
