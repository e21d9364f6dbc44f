"""ant-bag report on the sample trial bag, and partial reports from bad bags."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from helpers.figures import assert_figure

from ant_controller.controller import Controller
from blueprint_server.blueprint import default_blueprint
from excavation_bags.cli import main as ant_bag
from excavation_bags.reader import open_bag
from excavation_bags.report import make_report
from excavation_bags.trial_data import read_trial
from excavation_bags.writer import BagWriter
from excavation_sim.detectors import count, random_turn_direction

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "bags" / "sample"
# how bags/sample was made (docs/bags.md): ant-trial --genome genomes/best.json --robots 4
# --blueprint default:1 --steps 100 --seed 0 --record bags/sample
GENOME, ROBOTS, STEPS, SEED, DEPTH = ROOT / "genomes" / "best.json", 4, 100, 0, 1


def offline_trial():
    """The sample's trial offline: sensor vectors, masks and random-turn directions."""
    from ant_evolution.evaluate import ScenarioSet
    from excavation_sim.world import HEADING

    ctl = Controller.from_file(GENOME)
    batch = ScenarioSet.create(default_blueprint(DEPTH), ROBOTS, 1, STEPS, SEED)
    world = batch.world(0)
    sensors, masks, turns = [], [], []
    for t in range(STEPS + 1):  # the controllers also answer the final state
        s = world.sense()
        m = np.array([ctl.decide(s[k]) for k in range(ROBOTS)], dtype=np.int64)
        sensors.append(s)
        masks.append(m)
        if t < STEPS:
            before = world.robots[:, HEADING].copy()
            world.step(m)
            turns.append(random_turn_direction(before, world.robots[:, HEADING], m))
        else:
            turns.append(np.zeros(ROBOTS, dtype=np.int8))
    return world, np.array(sensors), np.array(masks), np.array(turns)


