"""``ros2 run dome_emulator servo_board``: one robot's blade servo board on a pseudo-terminal.

Opens a pseudo-terminal (``os.openpty``, raw) and answers the blade driver's ``serial``
backend on it as the robot's board would (:mod:`dome_emulator.servo_board`), so that the
real driver runs unchanged against it: point the driver's ``port`` at the path. The path
(the terminal's slave name, e.g. ``/dev/pts/5``) is written to ``path_file`` (one line,
atomically, before the first diagnostics) and shown on ``/diagnostics``; with ``link`` a
symlink of that name points at it, a stable port name to write into the driver's
parameters before the board starts (as ``/dev/serial/by-id/...`` is on a robot)::

    ros2 run dome_emulator servo_board --ros-args -r __ns:=/robot_0 -p link:=/tmp/robot_0_blade
      -r world/servo_command:=/robot_0/blade/servo_command
      -r world/plant_state:=/robot_0/blade/plant_state
    ros2 run blade_driver driver --ros-args -r __ns:=/robot_0 -p backend:=serial
      -p port:=/tmp/robot_0_blade

Publishes ``world/servo_command`` (excavation_interfaces/BladeCommand: the blade position
the servo is at, stamped with the node clock; ``dynamics``'
``/robot_k/blade/servo_command``, which sets the simulated blade to the nearest setting:
run ``dynamics`` with ``blade_after_motion: false``, since the serial driver holds a
tick's blade bits itself) whenever the servo moved, and every ``refresh`` seconds.
Subscribes ``world/plant_state`` (JointState: ``dynamics``' ``/robot_k/blade/plant_state``,
its effort the blade's push force) for the load cell (``force_source: world``).
``/diagnostics``: ``/robot_k/servo_board``, OK with the port in the message and the values
port, link, path_file, requests, set_points, refused, dropped, corrupted, angle, target,
force. ``drop_every`` and ``corrupt_every`` can be set at runtime (fault drills).

A reader thread serves the terminal (one request, one answer); the servo model moves on
``rate`` times a second on the wall clock.
"""

from __future__ import annotations

import math
import os
import select
import sys
import threading
import time
import tty

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from excavation_interfaces.msg import BladeCommand
from rclpy.node import Node
from sensor_msgs.msg import JointState

from dome_emulator.errors import PtyError
from dome_emulator.servo_board import Dropped, Reply, ServoBoard, ServoBoardParams
from excavation_common.files import write_text_atomic
from excavation_common.ros import declare_params, diagnostics, spin_node


def open_pty() -> tuple[int, int, str]:
    """A raw pseudo-terminal: ``(master fd, slave fd, slave path)``.

    The slave stays open here, so the master never reads end-of-file while no host has the
    port open (the driver closes and reopens it).
    """
    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    return master, slave, os.ttyname(slave)


def make_link(link: str, target: str) -> None:
    """Point the symlink ``link`` at ``target``, replacing what was there atomically.

    Raises:
        PtyError: The link cannot be made.
    """
    temporary = f"{link}.{os.getpid()}.tmp"
    try:
        if os.path.lexists(temporary):
            os.unlink(temporary)
        os.symlink(target, temporary)
        os.replace(temporary, link)
    except OSError as exc:
        raise PtyError(link, "link", target, f"cannot make the symlink: {exc}") from exc


