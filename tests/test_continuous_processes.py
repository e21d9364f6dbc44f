"""``ant-trial --drive continuous --processes [--record BAG]`` against the composed trial.

Every node in its own process must give what the composed continuous trial gives (and
so the lockstep grid trial, tests/test_continuous_trial.py) with slip and noise off; the
recorder's bag must hold the continuous trial's topics and read back with ``ant-bag info``.
"""

from __future__ import annotations

import numpy as np
import pytest

from ant_controller.controller import Controller
from excavation_bags.cli import main as bag_main
from excavation_bags.reader import open_bag
from excavation_bringup.trial import run_trial

SPEC, ROBOTS, STEPS, SEED = "genomes/best.json", 2, 10, 3
CONTINUOUS_TOPICS = {
    "/clock",
    "/robot_0/cmd_vel",
    "/robot_1/cmd_vel",
    "/robot_0/drive/status",
    "/robot_0/imu",
    "/robot_0/pose",
    "/robot_0/behaviour",
    "/robot_0/blade/plant_state",
    "/team/tick",
    "/team/heartbeat",
    "/tick/robot_0/pose",
    "/worksite/height_map",
}


def trial(domain, **kw):
    return run_trial(
        SPEC,
        ROBOTS,
        STEPS,
        SEED,
        "default:1",
        domain=domain,
        command_timeout=30.0,
        timeout=900.0,
        **kw,
    )


@pytest.mark.system  # every node its own process
def test_processes_equal_the_composed_and_grid_trials_and_record_a_bag(tmp_path, capfd, domains):
    bag = tmp_path / "bag"
    procs = trial(domains(), drive="continuous", exact=True, processes=True, record=str(bag))
    composed = trial(domains(), drive="continuous", exact=True)
    grid = trial(domains())
    assert sum(procs.missed.values()) == 0 and procs.robots_late == 0
    assert np.array_equal(procs.heights, composed.heights)
    assert np.array_equal(procs.heights, grid.heights)
    assert procs.fitness == composed.fitness == grid.fitness
    assert procs.trace == composed.trace == grid.trace
    assert procs.commands == composed.commands == grid.commands
    assert procs.primitives_aborted == composed.primitives_aborted
    assert procs.stuck_events == composed.stuck_events
    assert len(procs.tick_wall) == STEPS
    recorded = open_bag(bag)
    assert not recorded.warnings  # the recorder stopped last and finished the bag
    assert CONTINUOUS_TOPICS <= set(recorded.topics)
    assert recorded.topics["/team/tick"].count >= STEPS
    status = recorded.topics["/robot_0/drive/status"]
    assert status.msgtype == "excavation_interfaces/msg/DriveStatus"
    # the suite's own types are recorded with their definitions: a foreign reader (mcap_ros2,
    # no package of ours) decodes every status with its goal, the ticks in order, the team
    # tick's ticks and the blade drivers' set-points
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    (mcap_file,) = bag.glob("*.mcap")
    seen: dict[str, list] = {
        "/robot_0/drive/status": [],
        "/team/tick": [],
        "/robot_0/blade/servo_command": [],
    }
    with open(mcap_file, "rb") as f:
        for _, channel, _, m in make_reader(
            f, decoder_factories=[DecoderFactory()]
        ).iter_decoded_messages(topics=list(seen)):
            seen[channel.topic].append(m)
    started = [m.goal for m in seen["/robot_0/drive/status"] if m.status == 2]  # EXECUTING
    goals = [int(g.tick) for g in started]
    assert goals and goals == sorted(goals)
    assert all(g.robot == 0 for g in started)
    ended = {int(m.goal.tick) for m in seen["/robot_0/drive/status"] if m.status in (4, 6)}
    assert set(goals) <= ended  # every goal of robot 0 ended (succeeded or aborted)
    ticks = [int(m.tick) for m in seen["/team/tick"]]
    assert ticks[:STEPS] == list(range(STEPS))
    assert all(m.stamp.sec == m.tick for m in seen["/team/tick"])  # the tick period is 1 s
    commands = seen["/robot_0/blade/servo_command"]
    assert commands and all(-0.1 < m.position < 0.2 and not m.held for m in commands)
    assert bag_main(["info", str(bag)]) == 0
    out = capfd.readouterr().out
    assert "/robot_1/cmd_vel" in out and "geometry_msgs/msg/TwistStamped" in out


def test_the_composed_continuous_trial_records_a_bag_that_replays_tick_by_tick(
    tmp_path, domain, ros
):
    bag = tmp_path / "bag"
    result = trial(domain, drive="continuous", exact=True, record=str(bag))
    recorded = open_bag(bag)
    assert not recorded.warnings
    assert CONTINUOUS_TOPICS <= set(recorded.topics)
    # one word per tick and robot (the final snapshot ends the trial unanswered)
    assert recorded.topics["/robot_1/behaviour"].count == STEPS
    assert recorded.topics["/team/tick"].count == STEPS
    assert len(result.commands) == STEPS
    # the field figures of ant-bag report: goals, aborts and U1 per robot as the trial saw
    from excavation_bags.field_report import field_figures

    _, _, raw = next(iter(recorded.messages(["/worksite/map_info"])))
    cell = float(recorded.decode("/worksite/map_info", raw).resolution)
    field = field_figures(recorded, cell)
    robots = field["robots"]
    assert sorted(robots) == ["0", "1"] and field["ticks"]["count"] == STEPS
    assert sum(r["stuck_events"] for r in robots.values()) == result.stuck_events, field
    for r in robots.values():
        assert r["goals_aborted"] == r["stuck_events"], field  # U1: the goal was aborted
        assert 0 < r["goals_ended"] <= STEPS and r["track_m"] > 0, field
        assert 0 <= r["drift_cm_max"] < cell * 50, field  # within half a cell of the lattice
    # tick replay: the recorded genome gives every word again; the hand-coded rules part
    # from it at some tick, which the comparison names with the inputs decided on
    same = _tick_replay(recorded, Controller.from_file(SPEC), ros, "a")
    assert same["ticks"] == STEPS and same["differing"] == [] and same["missing"] == {}, same
    other = _tick_replay(recorded, Controller.hand_coded(), ros, "b")
    assert other["first_difference"] is not None and other["missing"] == {}, other
    first = other["differing"][0]
    assert first["tick"] == other["first_difference"] and len(first["sensors"]) == 14


def _tick_replay(recorded, controller, ros, name: str) -> dict:
    from excavation_bags.tick_replay import compare, recorded_robots, recorded_words, replay_nodes

    robots = recorded_robots(recorded)
    player, controllers, log, probe = replay_nodes(recorded, controller, ros.context)
    for node in (player, *controllers, probe):
        ros.add(node)
    assert ros.spin_until(lambda: player.finished, timeout=120.0)
    ros.spin_until(lambda: False, timeout=0.5)  # the last words
    for node in (player, *controllers, probe):
        ros.executor.remove_node(node)
        node.destroy_node()
    return compare(recorded_words(recorded, robots), log.words, log.sensors)
