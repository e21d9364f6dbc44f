"""The field nodes' config/*.yaml name exactly their parameters and load via --params-file."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1] / "ros2_ws" / "src"


def _make(kind, context, args):
    if kind == "executor":
        from drive_executor.executor_node import ExecutorNode

        return ExecutorNode(context=context, namespace="/robot_0", cli_args=args)
    if kind == "dynamics":
        from excavation_sim.dynamics_node import DynamicsNode

        return DynamicsNode(context=context, cli_args=args)
    from team_tick.node import TeamTickNode

    return TeamTickNode(context=context, cli_args=args)


@pytest.mark.parametrize(
    ("kind", "path"),
    [
        ("executor", "drive_executor/config/executor.yaml"),
        ("dynamics", "excavation_sim/config/dynamics.yaml"),
        ("team_tick", "team_tick/config/team_tick.yaml"),
    ],
)
def test_config_file_sets_every_parameter(ros, kind, path, tmp_path):
    values = yaml.safe_load((ROOT / path).read_text())["/**"]["ros__parameters"]
    key = next(k for k, v in values.items() if isinstance(v, float) and k != "throttle_speed")
    values[key] = values[key] * 1.5
    changed = tmp_path / "params.yaml"
    changed.write_text(yaml.safe_dump({"/**": {"ros__parameters": values}}))
    node = _make(kind, ros.context, ["--ros-args", "--params-file", str(changed)])
    try:
        declared = set(node._parameters) - {"use_sim_time", "start_type_description_service"}
        assert declared == set(values), path
        assert node.get_parameter(key).value == values[key]
    finally:
        node.destroy_node()
