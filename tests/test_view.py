"""ant-view: a WebSocket client subscribes to its Foxglove channels during a trial and decodes
robot poses and the height map."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from helpers.rigs import controller_node
from helpers.view_client import Client
from rclpy.parameter import Parameter

from excavation_bringup import view
from excavation_common.frames import robot_center

LAYOUT = (
    Path(__file__).resolve().parents[1]
    / "ros2_ws/src/excavation_bringup/config/foxglove_layout.json"
)


def test_client_decodes_robots_and_height_map_of_a_running_trial(ros):
    import foxglove

    from blueprint_server.server_node import BlueprintServer
    from excavation_sim.sim_node import SimNode

    server = foxglove.start_server(host="127.0.0.1", port=0)
    try:
        ros.add(BlueprintServer(context=ros.context))
        sim = ros.add(
            SimNode(
                context=ros.context,
                parameter_overrides=[
                    Parameter("robots", value=2),
                    Parameter("steps", value=6),
                    # No team supervisor here: a supervised simulator would hold tick 0
                    # until one arms the team (this test is about the view, not oversight).
                    Parameter("supervised", value=False),
                ],
            )
        )
        for k in range(2):
            controller_node(ros, k, 2)
        v = view.ViewNode(2, 0.05, period=0.2, context=ros.context)
        ros.add(v.node)
        topics = ["/view/robots", "/view/height_map", "/view/blueprint", "/view/fitness", "/tf"]
        client = Client(server.port, topics)
        client.start()
        assert ros.spin_until(lambda: sim.tick >= 2 and set(topics) <= set(client.last), timeout=60)
        assert ros.spin_until(lambda: sim.finished, timeout=60)
        # The final state reaches the client (the view publishes every 0.2 s): wait for it.
        ros.spin_until(lambda: not _view_differs(client.last, sim), timeout=60)
        client.stop.set()
        client.join(5)
        assert client.error is None, client.error
    finally:
        server.stop()
    assert _view_differs(client.last, sim) == []


def _view_differs(last: dict, sim) -> list[str]:
    """What the client's newest messages show differently from the simulator's state."""
    from excavation_sim.world import COL, ROW

    wrong = []
    scene = last["/view/robots"]
    positions = {
        e.id: (e.cubes[0].pose.position.x, e.cubes[0].pose.position.y) for e in scene.entities
    }
    for k in range(2):
        r = sim.world.robots[k]
        if positions.get(f"robot_{k}") != pytest.approx(
            robot_center(int(r[ROW]), int(r[COL]), 0.25)
        ):
            wrong.append(f"robot_{k} at {positions.get(f'robot_{k}')}")
    g = last["/view/height_map"]
    if not (g.frame_id == "map" and g.column_count == 16 and g.fields[0].name == "height"):
        wrong.append(f"height map frame {g.frame_id}, {g.column_count} columns")
    else:
        heights = np.frombuffer(g.data, dtype="<f4").reshape(-1, g.column_count)
        if not np.array_equal(heights, (sim.world.heights * 0.05).astype(np.float32)):
            wrong.append("height map differs")
    # the view forwards the simulator's /tf: map -> robot_k/base_link and (no blade drivers
    # here) robot_k/base_link -> robot_k/blade, at the robots' cells
    tf = {t.child_frame_id: t for t in last["/tf"].transforms}
    for k in range(2):
        t = tf.get(f"robot_{k}/base_link")
        r = sim.world.robots[k]
        if t is None or (t.translation.x, t.translation.y) != pytest.approx(
            robot_center(int(r[ROW]), int(r[COL]), 0.25)
        ):
            wrong.append(f"tf robot_{k}/base_link: {t}")
        blade = tf.get(f"robot_{k}/blade")
        if blade is None or blade.parent_frame_id != f"robot_{k}/base_link":
            wrong.append(f"tf robot_{k}/blade: {blade}")
    fitness = last["/view/fitness"]
    if fitness["fitness"] != pytest.approx(sim.world.fitness()):
        wrong.append(f"fitness {fitness['fitness']}")
    if fitness["mapped"] != pytest.approx(sim.world.fitness(), abs=1e-6):
        wrong.append(f"mapped fitness {fitness['mapped']}")
    return wrong


def test_layout_names_the_view_channels():
    layout = json.loads(LAYOUT.read_text())
    text = json.dumps(layout)
    for topic in (
        "/view/robots",
        "/view/height_map",
        "/view/blueprint",
        "/view/camera",
        "/view/fitness",
        "/view/diagnostics",
        "/view/team",
        "/operator/estop",  # the operator's panels: services and the Teleop panel's topic
        "/operator/pause",
        "/operator/arm",
        "/robot_0/drive/override",
    ):
        assert topic in text, topic
    from excavation_bringup.view_control import TRIGGERS

    services = {c["serviceName"] for k, c in layout["configById"].items() if "serviceName" in c}
    enables = {f"/operator/robot_{k}/enable" for k in range(4)}
    assert services == {f"/operator/{t}" for t in ("estop", "pause", "resume", "arm")} | enables
    assert set(TRIGGERS) >= {"estop", "pause", "resume", "arm"}


def test_the_view_checks_its_site_for_what_runs_it():
    """A rehearsal's site keeps the dome's compressed camera: the view started for a
    rehearsal (``--hardware emulated``, as ``ant-dome rehearse --view`` starts it) takes
    it, where a ``--sim`` check refuses it (the reason ``--view`` once failed there)."""
    from excavation_bringup.site import SiteError
    from excavation_bringup.view import view_site

    config = Path(__file__).resolve().parents[1] / "ros2_ws/src/excavation_bringup/config"
    rehearsal = str(config / "site_rehearsal.yaml")
    assert view_site(rehearsal, "emulated").n_robots >= 1
    with pytest.raises(SiteError, match="with --sim the synthetic camera"):
        view_site(rehearsal, "sim")
    assert view_site(str(config / "site_sim.yaml"), None).n_robots >= 1


def test_ant_dome_starts_the_view_with_its_hardware():
    from excavation_bringup.deployment import Deployment
    from excavation_bringup.nodes import view as view_spec
    from excavation_bringup.site import load_site

    config = Path(__file__).resolve().parents[1] / "ros2_ws/src/excavation_bringup/config"
    site = load_site(config / "site_rehearsal.yaml", emulated=True)
    dep = Deployment("", site.n_robots, 4, 0, hardware="emulated", site=site, drive="continuous")
    spec = view_spec(dep, 8765)
    assert spec.args[spec.args.index("--hardware") + 1] == "emulated"


def test_the_view_is_a_console_for_the_supervisor_and_the_robots(ros):
    """Foxglove's service calls reach the supervisor (arm, e-stop, enable) and its client
    publishing drives a robot; each action is counted on the view's diagnostics."""
    import foxglove
    from excavation_interfaces.msg import TeamState
    from geometry_msgs.msg import TwistStamped
    from helpers.view_client import free_port
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from std_msgs.msg import Bool

    from excavation_bringup.view_client import ControlClient
    from excavation_bringup.view_control import ControlPolicy, ViewControl
    from excavation_common.ros import LATCHED
    from team_supervisor.supervisor_node import SupervisorNode

    ros.add(SupervisorNode(context=ros.context, parameter_overrides=[Parameter("robots", value=2)]))
    watch = ros.add(Node("watch", context=ros.context))
    states, estops, twists = [], [], []
    watch.create_subscription(TeamState, "/team/heartbeat", lambda m: states.append(m.state), 10)
    watch.create_subscription(Bool, "/team/estop", lambda m: estops.append(m.data), LATCHED)
    watch.create_subscription(TwistStamped, "/robot_1/drive/override", twists.append, 10)
    v = view.ViewNode(2, 0.05, period=0.2, context=ros.context)
    ros.add(v.node)
    v.control = control = ViewControl(v.node, 2, ControlPolicy("127.0.0.1"))
    server = foxglove.start_server(
        name="test", port=free_port(),
        capabilities=[foxglove.Capability.Services, foxglove.Capability.ClientPublish],
        supported_encodings=["json"], server_listener=control.listener(),
        services=control.services(),
    )  # fmt: skip
    client = ControlClient(server.port, pump=lambda: ros.executor.spin_once(timeout_sec=0.01))
    try:
        ready = control.triggers.values()
        assert ros.spin_until(lambda: states and all(c.service_is_ready() for c in ready), 30)
        ok, reply = client.call("/operator/arm", {})
        assert ok and reply["success"] and "armed" in reply["message"], reply
        assert ros.spin_until(lambda: states[-1] == "armed", 30)
        ok, reply = client.call("/operator/robot_1/enable", {"data": "yes"})
        assert ok and not reply["success"] and "true or false" in reply["message"], reply
        ok, reply = client.call("/operator/robot_1/enable", {"data": False})
        assert ok and reply["success"], reply
        channel = client.advertise("/robot_1/drive/override", "geometry_msgs/Twist")
        client.wait(lambda: 1 in [k for k, _ in control.channels.values()], 30)
        client.publish(channel, {"linear": {"x": 0.1}, "angular": {"z": -0.2}})
        assert ros.spin_until(lambda: twists, 30)
        assert (twists[-1].twist.linear.x, twists[-1].twist.angular.z) == (0.1, -0.2)
        ok, reply = client.call("/operator/estop", {})
        assert ok and reply["success"] and ros.spin_until(lambda: estops and estops[-1], 30)
        assert control.count == 5 and "estop from view client" in control.last
        assert "controls" in control.diagnostic_values()
        # /view/team: the team's state, robot 1 disabled, the operator's twist in charge of
        # nothing (no executor here), no word yet
        assert ros.spin_until(lambda: v.team_state == "estop", 30)
        assert ros.spin_until(lambda: v.robot_state[1].enabled is False, 30)
        team = view.team_message(v.team_state, v.robot_state)
        assert team["team"] == "estop" and team["robots"][1]["enabled"] is False
        assert team["robots"][0]["word"] is None
    finally:
        client.close()
        server.stop()


