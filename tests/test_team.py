"""The supervisor's pure state machine: team transitions, enables, lost-robot policy."""

from __future__ import annotations

import pytest

from excavation_common.safety import ARMED, DISARMED, ESTOPPED, PAUSED
from team_supervisor.team import Team


def test_team_starts_disarmed_and_arms_only_from_disarmed():
    team = Team(2)
    assert team.state == DISARMED
    assert not team.resume().success and not team.pause().success and not team.reset().success
    assert team.arm().success and team.state == ARMED
    assert team.pause().success and team.state == PAUSED
    assert not team.arm().success  # a paused team resumes, it is not re-armed
    assert team.resume().success and team.state == ARMED


@pytest.mark.parametrize("start", [DISARMED, ARMED, PAUSED])
def test_estop_latches_from_every_state_until_reset_then_disarmed(start):
    team = Team(1)
    if start != DISARMED:
        team.arm()
    if start == PAUSED:
        team.pause()
    assert team.estop("test").success and team.state == ESTOPPED
    for blocked in (team.arm, team.resume, team.pause):
        assert not blocked().success and team.state == ESTOPPED
    assert team.estop().success and team.estop_reason == "test"  # idempotent, first reason kept
    assert team.reset().success and team.state == DISARMED  # never straight back to armed
    assert team.arm().success


def test_operator_enable_and_bad_robot():
    team = Team(3)
    assert all(team.enabled(k) for k in range(3))
    assert team.enable(1, False).success and not team.enabled(1)
    assert "operator" in team.describe(1)
    assert team.enable(1, True).success and team.enabled(1)
    assert not team.enable(3, True).success
    assert not Team(2, enabled_at_start=False).enabled(0)
    with pytest.raises(ValueError):
        Team(0)


def feed(team, stamp, robots):
    for k in robots:
        team.on_pose(k, stamp)


def test_lost_robot_stops_at_once_rejoins_within_grace():
    team = Team(3, lost_timeout=1.5, lost_grace=3.0)
    feed(team, 0.0, [0, 1, 2])
    feed(team, 1.0, [0, 1])  # robot 2 misses one tick: 1 s behind, not lost
    assert team.enabled(2) and not team.members[2].lost
    feed(team, 2.0, [0, 1])  # 2 s behind: lost, stopped at once
    assert not team.enabled(2) and team.members[2].operator_enabled
    assert "lost" in team.describe(2)
    assert not team.enable(2, True).success  # cannot be enabled while lost
    feed(team, 3.0, [0, 1, 2])  # seen again within the grace period: rejoins by itself
    assert team.enabled(2)


def test_lost_beyond_grace_is_disabled_until_seen_and_enabled():
    team = Team(2, lost_timeout=1.5, lost_grace=2.0)
    for t in range(6):
        feed(team, float(t), [0])  # robot 1 never seen: counts from the team's first pose
    assert team.members[1].lost and team.members[1].disabled_reason == "lost"
    feed(team, 6.0, [0, 1])  # seen again, but stays disabled
    assert not team.members[1].lost and not team.enabled(1)
    assert team.enable(1, True).success and team.enabled(1)
    assert team.enabled(0)


def test_stamps_not_arrival_order_decide():
    """Poses of one tick arriving one after another never make a robot lost."""
    team = Team(4, lost_timeout=1.5)
    for t in range(50):
        for k in (3, 1, 0, 2):
            team.on_pose(k, float(t))
            assert all(team.enabled(j) for j in range(4))


def test_clock_going_back_restarts_the_stamps():
    """A restarted simulator: stamps from 0 again. The policy follows the new clock at once."""
    team = Team(2, lost_timeout=1.5, lost_grace=2.0)
    for t in range(40):
        feed(team, float(t), [0, 1])
    assert team.enable(0, False).success  # the operator disables robot 0
    for t in range(5):  # the new trial: both seen, robot 1 is not disabled by the old stamps
        feed(team, float(t), [0, 1])
        assert team.enabled(1) and team.pose_age(1) <= 0.0
    for t in range(5, 10):  # robot 1 unseen in the new time: disabled after 3.5 s, not 38 s
        feed(team, float(t), [0])
    assert team.members[1].lost and team.members[1].disabled_reason == "lost"
    assert not team.enabled(0) and team.members[0].disabled_reason == "operator"


def test_the_first_pose_after_a_gap_makes_nobody_lost():
    """No robot seen for 10 s (camera stalled, localiser restarted), then a frame comes."""
    team = Team(3, lost_timeout=1.5, lost_grace=2.0)
    for t in range(5):
        feed(team, float(t), [0, 1, 2])
    for k in (2, 0, 1):  # the frame after the gap, one pose after another
        team.on_pose(k, 14.0)
        assert all(team.enabled(j) for j in range(3)), k
    for t in range(15, 20):  # robot 1 is not in the frames after that: lost, then disabled
        feed(team, float(t), [0, 2])
    assert team.members[1].lost and team.members[1].disabled_reason == "lost"


