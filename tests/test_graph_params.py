"""The trial graph's typed node parameters (``excavation_bringup.node_params``)."""

from __future__ import annotations

import pytest
from team_tick.core import TeamTickParams
from team_tick.node import TeamTickNodeParams

from drive_executor.params import ExecutorParams
from excavation_bringup.deployment import Deployment
from excavation_bringup.graph import GraphError, build
from excavation_bringup.node_params import NodeParams
from excavation_common.params import ParameterError


def test_values_are_typed_and_checked_when_built():
    """Derived and tuned values fill the kind's dataclasses; an integer for a double becomes
    the double rclpy needs; the mapping lists what was given, in order."""
    p = NodeParams.build("executor", "executor_0", {"cell_size": 1, "seed": 7}, {"max_speed": 0.1})
    assert isinstance(p.typed(ExecutorParams), ExecutorParams)
    assert p["cell_size"] == 1.0 and type(p["cell_size"]) is float
    assert list(p) == ["max_speed", "cell_size", "seed"] and p.derived == {"cell_size", "seed"}
    assert p.value("rate") == ExecutorParams().rate and "rate" not in p  # a default, not given
    assert p.ros() == {"max_speed": 0.1, "cell_size": 1.0, "seed": 7}
    with pytest.raises(ParameterError, match="executor_0: cell_size = 'big': expected a number"):
        NodeParams.build("executor", "executor_0", {"cell_size": "big"})
    with pytest.raises(ParameterError, match="executor has no such parameter"):
        NodeParams.build("executor", "executor_0", {"cell_sise": 0.25})
    with pytest.raises(ParameterError, match="both derived and tuned"):
        NodeParams.build("executor", "executor_0", {"seed": 1}, {"seed": 2})


def test_a_kind_with_two_dataclasses_splits_its_values():
    p = NodeParams.build("team_tick", "team_tick", {"robots": 3, "blade_in": "blade/x"})
    assert p.typed(TeamTickParams).robots == 3
    assert p.typed(TeamTickNodeParams).blade_in == "blade/x"
    with pytest.raises(KeyError, match="ExecutorParams"):
        p.typed(ExecutorParams)


def test_overrides_apply_to_tuned_values_and_are_refused_on_derived_ones():
    derived = {"cell_size": 0.25, "seed": 7}
    tuned = {"position_tolerance": 0.012}
    p = NodeParams.build(
        "executor",
        "executor_0",
        derived,
        tuned,
        {"position_tolerance": 0.015, "time_allowance": 20, "seed": 3},
        "site.yaml",
    )
    assert p["position_tolerance"] == 0.015 and p["time_allowance"] == 20.0
    assert p["seed"] == 7  # the derived value stands
    assert [str(e) for e in p.problems] == [
        "site.yaml: overrides.executor.seed = 3: the graph sets it from the site file or the "
        "run's options (excavation_bringup.nodes.executor): change the site's own field"
    ]


def test_each_refused_override_is_one_problem_and_the_rest_apply():
    p = NodeParams.build(
        "executor",
        "executor_0",
        {"cell_size": 0.25},
        overrides={"max_speed": "fast", "mode": "auto", "rate": 50},
        where="site.yaml",
    )
    assert [e.field for e in p.problems] == [
        "overrides.executor.max_speed",
        "overrides.executor.mode",
    ]
    assert p["rate"] == 50.0
    rule = NodeParams.build("executor", "e", {}, overrides={"max_speed": 0.2}, where="s.yaml")
    assert [str(e) for e in rule.problems] == [
        "s.yaml: overrides.executor = {'max_speed': 0.2}: throttle_speed 0.15 < max_speed 0.2"
    ]
    assert "max_speed" not in rule


def test_updated_checks_each_value():
    p = NodeParams.build("team_tick", "team_tick", {"robots": 2})
    q = p.updated("team_tick", motion_limit=60)
    assert q["motion_limit"] == 60.0 and p.get("motion_limit") is None
    with pytest.raises(ParameterError, match="blade_wait = -1.0: must be >= 0.0"):
        p.updated("team_tick", blade_wait=-1.0)
    with pytest.raises(ParameterError, match="unknown parameter"):
        p.updated("team_tick", blade_waits=1.0)


def test_a_trial_graph_is_built_from_typed_parameters(tmp_path):
    """Every node of a process trial's graph holds its kind's dataclasses, no problems."""
    dep = Deployment("hand-coded", robots=2, steps=3, seed=1, drive="continuous")
    graph = build(dep, tmp_path)
    assert graph.problems() == []
    executor = graph.spec("executor_1")
    assert executor.params.typed(ExecutorParams).seed == executor.params["seed"]
    assert executor.sim_time and executor.ros_params()["use_sim_time"] is True
    assert "use_sim_time" not in executor.params


def test_graph_error_lists_every_problem():
    errors = NodeParams.build("executor", "e", {}, overrides={"mode": "x", "rate": "y"}).problems
    exc = GraphError(list(errors))
    assert str(exc).count("\n") == 1 and exc.problems == list(errors)
