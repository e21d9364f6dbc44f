"""The mapper node: sweeps in, latched height map out; bad scans are reported."""

from __future__ import annotations

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus
from helpers.rigs import LASER, MapperRig

from excavation_common.messages import image_to_grid
from excavation_sim.laser import OverheadLaser
from terrain_mapper.geometry import PAN_JOINT


def test_a_sweep_gives_a_map_stamped_with_its_first_scan(ros):
    rig = MapperRig(ros)
    heights = np.random.default_rng(0).integers(-3, 4, (16, 16)) * 0.05
    rig.sweep(100, heights, np.random.default_rng(1))
    assert ros.spin_until(lambda: rig.maps)
    msg = rig.maps[0]
    assert msg.header.stamp.sec == 100 and msg.encoding == "32FC1"
    grid = image_to_grid(msg, "32FC1", shape=(16, 16))
    known = np.isfinite(grid)
    assert known.mean() > 0.5
    assert np.sqrt(np.mean((grid[known] - heights[known]) ** 2)) < 0.25 * 0.05


def test_scans_without_valid_returns_publish_nothing(ros):
    rig = MapperRig(ros)
    for i, tilt in enumerate(LASER.tilts()):
        rig.send(10 + i, [np.inf] * LASER.beams, tilt)
    assert ros.spin_until(rig.reported(DiagnosticStatus.WARN, "has no valid return"))
    assert ros.spin_until(rig.reported(DiagnosticStatus.WARN, "sweep measured no cell"))
    assert not rig.maps
    rig.sweep(50, np.zeros((16, 16)), np.random.default_rng(0))  # still running
    assert ros.spin_until(lambda: rig.maps)


def test_malformed_scan_and_mount_are_reported(ros):
    rig = MapperRig(ros)
    rig.send(1, [1.0] * LASER.beams, 0.0, n=10)
    assert ros.spin_until(rig.reported(DiagnosticStatus.ERROR, "ranges = '10 values'"))
    rig.send(2, [1.0] * LASER.beams, 0.0, joints=(PAN_JOINT,))
    assert ros.spin_until(rig.reported(DiagnosticStatus.ERROR, "has no 'laser_tilt' joint"))
    ros.spin_until(lambda: False, 0.3)
    assert not rig.maps and rig.mapper.core.scans == 0


def test_a_lost_scan_does_not_shift_later_sweeps(ros):
    rig = MapperRig(ros)
    laser = OverheadLaser(LASER, 0.25)
    scans = laser.sweep(np.zeros((16, 16)), np.random.default_rng(0))
    for start in (100, 200, 300):
        for i, (_, tilt, ranges) in enumerate(scans):
            if not (start == 200 and i == 5):  # scan 5 of the second sweep is lost
                rig.send(start + i, ranges, tilt)
    assert ros.spin_until(lambda: len(rig.maps) == 3)
    assert [m.header.stamp.sec for m in rig.maps] == [100, 200, 300]
    assert rig.mapper.short_sweeps == 1


def test_a_first_sweep_joined_mid_way_is_start_up_not_a_fault(ros):
    """The mount nods before the mapper comes up, so the first sweep it sees is short
    (too short for a map here): it is said at INFO and not counted (the mapper cannot tell
    it from a first sweep that lost a scan; from the second sweep on, a short one is a
    fault)."""
    rig = MapperRig(ros)
    laser = OverheadLaser(LASER, 0.25)
    scans = laser.sweep(np.zeros((16, 16)), np.random.default_rng(0))
    for i, (_, tilt, ranges) in enumerate(scans[20:]):  # joined at scan 20
        rig.send(200 + i, ranges, tilt)
    for i, (_, tilt, ranges) in enumerate(scans):
        rig.send(300 + i, ranges, tilt)
    assert ros.spin_until(lambda: rig.maps and rig.maps[-1].header.stamp.sec == 300)
    assert rig.mapper.short_sweeps == 0 and "sweep_size" not in rig.mapper.problems
    assert "sweep" not in rig.mapper.problems  # it measured nothing: said at INFO
