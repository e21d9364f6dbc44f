"""ant-dome up --sim end to end: the same fitness as ant-trial, a killed node restarted,
Ctrl-C stopping the nodes in reverse order and finishing the bag; the real dome's drive
chain (executor, team tick, controller) wired as its table says."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from helpers.figures import assert_figure
from helpers.view_client import free_port
from helpers.waits import poll_until

from excavation_bringup.dome import sim_result
from excavation_bringup.trial import run_trial

ROOT = Path(__file__).resolve().parents[1]
SITE = ROOT / "ros2_ws/src/excavation_bringup/config/site_sim.yaml"


def dome(tmp_path, domain, *extra, ticks=None):
    cmd = [sys.executable, "-m", "excavation_bringup.dome", "up", str(SITE), "--sim", "--json"]
    cmd += ["--domain", str(domain), "--run-dir", str(tmp_path / "run"), "--timeout", "900"]
    if ticks:
        cmd += ["--ticks", str(ticks)]
    return subprocess.Popen(
        [*cmd, *extra], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )


def state(tmp_path):
    try:
        return json.loads((tmp_path / "run" / "state.json").read_text())
    except (FileNotFoundError, json.JSONDecodeError):
        return {}


def events(tmp_path):
    try:
        return (tmp_path / "run" / "events.log").read_text()
    except FileNotFoundError:
        return ""


def snapshots(tmp_path) -> int:
    """Ticks the simulator has taken a snapshot for (``RUN/world.json``)."""
    try:
        return len(json.loads((tmp_path / "run" / "world.json").read_text())["snapshots"])
    except (FileNotFoundError, json.JSONDecodeError):
        return 0


def warnings(tmp_path, limit: int = 40) -> str:
    """The WARN and ERROR lines of every node's log (for a failure's message)."""
    lines = []
    for log in sorted((tmp_path / "run" / "logs").glob("*.log")):
        lines += [
            f"{log.stem}: {x}"
            for x in log.read_text().splitlines()
            if "[WARN]" in x or "[ERROR]" in x
        ]
    return "\n".join(lines[:limit]) or "no warnings in the node logs"


def divergence(a: list, b: list) -> str:
    """Where two runs' words first differ."""
    t = next((i for i, (x, y) in enumerate(zip(a, b, strict=False)) if x != y), min(len(a), len(b)))
    return f"words first differ at tick {t}: {a[t : t + 1]} != {b[t : t + 1]}"


@pytest.fixture(scope="module")
def composed(domains):
    """The composed trial equal to ``site_sim.yaml`` for 20 ticks (docs/dome.md): ``ant-trial
    --genome genomes/best.json --robots 2 --steps 20 --blueprint default:1 --drive continuous
    --perception full --no-slip`` (site_sim.yaml: ``sim.exact``)."""
    return run_trial(
        "genomes/best.json",
        2,
        20,
        0,
        "default:1",
        domain=domains(),
        command_timeout=30.0,
        drive="continuous",
        perception="full",
        exact=True,
    )


def assert_same_run(tmp_path, result: dict, summary: dict, trial) -> None:
    """The dome's 20 ticks are the composed trial's: words, fitness and heights."""
    assert result["commands"] == trial.commands, (
        divergence(result["commands"], trial.commands)
        + f"\nholds {result.get('holds')}, reports {result.get('reports')}\n"
        + warnings(tmp_path)
    )
    assert summary["fitness"] == trial.fitness
    assert np.array_equal(np.array(result["heights"]), trial.heights)


@pytest.mark.system
@pytest.mark.serial  # full perception on the continuous simulator: words equal only unloaded
def test_dome_up_sim_runs_20_ticks_with_the_fitness_of_ant_trial(tmp_path, domain, composed):
    proc = dome(tmp_path, domain, ticks=20)
    out, err = proc.communicate(timeout=1200)
    assert proc.returncode == 0, err + events(tmp_path)
    summary = json.loads(out.strip().splitlines()[-1])
    result = sim_result(tmp_path / "run")
    assert summary["ticks"] == 20 and summary["ok"] and not summary["restarts"]
    assert result["missed"] == {"0": 0, "1": 0} and result["robots_late"] == 0
    assert_same_run(tmp_path, result, summary, composed)
    logs = {p.stem for p in (tmp_path / "run" / "logs").glob("*.log")}
    assert logs == {
        "dynamics",
        "executor_0",
        "executor_1",
        "supervisor",
        "server",
        "sensors",
        "localizer",
        "mapper",
        "blade_driver_0",
        "blade_driver_1",
        "controller_0",
        "controller_1",
        "team_tick",
    }
    order = [
        line.split("starting ")[1].split(" ")[0]
        for line in events(tmp_path).splitlines()
        if " starting " in line
    ]
    assert order[:3] == ["dynamics", "executor_0", "executor_1"]
    assert order[3:5] == ["supervisor", "server"] and order[-1] == "team_tick"


