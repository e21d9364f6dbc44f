"""Mount angles interpolated to each scan's stamp; mount offsets and their calibration."""

from __future__ import annotations

import math

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus
from helpers.rigs import LASER, MapperRig

from excavation_common.messages import image_to_grid
from excavation_sim.laser import LaserParams, OverheadLaser, trace, trace_rays
from terrain_mapper.calibrate_mount import Scan, fit_offsets, main, pair_scans
from terrain_mapper.geometry import PAN_JOINT, TILT_JOINT, beam_directions, beam_rays
from terrain_mapper.mapper import MapperParams, TerrainMapper
from terrain_mapper.mapper_node import MOUNT_TOPIC, SCAN_TOPIC
from terrain_mapper.mount_sync import MISS, WAIT, MountSync

PERIOD_NS = 10_000_000  # a scan every 10 ms, the tilt moving steadily


def test_sync_interpolates_waits_and_misses():
    sync = MountSync(max_gap_ns=50_000_000)
    assert sync.lookup(5).status == WAIT
    sync.add(0, 0.0, 0.0)
    sync.add(10_000_000, 0.1, 0.2)
    found = sync.lookup(3_000_000)
    assert found.status == "ok"
    assert math.isclose(found.pan, 0.03) and math.isclose(found.tilt, 0.06)
    assert sync.lookup(10_000_000).tilt == 0.2  # an exact stamp is used as it is
    assert sync.lookup(12_000_000).status == WAIT  # its later state has not arrived
    assert sync.lookup(-1_000_000).status == MISS
    sync.add(200_000_000, 0.0, 0.0)  # a gap in the mount's stream
    gap = sync.lookup(100_000_000)
    assert gap.status == MISS and "0.190 s apart" in gap.reason
    sync.add(5, 1.0, 1.0)  # out of order: ignored
    assert sync.out_of_order == 1


