"""The mapper node against a real tilting laser (a LaserScan driver on a nodding mount).

Every sweep here is rendered by the synthetic laser with the real scanner's quirks on
(other joint names, a lever arm, upside down, beams taken while the mount moves, a clock
offset) and without noise, so a mapper told about them maps the true heights (to 1 mm);
today's mapper, which knew none of them, does not.
"""

from __future__ import annotations

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticStatus
from helpers.rigs import MapperRig

from excavation_common.messages import image_to_grid
from excavation_sim.laser import LaserParams, OverheadLaser
from terrain_mapper.geometry import PAN_JOINT, TILT_JOINT

EPOCH_S = 100
SCANS = 64
EXACT = dict(sweep_scans=SCANS, range_noise=0.0, dropout=0.0)
LEVER = (0.03, -0.05, -0.12)
NOD = 2**-15  # s between beams: 241 beams in 7.4 ms of a 10 ms scan


class Rig(MapperRig):
    """The mapper rig (tests/helpers/rigs.py) with sweeps of 64 scans and a real laser's
    messages: mount states with both joints, scans with their beam timing."""

    def __init__(self, ros, **params):
        super().__init__(ros, **({"sweep_scans": SCANS, "mount_wait": 0.5} | params))

    def mount_at(self, t_ns: int, pan: float, tilt: float, joints=(PAN_JOINT, TILT_JOINT)) -> None:
        """A mount state stamped ``t_ns`` after the epoch."""
        from sensor_msgs.msg import JointState

        msg = JointState(name=list(joints), position=[pan, tilt])
        msg.header.stamp = self.stamp(t_ns)
        self.mount_pub.publish(msg)

    def scan_of(self, t_ns: int, ranges, laser: LaserParams, time_increment=None, scan_time=None):
        """A scan stamped ``t_ns`` after the epoch, laid out as ``laser``'s."""
        from sensor_msgs.msg import LaserScan

        msg = LaserScan()
        msg.header.stamp = self.stamp(t_ns)
        msg.header.frame_id = "overhead_laser"
        msg.angle_min, msg.angle_max = laser.angle_min, laser.angle_max
        msg.angle_increment = laser.angle_increment
        msg.time_increment = laser.time_increment if time_increment is None else time_increment
        msg.scan_time = laser.scan_period if scan_time is None else scan_time
        msg.range_min, msg.range_max = laser.range_min, laser.range_max
        msg.ranges = [float(r) for r in ranges]
        self.scan_pub.publish(msg)

    def sweep_of(self, laser: LaserParams, heights, clock_lag: float = 0.0) -> None:
        """One sweep of ``laser`` over ``heights``: its mount's states at every scan's start
        and one more after the last, named as the laser's joints; the scans stamped by the
        scanner's clock, ``clock_lag`` seconds behind the mount's."""
        period = int(round(laser.scan_period * 1e9))
        lag = int(round(clock_lag * 1e9))
        scans = OverheadLaser(laser, 0.25).sweep(heights, np.random.default_rng(0))
        joints = (laser.pan_joint, laser.tilt_joint)
        for i, (pan, _, ranges) in enumerate(scans):
            self.mount_at(i * period, pan, laser.tilt_at(i * laser.scan_period), joints)
            self.scan_of(i * period - lag, ranges, laser)
        end = len(scans) * laser.scan_period
        self.mount_at(len(scans) * period, laser.pan, laser.tilt_at(end), joints)

    def grid(self) -> np.ndarray:
        """The first map, once published."""
        assert self.ros.spin_until(lambda: self.maps)
        return image_to_grid(self.maps[0], "32FC1", shape=(16, 16))

    def reported(self, level, text: str):
        return lambda: (
            self.status is not None and self.status.level == level and text in self.status.message
        )


def terrain(seed: int) -> np.ndarray:
    return np.random.default_rng(seed).integers(-3, 5, (16, 16)) * 0.05


def max_error(grid: np.ndarray, heights: np.ndarray) -> float:
    known = np.isfinite(grid)
    assert known.mean() > 0.95
    return float(np.abs(grid[known] - heights[known]).max())


# --- 1. mount joint names --------------------------------------------------------------


