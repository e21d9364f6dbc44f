"""The lockstep simulator's tick clock and parameters, without rclpy."""

from __future__ import annotations

import subprocess
import sys

import pytest

from excavation_common.params import ParameterError, replace, validate
from excavation_sim.lockstep import Action, SimParams, TickClock


def clock(**kw) -> TickClock:
    args = dict(robots=2, steps=3, timeout=1.0, first_timeout=5.0, startup_period=0.5)
    args.update(kw)
    return TickClock(**args)


def test_waits_for_the_team_for_the_startup_period():
    c = clock()
    assert c.poll(0.0, team_present=False) is Action.WAIT
    assert c.poll(1.0, team_present=True) is Action.WAIT  # present since 1.0
    assert c.poll(1.2, team_present=False) is Action.WAIT  # left again: start over
    assert c.poll(2.0, team_present=True) is Action.WAIT
    assert c.poll(2.6, team_present=True) is Action.PUBLISH_FIRST


def test_applies_when_every_word_is_in_and_counts_missing_ones():
    c = clock()
    c.poll(0.0, True)
    assert c.poll(1.0, True) is Action.PUBLISH_FIRST
    c.published(1.0)
    c.on_command(0, 0x1FFF)  # 13 bits: only 12 are behaviours
    assert c.poll(1.1, True) is Action.WAIT
    c.on_command(1, 5)
    c.on_command(1, 7)  # the first word of a tick counts
    assert c.poll(1.2, True) is Action.APPLY
    inputs = c.take()
    assert inputs.masks.tolist() == [0xFFF, 5] and inputs.missing == []
    c.published(2.0)
    c.on_command(1, 3)
    assert c.poll(2.5, True) is Action.WAIT
    assert c.poll(3.0, True) is Action.APPLY  # tick 1 times out after 1 s
    inputs = c.take()
    assert inputs.masks.tolist() == [0, 3] and inputs.missing == [0]
    c.published(3.0)
    c.take()
    assert c.finished and c.poll(10.0, True) is Action.WAIT


def test_tick_zero_waits_longer():
    c = clock()
    c.poll(0.0, True)
    c.poll(1.0, True)
    c.published(1.0)
    assert c.poll(4.0, True) is Action.WAIT
    assert c.poll(6.1, True) is Action.APPLY


def test_blade_driver_mode_waits_for_setpoints():
    c = clock(blade_driver=True)
    c.poll(0.0, True)
    c.poll(1.0, True)
    c.published(1.0)
    c.on_command(0, 1)
    c.on_command(1, 1)
    assert c.poll(1.1, True) is Action.WAIT
    c.on_setpoint(0, 0.02)
    c.on_setpoint(1, -0.02)
    assert c.poll(1.2, True) is Action.APPLY
    inputs = c.take()
    assert inputs.setpoints == {0: 0.02, 1: -0.02} and inputs.missing_setpoints == []


def test_hold_keeps_the_words_and_restarts_the_wait():
    c = clock()
    c.poll(0.0, True)
    c.poll(1.0, True)
    c.published(1.0)
    c.on_command(0, 9)
    c.hold(True, 1.5)
    c.on_command(1, 4)
    assert c.poll(100.0, True) is Action.WAIT  # held: never applies, never times out
    c.hold(False, 100.0)
    assert c.poll(100.1, True) is Action.APPLY
    assert c.take().masks.tolist() == [9, 4]


def test_words_before_tick_zero_and_from_strangers_are_ignored():
    c = clock()
    c.on_command(0, 1)
    c.poll(0.0, True)
    c.poll(1.0, True)
    c.published(1.0)
    c.on_command(7, 1)
    c.on_command(-1, 1)
    assert c.commands == {}


@pytest.mark.parametrize(
    ("values", "match"),
    [
        ({"robots": 0}, "robots = 0: must be >= 1"),
        ({"dt": 0.0}, "dt = 0.0: must be >="),
        ({"command_timeout": float("nan")}, "must be finite"),
        ({"steps": 1.5}, "expected an integer"),
        ({"bogus": 1}, "unknown parameter"),
    ],
)
def test_bad_parameters_are_named(values, match):
    with pytest.raises(ParameterError, match=match):
        validate(SimParams, values, "/sim")


def test_read_only_parameters_are_refused_at_runtime():
    p = validate(SimParams, {}, "/sim")
    with pytest.raises(ParameterError, match="read-only"):
        replace(p, {"blueprint": "landing-pad"}, "/sim")


def test_node_refuses_a_bad_parameter_with_one_line_and_exit_code_2(ros_env):
    run = subprocess.run(
        [sys.executable, "-m", "excavation_sim.sim_node", "--ros-args", "-p", "robots:=0"],
        capture_output=True,
        text=True,
        timeout=120,
        env=ros_env,
    )
    assert run.returncode == 2
    assert "Traceback" not in run.stderr
    assert "robots" in run.stderr and "must be >= 1" in run.stderr
