"""The team tick's barrier (pure): snapshots, words, random turns, robot-order scheduling."""

from __future__ import annotations

import dataclasses
import json
import typing

import numpy as np
import pytest
from team_tick.core import (
    Finished,
    Phase,
    PublishTick,
    Report,
    RequestSnapshot,
    SendGoal,
    Snapshot,
    TeamTick,
    TeamTickParams,
    TickAction,
    TickSummary,
    draw_turns,
    schedule,
)

from ant_controller.layout import (
    BLADE_BELOW,
    BLADE_BELOW_CMD,
    BLADE_HOME,
    MOVE_FORWARD,
    RANDOM_TURN,
    TURN_RIGHT,
)
from blueprint_server.blueprint import default_blueprint
from excavation_sim.world import HEADING, World, seed_state

FWD = 1 << MOVE_FORWARD


def make(robots=3, **kw) -> TeamTick:
    return TeamTick(TeamTickParams(robots=robots, **kw), seed_state(12345))


def feed_snapshot(tt: TeamTick, stamp: float, poses, blades=None) -> None:
    for k, pose in enumerate(poses):
        tt.on_pose(k, pose, stamp, f"pose{k}@{stamp}")
        tt.on_blade(k, (blades or [BLADE_HOME] * len(poses))[k], stamp, f"blade{k}")
    tt.on_heights(stamp, "heights")


def kinds(actions):
    return [type(a) for a in actions]


def of(cls, actions):
    return [a for a in actions if isinstance(a, cls)]


def test_random_turns_are_the_world_model_s_draws():
    """Directions drawn in robot order from the world's stream turn as world.step turns."""
    bp = default_blueprint(1)
    rng = np.random.default_rng(0)
    for index in range(30):
        world = World.scenario(bp.zones, bp.goal, 4, 9, index)
        stream = world.rng.copy()
        for _ in range(5):
            words = [int(w) for w in rng.choice([0, 1 << RANDOM_TURN], size=4)]
            before = world.robots[:, HEADING].copy()
            turns = draw_turns(words, stream)
            world.step(np.array(words))
            assert list((before + np.array(turns)) % 4) == list(world.robots[:, HEADING])
            assert all((t != 0) == bool(w) for t, w in zip(turns, words, strict=True))
        assert stream[0] == world.rng[0]


def test_conflicting_robots_wait_in_robot_order_disjoint_ones_move_at_once():
    poses = [(2, 2, 0), (4, 3, 2), (12, 12, 1), (3, 10, 0)]
    waits = schedule(poses, [FWD] * 4, reach=2)
    assert waits == [set(), {0}, set(), set()]
    assert schedule(poses, [0, FWD, FWD, FWD], reach=2)[1] == set()  # robot 0 does not move
    assert schedule(poses, [FWD] * 4, reach=4)[3] == {0, 1, 2}


def test_one_tick_end_to_end():
    tt = make(robots=3, settle=0.1)
    assert kinds(tt.start(0.0)) == [RequestSnapshot]
    assert tt.step(0.05, 0.0) == []  # nothing in yet
    feed_snapshot(tt, 0.2, [(2, 2, 0), (4, 3, 2), (12, 12, 1)])
    actions = tt.step(0.25, 1.0)
    publish = of(PublishTick, actions)
    assert publish and (publish[0].tick, publish[0].stamp) == (0, 0.0)
    assert publish[0].snapshot.poses == ("pose0@0.2", "pose1@0.2", "pose2@0.2")
    assert publish[0].snapshot.stuck == (False, False, False)
    assert tt.phase is Phase.WORDS
    tt.on_word(0, FWD)
    tt.on_word(1, FWD | 1 << BLADE_BELOW_CMD)
    assert tt.step(0.3, 1.1) == []
    tt.on_word(2, 1 << TURN_RIGHT)
    tt.on_word(2, 0)  # a second word of the same tick does not count
    goals = of(SendGoal, tt.step(0.35, 1.2))
    assert goals == [  # 1 waits for 0
        SendGoal(robot=0, tick=0, stamp=0.0, word=FWD, turn=0),
        SendGoal(robot=2, tick=0, stamp=0.0, word=1 << TURN_RIGHT, turn=0),
    ]
    tt.on_status(0, 0, terminal=True, aborted=True, now=3.0)
    goals = of(SendGoal, tt.step(3.0, 2.0))
    assert [g.robot for g in goals] == [1]
    tt.on_status(2, 0, terminal=True, aborted=False, now=3.5)
    tt.on_status(1, 0, terminal=True, aborted=False, now=6.0)
    actions = tt.step(6.0, 3.0)
    assert actions == [RequestSnapshot(1, 6.0 + 0.1)]
    assert tt.tick == 1 and tt.phase is Phase.SNAPSHOT
    # A snapshot from before the motion ended does not count; nor a blade not yet lowered.
    feed_snapshot(tt, 5.0, [(3, 2, 0), (4, 3, 2), (12, 12, 2)])
    assert tt.step(6.2, 3.1) == []
    feed_snapshot(tt, 6.2, [(3, 2, 0), (4, 3, 2), (12, 12, 2)])
    assert tt.step(6.3, 3.2) == []
    assert tt.snapshot_ready(6.3) == "blade of robot 1 at its setting"
    feed_snapshot(
        tt, 6.3, [(3, 2, 0), (4, 3, 2), (12, 12, 2)], [BLADE_HOME, BLADE_BELOW, BLADE_HOME]
    )
    publish = of(PublishTick, tt.step(6.4, 3.3))
    assert (publish[0].tick, publish[0].stamp) == (1, 1.0)
    assert publish[0].snapshot.stuck == (True, False, False)


