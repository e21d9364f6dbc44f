"""The blade driver on a pseudo-terminal servo board and against the simulator's topics."""

from __future__ import annotations

import os
import threading

import pytest
from helpers.blades import blade_driver_node, blade_probe, word

from ant_controller.layout import (
    BLADE_ABOVE_CMD,
    BLADE_BELOW_CMD,
    BLADE_HOME,
    BLADE_LEVEL_CMD,
    MOVE_FORWARD,
)
from blade_driver.errors import BoardError
from blade_driver.fake_board import FakeBoard, open_pty
from blade_driver.protocol import ServoCalibration
from blade_driver.serial_backend import SerialBackend


@pytest.fixture
def board():
    """A fake servo board answering on a pseudo-terminal: ``(board, port path)``."""
    fake = FakeBoard()
    master, path = open_pty()
    stop = threading.Event()
    thread = threading.Thread(target=fake.serve, args=(master, stop.is_set), daemon=True)
    thread.start()
    yield fake, path
    stop.set()
    thread.join(timeout=2)
    os.close(master)


def test_serial_backend_talks_to_the_board(board):
    fake, path = board
    link = SerialBackend(path, timeout=1.0)
    try:
        assert link.ping() == "fake_board/1"
        angle = link.set_position(-0.02)
        assert angle == pytest.approx(ServoCalibration().angle(-0.02))
        assert fake.target == pytest.approx(angle)
        position, force = link.read()
        assert position == pytest.approx(-0.02)
        assert force == pytest.approx(400.0 * 0.02)  # the board's soil spring
        link.set_position(5.0)  # beyond the servo: clipped to its range, accepted
        assert fake.target == 180.0
    finally:
        link.close()


@pytest.mark.parametrize(
    ("fault", "match"),
    [("drop_every", "no answer from the servo board"), ("corrupt_every", "checksum")],
)
def test_serial_faults_are_clear_errors(board, fault, match):
    fake, path = board
    setattr(fake, fault, 2)
    link = SerialBackend(path, timeout=0.3)
    try:
        link.ping()  # request 1 is answered
        with pytest.raises(BoardError, match=match) as info:
            link.read()  # request 2 is dropped or garbled
        assert path in str(info.value)
        assert link.ping() == "fake_board/1"  # the link recovers
    finally:
        link.close()


def test_board_refusal_and_missing_port(board, tmp_path):
    fake, path = board
    link = SerialBackend(path, timeout=1.0, calibration=ServoCalibration(min_deg=-50.0))
    try:
        with pytest.raises(BoardError, match="board refused SET"):
            link.set_position(-0.2)  # -30 deg: the board's range is 0..180
    finally:
        link.close()
    with pytest.raises(BoardError, match="cannot open"):
        SerialBackend(str(tmp_path / "no-such-tty"))


def test_serial_driver_node_commands_the_board(ros, board):
    from std_msgs.msg import Float64MultiArray, UInt16

    fake, path = board
    cal = ServoCalibration()
    blade_driver_node(ros, backend="serial", port=path, rate=50.0, watchdog_timeout=0.6)
    probe = blade_probe(ros)
    assert ros.spin_until(lambda: len(probe.joints) > 3)  # reads the board and publishes
    assert probe.joints[-1].position[0] == pytest.approx(0.10, abs=1e-4)  # starts home

    def send_until(msg_pub, msg, cond, timeout=10.0):
        def check():
            msg_pub.publish(msg)
            return cond()

        return ros.spin_until(check, timeout)

    level = UInt16(data=word(BLADE_LEVEL_CMD))
    assert send_until(probe.behaviour, level, lambda: fake.target == cal.angle(0.0))
    assert probe.joints[-1].name == ["blade"]
    # The operator's set-point wins while it keeps coming...
    override = Float64MultiArray(data=[0.05])
    assert send_until(probe.override, override, lambda: fake.target == cal.angle(0.05))
    assert any(s.message == "operator override" for s in probe.diags)
    # ...a malformed one is reported and changes nothing...
    bad = Float64MultiArray(data=[0.0, 1.0])
    assert send_until(probe.override, bad, lambda: any(s.level == b"\x02" for s in probe.diags))
    assert any("needs one value per joint" in s.message for s in probe.diags)
    # ...and silence from the controller sends the blade home.
    assert ros.spin_until(lambda: fake.target == cal.angle(0.10), timeout=10.0)
    assert ros.spin_until(lambda: any("watchdog" in s.message for s in probe.diags), 5.0)
    # Pushing below ground with the blade: the force loop trims the blade up (board force 8 N
    # at -0.02 m is above the 6 N wanted).
    push = UInt16(data=word(MOVE_FORWARD, BLADE_BELOW_CMD))
    assert send_until(
        probe.behaviour, push, lambda: cal.angle(-0.02) < fake.target < cal.angle(-0.012)
    )


