"""``ros2 run terrain_mapper calibrate_mount``: the laser mount's offsets from a flat floor.

Before the soil goes in (or on a flat stretch of the dome floor) the laser sweeps a floor
whose height is known (``--floor``, 0 by default). Every return then should lie at that
height; a mount whose base is not level makes the floor look tilted. :func:`fit_offsets`
finds the mount's ``tilt_offset`` (pitch about east) and ``roll_offset`` (roll about north)
and, with ``--fit-height``, the mount's height, that make the measured floor flattest and
at the right height (Gauss-Newton on the returns' heights, with returns further than
``--outlier`` from the floor, such as a box or a person, dropped). A yaw error
(``pan_offset``) leaves a flat floor flat, so it is not fitted: measure it against a
landmark and give it with ``--pan-offset``.

The sweep comes from a bag (``--bag DIR``: the laser's ``LaserScan`` and the mount's
``JointState`` topics, paired by interpolating the mount angles to each scan's stamp as the
mapper does) or live (``--live --scans N``). The result is printed as the ``laser:`` lines of
a site file (``docs/dome.md``) and, with ``--out``, written as YAML.

A real scanner is described as the mapper's parameters describe it: ``--pan-joint`` /
``--tilt-joint`` (the mount's joint names), ``--laser-offset X Y Z`` (the lever arm),
``--flip`` (upside down), ``--stamp-offset`` (seconds added to the scans' stamps); a scan
with ``time_increment`` gets the mount's angles beam by beam.

Examples::

    ros2 run terrain_mapper calibrate_mount --bag floor_sweep --mount 2.0 2.0 4.0
    ros2 run terrain_mapper calibrate_mount --live --scans 64 --mount 2.0 2.0 4.0 --fit-height
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from excavation_common.errors import FieldError
from excavation_common.files import write_text_atomic
from terrain_mapper.errors import MapperError
from terrain_mapper.geometry import NO_LEVER, PAN_JOINT, TILT_JOINT, beam_rays
from terrain_mapper.mapper import scan_timing_check
from terrain_mapper.mount_sync import MountSync


@dataclass(frozen=True)
class Scan:
    """One scan with the mount angles at its stamp: ranges and their scan angles.

    ``pan`` and ``tilt`` are one pair for the scan or one per beam (arrays).
    """

    pan: float | np.ndarray
    tilt: float | np.ndarray
    angles: np.ndarray
    ranges: np.ndarray


@dataclass(frozen=True)
class MountFit:
    """What :func:`fit_offsets` found.

    Attributes:
        tilt_offset: Mount pitch error about east, radians.
        roll_offset: Mount roll error about north, radians.
        mount_z: Mount height (the given one unless fitted), metres.
        rms_before: RMS of the floor returns' heights from the floor, offsets zero, m.
        rms_after: ... with the fitted offsets, m.
        points: Returns used.
        dropped: Returns dropped as not on the floor.
    """

    tilt_offset: float
    roll_offset: float
    mount_z: float
    rms_before: float
    rms_after: float
    points: int
    dropped: int


def _points(scans, mount, offsets, lever=NO_LEVER, flip=False) -> np.ndarray:
    out = []
    for s in scans:
        ok = np.isfinite(s.ranges)
        pan = np.broadcast_to(s.pan, ok.shape)[ok] if np.ndim(s.pan) else s.pan
        tilt = np.broadcast_to(s.tilt, ok.shape)[ok] if np.ndim(s.tilt) else s.tilt
        origins, dirs = beam_rays(pan, tilt, s.angles[ok], offsets, lever, flip)
        out.append(np.asarray(mount) + origins + s.ranges[ok, None] * dirs)
    return np.concatenate(out) if out else np.zeros((0, 3))


def _valid(scans: list[Scan], range_min: float, range_max: float) -> list[Scan]:
    out = []
    for s in scans:
        r = np.asarray(s.ranges, dtype=np.float64)
        with np.errstate(invalid="ignore"):
            r = np.where(np.isfinite(r) & (r >= range_min) & (r <= range_max), r, np.nan)
        out.append(Scan(s.pan, s.tilt, np.asarray(s.angles, dtype=np.float64), r))
    return out


def fit_offsets(
    scans: list[Scan],
    mount: tuple[float, float, float],
    floor: float = 0.0,
    pan_offset: float = 0.0,
    fit_height: bool = False,
    outlier: float = 0.05,
    range_min: float = 0.0,
    range_max: float = math.inf,
    lever: tuple[float, float, float] = NO_LEVER,
    flip: bool = False,
) -> MountFit:
    """Tilt and roll offsets (and the height) that put a flat floor's returns at ``floor``.

    Args:
        scans: The sweep, each scan with the mount angles at its stamp.
        mount: The mount's pan/tilt centre ``(x, y, z)`` in ``map`` (``z`` a first guess
            with ``fit_height``).
        floor: The floor's height in ``map``, metres.
        pan_offset: The mount's yaw error (not fitted), radians.
        fit_height: Also fit the mount's height.
        outlier: Returns further than this (metres) from the floor once fitted are dropped.
        range_min: Shorter returns are dropped.
        range_max: Longer returns are dropped.
        lever: The scanner's lever arm in the tilting frame (the mapper's
            ``laser_offset_*``), metres.
        flip: The scanner is upside down (the mapper's ``scanner_flip``).

    Raises:
        ValueError: Fewer than 10 usable returns, or a fit that does not converge.
    """
    scans = _valid(scans, range_min, range_max)
    x, y, z0 = (float(v) for v in mount)
    theta = np.array([0.0, 0.0, z0])  # tilt, roll, height
    free = [0, 1, 2] if fit_height else [0, 1]

    def residual(t: np.ndarray, keep=None) -> np.ndarray:
        pts = _points(scans, (x, y, t[2]), (pan_offset, t[0], t[1]), lever, flip)
        res = pts[:, 2] - floor
        return res if keep is None else res[keep]

    start = residual(theta)
    if len(start) < 10:
        raise ValueError(f"{len(start)} usable returns: a floor sweep needs at least 10")
    keep = np.ones(len(start), dtype=bool)
    for _ in range(3):  # fit, drop what is not floor, fit again
        for _ in range(30):
            r = residual(theta, keep)
            jac = np.empty((len(r), len(free)))
            for j, i in enumerate(free):
                step = np.zeros(3)
                step[i] = 1e-6
                jac[:, j] = (residual(theta + step, keep) - r) / 1e-6
            delta = np.linalg.lstsq(jac, -r, rcond=None)[0]
            theta[free] += delta
            if np.abs(delta).max() < 1e-10:
                break
        keep = np.abs(residual(theta)) <= outlier
        if keep.sum() < 10:
            raise ValueError(f"only {int(keep.sum())} returns lie within {outlier} m of the floor")
    if not np.isfinite(theta).all() or max(abs(theta[0]), abs(theta[1])) > 0.5:
        raise ValueError(f"the fit did not converge (tilt, roll = {theta[:2].tolist()})")
    final = residual(theta, keep)
    before_keep = np.abs(start) <= max(outlier, 3 * float(np.sqrt(np.mean(start**2))))
    return MountFit(
        float(theta[0]),
        float(theta[1]),
        float(theta[2]),
        float(np.sqrt(np.mean(start[before_keep] ** 2))),
        float(np.sqrt(np.mean(final**2))),
        int(keep.sum()),
        int((~keep).sum()),
    )


def _stamp_ns(stamp) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def pair_scans(
    scan_msgs,
    mount_msgs,
    max_gap: float = 0.2,
    joints: tuple[str, str] = (PAN_JOINT, TILT_JOINT),
    stamp_offset: float = 0.0,
) -> tuple[list[Scan], int]:
    """Scans with the mount angles interpolated to their stamps; and how many had none.

    ``scan_msgs`` and ``mount_msgs`` are LaserScan and JointState messages (duck-typed);
    ``joints`` names the mount's pan and tilt joints; ``stamp_offset`` seconds are added to
    every scan's stamp. A scan with ``time_increment`` gets the angles beam by beam; one
    whose beam timing is malformed counts as missed.
    """
    pan_joint, tilt_joint = joints
    sync = MountSync(int(max_gap * 1e9), keep=10**7)
    for m in sorted(mount_msgs, key=lambda m: _stamp_ns(m.header.stamp)):
        names = list(m.name)
        if pan_joint in names and tilt_joint in names:
            sync.add(
                _stamp_ns(m.header.stamp),
                float(m.position[names.index(pan_joint)]),
                float(m.position[names.index(tilt_joint)]),
            )
    offset = int(round(stamp_offset * 1e9))
    out, missed = [], 0
    for s in scan_msgs:
        stamp = _stamp_ns(s.header.stamp) + offset
        try:
            beams = scan_timing_check(
                len(s.ranges),
                float(getattr(s, "time_increment", 0.0)),
                float(getattr(s, "scan_time", 0.0)),
                "scan",
            )
        except MapperError:
            missed += 1
            continue
        found = sync.lookup(stamp) if beams is None else sync.lookup_beams(stamp + beams)
        if found.status != "ok":
            missed += 1
            continue
        angles = s.angle_min + s.angle_increment * np.arange(len(s.ranges))
        r = np.asarray(s.ranges, dtype=np.float64)
        with np.errstate(invalid="ignore"):
            r = np.where((r >= s.range_min) & (r <= s.range_max), r, np.nan)
        out.append(Scan(found.pan, found.tilt, angles, r))
    return out, missed


def read_bag(path: str, scan_topic: str, mount_topic: str) -> tuple[list, list]:
    """LaserScan and JointState messages of a rosbag2 directory (MCAP or SQLite).

    Raises:
        MapperError: The bag cannot be read or lacks one of the topics.
    """
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    scans, mounts = [], []
    try:
        with Reader(path) as reader:
            topics = {c.topic for c in reader.connections}
            for topic in (scan_topic, mount_topic):
                if topic not in topics:
                    raise MapperError(path, "topics", sorted(topics), f"has no {topic}")
            wanted = [c for c in reader.connections if c.topic in (scan_topic, mount_topic)]
            for conn, _, raw in reader.messages(connections=wanted):
                msg = store.deserialize_cdr(raw, conn.msgtype)
                (scans if conn.topic == scan_topic else mounts).append(msg)
    except MapperError:
        raise
    except Exception as exc:  # rosbags raises several unrelated types for unreadable bags
        raise MapperError(path, "<bag>", path, f"cannot be read: {exc}") from None
    return scans, mounts


def read_live(
    scan_topic: str, mount_topic: str, n_scans: int, timeout: float, stamp_offset: float = 0.0
) -> tuple[list, list]:
    """``n_scans`` scans and the mount states around them, from the running laser.

    It waits for a mount state after the last scan's last beam (its stamp plus
    ``stamp_offset`` plus its beams' time).

    Raises:
        MapperError: Fewer scans arrived within ``timeout`` seconds.
    """
    import time

    import rclpy
    from rclpy.node import Node
    from sensor_msgs.msg import JointState, LaserScan

    from excavation_common.ros import SENSOR_DATA, init_rclpy

    init_rclpy()
    scans, mounts = [], []
    try:
        node = Node("calibrate_mount")
        node.create_subscription(LaserScan, scan_topic, scans.append, SENSOR_DATA)
        node.create_subscription(JointState, mount_topic, mounts.append, SENSOR_DATA)
        deadline = time.monotonic() + timeout

        def last_beam(s) -> int:
            span = abs(s.time_increment) * max(len(s.ranges) - 1, 0)
            return _stamp_ns(s.header.stamp) + int(round((stamp_offset + span) * 1e9))

        # one mount state more than the last scan, so the last scan is bracketed
        while time.monotonic() < deadline and not (
            len(scans) >= n_scans
            and mounts
            and _stamp_ns(mounts[-1].header.stamp) >= last_beam(scans[n_scans - 1])
        ):
            rclpy.spin_once(node, timeout_sec=0.05)
        node.destroy_node()
    finally:
        rclpy.try_shutdown()
    if len(scans) < n_scans:
        raise MapperError(scan_topic, "scans", len(scans), f"{n_scans} expected in {timeout} s")
    return scans[:n_scans], mounts


def site_lines(fit: MountFit, mount: tuple[float, float, float], pan_offset: float) -> str:
    """The fit as the ``laser:`` lines of a site file."""
    doc = {
        "mount": [round(float(mount[0]), 4), round(float(mount[1]), 4), round(fit.mount_z, 4)],
        "offsets": {
            "pan": round(float(pan_offset), 6),
            "tilt": round(fit.tilt_offset, 6),
            "roll": round(fit.roll_offset, 6),
        },
    }
    return yaml.safe_dump({"laser": doc}, sort_keys=False, default_flow_style=None)


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ros2 run terrain_mapper calibrate_mount``."""
    from rclpy.utilities import remove_ros_args

    argv = sys.argv[1:] if argv is None else argv
    p = argparse.ArgumentParser(prog="calibrate_mount", description=__doc__.split("\n\n")[0])
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--bag", metavar="DIR", help="a recorded floor sweep")
    src.add_argument("--live", action="store_true", help="record a sweep from the laser now")
    p.add_argument("--mount", nargs=3, type=float, required=True, metavar=("X", "Y", "Z"))
    p.add_argument("--scan-topic", default="/worksite/scan")
    p.add_argument("--mount-topic", default="/worksite/laser_mount/joint_states")
    p.add_argument("--pan-joint", default=PAN_JOINT, help="the mount's pan joint")
    p.add_argument("--tilt-joint", default=TILT_JOINT, help="the mount's tilt joint")
    p.add_argument(
        "--laser-offset",
        nargs=3,
        type=float,
        default=list(NO_LEVER),
        metavar=("X", "Y", "Z"),
        help="the scanner's lever arm in the tilting frame, m (laser_offset_x/y/z)",
    )
    p.add_argument("--flip", action="store_true", help="the scanner is upside down")
    p.add_argument("--stamp-offset", type=float, default=0.0, help="s added to every scan's stamp")
    p.add_argument("--scans", type=int, default=64, help="--live: scans to record (a sweep)")
    p.add_argument("--timeout", type=float, default=30.0, help="--live: seconds to wait")
    p.add_argument("--floor", type=float, default=0.0, help="the floor's height in map, m")
    p.add_argument("--pan-offset", type=float, default=0.0, help="measured yaw error, rad")
    p.add_argument("--fit-height", action="store_true", help="also fit the mount's height")
    p.add_argument("--outlier", type=float, default=0.05, help="m from the floor: not floor")
    p.add_argument("--out", metavar="FILE", help="write the result as YAML")
    args = p.parse_args(remove_ros_args(["calibrate_mount", *argv])[1:])
    try:
        if args.bag:
            scan_msgs, mount_msgs = read_bag(args.bag, args.scan_topic, args.mount_topic)
        else:
            scan_msgs, mount_msgs = read_live(
                args.scan_topic, args.mount_topic, args.scans, args.timeout, args.stamp_offset
            )
        scans, missed = pair_scans(
            scan_msgs,
            mount_msgs,
            joints=(args.pan_joint, args.tilt_joint),
            stamp_offset=args.stamp_offset,
        )
        fit = fit_offsets(
            scans,
            tuple(args.mount),
            args.floor,
            args.pan_offset,
            args.fit_height,
            args.outlier,
            lever=tuple(args.laser_offset),
            flip=args.flip,
        )
    except (FieldError, ValueError, OSError) as exc:
        print(f"calibrate_mount: error: {exc}", file=sys.stderr)
        return 2
    print(
        f"calibrate_mount: {len(scans)} scans ({missed} without mount state), {fit.points} "
        f"floor returns ({fit.dropped} dropped); floor RMS {fit.rms_before * 1000:.1f} mm "
        f"-> {fit.rms_after * 1000:.1f} mm",
        file=sys.stderr,
    )
    text = site_lines(fit, tuple(args.mount), args.pan_offset)
    print(text, end="")
    if args.out:
        write_text_atomic(Path(args.out), text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
