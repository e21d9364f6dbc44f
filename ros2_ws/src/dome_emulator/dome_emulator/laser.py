"""A tilting laser scanner on a nodding mount, on its own clock (pure).

The dome's laser is two devices: a line scanner that sends a ``sensor_msgs/LaserScan`` per
turn of its mirror, and a pan/tilt mount that nods the scan plane up and down and reports
its joints. Neither waits for the other, and each stamps its messages with its own clock;
the mapper pairs them by stamp (``terrain_mapper.mount_sync``). :class:`LaserCore` is both:

* **The nod.** The tilt runs from ``tilt_min`` to ``tilt_max`` and back at a steady rate,
  without stopping: a triangle wave whose half period is ``sweep_scans`` scan periods, so
  every nod from one end to the other holds exactly ``sweep_scans`` scans (the mapper's
  sweep), the first of each at the end the nod starts from.
* **Scans.** Scan ``j`` starts ``j / scan_rate`` seconds after the device starts and is
  stamped then; its beam ``i`` is taken ``i * time_increment`` later, while the mount nods
  on, and the scan is handed over once its last beam is in. ``(beams - 1) *
  time_increment`` must fit in one scan period (a mirror turn), so no scan spans a turn of
  the nod.
* **Mount states.** Every ``1 / mount_rate`` seconds, stamped with the instant its angles
  are read; a ``JointState`` under the joint names ``pan_joint`` and ``tilt_joint``.
* **Rendering.** Each scan traces the world's current heights (the latest height map, the
  robots raised on their footprints by ``robot_height``) with excavation_sim's laser model,
  :class:`excavation_sim.laser.OverheadLaser`: one model for each direction of the nod,
  its ``tilt_rate`` the nod's, so the model puts beam ``i`` where the nodding mount
  points it. Scans wait for the world's first height map; the mount nods regardless.

The device clock is the node clock at start plus the time since (:meth:`LaserCore.due`
takes the node clock, ns): stamps are evenly spaced whatever the timers' jitter. A device
that falls behind by more than ``max_backlog`` seconds drops what it could not send, as a
driver's full buffer does. All noise comes from one generator seeded by ``seed``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dome_emulator.truth import Truth
from excavation_common.params import param
from excavation_sim.laser import LaserParams, OverheadLaser, surface_with_robots
from terrain_mapper.geometry import PAN_JOINT, TILT_JOINT


@dataclass(frozen=True)
class LaserEmulatorParams:
    """The emulated laser's parameters (the scanner's default to :class:`LaserParams`)."""

    robots: int = param(4, "team size (robots raised on their footprints)", low=0, high=64)
    truth_prefix: str = param(
        "/truth", "prefix of the world's poses (robot_k/pose) and height map (worksite/height_map)"
    )
    rows: int = param(16, "grid rows", low=2, high=4096)
    cols: int = param(16, "grid columns", low=2, high=4096)
    cell_size: float = param(0.25, "m per grid cell", low=1e-3, high=100.0)
    mount: tuple[float, ...] = param(
        LaserParams.mount, "pan/tilt centre (x, y, z) in map, m (the site's laser.mount)"
    )
    pan: float = param(LaserParams.pan, "the pan joint's angle, rad", low=-3.15, high=3.15)
    angle_min: float = param(LaserParams.angle_min, "first beam's angle, rad", low=-3.15)
    angle_max: float = param(LaserParams.angle_max, "last beam's angle, rad", high=3.15)
    beams: int = param(LaserParams.beams, "beams per scan", low=2, high=100_000)
    tilt_min: float = param(LaserParams.tilt_min, "the nod's lower end, rad", low=-1.5)
    tilt_max: float = param(LaserParams.tilt_max, "the nod's upper end, rad", high=1.5)
    sweep_scans: int = param(
        LaserParams.sweep_scans, "scans per nod from one end to the other", low=2, high=100_000
    )
    scan_rate: float = param(40.0, "scans per second (mirror turns)", low=0.1, high=1000.0)
    time_increment: float = param(
        0.0001, "s between neighbouring beams of a scan", low=0.0, high=1.0
    )
    mount_rate: float = param(100.0, "mount states per second", low=1.0, high=1000.0)
    range_min: float = param(LaserParams.range_min, "shortest range reported, m", low=0.0)
    range_max: float = param(LaserParams.range_max, "longest range reported, m", low=0.01)
    range_noise: float = param(LaserParams.range_noise, "range noise (std), m", low=0.0, high=10.0)
    dropout: float = param(LaserParams.dropout, "share of beams lost", low=0.0, high=1.0)
    robot_height: float = param(
        LaserParams.robot_height, "a robot's body above its footprint, m", low=0.0, high=10.0
    )
    lever: tuple[float, ...] = param(
        LaserParams.lever, "optical centre off the pan/tilt centre in the tilting frame, m"
    )
    flip: bool = param(LaserParams.flip, "the scanner is mounted upside down")
    pan_joint: str = param(PAN_JOINT, "the pan joint's name in the mount's JointState")
    tilt_joint: str = param(TILT_JOINT, "the tilt joint's name in the mount's JointState")
    frame_id: str = param("overhead_laser", "frame of the scans")
    seed: int = param(0, "noise seed", low=0, high=2**63 - 1)
    max_backlog: float = param(
        0.5, "s: scans and mount states this far behind are dropped", low=0.01, high=60.0
    )
    diagnostics_period: float = param(1.0, "s between diagnostics", low=0.05, high=3600.0)

    def check(self) -> None:
        """Whole scans within a mirror turn; a nod that moves; three-vectors."""
        if (self.beams - 1) * self.time_increment > 1.0 / self.scan_rate:
            raise ValueError(
                f"(beams - 1) x time_increment = {(self.beams - 1) * self.time_increment:.6f} s"
                f" does not fit in one scan period (1 / scan_rate = {1.0 / self.scan_rate:.6f} s)"
            )
        if not self.tilt_min < self.tilt_max:
            raise ValueError(f"tilt_min {self.tilt_min} must be below tilt_max {self.tilt_max}")
        if not self.angle_min < self.angle_max:
            raise ValueError(f"angle_min {self.angle_min} must be below angle_max {self.angle_max}")
        if not self.range_min < self.range_max:
            raise ValueError(f"range_min {self.range_min} must be below range_max {self.range_max}")
        for name in ("mount", "lever"):
            if len(getattr(self, name)) != 3:
                raise ValueError(f"{name} needs three values (x, y, z), got {getattr(self, name)}")

    @property
    def scan_period(self) -> float:
        """Seconds between scans."""
        return 1.0 / self.scan_rate

    @property
    def nod_period(self) -> float:
        """Seconds for one nod from one end to the other."""
        return self.sweep_scans * self.scan_period

    def tilt_at(self, t: float) -> float:
        """The mount's tilt ``t`` seconds after the device started (the triangle wave)."""
        u = (t / self.nod_period) % 2.0
        frac = u if u < 1.0 else 2.0 - u
        return self.tilt_min + (self.tilt_max - self.tilt_min) * frac

    def scan_tilt(self, j: int) -> tuple[float, bool]:
        """``(tilt, rising)`` at the start of scan ``j`` (exact at the nod's ends)."""
        rising = (j // self.sweep_scans) % 2 == 0
        step = (self.tilt_max - self.tilt_min) * (j % self.sweep_scans) / self.sweep_scans
        return (self.tilt_min + step, True) if rising else (self.tilt_max - step, False)

    def model(self, rising: bool) -> LaserParams:
        """excavation_sim's laser for one direction of the nod (its ``tilt_rate`` the nod's).

        The model's sweep runs ``tilt_min`` to ``tilt_max`` (swapped when falling) in
        ``sweep_scans`` scans ``scan_period`` apart, so its ``tilt_rate`` is ``range /
        ((sweep_scans - 1) scan_period)``; the nod covers the range in ``sweep_scans`` scan
        periods, so the model's ``scan_period`` is stretched by ``sweep_scans / (sweep_scans
        - 1)``.
        """
        low, high = (self.tilt_min, self.tilt_max) if rising else (self.tilt_max, self.tilt_min)
        return LaserParams(
            mount=tuple(self.mount),
            pan=self.pan,
            angle_min=self.angle_min,
            angle_max=self.angle_max,
            beams=self.beams,
            tilt_min=low,
            tilt_max=high,
            sweep_scans=self.sweep_scans,
            range_min=self.range_min,
            range_max=self.range_max,
            range_noise=self.range_noise,
            dropout=self.dropout,
            robot_height=self.robot_height,
            lever=tuple(self.lever),
            flip=self.flip,
            time_increment=self.time_increment,
            scan_period=self.nod_period / (self.sweep_scans - 1),
            pan_joint=self.pan_joint,
            tilt_joint=self.tilt_joint,
        )


@dataclass(frozen=True)
class Scan:
    """One scan: its stamp (its first beam), the tilt then, and the ranges (m, ``float32``)."""

    stamp_ns: int
    tilt: float
    ranges: np.ndarray


@dataclass(frozen=True)
class MountState:
    """The mount's joints at ``stamp_ns``."""

    stamp_ns: int
    pan: float
    tilt: float


Output = Scan | MountState


class LaserCore:
    """The scanner and its nodding mount (module docstring)."""

    def __init__(self, params: LaserEmulatorParams, start_ns: int) -> None:
        """A device started at ``start_ns`` of the node clock."""
        self.params = params
        self.start_ns = start_ns
        self.rng = np.random.default_rng(params.seed)
        self.truth = Truth(params.robots, params.rows, params.cols, params.cell_size)
        self.lasers = {
            rising: OverheadLaser(params.model(rising), params.cell_size)
            for rising in (True, False)
        }
        self.angles = self.lasers[True].params.angles()
        self.next_scan = 0  # index of the next scan
        self.next_mount = 0  # index of the next mount state
        self.scans = 0
        self.mount_states = 0
        self.waiting = 0  # scans not taken for want of a height map
        self.dropped = 0  # scans and mount states dropped behind max_backlog

    def scan_stamp(self, j: int) -> int:
        """Stamp of scan ``j``, ns."""
        return self.start_ns + int(round(j * self.params.scan_period * 1e9))

    def mount_stamp(self, m: int) -> int:
        """Stamp of mount state ``m``, ns."""
        return self.start_ns + int(round(m / self.params.mount_rate * 1e9))

    def due(self, now_ns: int) -> list[Output]:
        """Everything finished by ``now_ns``, in stamp order."""
        p = self.params
        backlog_ns = int(round(p.max_backlog * 1e9))
        last_beam_ns = int(round((p.beams - 1) * p.time_increment * 1e9))
        out: list[Output] = []
        self.skip_backlog(now_ns - backlog_ns)
        while self.mount_stamp(self.next_mount) <= now_ns:
            stamp = self.mount_stamp(self.next_mount)
            self.next_mount += 1
            if now_ns - stamp > backlog_ns:
                self.dropped += 1
                continue
            t = (stamp - self.start_ns) * 1e-9
            out.append(MountState(stamp, p.pan, p.tilt_at(t)))
            self.mount_states += 1
        while self.scan_stamp(self.next_scan) + last_beam_ns <= now_ns:
            j, stamp = self.next_scan, self.scan_stamp(self.next_scan)
            self.next_scan += 1
            if now_ns - stamp > backlog_ns:
                self.dropped += 1
                continue
            scan = self.render(j)
            if scan is not None:
                out.append(scan)
        out.sort(key=lambda o: o.stamp_ns)
        return out

    def skip_backlog(self, oldest_ns: int) -> None:
        """Drop at once what is older than ``oldest_ns`` (a long stall, or a clock jump)."""
        p = self.params
        first_mount = max(0, -(-(oldest_ns - self.start_ns) * p.mount_rate // 1e9))
        first_scan = max(0, -(-(oldest_ns - self.start_ns) * p.scan_rate // 1e9))
        for name, first in (("next_mount", int(first_mount)), ("next_scan", int(first_scan))):
            behind = first - getattr(self, name) - 1  # the one at the edge is judged below
            if behind > 0:
                self.dropped += behind
                setattr(self, name, getattr(self, name) + behind)

    def render(self, j: int) -> Scan | None:
        """Scan ``j`` of the world's current heights (None: no height map yet)."""
        heights = self.truth.heights
        if heights is None:
            self.waiting += 1
            return None
        p = self.params
        tilt, rising = p.scan_tilt(j)
        surface = surface_with_robots(heights, self.truth.anchors(), p.robot_height)
        ranges = self.lasers[rising].scan(surface, tilt, self.rng)
        self.scans += 1
        return Scan(self.scan_stamp(j), tilt, ranges)
