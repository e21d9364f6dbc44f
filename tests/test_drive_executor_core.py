"""Drive executor core (no rclpy): words as primitives, closed loop, time-outs, gate, override."""

from __future__ import annotations

import dataclasses
import math
import typing

import numpy as np
import pytest

from ant_controller.layout import (
    MOVE_BACKWARD,
    MOVE_FORWARD,
    RANDOM_TURN,
    THROTTLE_UP,
    TURN_LEFT,
    TURN_RIGHT,
)
from blueprint_server.blueprint import default_blueprint
from drive_executor.core import (
    DriveExecutorCore,
    DriveStep,
    ExecutorEvent,
    ReportStatus,
    SetThrottle,
    TurnStep,
    plan,
)
from drive_executor.errors import GoalError
from drive_executor.goals import (
    ABORTED,
    EXECUTING,
    LEFT,
    RIGHT,
    SUCCEEDED,
    DriveGoal,
    goal_from_message,
    goal_message,
)
from drive_executor.params import ExecutorParams
from drive_executor.primitives import DriveCells, Limits, Pose2D, Status, Turn, Twist2D
from excavation_common.frames import heading_to_yaw, robot_anchor, robot_center, yaw_to_heading
from excavation_common.params import ParameterError, validate
from excavation_common.safety import ARMED, PAUSED, MotionGate
from excavation_sim.world import COL, HEADING, ROW, World, next_random

CELL = 0.25
DT = 0.05


def armed_gate(now: float = 0.0) -> MotionGate:
    gate = MotionGate(active=True, enabled=True)
    gate.on_heartbeat(ARMED, now)
    return gate


class Plant:
    """A perfect unicycle: the twist is the motion."""

    def __init__(self, x: float, y: float, yaw: float) -> None:
        self.x, self.y, self.yaw = x, y, yaw

    def pose(self) -> Pose2D:
        return Pose2D(self.x, self.y, self.yaw)

    def apply(self, twist: Twist2D, dt: float = DT) -> None:
        self.x += twist.linear * math.cos(self.yaw) * dt
        self.y += twist.linear * math.sin(self.yaw) * dt
        self.yaw += twist.angular * dt


def statuses(events) -> list[ReportStatus]:
    return [e for e in events if isinstance(e, ReportStatus)]


def codes(events) -> list[int]:
    return [e.code for e in statuses(events)]


def run_goal(core, gate, plant, goal, t=0.0, limit=2000, move=True):
    """Drive a goal to its end; returns (final status event, time, twists)."""
    core.submit(goal, t)
    twists = []
    for _ in range(limit):
        gate.on_heartbeat(ARMED, t)
        twist = core.on_pose(plant.pose(), t, t)
        twists.append(twist)
        ends = [e for e in statuses(core.drain()) if e.code in (SUCCEEDED, ABORTED)]
        if ends:
            return ends[0], t, twists
        if move:
            plant.apply(twist)
        t += DT
    raise AssertionError("goal did not end")


def world_direction(rng_state: np.ndarray) -> int:
    """The direction the world model's next random turn takes (its own rule)."""
    probe = rng_state.copy()
    return RIGHT if next_random(probe) >> np.uint64(63) else LEFT


def test_every_word_ends_where_the_world_model_puts_the_robot():
    """All 4096 words from random interior poses, a perfect plant: the world model's cell."""
    bp = default_blueprint(1)
    rng = np.random.default_rng(7)
    params = ExecutorParams(cell_size=CELL)
    for word in range(4096):
        world = World.scenario(bp.zones, bp.goal, 1, 0, word)
        world.robots[0, ROW] = rng.integers(2, 12)
        world.robots[0, COL] = rng.integers(2, 12)
        world.robots[0, HEADING] = rng.integers(0, 4)
        turn = world_direction(world.rng)
        x, y = robot_center(int(world.robots[0, ROW]), int(world.robots[0, COL]), CELL)
        yaw = heading_to_yaw(int(world.robots[0, HEADING]))
        plant = Plant(x + rng.normal(0, 0.003), y + rng.normal(0, 0.003), yaw + rng.normal(0, 0.02))
        world.step(np.array([word]))
        gate = armed_gate()
        core = DriveExecutorCore(params, gate)
        end, _, _ = run_goal(core, gate, plant, DriveGoal(word, word, turn))
        assert end.code == SUCCEEDED and not end.stuck, word
        row, col = robot_anchor(plant.x, plant.y, CELL)
        assert (row, col, yaw_to_heading(plant.yaw)) == (
            int(world.robots[0, ROW]),
            int(world.robots[0, COL]),
            int(world.robots[0, HEADING]),
        ), word


