"""The tick clock under oversight: held ticks, absent robots, held blade set-points."""

from __future__ import annotations

from excavation_sim.lockstep import Action, TickClock


def started(**kw):
    c = TickClock(robots=3, steps=10, timeout=1.0, first_timeout=1.0, startup_period=0.0, **kw)
    assert c.poll(0.0, True) is Action.PUBLISH_FIRST
    c.published(0.0)
    return c


def test_held_clock_keeps_the_words_and_restarts_the_wait():
    c = started()
    c.on_command(0, 5)
    c.hold(True, 0.1)
    assert c.poll(50.0, False) is Action.WAIT  # held: no timeout either
    c.on_command(1, 6)
    c.hold(False, 50.0)
    assert c.poll(50.5, False) is Action.WAIT  # the wait restarted at the release
    c.on_command(2, 7)
    assert c.poll(50.6, False) is Action.APPLY
    assert c.take().masks.tolist() == [5, 6, 7]


def test_absent_robots_are_not_waited_for_and_idle():
    c = started()
    c.absent.add(1)
    c.on_command(0, 5)
    c.on_command(1, 9)  # a disabled robot's word is not applied
    c.on_command(2, 7)
    assert c.poll(0.1, False) is Action.APPLY
    inputs = c.take()
    assert inputs.masks.tolist() == [5, 0, 7] and inputs.missing == []


def test_held_setpoint_withdraws_until_the_open_one_returns():
    c = started(blade_driver=True)
    for k in range(3):
        c.on_command(k, 1)
        c.on_setpoint(k, 0.0)
    c.on_setpoint(2, 0.10, held=True)  # robot 2's driver lost the heartbeat
    assert not c.complete()
    c.on_setpoint(2, 0.0)  # the gate reopened: the tick's own set-point again
    assert c.complete() and c.take().setpoints == {0: 0.0, 1: 0.0, 2: 0.0}
    c.published(1.0)
    for k in range(3):
        c.on_command(k, 1)
        c.on_setpoint(k, -0.02)
    c.on_setpoint(0, 0.10, held=True)
    assert c.poll(1.5, False) is Action.WAIT
    assert c.poll(2.1, False) is Action.APPLY  # timed out: the held set-point applies
    inputs = c.take()
    assert inputs.setpoints[0] == 0.10 and inputs.missing_setpoints == []
