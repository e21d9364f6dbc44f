"""The blade driver's hardware interfaces: the simulator's blade and a servo board.

In the style of ros2_control's hardware components, each backend is one class behind one
interface (:class:`BladeHardware`): it creates its own topics, timers or port when the node
is configured, reads the blade (position, force) and writes the set-point, and says which
clock the driver runs on. The node (:mod:`blade_driver.driver_node`) picks the class from
the ``backend`` parameter (:data:`BACKENDS`) and never branches on it; the set-point logic
lives in :mod:`blade_driver.core`.

* :class:`SimBlade` (``sim``): the simulator's blade through two topics in the style of
  topic_based_ros2_control: ``blade/servo_state`` (JointState, stamped with the simulator's
  tick) in, ``blade/servo_command`` (excavation_interfaces/BladeCommand, the set-point,
  stamped with the tick it is for) out. Time is the simulator's, one set-point per tick
  (:class:`~blade_driver.core.TickSetpoints`); a set-point sent under a closed gate says so
  (``held``). A tick stamped before the
  last one (the simulator restarted) is a new trial: set-points, word and override are
  dropped and the core starts afresh.
* :class:`SerialBlade` (``serial``): a servo board on ``port``
  (:mod:`blade_driver.serial_backend`), read and written by a wall-clock timer at ``rate``
  Hz; a port that is absent or fails is reopened with back-off; the board's own set-point
  timeout is armed once per connection. Once ``/team/tick`` has come, the watchdog counts
  the team's tick time.
"""

from __future__ import annotations

import math
from typing import Protocol

from builtin_interfaces.msg import Time as TimeMsg
from excavation_interfaces.msg import BladeCommand, Tick
from rclpy.lifecycle import LifecycleNode
from sensor_msgs.msg import JointState

from blade_driver.core import AfterDrive, Stamp, TickSetpoints
from blade_driver.errors import BoardError, DriverConfigError, PortError
from blade_driver.params import JOINT

TEAM_TICK_TOPIC = "/team/tick"


def joint_state(position: float, force: float, stamp: TimeMsg | None = None) -> JointState:
    """A ``blade`` joint state (position m, effort N)."""
    msg = JointState()
    if stamp is not None:
        msg.header.stamp = stamp
    msg.name = [JOINT]
    msg.position = [float(position)]
    msg.effort = [float(force)]
    return msg


def read_joint(msg: JointState, topic: str) -> tuple[float, float]:
    """``(position, effort)`` of the ``blade`` joint.

    Raises:
        DriverConfigError: No ``blade`` joint, a missing entry, or a non-finite value.
    """
    names = list(msg.name)
    if JOINT not in names:
        raise DriverConfigError(topic, "name", names, "has no 'blade' joint")
    i = names.index(JOINT)
    if i >= len(msg.position) or i >= len(msg.effort):
        raise DriverConfigError(
            topic, "position/effort", (len(msg.position), len(msg.effort)), "no blade entry"
        )
    pos, force = float(msg.position[i]), float(msg.effort[i])
    if not (math.isfinite(pos) and math.isfinite(force)):
        raise DriverConfigError(topic, "blade", (pos, force), "must be finite")
    return pos, force


def seconds(stamp: TimeMsg) -> float:
    """A stamp in seconds."""
    return stamp.sec + stamp.nanosec * 1e-9


class BladeHardware(Protocol):
    """What the node asks of a backend (each method returns at once)."""

    name: str

    def configure(self) -> None:
        """Create the backend's topics, timers or port (the node is being configured)."""

    def release(self) -> None:
        """Destroy what :meth:`configure` created; close the port."""

    def now(self) -> float:
        """Seconds on the driver's clock (the simulator's ticks, or the node's clock)."""

    def word_tick(self) -> Stamp | None:
        """The tick a behaviour word arriving now belongs to (``None``: not known yet)."""

    def tick_time(self) -> float | None:
        """The team's tick time the watchdog counts in (``None``: the driver's clock)."""

    def override(self, value: float) -> None:
        """An operator set-point (m), checked for a value.

        Raises:
            DriverConfigError: A value that is not finite.
        """

    def on_word(self) -> None:
        """The controller's word was given to the core."""

    def on_released(self) -> None:
        """Blade bits held for the drive were given to the core."""

    def on_override(self) -> None:
        """An operator set-point was accepted (:meth:`override`)."""

    def on_gate(self) -> None:
        """The team's gate opened or closed (or the lifecycle changed): act at once."""

    def diagnostic_values(self) -> dict:
        """The backend's own key values on ``/diagnostics``."""

    def hardware_id(self) -> str:
        """The ``hardware_id`` of the driver's diagnostics."""