def test_plan_follows_table_2_order_and_nets_the_turns():
    fwd, back = 1 << MOVE_FORWARD, 1 << MOVE_BACKWARD
    assert plan(fwd | back, 0) == [DriveStep(1), DriveStep(-1)]
    assert plan(1 << TURN_RIGHT | 1 << TURN_LEFT, 0) == []
    assert plan(1 << RANDOM_TURN | 1 << TURN_RIGHT, RIGHT) == [TurnStep(1), TurnStep(1)]
    assert plan(1 << RANDOM_TURN | 1 << TURN_RIGHT, LEFT) == []
    assert plan(fwd | 1 << TURN_LEFT, 0) == [DriveStep(1), TurnStep(-1)]
    assert (
        plan(0xFFF & ~(fwd | back | 1 << RANDOM_TURN | 1 << TURN_RIGHT | 1 << TURN_LEFT), 0) == []
    )


def test_bad_words_and_goals_are_refused():
    with pytest.raises(GoalError, match="12-bit"):
        plan(0x1000, 0)
    with pytest.raises(GoalError, match="direction"):
        plan(1 << RANDOM_TURN, 0)
    msg = goal_message(DriveGoal(3, 5))
    msg.word = 0x1000
    with pytest.raises(GoalError, match="beyond the 12 behaviours"):
        goal_from_message(msg)
    msg = goal_message(DriveGoal(3, 5))
    msg.turn = 2
    with pytest.raises(GoalError, match="turn"):
        goal_from_message(msg)
    good = goal_message(DriveGoal(12345, 0xABC, LEFT, 2, (12, 5)))
    assert goal_from_message(good) == DriveGoal(12345, 0xABC, LEFT, 2, (12, 5))
    gate = armed_gate()
    core = DriveExecutorCore(ExecutorParams(), gate)
    core.submit(DriveGoal(0, 0x1FFF), 0.0)
    assert statuses(core.drain()) == [ReportStatus(DriveGoal(0, 0x1FFF), ABORTED, True)]
    assert not core.busy


def test_random_turn_without_a_direction_uses_the_executor_s_own_seeded_generator():
    def direction(seed):
        core = DriveExecutorCore(ExecutorParams(seed=seed), armed_gate())
        core.submit(DriveGoal(0, 1 << RANDOM_TURN), 0.0)
        return core.queue[0].direction

    draws = [direction(s) for s in range(20)]
    assert draws == [direction(s) for s in range(20)]
    assert set(draws) == {RIGHT, LEFT}


def test_blocked_robot_times_out_stops_and_reports_stuck():
    """A plant that does not move: no progress, abort, zero twist, settle, U1."""
    gate = armed_gate()
    params = ExecutorParams(progress_window=0.5)
    core = DriveExecutorCore(params, gate)
    plant = Plant(*robot_center(4, 4, CELL), heading_to_yaw(0))
    end, t, twists = run_goal(core, gate, plant, DriveGoal(0, 1 << MOVE_FORWARD), move=False)
    assert end.code == ABORTED and end.stuck
    assert core.counters.primitives_aborted >= 1
    assert "no progress" in core.counters.last_failure
    assert any(tw.linear > 0 for tw in twists) and twists[-1] == Twist2D()
    assert t < params.time_allowance