def test_sim_driver_node_answers_each_tick_in_sim_time(ros):
    from builtin_interfaces.msg import Time
    from std_msgs.msg import UInt16

    from blade_driver.hardware import joint_state

    driver = blade_driver_node(ros, backend="sim", watchdog_timeout=1.5)
    probe = blade_probe(ros)
    assert ros.spin_until(lambda: probe.count_subscribers("/robot_0/blade/servo_state") > 0)
    assert ros.spin_until(lambda: driver.hold is None)  # the team is armed

    def tick(t, behaviour=None, force=0.0, position=0.10):
        n_servo = len(probe.servo)
        probe.state.publish(joint_state(position, force, Time(sec=t)))
        assert ros.spin_until(lambda: probe.joints and probe.joints[-1].header.stamp.sec == t)
        if behaviour is not None:
            probe.behaviour.publish(UInt16(data=behaviour))
            assert ros.spin_until(lambda: len(probe.servo) > n_servo)
            return probe.servo[-1]
        ros.spin_until(lambda: len(probe.servo) > n_servo, timeout=0.5)
        return probe.servo[-1] if len(probe.servo) > n_servo else None

    cmd = tick(0, word(BLADE_BELOW_CMD))
    assert cmd.stamp.sec == 0 and cmd.position == pytest.approx(-0.02)
    assert probe.joints[-1].effort[0] == 0.0
    cmd = tick(1, word(BLADE_LEVEL_CMD), position=-0.02)
    assert cmd.stamp.sec == 1 and cmd.position == pytest.approx(0.0)
    # The controller goes quiet: at tick 2 the watchdog (1.5 s of sim time) is not due, so
    # no set-point; at tick 3 it is, and the driver sends "home" without waiting.
    assert tick(2) is None
    cmd = tick(3)
    assert cmd is not None and cmd.stamp.sec == 3
    assert cmd.position == pytest.approx(0.10)


def test_sim_driver_gives_a_late_reader_the_ticks_joint_state(ros):
    """A reader matched after the tick's relay (a controller that joined late) gets it too.

    The relay goes out once per tick on a volatile writer; without the copy, a controller
    matched a moment later waited for its tick until the next (a robot idled tick 0).
    """
    from builtin_interfaces.msg import Time
    from rclpy.node import Node
    from sensor_msgs.msg import JointState

    from blade_driver.hardware import joint_state

    blade_driver_node(ros, backend="sim")
    probe = blade_probe(ros)
    assert ros.spin_until(lambda: probe.count_subscribers("/robot_0/blade/servo_state") > 0)
    probe.state.publish(joint_state(0.10, 0.0, Time(sec=7)))
    assert ros.spin_until(lambda: probe.joints and probe.joints[-1].header.stamp.sec == 7)
    late: list[JointState] = []
    reader = ros.add(Node("late_controller", context=ros.context))
    reader.create_subscription(JointState, "/robot_0/blade/joint_states", late.append, 10)
    assert ros.spin_until(lambda: late)
    assert {m.header.stamp.sec for m in late} == {7}
    assert ros.spin_until(lambda: len(probe.joints) >= 2)  # the first reader got the copy too
    assert {m.header.stamp.sec for m in probe.joints} == {7}


def _drive_status(probe, tick, status):
    """Publish what the drive executor says about its goal of ``tick`` (sec)."""
    from excavation_interfaces.msg import DriveStatus

    msg = DriveStatus(status=status)
    msg.goal.stamp.sec = tick
    probe.status.publish(msg)


