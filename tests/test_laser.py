"""The synthetic overhead laser (excavation_sim.laser) and the mount geometry."""

from __future__ import annotations

import numpy as np
import pytest

from excavation_sim.laser import LaserParams, OverheadLaser, surface_with_robots
from terrain_mapper.geometry import beam_directions, mount_rotation


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
