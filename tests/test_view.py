"""ant-view: a WebSocket client subscribes to its Foxglove channels during a trial and decodes
robot poses and the height map."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
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

    from ant_controller.controller import Controller
    from ant_controller.controller_node import ControllerNode
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
            ros.add(
                ControllerNode(
                    Controller.hand_coded(),
                    context=ros.context,
                    namespace=f"/robot_{k}",
                    parameter_overrides=[
                        Parameter("robot_id", value=k),
                        Parameter("robots", value=2),
                        Parameter("lockstep", value=True),
                    ],
                )
            )
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
    ):
        assert topic in text, topic


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
