"""The YAML files in each package's config/ load through --params-file and name real parameters."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1] / "ros2_ws" / "src"


def _make(kind, context, args):
    if kind == "controller":
        from ant_controller.controller import Controller
        from ant_controller.controller_node import ControllerNode

        return ControllerNode(Controller.hand_coded(), context=context, cli_args=args)
    if kind == "server":
        from blueprint_server.server_node import BlueprintServer

        return BlueprintServer(context=context, cli_args=args)
    if kind == "sim":
        from excavation_sim.sim_node import SimNode

        return SimNode(context=context, cli_args=args)
    if kind == "supervisor":
        from team_supervisor.supervisor_node import SupervisorNode

        return SupervisorNode(context=context, cli_args=args)
    from blade_driver.driver_node import BladeDriverNode

    return BladeDriverNode(context=context, cli_args=args)


@pytest.mark.parametrize(
    ("kind", "path"),
    [
        ("controller", "ant_controller/config/controller.yaml"),
        ("server", "blueprint_server/config/server.yaml"),
        ("sim", "excavation_sim/config/sim.yaml"),
        ("driver", "blade_driver/config/driver.yaml"),
        ("supervisor", "team_supervisor/config/supervisor.yaml"),
    ],
)
def test_config_file_sets_every_parameter(ros, kind, path, tmp_path):
    values = yaml.safe_load((ROOT / path).read_text())["/**"]["ros__parameters"]
    # Change one numeric value so the test sees the file, not the defaults.
    key = next(k for k, v in values.items() if isinstance(v, float))
    values[key] = values[key] * 2 + 1.0
    changed = tmp_path / "params.yaml"
    changed.write_text(yaml.safe_dump({"/**": {"ros__parameters": values}}))
    node = _make(kind, ros.context, ["--ros-args", "--params-file", str(changed)])
    try:
        declared = set(node._parameters)
        assert set(values) <= declared, f"{path} names unknown parameters"
        assert set(declared) - {"use_sim_time", "start_type_description_service"} <= set(values), (
            f"{path} misses parameters"
        )
        assert node.get_parameter(key).value == values[key]
    finally:
        node.destroy_node()
