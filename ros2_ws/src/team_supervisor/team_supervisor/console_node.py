"""``ant-operator console``: one connected process for the operator, keys in, status out.

The keys and what they do: :mod:`team_supervisor.console`. The process connects once (the
supervisor's services, each robot's ``enable`` service and ``drive/override`` topic,
``/team/heartbeat`` and ``/diagnostics``) and then waits on the terminal and the ROS graph
together, so a key reaches the supervisor as one call on a connection already made. Service
calls do not block the console: each answer is printed when it comes. A robot taken over gets
a twist every 1/:data:`~team_supervisor.client.OVERRIDE_RATE` s (zero unless an arrow key
was pressed in the last :data:`~team_supervisor.console.HOLD` s), so its executor keeps
following the operator (its ``override_timeout`` is 0.5 s) until it is handed back.

From a terminal the keys are read one at a time (cbreak mode, restored at exit); from a pipe
(a script, a test) whatever is written is read as keys. The status (team state, each
robot's executor and blade driver, who is selected and taken over) is printed when it
changes, at most twice a second.
"""

from __future__ import annotations

import os
import select
import sys
import time
from typing import TextIO

from excavation_interfaces.msg import TeamState

from team_supervisor.client import OVERRIDE_RATE, NoAnswer, Operator
from team_supervisor.console import (
    HOLD,
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

REDRAW = 0.5
"""Most often the status is printed, s."""


class ConsoleNode:
    """The console's ROS side: clients, publishers and what it hears, on an operator node."""

    def __init__(self, op: Operator, robots: int, out: TextIO) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from std_srvs.srv import SetBool
        from std_srvs.srv import Trigger as TriggerSrv

        self.op, self.robots, self.out = op, robots, out
        node = op.node
        self.team: str | None = None
        self.statuses: dict[str, tuple[int, str]] = {}
        names = ("estop", "reset", "arm", "pause", "resume")
        self.triggers = {n: node.create_client(TriggerSrv, f"{op.supervisor}/{n}") for n in names}
        self.enables = {k: node.create_client(SetBool, f"/robot_{k}/enable") for k in range(robots)}
        self.drives: dict[int, object] = {}
        self.pending: list[tuple[str, object]] = []
        self.controls = 0
        self.last = ""
        self.diag_pub = node.create_publisher(DiagnosticArray, "/diagnostics", 10)
        node.create_subscription(TeamState, "/team/heartbeat", self.on_heartbeat, 10)
        node.create_subscription(DiagnosticArray, "/diagnostics", self.on_diagnostics, 50)

    def wait_for_supervisor(self) -> None:
        """Block until the supervisor's e-stop service answers.

        Raises:
            NoAnswer: Not within the operator's timeout.
        """
        if not self.triggers["estop"].wait_for_service(timeout_sec=self.op.timeout):
            raise NoAnswer(
                f"no supervisor answers {self.op.supervisor}/estop within {self.op.timeout:g} s"
            )

    def on_heartbeat(self, msg) -> None:
        """The team's state (the supervisor's heartbeat)."""
        self.team = msg.state

    def on_diagnostics(self, msg) -> None:
        """The newest status of each node."""
        for s in msg.status:
            level = s.level[0] if isinstance(s.level, bytes) else int(s.level)
            self.statuses[s.name] = (level, s.message)

    def control(self, what: str) -> None:
        """Count and remember an action (the console's ``/diagnostics``: its origin)."""
        self.controls += 1
        self.last = f"{what} from the console"

    def publish_diagnostics(self) -> None:
        """The console's status: its actions, named after it (the origin of each)."""
        from diagnostic_msgs.msg import DiagnosticStatus

        from excavation_common.ros import diagnostics

        values = {"controls": self.controls, "last_control": self.last}
        message = f"operator console: {self.controls} actions"
        self.diag_pub.publish(diagnostics(self.op.node, DiagnosticStatus.OK, message, values))

    def say(self, text: str) -> None:
        """One line to the operator."""
        self.out.write(text + "\n")
        self.out.flush()

    def trigger(self, name: str) -> None:
        """Call ``~/NAME`` without waiting (the answer is printed when it comes)."""
        from std_srvs.srv import Trigger as TriggerSrv

        self.control(name)
        self.pending.append((name, self.triggers[name].call_async(TriggerSrv.Request())))

    def enable(self, robot: int, on: bool) -> None:
        """Enable or disable ``robot`` without waiting."""
        from std_srvs.srv import SetBool

        what = f"{'enable' if on else 'disable'} robot {robot}"
        self.control(what)
        self.pending.append((what, self.enables[robot].call_async(SetBool.Request(data=on))))

    def answers(self) -> None:
        """Print the answers that came."""
        for what, future in list(self.pending):
            if future.done():
                self.pending.remove((what, future))
                reply = future.result()
                word = "done" if reply.success else "refused"
                self.say(f"{what}: {word}: {reply.message}")

    def twist(self, robot: int, vx: float, wz: float) -> None:
        """One drive override for ``robot``."""
        from geometry_msgs.msg import TwistStamped

        if robot not in self.drives:
            self.drives[robot] = self.op.node.create_publisher(
                TwistStamped, f"/robot_{robot}/drive/override", 10
            )
        msg = TwistStamped()
        msg.header.stamp = self.op.node.get_clock().now().to_msg()
        msg.header.frame_id = f"robot_{robot}/base_link"
        msg.twist.linear.x, msg.twist.angular.z = float(vx), float(wz)
        self.drives[robot].publish(msg)


def _read_keys(fd: int) -> tuple[list[str], bool]:
    """The keys waiting on ``fd`` and whether the input ended (a closed pipe)."""
    data = os.read(fd, 256)
    if not data:
        return [], True
    return split_keys(data.decode("utf-8", errors="replace")), False


def run_console(op: Operator, robots: int, fd: int, out: TextIO) -> int:
    """The console's loop until ``q`` or the end of the input; returns the exit code."""
    ros = ConsoleNode(op, robots, out)
    console = Console(robots)
    ros.wait_for_supervisor()
    ros.say("ant-operator console: space/e e-stop, a arm, p/c pause/resume, r reset, 0-9 select,")
    ros.say("  t take over, arrows drive, h hand back, d/n disable/enable, q quit")
    drive = (0.0, 0.0, 0.0)  # vx, wz, until (monotonic)
    next_twist = next_status = 0.0
    shown: list[str] = []
    ended = False
    while True:
        ready, _, _ = select.select([fd], [], [], 0.02) if not ended else ([], [], [])
        keys: list[str] = []
        if ready:
            keys, ended = _read_keys(fd)
        for key in keys:
            for action in console.key(key):
                if isinstance(action, Trigger):
                    ros.trigger(action.name)
                elif isinstance(action, Enable):
                    ros.enable(action.robot, action.on)
                elif isinstance(action, Take):
                    ros.control(f"take robot {action.robot} over")
                    drive = (0.0, 0.0, 0.0)
                    ros.twist(action.robot, 0.0, 0.0)
                    ros.say(f"robot {action.robot}: taken over (zero until an arrow key)")
                elif isinstance(action, Drive):
                    drive = (action.vx, action.wz, time.monotonic() + HOLD)
                    ros.twist(action.robot, action.vx, action.wz)
                elif isinstance(action, Release):
                    ros.control(f"hand robot {action.robot} back")
                    ros.twist(action.robot, 0.0, 0.0)
                    ros.say(f"robot {action.robot}: handed back to the team")
                elif isinstance(action, Note):
                    ros.say(action.text)
                elif isinstance(action, Quit):
                    _flush(ros)
                    return 0
        now = time.monotonic()
        if console.taken is not None and now >= next_twist:
            vx, wz, until = drive
            moving = now < until
            ros.twist(console.taken, vx if moving else 0.0, wz if moving else 0.0)
            next_twist = now + 1.0 / OVERRIDE_RATE
        op.executor.spin_once(timeout_sec=0.0)
        ros.answers()
        if now >= next_status:
            lines = status_lines(robots, ros.team, ros.statuses, console.selected, console.taken)
            if lines != shown:
                ros.say("\n".join(lines))
                shown = lines
            ros.publish_diagnostics()
            next_status = now + REDRAW
        if ended and not ros.pending:
            if console.taken is not None:
                ros.twist(console.taken, 0.0, 0.0)
            _flush(ros)
            return 0


def _flush(ros: ConsoleNode) -> None:
    """Wait briefly for the answers still pending and for every override to be delivered."""
    from rclpy.duration import Duration

    deadline = time.monotonic() + ros.op.timeout
    while ros.pending and time.monotonic() < deadline:
        ros.op.executor.spin_once(timeout_sec=0.05)
        ros.answers()
    for pub in ros.drives.values():
        pub.wait_for_all_acked(Duration(seconds=ros.op.timeout))


def console_main(op: Operator, robots: int) -> int:
    """``ant-operator console`` on this process's terminal (or piped input)."""
    fd = sys.stdin.fileno()
    if not os.isatty(fd):
        return run_console(op, robots, fd, sys.stdout)
    import termios
    import tty

    saved = termios.tcgetattr(fd)
    try:
        # TCSANOW, not setcbreak's default TCSAFLUSH: a key pressed while the console was
        # starting (an e-stop) is kept, not discarded
        tty.setcbreak(fd, termios.TCSANOW)
        return run_console(op, robots, fd, sys.stdout)
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, saved)