def test_off_loopback_only_an_estop_goes_without_the_operators_token():
    from excavation_bringup.view_control import ControlPolicy

    open_, closed = ControlPolicy("127.0.0.1"), ControlPolicy("198.18.0.1")
    keyed = ControlPolicy("198.18.0.1", token="s3cret")
    assert open_.refusal("arm", {}) is None and open_.publish_refusal() is None
    assert closed.refusal("estop", {}) is None
    assert "--operator-token" in closed.refusal("arm", {})
    assert keyed.refusal("arm", {"token": "s3cret"}) is None
    assert keyed.refusal("reset", {"token": "guess"}) == "wrong or missing operator token"
    assert "loopback only" in keyed.publish_refusal()


def test_bad_control_messages_are_refused_with_their_reason():
    from excavation_bringup.view_control import (
        ControlError,
        blade_of,
        parse_request,
        robot_topic,
        twist_of,
    )

    assert parse_request(b"") == {}
    assert robot_topic("/robot_1/blade/commands", 2) == (1, "blade/commands")
    for bad, what in (
        (lambda: parse_request(b"[1]"), "JSON object"),
        (lambda: parse_request(b"{"), "not JSON"),
        (lambda: robot_topic("/robot_2/drive/override", 2), "no robot 2"),
        (lambda: robot_topic("/cmd_vel", 2), "/robot_K/drive/override"),
        (lambda: twist_of({"linear": {"x": float("nan")}}), "finite"),
        (lambda: twist_of({"linear": 3}), "objects"),
        (lambda: blade_of({"data": [0.1, 0.2]}), "one value"),
    ):
        with pytest.raises(ControlError, match=what):
            bad()
    assert twist_of({"angular": {"z": 1}}) == (0.0, 1.0) and blade_of({"data": [0.05]}) == 0.05