@pytest.mark.system
@pytest.mark.serial
def test_a_supervisor_that_stalls_every_second_leaves_the_run_unchanged(tmp_path, domain, composed):
    """A loaded machine's hiccups: the supervisor stopped for 0.3 s of every second.

    Each stall is a heartbeat gap (the simulator's clock runs on at up to 20 x): blades go
    home, executors stop, the team tick holds. A gap changes nothing on the site, so it asks
    for no new snapshot, however long, and the run ends as the undisturbed one. Before the
    team tick told a heartbeat gap from a pause, such a gap in a snapshot asked for another
    frame and sweep and the words diverged (as in CI: "a sweep ended after 17 of 32 scans");
    later a stall while tick 0 waited for the supervisor's first heartbeat ("no heartbeat
    yet") still did ("tick 0: team held 0.1 s; new snapshot"), so the stalls begin as soon
    as every node is up.
    """
    proc = dome(tmp_path, domain, ticks=20)
    stalls = 0
    try:
        assert poll_until(lambda: "all 13 nodes are up" in events(tmp_path), 600)
        while proc.poll() is None:
            pid = state(tmp_path).get("supervisor", {}).get("pid")
            try:
                os.kill(pid, signal.SIGSTOP)
                time.sleep(0.3)
                os.kill(pid, signal.SIGCONT)
                stalls += 1
            except (ProcessLookupError, TypeError):
                pass  # stopping: the supervisor is gone
            time.sleep(0.7)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err + events(tmp_path)
    summary = json.loads(out.strip().splitlines()[-1])
    result = sim_result(tmp_path / "run")
    assert summary["ticks"] == 20 and summary["ok"] and not summary["restarts"]
    assert stalls >= 10 and result["holds"] >= 5, (stalls, result["holds"])
    assert not any("new snapshot" in r for r in result["reports"]), result["reports"]
    assert_same_run(tmp_path, result, summary, composed)


@pytest.mark.system
def test_a_killed_controller_is_restarted_and_the_run_completes(tmp_path, domain):
    proc = dome(tmp_path, domain, ticks=12)
    try:
        assert poll_until(lambda: "all 13 nodes are up" in events(tmp_path), 600)
        assert poll_until(lambda: snapshots(tmp_path) >= 3, 600)  # a few ticks
        victim = state(tmp_path)["controller_1"]["pid"]
        os.kill(victim, signal.SIGKILL)
        out, err = proc.communicate(timeout=900)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err + events(tmp_path)
    summary = json.loads(out.strip().splitlines()[-1])
    assert summary["ticks"] == 12 and summary["restarts"] == {"controller_1": 1}
    log = events(tmp_path)
    assert "controller_1 exited with code -9" in log
    assert "restarting controller_1 in 1.0 s (restart 1)" in log
    assert "controller_1 is up again (restart 1)" in log
    assert state(tmp_path)["controller_1"]["pid"] != victim
    assert (tmp_path / "run" / "logs" / "controller_1.log").read_text().count("start\n") == 2


@pytest.mark.system
def test_ctrl_c_stops_in_reverse_order_and_finishes_the_bag_which_replays(tmp_path, domain, ros):
    from excavation_bags.reader import open_bag

    bag = tmp_path / "bag"
    port = free_port()
    proc = dome(
        tmp_path, domain, "--record", str(bag), "--view", "--view-port", str(port), ticks=300
    )
    try:
        assert poll_until(lambda: "all 15 nodes are up" in events(tmp_path), 600)
        assert poll_until(lambda: snapshots(tmp_path) >= 3, 300)  # two ticks done
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err + events(tmp_path)
    log = events(tmp_path)
    assert "stopping: SIGINT" in log
    stopped = [
        line.split("stopping ")[1]
        for line in log.splitlines()
        if " stopping " in line and ":" not in line.split("stopping ")[1]
    ]
    started = [
        line.split("starting ")[1].split(" ")[0]
        for line in log.splitlines()
        if " starting " in line
    ]
    assert stopped == started[::-1] and started[0] == "recorder" and started[-1] == "view"
    assert f"serving ws://127.0.0.1:{port}" in (tmp_path / "run" / "logs" / "view.log").read_text()
    recorded = open_bag(bag)
    assert not recorded.warnings  # closed properly: summary and footer written
    assert recorded.topics["/worksite/height_map"].count > 0
    assert recorded.topics["/overhead/image_raw/compressed"].count > 0  # the recorder compresses
    _replay_with_clock(recorded, ros)
    _tick_replay(recorded, ros)
    _reperceive(recorded, tmp_path, ros)
    from excavation_bags.report import make_report

    report = make_report(recorded, tmp_path / "report", gif=False)
    assert "tracks.png" in report.files, report.skipped
    assert_figure(tmp_path / "report" / "tracks.png")
    field = report.numbers["field"]
    assert sorted(field["robots"]) == ["0", "1"] and field["ticks"]["count"] >= 2
    for robot in field["robots"].values():  # the camera's frames, each with its pose or not
        assert robot["frames"] > 0 and 0 <= robot["frames_without_pose"] <= robot["frames"]
        assert robot["goals_ended"] >= 2 and robot["drift_cm_max"] is not None


