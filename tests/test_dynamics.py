"""Continuous-motion simulator core: the executor on it ends where the world model does."""

from __future__ import annotations

import numpy as np
import pytest

from ant_controller.controller import Controller, ControllerCore
from ant_controller.layout import BLADE_BELOW, MOVE_FORWARD, THROTTLE_UP, TURN_RIGHT
from blade_driver.core import blade_setting
from blueprint_server.blueprint import default_blueprint
from drive_executor.core import DriveExecutorCore, ReportStatus
from drive_executor.goals import ABORTED, LEFT, RIGHT, SUCCEEDED, DriveGoal
from drive_executor.params import ExecutorParams
from drive_executor.primitives import Pose2D
from excavation_common.safety import ARMED, MotionGate
from excavation_sim.dynamics import Dynamics, DynamicsParams
from excavation_sim.world import BLADE, COL, HEADING, ROW, STUCK, World, next_random

CELL = 0.25


def drive(dyn: Dynamics, k: int, word: int, turn: int = 0, params=None, limit=4000):
    """Run one word of robot k through an executor on the dynamics; returns (code, stuck)."""
    gate = MotionGate(active=True, enabled=True)
    core = DriveExecutorCore(params or ExecutorParams(cell_size=CELL), gate)
    dyn.throttle[k] = bool((word >> THROTTLE_UP) & 1)
    t = dyn.time
    gate.on_heartbeat(ARMED, t)
    core.submit(DriveGoal(0, word, turn), t)
    for _ in range(limit):
        gate.on_heartbeat(ARMED, dyn.time)
        twist = core.on_pose(Pose2D(*dyn.measured(k)), dyn.time, dyn.time)
        for event in core.drain():
            if isinstance(event, ReportStatus) and event.code in (SUCCEEDED, ABORTED):
                dyn.command(k, 0.0, 0.0)
                return event.code, event.stuck
        dyn.command(k, twist.linear, twist.angular)
        dyn.step()
    raise AssertionError("goal did not end")


def world_turn(world: World) -> int:
    probe = world.rng.copy()
    return RIGHT if next_random(probe) >> np.uint64(63) else LEFT


def random_world(rng, index: int, robots: int = 1) -> World:
    bp = default_blueprint(1)
    world = World.scenario(bp.zones, bp.goal, robots, 11, index)
    world.heights[:] = rng.integers(-2, 3, world.heights.shape)
    world.robots[:, BLADE] = rng.integers(0, 4, robots)
    return world


def test_exact_dynamics_with_the_executor_equals_the_world_model():
    """Random words, terrain, blades and poses: heights, grid pose and U1 as world.step gives."""
    rng = np.random.default_rng(3)
    refused = 0
    for i in range(300):
        world = random_world(rng, i)
        word = int(rng.integers(0, 4096))
        ref = world.copy()
        turn = world_turn(world)
        ref.step(np.array([word]))
        dyn = Dynamics(world, DynamicsParams.exact(), CELL, np.random.default_rng(0))
        code, stuck = drive(dyn, 0, word, turn)
        dyn.set_blade(0, blade_setting(word, int(world.robots[0, BLADE])))
        assert np.array_equal(world.heights, ref.heights), (i, word)
        assert np.array_equal(world.robots[0, :4], ref.robots[0, :4]), (i, word)
        assert stuck == bool(ref.robots[0, STUCK]) == (code == ABORTED), (i, word)
        assert world.heights.sum() == ref.heights.sum()
        refused += dyn.counters.refused
    assert refused > 20  # the sample exercises refused moves


def test_pushing_beyond_capacity_stalls_reports_u1_and_the_controller_reacts():
    bp = default_blueprint(1)
    world = World.scenario(bp.zones, bp.goal, 1, 0, 0)
    world.robots[0, :3] = (4, 4, 0)  # facing north
    world.robots[0, BLADE] = BLADE_BELOW
    world.heights[6, 4:6] = 5  # blade cells: 16 units against the blade, capacity 12
    before = world.heights.copy()
    dyn = Dynamics(world, DynamicsParams.exact(), CELL, np.random.default_rng(0))
    code, stuck = drive(dyn, 0, 1 << MOVE_FORWARD)
    assert code == ABORTED and stuck and dyn.counters.refused >= 1
    assert np.array_equal(world.heights, before)
    assert tuple(world.robots[0, :3]) == (4, 4, 0)
    assert abs(dyn.offset(0)) < 0.05  # settled back on its cell centre
    ctl = ControllerCore(Controller.hand_coded())
    poses = world.robots[:, :3].copy()
    blade, volume = int(world.robots[0, BLADE]), 0
    calm = ControllerCore(Controller.hand_coded()).decide(
        world.heights, world.zones, world.goal, poses, 0, blade, volume, False
    )
    reacted = ctl.decide(world.heights, world.zones, world.goal, poses, 0, blade, volume, stuck)
    assert reacted != calm
    assert (reacted >> THROTTLE_UP) & 1  # the paper's rule when stuck: throttle up, turn away
    # With throttle up (24 units of capacity) the same push goes through.
    code, stuck = drive(dyn, 0, 1 << MOVE_FORWARD | 1 << THROTTLE_UP)
    assert code == SUCCEEDED and not stuck and tuple(world.robots[0, :2]) == (5, 4)
    assert world.heights.sum() == before.sum() and world.heights[7, 4:6].sum() > 0


