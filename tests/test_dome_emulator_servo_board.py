"""The emulated servo board: the blade protocol with the fake board's board-side behaviour,
and the real serial blade driver moving the simulated world's blade through it."""

from __future__ import annotations

import dataclasses
import os

import pytest
from dome_emulator.servo_board import (
    SPRING,
    Dropped,
    MoveBlade,
    Reply,
    ServoBoard,
    ServoBoardParams,
)
from helpers.diagnostics import DiagnosticsProbe, values

from blade_driver.errors import BoardError
from blade_driver.fake_board import FakeBoard
from blade_driver.protocol import ServoCalibration, decode, encode
from excavation_common.params import ParameterError, validate


def board(**changes) -> ServoBoard:
    params = dataclasses.replace(ServoBoardParams(), noise=0.0, **changes)
    return ServoBoard(params, 0.0)


def ask(b: ServoBoard, *fields, now: float = 0.0) -> list[str]:
    answer = b.handle(encode(*fields), now)
    assert isinstance(answer, Reply)
    return decode(answer.data)


def test_requests_are_answered_as_the_protocol_says():
    b = board(speed=0.0)
    assert ask(b, "PING") == ["PONG", "dome_emulator/1"]
    assert ask(b, "READ") == ["STATE", "150.00", "0.000"]
    assert ask(b, "SET", "78.00") == ["ACK", "SET", "78.00"]
    assert ask(b, "READ") == ["STATE", "78.00", "0.000"]
    assert b.position() == pytest.approx(ServoCalibration().position(78.0))
    assert ask(b, "SET", "abc")[:2] == ["ERR", "2"]
    assert ask(b, "SET", "181")[:2] == ["ERR", "3"]
    assert ask(b, "SET", "nan")[:2] == ["ERR", "3"]
    assert ask(b, "MOVE")[:2] == ["ERR", "4"]
    answer = b.handle(b"READ*00\n", 0.0)
    assert decode(answer.data)[:2] == ["ERR", "1"]
    assert (b.requests, b.set_points, b.refused) == (9, 1, 5)


def test_the_servo_slews_and_the_world_follows():
    b = board(speed=120.0)
    assert b.world_command(0.0) == MoveBlade(pytest.approx(0.10))  # home at power-up
    assert b.world_command(0.5) is None  # standing, refresh not due
    ask(b, "SET", "78.00", now=0.5)
    moved = b.world_command(0.6)  # 12 degrees in 0.1 s
    assert moved == MoveBlade(pytest.approx(ServoCalibration().position(138.0)))
    assert ask(b, "READ", now=0.6)[1] == "138.00"
    assert b.world_command(1.5) == MoveBlade(pytest.approx(-0.02))  # arrived at 78 deg
    assert b.world_command(2.0) is None
    assert b.world_command(2.6) == MoveBlade(pytest.approx(-0.02))  # refresh: 1 s


def test_the_load_cell_reads_the_world_or_the_spring():
    b = board(speed=0.0)
    assert ask(b, "READ")[2] == "0.000"  # no world force yet
    b.set_world_force(8.25)
    assert ask(b, "READ")[2] == "8.250"
    b.set_world_force(float("nan"))  # ignored
    assert ask(b, "READ")[2] == "8.250"
    b.set_world_force(-3.0)  # never negative
    assert ask(b, "READ")[2] == "0.000"
    spring = board(speed=0.0, force_source=SPRING, stiffness=400.0, soil_surface=0.0)
    ask(spring, "SET", "78.00")  # -0.02 m: 2 cm below the surface
    assert ask(spring, "READ")[2] == "8.000"
    noisy = [ServoBoard(dataclasses.replace(ServoBoardParams(), seed=3), 0.0) for _ in "ab"]
    readings = [[ask(n, "READ")[2] for _ in range(5)] for n in noisy]
    assert readings[0] == readings[1] and len(set(readings[0])) > 1


def test_faults_drop_and_garble_answers():
    b = board(drop_every=3, corrupt_every=2)
    assert isinstance(b.handle(encode("PING"), 0.0), Reply)
    garbled = b.handle(encode("PING"), 0.0)
    with pytest.raises(BoardError, match="checksum"):
        decode(garbled.data)
    assert b.handle(encode("PING"), 0.0) == Dropped()
    assert (b.dropped, b.corrupted) == (1, 1)
    b.set_params(dataclasses.replace(b.params, drop_every=0, corrupt_every=0))
    assert isinstance(b.handle(encode("PING"), 0.0), Reply)


