"""The blade driver's pure core: settings, limits, watchdog, override, force loop, protocol."""

from __future__ import annotations

import math

import pytest
from helpers.blades import word

from ant_controller.layout import (
    BLADE_ABOVE,
    BLADE_ABOVE_CMD,
    BLADE_BELOW,
    BLADE_BELOW_CMD,
    BLADE_HOME,
    BLADE_HOME_CMD,
    BLADE_LEVEL,
    BLADE_LEVEL_CMD,
    MOVE_FORWARD,
)
from blade_driver.core import AfterDrive, BladeDriverCore, DriverParams, Pid, blade_setting
from blade_driver.errors import BoardError, DriverConfigError
from blade_driver.protocol import ServoCalibration, checksum, decode, encode


@pytest.mark.parametrize(
    ("bits", "expected"),
    [
        ((), BLADE_LEVEL),  # no blade bit: unchanged
        ((BLADE_ABOVE_CMD,), BLADE_ABOVE),
        ((BLADE_BELOW_CMD,), BLADE_BELOW),
        ((BLADE_HOME_CMD,), BLADE_HOME),
        ((BLADE_ABOVE_CMD, BLADE_BELOW_CMD), BLADE_BELOW),  # table order: the last one wins
        ((BLADE_BELOW_CMD, BLADE_LEVEL_CMD), BLADE_LEVEL),
        ((BLADE_ABOVE_CMD, BLADE_HOME_CMD, BLADE_LEVEL_CMD), BLADE_HOME),
        ((MOVE_FORWARD,), BLADE_LEVEL),
    ],
)
def test_blade_setting_follows_table_order(bits, expected):
    assert blade_setting(word(*bits), BLADE_LEVEL) == expected


def test_blade_setting_agrees_with_the_world_model():
    import numpy as np

    from blueprint_server.blueprint import default_blueprint
    from excavation_sim.world import BLADE, World

    bp = default_blueprint(1)
    start = World.scenario(bp.zones, bp.goal, 1, 0)
    for w in range(1 << 12):
        world = start.copy()
        before = int(world.robots[0, BLADE])
        world.step(np.array([w & ~word(1, 2)], dtype=np.int64))  # no moves: blade only
        assert world.robots[0, BLADE] == blade_setting(w, before)


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("trim_limit", 0.01, "half the step"),
        ("watchdog_timeout", 0.0, "must be > 0"),
        ("kp", -1.0, "must be >= 0"),
        ("max_speed", math.nan, "must be finite"),
        ("position_max", 0.05, "include every setting"),
        ("home", 0.01, "above `depth`"),
    ],
)
def test_bad_parameters_name_the_field(field, value, match):
    with pytest.raises(DriverConfigError, match=match) as info:
        DriverParams(**{field: value})
    assert field in str(info.value)


def test_settings_map_to_joint_positions():
    core = BladeDriverCore()
    assert core.update(0.0, None) == pytest.approx(0.10)  # home before any command
    for t, (bit, pos) in enumerate(
        [(BLADE_BELOW_CMD, -0.02), (BLADE_LEVEL_CMD, 0.0), (BLADE_ABOVE_CMD, 0.02)], start=1
    ):
        core.command(word(bit), float(t))
        assert core.update(float(t), 0.0) == pytest.approx(pos)
        assert core.state.source == "controller"


def test_speed_limit_and_position_limits():
    core = BladeDriverCore(DriverParams(max_speed=0.1))
    core.update(0.0, None)
    core.command(word(BLADE_BELOW_CMD), 0.0)
    assert core.update(0.1, 0.0) == pytest.approx(0.10 - 0.01)  # 0.1 m/s for 0.1 s
    assert core.update(0.5, 0.0) == pytest.approx(0.10 - 0.05)
    core.command(word(BLADE_BELOW_CMD), 1.0)
    assert core.update(2.0, 0.0) == pytest.approx(-0.02)
    core.override(1.0, 2.0)  # far above the mechanism: clipped
    assert core.state.override == pytest.approx(0.12)
    assert core.state.clipped == 1
    with pytest.raises(DriverConfigError, match="finite"):
        core.override(math.inf, 2.0)