def test_the_team_channel_names_each_robots_word():
    pushing = view.RobotState(enabled=True, operator=False, stuck=True, word=1 | 1 << 8)
    state = [pushing, view.RobotState(word=0)]
    msg = view.team_message("armed", state)
    assert msg["team"] == "armed" and msg["robots"][0]["stuck"] is True
    assert msg["robots"][0]["word"].count("+") == 1 and msg["robots"][1]["word"] == "idle"


_REMOTE_CLIENT = """
import json, sys
from excavation_bringup.view_client import ControlClient
client = ControlClient(int(sys.argv[2]), host=sys.argv[1])
out = {}
for name, service, request in (
    ("arm", "/operator/arm", {}),
    ("reset_wrong", "/operator/reset", {"token": "guess"}),
    ("estop", "/operator/estop", {}),
    ("reset_token", "/operator/reset", {"token": sys.argv[3]}),
):
    ok, answer = client.call(service, request)
    out[name] = answer if ok else {"failure": answer}
client.close()
print(json.dumps(out))
"""


@pytest.mark.system
@pytest.mark.serial  # network namespaces: alone, after the parallel part
def test_off_loopback_the_view_takes_only_an_estop_without_the_token(tmp_path):
    """The view and a supervisor on one host (a network namespace, 198.18.0.0/15), a
    Foxglove client on another: arm and a reset with a wrong token are refused by the
    view, an e-stop goes through, a reset with the operator's token too."""
    import json
    import os
    import secrets
    import subprocess
    import sys

    from excavation_bringup.virtual_hosts import VirtualHosts

    dome, other, port = "198.18.9.1", "198.18.9.2", 8799
    token = secrets.token_hex(8)
    env = dict(os.environ, ROS_DOMAIN_ID="7", ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    env["PYTHONPATH"] = str(Path(__file__).parent) + os.pathsep + env.get("PYTHONPATH", "")
    py = sys.executable
    with VirtualHosts([("dome", dome), ("other", other)], "tview") as hosts:
        procs = [
            subprocess.Popen(
                [*hosts.prefix("dome"), py, "-m", "team_supervisor.supervisor_node",
                 "--ros-args", "-p", "robots:=2"],
                env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            ),
            subprocess.Popen(
                [*hosts.prefix("dome"), py, "-m", "excavation_bringup.view", "--robots", "2",
                 "--host", dome, "--port", str(port), "--operator-token", token],
                env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
            ),
        ]  # fmt: skip
        try:
            remote = subprocess.run(
                [*hosts.prefix("other"), py, "-c", _REMOTE_CLIENT, dome, str(port), token],
                env=env, capture_output=True, text=True, timeout=300,
            )  # fmt: skip
        finally:
            for p in procs:
                p.terminate()
            for p in procs:
                p.wait(timeout=30)
    assert remote.returncode == 0, remote.stderr[-3000:]
    out = json.loads(remote.stdout.strip().splitlines()[-1])
    assert not out["arm"]["success"] and "--operator-token" not in out["arm"]["message"]
    assert "wrong or missing operator token" in out["arm"]["message"]
    assert out["reset_wrong"] == {"success": False, "message": out["reset_wrong"]["message"]}
    assert "token" in out["reset_wrong"]["message"]
    assert out["estop"]["success"], out
    assert out["reset_token"]["success"], out