class ServoBoardNode(Node):
    """Thin ROS plumbing around :class:`ServoBoard` and its pseudo-terminal."""

    def __init__(self, **kwargs) -> None:
        super().__init__("servo_board", **kwargs)
        self.params = p = declare_params(self, ServoBoardParams, on_change=self.on_params)
        self.lock = threading.Lock()
        self.core = ServoBoard(p, time.monotonic())
        self.master, self.slave, self.port = open_pty()
        try:
            if p.link:
                make_link(p.link, self.port)
            if p.path_file:
                try:
                    write_text_atomic(p.path_file, self.port + "\n")
                except OSError as exc:
                    raise PtyError(p.path_file, "path_file", self.port, str(exc)) from exc
        except PtyError:
            self.close_pty()
            raise
        self.command_pub = self.create_publisher(BladeCommand, "world/servo_command", 10)
        self.create_subscription(JointState, "world/plant_state", self.on_plant_state, 10)
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.create_timer(1.0 / p.rate, self.move)
        self.create_timer(p.diagnostics_period, self.publish_diagnostics)
        self.stop = threading.Event()
        self.reader = threading.Thread(target=self.serve, name="servo_board", daemon=True)
        self.reader.start()
        self.get_logger().info(f"servo board on {self.port}")

    def on_params(self, params: ServoBoardParams) -> None:
        """Runtime changes: the injected faults."""
        with self.lock:
            self.params = params
            self.core.set_params(params)

    def serve(self) -> None:
        """Answer the host's requests until the node is destroyed (the reader thread)."""
        buffer = b""
        while not self.stop.is_set():
            ready, _, _ = select.select([self.master], [], [], 0.05)
            if not ready:
                continue
            try:
                chunk = os.read(self.master, 1024)
            except OSError:
                return
            buffer += chunk
            while b"\n" in buffer:
                line, buffer = buffer.split(b"\n", 1)
                with self.lock:
                    answer = self.core.handle(line + b"\n", time.monotonic())
                match answer:
                    case Reply(data):
                        os.write(self.master, data)
                    case Dropped():
                        pass

    def move(self) -> None:
        """Move the servo on; send the world's blade where it is."""
        with self.lock:
            command = self.core.world_command(time.monotonic())
        if command is None:
            return
        stamp = self.get_clock().now().to_msg()
        self.command_pub.publish(BladeCommand(stamp=stamp, position=float(command.position)))

    def on_plant_state(self, msg: JointState) -> None:
        """The simulated blade's push force, for the load cell."""
        names = list(msg.name)
        joint = self.params.joint
        if joint not in names or names.index(joint) >= len(msg.effort):
            self.get_logger().warning(
                f"world/plant_state has no effort for joint {joint!r} ({names})",
                throttle_duration_sec=5.0,
            )
            return
        force = float(msg.effort[names.index(joint)])
        if math.isfinite(force):
            with self.lock:
                self.core.set_world_force(force)

    def publish_diagnostics(self) -> None:
        """The port, and what the board has answered."""
        c = self.core
        with self.lock:
            values = {
                "port": self.port,
                "link": self.params.link,
                "path_file": self.params.path_file,
                "firmware": self.params.firmware,
                "requests": c.requests,
                "set_points": c.set_points,
                "refused": c.refused,
                "dropped": c.dropped,
                "corrupted": c.corrupted,
                "angle": f"{c.angle:.2f}",
                "target": f"{c.target:.2f}",
                "force_source": self.params.force_source,
                "world_force": "none yet" if c.world_force is None else f"{c.world_force:.3f}",
            }
            requests = c.requests
        message = f"servo board on {self.port}: " + (
            f"{requests} requests" if requests else "waiting for the host"
        )
        self.diag_pub.publish(
            diagnostics(self, DiagnosticStatus.OK, message, values, hardware_id=self.port)
        )

    def close_pty(self) -> None:
        """Close both ends of the terminal (never raises)."""
        for fd in (self.master, self.slave):
            try:
                os.close(fd)
            except OSError:
                pass

    def destroy_node(self) -> None:
        """Stop serving, close the terminal, remove the link and the path file."""
        self.stop.set()
        self.reader.join(timeout=2.0)
        self.close_pty()
        for name in (self.params.link, self.params.path_file):
            if name and os.path.lexists(name):
                try:
                    os.unlink(name)
                except OSError:
                    pass
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run dome_emulator servo_board``."""
    return spin_node(ServoBoardNode, args)


if __name__ == "__main__":
    sys.exit(main())