def _reperceive(recorded, tmp_path, ros) -> None:
    """``ant-bag play BAG --reperceive --run-dir RUN``: a fresh localiser and mapper with the
    run's parameters give the recorded poses again, within the camera frames' JPEG noise
    (``ant-bag diff``)."""
    from excavation_bags.diff import diff_bags
    from excavation_bags.reader import open_bag
    from excavation_bags.reperceive import parameter_files, reperceive_nodes

    localizer, mapper = parameter_files(str(tmp_path / "run"), None, None)
    out = tmp_path / "reperceived"
    player, others = reperceive_nodes(recorded, out, ros.context, localizer, mapper)
    for node in (player, *others):
        ros.add(node)
    assert ros.spin_until(lambda: player.finished, timeout=600.0)
    ros.spin_until(lambda: False, timeout=2.0)  # the last poses and maps
    for node in (player, *others):
        getattr(node, "close", lambda: None)()
        ros.executor.remove_node(node)
        node.destroy_node()
    result = diff_bags(recorded, open_bag(out), ["/robot_*/pose", "/worksite/height_map"])
    for k in (0, 1):
        pose = result["topics"][f"/robot_{k}/pose"]
        assert pose["matched"] >= 2 and pose["only_in_a"] <= 1, result
        assert pose["position_cm_max"] < 1.0 and pose["heading_deg_max"] < 1.0, result
    assert result["topics"]["/worksite/height_map"]["largest_difference"] < 0.01, result


def _tick_replay(recorded, ros) -> None:
    """``ant-bag play BAG --genome``: fresh controllers answer every recorded tick of the
    dome run with the recorded words (the last tick, cut by Ctrl-C, may go unanswered)."""
    from ant_controller.controller import Controller
    from excavation_bags.tick_replay import compare, recorded_robots, recorded_words, replay_nodes

    robots = recorded_robots(recorded)
    words = recorded_words(recorded, robots)
    assert min(len(w) for w in words.values()) >= 2, words
    controller = Controller.from_file(ROOT / "genomes" / "best.json")
    player, controllers, log, probe = replay_nodes(recorded, controller, ros.context, timeout=5.0)
    for node in (player, *controllers, probe):
        ros.add(node)
    assert ros.spin_until(lambda: player.finished, timeout=300.0)
    ros.spin_until(lambda: False, timeout=1.0)  # the last words
    result = compare(words, log.words, log.sensors)
    assert result["differing"] == [] and result["missing"] == {}, result


