"""The synthetic overhead laser (excavation_sim.laser) and the mount geometry."""

from __future__ import annotations

import numpy as np
import pytest

from excavation_sim.laser import LaserParams, OverheadLaser, surface_with_robots
from terrain_mapper.geometry import beam_directions, beam_rays, mount_rotation, tilting_rotation


def test_mount_axes():
    down, east = beam_directions(0.0, 0.0, [0.0, np.pi / 2])
    assert np.allclose(down, [0, 0, -1]) and np.allclose(east, [1, 0, 0])
    (tilted,) = beam_directions(0.0, 0.3, [0.0])
    assert tilted[1] > 0  # positive tilt looks north
    (panned,) = beam_directions(np.pi / 2, 0.0, [np.pi / 2])
    assert np.allclose(panned, [0, 1, 0])
    rot = mount_rotation(0.2, -0.4)
    assert np.allclose(rot @ rot.T, np.eye(3)) and np.isclose(np.linalg.det(rot), 1)


def noiseless(**kw):
    return OverheadLaser(LaserParams(range_noise=0.0, dropout=0.0, **kw), 0.25)


def test_flat_ground_ranges_are_exact():
    laser = noiseless()
    ranges = laser.scan(np.zeros((16, 16)), 0.2, np.random.default_rng(0))
    dirs = beam_directions(0.0, 0.2, laser.params.angles())
    assert np.allclose(ranges, 4.0 / -dirs[:, 2], atol=1e-5)


def test_raised_cell_top_and_side():
    laser = noiseless()
    surface = np.zeros((16, 16))
    surface[8, 8] = 0.5  # the cell just north-east of the mount's foot
    ranges = laser.scan(surface, 0.0, np.random.default_rng(0))  # scan plane y = 2.0
    hit = laser.params.mount + ranges[:, None] * beam_directions(0, 0, laser.params.angles())
    on_top = (hit[:, 0] > 2.0) & (hit[:, 0] < 2.25)
    assert np.allclose(hit[on_top, 2], 0.5, atol=1e-6)
    assert np.all(hit[:, 2] >= -1e-6)


def test_robots_are_in_the_way():
    laser = noiseless()
    heights = np.zeros((16, 16))
    surface = surface_with_robots(heights, np.array([[7, 7]]), 0.2)
    assert surface[7:9, 7:9].min() == pytest.approx(0.2) and surface.sum() == pytest.approx(0.8)
    free = laser.scan(heights, 0.0, np.random.default_rng(0))
    blocked = laser.scan(surface, 0.0, np.random.default_rng(0))
    assert (blocked < free - 0.15).sum() > 20


def test_noise_dropouts_and_determinism():
    laser = OverheadLaser(LaserParams(dropout=0.1), 0.25)
    sweep_a = laser.sweep(np.zeros((16, 16)), np.random.default_rng(3))
    sweep_b = laser.sweep(np.zeros((16, 16)), np.random.default_rng(3))
    assert len(sweep_a) == 64
    ranges = np.concatenate([r for _, _, r in sweep_a])
    assert np.array_equal(ranges, np.concatenate([r for _, _, r in sweep_b]), equal_nan=True)
    assert 0.03 < np.isnan(ranges).mean() < 0.07 and 0.03 < np.isinf(ranges).mean() < 0.07
    exact = noiseless().scan(np.zeros((16, 16)), sweep_a[0][1], np.random.default_rng(0))
    ok = np.isfinite(ranges[: len(exact)])
    err = ranges[: len(exact)][ok] - exact[ok]
    assert 0.004 < err.std() < 0.012


def test_out_of_range_is_inf():
    laser = OverheadLaser(LaserParams(range_max=3.0, range_noise=0.0, dropout=0.0), 0.25)
    assert np.isinf(laser.scan(np.zeros((16, 16)), 0.0, np.random.default_rng(0))).all()


# --- a real scanner: lever arm, upside down, beams taken while the mount nods -------------


def test_lever_arm_turns_with_the_joints():
    lever = (0.0, 0.0, -0.1)  # hanging 10 cm under the tilt axis
    origin, dirs = beam_rays(0.0, 0.0, [0.0], lever=lever)
    assert np.allclose(origin, lever) and np.allclose(dirs, [[0, 0, -1]])
    origin, _ = beam_rays(0.0, 0.3, [0.0], lever=lever)
    assert np.allclose(origin, [0.0, 0.1 * np.sin(0.3), -0.1 * np.cos(0.3)])  # swings north
    offsets = (0.1, 0.02, -0.03)
    origin, _ = beam_rays(0.4, -0.2, [0.0], offsets, lever=(0.05, 0.0, 0.0))
    assert np.allclose(origin, tilting_rotation(0.4, -0.2, offsets) @ [0.05, 0.0, 0.0])
    # the tilting frame is the laser frame turned back to map axes at pan = tilt = 0
    assert np.allclose(
        tilting_rotation(0.4, -0.2, offsets),
        mount_rotation(0.4, -0.2, offsets) @ mount_rotation(0, 0).T,
    )


def test_upside_down_scanner_mirrors_its_beams():
    angles = np.array([-0.4, 0.0, 0.25])
    _, flipped = beam_rays(0.2, 0.1, angles, flip=True)
    assert np.allclose(flipped, beam_directions(0.2, 0.1, -angles))
    (east,) = beam_directions(0.0, 0.0, [np.pi / 2], flip=True)
    assert np.allclose(east, [-1, 0, 0])  # its "+y" beam looks west


