"""The emulated tilting laser: a continuous nod, scans and mount states on their own even
stamps, every beam traced where the nodding mount points it, and the real mapper building
the world's heights from the node's scans."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from dome_emulator.laser import LaserCore, LaserEmulatorParams, MountState, Scan
from helpers.diagnostics import DiagnosticsProbe

from excavation_common.params import ParameterError, validate
from terrain_mapper.geometry import beam_rays
from terrain_mapper.mount_sync import MountSync

S = 1_000_000_000
T0 = 1_700_000_000 * S


def laser(**changes) -> LaserCore:
    params = dataclasses.replace(LaserEmulatorParams(), **{"robots": 1, **changes})
    return LaserCore(params, T0)


def test_the_mount_nods_up_and_down_in_whole_sweeps():
    p = dataclasses.replace(LaserEmulatorParams(), sweep_scans=4, scan_rate=10.0)
    tilts = [p.scan_tilt(j) for j in range(10)]
    assert [t for t, _ in tilts] == pytest.approx(
        [-0.5, -0.25, 0.0, 0.25, 0.5, 0.25, 0.0, -0.25, -0.5, -0.25]
    )
    assert [r for _, r in tilts] == [True] * 4 + [False] * 4 + [True] * 2
    for j in range(10):  # the mount's continuous tilt agrees at every scan's start
        assert p.tilt_at(j * 0.1) == pytest.approx(tilts[j][0])
    assert p.tilt_at(0.45) == pytest.approx(0.375)  # on its way down


def test_scans_and_mount_states_come_on_their_own_even_stamps():
    core = laser(scan_rate=40.0, mount_rate=100.0, time_increment=0.0001)
    assert core.due(T0 + S // 100) == [
        MountState(T0, 0.0, pytest.approx(-0.5)),
        MountState(T0 + S // 100, 0.0, pytest.approx(core.params.tilt_at(0.01))),
    ]
    assert core.waiting == 0  # the first scan's last beam is 24 ms after its stamp
    core.truth.set_heights(np.zeros((16, 16)))
    out = core.due(T0 + S // 2)
    scans = [o for o in out if isinstance(o, Scan)]
    mounts = [o for o in out if isinstance(o, MountState)]
    assert [s.stamp_ns for s in scans] == [T0 + j * S // 40 for j in range(20)]
    assert [m.stamp_ns for m in mounts] == [T0 + m * S // 100 for m in range(2, 51)]
    assert [o.stamp_ns for o in out] == sorted(o.stamp_ns for o in out)
    assert scans[0].ranges.dtype == np.float32 and len(scans[0].ranges) == 241
    assert core.due(T0 + S // 2) == []  # nothing twice


def test_scans_wait_for_the_worlds_heights_and_a_late_device_drops_its_backlog():
    core = laser(scan_rate=40.0, max_backlog=0.2)
    out = core.due(T0 + 3 * S // 20)  # scans 0-5 done, none older than 0.2 s
    assert not any(isinstance(o, Scan) for o in out) and core.waiting == 6
    assert any(isinstance(o, MountState) for o in out)  # the mount nods regardless
    core.truth.set_heights(np.zeros((16, 16)))
    out = core.due(T0 + 2 * S)  # held up 1.75 s: only the last 0.2 s goes out
    assert min(o.stamp_ns for o in out) >= T0 + 2 * S - S // 5
    assert core.dropped > 0
    out = core.due(T0 + 3600 * S)  # an hour's stall (or a clock jump) costs no hour of work
    assert min(o.stamp_ns for o in out) >= T0 + 3600 * S - S // 5
    assert len(out) <= 0.2 * (40 + 100) + 2
    # every mount state (0 .. 360000) and scan (0 .. 143999) once: sent, waited or dropped
    assert core.dropped + core.scans + core.mount_states + core.waiting == 360_001 + 144_000


@pytest.mark.parametrize("j", [5, 70])  # a scan on the way up, one on the way down
def test_every_beam_is_traced_where_the_nodding_mount_points_it(j):
    core = laser(range_noise=0.0, dropout=0.0, time_increment=0.0001, scan_rate=40.0)
    core.truth.set_heights(np.full((16, 16), 0.1))  # a level floor 10 cm up, the site only
    p = core.params
    (scan,) = [o for o in core.due(T0 + j * S // 40 + S // 40) if isinstance(o, Scan)][-1:]
    assert scan.stamp_ns == T0 + j * S // 40
    beam_times = (scan.stamp_ns - T0) * 1e-9 + p.time_increment * np.arange(p.beams)
    tilts = np.array([p.tilt_at(t) for t in beam_times])
    assert (np.diff(tilts) > 0).all() == (j < p.sweep_scans)
    angles = p.model(True).angles()
    origin, dirs = beam_rays(p.pan, tilts, angles)
    t = (0.1 - p.mount[2]) / dirs[:, 2]  # down to the floor's plane
    hit = np.asarray(p.mount) + t[:, None] * dirs
    on_site = (hit[:, 0] > 0.01) & (hit[:, 0] < 3.99) & (hit[:, 1] > 0.01) & (hit[:, 1] < 3.99)
    assert on_site.sum() > 100
    np.testing.assert_allclose(scan.ranges[on_site], t[on_site], rtol=1e-5)


def test_the_mount_states_interpolate_to_every_beams_tilt():
    """What the mapper does (MountSync.lookup_beams) gives the tilts the beams were traced at."""
    core = laser(time_increment=0.0001, scan_rate=40.0, mount_rate=100.0, max_backlog=10.0)
    core.truth.set_heights(np.zeros((16, 16)))
    out = core.due(T0 + 4 * S)
    sync = MountSync(int(0.2 * S))
    for o in out:
        if isinstance(o, MountState):
            sync.add(o.stamp_ns, o.pan, o.tilt)
    p = core.params
    beams = (p.time_increment * S * np.arange(p.beams)).astype(np.int64)
    worst = 0.0
    for scan in [o for o in out if isinstance(o, Scan)][:-2]:
        found = sync.lookup_beams(scan.stamp_ns + beams)
        assert found.status == "ok"
        t = (scan.stamp_ns - T0) * 1e-9 + p.time_increment * np.arange(p.beams)
        worst = max(worst, float(np.abs(found.tilt - [p.tilt_at(x) for x in t]).max()))
    rate = (p.tilt_max - p.tilt_min) / p.nod_period
    assert worst <= rate * 0.01 / 2 + 1e-9  # exact but within half a state of a turn


def test_robots_stand_on_their_footprints_in_the_scans():
    core = laser(range_noise=0.0, dropout=0.0)
    core.truth.set_heights(np.zeros((16, 16)))
    core.truth.set_pose(0, 2.0, 2.0, 0.0)  # under the mount
    j = core.params.sweep_scans // 2  # the scan through the middle of the site
    scan = [o for o in core.due(T0 + (j + 1) * S // 40) if isinstance(o, Scan)][-1]
    assert scan.stamp_ns == T0 + j * S // 40 and scan.tilt == pytest.approx(0.0)
    middle = scan.ranges[len(scan.ranges) // 2]
    assert middle == pytest.approx(4.0 - 0.2, abs=0.02)  # the robot's top, 0.2 m up


def test_parameters_are_checked():
    validate(LaserEmulatorParams, {})
    with pytest.raises(ParameterError, match="does not fit in one scan period"):
        validate(LaserEmulatorParams, {"time_increment": 0.001})
    with pytest.raises(ParameterError, match="tilt_min"):
        validate(LaserEmulatorParams, {"tilt_min": 0.6})
    with pytest.raises(ParameterError, match="mount needs three"):
        validate(LaserEmulatorParams, {"mount": [1.0, 2.0]})
    with pytest.raises(dataclasses.FrozenInstanceError):
        MountState(0, 0.0, 0.0).tilt = 1.0


def test_the_mapper_builds_the_worlds_heights_from_the_laser_node(ros):
    from dome_emulator.laser_node import LaserNode
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Image, JointState, LaserScan

    from excavation_common.messages import grid_to_image, image_to_grid
    from excavation_common.ros import LATCHED
    from terrain_mapper.mapper_node import MapperNode

    deep = QoSProfile(depth=1000, reliability=ReliabilityPolicy.BEST_EFFORT)  # keep them all

    shared = {"sweep_scans": 32, "pan_joint": "mount_pan", "tilt_joint": "mount_nod"}
    laser_params = {
        **shared,
        "robots": 0,
        "beams": 121,
        "scan_rate": 80.0,
        "time_increment": 0.0001,
        "diagnostics_period": 0.1,
    }
    ros.add(
        LaserNode(
            context=ros.context,
            namespace="/worksite",
            parameter_overrides=[Parameter(k, value=v) for k, v in laser_params.items()],
        )
    )
    mapper_params = {**shared, "robots": 0}
    ros.add(
        MapperNode(
            context=ros.context,
            parameter_overrides=[Parameter(k, value=v) for k, v in mapper_params.items()],
        )
    )
    probe = ros.add(Node("probe", context=ros.context))
    scans, mounts, maps = [], [], []
    probe.create_subscription(LaserScan, "/worksite/scan", scans.append, deep)
    probe.create_subscription(JointState, "/worksite/laser_mount/joint_states", mounts.append, deep)
    probe.create_subscription(Image, "/worksite/height_map", maps.append, LATCHED)
    diags = DiagnosticsProbe(probe).named("/worksite/laser")
    # Before the world's heights: the mount nods, no scans, a WARN says why.
    assert ros.spin_until(lambda: any("no height map" in s.message for s in diags))
    assert mounts and not scans
    assert mounts[-1].name == ["mount_pan", "mount_nod"]
    truth = np.zeros((16, 16), dtype=np.float32)
    truth[4:8, 6:12] = 0.15  # a pile
    truth[10:14, 2:6] = -0.1  # a pit
    world = probe.create_publisher(Image, "/truth/worksite/height_map", LATCHED)
    world.publish(grid_to_image(truth, "32FC1"))

    def covered() -> bool:  # the first sweep starts mid-nod; later ones fill the map in
        return bool(maps) and np.isfinite(image_to_grid(maps[-1], "32FC1", "map")).mean() >= 0.8

    assert ros.spin_until(covered, 60.0)
    assert scans[0].time_increment == pytest.approx(0.0001)
    assert scans[0].header.frame_id == "overhead_laser"
    stamps = [s.header.stamp.sec * S + s.header.stamp.nanosec for s in scans]
    period = S / 80  # evenly spaced whatever the timers did (a lost scan leaves a gap)
    assert all(abs(d - period * round(d / period)) <= 1 for d in np.diff(stamps))

    def nodded_both_ways() -> bool:  # the probe may lag behind what the mapper has taken
        tilts = np.array([m.position[1] for m in mounts])
        steps = np.diff(tilts)
        return (steps > 0).any() and (steps < 0).any() and tilts.max() > 0.45

    assert ros.spin_until(nodded_both_ways, 30.0)
    tilts = [m.position[1] for m in mounts]
    assert max(tilts) <= 0.5 + 1e-9 and min(tilts) >= -0.5 - 1e-9
    mapped = image_to_grid(maps[-1], "32FC1", "height_map")
    known = np.isfinite(mapped)
    error = np.abs(mapped[known] - truth[known])
    assert np.median(error) < 0.01 and np.mean(error < 0.02) > 0.9  # edges of a step blur
    assert np.nanmean(mapped[5:7, 7:11]) == pytest.approx(0.15, abs=0.02)  # the pile's core
    assert np.nanmean(mapped[11:13, 3:5]) == pytest.approx(-0.1, abs=0.02)  # the pit's