def test_silent_controller_idles_and_a_robot_that_never_finishes_is_left_out():
    tt = make(robots=2, motion_limit=10.0, word_timeout=0.5, first_word_timeout=0.5)
    tt.start(0.0)
    feed_snapshot(tt, 0.1, [(2, 2, 0), (8, 8, 0)])
    tt.step(0.2, 0.0)
    tt.on_word(0, FWD)
    actions = tt.step(0.3, 1.0)  # robot 1 silent past the timeout: word 0
    assert [(a.robot, a.word) for a in of(SendGoal, actions)] == [(0, FWD), (1, 0)]
    assert tt.missed == [0, 1]
    tt.on_status(1, 0, terminal=True, aborted=False, now=0.4)
    assert kinds(tt.step(5.0, 2.0)) == []
    actions = tt.step(10.5, 3.0)
    assert Report in kinds(actions) and RequestSnapshot in kinds(actions)
    assert tt.late == [1, 0] and tt.stuck == [True, False] and tt.records[0].late == [0]


def test_no_tick_starts_while_the_team_is_not_armed_and_the_snapshot_is_taken_again():
    tt = make(robots=1, settle=0.1)
    tt.start(0.0)
    feed_snapshot(tt, 0.5, [(2, 2, 0)])
    tt.armed = False
    assert tt.step(0.6, 0.0) == []
    tt.armed = True
    # Held: the snapshot taken before (blades homed meanwhile) does not count; a new one.
    actions = tt.step(0.7, 0.1)
    assert actions[1:] == [RequestSnapshot(0, 0.7 + 0.1)]
    assert isinstance(actions[0], Report) and "held" in actions[0].message
    assert tt.step(0.75, 0.2) == []
    feed_snapshot(tt, 0.8, [(2, 2, 0)])
    assert PublishTick in kinds(tt.step(0.85, 0.3))


def held(tt: TeamTick, hold: str, now: float, wall: float, seconds: float) -> list[TickAction]:
    """Hold the team for ``seconds`` of wall time from ``wall``; the step that re-arms it."""
    tt.armed, tt.hold = False, hold
    assert tt.step(now, wall) == [] and tt.step(now + seconds / 2, wall + seconds / 2) == []
    tt.armed, tt.hold = True, None
    return tt.step(now + seconds, wall + seconds)


def test_a_short_heartbeat_gap_delays_the_snapshot_but_asks_for_no_other():
    # A loaded machine's hiccup: nothing moved, so the snapshot asked for still holds (a new
    # one would render another frame and sweep and move the sensors' noise stream on).
    tt = make(robots=1, snapshot_retry=2.0)
    tt.start(0.0, 0.0)
    feed_snapshot(tt, 0.5, [(2, 2, 0)])
    action = held(tt, "heartbeat lost", 0.6, 0.1, 1.5)[0]
    assert isinstance(action, PublishTick) and action.tick == 0
    assert tt.records[0].started_wall == 1.6