def test_a_blocked_robot_never_overlaps_the_one_in_its_way():
    bp = default_blueprint(1)
    world = World.scenario(bp.zones, bp.goal, 2, 0, 0)
    world.robots[0, :3] = (4, 4, 0)
    world.robots[1, :3] = (6, 4, 2)  # nose to nose
    dyn = Dynamics(world, DynamicsParams.exact(), CELL, np.random.default_rng(0))
    code, stuck = drive(dyn, 0, 1 << MOVE_FORWARD)
    assert stuck and tuple(world.robots[0, :2]) == (4, 4)
    gap = dyn.bodies[1, 1] - dyn.bodies[0, 1]
    assert gap >= 2 * CELL - dyn.params.commit_fraction * CELL - 1e-9


def test_wheel_speed_limit_keeps_the_turn_to_drive_ratio():
    dyn = Dynamics(random_world(np.random.default_rng(0), 0), DynamicsParams.exact(), CELL, None)
    v, w = dyn.wheel_speeds(1.0, 1.0)
    top = dyn.params.max_wheel_speed
    assert abs(v) + abs(w) * dyn.params.track_width / 2 == pytest.approx(top)
    assert w / v == pytest.approx(1.0)


def test_default_slip_and_noise_still_reach_the_cells():
    rng = np.random.default_rng(5)
    world = random_world(rng, 0)
    world.heights[:] = 0
    world.robots[0, :3] = (6, 6, 1)
    dyn = Dynamics(world, DynamicsParams(), CELL, np.random.default_rng(1))
    for word in (1 << MOVE_FORWARD, 1 << 4, 1 << MOVE_FORWARD, 1 << 5 | 1 << 2):
        code, stuck = drive(dyn, 0, word)
        assert code == SUCCEEDED and not stuck
    assert tuple(world.robots[0, :3]) == (6, 7, 1)
    assert dyn.bodies[0, 0] != pytest.approx((7 + 1) * CELL, abs=1e-9)  # noise did act


def test_same_seed_same_run():
    word = 1 << MOVE_FORWARD | 1 << TURN_RIGHT

    def start():
        world = random_world(np.random.default_rng(2), 0)
        world.heights[:] = 0
        world.robots[0, :3] = (6, 6, 1)
        return world

    def run(seed):
        world = start()
        dyn = Dynamics(world, DynamicsParams(), CELL, np.random.default_rng(seed))
        drive(dyn, 0, word)
        return dyn.bodies.copy(), tuple(int(v) for v in world.robots[0, [ROW, COL, HEADING]])

    a, b, c = run(4), run(4), run(5)
    assert np.array_equal(a[0], b[0]) and a[1:] == b[1:]
    assert not np.array_equal(a[0], c[0])
    # Another seed's noise moves the body elsewhere, not the robot off its cells: both end
    # where the world model's step puts it (one cell east, turned to face south).
    model = start()
    model.step(np.array([word]))
    assert a[1] == c[1] == tuple(int(v) for v in model.robots[0, [ROW, COL, HEADING]])
    assert a[1] == (6, 7, 2)


def test_warming_the_kernels_changes_nothing():
    """``Dynamics.warm`` runs a grid event's kernels on copies: the world is untouched."""
    from excavation_sim.sim_node import scenario_world

    _, world = scenario_world("default", 2, 0, 0)
    before = (world.heights.copy(), world.robots.copy(), world.active.copy(), world.rng.copy())
    sim = Dynamics(world, DynamicsParams.exact(), 0.25, np.random.default_rng(0))
    sim.warm()
    after = (world.heights, world.robots, world.active, world.rng)
    assert all(np.array_equal(a, b) for a, b in zip(before, after, strict=True))
    assert sim.counters == type(sim.counters)() and sim.time == 0.0


def test_the_world_result_goes_through_json_and_back():
    """``dynamics``' ``world.json``: the record comes back; physical soil's fields only with
    physical soil; a missing field is named."""
    import json

    from excavation_sim.dynamics import WorldResult

    grid = WorldResult(0.5, [[0, 1]], {"tick 0": 0.25}, 3.0, 60, 0)
    assert "volume" not in grid.to_json()
    assert WorldResult.from_json(json.loads(json.dumps(grid.to_json()))) == grid
    soil = WorldResult(0.5, [[0, 1]], {"tick 0": 0.25}, 3.0, 60, 1, [[0.0, 1.25]], 0, 7)
    assert WorldResult.from_json(json.loads(json.dumps(soil.to_json()))) == soil
    data = grid.to_json()
    del data["snapshots"]
    with pytest.raises(ValueError, match="w.json: no field 'snapshots'"):
        WorldResult.from_json(data, "w.json")
