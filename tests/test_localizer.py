"""Overhead LED localizer core: calibration, detection, pairing, tracking, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest

from blueprint_server.blueprint import default_blueprint
from excavation_common.frames import yaw_to_heading
from excavation_sim.camera import (
    CameraParams,
    OverheadCamera,
    RobotView,
    calibration_marks,
    default_beacons,
    marks_yaml,
    robot_views,
)
from excavation_sim.world import HEADING, World
from overhead_localizer.beacons import CONFIG_DIR, Beacons, load_beacons
from overhead_localizer.calibrate import main as calibrate_main
from overhead_localizer.camera_model import calibrate, load_model, save_model
from overhead_localizer.errors import ImageError, LocalizerConfigError
from overhead_localizer.localize import AMBIGUOUS, COASTING, DUPLICATE, LOST, SEEN, Localizer

CELL, UNIT = 0.25, 0.05


@pytest.fixture(scope="module")
def model(camera):
    pixels, points = calibration_marks(camera, np.random.default_rng(1))
    return calibrate(pixels, points, (1280, 720))


def rough_world(seed: int, robots: int = 4) -> World:
    """A scenario with dug pits and dumped berms (heights -3 .. +4 units)."""
    bp = default_blueprint(3)
    world = World.scenario(bp.zones, bp.goal, robots, seed)
    rng = np.random.default_rng(seed)
    world.heights[:] = np.where(bp.zones == 1, -rng.integers(0, 4, bp.shape), 0)
    world.heights[bp.zones == 2] = rng.integers(0, 5, int((bp.zones == 2).sum()))
    return world


def test_shipped_tables_agree():
    assert load_beacons(CONFIG_DIR / "beacons.yaml") == default_beacons()
    assert not default_beacons().duplicates()


def test_calibration_recovers_the_camera(camera, model, tmp_path):
    assert model.rms_px < 0.6
    assert np.allclose(model.centre, camera.params.position, atol=0.05)
    path = tmp_path / "camera.yaml"
    save_model(model, path)
    again = load_model(path)
    pts = np.array([[0.5, 0.5, 0.15], [3.5, 3.0, 0.0], [2.0, 2.0, -0.15]])
    assert np.allclose(again.project(pts), camera.project(pts), atol=1.0)
    xy = again.to_map(camera.project(pts), pts[:, 2])
    assert np.allclose(xy, pts[:, :2], atol=0.01)


def test_calibrate_command(camera, tmp_path, capsys):
    marks = tmp_path / "marks.yaml"
    marks.write_text(marks_yaml(camera, *calibration_marks(camera, np.random.default_rng(2))))
    out = tmp_path / "camera.yaml"
    assert calibrate_main([str(marks), "--out", str(out)]) == 0
    assert "reprojection error" in capsys.readouterr().out
    assert load_model(out).width == 1280
    marks.write_text("image_width: 1280\nimage_height: 720\npoints: [{pixel: [1, 2]}]\n")
    assert calibrate_main([str(marks), "--out", str(out)]) == 2
    assert "marks.yaml: points = 1: expected a list of at least 6" in capsys.readouterr().err


def test_calibrate_with_a_drivers_camera_info_fits_the_pose_alone(camera, tmp_path, capsys):
    """``calibrate --camera-info``: the driver's K and D held fixed, the pose fitted under
    them, the file records it; localizing with them is as good as with the true camera."""
    from overhead_localizer.camera_info import camera_info_yaml
    from overhead_localizer.camera_model import FROM_CAMERA_INFO, FROM_MARKS, CameraModel

    p = CameraParams()
    truth = CameraModel(p.width, p.height, p.camera_matrix(), p.dist_coeffs(), *p.extrinsics())
    marks = tmp_path / "marks.yaml"
    marks.write_text(marks_yaml(camera, *calibration_marks(camera, np.random.default_rng(2))))
    info = tmp_path / "ost.yaml"  # as camera_calibration_parsers writes it
    info.write_text(camera_info_yaml(truth))
    out = tmp_path / "camera.yaml"
    assert calibrate_main([str(marks), "--out", str(out), "--camera-info", str(info)]) == 0
    assert "(the driver's, from" in capsys.readouterr().out
    fitted = load_model(out)
    assert fitted.intrinsics == FROM_CAMERA_INFO and fitted.intrinsics_file == str(info.resolve())
    assert np.array_equal(fitted.camera_matrix, truth.camera_matrix)
    assert np.array_equal(fitted.dist_coeffs, truth.dist_coeffs)
    assert fitted.rms_px < 0.6 and np.allclose(fitted.centre, p.position, atol=0.01)
    pts = np.array([[x, y, 0.15] for x in np.linspace(0.2, 3.8, 8) for y in (0.2, 2.0, 3.8)])
    err = np.hypot(*(fitted.to_map(truth.project(pts), 0.15) - pts[:, :2]).T)
    assert err.max() < 0.003  # metres, over the whole site
    assert calibrate_main([str(marks), "--out", str(out)]) == 0  # without: fitted to marks
    assert load_model(out).intrinsics == FROM_MARKS

    # what an uncalibrated driver wrote, another image size, fixed and fitted at once
    zero = camera_info_yaml(truth).replace("data: [1050.0, 0.0, 639.5", "data: [0.0, 0.0, 0.0")
    zero = zero.replace("0.0, 1050.0, 359.5, 0.0, 0.0, 1.0]", "0.0, 0.0, 0.0, 0.0, 0.0, 0.0]")
    info.write_text(zero)
    assert calibrate_main([str(marks), "--out", str(out), "--camera-info", str(info)]) == 2
    assert "camera_matrix = " in (err_text := capsys.readouterr().err)
    assert "is zero: the camera has no calibration" in err_text
    info.write_text(camera_info_yaml(truth).replace("image_width: 1280", "image_width: 640"))
    assert calibrate_main([str(marks), "--out", str(out), "--camera-info", str(info)]) == 2
    assert "differs from the marks' 1280 x 720" in capsys.readouterr().err
    info.write_text(camera_info_yaml(truth).replace("  cols: 5\n", "  cols: 4\n"))
    assert calibrate_main([str(marks), "--out", str(out), "--camera-info", str(info)]) == 2
    assert "distortion_coefficients = " in capsys.readouterr().err
    with pytest.raises(SystemExit):
        calibrate_main([str(marks), "--out", str(out), "--camera-info", str(info), "--focal", "9"])


def test_accuracy_over_varied_scenes(camera, model):
    """p95 position error under a quarter cell and every cardinal heading right."""
    rng = np.random.default_rng(0)
    errors, wrong, missing = [], 0, 0
    for seed in range(25):
        world = rough_world(seed)
        views = robot_views(world.robots, world.heights, CELL, UNIT)
        image, _ = camera.render(views, world.heights * UNIT, rng)
        localizer = Localizer(model, default_beacons(), 4)
        for k, est in enumerate(localizer.update(image, world.heights * UNIT, CELL)):
            if not est.reportable:
                missing += 1
                continue
            errors.append(math.hypot(est.x - views[k].x, est.y - views[k].y) / CELL)
            wrong += yaw_to_heading(est.yaw) != int(world.robots[k, HEADING])
            assert est.covariance[0, 0] > 0 and est.covariance[2, 2] > 0
    assert missing <= 2 and wrong == 0
    assert np.percentile(errors, 95) < 0.25


def test_covariance_grows_without_the_height_map(camera, model):
    world = rough_world(3)
    views = robot_views(world.robots, world.heights, CELL, UNIT)
    image, _ = camera.render(views, world.heights * UNIT, np.random.default_rng(0))
    with_map = Localizer(model, default_beacons(), 4).update(image, world.heights * UNIT, CELL)
    without = Localizer(model, default_beacons(), 4).update(image)
    assert all(
        a.covariance[0, 0] < b.covariance[0, 0] for a, b in zip(with_map, without, strict=True)
    )


def test_tracks_through_a_short_dropout(camera, model):
    views = [RobotView(1.0, 1.0, 0.0), RobotView(3.0, 3.0, math.pi / 2)]
    heights = np.zeros((16, 16))
    rng = np.random.default_rng(0)
    localizer = Localizer(model, default_beacons(), 2)
    image, _ = camera.render(views, heights, rng)
    assert [e.status for e in localizer.update(image)] == [SEEN, SEEN]
    statuses = []
    for _ in range(5):
        image, _ = camera.render(views, heights, rng, hidden={(0, "front")})
        est = localizer.update(image)
        statuses.append(est[0].status)
        assert est[1].status == SEEN
    assert statuses == [COASTING] * 3 + [LOST] * 2
    image, _ = camera.render(views, heights, rng)
    assert localizer.update(image)[0].status == SEEN


def test_coasting_covariance_grows(camera, model):
    views = [RobotView(2.0, 2.0, 0.0)]
    rng = np.random.default_rng(0)
    localizer = Localizer(model, default_beacons(), 1)
    seen = localizer.update(camera.render(views, np.zeros((16, 16)), rng)[0])[0]
    hidden = {(0, "front"), (0, "rear")}
    coast = localizer.update(camera.render(views, np.zeros((16, 16)), rng, hidden)[0])[0]
    assert coast.status == COASTING and (coast.x, coast.y) == (seen.x, seen.y)
    assert coast.covariance[0, 0] > seen.covariance[0, 0]


def test_two_robots_with_the_same_colours(camera, model):
    table = default_beacons()
    same = Beacons(table.colours, (table.robots[0], table.robots[1], table.robots[0]))
    assert same.duplicates() == [[0, 2]]
    views = [RobotView(1.0, 1.0, 0.0), RobotView(2.0, 3.0, 0.0), RobotView(3.0, 1.0, 0.0)]
    sim = OverheadCamera(CameraParams(), same, 16, 16, CELL, seed=0)
    image, _ = sim.render(views, np.zeros((16, 16)), np.random.default_rng(0))
    est = Localizer(model, same, 3).update(image)
    assert [e.status for e in est] == [DUPLICATE, SEEN, DUPLICATE]
    assert "shares LED colours" in est[0].detail and not est[0].reportable


def test_ambiguous_pairs_are_not_reported(model):
    """Two robots carrying robot 0's colours: with no track, neither pair is trusted."""
    table = default_beacons()
    views = [RobotView(1.0, 1.0, 0.0), RobotView(3.0, 3.0, 0.0)]
    twins = Beacons(table.colours, (table.robots[0], table.robots[0]))
    sim = OverheadCamera(CameraParams(), twins, 16, 16, CELL, seed=0)
    image, _ = sim.render(views, np.zeros((16, 16)), np.random.default_rng(0))
    one = Beacons(table.colours, (table.robots[0],))
    (est,) = Localizer(model, one, 1).update(image)
    assert est.status == AMBIGUOUS and not est.reportable


