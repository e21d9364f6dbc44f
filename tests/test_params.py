"""Node parameters declared from frozen dataclasses (excavation_common.params and .ros)."""

from __future__ import annotations

from dataclasses import dataclass

import pytest
from rcl_interfaces.msg import ParameterType
from rclpy.node import Node
from rclpy.parameter import Parameter

from excavation_common.params import ParameterError, defaults, param, replace, validate


@dataclass(frozen=True)
class Demo:
    rate: float = param(10.0, "Hz", low=0.5, high=100.0, read_only=False)
    robots: int = param(4, "team size", low=1, high=8)
    backend: str = param("sim", "backend", choices=("sim", "serial"))
    joints: tuple = param(["blade"], "joint names")
    verbose: bool = param(False, "chatty", read_only=False)

    def check(self) -> None:
        if self.backend == "serial" and self.robots > 2:
            raise ValueError("at most 2 robots on one serial board")


def test_defaults_and_validation():
    assert validate(Demo, {}) == Demo()
    assert defaults(Demo)["joints"] == ("blade",)
    assert validate(Demo, {"rate": 20, "joints": ["a", "b"]}).joints == ("a", "b")
    for values, match in [
        ({"rate": 0.1}, r"rate = 0.1: must be >= 0.5"),
        ({"robots": 9}, r"robots = 9: must be <= 8"),
        ({"robots": True}, "expected an integer"),
        ({"backend": "can"}, "must be one of sim, serial"),
        ({"verbose": 1}, "expected true or false"),
        ({"backend": "serial"}, "at most 2 robots"),
        ({"nope": 1}, "unknown parameter"),
    ]:
        with pytest.raises(ParameterError, match=match):
            validate(Demo, values, "/demo")


def test_replace_refuses_read_only_and_bad_values():
    d = Demo()
    assert replace(d, {"rate": 50.0}).rate == 50.0
    with pytest.raises(ParameterError, match="read-only"):
        replace(d, {"robots": 2})
    with pytest.raises(ParameterError, match="must be <= 100"):
        replace(d, {"rate": 1000.0})


def test_declare_params_on_a_node(ros):
    from excavation_common.ros import declare_params

    seen = []
    node = ros.add(
        Node("demo", context=ros.context, parameter_overrides=[Parameter("robots", value=2)])
    )
    params = declare_params(node, Demo, on_change=seen.append)
    assert params == Demo(robots=2)
    described = node.describe_parameter("rate")
    assert described.type == ParameterType.PARAMETER_DOUBLE
    assert described.floating_point_range[0].from_value == 0.5
    assert node.describe_parameter("robots").read_only
    assert node.get_parameter("joints").value == ["blade"]
    # runtime: applied, rejected with a reason, never silently ignored
    (ok,) = node.set_parameters([Parameter("rate", value=25.0)])
    assert ok.successful and seen[-1].rate == 25.0
    (bad,) = node.set_parameters([Parameter("robots", value=3)])
    assert not bad.successful and "read-only" in bad.reason
    (bad,) = node.set_parameters([Parameter("rate", value=500.0)])
    assert not bad.successful
    assert seen[-1].rate == 25.0


def test_declare_params_turns_rclpy_refusals_into_one_line(ros):
    from excavation_common.ros import declare_params

    for override, match in [
        (Parameter("rate", value=0.0), r"rate = 0: must be >= 0.5"),
        (Parameter("rate", value=10), r"rate = '10': expected DOUBLE, got INTEGER \(write 10.0\)"),
        (Parameter("backend", value="can"), "must be one of"),
    ]:
        node = ros.add(Node("demo", context=ros.context, parameter_overrides=[override]))
        with pytest.raises(ParameterError, match=match):
            declare_params(node, Demo)


def test_without_on_change_runtime_changes_are_refused(ros):
    from excavation_common.ros import declare_params

    node = ros.add(Node("demo", context=ros.context))
    declare_params(node, Demo)
    (result,) = node.set_parameters([Parameter("rate", value=25.0)])
    assert not result.successful and "read at start only" in result.reason
