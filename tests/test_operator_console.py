"""``ant-operator console``: keys to actions (pure), and one connected process on a
pseudo-terminal against a running supervisor: arm, take a robot over and drive it, hand it
back, e-stop."""

from __future__ import annotations

import os
import pty
import select
import subprocess
import sys
import time

import pytest
from excavation_interfaces.msg import TeamState
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import Bool

from excavation_common.ros import LATCHED
from team_supervisor.console import (
    Console,
    Drive,
    Enable,
    Note,
    Quit,
    Release,
    Take,
    Trigger,
    split_keys,
    status_lines,
)
from team_supervisor.supervisor_node import SupervisorNode


def test_keys_become_actions():
    c = Console(robots=2)
    assert c.key(" ") == [Trigger("estop")] == c.key("e")
    assert c.key("a") == [Trigger("arm")] and c.key("c") == [Trigger("resume")]
    assert isinstance(c.key("up")[0], Note)  # nothing selected, nothing taken: nothing moves
    assert isinstance(c.key("t")[0], Note)
    assert isinstance(c.key("5")[0], Note) and c.selected is None  # no robot 5
    c.key("1")
    assert c.key("up") == [Note("take the robot over first (t)")]
    assert c.key("t") == [Take(1)] and c.taken == 1
    assert c.key("up") == [Drive(1, 0.1, 0.0)] and c.key("down") == [Drive(1, -0.1, 0.0)]
    assert c.key("left") == [Drive(1, 0.0, 0.5)] and c.key("right") == [Drive(1, 0.0, -0.5)]
    assert c.key(" ") == [Trigger("estop")] and c.taken == 1  # an e-stop changes no selection
    c.key("0")
    assert c.key("t") == [Release(1), Take(0)]  # one robot taken over at a time
    assert c.key("d") == [Enable(0, False)] and c.key("n") == [Enable(0, True)]
    assert c.key("h") == [Release(0)] and c.taken is None
    assert c.key("h") == [Note("no robot is taken over")]
    c.key("t")
    assert c.key("q") == [Release(0), Quit()]


def test_terminal_input_splits_into_keys_and_the_status_names_each_robot():
    assert split_keys("a1t\x1b[A\x1b[Dh ") == ["a", "1", "t", "up", "left", "h", " "]
    lines = status_lines(
        2, "armed", {"/robot_1/executor": (0, "following the team")}, selected=1, taken=1
    )
    assert lines[0] == "team: armed"
    assert lines[1] == "  robot 0: no diagnostics yet"
    assert lines[2] == "> robot 1 [operator]: drive: following the team"


def test_a_console_arms_drives_a_robot_hands_it_back_and_stops_the_team(ros):
    """One process, keys written to its input one group at a time, each waited for."""
    from geometry_msgs.msg import TwistStamped
    from helpers.diagnostics import DiagnosticsProbe

    ros.add(SupervisorNode(context=ros.context, parameter_overrides=[Parameter("robots", value=2)]))
    watch = ros.add(Node("watch", context=ros.context))
    states, estops, twists = [], [], []
    watch.create_subscription(TeamState, "/team/heartbeat", lambda m: states.append(m.state), 10)
    watch.create_subscription(Bool, "/team/estop", lambda m: estops.append(m.data), LATCHED)
    watch.create_subscription(TwistStamped, "/robot_1/drive/override", twists.append, 100)
    probe = DiagnosticsProbe(watch)  # the console's own status: its actions, named after it

    def console_said(text: str) -> bool:
        return any(
            s.name.startswith("/ant_operator") and text in str(s.values) for s in probe.statuses
        )

    env = dict(os.environ, ROS_DOMAIN_ID=str(ros.domain))
    command = [sys.executable, "-m", "team_supervisor.operator", "--timeout", "30", "console"]
    # A pseudo-terminal, as an operator's: the console reads keys in cbreak mode from it
    master, slave = pty.openpty()
    proc = subprocess.Popen(
        [*command, "--robots", "2"], stdin=slave, stdout=slave, stderr=subprocess.PIPE, env=env
    )
    os.close(slave)
    screen: list[bytes] = []

    def read_screen() -> None:
        while select.select([master], [], [], 0)[0]:
            try:
                screen.append(os.read(master, 4096))
            except OSError:  # the console closed its end
                return

    def spin_until(condition, timeout=60) -> bool:
        return ros.spin_until(lambda: read_screen() or condition(), timeout=timeout)

    try:
        assert spin_until(lambda: states)

        def keys(data: bytes) -> None:
            os.write(master, data)

        keys(b"a")
        assert spin_until(lambda: states[-1] == "armed")
        keys(b"1t\x1b[A")
        assert spin_until(lambda: any(t.twist.linear.x > 0 for t in twists))
        # it keeps sending while the robot is held: zero once the arrow's half second is over
        assert spin_until(lambda: twists[-1].twist.linear.x == 0.0)
        keys(b"h")
        assert spin_until(lambda: b"handed back to the team" in b"".join(screen))
        ros.spin_until(lambda: False, timeout=0.5)
        count = len(twists)
        ros.spin_until(lambda: False, timeout=1.0)
        assert len(twists) == count and twists[-1].twist.linear.x == 0.0  # handed back
        sent = time.monotonic()
        keys(b" ")
        assert spin_until(lambda: estops and estops[-1])
        print(f"e-stop key to /team/estop: {1000 * (time.monotonic() - sent):.0f} ms")
        assert spin_until(lambda: console_said("estop from the console"))
        keys(b"q")
        assert proc.wait(timeout=60) == 0, proc.stderr.read().decode()
        read_screen()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        os.close(master)
    text = b"".join(screen).decode(errors="replace")
    err = proc.stderr.read()
    assert proc.returncode == 0, err.decode()
    assert "arm: done" in text and "estop: done" in text, text
    assert "robot 1: taken over" in text and "robot 1: handed back to the team" in text
    assert "> robot 1 [operator]" in text


@pytest.mark.system
def test_the_estop_bench_times_every_console(domains, tmp_path):
    """``estop_bench``: an e-stop from each console arrives (the table has each row)."""
    from excavation_bringup.estop_bench import MARK, main

    out = tmp_path / "bench.md"
    assert main(["--repeats", "1", "--domain", str(domains()), "--write", str(out)]) == 0
    text = out.read_text()
    assert text.count(MARK) == 2
    for name in ("ant-operator estop", "ant-operator console", "live view"):
        assert f"| {name} | 1 |" in text