def test_watchdog_sends_the_blade_home_and_commands_bring_it_back():
    p = DriverParams(watchdog_timeout=1.5)
    core = BladeDriverCore(p)
    core.command(word(BLADE_BELOW_CMD), 0.0)
    assert core.update(0.0, 0.0) == pytest.approx(-0.02)
    assert not core.needs_no_controller(1.5)
    assert core.update(1.5, 0.0) == pytest.approx(-0.02)  # exactly at the limit: still fine
    assert core.needs_no_controller(1.6)
    assert core.update(1.6, 0.0) == pytest.approx(-0.02 + 0.25 * 0.1)  # homing, speed-limited
    assert core.state.watchdog_tripped and "watchdog" in core.state.source
    assert core.update(2.5, 0.0) == pytest.approx(0.10)
    core.command(word(MOVE_FORWARD), 3.0)  # a word without blade bits: the blade stays home
    assert core.update(3.0, 0.0) == pytest.approx(0.10)
    assert not core.state.watchdog_tripped and core.state.source == "controller"


def test_in_a_ticked_team_the_watchdog_counts_ticks_not_wall_seconds():
    """A dome tick lasts many wall seconds and the controller answers once per tick."""
    core = BladeDriverCore(DriverParams(watchdog_timeout=1.5))
    core.command(word(BLADE_LEVEL_CMD), 100.0, tick=0.0)
    for now in (101.0, 105.0, 109.0):  # tick 0 still: 9 wall seconds are no silence
        core.update(now, 0.0, tick=0.0)
    assert not core.state.watchdog_tripped and core.state.setting == BLADE_LEVEL
    core.update(110.0, 0.0, tick=1.0)  # tick 1 began, its word not in yet
    assert not core.state.watchdog_tripped
    core.command(word(MOVE_FORWARD), 111.0, tick=1.0)
    core.update(120.0, 0.0, tick=2.0)  # tick 2 began: one tick without a word
    assert not core.state.watchdog_tripped and core.state.setting == BLADE_LEVEL
    core.update(121.0, 0.0, tick=3.0)  # tick 3 began: ticks 2 and 3 without a word
    assert core.state.watchdog_tripped and core.state.setting == BLADE_HOME
    # Without tick times (no team tick), wall seconds count as before.
    wall = BladeDriverCore(DriverParams(watchdog_timeout=1.5))
    wall.command(word(BLADE_LEVEL_CMD), 100.0)
    wall.update(101.6, 0.0, tick=0.0)
    assert wall.state.watchdog_tripped


def test_operator_override_wins_while_fresh():
    core = BladeDriverCore(DriverParams(override_timeout=0.5))
    core.command(word(BLADE_LEVEL_CMD), 0.0)
    core.override(0.05, 0.1)
    assert core.update(0.2, 0.0) == pytest.approx(0.05)
    assert core.state.source == "operator override"
    core.command(word(BLADE_BELOW_CMD), 0.3)  # the controller is overruled...
    assert core.update(0.6, 0.0) == pytest.approx(0.05)
    core.command(word(BLADE_BELOW_CMD), 0.9)
    assert core.update(0.9, 0.0) < 0.05  # ...until the override is stale
    assert core.state.source == "controller"
    assert core.update(1.2, 0.0) == pytest.approx(-0.02)


def test_constant_force_loop_holds_the_push_force():
    """Blade below, moving forward, soil force k * (surface - height): the loop settles."""
    p = DriverParams(push_force=6.0)
    core = BladeDriverCore(p)
    stiffness, surface = 400.0, 0.0
    height, t = p.home, 0.0
    for _ in range(400):
        core.command(word(MOVE_FORWARD, BLADE_BELOW_CMD), t)
        force = stiffness * max(0.0, surface - height)
        height = core.update(t, force)
        t += 0.05
    assert stiffness * (surface - height) == pytest.approx(6.0, abs=0.05)
    assert abs(core.state.trim) <= p.trim_limit
    assert "constant force" in core.state.source
    core.command(word(BLADE_BELOW_CMD), t)  # not moving: no trimming
    assert core.update(t, 8.0) == pytest.approx(-0.02)


def test_pid_clamps_and_does_not_wind_up():
    pid = Pid(kp=0.0, ki=1.0, kd=0.0, limit=0.01)
    for _ in range(1000):
        out = pid.update(5.0, 0.1)
    assert out == pytest.approx(0.01)
    assert pid.integral <= 0.01 + 1e-12
    out = pid.update(-5.0, 0.1)  # the error flips: the output leaves saturation at once
    assert out < 0.01


