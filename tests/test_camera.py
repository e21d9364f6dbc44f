"""The synthetic overhead camera (excavation_sim.camera)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from blueprint_server.blueprint import default_blueprint
from excavation_sim.camera import (
    CameraParams,
    OverheadCamera,
    RobotView,
    calibration_marks,
    default_beacons,
    robot_views,
)
from excavation_sim.world import World


def scene(n=4, seed=0):
    bp = default_blueprint(2)
    world = World.scenario(bp.zones, bp.goal, n, seed)
    return robot_views(world.robots, world.heights, 0.25, 0.05), world.heights * 0.05


def test_frame_size_type_and_same_seed_same_image(camera):
    views, heights = scene()
    a, leds_a = camera.render(views, heights, np.random.default_rng(7))
    b, leds_b = camera.render(views, heights, np.random.default_rng(7))
    c, _ = camera.render(views, heights, np.random.default_rng(8))
    assert a.shape == (720, 1280, 3) and a.dtype == np.uint8
    assert np.array_equal(a, b) and np.array_equal(leds_a, leds_b)
    assert not np.array_equal(a, c)


def test_north_is_up_and_east_is_right(camera):
    corners = camera.project(np.array([[0, 0, 0], [4, 0, 0], [0, 4, 0]], dtype=float))
    sw, se, nw = corners
    assert se[0] > sw[0] + 400 and abs(se[1] - sw[1]) < 5
    assert nw[1] < sw[1] - 400 and abs(nw[0] - sw[0]) < 15


def test_leds_are_bright_in_the_dark_and_in_their_colour(camera):
    views, heights = scene()
    img, leds = camera.render(views, heights, np.random.default_rng(0))
    beacons = default_beacons()
    assert np.median(img) < 80  # low light
    for k, (front, rear) in enumerate(beacons.robots[:4]):
        for i, name in enumerate((front, rear)):
            u, v, seen = leds[k, i]
            assert seen == 1.0
            px = img[int(round(v)), int(round(u))]
            assert px.max() > 200
            hue = cv2.cvtColor(px.reshape(1, 1, 3), cv2.COLOR_BGR2HSV)[0, 0, 0]
            want = cv2.cvtColor(np.uint8([[beacons.colours[name]]]), cv2.COLOR_BGR2HSV)[0, 0, 0]
            assert abs((int(hue) - int(want) + 90) % 180 - 90) <= 8


def test_occlusion_and_dropout_remove_leds(camera):
    views, heights = scene()
    img, leds = camera.render(views, heights, np.random.default_rng(0), hidden={(1, "rear")})
    assert leds[1, 1, 2] == 0.0 and leds[1, 0, 2] == 1.0
    u, v = leds[1, 1, :2]
    assert img[int(round(v)), int(round(u))].max() < 150
    dark = OverheadCamera(
        CameraParams(dropout=1.0), default_beacons(), 16, 16, 0.25, seed=0
    ).render(views, heights, np.random.default_rng(0))[1]
    assert not dark[:, :, 2].any()


def test_led_height_follows_the_soil(camera):
    low = camera.led_points(RobotView(2.0, 2.0, 0.0, ground=-0.15))
    high = camera.led_points(RobotView(2.0, 2.0, 0.0, ground=0.0))
    assert np.allclose(high[:, 2] - low[:, 2], 0.15)
    assert np.allclose(high[0, :2] - high[1, :2], [0.36, 0.0])


def test_calibration_marks_project_to_their_pixels(camera):
    pixels, points = calibration_marks(camera, np.random.default_rng(0), pixel_noise=0.0)
    assert np.allclose(camera.project(points), pixels)
    assert len(points) >= 30 and (points[:, 2] > 0).sum() >= 6


def test_too_many_robots_for_the_table(camera):
    views = [RobotView(1.0, 1.0, 0.0)] * 11
    with pytest.raises(ValueError, match="robots"):
        camera.render(views, np.zeros((16, 16)), np.random.default_rng(0))


def test_occlusion_parameter():
    from excavation_sim.sensors_node import parse_occlude

    assert parse_occlude("0:front, 2:rear") == {(0, "front"), (2, "rear")}
    assert parse_occlude("") == frozenset()
    with pytest.raises(ValueError, match="'2:top' is not K:front or K:rear"):
        parse_occlude("2:top")