def test_the_board_answers_as_the_fake_board_does():
    """The same requests at the same instants: byte for byte, but the firmware name."""
    params = dataclasses.replace(
        ServoBoardParams(), force_source=SPRING, noise=0.5, seed=7, firmware="fake_board/1"
    )
    ours = ServoBoard(params, 0.0)
    fake = FakeBoard(speed=120.0, noise=0.5, seed=7)
    script = [
        (0.0, encode("PING")),
        (0.1, encode("READ")),
        (0.2, encode("SET", "60.00")),
        (0.3, encode("READ")),
        (0.9, encode("READ")),
        (1.0, encode("SET", "200.00")),
        (1.1, encode("SET", "x")),
        (1.2, b"READ*77\n"),
        (1.3, encode("HELLO")),
        (1.4, encode("READ")),
        (1.5, encode("TIMEOUT", "300")),
        (1.6, encode("SET", "70.00")),
        (1.7, encode("READ")),
        (2.5, encode("READ")),  # no SET since 1.6: both went home at the timeout
        (2.6, encode("TIMEOUT", "soon")),
        (2.7, encode("TIMEOUT", "0")),
        (2.8, encode("SET", "80.00")),
        (9.0, encode("READ")),  # off: the set-point holds
    ]
    for now, line in script:
        answer = ours.handle(line, now)
        assert answer.data == fake.handle(line, now), line


def test_the_set_point_timeout_homes_the_servo_until_the_next_set():
    b = board(speed=0.0)
    assert ask(b, "TIMEOUT", "500") == ["ACK", "TIMEOUT", "500"]
    ask(b, "SET", "78.00", now=1.0)
    b.advance(1.4)
    assert b.target == 78.0
    ask(b, "SET", "78.00", now=1.4)  # the host keeps sending
    b.advance(1.8)
    assert b.target == 78.0 and b.timeouts == 0
    assert b.world_command(1.85) == MoveBlade(pytest.approx(-0.02))
    assert b.world_command(2.5) == MoveBlade(pytest.approx(0.10))  # 1.1 s silent: home
    assert b.timeouts == 1 and ask(b, "READ", now=2.6)[1] == "150.00"
    ask(b, "SET", "90.00", now=3.0)
    assert b.position() == pytest.approx(0.0)


def test_parameters_are_checked():
    validate(ServoBoardParams, {})
    with pytest.raises(ParameterError, match="start_angle"):
        validate(ServoBoardParams, {"start_angle": 200.0})
    with pytest.raises(ParameterError, match="force_source"):
        validate(ServoBoardParams, {"force_source": "load_cell"})
    with pytest.raises(dataclasses.FrozenInstanceError):
        MoveBlade(0.0).position = 1.0


def test_the_serial_blade_driver_moves_the_world_blade_through_the_board(ros, tmp_path):
    from dome_emulator.servo_board_node import ServoBoardNode
    from excavation_interfaces.msg import BladeCommand
    from helpers.blades import blade_driver_node, blade_probe, word
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import JointState
    from std_msgs.msg import UInt16

    from ant_controller.layout import BLADE_BELOW_CMD

    path_file, link = tmp_path / "port", tmp_path / "blade_tty"
    overrides = {"path_file": str(path_file), "link": str(link), "noise": 0.0, "refresh": 0.2}
    board_node = ros.add(
        ServoBoardNode(
            context=ros.context,
            namespace="/robot_0",
            parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()],
        )
    )
    port = path_file.read_text().strip()
    assert port == board_node.port and port.startswith("/dev/pts/")
    assert os.path.realpath(link) == os.path.realpath(port)
    world = ros.add(Node("world", context=ros.context))
    commands = []
    world.create_subscription(BladeCommand, "/robot_0/world/servo_command", commands.append, 10)
    diags = DiagnosticsProbe(world).named("/robot_0/servo_board")
    plant = world.create_publisher(JointState, "/robot_0/world/plant_state", 10)

    # The port survives a host that closes it and opens it again (the driver's reconnect).
    from blade_driver.serial_backend import SerialBackend

    for _ in range(2):
        link_to_board = SerialBackend(str(link), timeout=1.0)
        try:
            assert link_to_board.ping() == "dome_emulator/1"
        finally:
            link_to_board.close()
    # The real driver, serial backend, on the board's stable name.
    blade_driver_node(ros, backend="serial", port=str(link), rate=50.0)
    probe = blade_probe(ros)
    assert ros.spin_until(lambda: len(probe.joints) > 3, 30.0)  # it reads the board
    assert probe.joints[-1].position[0] == pytest.approx(0.10, abs=1e-4)  # home
    assert ros.spin_until(lambda: bool(commands))
    assert commands[-1].position == pytest.approx(0.10) and not commands[-1].held
    assert ros.spin_until(lambda: any(port in s.message for s in diags))
    assert values(diags[-1])["port"] == port

    # A word with the blade below: the driver sets 78 deg, the servo slews, the world follows.
    below = UInt16(data=word(BLADE_BELOW_CMD))

    def lowered():
        probe.behaviour.publish(below)
        return bool(commands) and commands[-1].position == pytest.approx(-0.02)

    assert ros.spin_until(lowered, 30.0)
    assert ros.spin_until(lambda: probe.joints[-1].position[0] == pytest.approx(-0.02), 10.0)
    # The world's push force reaches the driver through the board's load cell.
    pushed = JointState(name=["blade"], position=[-0.02], effort=[8.0])

    def loaded():
        probe.behaviour.publish(below)
        plant.publish(pushed)
        return probe.joints[-1].effort[0] == pytest.approx(8.0)

    assert ros.spin_until(loaded, 10.0)
    assert board_node.core.set_points >= 1 and board_node.core.refused == 0