def test_a_heartbeat_gap_of_any_length_asks_for_no_other_snapshot():
    # Nothing could move while heartbeats were missing (every gate closed), however long:
    # the snapshot asked for stands. Nor before the first heartbeat (the CI rehearsal's
    # "tick 0: team held 0.1 s; new snapshot": a supervisor not heard yet at tick 0).
    for hold, seconds in [
        ("heartbeat lost", 2.0),
        ("heartbeat lost", 60.0),
        ("no heartbeat yet", 0.1),
    ]:
        tt = make(robots=1, snapshot_retry=2.0)
        tt.start(0.0, 0.0)
        tt.on_ack(0, 0.1)
        feed_snapshot(tt, 0.5, [(2, 2, 0)])
        assert kinds(held(tt, hold, 0.6, 0.1, seconds)) == [PublishTick], (hold, seconds)
    # a gap, then an unacknowledged request: sent again, unchanged (the simulator takes it once)
    tt = make(robots=1, snapshot_retry=2.0)
    tt.start(0.0, 0.0)
    actions = held(tt, "heartbeat lost", 0.6, 0.1, 3.0)
    assert actions[1:] == [RequestSnapshot(0, 0.1)]
    assert "not acknowledged" in actions[0].message


def test_after_a_heartbeat_gap_the_blades_get_blade_wait_again():
    # A blade driver homes its blade when heartbeats stop; the snapshot waits for it again.
    tt = make(robots=1, settle=0.1, blade_wait=2.0, snapshot_retry=30.0)
    tt.start(0.0, 0.0)
    feed_snapshot(tt, 0.2, [(2, 2, 0)])
    tt.step(0.3, 0.1)
    tt.on_word(0, 1 << BLADE_BELOW_CMD)
    tt.step(0.4, 0.2)
    tt.on_status(0, 0, terminal=True, aborted=False, now=1.0)
    assert kinds(tt.step(1.0, 0.3)) == [RequestSnapshot]
    tt.on_ack(1, 1.1)
    feed_snapshot(tt, 1.1, [(2, 2, 0)], [BLADE_BELOW])  # lowered, as the word asked
    tt.armed, tt.hold = False, "heartbeat lost"
    assert tt.step(1.2, 0.4) == []
    tt.on_blade(0, BLADE_HOME, 5.0, "homed")  # the driver's deadman, during the gap
    tt.armed, tt.hold = True, None
    assert tt.step(6.0, 5.0) == []  # past blade_wait since the motion, not since the gap
    tt.on_blade(0, BLADE_BELOW, 6.1, "lowered")
    publish = of(PublishTick, tt.step(6.2, 5.1))
    assert publish and publish[0].snapshot.blades == ("lowered",)


def test_an_operator_hold_asks_for_a_new_snapshot_and_says_why():
    for hold in ["team paused", "e-stop latched", "team disarmed"]:
        tt = make(robots=1, snapshot_retry=2.0)
        tt.start(0.0, 0.0)
        tt.on_ack(0, 0.1)
        feed_snapshot(tt, 0.5, [(2, 2, 0)])
        actions = held(tt, hold, 0.6, 0.1, 0.2)
        assert kinds(actions) == [Report, RequestSnapshot], hold
        assert f"({hold}); new snapshot" in actions[0].message
        assert actions[1].not_before == 0.6 + 0.2 + 0.1  # taken after the hold ended (+ settle)
        feed_snapshot(tt, 0.6 + 0.2 + 0.1, [(2, 2, 0)])
        assert kinds(tt.step(0.6 + 0.2 + 0.2, 0.1 + 0.2 + 0.1)) == [PublishTick]
    # a heartbeat gap that turns into a pause is a pause, however short
    tt = make(robots=1, snapshot_retry=2.0)
    tt.start(0.0, 0.0)
    feed_snapshot(tt, 0.5, [(2, 2, 0)])
    tt.armed, tt.hold = False, "heartbeat lost"
    tt.step(0.6, 0.1)
    tt.hold = "team paused"
    tt.step(0.7, 0.2)
    tt.armed, tt.hold = True, None
    actions = tt.step(0.8, 0.3)
    assert kinds(actions) == [Report, RequestSnapshot]
    assert "(heartbeat lost, team paused); new snapshot" in actions[0].message