def test_bad_images(model):
    localizer = Localizer(model, default_beacons(), 4)
    with pytest.raises(ImageError, match=r"height x width x channels = \(480, 640, 3\)"):
        localizer.update(np.zeros((480, 640, 3), dtype=np.uint8))
    with pytest.raises(ImageError, match="uint8 BGR"):
        localizer.update(np.zeros((720, 1280), dtype=np.uint8))


def test_bad_files(tmp_path):
    with pytest.raises(LocalizerConfigError, match="does not exist"):
        load_model(tmp_path / "missing.yaml")
    (tmp_path / "cam.yaml").write_text("format: overhead-camera/1\nimage_width: 0\n")
    with pytest.raises(LocalizerConfigError, match="image_width = 0"):
        load_model(tmp_path / "cam.yaml")
    (tmp_path / "b.yaml").write_text(
        "colours: {red: [0, 0, 255]}\nrobots: [{front: red, rear: teal}]\n"
    )
    with pytest.raises(LocalizerConfigError, match=r"robots\[0\].rear = 'teal'"):
        load_beacons(tmp_path / "b.yaml")
    with pytest.raises(ValueError, match="names only 10"):
        Localizer(load_model(CONFIG_DIR / "camera_sim.yaml"), default_beacons(), 11)


def test_shipped_calibration_fits_the_default_camera(camera):
    shipped = load_model(CONFIG_DIR / "camera_sim.yaml")
    pts = np.array([[1.0, 1.0, 0.15], [3.0, 3.5, 0.15]])
    assert np.allclose(shipped.project(pts), camera.project(pts), atol=1.5)