def test_protocol_round_trip_and_errors():
    line = encode("SET", "92.50")
    assert line == b"SET 92.50*" + checksum(b"SET 92.50").encode() + b"\n"
    assert decode(line) == ["SET", "92.50"]
    with pytest.raises(BoardError, match="checksum"):
        decode(b"SET 92.50*00\n", "/dev/ttyX")
    with pytest.raises(BoardError, match="no checksum"):
        decode(b"SET 92.50\n")
    with pytest.raises(BoardError, match="timeout"):
        decode(b"", "/dev/ttyX")
    with pytest.raises(BoardError, match="incomplete"):
        decode(b"SET 9")


def test_calibration_round_trip_and_clipping():
    c = ServoCalibration(zero_deg=90.0, deg_per_m=600.0)
    for pos in (-0.02, 0.0, 0.02, 0.10):
        assert c.position(c.angle(pos)) == pytest.approx(pos)
    assert c.angle(1.0) == 180.0 and c.angle(-1.0) == 0.0


def test_hold_sends_home_at_once_over_override_and_controller():
    from ant_controller.layout import BLADE_BELOW_CMD

    core = BladeDriverCore(DriverParams())
    core.command(1 << BLADE_BELOW_CMD, 0.0)
    assert core.update(0.0, 0.0) == pytest.approx(-0.02)
    core.override(0.05, 0.05)
    assert core.update(0.1, 0.0, hold="e-stop latched") == pytest.approx(0.10)  # no ramp
    assert core.state.source == "hold: e-stop latched"
    # Released: the operator's set-point is in charge again, reached with the slew ramp.
    assert core.update(0.2, 0.0) == pytest.approx(0.10 - 0.25 * 0.1)


def test_backoff_doubles_up_to_the_maximum_and_resets():
    from blade_driver.reconnect import Backoff

    b = Backoff(0.5, 3.0)
    assert b.due(0.0)
    delays = [b.failed(float(t)) for t in range(5)]
    assert delays == [0.5, 1.0, 2.0, 3.0, 3.0]
    assert not b.due(4.0) and b.due(7.0)
    b.succeeded()
    assert b.due(0.0) and b.failed(10.0) == 0.5
    with pytest.raises(ValueError):
        Backoff(2.0, 1.0)


def test_after_drive_releases_a_ticks_blade_bits_when_its_drive_ends():
    after = AfterDrive()
    below, level = 1 << BLADE_BELOW_CMD, 1 << BLADE_LEVEL_CMD
    assert after.word((0, 0), below) == [] and after.holding()
    assert after.drive_ended((0, 0)) == [below] and not after.holding()
    assert after.word((0, 0), level) == [level]  # its drive has ended: at once
    assert after.word((2, 0), below) == []
    assert after.drive_ended((1, 0)) == []  # an older tick's end releases nothing newer
    assert after.word((3, 0), level) == []
    assert after.drive_ended((3, 0)) == [below, level]  # tick 2's status never came: in order


def test_a_word_whose_blade_waits_still_feeds_the_watchdog_and_the_force_loop():
    core = BladeDriverCore(DriverParams(watchdog_timeout=1.0))
    core.command(1 << BLADE_BELOW_CMD, 0.0)
    core.update(0.0, 0.0)
    core.command((1 << MOVE_FORWARD) | (1 << BLADE_LEVEL_CMD), 0.9, blade=False)
    assert core.state.setting == BLADE_BELOW and core.pushing
    core.update(1.5, 0.0)
    assert not core.state.watchdog_tripped  # the word at 0.9 s counts
    core.apply_blade(1 << BLADE_LEVEL_CMD)
    assert core.state.setting == BLADE_LEVEL


def test_after_drive_holds_repeated_words_of_one_tick_as_one():
    after = AfterDrive()
    below, level, forward = 1 << BLADE_BELOW_CMD, 1 << BLADE_LEVEL_CMD, 1 << MOVE_FORWARD
    for w in (below, forward, level, forward):
        after.word((5, 0), w)
    assert after.held == [((5, 0), level)]
    assert after.drive_ended((5, 0)) == [level]


