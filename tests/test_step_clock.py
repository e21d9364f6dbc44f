"""``dynamics``' step barrier (excavation_sim.step_clock), without rclpy: start, answers,
late steps and lagging robots, the time factors' schedule, silent robots."""

from __future__ import annotations

import pytest

from excavation_sim.step_clock import SCHEDULE_SLACK, Next, StepClock

DT = 50_000_000  # 50 ms of sim time


def clock(**kw) -> StepClock:
    args = dict(robots=2, dt_ns=DT, command_timeout=1.0, cmd_vel_timeout=0.5, startup_period=0.5)
    return StepClock(**(args | kw))


def started(**kw) -> StepClock:
    c = clock(**kw)
    assert c.poll(0.0, True, False) is Next.WAIT
    assert c.poll(0.6, True, False) is Next.START
    c.published(0.6)
    return c


def test_it_starts_once_the_team_has_been_present_for_the_startup_period():
    c = clock()
    assert c.poll(0.0, True, False) is Next.WAIT
    assert c.poll(0.3, False, False) is Next.WAIT  # a robot left: the wait starts over
    assert c.poll(0.4, True, False) is Next.WAIT
    assert c.poll(0.8, True, False) is Next.WAIT
    assert c.poll(0.9, True, False) is Next.START and c.started


def test_a_step_waits_for_every_robot_and_older_answers_do_not_count():
    c = started()
    assert c.on_command(0, 0, 0.61, False) == (False, False)
    assert c.poll(0.62, False, False) is Next.WAIT
    c.stepped()
    c.published(0.63)
    assert c.on_command(0, 0, 0.64, False) == (False, False)  # stamped with the old step
    assert c.on_command(1, DT, 0.65, False) == (False, False)
    assert c.on_command(0, DT, 0.66, False) == (False, True)  # the last answer: step now
    assert c.poll(0.66, False, False) is Next.STEP


def test_a_silent_robot_makes_one_late_step_then_is_not_waited_for_until_heard():
    c = started()
    c.on_command(0, 0, 0.7, False)
    assert c.poll(1.5, False, False) is Next.WAIT
    assert c.poll(1.61, False, False) is Next.STEP and c.late == 1 and c.lagging == {1}
    c.stepped()
    c.published(1.62)
    assert c.on_command(0, DT, 1.63, False) == (False, True)  # robot 1 is not waited for
    c.stepped()
    c.published(1.64)
    c.on_command(1, 2 * DT, 1.65, False)
    assert c.lagging == set() and c.poll(1.66, False, False) is Next.WAIT  # robot 0 now


def test_time_factor_keeps_a_fixed_schedule_and_starts_over_when_far_behind():
    c = started(time_factor=1.0)  # a step is due every 50 ms of wall time
    for k in range(2):
        c.on_command(k, 0, 0.61, False)
    assert c.poll(0.62, False, False) is Next.WAIT
    assert c.poll(0.65, False, False) is Next.STEP
    c.stepped()
    c.published(0.66)  # taking the step cost 10 ms: the next is still due at 0.70
    for k in range(2):
        c.on_command(k, DT, 0.67, False)
    assert c.poll(0.69, False, False) is Next.WAIT
    assert c.poll(0.70, False, False) is Next.STEP
    c.stepped()
    c.published(2.0)  # a stall: far behind its schedule, which starts over from now
    c.on_command(0, 2 * DT, 2.0, False)
    assert c.on_command(1, 2 * DT, 2.0, False) == (False, True)
    assert c.schedule == (2.0, 3 * DT)
    c.stepped()
    c.published(2.0 + SCHEDULE_SLACK / 2)
    for k in range(2):
        c.on_command(k, 3 * DT, 2.03, False)
    assert c.poll(2.04, False, False) is Next.WAIT  # no burst: the next is due at 2.05
    assert c.poll(2.05, False, False) is Next.STEP


@pytest.mark.parametrize(("moving", "wait"), [(True, 0.025), (False, 0.1)])
def test_max_and_idle_time_factors_hold_a_step_after_the_last(moving, wait):
    c = started(max_time_factor=2.0, idle_time_factor=0.5)
    for k in range(2):
        c.on_command(k, 0, 0.6, moving)
    assert c.poll(0.6 + 0.9 * wait, False, moving) is Next.WAIT
    assert c.poll(0.6 + 1.01 * wait, False, moving) is Next.STEP


def test_a_robot_silent_past_cmd_vel_timeout_is_stopped_once_and_heard_again():
    c = started()
    c.on_command(0, 0, 0.6, True)
    c.on_command(1, 0, 0.6, True)
    for _ in range(10):
        c.stepped()
        c.published(0.7)
        c.on_command(0, c.now_ns, 0.7, True)
    assert c.silent() == []  # 0.5 s of sim time exactly: not yet
    c.stepped()
    assert c.silent() == [1] and c.silent() == []
    c.published(0.8)
    assert c.on_command(0, c.now_ns, 0.8, True) == (False, True)  # 1 is not waited for
    assert c.on_command(1, c.now_ns, 0.8, True) == (True, True)
    assert c.timed_out == set()