def late_drive(predict: bool, latency: float = 0.2) -> float:
    """A one-cell drive on poses ``latency`` s old (a camera's): the overshoot past the
    cell centre where the robot stops, m."""
    gate = armed_gate()
    core = DriveExecutorCore(ExecutorParams(predict_pose=predict, pose_timeout=0.6), gate)
    start = robot_center(4, 4, CELL)
    plant = Plant(*start, heading_to_yaw(0))
    history = [(0.0, plant.pose())]
    core.submit(DriveGoal(0, 1 << MOVE_FORWARD), 0.0)
    t = 0.0
    for _ in range(4000):
        gate.on_heartbeat(ARMED, t)
        stamp, seen = next((h for h in reversed(history) if h[0] <= t - latency), history[0])
        twist = core.on_pose(seen, stamp, t)
        if any(e.code in (SUCCEEDED, ABORTED) for e in statuses(core.drain())):
            break
        plant.apply(twist)
        t += DT
        history.append((t, plant.pose()))
    yaw = heading_to_yaw(0)
    along = np.subtract((plant.x, plant.y), start) @ np.array([math.cos(yaw), math.sin(yaw)])
    return float(along - CELL)


def test_a_late_pose_is_advanced_by_its_age_so_the_drive_ends_on_its_cell():
    """Poses 0.2 s old (a camera's latency): acting on them as they are, the robot stops a
    few centimetres past its cell centre; advanced along the twist last sent, within the
    position tolerance (the dome's ``predict_pose``)."""
    late = late_drive(predict=False)
    predicted = late_drive(predict=True)
    assert late > 0.01  # the overshoot the rehearsal showed
    assert abs(predicted) <= ExecutorParams().position_tolerance + 1e-3 < late


def test_predict_advances_along_the_last_twist_and_never_beyond_the_timeout():
    core = DriveExecutorCore(ExecutorParams(pose_timeout=0.5))
    core.sent = Twist2D(0.1, 0.0)
    moved, stamp = core.predict(Pose2D(1.0, 2.0, 0.0), 10.0, 10.2)
    assert (moved.x, moved.y, stamp) == pytest.approx((1.02, 2.0, 10.2))
    moved, stamp = core.predict(Pose2D(1.0, 2.0, math.pi / 2), 10.0, 12.0)  # capped at 0.5 s
    assert (moved.x, moved.y, stamp) == pytest.approx((1.0, 2.05, 10.5))
    assert core.predict(Pose2D(1.0, 2.0, 0.0), 10.0, 9.9) == (Pose2D(1.0, 2.0, 0.0), 10.0)


def test_time_allowance_ends_a_slow_primitive():
    """A plant that creeps (progress, but too slowly): the time allowance aborts it."""
    params = ExecutorParams(time_allowance=2.0, min_progress=0.0)
    prim = DriveCells(1, params, Limits.of(params, False))
    pose = Pose2D(*robot_center(4, 4, CELL), heading_to_yaw(1))
    prim.on_run(pose, 0.0)
    t, status = 0.0, Status.RUNNING
    while status is Status.RUNNING:
        t += DT
        pose = Pose2D(pose.x + 0.0005, pose.y, pose.yaw)
        status, twist = prim.on_cycle_update(pose, t)
    assert status is Status.FAILED and "time allowance" in prim.failure
    assert twist == Twist2D() and t == pytest.approx(2.0 + DT, abs=DT)


def test_stale_pose_gives_zero_twist_at_once_and_aborts():
    gate = armed_gate()
    core = DriveExecutorCore(ExecutorParams(pose_timeout=0.3), gate)
    plant = Plant(*robot_center(4, 4, CELL), heading_to_yaw(0))
    core.submit(DriveGoal(0, 1 << MOVE_FORWARD), 0.0)
    for i in range(10):
        twist = core.on_pose(plant.pose(), i * DT, i * DT)
        plant.apply(twist)
    assert twist.linear > 0
    gate.on_heartbeat(ARMED, 0.8)
    assert core.check(0.8) == Twist2D()  # the last pose is stamped 0.45 s: stale
    ends = [e for e in statuses(core.drain()) if e.code == ABORTED]
    assert ends and ends[0].stuck and not core.busy
    # A pose that arrives already stale moves nothing either.
    core.submit(DriveGoal(1, 1 << MOVE_FORWARD), 0.8)
    assert core.on_pose(plant.pose(), 0.0, 0.8) == Twist2D()
    assert codes(core.drain()) == [EXECUTING, ABORTED]