def test_sim_driver_waits_for_the_ticks_drive_before_moving_the_blade(ros):
    """``blade_after_motion``: a fake executor's ``drive/status`` releases each tick's blade."""
    from builtin_interfaces.msg import Time
    from excavation_interfaces.msg import DriveStatus as GoalStatus
    from std_msgs.msg import UInt16

    from blade_driver.hardware import joint_state

    driver = blade_driver_node(ros, backend="sim", blade_after_motion=True)
    probe = blade_probe(ros)
    probe.status = probe.create_publisher(GoalStatus, "/robot_0/drive/status", 10)
    assert ros.spin_until(lambda: probe.count_subscribers("/robot_0/drive/status") > 0)
    assert ros.spin_until(lambda: driver.hold is None)

    def new_tick(t):
        probe.state.publish(joint_state(0.10, 0.0, Time(sec=t)))
        assert ros.spin_until(lambda: probe.joints and probe.joints[-1].header.stamp.sec == t)

    sent = [0]  # set-points the test has seen (a late one would show in the next count)

    def answer(m, expect):
        """The set-point the last input released, or None; ``expect``: one is due.

        A set-point is published in the callback that takes the input, so once the driver
        has taken it (the callers wait for that) one is either on its way or not coming;
        none expected waits briefly, and every later answer checks that exactly one
        set-point came since the last one seen, so a late one fails the test there.
        """
        ros.spin_until(lambda: len(probe.servo) > m, timeout=10.0 if expect else 0.5)
        if len(probe.servo) == m:
            return None
        assert len(probe.servo) == m + 1 == sent[0] + 1, [s.position for s in probe.servo]
        sent[0] = len(probe.servo)
        return probe.servo[-1]

    def send_word(bits, expect=False):
        n, m = driver.commands, len(probe.servo)
        probe.behaviour.publish(UInt16(data=bits))
        assert ros.spin_until(lambda: driver.commands > n)
        return answer(m, expect)

    def send_status(tick, status, expect=False):
        m = len(probe.servo)
        _drive_status(probe, tick, status)
        if status != GoalStatus.STATUS_EXECUTING:
            done = driver.after
            assert ros.spin_until(lambda: done.done is not None and done.done[0] >= tick)
        return answer(m, expect)

    new_tick(0)
    assert send_word(word(MOVE_FORWARD, BLADE_BELOW_CMD)) is None
    assert send_status(0, GoalStatus.STATUS_EXECUTING) is None  # still driving: the blade waits
    assert driver.core.pushing and driver.core.state.setting == BLADE_HOME  # not yet set
    cmd = send_status(0, GoalStatus.STATUS_SUCCEEDED, expect=True)
    # below ground, trimmed by the constant-force loop (it pushes: 0 N measured)
    assert cmd.stamp.sec == 0 and cmd.position == pytest.approx(-0.02, abs=0.008)
    # Tick 1: an old tick's status releases nothing; an aborted drive of tick 1 does.
    new_tick(1)
    assert send_word(word(BLADE_LEVEL_CMD)) is None
    assert send_status(0, GoalStatus.STATUS_SUCCEEDED) is None
    cmd = send_status(1, GoalStatus.STATUS_ABORTED, expect=True)
    assert cmd.stamp.sec == 1 and cmd.position == pytest.approx(0.0)
    # Tick 2: the drive ended before the word came (nothing to drive): the blade at once.
    new_tick(2)
    assert send_status(2, GoalStatus.STATUS_SUCCEEDED) is None
    cmd = send_word(word(BLADE_ABOVE_CMD), expect=True)
    assert cmd.stamp.sec == 2 and cmd.position == pytest.approx(0.02)


def test_serial_driver_waits_for_the_team_ticks_drive(ros, board):
    from builtin_interfaces.msg import Time
    from excavation_interfaces.msg import DriveStatus as GoalStatus
    from excavation_interfaces.msg import Tick
    from std_msgs.msg import UInt16

    fake, path = board
    cal = ServoCalibration()
    driver = blade_driver_node(ros, backend="serial", port=path, rate=50.0, blade_after_motion=True)
    probe = blade_probe(ros)
    probe.status = probe.create_publisher(GoalStatus, "/robot_0/drive/status", 10)
    team_tick = probe.create_publisher(Tick, "/team/tick", 10)
    assert ros.spin_until(lambda: probe.count_subscribers("/team/tick") > 0)
    assert ros.spin_until(lambda: len(probe.joints) > 3 and fake.target == cal.angle(0.10))
    team_tick.publish(Tick(stamp=Time(sec=4), tick=4))
    assert ros.spin_until(lambda: driver.hw.team_tick == (4, 0))
    level = UInt16(data=word(BLADE_LEVEL_CMD))

    def words_until(cond, timeout):
        def check():
            probe.behaviour.publish(level)  # the controller repeats (feeds the watchdog)
            return cond()

        return ros.spin_until(check, timeout)

    assert not words_until(lambda: fake.target != cal.angle(0.10), timeout=1.0)  # waits
    assert driver.commands > 0 and driver.after.holding()
    _drive_status(probe, 4, GoalStatus.STATUS_SUCCEEDED)
    assert words_until(lambda: fake.target == cal.angle(0.0), timeout=5.0)