class SimBlade:
    """The simulator's blade (``backend: sim``): one set-point per simulator tick."""

    name = "sim"

    def __init__(self, node: LifecycleNode) -> None:
        self.node = node
        self.tick_stamp: TimeMsg | None = None
        self.ticks = TickSetpoints()
        self._io: list = []
        self.servo_pub = None

    def configure(self) -> None:
        """The set-point publisher and the simulator's blade subscription."""
        node = self.node
        self.servo_pub = node.create_publisher(BladeCommand, "blade/servo_command", 10)
        self._io = [
            node.create_subscription(JointState, "blade/servo_state", self.on_servo_state, 10)
        ]

    def release(self) -> None:
        """Destroy the two topics."""
        for sub in self._io:
            self.node.destroy_subscription(sub)
        self._io = []
        if self.servo_pub is not None:
            self.node.destroy_publisher(self.servo_pub)
            self.servo_pub = None

    def now(self) -> float:
        """The current tick's time (0 before the first tick)."""
        return seconds(self.tick_stamp) if self.tick_stamp is not None else 0.0

    def word_tick(self) -> Stamp | None:
        """The current tick (a word arriving now is for it)."""
        stamp = self.tick_stamp
        return None if stamp is None else (stamp.sec, stamp.nanosec)

    def tick_time(self) -> float | None:
        """None: the simulator's time is already tick time."""
        return None

    def override(self, value: float) -> None:
        """Keep the set-point for the next one computed (every tick of a stream gets it)."""
        if not math.isfinite(value):
            raise DriverConfigError("blade/commands", "data[0]", value, "must be finite")
        self.ticks.pending_override = value  # taken by the next set-point computed

    def on_word(self) -> None:
        """Mark the word's tick and send the tick's set-point once it is due."""
        if self.tick_stamp is not None:
            self.ticks.word_tick = self.word_tick()
            self.send()

    def on_released(self) -> None:
        """Send the tick's set-point (its blade bits were waiting)."""
        self.send()

    def on_override(self) -> None:
        """Send the tick's set-point (the override is in charge)."""
        self.send()

    def on_gate(self) -> None:
        """Send home marked held, or the tick's own set-point when the gate opens."""
        self.send()

    def on_servo_state(self, msg: JointState) -> None:
        """The simulator's blade for a new tick: relay it, then send the tick's set-point."""
        node = self.node
        topic = "blade/servo_state"
        try:
            node.position, node.force = read_joint(msg, topic)
        except DriverConfigError as exc:
            node.errors[topic] = str(exc)
            node.publish_diagnostics()
            return
        node.errors.pop(topic, None)
        if self.tick_stamp is not None and seconds(msg.header.stamp) < seconds(self.tick_stamp):
            self.restart(msg.header.stamp)
        self.tick_stamp = msg.header.stamp
        node.last_joint = joint_state(node.position, node.force, msg.header.stamp)
        node.publish_joint(node.last_joint)
        self.send()

    def restart(self, stamp: TimeMsg) -> None:
        """The simulator's time went back (it restarted): a new trial.

        The set-point, the controller's word and any operator set-point of the old trial are
        dropped (so are blade bits held for the drive) and the core starts afresh (blade
        home, as at start).
        """
        node = self.node
        node.get_logger().warning(
            f"sim time went back ({seconds(self.tick_stamp):.3f} s -> {seconds(stamp):.3f} s):"
            " a new trial; set-point dropped, blade home"
        )
        node.core.restart()
        self.ticks = TickSetpoints()
        if node.after is not None:
            node.after = AfterDrive()  # held blade bits belong to the old trial's ticks

    def send(self) -> None:
        """The current tick's set-point, if it is due and not yet sent."""
        node = self.node
        if self.tick_stamp is None or self.servo_pub is None:
            return
        due = self.ticks.next(
            node.core,
            self.word_tick(),
            self.now(),
            node.force,
            held=node.hold is not None,
            waiting_for_drive=node.after is not None and node.after.holding(),
        )
        if due is None:
            return
        value, held = due
        command = BladeCommand(stamp=self.tick_stamp, position=float(value), held=bool(held))
        self.servo_pub.publish(command)
        node.report_changes()

    def diagnostic_values(self) -> dict:
        """None of its own."""
        return {}

    def hardware_id(self) -> str:
        """``sim`` and the robot's namespace."""
        return f"sim{self.node.get_namespace()}"