def _replay_with_clock(recorded, ros) -> None:
    """``ant-bag play --clock --rate 8`` of the dome's bag, as a subscriber sees it: each
    topic's messages in the bag's order and number, the latched map info to a late
    subscriber, and ``/clock`` rising through the bag's span at the replay's pace."""
    import rclpy
    from nav_msgs.msg import MapMetaData
    from rclpy.parameter import Parameter
    from rosgraph_msgs.msg import Clock

    from excavation_bags.player_node import PlayerNode
    from excavation_bags.recorder_node import message_class
    from excavation_common.ros import LATCHED

    topics = ["/team/heartbeat", "/robot_0/pose", "/worksite/height_map"]
    expected = {t: [raw for _, _, raw in recorded.messages([t])] for t in topics}
    assert all(expected.values()), {t: len(v) for t, v in expected.items()}
    probe = ros.add(rclpy.create_node("replay_probe", context=ros.context))
    got: dict[str, list[bytes]] = {t: [] for t in topics}
    clocks: list[tuple[float, int]] = []
    for t in topics:
        cls = message_class(recorded.topics[t].msgtype)
        probe.create_subscription(cls, t, lambda raw, t=t: got[t].append(raw), 1000, raw=True)

    def on_clock(m: Clock) -> None:
        clocks.append((time.monotonic(), m.clock.sec * 10**9 + m.clock.nanosec))

    probe.create_subscription(Clock, "/clock", on_clock, 100)
    overrides = [
        Parameter("topics", value=[*topics, "/worksite/map_info"]),
        Parameter("rate", value=8.0),
        Parameter("clock", value=True),
        Parameter("delay", value=2.0),  # the probe's subscriptions match first
    ]
    player = ros.add(PlayerNode(recorded, context=ros.context, parameter_overrides=overrides))
    assert ros.spin_until(lambda: player.finished, timeout=300.0)
    assert ros.spin_until(lambda: all(len(got[t]) >= len(expected[t]) for t in topics), 30.0)
    for t in topics:
        assert got[t] == expected[t], t  # order and count, byte for byte
    late = []
    probe.create_subscription(MapMetaData, "/worksite/map_info", late.append, LATCHED)
    assert ros.spin_until(lambda: late, timeout=10.0)  # replayed latched
    stamps = [c for _, c in clocks]
    assert stamps == sorted(stamps)
    span = (stamps[-1] - stamps[0]) * 1e-9
    assert span > 0
    wall = clocks[-1][0] - clocks[0][0]
    assert wall >= span / 8.0 * 0.5  # paced by the bag at 8 x, not a flood (a lower bound)


def test_the_real_dome_wires_executor_team_tick_and_controller(tmp_path, ros, ros_env):
    """Started from the real dome's table: the executor drives the site's ``drive_topic`` on the
    localiser's pose, the team tick reads the blade driver's joint state and republishes it
    per tick, and the controller reads the tick's blade, poses, height map and stuck flag."""
    import yaml

    from excavation_bringup import site as sitefile
    from excavation_bringup.dome import dome_graph

    site = sitefile.load_site(ROOT / "tests/data/sites/good.yaml")
    by_name = {s.name: s for s in dome_graph(site, tmp_path).nodes}
    env = {**ros_env, "ROS_DOMAIN_ID": str(ros.domain)}
    procs = []
    try:
        for name in ("executor_1", "team_tick", "controller_1"):
            spec = by_name[name]
            params = tmp_path / f"{name}.yaml"
            params.write_text(yaml.safe_dump({"/**": {"ros__parameters": spec.ros_params()}}))
            log = (tmp_path / f"{name}.log").open("w")
            procs.append(subprocess.Popen(spec.command(params), env=env, stdout=log, stderr=log))
        probe = ros.add(rclpy_node(ros, "probe"))

        def names(kind, topic):
            pub = kind == "pub"
            get = (
                probe.get_publishers_info_by_topic if pub else probe.get_subscriptions_info_by_topic
            )
            return sorted(i.node_name for i in get(topic))

        wanted = {
            ("pub", "/base_1/cmd_vel"): ["executor"],  # good.yaml: robot_1's drive_topic
            ("pub", "/robot_1/cmd_vel"): [],
            ("sub", "/robot_1/pose"): ["executor", "team_tick"],  # the localiser's pose
            ("sub", "/robot_1/blade/joint_states"): ["team_tick"],  # the board's, not the tick's
            ("pub", "/robot_1/blade/tick_state"): ["team_tick"],
            ("sub", "/robot_1/blade/tick_state"): ["controller"],
            ("sub", "/tick/robot_0/pose"): ["controller"],
            ("sub", "/tick/robot_1/stuck"): ["controller"],
            ("sub", "/tick/worksite/height_map"): ["controller"],
            ("pub", "/robot_1/drive/_action/status"): ["executor"],  # the drive action's
            ("sub", "/robot_1/drive/_action/feedback"): ["team_tick"],  # server and client
        }
        seen = {}

        def wired():
            seen.update({key: names(*key) for key in wanted})
            return seen == wanted and all(p.poll() is None for p in procs)

        assert ros.spin_until(wired, timeout=90.0), (seen, [p.poll() for p in procs])
    finally:
        for p in procs:
            p.send_signal(signal.SIGINT)
        for p in procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


def rclpy_node(ros, name):
    """A bare node in the ``ros`` fixture's context (graph queries only)."""
    import rclpy

    return rclpy.create_node(name, context=ros.context)