def test_time_going_back_restarts_the_core_like_a_fresh_one():
    """A restarted simulator (time back to 0): the old setting, set-point and override go."""
    core = BladeDriverCore(DriverParams(override_timeout=30.0))
    core.command(word(BLADE_BELOW_CMD, MOVE_FORWARD), 0.0)
    for t in range(1, 13):
        core.command(word(BLADE_BELOW_CMD, MOVE_FORWARD), float(t))
        core.update(float(t), 7.0)
    core.override(0.05, 12.0)  # an operator set-point, valid until t = 42 on the old clock
    assert core.update(12.0, 7.0) != pytest.approx(0.10)
    assert not core.went_back(12.0) and core.went_back(0.0)
    fresh = BladeDriverCore(DriverParams(override_timeout=30.0))
    for t, w in enumerate((word(BLADE_LEVEL_CMD), word(MOVE_FORWARD), 0)):
        core.command(w, float(t))
        fresh.command(w, float(t))
        assert core.update(float(t), 2.0) == fresh.update(float(t), 2.0)
        assert core.state == fresh.state
    assert core.restarts == 1 and core.state.override is None
    assert core.update(2.0, 2.0) == pytest.approx(0.0)  # level, no old override, no ramp


def test_update_with_an_earlier_time_homes_without_a_command():
    """Wall clock set back on hardware: no word yet in the new time, so the blade goes home."""
    core = BladeDriverCore()
    core.command(word(BLADE_BELOW_CMD), 100.0)
    assert core.update(100.0, 0.0) == pytest.approx(-0.02)
    assert core.update(50.0, 0.0) == pytest.approx(0.10)  # restart: home, no rate limit
    assert core.state.source == "no command yet" and core.restarts == 1


def test_gate_reason_kind_ignores_the_growing_age():
    """A lost heartbeat is one hold, not a new one each time its age is asked."""
    from excavation_common.safety import MotionGate

    gate = MotionGate(deadman=0.5)
    gate.active = True
    gate.on_enabled(True)
    gate.on_heartbeat("armed", 0.0)
    assert gate.reason(0.2) is None and MotionGate.kind(None) is None
    first, later = gate.reason(1.0), gate.reason(2.0)
    assert first != later and MotionGate.kind(first) == MotionGate.kind(later) == "heartbeat lost"
    gate.on_heartbeat("paused", 2.0)
    assert MotionGate.kind(gate.reason(2.1)) == "team paused"


def test_the_sim_schedule_sends_one_set_point_per_tick_when_its_word_is_in():
    """TickSetpoints: a tick waits for its word, sends once, a closed gate sends home held
    without touching the core, and the tick's own set-point follows when it opens."""
    from blade_driver.core import TickSetpoints

    core = BladeDriverCore(DriverParams())
    ticks = TickSetpoints()
    home = core.params.home
    assert ticks.next(core, (1, 0), 1.0, None, held=False, waiting_for_drive=False) is None
    core.command(word(BLADE_BELOW_CMD), 1.0)
    ticks.word_tick = (1, 0)
    assert ticks.next(core, (1, 0), 1.0, None, held=False, waiting_for_drive=True) is None
    value, held = ticks.next(core, (1, 0), 1.0, None, held=False, waiting_for_drive=False)
    assert not held and value == core.state.setpoint and core.state.setting == BLADE_BELOW
    assert ticks.next(core, (1, 0), 1.0, None, held=False, waiting_for_drive=False) is None
    before = core.state.setpoint
    assert ticks.next(core, (2, 0), 2.0, None, held=True, waiting_for_drive=False) == (home, True)
    assert core.state.setpoint == before  # held: the core untouched
    assert ticks.next(core, (2, 0), 2.0, None, held=True, waiting_for_drive=False) is None
    ticks.pending_override = 0.02  # an operator set-point: no word needed, taken once
    value, held = ticks.next(core, (2, 0), 2.0, None, held=False, waiting_for_drive=False)
    assert not held and ticks.pending_override is None and core.state.override == 0.02


def test_the_driver_node_never_branches_on_its_backend():
    from pathlib import Path

    import blade_driver.driver_node as node

    source = Path(node.__file__).read_text()
    assert "backend ==" not in source and "backend !=" not in source
