"""The simulated world's current truth, as the emulated camera and laser see it (pure).

The emulated sensors render what the world is *now*, whenever their own clocks say a frame
or a scan is due: they keep the latest pose of every robot and the latest height map, not
a snapshot of one instant (which the simulator's own ``sensors`` node renders). Messages are
parsed by the nodes; this module holds the values and turns them into what
:mod:`excavation_sim.camera` and :mod:`excavation_sim.laser` take.
"""

from __future__ import annotations

import math

import numpy as np

from dome_emulator.errors import TruthError
from excavation_common.frames import robot_anchor
from excavation_sim.camera import RobotView


def yaw_of(qx: float, qy: float, qz: float, qw: float) -> float:
    """Yaw (radians about z) of a quaternion."""
    return math.atan2(2 * (qw * qz + qx * qy), 1 - 2 * (qy * qy + qz * qz))


class Truth:
    """The latest pose of each robot and the latest height map (metres)."""

    def __init__(self, robots: int, rows: int, cols: int, cell_size: float) -> None:
        """An empty truth for ``robots`` robots on a ``rows`` x ``cols`` site."""
        self.robots = robots
        self.rows = rows
        self.cols = cols
        self.cell_size = cell_size
        self.poses: dict[int, tuple[float, float, float]] = {}  # k -> (x, y, yaw)
        self.heights: np.ndarray | None = None  # [rows, cols] metres

    def set_pose(self, k: int, x: float, y: float, yaw: float, source: str = "<pose>") -> None:
        """Robot ``k``'s pose in ``map``.

        Raises:
            TruthError: A non-finite value.
        """
        if not all(math.isfinite(v) for v in (x, y, yaw)):
            raise TruthError(source, "pose", (x, y, yaw), "must be finite")
        self.poses[k] = (float(x), float(y), float(yaw))

    def set_heights(self, grid: np.ndarray, source: str = "<height_map>") -> None:
        """The soil heights, metres.

        Raises:
            TruthError: A grid of another size than the site's, or with non-finite cells.
        """
        grid = np.asarray(grid, dtype=np.float64)
        if grid.shape != (self.rows, self.cols):
            raise TruthError(
                source,
                "shape",
                grid.shape,
                f"the emulator is set up for {self.rows} x {self.cols} cells (rows, cols)",
            )
        if not np.isfinite(grid).all():
            raise TruthError(source, "data", "non-finite cells", "the world's heights are known")
        self.heights = grid

    def missing(self) -> list[int]:
        """Robots whose pose has not come yet."""
        return [k for k in range(self.robots) if k not in self.poses]

    def ground(self) -> np.ndarray:
        """The heights, or a flat floor at 0 while none has come."""
        if self.heights is None:
            return np.zeros((self.rows, self.cols))
        return self.heights

    def anchors(self) -> np.ndarray:
        """Footprint anchors ``(row, col)`` of the robots with a pose, ``int [n, 2]``."""
        out = [robot_anchor(*self.poses[k][:2], self.cell_size) for k in sorted(self.poses)]
        return np.array(out, dtype=np.int64).reshape(-1, 2)

    def views(self) -> list[RobotView]:
        """The camera's view of robots 0 .. n - 1 (each must have a pose) on the ground."""
        heights = self.ground()
        out = []
        for k in range(self.robots):
            x, y, yaw = self.poses[k]
            r, c = robot_anchor(x, y, self.cell_size)
            block = heights[max(r, 0) : r + 2, max(c, 0) : c + 2]
            out.append(RobotView(x, y, yaw, float(block.mean()) if block.size else 0.0))
        return out