def test_a_pose_from_the_future_is_stale_within_a_small_tolerance():
    """A pose stamped ahead of the node's clock by more than ``future_tolerance`` (its clock
    runs ahead: a localiser that stopped would look fresh for as long) stops the wheels and
    aborts the goal, as an old one does; within the tolerance it drives."""
    gate = armed_gate()
    params = ExecutorParams()
    core = DriveExecutorCore(params, gate)
    plant = Plant(*robot_center(4, 4, CELL), heading_to_yaw(0))
    core.submit(DriveGoal(0, 1 << MOVE_FORWARD), 0.0)
    ahead = params.future_tolerance * 0.8
    t = 0.0
    for _ in range(10):
        gate.on_heartbeat(ARMED, t)
        twist = core.on_pose(plant.pose(), t + ahead, t)
        plant.apply(twist)
        t += DT
    assert twist.linear > 0 and core.busy
    core.drain()
    ahead = params.future_tolerance + 0.01
    gate.on_heartbeat(ARMED, t)
    assert core.on_pose(plant.pose(), t + ahead, t) == Twist2D()
    assert codes(core.drain()) == [ABORTED] and not core.busy
    assert "pose from the future" in core.counters.last_failure
    # the safety loop says the same while no newer pose comes
    assert core.check(t) == Twist2D()


@pytest.mark.parametrize("stop", ["estop", "heartbeat", "disable", "inactive"])
def test_gate_stops_at_once_and_nothing_moves_before_armed_again(stop):
    gate = armed_gate()
    core = DriveExecutorCore(ExecutorParams(), gate)
    plant = Plant(*robot_center(4, 4, CELL), heading_to_yaw(0))
    core.submit(DriveGoal(0, 1 << MOVE_FORWARD), 0.0)
    t = 0.0
    for _ in range(8):
        gate.on_heartbeat(ARMED, t)
        twist = core.on_pose(plant.pose(), t, t)
        plant.apply(twist)
        t += DT
    assert twist.linear > 0
    core.drain()
    if stop == "estop":
        gate.on_estop(True)
    elif stop == "disable":
        gate.on_enabled(False)
    elif stop == "inactive":
        gate.active = False
    else:
        t += 0.6  # no heartbeat for longer than the deadman
    assert core.check(t) == Twist2D()
    assert codes(core.drain()) == [ABORTED]
    # A new goal while stopped: refused at once, nothing moves.
    core.submit(DriveGoal(1, 1 << MOVE_FORWARD), t)
    assert codes(core.drain()) == [EXECUTING, ABORTED]
    assert core.on_pose(plant.pose(), t, t) == Twist2D()
    # Armed again (reset, enable, resume, heartbeat, active): the next goal moves.
    gate.on_estop(False)
    gate.on_enabled(True)
    gate.active = True
    gate.on_heartbeat(ARMED, t)
    core.submit(DriveGoal(2, 1 << MOVE_FORWARD), t)
    assert core.on_pose(plant.pose(), t, t).linear > 0


def test_pause_suspends_the_goal_and_resume_ends_it_where_an_unpaused_one_ends():
    def drive(pause_at: int | None, paused_for: float = 30.0):
        gate = armed_gate()
        core = DriveExecutorCore(ExecutorParams(time_allowance=6.0), gate)
        plant = Plant(*robot_center(4, 4, CELL), heading_to_yaw(1))
        core.submit(DriveGoal(0, (1 << MOVE_FORWARD) | (1 << TURN_RIGHT)), 0.0)
        t, statuses, moved_while_paused = 0.0, [], 0.0
        for i in range(2000):
            if i == pause_at:
                gate.on_heartbeat(PAUSED, t)
                assert core.check(t) == Twist2D()  # stops at once
                end = t + paused_for
                while t < end:  # longer than the time allowance: it must not count
                    gate.on_heartbeat(PAUSED, t)
                    twist = core.on_pose(plant.pose(), t, t)
                    moved_while_paused += abs(twist.linear) + abs(twist.angular)
                    t += DT
                assert core.busy  # still executing: suspended, not aborted
            gate.on_heartbeat(ARMED, t)
            twist = core.on_pose(plant.pose(), t, t)
            statuses += codes(core.drain())
            if not core.busy:
                break
            plant.apply(twist)
            t += DT
        return (
            statuses,
            robot_anchor(plant.x, plant.y, CELL),
            yaw_to_heading(plant.yaw),
            (moved_while_paused),
        )

    plain = drive(None)
    assert plain[0] == [EXECUTING, SUCCEEDED]
    for pause_at in (5, 20, 60):  # while driving, mid-cell, while turning
        paused = drive(pause_at)
        assert paused[0] == [EXECUTING, SUCCEEDED], pause_at
        assert paused[1:3] == plain[1:3] and paused[3] == 0.0


