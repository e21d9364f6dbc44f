"""Laser scans -> a per-cell height map of the worksite (paper, 6.2).

:class:`TerrainMapper` turns the overhead laser's scans into the height map the controllers
read (one value per cell, metres, NaN unknown):

1. **Project** (:meth:`TerrainMapper.add_scan`): every finite return within the scan's
   ``[range_min, range_max]`` becomes a ``map`` point ``mount + origin + range *
   direction`` (:mod:`terrain_mapper.geometry`: the lever arm ``laser_offset_*`` gives the
   beam's origin, ``scanner_flip`` mirrors an upside-down scanner's beams; the pan and tilt
   are one pair for the scan or one per beam, for a mount that moves during the scan); NaN,
   inf and out-of-range returns are dropped and counted.
2. **Bin** (:meth:`TerrainMapper.finish_sweep`): points within ``robot_margin`` of a
   robot's footprint (known poses) are dropped, and so are points closer than
   ``edge_margin`` (a fraction of a cell) to a cell border, where a beam may have hit the
   side of a neighbouring cell; each cell with at least ``min_returns`` points gets the
   median of their heights.
3. **Fuse**: a cell measured again within ``change_threshold`` of its map value is
   averaged with it (up to ``max_count`` sweeps' weight); one that moved further (soil was
   dug or dumped) takes the new value. Cells not measured in a sweep (under a robot, in a
   beam's shadow) keep their value; cells never measured are NaN (unknown), or with
   ``prior_known`` hold ``prior_height`` (the closed-loop trial and the dome use 0: a level
   site surveyed before the robots enter).
4. **Under the robots** (optional, ``robot_height`` > 0): the laser cannot see the cells a
   robot stands on, but it sees the robot's body; the median height of the returns on its
   top, less ``robot_height``, is taken as the soil under it for every footprint cell that
   disagrees with its map value by more than ``change_threshold``.

Pure module (numpy), no ``rclpy``; ``mapper_node`` wraps it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from excavation_common.params import param
from terrain_mapper.errors import MapperError
from terrain_mapper.geometry import beam_rays


@dataclass(frozen=True)
class MapperParams:
    """Grid, mount and estimation settings (``config/mapper.yaml``).

    Attributes:
        rows: Worksite rows.
        cols: Worksite columns.
        cell_size: Metres per cell.
        mount_x: Laser pan/tilt centre, metres east.
        mount_y: Laser pan/tilt centre, metres north.
        mount_z: Laser pan/tilt centre, metres up.
        pan_offset: Mount yaw error, radians (:mod:`terrain_mapper.geometry`).
        tilt_offset: Mount pitch error about the east axis, radians.
        roll_offset: Mount roll error about the north axis, radians.
        edge_margin: Points closer than this fraction of a cell to its border are dropped.
        min_returns: Points a cell needs in a sweep to be measured.
        robot_margin: Points this close (metres) to a robot's footprint are dropped.
        change_threshold: A new value further than this (metres) from the map replaces it.
        max_count: Most sweeps averaged into a cell.
        prior_known: Never-measured cells hold ``prior_height`` (else NaN, unknown).
        prior_height: Value of never-measured cells with ``prior_known`` (metres).
        robot_height: A robot's body top above the soil it stands on (metres); when > 0,
            the footprint cells that disagree with "body top - robot_height" by more than
            ``change_threshold`` take that value (0: cells under robots keep the last
            value seen).
    """

    rows: int = param(16, "worksite rows", low=1, high=4096)
    cols: int = param(16, "worksite columns", low=1, high=4096)
    cell_size: float = param(0.25, "metres per cell", low=1e-3, high=100.0)
    mount_x: float = param(2.0, "laser pan/tilt centre in map, m east")
    mount_y: float = param(2.0, "laser pan/tilt centre in map, m north")
    mount_z: float = param(4.0, "laser pan/tilt centre in map, m up", low=1e-3)
    pan_offset: float = param(0.0, "mount yaw error, rad", low=-0.5, high=0.5)
    tilt_offset: float = param(0.0, "mount pitch error (about east), rad", low=-0.5, high=0.5)
    roll_offset: float = param(0.0, "mount roll error (about north), rad", low=-0.5, high=0.5)
    laser_offset_x: float = param(
        0.0, "m, optical centre from the pan/tilt centre, tilting frame x", low=-2.0, high=2.0
    )
    laser_offset_y: float = param(
        0.0, "m, optical centre from the pan/tilt centre, tilting frame y", low=-2.0, high=2.0
    )
    laser_offset_z: float = param(
        0.0, "m, optical centre from the pan/tilt centre, tilting frame z", low=-2.0, high=2.0
    )
    scanner_flip: bool = param(False, "scanner mounted upside down (beam angles mirrored)")
    edge_margin: float = param(
        0.12, "fraction of a cell: returns nearer a border are dropped", low=0.0, high=0.49
    )
    min_returns: int = param(3, "returns a cell needs in a sweep", low=1, high=100000)
    robot_margin: float = param(0.06, "m around a robot's footprint", low=0.0)
    change_threshold: float = param(0.02, "m; a bigger change replaces a cell's value", low=0.0)
    max_count: int = param(8, "sweeps averaged into a cell at most", low=1, high=100000)
    prior_known: bool = param(False, "never-measured cells hold prior_height (else NaN)")
    prior_height: float = param(0.0, "m, value of never-measured cells with prior_known")
    robot_height: float = param(0.0, "m, body top above the soil (0: not used)", low=0.0)

    @property
    def prior(self) -> float:
        """The value of never-measured cells (NaN: unknown)."""
        return self.prior_height if self.prior_known else math.nan

    @property
    def offsets(self) -> tuple[float, float, float]:
        """``(pan_offset, tilt_offset, roll_offset)``."""
        return (self.pan_offset, self.tilt_offset, self.roll_offset)

    @property
    def lever(self) -> tuple[float, float, float]:
        """``(laser_offset_x, laser_offset_y, laser_offset_z)``: the lever arm."""
        return (self.laser_offset_x, self.laser_offset_y, self.laser_offset_z)


@dataclass(frozen=True)
class SweepStats:
    """What one sweep gave: points used, returns dropped, cells measured and masked."""

    points: int
    invalid: int
    masked: int
    measured: int


def scan_ranges_check(
    n: int, angle_min: float, angle_max: float, angle_increment: float, source: str
) -> None:
    """Raise :class:`MapperError` unless ``n`` ranges fit the scan's angles."""
    if not (math.isfinite(angle_increment) and angle_increment > 0):
        raise MapperError(source, "angle_increment", angle_increment, "must be > 0")
    if not (math.isfinite(angle_min) and math.isfinite(angle_max) and angle_max >= angle_min):
        raise MapperError(source, "angle_min/angle_max", (angle_min, angle_max), "bad interval")
    expected = int(round((angle_max - angle_min) / angle_increment)) + 1
    if n != expected:
        raise MapperError(source, "ranges", f"{n} values", f"angles give {expected} beams")