def test_per_beam_angles_match_one_pair_per_scan():
    angles = np.linspace(-0.5, 0.5, 7)
    offsets = (0.01, -0.02, 0.03)
    pans, tilts = np.full(7, 0.3), np.linspace(-0.2, 0.4, 7)
    origins, dirs = beam_rays(pans, tilts, angles, offsets, lever=(0.02, -0.01, -0.07), flip=True)
    for i in range(7):
        o, d = beam_rays(0.3, tilts[i], angles[i : i + 1], offsets, (0.02, -0.01, -0.07), True)
        assert np.allclose(origins[i], o) and np.allclose(dirs[i], d[0])
    # one pair, no lever, no flip: exactly the directions of before, a zero origin
    o, d = beam_rays(0.3, 0.1, angles, offsets)
    assert not o.any() and np.array_equal(d, beam_directions(0.3, 0.1, angles, offsets))


def test_flipped_scanner_sees_the_upright_scan_reversed():
    surface = np.random.default_rng(4).integers(-3, 5, (16, 16)) * 0.05
    upright = noiseless().scan(surface, 0.1, np.random.default_rng(0))
    flipped = noiseless(flip=True).scan(surface, 0.1, np.random.default_rng(0))
    assert np.allclose(flipped, upright[::-1], atol=1e-6)  # symmetric angles: mirrored


def test_lever_arm_shortens_the_ranges_to_the_floor():
    ranges = noiseless(lever=(0.0, 0.0, -0.12)).scan(
        np.zeros((16, 16)), 0.0, np.random.default_rng(0)
    )
    a = LaserParams().angles()
    assert np.allclose(ranges, 3.88 / np.cos(a), atol=1e-5)


def test_nodding_mount_tilts_beam_by_beam():
    ti = 2**-15
    params = LaserParams(range_noise=0.0, dropout=0.0, time_increment=ti)
    tilts = params.beam_tilts(0.1)
    assert tilts[0] == 0.1 and np.allclose(np.diff(tilts), params.tilt_rate * ti)
    assert params.tilt_at(params.scan_period) == pytest.approx(params.tilts()[1])
    ranges = OverheadLaser(params, 0.25).scan(np.zeros((16, 16)), 0.1, np.random.default_rng(0))
    dirs = np.array(
        [beam_directions(0.0, t, [a])[0] for t, a in zip(tilts, params.angles(), strict=True)]
    )
    assert np.allclose(ranges, 4.0 / -dirs[:, 2], atol=1e-5)
    assert LaserParams().beam_tilts(0.1) == 0.1  # time_increment 0: one tilt per scan


def test_default_options_render_exactly_as_before():
    surface = surface_with_robots(np.zeros((16, 16)), np.array([[3, 4]]), 0.2)
    laser = OverheadLaser(LaserParams(), 0.25)
    got = laser.scan(surface, 0.2, np.random.default_rng(7))
    from excavation_sim.laser import trace

    dirs = beam_directions(0.0, 0.2, LaserParams().angles())
    want = np.empty(len(dirs))
    trace(surface, 0.25, np.array([2.0, 2.0, 4.0]), dirs, 8.0, want)
    rng = np.random.default_rng(7)
    want = want + rng.normal(0.0, 0.008, len(want))
    lost, nan = rng.random(len(want)) < 0.01, rng.random(len(want)) < 0.5
    want[lost & nan], want[lost & ~nan] = np.nan, np.inf
    assert np.array_equal(got, want.astype(np.float32), equal_nan=True)


def test_a_fine_height_field_traces_as_its_cells_and_shows_what_is_finer():
    """The physical soil's fine field (sub-cells ``scale`` to a cell): a field that is each
    cell's height repeated traces exactly as the cells do; a bump on one sub-cell shows."""
    rng = np.random.default_rng(3)
    cells = rng.integers(-2, 3, (16, 16)) * 0.05
    scale = 4
    fine = np.repeat(np.repeat(cells, scale, 0), scale, 1)
    anchors = np.array([[3, 4], [9, 9]])
    coarse = surface_with_robots(cells, anchors, 0.2)
    fine_surface = surface_with_robots(fine, anchors * scale, 0.2, scale)
    assert np.array_equal(fine_surface, np.repeat(np.repeat(coarse, scale, 0), scale, 1))
    ideal = LaserParams(range_noise=0.0, dropout=0.0)
    for tilt in (-0.3, 0.0, 0.25):
        a = OverheadLaser(ideal, 0.25).scan(coarse, tilt, np.random.default_rng(0))
        b = OverheadLaser(ideal, 0.25 / scale).scan(fine_surface, tilt, np.random.default_rng(0))
        assert np.allclose(a, b, atol=1e-4)
    bumped = fine_surface.copy()
    bumped[32:34, 20:60] += 0.2  # a ridge half a cell wide across the site
    hit = [
        OverheadLaser(ideal, 0.25 / scale).scan(s, t, np.random.default_rng(0))
        for s in (fine_surface, bumped)
        for t in np.linspace(-0.5, 0.5, 41)
    ]
    assert any(not np.allclose(hit[i], hit[41 + i]) for i in range(41))