def test_pause_then_estop_aborts_and_a_goal_sent_while_paused_waits_for_the_resume():
    gate = armed_gate()
    core = DriveExecutorCore(ExecutorParams(), gate)
    pose = Pose2D(*robot_center(4, 4, CELL), 0.0)
    gate.on_heartbeat(PAUSED, 0.0)
    core.submit(DriveGoal(0, 1 << MOVE_FORWARD), 0.0)
    assert core.on_pose(pose, 0.0, 0.0) == Twist2D() and core.busy
    gate.on_heartbeat(ARMED, 0.1)
    assert core.on_pose(pose, 0.1, 0.1).linear > 0  # resumed: the goal drives
    gate.on_heartbeat(PAUSED, 0.2)
    assert core.check(0.2) == Twist2D() and core.busy
    gate.on_estop(True)  # an e-stop during the pause is never a pause
    assert core.check(0.3) == Twist2D() and not core.busy
    assert codes(core.drain()) == [EXECUTING, ABORTED]


def test_nothing_moves_before_the_first_armed_heartbeat():
    gate = MotionGate(active=True, enabled=True)
    core = DriveExecutorCore(ExecutorParams(), gate)
    core.submit(DriveGoal(0, 1 << MOVE_FORWARD), 0.0)
    assert core.on_pose(Pose2D(*robot_center(4, 4, CELL), 0.0), 0.0, 0.0) == Twist2D()
    assert not core.busy


def test_override_wins_while_fresh_clamped_and_the_estop_still_wins():
    params = ExecutorParams(override_timeout=0.5)
    gate = armed_gate()
    core = DriveExecutorCore(params, gate)
    pose = Pose2D(*robot_center(4, 4, CELL), 0.0)
    core.submit(DriveGoal(0, 1 << MOVE_FORWARD), 0.0)
    core.on_pose(pose, 0.0, 0.0)
    assert not core.operator
    core.on_override(Twist2D(5.0, -9.0), 0.1)
    twist = core.check(0.1)
    assert twist == Twist2D(params.throttle_speed, -params.throttle_turn_rate)
    assert core.operator
    assert core.on_pose(pose, 0.2, 0.2) == twist
    assert not core.busy  # the goal gave way to the operator
    gate.on_heartbeat(ARMED, 0.3)
    gate.on_estop(True)
    assert core.check(0.3) == Twist2D()
    gate.on_estop(False)
    gate.on_heartbeat(ARMED, 0.7)
    assert core.on_pose(pose, 0.7, 0.7) == Twist2D()  # the override is 0.6 s old
    assert core.check(0.7) is None
    assert not core.operator  # handed back: the team's goals drive it again
    core.on_override(Twist2D(0.1, 0.0), 0.8)
    core.check(0.8)
    assert core.operator


def test_throttle_up_raises_the_limits():
    params = ExecutorParams()
    fast = max(abs(tw.linear) for tw in _drive(params, 1 << MOVE_FORWARD | 1 << THROTTLE_UP))
    slow = max(abs(tw.linear) for tw in _drive(params, 1 << MOVE_FORWARD))
    assert slow == pytest.approx(params.max_speed)
    assert fast > slow and fast <= params.throttle_speed
    with pytest.raises(ParameterError, match="throttle_speed"):
        validate(ExecutorParams, {"throttle_speed": 0.05})