def test_config_file_states_the_defaults():
    import yaml

    from overhead_localizer.localize import LocalizerParams

    shipped = yaml.safe_load((CONFIG_DIR / "localizer.yaml").read_text())
    params = shipped["localizer"]["ros__parameters"]
    for name, value in LocalizerParams().__dict__.items():
        assert params[name] == value, name


def test_no_coasting_across_a_long_gap(camera, model):
    """A robot unseen for longer than max_coast_time is lost, not reported where it was."""
    views = [RobotView(2.0, 2.0, 0.0)]
    rng = np.random.default_rng(0)
    hidden = {(0, "front")}
    fast = Localizer(model, default_beacons(), 1)
    fast.update(camera.render(views, np.zeros((16, 16)), rng)[0], stamp=10.0)
    image = camera.render(views, np.zeros((16, 16)), rng, hidden)[0]
    assert fast.update(image, stamp=10.033)[0].status == COASTING  # 30 frames per second
    slow = Localizer(model, default_beacons(), 1)
    slow.update(camera.render(views, np.zeros((16, 16)), rng)[0], stamp=10.0)
    (est,) = slow.update(image, stamp=11.0)  # one simulator tick later
    assert est.status == LOST and "1.00 s" in est.detail
    seen = slow.update(camera.render(views, np.zeros((16, 16)), rng)[0], stamp=12.0)[0]
    assert seen.status == SEEN
