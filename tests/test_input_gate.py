"""The controller's input gate and lockstep barrier, without rclpy.init."""

from __future__ import annotations

import numpy as np
import pytest

from ant_controller.input_gate import UNKNOWN, ControllerParams, InputGate
from blueprint_server.blueprint import default_blueprint
from excavation_common.params import ParameterError, validate


def ready_gate(robots=3, lockstep=False):
    g = InputGate(
        0, robots, pose_timeout=0.5, map_timeout=2.0, joint_timeout=0.5, lockstep=lockstep
    )
    bp = default_blueprint(1)
    g.zones, g.goal, g.cell_size = bp.zones, bp.goal, 0.25
    return g


def feed(g, now, stamp, robots):
    for j in robots:
        g.on_pose(j, now, (2 + 3 * j, 2, 0), stamp)
    g.on_heights(now, np.zeros((16, 16), dtype=np.int32), stamp)
    g.on_joint(now, (3, 0), stamp)
    g.on_stuck(now, False)


def test_fresh_inputs_then_stale_pose_of_another_robot():
    g = ready_gate()
    assert g.missing(0.0) == "no own pose"
    feed(g, 0.0, (0, 0), range(3))
    assert g.missing(0.1) is None
    feed(g, 1.0, (1, 0), [0])  # robots 1 and 2 go silent
    assert g.missing(1.1) == "pose of robot 1 is stale (1.10 s)"
    g.on_enabled(1, False)
    g.on_enabled(2, False)  # the supervisor disables them: absent, not waited for
    assert g.missing(1.1) is None
    assert g.active().tolist() == [True, False, False]
    g.on_enabled(0, False)
    assert g.missing(1.1) == "this robot is disabled (supervisor)"


def test_unknown_terrain_and_off_site_pose():
    g = ready_gate(robots=1)
    feed(g, 0.0, (0, 0), [0])
    heights = np.zeros((16, 16), dtype=np.int32)
    heights[3, 3] = UNKNOWN
    g.on_heights(0.0, heights, (0, 0))
    assert g.missing(0.0) == "unknown terrain around the robot"
    g.on_pose(0, 0.0, (15, 3, 0), (0, 0))
    assert "off the 16 x 16 worksite" in g.missing(0.0)


def test_lockstep_decides_once_per_tick_and_skips_disabled_robots():
    g = ready_gate(lockstep=True)
    feed(g, 0.0, (0, 0), range(3))
    assert g.lockstep_ready(100.0)  # ages do not count in lockstep mode
    assert not g.lockstep_ready(100.0)  # once per tick
    feed(g, 1.0, (1, 0), [0, 1])  # robot 2's pose of tick 1 never comes
    assert not g.lockstep_ready(1.0)
    g.on_enabled(2, False)  # lost and disabled: tick 1 can be decided without it
    assert g.lockstep_ready(1.0)
    assert g.pose_array()[2].tolist() == [8, 2, 0]  # its last pose is kept, but inactive
    feed(g, 2.0, (2, 0), [0, 1])
    g.fresh_stuck = 0  # no stuck flag of tick 2 yet
    assert not g.lockstep_ready(2.0)
    g.on_stuck(2.0, False)
    assert g.lockstep_ready(2.0)


@pytest.mark.parametrize(
    ("values", "match"),
    [
        ({"rate": 0.0}, "rate"),
        ({"robot_id": 4, "robots": 4}, "outside the team of 4"),
        ({"robots": 0}, "robots"),
        ({"blade_home": 0.01}, "blade_home"),
    ],
)
def test_bad_parameters_are_named(values, match):
    with pytest.raises(ParameterError, match=match):
        validate(ControllerParams, values, "/robot_0/controller")