class SerialBlade:
    """A servo board on a serial port (``backend: serial``), stepped by a wall-clock timer."""

    name = "serial"

    def __init__(self, node: LifecycleNode) -> None:
        self.node = node
        self.board = None
        self.backoff = node.params.backoff()
        self.reopened = 0
        self.board_timeout = "off"  # the board's set-point timeout: off, pending, armed, refused
        self.team_tick: Stamp | None = None
        self._io: list = []

    def configure(self) -> None:
        """The team tick's subscription, the port (opened now or retried) and the timer."""
        node = self.node
        self._io = [node.create_subscription(Tick, TEAM_TICK_TOPIC, self.on_team_tick, 10)]
        self.backoff = node.params.backoff()
        self.open_board()
        self._io.append(node.create_timer(1.0 / node.params.rate, self.step))

    def release(self) -> None:
        """Destroy the subscription and the timer; close the port."""
        for entity in self._io:
            if hasattr(entity, "cancel"):
                self.node.destroy_timer(entity)
            else:
                self.node.destroy_subscription(entity)
        self._io = []
        self.close()

    def close(self) -> None:
        """Close the port (if open)."""
        if self.board is not None:
            self.board.close()
            self.board = None

    def now(self) -> float:
        """The node's clock."""
        return self.node.wall()

    def word_tick(self) -> Stamp | None:
        """The team tick's current tick (``None`` before ``/team/tick``)."""
        return self.team_tick

    def tick_time(self) -> float | None:
        """The team's current tick time (s); ``None`` before the first ``/team/tick``.

        A dome tick lasts many wall seconds and a controller answers once per tick, so on
        the wall clock the watchdog would home the blade in every tick.
        """
        if self.team_tick is None:
            return None
        return self.team_tick[0] + self.team_tick[1] * 1e-9

    def override(self, value: float) -> None:
        """Give the set-point to the core now (the next control step sends it)."""
        self.node.core.override(value, self.now())

    def on_word(self) -> None:
        """The next control step sends it."""

    def on_released(self) -> None:
        """The next control step sends it."""

    def on_override(self) -> None:
        """The next control step sends it."""

    def on_gate(self) -> None:
        """A control step at once (a closed gate sends home without waiting)."""
        self.step()

    def on_team_tick(self, msg: Tick) -> None:
        """The team tick began the tick stamped ``msg.stamp`` (its words come next)."""
        self.team_tick = (msg.stamp.sec, msg.stamp.nanosec)

    def open_board(self) -> bool:
        """Try to open the port; on failure schedule the next try."""
        from blade_driver.serial_backend import SerialBackend

        node, p = self.node, self.node.params
        try:
            self.board = SerialBackend(p.port, p.baudrate, p.serial_timeout, p.calibration())
        except PortError as exc:
            delay = self.backoff.failed(node.wall())
            node.fault(f"{exc}; retry in {delay:.1f} s")
            return False
        reopened = self.backoff.failures > 0
        self.backoff.succeeded()
        self.board_timeout = "pending" if p.board_timeout > 0 else "off"
        node.errors.pop("board", None)
        if reopened:
            self.reopened += 1
            node.get_logger().info(f"{p.port}: port open again")
            node.publish_diagnostics()
        return True

    def arm_board_timeout(self) -> None:
        """Arm the board's own set-point timeout (``TIMEOUT``), once per connection.

        A board that refuses it (firmware without one: ``ERR``) is reported and used as it
        is; no answer leaves it pending for the next control step.
        """
        p = self.node.params
        try:
            self.board.set_timeout(p.board_timeout)
        except BoardError as exc:
            if "board refused" not in str(exc):
                raise
            self.board_timeout = "refused"
            self.node.get_logger().warning(
                f"{p.port}: the board has no set-point timeout ({exc}): only this driver "
                "homes the blade when its host fails"
            )
            return
        self.board_timeout = "armed"
        self.node.get_logger().info(f"{p.port}: board set-point timeout {p.board_timeout:g} s")

    def step(self) -> None:
        """One control step: read the board, publish, run the force loop, send the set-point."""
        node = self.node
        if self.board is None:
            if not self.backoff.due(node.wall()) or not self.open_board():
                return
        now = node.wall()
        try:
            if self.board_timeout == "pending":
                self.arm_board_timeout()
            node.position, node.force = self.board.read()
            node.publish_joint(
                joint_state(node.position, node.force, node.get_clock().now().to_msg())
            )
            setpoint = node.core.update(now, node.force, node.gate.reason(now), self.tick_time())
            self.board.set_position(setpoint)
        except PortError as exc:
            self.close()
            delay = self.backoff.failed(node.wall())
            node.fault(f"{exc}; port closed, reopening in {delay:.1f} s")
            return
        except BoardError as exc:
            node.fault(str(exc))
            return
        if node.errors.pop("board", None) is not None:
            node.get_logger().info(f"{node.params.port}: servo board answers again")
        node.report_changes()

    def diagnostic_values(self) -> dict:
        """The port, its reopenings and the board's own timeout."""
        p = self.node.params
        return {
            "port": p.port,
            "port_open": self.board is not None,
            "reopen_failures": self.backoff.failures,
            "reopened": self.reopened,
            "board_timeout": self.board_timeout,
        }

    def hardware_id(self) -> str:
        """The port."""
        return self.node.params.port


BACKENDS: dict[str, type] = {"sim": SimBlade, "serial": SerialBlade}
"""The hardware interface of each ``backend`` parameter value."""