def test_a_request_is_sent_again_only_while_not_acknowledged():
    tt = make(robots=1, settle=0.1, snapshot_retry=2.0)
    assert tt.start(0.0, 0.0) == [RequestSnapshot(0, 0.1)]
    assert tt.step(0.5, 1.9) == []
    # lost (no acknowledgement): the same request again, every snapshot_retry
    actions = tt.step(0.6, 2.0)
    assert kinds(actions) == [Report, RequestSnapshot]
    assert "not acknowledged" in actions[0].message
    assert actions[1] == RequestSnapshot(0, 0.1)
    assert tt.step(0.7, 3.9) == []
    tt.on_ack(1, 0.2)  # another tick's (a restarted team tick's latched one): not ours
    tt.on_ack(0, 0.05)  # taken before the instant asked for: not ours
    assert kinds(tt.step(0.8, 4.0)) == [Report, RequestSnapshot]
    tt.on_ack(0, 0.15)  # taken: perception is slow, nothing is asked again
    assert tt.step(0.9, 5.9) == []
    feed_snapshot(tt, 0.15, [(2, 2, 0)])
    assert kinds(tt.step(1.0, 6.0)) == [PublishTick]


def test_a_snapshot_taken_without_a_robot_asks_for_another_instant():
    # A robot hidden from the camera: further frames let the lost-robot policy judge it.
    tt = make(robots=2, settle=0.1, snapshot_retry=2.0)
    tt.start(0.0, 0.0)
    tt.on_ack(0, 0.1)
    tt.on_pose(0, (2, 2, 0), 0.1, "p0")
    for k in range(2):
        tt.on_blade(k, BLADE_HOME, 0.1, f"blade{k}")
    tt.on_heights(0.1, "heights")
    assert tt.step(0.5, 1.0) == []
    actions = tt.step(3.0, 2.0)
    assert actions[1:] == [RequestSnapshot(0, 3.0)]  # a new instant: rendered anew
    assert "no pose of robot 1 yet" in actions[0].message
    tt.on_ack(0, 0.1)  # the first request's again: not the new one's
    assert kinds(tt.step(3.1, 4.0)) == [Report, RequestSnapshot]
    assert tt.step(3.2, 4.1) == []  # sent again (not acknowledged), unchanged


def test_without_acknowledgements_a_request_is_never_sent_again_for_want_of_one():
    # The dome: no node acknowledges; the camera and laser run anyway.
    tt = make(robots=1, settle=0.1, snapshot_retry=2.0, snapshot_ack=False)
    tt.start(0.0, 0.0)
    feed_snapshot(tt, 0.05, [(2, 2, 0)])  # before the motion ended: not the snapshot
    actions = tt.step(1.0, 2.0)  # incomplete: another instant, as a taken request
    assert actions[1:] == [RequestSnapshot(0, 1.0)]
    assert "no pose of robot 0" in actions[0].message
    feed_snapshot(tt, 0.2, [(2, 2, 0)])  # any instant after the motion still counts
    assert kinds(tt.step(1.1, 2.1)) == [PublishTick]


def test_held_team_grants_no_goal_and_held_time_is_not_motion_time():
    tt = make(robots=2, motion_limit=10.0)
    tt.start(0.0)
    feed_snapshot(tt, 0.1, [(2, 2, 0), (4, 3, 2)])  # overlapping reaches: 1 waits for 0
    tt.step(0.2, 0.0)
    tt.on_word(0, FWD)
    tt.on_word(1, FWD)
    tt.armed = False
    assert tt.step(0.3, 0.1) == [] and tt.phase is Phase.WORDS  # words wait for the team
    tt.armed = True
    assert [a.robot for a in of(SendGoal, tt.step(0.4, 0.2))] == [0]
    tt.armed = False  # paused while robot 0 drives: 60 s held, far beyond motion_limit
    for t in range(1, 61):
        assert tt.step(0.4 + t, 0.2 + t) == []
    tt.on_status(0, 0, terminal=True, aborted=False, now=61.0)
    assert tt.step(61.5, 62.0) == []  # robot 1 is not granted while held
    tt.armed = True
    assert [a.robot for a in of(SendGoal, tt.step(62.0, 63.0))] == [1]
    assert tt.late == [0, 0]