def scan_timing_check(
    n: int, time_increment: float, scan_time: float, source: str
) -> np.ndarray | None:
    """Each beam's time after the scan's stamp, integer ns (None: all at the stamp).

    ``time_increment`` (``sensor_msgs/LaserScan``) is the time between neighbouring beams:
    beam ``i`` is taken ``i * time_increment`` after the stamp (0: every beam at the
    stamp, one mount pose for the scan; negative: the beams were taken last to first).
    ``scan_time`` is the time from one scan to the next; when it is given (> 0) the scan's
    beams must fit into it, ``|time_increment| * (n - 1) <= scan_time``.

    Raises:
        MapperError: A ``time_increment`` that is not finite, or beams spanning more time
            than ``scan_time``.
    """
    if time_increment == 0.0:
        return None
    if not math.isfinite(time_increment):
        raise MapperError(source, "time_increment", time_increment, "must be finite")
    span = abs(time_increment) * max(n - 1, 0)
    if math.isfinite(scan_time) and scan_time > 0 and span > scan_time * (1 + 1e-3) + 1e-6:
        raise MapperError(
            source,
            "time_increment",
            time_increment,
            f"{n} beams span {span:.6g} s, longer than scan_time {scan_time:.6g} s",
        )
    return np.round(np.arange(n) * (time_increment * 1e9)).astype(np.int64)


