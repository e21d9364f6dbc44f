"""Terrain mapper core: projection, robust binning, robot masks, fusion, bad scans."""

from __future__ import annotations

import math

import numpy as np
import pytest

from excavation_common.frames import robot_center
from excavation_sim.laser import LaserParams, OverheadLaser, surface_with_robots
from terrain_mapper.errors import MapperError
from terrain_mapper.mapper import MapperParams, TerrainMapper, scan_ranges_check

CELL, UNIT = 0.25, 0.05
LASER = LaserParams()


def terrain(seed: int) -> np.ndarray:
    """Pits and berms, -3 .. +4 soil units, in metres."""
    rng = np.random.default_rng(seed)
    return rng.integers(-3, 5, (16, 16)) * UNIT


def sweep_into(mapper, heights, anchors=(), rng=None, laser=LASER, per_beam=True):
    """One sweep of ``laser`` into ``mapper``; with ``per_beam`` each beam's own tilt."""
    scanner = OverheadLaser(laser, CELL)
    surface = surface_with_robots(heights, np.array(anchors, dtype=int).reshape(-1, 2), 0.2)
    for pan, tilt, ranges in scanner.sweep(surface, rng or np.random.default_rng(0)):
        mapper.add_scan(
            ranges,
            laser.angle_min,
            laser.angle_increment,
            laser.range_min,
            laser.range_max,
            pan,
            laser.beam_tilts(tilt) if per_beam else tilt,
        )
    poses = [(*robot_center(r, c, CELL), 0.0) for r, c in anchors]
    return mapper.finish_sweep(poses)


def test_one_sweep_rmse_under_a_quarter_unit():
    for seed in range(3):
        heights = terrain(seed)
        anchors = [(2, 3), (9, 9), (12, 1), (5, 12)]
        mapper = TerrainMapper()
        stats = sweep_into(mapper, heights, anchors, np.random.default_rng(seed))
        est = mapper.height_map()
        known = np.isfinite(est)
        under = np.zeros((16, 16), dtype=bool)
        for r, c in anchors:
            under[r : r + 2, c : c + 2] = True
        assert not known[under].any()  # robots are masked, never mapped as soil
        assert known[~under].mean() > 0.97
        rmse = math.sqrt(np.mean((est[known] - heights[known]) ** 2)) / UNIT
        assert rmse < 0.25
        assert stats.masked > 0 and stats.invalid > 0 and stats.measured == known.sum()


def test_without_masks_robots_would_be_soil():
    heights = np.zeros((16, 16))
    mapper = TerrainMapper()
    scanner = OverheadLaser(LaserParams(range_noise=0.0, dropout=0.0), CELL)
    for pan, tilt, ranges in scanner.sweep(
        surface_with_robots(heights, np.array([[7, 7]]), 0.2), np.random.default_rng(0)
    ):
        mapper.add_scan(ranges, LASER.angle_min, LASER.angle_increment, 0.1, 8.0, pan, tilt)
    mapper.finish_sweep([])
    assert mapper.height_map()[7:9, 7:9] == pytest.approx(0.2, abs=1e-4)


def test_prior_holds_cells_never_seen_and_fusion_follows_changes():
    heights = terrain(5)
    mapper = TerrainMapper(MapperParams(prior_known=True, prior_height=0.0))
    sweep_into(mapper, heights, [(7, 7)])
    assert np.all(mapper.height_map()[7:9, 7:9] == 0.0)
    first = mapper.height_map().copy()
    heights2 = heights.copy()
    heights2[3, 3] -= 2 * UNIT  # dug
    sweep_into(mapper, heights2, [(7, 7)], np.random.default_rng(1))
    est = mapper.height_map()
    assert est[3, 3] == pytest.approx(heights2[3, 3], abs=0.25 * UNIT)
    steady = np.ones((16, 16), dtype=bool)
    steady[3, 3] = False
    steady[7:9, 7:9] = False
    assert mapper.counts[steady].min() >= 2  # averaged over both sweeps
    assert np.abs(est - heights2)[steady].max() <= np.abs(first - heights)[steady].max() + 1e-3


def test_nan_inf_and_out_of_range_returns_are_dropped():
    mapper = TerrainMapper()
    ranges = np.array([np.nan, np.inf, -np.inf, 0.01, 50.0, 4.0, 4.0, 4.0], dtype=np.float32)
    valid = mapper.add_scan(ranges, -0.01, 0.002, 0.1, 8.0, 0.0, 0.0)
    assert valid == 3 and mapper.invalid == 5
    assert mapper.add_scan(np.full(8, np.nan), -0.01, 0.002, 0.1, 8.0, 0.0, 0.0) == 0
    stats = mapper.finish_sweep()
    assert stats.invalid == 13