def test_absent_robots_are_not_waited_for():
    tt = make(robots=3, word_timeout=30.0, first_word_timeout=30.0)
    tt.absent = {1}
    tt.start(0.0)
    tt.on_pose(0, (2, 2, 0), 0.2, "p0")
    tt.on_pose(2, (12, 12, 1), 0.2, "p2")  # no pose of robot 1 (hidden from the camera)
    for k in range(3):
        tt.on_blade(k, BLADE_HOME, 0.2, f"b{k}")
    tt.on_heights(0.2, "heights")
    publish = of(PublishTick, tt.step(0.3, 0.0))
    assert publish and publish[0].snapshot.poses == ("p0", None, "p2")
    tt.on_word(0, FWD)
    tt.on_word(1, FWD)  # a disabled robot's word does not count
    tt.on_word(2, FWD)
    goals = [(a.robot, a.word) for a in of(SendGoal, tt.step(0.4, 0.1))]
    assert goals == [(0, FWD), (1, 0), (2, FWD)]  # told to idle, not awaited
    assert tt.missed == [0, 0, 0]
    tt.on_status(0, 0, terminal=True, aborted=False, now=1.0)
    tt.absent.add(2)  # lost while driving: its executor has stopped it
    assert kinds(tt.step(1.1, 0.2)) == [RequestSnapshot] and tt.tick == 1


def one_tick(word: int) -> tuple[TeamTick, list, list]:
    """A one-robot, one-tick run whose robot says ``word``: the team tick and the actions
    after its motion and after the last snapshot."""
    tt = make(robots=1, steps=1)
    tt.start(0.0)
    feed_snapshot(tt, 0.2, [(2, 2, 0)])
    tt.step(0.3, 0.0)
    tt.on_word(0, word)
    tt.step(0.3, 0.1)
    tt.on_status(0, 0, terminal=True, aborted=False, now=0.4)
    moved = tt.step(0.4, 0.2)
    feed_snapshot(tt, 0.6, [(2, 2, 0)])
    return tt, moved, tt.step(0.6, 0.3)


def test_finishes_after_the_last_tick_s_snapshot():
    tt, moved, last = one_tick(0)
    assert kinds(moved) == [RequestSnapshot]
    assert last == [Finished()]
    assert tt.phase is Phase.FINISHED and len(tt.records) == 1


def test_the_summary_is_a_record_that_goes_through_json_and_back():
    """The trial's result crosses a process as JSON (``result.json``): the same record comes
    back; a missing or malformed field is named."""
    tt, _, _ = one_tick(5)
    summary = tt.summary()
    assert summary.ticks == 1 and summary.commands == [[5]] and summary.missed == {0: 0}
    text = json.dumps(summary.to_json() | {"reports": []})
    assert TickSummary.from_json(json.loads(text)) == summary
    data = summary.to_json()
    del data["stuck_events"]
    with pytest.raises(ValueError, match="run/result.json: no field 'stuck_events'"):
        TickSummary.from_json(data, "run/result.json")
    with pytest.raises(ValueError, match="malformed"):
        TickSummary.from_json(summary.to_json() | {"commands": "words"})


def test_the_ticks_the_operator_drove_a_robot_are_in_the_summary():
    """A robot taken over before a tick counts for it; one taken over during a tick and
    handed back counts for that tick alone; a result without the field (older) still reads."""
    tt = make(robots=2, steps=3)
    tt.on_operator(1, True)  # before tick 0: the operator holds robot 1
    tt.start(0.0)
    feed_snapshot(tt, 0.2, [(2, 2, 0), (8, 8, 0)])
    tt.step(0.3, 0.0)
    tt.on_operator(1, False)
    assert tt.records[-1].operated == {1}
    tt.on_operator(0, True)
    tt.on_operator(0, False)
    summary = tt.summary()
    assert summary.operator_ticks == {0: [0], 1: [0]}
    assert TickSummary.from_json(json.loads(json.dumps(summary.to_json()))) == summary
    older = summary.to_json()
    del older["operator_ticks"]
    assert TickSummary.from_json(older).operator_ticks == {}


ACTIONS = typing.get_args(TickAction)