def _drive(params, word):
    gate = armed_gate()
    core = DriveExecutorCore(params, gate)
    plant = Plant(*robot_center(4, 4, 0.25), 0.0)
    return run_goal(core, gate, plant, DriveGoal(0, word))[2]


def test_turn_primitive_respects_rate_and_acceleration_limits():
    params = ExecutorParams()
    prim = Turn(-1, params, Limits.of(params, False))
    plant = Plant(0.0, 0.0, 0.0)
    prim.on_run(plant.pose(), 0.0)
    t, last, status = 0.0, 0.0, Status.RUNNING
    while status is Status.RUNNING:
        status, twist = prim.on_cycle_update(plant.pose(), t)
        assert abs(twist.angular) <= params.max_turn_rate + 1e-12
        # The stop within tolerance is from at most sqrt(2 accel tolerance), a slow crawl.
        step = params.max_turn_accel * DT if status is Status.RUNNING else last
        assert abs(twist.angular - last) <= step + 1e-9
        assert abs(last) <= 2 * math.sqrt(2 * params.max_turn_accel * params.heading_tolerance)
        last = twist.angular
        plant.apply(twist)
        t += DT
    assert status is Status.SUCCEEDED
    assert abs(plant.yaw - math.pi / 2) <= params.heading_tolerance


EVENTS = typing.get_args(ExecutorEvent)


def test_every_event_is_a_declared_frozen_class_and_every_state_is_declared():
    """Goals that succeed, fail, are refused, superseded and stopped: every event one of
    ExecutorEvent's classes, each frozen; the core keeps no attribute ``__init__`` lacks."""
    assert set(EVENTS) == {SetThrottle, ReportStatus}
    for cls in (*EVENTS, DriveStep, TurnStep):
        assert dataclasses.is_dataclass(cls) and cls.__dataclass_params__.frozen, cls
        assert cls.__doc__ and not cls.__doc__.startswith(cls.__name__ + "("), cls
    gate = armed_gate()
    core = DriveExecutorCore(ExecutorParams(progress_window=0.5), gate)
    declared = set(vars(core))
    events = []
    plant = Plant(*robot_center(4, 4, CELL), heading_to_yaw(0))
    for goal, move in [
        (DriveGoal(0, 1 << MOVE_FORWARD | 1 << THROTTLE_UP | 1 << TURN_RIGHT), True),
        (DriveGoal(1, 1 << MOVE_BACKWARD | 1 << RANDOM_TURN, LEFT), False),  # blocked
    ]:
        end, t, _ = run_goal(core, gate, plant, goal, move=move)
        events.append(end)
    core.submit(DriveGoal(2, 0x1FFF), t)  # refused
    core.submit(DriveGoal(3, 1 << THROTTLE_UP), t)  # nothing to drive: done at once
    events += core.drain()
    core.on_word(1 << MOVE_FORWARD, t)  # free mode, then superseded
    core.submit(DriveGoal(4, 1 << TURN_LEFT), t)
    core.on_override(Twist2D(0.1, 0.0), t)  # the operator takes over
    assert core.check(t) is not None
    events += core.drain()
    assert {type(e) for e in events} == set(EVENTS)
    assert {e.code for e in statuses(events)} == {EXECUTING, SUCCEEDED, ABORTED}
    assert [e.on for e in events if isinstance(e, SetThrottle)] == [True, False, False]
    for event in events:
        assert isinstance(event, EVENTS)
        for f in dataclasses.fields(event):
            with pytest.raises(dataclasses.FrozenInstanceError):
                setattr(event, f.name, None)
    assert set(vars(core)) == declared


def test_the_core_emits_no_tagged_tuples():
    """No string-tagged tuple is left in the core (every event and step is a class)."""
    import ast
    import inspect

    import drive_executor.core

    tree = ast.parse(inspect.getsource(drive_executor.core))
    tagged = [
        node.lineno
        for node in ast.walk(tree)
        if isinstance(node, ast.Tuple)
        and node.elts
        and isinstance(node.elts[0], ast.Constant)
        and isinstance(node.elts[0].value, str)
    ]
    assert tagged == []