class TerrainMapper:
    """Scans in, fused height map out (see the module docstring)."""

    def __init__(self, params: MapperParams | None = None) -> None:
        """An empty map (``prior_height`` everywhere)."""
        self.params = p = params or MapperParams()
        self.heights = np.full((p.rows, p.cols), p.prior, dtype=np.float64)
        self.counts = np.zeros((p.rows, p.cols), dtype=np.int64)
        self.mount = np.array([p.mount_x, p.mount_y, p.mount_z])
        self._points: list[np.ndarray] = []
        self.invalid = 0
        self.scans = 0

    def add_scan(
        self,
        ranges: np.ndarray,
        angle_min: float,
        angle_increment: float,
        range_min: float,
        range_max: float,
        pan: float | np.ndarray,
        tilt: float | np.ndarray,
    ) -> int:
        """Project one scan's valid returns into the current sweep.

        Args:
            ranges: The scan's ranges, metres.
            angle_min: Scan angle of the first beam, radians.
            angle_increment: Scan angle between beams, radians.
            range_min: Shorter returns are invalid.
            range_max: Longer returns are invalid.
            pan: The mount's pan, radians: one for the scan, or one per beam (``[n]``,
                a mount that moved while the scan was taken).
            tilt: The mount's tilt, radians: one, or one per beam.

        Returns:
            The number of valid returns (0 for a scan with none).
        """
        p = self.params
        r = np.asarray(ranges, dtype=np.float64)
        angles = angle_min + angle_increment * np.arange(len(r))
        with np.errstate(invalid="ignore"):
            ok = np.isfinite(r) & (r >= range_min) & (r <= range_max)
        self.invalid += int(len(r) - ok.sum())
        self.scans += 1
        if ok.any():
            if np.ndim(pan) or np.ndim(tilt):  # per beam
                pan = np.broadcast_to(pan, r.shape)[ok]
                tilt = np.broadcast_to(tilt, r.shape)[ok]
            origins, dirs = beam_rays(pan, tilt, angles[ok], p.offsets, p.lever, p.scanner_flip)
            if np.ndim(origins) == 1 and not origins.any():
                self._points.append(self.mount + r[ok, None] * dirs)
            else:
                self._points.append(self.mount + origins + r[ok, None] * dirs)
        return int(ok.sum())

    def finish_sweep(self, robots: list[tuple[float, float, float]] = ()) -> SweepStats:
        """Bin the sweep's points, fuse them into the map and start a new sweep.

        Args:
            robots: Known robot poses ``(x, y, yaw)`` (centre of the 2 x 2 footprint).
        """
        p = self.params
        pts = np.concatenate(self._points) if self._points else np.zeros((0, 3))
        invalid = self.invalid
        self._points, self.invalid = [], 0
        keep = np.ones(len(pts), dtype=bool)
        half = p.cell_size + p.robot_margin
        bodies = []
        for x, y, yaw in robots:
            c, s = math.cos(yaw), math.sin(yaw)
            dx, dy = pts[:, 0] - x, pts[:, 1] - y
            along, across = np.abs(c * dx + s * dy), np.abs(-s * dx + c * dy)
            on_robot = (along <= half) & (across <= half)
            keep &= ~on_robot
            top = (along <= 0.8 * p.cell_size) & (across <= 0.8 * p.cell_size)
            if p.robot_height > 0 and top.sum() >= p.min_returns:
                bodies.append((x, y, float(np.median(pts[top, 2])) - p.robot_height))
        masked = int((~keep).sum())
        u = pts[:, 0] / p.cell_size
        v = pts[:, 1] / p.cell_size
        col, row = np.floor(u).astype(np.int64), np.floor(v).astype(np.int64)
        fu, fv = u - col, v - row
        m = p.edge_margin
        keep &= (fu >= m) & (fu <= 1 - m) & (fv >= m) & (fv <= 1 - m)
        keep &= (row >= 0) & (row < p.rows) & (col >= 0) & (col < p.cols)
        idx = row[keep] * p.cols + col[keep]
        z = pts[keep, 2]
        measured = self._fuse(idx, z)
        for x, y, ground in bodies:
            self._under_robot(x, y, ground)
        return SweepStats(int(keep.sum()), invalid, masked, measured)

    def _under_robot(self, x: float, y: float, ground: float) -> None:
        """Footprint cells that disagree with the body's height take the body's ground."""
        p = self.params
        r0, c0 = round(y / p.cell_size) - 1, round(x / p.cell_size) - 1
        for r in range(max(r0, 0), min(r0 + 2, p.rows)):
            for c in range(max(c0, 0), min(c0 + 2, p.cols)):
                old = self.heights[r, c]
                if not math.isfinite(old) or abs(old - ground) > p.change_threshold:
                    self.heights[r, c] = ground
                    self.counts[r, c] = 1

    def _fuse(self, idx: np.ndarray, z: np.ndarray) -> int:
        """Median per cell of this sweep, fused into the map; returns the cells measured."""
        p = self.params
        if len(idx) == 0:
            return 0
        order = np.lexsort((z, idx))
        idx, z = idx[order], z[order]
        cells, start, count = np.unique(idx, return_index=True, return_counts=True)
        enough = count >= p.min_returns
        cells, start, count = cells[enough], start[enough], count[enough]
        median = 0.5 * (z[start + (count - 1) // 2] + z[start + count // 2])
        flat_h = self.heights.reshape(-1)
        flat_n = self.counts.reshape(-1)
        old, n = flat_h[cells], flat_n[cells]
        with np.errstate(invalid="ignore"):
            reset = ~np.isfinite(old) | (n == 0) | (np.abs(median - old) > p.change_threshold)
        fused = np.where(reset, median, (old * n + median) / (n + 1))
        flat_h[cells] = fused
        flat_n[cells] = np.where(reset, 1, np.minimum(n + 1, p.max_count))
        return int(len(cells))

    def height_map(self) -> np.ndarray:
        """The fused map, ``float32 [rows, cols]`` metres, NaN unknown."""
        return self.heights.astype(np.float32)
