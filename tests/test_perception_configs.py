"""The localizer's and the mapper's config YAML load through --params-file and name every
declared parameter; bad values at start are refused with the parameter's name."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from rclpy.parameter import Parameter

from excavation_common.params import ParameterError
from overhead_localizer.beacons import CONFIG_DIR

ROOT = Path(__file__).resolve().parents[1] / "ros2_ws" / "src"


def _make(kind, context, args=None, overrides=()):
    if kind == "localizer":
        from overhead_localizer.localizer_node import LocalizerNode

        calibration = Parameter("calibration", value=str(CONFIG_DIR / "camera_sim.yaml"))
        return LocalizerNode(
            context=context, cli_args=args, parameter_overrides=[calibration, *overrides]
        )
    from terrain_mapper.mapper_node import MapperNode

    return MapperNode(context=context, cli_args=args, parameter_overrides=list(overrides))


@pytest.mark.parametrize(
    ("kind", "path"),
    [
        ("localizer", "overhead_localizer/config/localizer.yaml"),
        ("mapper", "terrain_mapper/config/mapper.yaml"),
    ],
)
def test_config_file_sets_every_parameter(ros, kind, path, tmp_path):
    values = yaml.safe_load((ROOT / path).read_text())[kind]["ros__parameters"]
    values.pop("calibration", None)  # given per test
    key = next(k for k, v in values.items() if isinstance(v, float) and v > 0)
    values[key] = min(values[key] * 1.5, 0.49) if key == "edge_margin" else values[key] * 1.5
    changed = tmp_path / "params.yaml"
    changed.write_text(yaml.safe_dump({kind: {"ros__parameters": values}}))
    node = _make(kind, ros.context, ["--ros-args", "--params-file", str(changed)])
    try:
        declared = set(node._parameters) - {"use_sim_time", "start_type_description_service"}
        assert set(values) <= declared, f"{path} names unknown parameters"
        assert declared - {"calibration"} <= set(values), f"{path} misses {declared - set(values)}"
        assert node.get_parameter(key).value == values[key]
    finally:
        node.destroy_node()


@pytest.mark.parametrize(
    ("kind", "name", "value", "match"),
    [
        ("localizer", "min_value", 300, "min_value = 300: must be <= 255"),
        ("localizer", "robots", 0, "robots = 0: must be >= 1"),
        ("mapper", "tilt_offset", 0.9, "tilt_offset = 0.9: must be <= 0.5"),
        ("mapper", "sweep_scans", 1, "sweep_scans = 1: must be >= 2"),
    ],
)
def test_bad_values_at_start_are_refused(ros, kind, name, value, match):
    with pytest.raises(ParameterError, match=match):
        _make(kind, ros.context, overrides=[Parameter(name, value=value)])


def test_runtime_changes_are_rejected_with_a_reason(ros):
    node = _make("mapper", ros.context)
    try:
        result = node.set_parameters([Parameter("tilt_offset", value=0.1)])[0]
        assert not result.successful and "read-only" in result.reason
    finally:
        node.destroy_node()