def test_sync_answers_every_beam_of_a_scan():
    sync = MountSync(max_gap_ns=50_000_000)
    beams = np.array([0, 2_500_000, 5_000_000, 7_500_000], dtype=np.int64)  # 2.5 ms apart
    assert sync.lookup_beams(beams).status == WAIT
    sync.add(0, 0.0, 0.0)
    sync.add(5_000_000, 0.05, 0.1)
    assert sync.lookup_beams(beams).status == WAIT  # its last beams' state has not come
    sync.add(10_000_000, 0.0, 0.3)
    found = sync.lookup_beams(beams)
    assert found.status == "ok"
    assert np.allclose(found.pan, [0.0, 0.025, 0.05, 0.025])
    assert np.allclose(found.tilt, [0.0, 0.05, 0.1, 0.2])
    assert found.tilt[2] == 0.1  # an exact stamp is used as it is
    for t in (2_500_000, 7_500_000):  # each beam as a single stamp would be answered
        one = sync.lookup(t)
        assert math.isclose(one.tilt, found.tilt[t // 2_500_000])
    assert sync.lookup_beams(beams - 1_000_000).status == MISS  # its first beam: too old
    sync.add(200_000_000, 0.0, 0.0)  # a gap in the mount's stream
    gap = sync.lookup_beams(beams + 100_000_000)
    assert gap.status == MISS and "0.190 s apart" in gap.reason
    assert sync.lookup_beams(beams + 300_000_000).status == WAIT


def tilt_at(t_ns: int) -> float:
    """The mount's tilt, sweeping steadily from tilt_min to tilt_max over the sweep."""
    span = (LASER.sweep_scans - 1) * PERIOD_NS
    return LASER.tilt_min + (LASER.tilt_max - LASER.tilt_min) * t_ns / span


def sweep_ranges(heights, seed=1):
    laser, rng = OverheadLaser(LASER, 0.25), np.random.default_rng(seed)
    return [laser.scan(heights, tilt_at(i * PERIOD_NS), rng) for i in range(LASER.sweep_scans)]


@pytest.mark.parametrize("lag_ms", [0, 3])
def test_scans_and_mount_states_apart_give_the_map_of_equal_stamps(ros, lag_ms):
    heights = np.random.default_rng(0).integers(-3, 4, (16, 16)) * 0.05
    scans = sweep_ranges(heights)
    exact = TerrainMapper(MapperParams())  # what equal stamps give: each scan's own tilt
    for i, ranges in enumerate(scans):
        exact.add_scan(
            ranges,
            LASER.angle_min,
            LASER.angle_increment,
            LASER.range_min,
            LASER.range_max,
            0.0,
            tilt_at(i * PERIOD_NS),
        )
    exact.finish_sweep()
    rig = MapperRig(ros, mount_wait=0.5)
    lag = lag_ms * 1_000_000
    for i, ranges in enumerate(scans):
        t = i * PERIOD_NS
        rig.mount(t - lag, tilt_at(t - lag))  # the mount's own driver, 3 ms earlier
        rig.scan(t, ranges)
    t_end = LASER.sweep_scans * PERIOD_NS - lag  # the mount keeps publishing
    rig.mount(t_end, tilt_at(t_end))
    assert ros.spin_until(lambda: rig.maps)
    got = image_to_grid(rig.maps[0], "32FC1", shape=(16, 16))
    want = exact.height_map()
    assert np.array_equal(np.isnan(got), np.isnan(want))
    assert np.isfinite(want).mean() > 0.5
    assert np.allclose(got[np.isfinite(want)], want[np.isfinite(want)], atol=1e-6)
    assert rig.mapper.unbracketed == 0


def test_unbracketed_scans_are_counted_and_warned(ros):
    rig = MapperRig(ros, mount_wait=0.5)
    scans = sweep_ranges(np.zeros((16, 16)))
    rig.mount(0, tilt_at(0))
    rig.mount(10**9, tilt_at(0))  # one second later: a gap in the mount's stream
    for i, ranges in enumerate(scans[1:], start=1):
        rig.scan(i * PERIOD_NS, ranges)

    def warned():  # every scan taken (a loaded machine takes them over several reports)
        s = rig.status
        return (
            s is not None
            and s.level == DiagnosticStatus.WARN
            and "no mount state brackets their stamp" in s.message
            and {kv.key: kv.value for kv in s.values}["unbracketed_scans"] == "15"
        )

    assert ros.spin_until(warned)
    assert rig.mapper.unbracketed == LASER.sweep_scans - 1
    assert not rig.maps


def queued(ros, sub, timeout=10.0) -> bool:
    """Whether a message waits in ``sub``'s queue, not yet taken (a wait set, no executor)."""
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

    wait_set = _rclpy.WaitSet(1, 0, 0, 0, 0, 0, ros.context.handle)
    wait_set.clear_entities()
    wait_set.add_subscription(sub.handle)
    wait_set.wait(int(timeout * 1e9))
    return sub.handle.pointer in wait_set.get_ready_entities("subscription")


def test_a_mount_state_queued_while_the_mapper_was_held_up_is_used_not_dropped(ros):
    # A loaded machine: the last scan of a sweep is in, its mount state comes while the
    # mapper gets no CPU for longer than mount_wait; when it runs again, its executor runs
    # the due timer before the subscriptions. The old mapper judged the scan's wait there
    # and dropped it (the sweep was fused only when the next began: a tick late).
    rig = MapperRig(ros, mount_wait=1.0)
    mapper = rig.mapper
    clock = [100.0]
    mapper.wall = lambda: clock[0]  # the mapper's wall clock, moved by hand
    scans = sweep_ranges(np.zeros((16, 16)))
    last = LASER.sweep_scans - 1
    for i, ranges in enumerate(scans):
        if i < last:
            rig.mount(i * PERIOD_NS, tilt_at(i * PERIOD_NS))
        rig.scan(i * PERIOD_NS, ranges)
    assert ros.spin_until(lambda: mapper.in_sweep == last and len(mapper.scans) == 1)
    rig.mount(last * PERIOD_NS, tilt_at(last * PERIOD_NS))
    assert queued(ros, mapper.mount_sub)  # in the queue, not taken: the mapper is held up
    clock[0] += 5.0  # longer than mount_wait
    mapper.on_timer()  # what the executor runs first when the mapper gets the CPU again
    assert mapper.unbracketed == 0 and mapper.published == 1  # the whole sweep, fused


def test_scans_from_before_the_mounts_first_state_are_dropped_quietly_at_start(ros):
    """The laser came up first: its first scans predate every mount state. They are
    dropped and counted as start-up, not reported as a sync fault (no WARN)."""
    rig = MapperRig(ros, mount_wait=0.5)
    scans = sweep_ranges(np.zeros((16, 16)))
    for i in range(2):
        rig.scan(i * PERIOD_NS, scans[i])  # before the mount's first state
    for i in range(2, len(scans) + 1):
        rig.mount(i * PERIOD_NS, tilt_at(i * PERIOD_NS))
    for i in range(2, len(scans)):
        rig.scan(i * PERIOD_NS, scans[i])
    assert ros.spin_until(lambda: rig.mapper.early == 2 and rig.mapper.bracketed == len(scans) - 2)
    assert rig.mapper.unbracketed == 0 and "mount_sync" not in rig.mapper.problems


def test_a_scan_the_laser_has_gone_past_is_dropped_by_stamps_not_wall_time(ros):
    # The mount's stream stopped while the laser's went on: scans more than mount_wait of
    # stamps older than the newest scan are given up, however little wall time passed.
    rig = MapperRig(ros, mount_wait=0.035)
    mapper = rig.mapper
    mapper.wall = lambda: 100.0  # no wall time passes
    scans = sweep_ranges(np.zeros((16, 16)))
    for i in range(10):
        rig.mount(i * PERIOD_NS, tilt_at(i * PERIOD_NS))
    for i, ranges in enumerate(scans):
        rig.scan(i * PERIOD_NS, ranges)
    # scans 10..15 have no mount state; 10..11 are more than 35 ms older than scan 15
    assert ros.spin_until(lambda: mapper.unbracketed == 2 and len(mapper.scans) == 4)
    assert mapper.in_sweep == 10
    mapper.on_timer()  # nothing queued, no wall time: the others still wait
    assert mapper.unbracketed == 2 and len(mapper.scans) == 4


# --- mount offsets ------------------------------------------------------------------------

TRUE_OFFSETS = (0.0, 0.021, -0.013)  # pan, tilt, roll (rad)
MOUNT = (2.0, 2.0, 4.0)


def floor_sweep(mount=MOUNT, offsets=TRUE_OFFSETS, seed=0, box=False):
    """A sweep of a flat floor (a box on it with ``box``) by a mount with ``offsets``."""
    rng = np.random.default_rng(seed)
    surface = np.zeros((16, 16))
    if box:
        surface[3:5, 10:12] = 0.3
    out = []
    for tilt in LaserParams(sweep_scans=32).tilts():
        dirs = beam_directions(0.0, tilt, LASER.angles(), offsets)
        ranges = np.empty(len(dirs))
        trace(surface, 0.25, np.asarray(mount, dtype=float), dirs, 8.0, ranges)
        out.append(Scan(0.0, float(tilt), LASER.angles(), ranges + rng.normal(0, 0.008, len(dirs))))
    return out


def test_offsets_make_the_mapper_see_a_level_floor():
    scans = floor_sweep()
    fit = fit_offsets(scans, MOUNT)
    assert abs(fit.tilt_offset - TRUE_OFFSETS[1]) < 1e-3
    assert abs(fit.roll_offset - TRUE_OFFSETS[2]) < 1e-3
    assert fit.rms_before > 0.03 and fit.rms_after < 0.012

    def floor_map(offsets):
        p = MapperParams(tilt_offset=offsets[1], roll_offset=offsets[2])
        mapper = TerrainMapper(p)
        for s in scans:
            mapper.add_scan(s.ranges, LASER.angle_min, LASER.angle_increment, 0.1, 8.0, 0.0, s.tilt)
        mapper.finish_sweep()
        return mapper.height_map()

    level = floor_map((0.0, fit.tilt_offset, fit.roll_offset))
    skewed = floor_map((0.0, 0.0, 0.0))
    assert np.nanmax(np.abs(level)) < 0.02 < np.nanmax(np.abs(skewed))


def test_fit_with_height_and_an_object_on_the_floor():
    scans = floor_sweep(mount=(2.0, 2.0, 4.06), box=True)
    fit = fit_offsets(scans, MOUNT, fit_height=True)
    assert abs(fit.mount_z - 4.06) < 5e-3
    assert abs(fit.tilt_offset - TRUE_OFFSETS[1]) < 2e-3
    assert fit.dropped > 0  # the box's returns are not floor


def test_calibrate_mount_reads_a_bag(tmp_path, capsys):
    import yaml
    from rosbags.typesys import Stores, get_typestore

    from excavation_bags.writer import BagWriter

    store = get_typestore(Stores.ROS2_JAZZY)
    types = store.types
    Header, Stamp = types["std_msgs/msg/Header"], types["builtin_interfaces/msg/Time"]
    bag = tmp_path / "floor"
    with BagWriter(bag) as writer:
        writer.add_topic(SCAN_TOPIC, "sensor_msgs/msg/LaserScan")
        writer.add_topic(MOUNT_TOPIC, "sensor_msgs/msg/JointState")
        scans = floor_sweep()
        step = scans[1].tilt - scans[0].tilt
        for i in range(len(scans) + 1):
            t = 10**9 + i * PERIOD_NS
            lagged = t - 3_000_000  # the mount's state 3 ms before the scan, moving steadily
            tilt = scans[0].tilt + (i - 0.3) * step
            head = Header(stamp=Stamp(sec=lagged // 10**9, nanosec=lagged % 10**9), frame_id="")
            state = types["sensor_msgs/msg/JointState"](
                header=head,
                name=[PAN_JOINT, TILT_JOINT],
                position=np.array([0.0, tilt]),
                velocity=np.array([], dtype=float),
                effort=np.array([], dtype=float),
            )
            writer.write(MOUNT_TOPIC, t, store.serialize_cdr(state, "sensor_msgs/msg/JointState"))
            if i == len(scans):
                break
            s = scans[i]
            head = Header(stamp=Stamp(sec=t // 10**9, nanosec=t % 10**9), frame_id="laser")
            scan = types["sensor_msgs/msg/LaserScan"](
                header=head,
                angle_min=LASER.angle_min,
                angle_max=LASER.angle_max,
                angle_increment=LASER.angle_increment,
                time_increment=0.0,
                scan_time=0.01,
                range_min=0.1,
                range_max=8.0,
                ranges=s.ranges.astype(np.float32),
                intensities=np.array([], dtype=np.float32),
            )
            writer.write(SCAN_TOPIC, t, store.serialize_cdr(scan, "sensor_msgs/msg/LaserScan"))
    out = tmp_path / "mount.yaml"
    assert main(["--bag", str(bag), "--mount", "2.0", "2.0", "4.0", "--out", str(out)]) == 0
    fitted = yaml.safe_load(out.read_text())["laser"]
    assert fitted["mount"] == [2.0, 2.0, 4.0]
    assert abs(fitted["offsets"]["roll"] - TRUE_OFFSETS[2]) < 2e-3
    assert abs(fitted["offsets"]["tilt"] - TRUE_OFFSETS[1]) < 1e-3
    assert "floor returns" in capsys.readouterr().err
    assert main(["--bag", str(tmp_path / "none"), "--mount", "2", "2", "4"]) == 2


def test_pairing_drops_scans_without_mount_state():
    class Msg:
        pass

    def stamped(ns):
        m = Msg()
        m.header = Msg()
        m.header.stamp = Time(sec=ns // 10**9, nanosec=ns % 10**9)
        return m

    states = []
    for ns in (0, 10_000_000):
        m = stamped(ns)
        m.name, m.position = [PAN_JOINT, TILT_JOINT], [0.0, ns * 1e-9]
        states.append(m)
    scans = []
    for ns in (5_000_000, 20_000_000):
        m = stamped(ns)
        m.angle_min, m.angle_increment, m.range_min, m.range_max = -0.1, 0.1, 0.1, 8.0
        m.ranges = [1.0, 2.0, 3.0]
        scans.append(m)
    paired, missed = pair_scans(scans, states)
    assert missed == 1 and len(paired) == 1 and math.isclose(paired[0].tilt, 0.005)


def test_calibration_of_a_real_laser():
    """Other joint names, a lever arm, upside down, nodding beams, the scanner's clock 5 ms
    behind: told about them as the mapper is, the fit finds the offsets."""
    lever, lag_ns = (0.03, -0.05, -0.12), 5_000_000
    laser = LaserParams(sweep_scans=32, lever=lever, flip=True, time_increment=2**-15)
    rng = np.random.default_rng(3)

    class Msg:
        pass

    def stamped(ns):
        m = Msg()
        m.header = Msg()
        m.header.stamp = Time(sec=1 + ns // 10**9, nanosec=ns % 10**9)
        return m

    scans, states = [], []
    for i, tilt in enumerate(laser.tilts()):
        origins, dirs = beam_rays(
            0.0, laser.beam_tilts(tilt), LASER.angles(), TRUE_OFFSETS, lever, True
        )
        ranges = np.empty(len(dirs))
        origins = np.ascontiguousarray(np.asarray(MOUNT) + origins)
        trace_rays(np.zeros((16, 16)), 0.25, origins, dirs, 8.0, ranges)
        scan = stamped(i * PERIOD_NS - lag_ns)
        scan.angle_min, scan.angle_increment = LASER.angle_min, LASER.angle_increment
        scan.range_min, scan.range_max = 0.1, 8.0
        scan.time_increment, scan.scan_time = laser.time_increment, 0.01
        scan.ranges = ranges + rng.normal(0, 0.008, len(ranges))
        scans.append(scan)
    for i in range(len(scans) + 1):
        state = stamped(i * PERIOD_NS)
        state.name = ["ptu_tilt", "ptu_pan"]
        state.position = [laser.tilt_at(i * 0.01), 0.0]
        states.append(state)
    paired, missed = pair_scans(
        scans, states, joints=("ptu_pan", "ptu_tilt"), stamp_offset=lag_ns * 1e-9
    )
    assert missed == 0 and np.ndim(paired[0].tilt) == 1  # per beam
    fit = fit_offsets(paired, MOUNT, lever=lever, flip=True)
    assert abs(fit.tilt_offset - TRUE_OFFSETS[1]) < 1e-3
    assert abs(fit.roll_offset - TRUE_OFFSETS[2]) < 1e-3
    assert fit.rms_after < 0.012
    with pytest.raises(ValueError, match="lie within 0.05 m of the floor"):
        fit_offsets(paired, MOUNT)  # the beams from the axis, upright: no floor at all
    assert pair_scans(scans, states)[1] == len(scans)  # no laser_pan / laser_tilt joints
