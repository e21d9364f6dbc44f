"""Every node of the suite reports its state on /diagnostics, even with nothing to do."""

from __future__ import annotations

import pytest
from helpers.diagnostics import DiagnosticsProbe
from rclpy.node import Node
from rclpy.parameter import Parameter


def _node(kind, context, tmp_path):
    if kind == "controller":
        from ant_controller.controller import Controller
        from ant_controller.controller_node import ControllerNode

        return ControllerNode(Controller.hand_coded(), context=context)
    if kind == "server":
        from blueprint_server.server_node import BlueprintServer

        return BlueprintServer(context=context)
    if kind == "sim":
        from excavation_sim.sim_node import SimNode

        return SimNode(context=context)
    if kind == "driver":
        from blade_driver.driver_node import BladeDriverNode

        return BladeDriverNode(context=context)
    if kind == "supervisor":
        from team_supervisor.supervisor_node import SupervisorNode

        return SupervisorNode(context=context)
    if kind == "sensors":
        from excavation_sim.sensors_node import SensorsNode

        return SensorsNode(context=context)
    if kind == "localizer":
        from overhead_localizer.beacons import CONFIG_DIR
        from overhead_localizer.localizer_node import LocalizerNode

        calibration = Parameter("calibration", value=str(CONFIG_DIR / "camera_sim.yaml"))
        return LocalizerNode(context=context, parameter_overrides=[calibration])
    if kind == "mapper":
        from terrain_mapper.mapper_node import MapperNode

        return MapperNode(context=context)
    if kind == "recorder":
        from excavation_bags.recorder_node import RecorderNode

        out = Parameter("out", value=str(tmp_path / "bag"))
        return RecorderNode(context=context, parameter_overrides=[out])
    from excavation_bags.player_node import PlayerNode

    bag = Parameter("bag", value="bags/sample")
    topics = Parameter("topics", value=["/worksite/fitness"])
    return PlayerNode(context=context, parameter_overrides=[bag, topics])


@pytest.mark.parametrize(
    "kind",
    [
        "controller",
        "server",
        "sim",
        "driver",
        "supervisor",
        "sensors",
        "localizer",
        "mapper",
        "recorder",
        "player",
    ],
)
def test_node_publishes_diagnostics(ros, kind, tmp_path):
    node = ros.add(_node(kind, ros.context, tmp_path))
    probe = DiagnosticsProbe(ros.add(Node("watcher", context=ros.context)))
    try:
        assert ros.spin_until(lambda: probe.statuses, timeout=10.0), f"{kind}: no diagnostics"
        assert all(s.message for s in probe.statuses)
    finally:
        if kind == "recorder":
            node.close()