def test_serial_driver_watchdog_counts_team_ticks(ros, board):
    """One word per tick, ticks of many wall seconds: the blade keeps its setting.

    The first dome rehearsal's blades went home 1.5 wall seconds into every tick (the
    watchdog counted wall time) and no word's setting outlived its drive. On tick time the
    watchdog trips only after two ticks without a word.
    """
    from builtin_interfaces.msg import Time
    from excavation_interfaces.msg import DriveStatus as GoalStatus
    from excavation_interfaces.msg import Tick
    from std_msgs.msg import UInt16

    fake, path = board
    cal = ServoCalibration()
    driver = blade_driver_node(
        ros, backend="serial", port=path, rate=50.0, blade_after_motion=True, watchdog_timeout=1.5
    )
    probe = blade_probe(ros)
    probe.status = probe.create_publisher(GoalStatus, "/robot_0/drive/status", 10)
    team_tick = probe.create_publisher(Tick, "/team/tick", 10)
    assert ros.spin_until(lambda: probe.count_subscribers("/team/tick") > 0)
    for topic in ("/robot_0/behaviour", "/robot_0/drive/status"):
        assert ros.spin_until(lambda topic=topic: probe.count_subscribers(topic) > 0)
    assert ros.spin_until(lambda: len(probe.joints) > 3 and fake.target == cal.angle(0.10))
    team_tick.publish(Tick(stamp=Time(sec=4), tick=4))
    assert ros.spin_until(lambda: driver.hw.team_tick == (4, 0))
    probe.behaviour.publish(UInt16(data=word(BLADE_LEVEL_CMD)))  # once
    assert ros.spin_until(lambda: driver.commands == 1)
    _drive_status(probe, 4, GoalStatus.STATUS_SUCCEEDED)
    assert ros.spin_until(lambda: fake.target == cal.angle(0.0), timeout=5.0)
    # 100 control steps (2 s at 50 Hz: past a wall-clock watchdog) in the same tick.
    seen = len(probe.joints)
    assert ros.spin_until(lambda: len(probe.joints) >= seen + 100, timeout=30.0)
    assert fake.target == cal.angle(0.0) and driver.core.state.source.startswith("controller")
    assert not driver.core.state.watchdog_tripped
    # Tick 5 without a word: still within the watchdog; tick 6 too: the blade goes home.
    team_tick.publish(Tick(stamp=Time(sec=5), tick=5))
    assert ros.spin_until(lambda: driver.hw.team_tick == (5, 0))
    seen = len(probe.joints)
    assert ros.spin_until(lambda: len(probe.joints) >= seen + 5, timeout=20.0)
    assert fake.target == cal.angle(0.0)
    team_tick.publish(Tick(stamp=Time(sec=6), tick=6))
    assert ros.spin_until(lambda: fake.target == cal.angle(0.10), timeout=5.0)
    assert driver.core.state.watchdog_tripped


def test_the_board_homes_the_servo_when_its_set_points_stop(board):
    """``TIMEOUT <ms>``: no ``SET`` for that long and the board retracts the blade itself."""
    fake, path = board
    cal = ServoCalibration()
    link = SerialBackend(path, timeout=1.0)
    try:
        assert link.set_timeout(0.3) == 300
        link.set_position(-0.02)
        assert fake.target == cal.angle(-0.02) and fake.timeout == 0.3
        for _ in range(5):  # set-points keep coming: the blade stays down
            link.set_position(-0.02)
        assert fake.target == cal.angle(-0.02) and fake.timeouts == 0
        assert fake.timed_out.wait(5.0)  # the host is gone: the board's own loop times it out
        assert fake.target == fake.home_deg == cal.angle(0.10) and fake.timeouts == 1
        link.set_position(0.0)  # the host is back: its set-points rule again
        assert fake.target == cal.angle(0.0)
        assert link.set_timeout(0) == 0 and fake.timeout == 0.0
    finally:
        link.close()


def test_the_driver_arms_the_boards_timeout_and_a_dead_driver_leaves_the_blade_home(ros, board):
    from std_msgs.msg import UInt16

    fake, path = board
    cal = ServoCalibration()
    driver = blade_driver_node(ros, backend="serial", port=path, rate=50.0, board_timeout=0.4)
    probe = blade_probe(ros)
    assert ros.spin_until(lambda: driver.hw.board_timeout == "armed" and fake.timeout == 0.4)
    level = UInt16(data=word(BLADE_LEVEL_CMD))

    def words_until(cond, timeout=10.0):
        def check():
            probe.behaviour.publish(level)
            return cond()

        return ros.spin_until(check, timeout)

    assert words_until(lambda: fake.target == cal.angle(0.0))
    ros.executor.remove_node(driver)  # its computer hangs: no set-point, no driver to home it
    try:
        assert fake.timed_out.wait(5.0)
        assert fake.target == cal.angle(0.10) and fake.timeouts == 1
    finally:
        driver.destroy_node()