def test_poses_taken_out_of_step_make_nobody_lost():
    """A busy supervisor takes robot 0's pose of tick t, then robot 1's of tick t + 2."""
    team = Team(2, lost_timeout=1.5)
    for t in range(0, 30, 2):
        team.on_pose(0, float(t))
        team.on_pose(1, float(t + 2))
        assert team.enabled(0) and team.enabled(1)


def test_continuous_frames_seconds_apart_a_late_pose_is_not_lost():
    """Frames come seconds of sim time apart (one per tick): robot 1's pose arriving after
    robot 0's of the same frame, or missing from one frame, never makes it lost."""
    team = Team(2, lost_timeout=1.5, lost_grace=2.0)
    t = 0.0
    for gap in (4.0, 7.5, 3.2, 12.0):
        t += gap
        team.on_pose(0, t)  # robot 1 is 'gap' seconds behind until its pose comes
        assert team.enabled(1) and team.missed_frames(1) == 1
        team.on_pose(1, t)
    t += 5.0
    team.on_pose(0, t)  # robot 1 missing from a whole frame: still one frame
    assert team.enabled(1)
    t += 5.0
    team.on_pose(0, t)  # a second frame without it, 10 s behind: lost, stopped
    assert team.members[1].lost and team.members[1].operator_enabled
    t += 5.0
    team.on_pose(0, t)  # beyond the grace and one more frame: disabled
    assert team.members[1].lost and team.members[1].disabled_reason == "lost"


def test_a_robot_whose_executor_drives_is_not_lost_until_its_goal_ends():
    team = Team(2, lost_timeout=1.0, lost_grace=2.0, busy_timeout=10.0)
    feed(team, 0.0, [0, 1])
    assert team.on_drive(1, True) == []
    for t in (0.5, 1.0, 1.5, 2.0, 2.5):
        assert team.on_pose(0, t) == []  # robot 1's frames are late while it drives
    assert team.enabled(1)
    assert team.on_drive(1, False) == [1]  # its goal ended without a pose since: lost now
    assert not team.enabled(1) and team.members[1].operator_enabled
    assert team.on_drive(1, True) == [] and not team.enabled(1)  # a new goal: still lost
    team.on_drive(1, False)
    team.on_pose(1, 3.0)
    assert team.enabled(1)
    # An executor that says it drives for longer than busy_timeout counts no longer.
    team.on_drive(1, True)
    for i in range(23):
        team.on_pose(0, 3.5 + 0.5 * i)
    assert team.members[1].lost and team.members[1].disabled_reason == "lost"


def test_lost_frames_must_be_at_least_one():
    with pytest.raises(ValueError, match="lost_frames"):
        Team(2, lost_frames=0)


def test_arming_an_armed_team_is_a_re_arm_and_counts():
    team = Team(1)
    assert team.armings == 0
    assert team.arm().message.startswith("team armed") and team.armings == 1
    reply = team.arm()
    assert reply.success and "re-armed" in reply.message and team.armings == 2
    team.estop("test")
    assert not team.arm().success and team.armings == 2


def test_a_robot_side_gate_waits_for_a_re_arm_after_its_heartbeat_was_lost():
    """A link that drops and returns: the supervisor still says armed, the robot stays still."""
    from excavation_common.safety import ARMED as ARMED_STATE
    from excavation_common.safety import MotionGate

    for robot_side in (False, True):
        gate = MotionGate(deadman=0.5, active=True, rearm_after_loss=robot_side)
        gate.on_enabled(True)
        gate.on_armed(100, 0, 1)
        for t in (0.0, 0.4):
            gate.on_heartbeat(ARMED_STATE, t)
        assert gate.allowed(0.5)
        assert gate.reason(1.0).startswith("heartbeat lost")  # the link drops for 2 s
        for t in (3.0, 3.1):  # it returns: armed heartbeats again, the same latched arming
            gate.on_heartbeat(ARMED_STATE, t)
        gate.on_armed(100, 0, 1)
        if not robot_side:
            assert gate.allowed(3.1)  # the dome PC's nodes: a dead supervisor came back
            continue
        assert gate.reason(3.1) == "heartbeat lost earlier: waiting for the operator to re-arm"
        gate.on_heartbeat(ARMED_STATE, 3.2)
        assert not gate.allowed(3.2)
        gate.on_armed(104, 5, 2)  # ant-operator arm
        assert gate.allowed(3.2)