def test_a_sweep_with_no_valid_return_changes_nothing():
    mapper = TerrainMapper(MapperParams(prior_known=True, prior_height=0.0))
    mapper.add_scan(np.full(241, np.inf), -0.5, 1 / 240, 0.1, 8.0, 0.0, 0.0)
    assert mapper.finish_sweep().measured == 0
    assert np.all(mapper.height_map() == 0.0) and not mapper.counts.any()


def test_scan_layout_is_checked():
    scan_ranges_check(241, -0.5, 0.5, 1 / 240, "scan")
    with pytest.raises(MapperError, match="ranges = '10 values': angles give 241 beams"):
        scan_ranges_check(10, -0.5, 0.5, 1 / 240, "scan")
    with pytest.raises(MapperError, match="angle_increment = 0.0"):
        scan_ranges_check(10, -0.5, 0.5, 0.0, "scan")


def test_tilted_mount_elsewhere_is_followed():
    """A mount moved and panned: the mapper uses the same geometry, heights still right."""
    laser = LaserParams(mount=(1.5, 2.5, 4.5), pan=0.3, range_noise=0.0, dropout=0.0)
    heights = terrain(9)
    mapper = TerrainMapper(MapperParams(mount_x=1.5, mount_y=2.5, mount_z=4.5))
    sweep_into(mapper, heights, [], laser=laser)
    est = mapper.height_map()
    known = np.isfinite(est)
    assert known.mean() > 0.8
    assert np.abs(est[known] - heights[known]).max() < 1e-3


def test_the_mappers_default_mount_is_the_simulated_lasers():
    """mapper.yaml itself is checked with every node's file (tests/test_node_params.py)."""
    from terrain_mapper.mapper import MapperParams
    from terrain_mapper.params import MapperNodeParams

    assert MapperParams().mount_z == LaserParams().mount[2]
    assert MapperNodeParams().sweep_scans == LaserParams().sweep_scans


def test_body_height_stands_in_for_the_cells_under_a_robot():
    heights = np.zeros((16, 16))
    heights[7:9, 7:9] = -2 * UNIT  # the robot drove into a pit the map saw as level
    mapper = TerrainMapper(MapperParams(prior_known=True, prior_height=0.0, robot_height=0.2))
    sweep_into(mapper, heights, [(7, 7)])
    assert mapper.height_map()[7:9, 7:9] == pytest.approx(-2 * UNIT, abs=0.25 * UNIT)
    blind = TerrainMapper(MapperParams(prior_known=True, prior_height=0.0))
    sweep_into(blind, heights, [(7, 7)])
    assert np.all(blind.height_map()[7:9, 7:9] == 0.0)


# --- a real scanner: lever arm, upside down, beams taken while the mount nods -------------

EXACT = dict(range_noise=0.0, dropout=0.0)
LEVER = (0.03, -0.05, -0.12)


def max_error(mapper, heights) -> float:
    est = mapper.height_map()
    known = np.isfinite(est)
    assert known.mean() > 0.95
    return float(np.abs(est[known] - heights[known]).max())


@pytest.mark.parametrize("lever, flip", [(LEVER, False), ((0.0, 0.0, 0.0), True), (LEVER, True)])
def test_lever_arm_and_upside_down_scanner_are_mapped_back(lever, flip):
    """A scanner off the tilt axis, upside down, panned: with both set, the true heights."""
    laser = LaserParams(lever=lever, flip=flip, pan=0.2, **EXACT)
    heights = terrain(11)
    x, y, z = lever
    params = MapperParams(laser_offset_x=x, laser_offset_y=y, laser_offset_z=z, scanner_flip=flip)
    mapper = TerrainMapper(params)
    sweep_into(mapper, heights, laser=laser)
    assert max_error(mapper, heights) < 1e-3
    naive = TerrainMapper()  # today's mapper: the beams from the axis, upright
    sweep_into(naive, heights, laser=laser)
    assert max_error(naive, heights) > 0.1


def test_beams_taken_while_the_mount_nods_are_mapped_with_their_own_tilt():
    laser = LaserParams(time_increment=2**-15, **EXACT)  # 241 beams in 7.4 ms of a 10 ms scan
    heights = terrain(12)
    mapper = TerrainMapper()
    sweep_into(mapper, heights, laser=laser)
    assert max_error(mapper, heights) < 1e-3
    one_tilt = TerrainMapper()  # every beam at the tilt of the scan's stamp
    sweep_into(one_tilt, heights, laser=laser, per_beam=False)
    assert max_error(one_tilt, heights) > 0.02
