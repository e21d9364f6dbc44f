"""Synthetic overhead laser: a line scanner on a pan/tilt mount sweeping the site (paper, 6.2).

The dome's soil heights came from periodic scans of an overhead laser range finder.
:class:`OverheadLaser` produces those scans from the simulator's truth: the worksite is a
height field of flat-topped cells (soil heights in metres; the dome floor around it is at
ground level) with the robots as boxes standing on their 2 x 2 footprints, and every beam
is traced through it exactly (a grid walk, :func:`trace`). One sweep steps the tilt from
``tilt_min`` to ``tilt_max`` in ``sweep_scans`` scans; each scan is the ranges of one
``sensor_msgs/LaserScan`` plus the pan and tilt it was taken at (the mount geometry is
:mod:`terrain_mapper.geometry`, shared with the mapper).

Noise: Gaussian range noise (``range_noise``); a share ``dropout`` of beams return nothing,
half of them reported as NaN (no echo measured) and half as +inf (out of range, the
LaserScan convention); beams that hit nothing within ``range_max`` are +inf. All random
draws come from the ``numpy.random.Generator`` passed in. Pure module (numpy, numba).

A real scanner on a real mount, on demand (the defaults are the ideal scanner above): a
lever arm (``lever``: the optical centre off the pan/tilt centre, in the tilting frame),
a scanner mounted upside down (``flip``), beams taken one after the other while the mount
keeps nodding (``time_increment`` seconds between beams, the tilt moving steadily by one
scan's step every ``scan_period``), and other names of the mount's joints (``pan_joint``,
``tilt_joint``, for whoever publishes its JointState).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from terrain_mapper.geometry import PAN_JOINT, TILT_JOINT, beam_directions, beam_rays


@dataclass(frozen=True)
class LaserParams:
    """The scanner, its mount and its noise.

    Attributes:
        mount: Pan/tilt centre ``(x, y, z)`` in ``map``, metres.
        pan: Pan angle during the sweep, radians.
        angle_min: First beam's scan angle, radians.
        angle_max: Last beam's scan angle, radians.
        beams: Beams per scan.
        tilt_min: Tilt of the first scan of a sweep, radians.
        tilt_max: Tilt of the last scan of a sweep, radians.
        sweep_scans: Scans per sweep.
        range_min: Shortest range reported, metres.
        range_max: Longest range reported, metres.
        range_noise: Range noise, standard deviation, metres.
        dropout: Share of beams without a return.
        robot_height: Height of a robot's body above its footprint's highest soil, metres.
        lever: The optical centre off the pan/tilt centre ``(x, y, z)`` in the tilting
            frame (``map`` axes at pan = tilt = 0), metres.
        flip: The scanner is mounted upside down (beam ``a`` goes where ``-a`` would).
        time_increment: Seconds between neighbouring beams of a scan (0: all at once).
        scan_period: Seconds between the scans of a sweep: the tilt moves steadily from
            one scan's tilt to the next in this time (matters with ``time_increment``).
        pan_joint: Name of the mount's pan joint in its JointState.
        tilt_joint: Name of the mount's tilt joint.
    """

    mount: tuple[float, float, float] = (2.0, 2.0, 4.0)
    pan: float = 0.0
    angle_min: float = -0.5
    angle_max: float = 0.5
    beams: int = 241
    tilt_min: float = -0.5
    tilt_max: float = 0.5
    sweep_scans: int = 64
    range_min: float = 0.1
    range_max: float = 8.0
    range_noise: float = 0.008
    dropout: float = 0.01
    robot_height: float = 0.2
    lever: tuple[float, float, float] = (0.0, 0.0, 0.0)
    flip: bool = False
    time_increment: float = 0.0
    scan_period: float = 0.01
    pan_joint: str = PAN_JOINT
    tilt_joint: str = TILT_JOINT

    @classmethod
    def for_site(cls, rows: int, cols: int, cell_size: float, **kwargs) -> LaserParams:
        """The default laser for a ``rows`` x ``cols`` site.

        The mount is over the centre, as high as the site is wide; at least 15 beams and 4
        scans per cell (the defaults are this for the 16 x 16 default site).
        """
        w, d = cols * cell_size, rows * cell_size
        kwargs.setdefault("beams", max(241, 15 * cols + 1))
        kwargs.setdefault("sweep_scans", max(64, 4 * rows))
        return cls(mount=(w / 2, d / 2, max(w, d)), **kwargs)

    @property
    def angle_increment(self) -> float:
        """Angle between neighbouring beams, radians."""
        return (self.angle_max - self.angle_min) / (self.beams - 1)

    def angles(self) -> np.ndarray:
        """Scan angles of the beams."""
        return self.angle_min + self.angle_increment * np.arange(self.beams)

    def tilts(self) -> np.ndarray:
        """Tilt of every scan of a sweep (at the scan's stamp, its first beam)."""
        return np.linspace(self.tilt_min, self.tilt_max, self.sweep_scans)

    @property
    def tilt_rate(self) -> float:
        """How fast the mount tilts during a sweep, radians per second."""
        return (self.tilt_max - self.tilt_min) / ((self.sweep_scans - 1) * self.scan_period)

    def tilt_at(self, t: float) -> float:
        """The mount's tilt ``t`` seconds after the sweep's first scan (steady motion)."""
        return self.tilt_min + self.tilt_rate * t

    def beam_tilts(self, tilt: float) -> float | np.ndarray:
        """Tilt of every beam of the scan whose first beam is at ``tilt``.

        The one ``tilt`` when ``time_increment`` is 0; else ``[beams]``, beam ``i`` taken
        ``i * time_increment`` later while the mount moves at :attr:`tilt_rate`.
        """
        if self.time_increment == 0.0:
            return tilt
        return tilt + self.tilt_rate * self.time_increment * np.arange(self.beams)


@numba.njit(cache=True)
def trace(surface, cell, origin, dirs, range_max, out):  # pragma: no cover - numba
    """Distance along each unit direction to the first surface hit (inf if none).

    ``surface[r, c]`` is the top of cell ``(r, c)`` (metres); everything off the grid is
    at height 0. Walks the cells the ray's ground track crosses; a ray hits the top of a
    cell where it comes down through it, or the side of a cell it enters below its top.
    """
    rows, cols = surface.shape
    ox, oy, oz = origin[0], origin[1], origin[2]
    for i in range(dirs.shape[0]):
        dx, dy, dz = dirs[i, 0], dirs[i, 1], dirs[i, 2]
        out[i] = np.inf
        if dz >= 0.0:
            continue
        c = math.floor(ox / cell)
        r = math.floor(oy / cell)
        step_c = 1 if dx > 0 else -1
        step_r = 1 if dy > 0 else -1
        if dx != 0.0:
            next_x = (c + (1 if dx > 0 else 0)) * cell
            t_x = (next_x - ox) / dx
            dt_x = cell / abs(dx)
        else:
            t_x = np.inf
            dt_x = np.inf
        if dy != 0.0:
            next_y = (r + (1 if dy > 0 else 0)) * cell
            t_y = (next_y - oy) / dy
            dt_y = cell / abs(dy)
        else:
            t_y = np.inf
            dt_y = np.inf
        t = 0.0
        while t <= range_max:
            top = surface[r, c] if (0 <= r < rows and 0 <= c < cols) else 0.0
            if oz + t * dz < top:  # entered through the side of a higher cell
                out[i] = t
                break
            t_exit = min(t_x, t_y)
            if oz + t_exit * dz <= top:  # comes down onto this cell's top
                out[i] = (top - oz) / dz
                break
            t = t_exit
            if t_x < t_y:
                t_x += dt_x
                c += step_c
            else:
                t_y += dt_y
                r += step_r
        if out[i] > range_max:
            out[i] = np.inf


@numba.njit(cache=True)
def trace_rays(surface, cell, origins, dirs, range_max, out):  # pragma: no cover - numba
    """:func:`trace` for beams each with its own origin (``origins[i]``, ``[n, 3]``)."""
    for i in range(dirs.shape[0]):
        trace(surface, cell, origins[i], dirs[i : i + 1], range_max, out[i : i + 1])


def surface_with_robots(
    heights_m: np.ndarray, anchors: np.ndarray, robot_height: float, scale: int = 1
) -> np.ndarray:
    """Soil heights with every robot's 2 x 2 footprint raised to its body's top.

    Args:
        heights_m: Soil heights, metres, ``[rows, cols]`` (cells, or sub-cells ``scale``
            to a cell's side).
        anchors: Robots' footprint anchors ``(row, col)`` in the rows of ``heights_m``,
            ``int [n, 2]``.
        robot_height: Body height above the footprint's highest soil, metres.
        scale: Rows of ``heights_m`` per grid cell (a footprint is ``2 * scale`` square).
    """
    surface = np.array(heights_m, dtype=np.float64)
    size = 2 * scale
    for r, c in np.asarray(anchors, dtype=np.int64).reshape(-1, 2):
        block = surface[max(r, 0) : r + size, max(c, 0) : c + size]
        ground = np.asarray(heights_m)[max(r, 0) : r + size, max(c, 0) : c + size]
        if block.size:
            block[...] = ground.max() + robot_height
    return surface


class OverheadLaser:
    """Sweeps of the overhead laser over a height field (see the module docstring)."""

    def __init__(self, params: LaserParams | None = None, cell_size: float = 0.25) -> None:
        """A laser over a grid of ``cell_size`` metre cells."""
        self.params = params or LaserParams()
        self.cell_size = float(cell_size)
        self._angles = self.params.angles()

    def scan(self, surface: np.ndarray, tilt: float, rng: np.random.Generator) -> np.ndarray:
        """Ranges (``float32 [beams]``) of one scan at ``tilt`` over ``surface``.

        ``tilt`` is the mount's tilt at the scan's first beam; with ``time_increment`` the
        later beams see the mount further on (:meth:`LaserParams.beam_tilts`).
        """
        p = self.params
        surface = np.ascontiguousarray(surface, dtype=np.float64)
        mount = np.asarray(p.mount, dtype=np.float64)
        if p.time_increment == 0.0 and not any(p.lever) and not p.flip:
            dirs = beam_directions(p.pan, tilt, self._angles)
            ranges = np.empty(len(dirs))
            trace(surface, self.cell_size, mount, dirs, p.range_max, ranges)
        else:
            origins, dirs = beam_rays(
                p.pan, p.beam_tilts(tilt), self._angles, lever=p.lever, flip=p.flip
            )
            origins = np.ascontiguousarray(np.broadcast_to(mount + origins, dirs.shape))
            ranges = np.empty(len(dirs))
            trace_rays(surface, self.cell_size, origins, dirs, p.range_max, ranges)
        ranges = ranges + rng.normal(0.0, p.range_noise, len(ranges))
        lost = rng.random(len(ranges)) < p.dropout
        nan = rng.random(len(ranges)) < 0.5
        ranges[lost & nan] = np.nan
        ranges[lost & ~nan] = np.inf
        ranges[ranges < p.range_min] = np.nan
        return ranges.astype(np.float32)

    def sweep(
        self, surface: np.ndarray, rng: np.random.Generator
    ) -> list[tuple[float, float, np.ndarray]]:
        """One sweep: ``(pan, tilt, ranges)`` for every scan, tilt from min to max."""
        return [
            (self.params.pan, float(t), self.scan(surface, t, rng)) for t in self.params.tilts()
        ]