@pytest.fixture(scope="module")
def sample_report(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    assert ant_bag(["report", str(SAMPLE), "--out", str(out), "--gif-stride", "10"]) == 0
    return out


def test_sample_report_has_every_section(sample_report):
    for name in (
        "fitness.png",
        "snapshots.png",
        "trial.gif",
        "detectors.png",
        "field_metrics.png",
        "summary.md",
        "report.json",
    ):
        assert (sample_report / name).stat().st_size > 500, name
    from PIL import Image

    with Image.open(sample_report / "trial.gif") as gif:
        assert gif.n_frames == 11  # 101 frames, every 10th
    data = json.loads((sample_report / "report.json").read_text())
    assert data["skipped"] == {} and data["warnings"] == []
    assert data["robots"] == ROBOTS and data["frames"] == STEPS + 1
    summary = (sample_report / "summary.md").read_text()
    assert "Table 3 detectors" in summary and "Field metrics" in summary


def test_sample_report_numbers_equal_the_offline_trial(sample_report):
    data = json.loads((sample_report / "report.json").read_text())
    world, sensors, masks, turns = offline_trial()
    assert data["fitness"]["recomputed_final"] == pytest.approx(world.fitness(), abs=1e-12)
    assert data["fitness"]["final"] == pytest.approx(world.fitness(), abs=1e-6)  # Float32
    expected = count(sensors, masks, turns)
    assert data["detectors"]["counts"] == {k: int(v) for k, v in expected.items()}
    assert data["detectors"]["decisions"] == (STEPS + 1) * ROBOTS
    assert sum(expected.values()) > 0
    fm = data["field_metrics"]
    assert fm["dig_cells"] == int((default_blueprint(DEPTH).zones == 1).sum())
    assert math.isclose(fm["towards_goal"] + fm["above_goal"] + fm["below_goal"], 1.0)


def test_rebuilt_sensor_vectors_give_the_recorded_behaviours():
    """What the report feeds the detectors is what the controllers saw."""
    data = read_trial(open_bag(SAMPLE))
    frames, sensors, behaviours, _ = data.decision_arrays()
    assert len(sensors) == (STEPS + 1) * ROBOTS
    ctl = Controller.from_file(GENOME)
    assert [ctl.decide(s) for s in sensors] == behaviours.tolist()
    _, offline_sensors, offline_masks, _ = offline_trial()
    robots = np.array([d.robot for d in data.decisions])
    for k in range(ROBOTS):
        assert np.array_equal(sensors[robots == k], offline_sensors[:, k])
        assert np.array_equal(behaviours[robots == k], offline_masks[:, k])


def first_ticks(bag, ticks=20):
    """The sample's messages up to its first ``ticks`` ticks (keeps these tests short)."""
    clocks = 0
    for topic, ts, raw in bag.messages():
        clocks += topic == "/clock"
        if clocks > ticks:
            return
        yield topic, ts, raw


def copy_bag(dst, drop=(), retype=None, custom=None, foreign=False):
    """A filtered copy of the sample's first ticks (optionally with a topic's type replaced)."""
    src = open_bag(SAMPLE)
    retype = retype or {}
    if foreign:
        from rosbags.rosbag2 import StoragePlugin, Writer

        from excavation_bags.topics import typestore

        store = typestore()  # Jazzy's, taught the suite's own types (as any reader would be)
        with Writer(dst, version=9, storage_plugin=StoragePlugin.MCAP) as w:
            conns = {
                t.name: w.add_connection(
                    t.name, t.msgtype, typestore=store, offered_qos_profiles=t.qos
                )
                for t in src.topics.values()
            }
            for topic, ts, raw in first_ticks(src):
                w.write(conns[topic], ts, raw)
        return dst
    with BagWriter(dst, custom) as w:
        for t in src.topics.values():
            if t.name not in drop:
                w.add_topic(t.name, retype.get(t.name, t.msgtype), t.qos)
        for topic, ts, raw in first_ticks(src):
            if topic in w.topics:
                w.write(topic, ts, raw if topic not in retype else b"\x00\x01\x00\x00\x00")
    return dst


def report_of(bag_dir, out):
    report = make_report(open_bag(bag_dir), out, gif=False)
    assert (out / "summary.md").exists() and (out / "report.json").exists()
    return report, (out / "summary.md").read_text()


def test_missing_height_map_gives_a_partial_report(tmp_path):
    report, summary = report_of(
        copy_bag(tmp_path / "b", drop=("/worksite/height_map",)), tmp_path / "r"
    )
    for section in ("fitness", "snapshots", "field metrics"):
        assert "no /worksite/height_map" in report.skipped[section]
    assert "detectors" in report.skipped
    assert "## Skipped" in summary and "no /worksite/height_map" in summary


def test_missing_blueprint_keeps_the_fitness_plot(tmp_path):
    report, summary = report_of(
        copy_bag(tmp_path / "b", drop=("/blueprint/zones",)), tmp_path / "r"
    )
    assert "fitness.png" in report.files
    assert_figure(tmp_path / "r" / "fitness.png")
    assert "no /blueprint/zones" in report.skipped["snapshots"]
    assert "inputs" in report.skipped["detectors"]
    assert report.numbers["fitness"]["recomputed_final"] is None


def test_wrong_type_for_a_needed_topic(tmp_path):
    bag = copy_bag(tmp_path / "b", retype={"/worksite/height_map": "std_msgs/msg/String"})
    report, summary = report_of(bag, tmp_path / "r")
    assert any(
        "/worksite/height_map: type = 'std_msgs/msg/String'" in w and "expected" in w
        for w in report.warnings
    )
    assert "snapshots" in report.skipped


def test_unknown_producer_still_gets_a_full_report(tmp_path):
    report, summary = report_of(copy_bag(tmp_path / "b", foreign=True), tmp_path / "r")
    assert any("not recorded by ant-bag" in w for w in report.warnings)
    assert set(report.skipped) == {"animation"}  # only the GIF, which was not asked for
    assert "unknown" in summary  # producer unknown


def test_truncated_bag_gets_a_report_of_what_is_left(tmp_path):
    bad = tmp_path / "bad"
    bad.mkdir()
    data = (SAMPLE / "sample.mcap").read_bytes()
    (bad / "bad.mcap").write_bytes(data[: len(data) // 2])
    report, summary = report_of(bad, tmp_path / "r")
    assert "truncated bag" in summary
    assert 0 < report.numbers["fitness"]["frames"] < STEPS + 1
    assert "detectors.png" in report.files
    assert_figure(tmp_path / "r" / "detectors.png")


def test_bag_with_an_unknown_type_topic(tmp_path):
    from rosbags.rosbag2 import StoragePlugin, Writer

    path = tmp_path / "odd"
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conn = w.add_connection("/odd", "my_pkg/msg/Odd", msgdef="", rihs01="RIHS01_x")
        w.write(conn, 1, b"\x00\x01\x00\x00")
    bag = open_bag(path)
    assert any("unknown type 'my_pkg/msg/Odd'" in w for w in bag.warnings)
    report, summary = report_of(path, tmp_path / "r")
    assert "no /worksite/height_map" in report.skipped["snapshots"]


def test_the_field_figures_read_the_drive_and_tick_types_before_and_after(tmp_path):
    """A bag recorded before the suite's own types (``action_msgs/GoalStatus`` with the goal
    packed in its uuid, the tick a ``std_msgs/Header`` with the number in its ``frame_id``)
    and one after (``excavation_interfaces/DriveStatus`` and ``Tick``) give the same figures:
    goals ended and aborted, time per tick."""
    from excavation_bags.field_report import field_figures
    from excavation_bags.topics import typestore

    store = typestore()
    types = store.types
    Time = types["builtin_interfaces/msg/Time"]
    TICK = "excavation_interfaces/msg/Tick"
    ends = [(1, 4), (2, 6), (2, 6), (3, 4)]  # (tick, status): tick 2's abort heard twice

    def pose(t: int):
        pwc = store.types["geometry_msgs/msg/PoseWithCovarianceStamped"]
        header = types["std_msgs/msg/Header"](stamp=Time(sec=t, nanosec=0), frame_id="map")
        p = types["geometry_msgs/msg/Pose"](
            position=types["geometry_msgs/msg/Point"](x=0.1 * t, y=0.0, z=0.0),
            orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        )
        inner = types["geometry_msgs/msg/PoseWithCovariance"](
            pose=p, covariance=np.zeros(36, dtype=np.float64)
        )
        return pwc(header=header, pose=inner)

    def old(tick: int, status: int):
        uuid = np.frombuffer(tick.to_bytes(8, "little") + bytes(4) + b"ANT1", dtype=np.uint8)
        info = types["action_msgs/msg/GoalInfo"](
            goal_id=types["unique_identifier_msgs/msg/UUID"](uuid=uuid),
            stamp=Time(sec=tick, nanosec=0),
        )
        return types["action_msgs/msg/GoalStatus"](goal_info=info, status=status)

    def new(tick: int, status: int):
        goal = types["excavation_interfaces/msg/DriveGoal"](
            stamp=Time(sec=tick, nanosec=0), tick=tick, word=0, turn=0, robot=0
        )
        return types["excavation_interfaces/msg/DriveStatus"](goal=goal, status=status)

    def old_tick(t: int):
        return types["std_msgs/msg/Header"](stamp=Time(sec=t, nanosec=0), frame_id=str(t))

    def new_tick(t: int):
        return types["excavation_interfaces/msg/Tick"](stamp=Time(sec=t, nanosec=0), tick=t)

    figures = []
    for name, make, msgtype, tick_of, ticktype in (
        ("old", old, "action_msgs/msg/GoalStatus", old_tick, "std_msgs/msg/Header"),
        ("new", new, "excavation_interfaces/msg/DriveStatus", new_tick, TICK),
    ):
        with BagWriter(tmp_path / name) as w:
            w.add_topic("/robot_0/pose", "geometry_msgs/msg/PoseWithCovarianceStamped")
            w.add_topic("/robot_0/drive/status", msgtype)
            w.add_topic("/team/tick", ticktype)
            for t in range(5):
                raw = store.serialize_cdr(pose(t), "geometry_msgs/msg/PoseWithCovarianceStamped")
                w.write("/robot_0/pose", t * 10**9 + 1, raw)
                w.write("/team/tick", int(t * 1.5e9), store.serialize_cdr(tick_of(t), ticktype))
            for i, (tick, status) in enumerate(ends):
                raw = store.serialize_cdr(make(tick, status), msgtype)
                w.write("/robot_0/drive/status", tick * 10**9 + i, raw)
        both = field_figures(open_bag(tmp_path / name), 0.1)
        robot = both["robots"]["0"]
        figures.append((robot["goals_ended"], robot["goals_aborted"], both["ticks"]))
    assert figures[0] == figures[1] and figures[0][:2] == (3, 1)
    assert figures[0][2]["count"] == 5 and figures[0][2]["wall_mean_s"] == pytest.approx(1.5)