def test_every_action_is_a_declared_frozen_class_and_every_state_is_declared():
    """A run through every path: each action one of TickAction's classes, each frozen.

    It reaches every kind (a resent request, an operator's hold, a silent controller, a
    robot left out, a stale snapshot taken as it is, the end), and leaves the tick with no
    attribute its dataclass does not declare.
    """
    assert set(ACTIONS) == {RequestSnapshot, PublishTick, SendGoal, Report, Finished}
    for cls in (*ACTIONS, Snapshot):
        assert dataclasses.is_dataclass(cls) and cls.__dataclass_params__.frozen, cls
        assert cls.__doc__ and not cls.__doc__.startswith(cls.__name__ + "("), cls
    tt = make(
        robots=2,
        steps=2,
        settle=0.1,
        snapshot_retry=1.0,
        snapshot_limit=5.0,
        word_timeout=0.5,
        first_word_timeout=0.5,
        motion_limit=5.0,
    )
    emitted: list = []
    emitted += tt.start(0.0, 0.0)
    emitted += tt.step(0.1, 1.0)  # not acknowledged: sent again
    tt.on_ack(0, 0.1)
    feed_snapshot(tt, 0.2, [(2, 2, 0), (8, 8, 0)])
    tt.armed, tt.hold = False, "team paused"
    emitted += tt.step(0.3, 1.1)
    tt.armed, tt.hold = True, None
    emitted += tt.step(0.4, 1.2)  # the operator's hold: a new snapshot
    tt.on_ack(0, 0.5)
    feed_snapshot(tt, 0.5, [(2, 2, 0), (8, 8, 0)])
    emitted += tt.step(0.6, 1.3)
    tt.on_word(0, FWD | 1 << RANDOM_TURN)
    emitted += tt.step(0.7, 2.0)  # robot 1 silent: it idles
    tt.on_status(0, 0, terminal=True, aborted=False, now=1.0)
    emitted += tt.step(6.0, 3.0)  # robot 1 never finishes: left out
    tt.on_ack(1, 6.1)
    feed_snapshot(tt, 0.5, [(2, 2, 0), (8, 8, 0)])  # from before the motion ended
    emitted += tt.step(6.2, 9.0)  # past snapshot_limit: taken as it is
    tt.on_word(0, 0)
    tt.on_word(1, 0)
    emitted += tt.step(6.3, 9.1)
    for k in range(2):
        tt.on_status(k, 1, terminal=True, aborted=False, now=6.4)
    emitted += tt.step(6.4, 9.2)
    tt.on_ack(2, 6.5)
    feed_snapshot(tt, 6.5, [(3, 2, 0), (8, 8, 0)])
    emitted += tt.step(6.6, 9.3)
    assert tt.phase is Phase.FINISHED
    assert {type(a) for a in emitted} == set(ACTIONS)
    assert all(isinstance(a, ACTIONS) for a in emitted)
    reports = [a.message for a in of(Report, emitted)]
    assert any("not acknowledged" in m for m in reports)
    assert any("team held" in m for m in reports)
    assert any("no word from robots [1]" in m for m in reports)
    assert any("did not finish" in m for m in reports)
    assert any("without a fresh" in m for m in reports)
    assert set(vars(tt)) == {f.name for f in dataclasses.fields(TeamTick)}


def test_the_core_emits_no_tagged_tuples():
    """No string-tagged tuple is left in the core (every action is a class)."""
    import ast
    import inspect

    import team_tick.core

    tree = ast.parse(inspect.getsource(team_tick.core))
    tagged = [
        node.lineno
        for node in ast.walk(tree)
        if isinstance(node, ast.Tuple)
        and node.elts
        and isinstance(node.elts[0], ast.Constant)
        and isinstance(node.elts[0].value, str)
    ]
    assert tagged == []


def test_a_restarted_executor_ends_its_robots_goal_as_stuck_at_once():
    """The killed executor's goal has no status to come: the tick does not wait motion_limit."""
    tt = make(robots=2, motion_limit=120.0, word_timeout=0.5, first_word_timeout=0.5)
    tt.start(0.0)
    feed_snapshot(tt, 0.1, [(2, 2, 0), (8, 8, 0)])
    tt.step(0.2, 0.0)
    tt.on_word(0, FWD)
    tt.on_word(1, FWD)
    assert len(of(SendGoal, tt.step(0.3, 1.0))) == 2
    report = tt.executor_restarted(1, 0.4)
    assert kinds(report) == [Report] and "robot 1's executor restarted" in report[0].message
    assert tt.executor_restarted(1, 0.5) == []  # once
    tt.on_status(0, 0, terminal=True, aborted=False, now=1.0)
    actions = tt.step(1.1, 2.0)
    assert RequestSnapshot in kinds(actions)  # robot 1 counted done: the tick ended
    assert tt.stuck == [False, True] and tt.late == [0, 0]
    assert tt.executor_restarted(0, 1.2) == []  # no goal of robot 0 runs now