def test_mount_joint_names_are_parameters(ros):
    rig = Rig(ros, pan_joint="ptu/pan", tilt_joint="ptu/tilt")
    heights = terrain(1)
    rig.sweep_of(LaserParams(pan_joint="ptu/pan", tilt_joint="ptu/tilt", **EXACT), heights)
    assert max_error(rig.grid(), heights) < 1e-3
    rig.mount_at(10**9, 0.0, 0.0)  # laser_pan, laser_tilt: not this mount's joints
    assert ros.spin_until(
        rig.reported(DiagnosticStatus.ERROR, "has no 'ptu/pan' joint (the pan_joint)")
    )
    assert "laser_tilt" in rig.status.message  # the names the state did have


def test_one_joint_for_pan_and_tilt_is_refused(ros):
    from rclpy.parameter import Parameter

    from excavation_common.params import ParameterError
    from terrain_mapper.mapper_node import MapperNode

    same = [Parameter("pan_joint", value="ptu"), Parameter("tilt_joint", value="ptu")]
    with pytest.raises(ParameterError, match="tilt_joint = 'ptu': is also the pan_joint"):
        MapperNode(context=ros.context, parameter_overrides=same)


# --- 2. lever arm and an upside-down scanner ----------------------------------------------


def test_lever_arm_and_upside_down_scanner(ros):
    x, y, z = LEVER
    rig = Rig(ros, laser_offset_x=x, laser_offset_y=y, laser_offset_z=z, scanner_flip=True)
    heights = terrain(2)
    rig.sweep_of(LaserParams(lever=LEVER, flip=True, **EXACT), heights)
    assert max_error(rig.grid(), heights) < 1e-3


# --- 3. beams taken while the mount nods -------------------------------------------------


def test_every_beam_gets_the_mount_angles_of_its_own_time(ros):
    rig = Rig(ros)
    heights = terrain(3)
    rig.sweep_of(LaserParams(time_increment=NOD, **EXACT), heights)
    # one tilt for the whole scan (the stamp's) is up to 4 cm off at the cell borders
    assert max_error(rig.grid(), heights) < 1e-3
    assert rig.mapper.unbracketed == 0


def test_beam_timing_that_does_not_fit_the_scan_is_reported(ros):
    rig = Rig(ros)
    laser = LaserParams(**EXACT)
    rig.mount_at(0, 0.0, 0.0)
    rig.scan_of(0, [4.0] * laser.beams, laser, time_increment=1e-3, scan_time=0.01)
    assert ros.spin_until(
        rig.reported(DiagnosticStatus.ERROR, "241 beams span 0.24 s, longer than scan_time 0.01 s")
    )
    rig.scan_of(1, [4.0] * laser.beams, laser, time_increment=float("nan"))
    assert ros.spin_until(rig.reported(DiagnosticStatus.ERROR, "time_increment = nan"))
    assert rig.mapper.core.scans == 0 and not rig.mapper.scans


# --- 4. the scanner's clock against the mount's ------------------------------------------


def test_scan_stamp_offset_moves_scans_onto_the_mount_clock(ros):
    rig = Rig(ros, scan_stamp_offset=0.04)
    heights = terrain(4)
    rig.sweep_of(LaserParams(**EXACT), heights, clock_lag=0.04)  # 4 scans' worth of tilt
    assert max_error(rig.grid(), heights) < 1e-3
    stamp = rig.maps[0].header.stamp  # the map is stamped on the mount's clock
    assert (stamp.sec, stamp.nanosec) == (EPOCH_S, 0)


# --- all of them at once ------------------------------------------------------------------


def test_a_real_laser_with_every_quirk_at_once(ros):
    x, y, z = LEVER
    rig = Rig(
        ros,
        pan_joint="ptu_pan_joint",
        tilt_joint="ptu_tilt_joint",
        laser_offset_x=x,
        laser_offset_y=y,
        laser_offset_z=z,
        scanner_flip=True,
        scan_stamp_offset=-0.013,
    )
    laser = LaserParams(
        pan=0.15,
        lever=LEVER,
        flip=True,
        time_increment=NOD,
        pan_joint="ptu_pan_joint",
        tilt_joint="ptu_tilt_joint",
        **EXACT,
    )
    heights = terrain(5)
    rig.sweep_of(laser, heights, clock_lag=-0.013)  # the scanner's clock 13 ms ahead
    assert max_error(rig.grid(), heights) < 1e-3
