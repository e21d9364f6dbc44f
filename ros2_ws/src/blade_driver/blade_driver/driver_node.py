r"""``ros2 run blade_driver driver``: one robot's blade, between its controller and its servo.

::

    ros2 run blade_driver driver --ros-args -r __ns:=/robot_0 \\
        -p backend:=serial -p port:=/dev/ttyUSB0
    ros2 run blade_driver driver --ros-args -r __ns:=/robot_0 --params-file config/driver.yaml

Subscribes ``behaviour`` (std_msgs/UInt16, the controller's word) and ``blade/commands``
(std_msgs/Float64MultiArray, one value per joint in ``joints``: the ros2_control
forward-command convention, for an operator override); publishes ``blade/joint_states``
(position = measured blade position, effort = measured push force) and ``/diagnostics``.
The logic is :class:`blade_driver.core.BladeDriverCore`; this node moves messages.

Backends (parameter ``backend``):

* ``serial``: a servo board on ``port`` (:mod:`blade_driver.protocol`). A wall-clock timer at
  ``rate`` Hz reads the board, publishes the joint state, runs the force loop and sends the
  set-point.
* ``sim``: the simulator's blade, through two topics in the style of
  topic_based_ros2_control: the simulator publishes ``blade/servo_state`` (JointState,
  stamped with its tick) and takes ``blade/servo_command`` (JointState, the set-point,
  stamped with the tick it is for). Time is the simulator's: watchdog and override
  timeouts count simulated seconds, so a lockstep trial is deterministic however slow the
  machine is. Each tick gets one set-point: at once when the watchdog or an override is in
  charge, otherwise when the controller's word for that tick arrives.
"""

from __future__ import annotations

import math
import sys

from builtin_interfaces.msg import Time as TimeMsg
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, UInt16

from blade_driver.core import BLADE_NAMES, BladeDriverCore, DriverParams
from blade_driver.errors import BoardError, DriverConfigError
from blade_driver.protocol import ServoCalibration
from excavation_common.ros import spin_node

JOINT = "blade"


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


def _seconds(stamp: TimeMsg) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


class BladeDriverNode(Node):
    """The blade driver of one robot (run it in the robot's namespace)."""

    def __init__(self, **kwargs) -> None:
        super().__init__("blade_driver", **kwargs)
        p = self.declare_parameter
        defaults = DriverParams()
        values = {name: float(p(name, getattr(defaults, name)).value) for name in _PARAM_NAMES}
        self.params = DriverParams(**values)
        self.backend_name = str(p("backend", "sim").value)
        self.joints = [str(j) for j in p("joints", [JOINT]).value]
        rate = float(p("rate", 20.0).value)
        calibration = ServoCalibration(
            float(p("servo_zero_deg", 90.0).value),
            float(p("servo_deg_per_m", 600.0).value),
            float(p("servo_min_deg", 0.0).value),
            float(p("servo_max_deg", 180.0).value),
        )
        port = str(p("port", "/dev/ttyUSB0").value)
        baudrate = int(p("baudrate", 115200).value)
        serial_timeout = float(p("serial_timeout", 0.1).value)
        period = float(p("diagnostics_period", 1.0).value)
        self.core = BladeDriverCore(self.params)
        self.errors: dict[str, str] = {}
        self.force: float | None = None
        self.position: float | None = None
        self.board = None
        self.port = ""
        self.tick_stamp: TimeMsg | None = None
        self.sent_for: tuple[int, int] | None = None
        self.commands = 0
        self._reported_source = ""

        self.joint_pub = self.create_publisher(JointState, "blade/joint_states", 10)
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.create_subscription(UInt16, "behaviour", self.on_behaviour, 10)
        self.create_subscription(Float64MultiArray, "blade/commands", self.on_override, 10)
        if self.backend_name == "sim":
            self.servo_pub = self.create_publisher(JointState, "blade/servo_command", 10)
            self.create_subscription(JointState, "blade/servo_state", self.on_servo_state, 10)
        elif self.backend_name == "serial":
            from blade_driver.serial_backend import SerialBackend

            self.port = port
            try:
                self.board = SerialBackend(port, baudrate, serial_timeout, calibration)
            except BoardError as exc:
                self.errors["board"] = str(exc)
                self.get_logger().error(str(exc))
            self.create_timer(1.0 / rate, self.on_control_step)
        else:
            raise DriverConfigError(
                "<parameters>", "backend", self.backend_name, "must be 'sim' or 'serial'"
            )
        self.create_timer(period, self.publish_diagnostics)

    # --- time -------------------------------------------------------------------------------

    def _now(self) -> float:
        """Seconds on the driver's clock: the simulator's ticks, or the node's clock."""
        if self.backend_name == "sim":
            return _seconds(self.tick_stamp) if self.tick_stamp is not None else 0.0
        return self.get_clock().now().nanoseconds * 1e-9

    # --- inputs -----------------------------------------------------------------------------

    def on_behaviour(self, msg: UInt16) -> None:
        """The controller's word: the blade setting it asks for."""
        self.commands += 1
        self.core.command(int(msg.data), self._now())
        if self.backend_name == "sim" and self.tick_stamp is not None:
            self.send_sim_setpoint()

    def on_override(self, msg: Float64MultiArray) -> None:
        """An operator set-point (forward-command convention: ``data[i]`` for ``joints[i]``)."""
        topic = "blade/commands"
        try:
            if len(msg.data) != len(self.joints):
                raise DriverConfigError(
                    topic, "data", list(msg.data), f"needs one value per joint {self.joints}"
                )
            self.core.override(float(msg.data[self.joints.index(JOINT)]), self._now())
        except (DriverConfigError, ValueError) as exc:
            self.errors[topic] = str(exc)
            self.get_logger().warning(str(exc), throttle_duration_sec=5.0)
            self.publish_diagnostics()
            return
        self.errors.pop(topic, None)

    def on_servo_state(self, msg: JointState) -> None:
        """Sim backend: the simulator's blade for a new tick."""
        topic = "blade/servo_state"
        try:
            self.position, self.force = read_joint(msg, topic)
        except DriverConfigError as exc:
            self.errors[topic] = str(exc)
            self.publish_diagnostics()
            return
        self.errors.pop(topic, None)
        self.tick_stamp = msg.header.stamp
        self.joint_pub.publish(joint_state(self.position, self.force, msg.header.stamp))
        if self.core.needs_no_controller(self._now()):
            self.send_sim_setpoint()

    def send_sim_setpoint(self) -> None:
        """Sim backend: the set-point for the current tick (at most one per tick)."""
        stamp = (self.tick_stamp.sec, self.tick_stamp.nanosec)
        if self.sent_for == stamp:
            return
        self.sent_for = stamp
        setpoint = self.core.update(self._now(), self.force)
        self.servo_pub.publish(joint_state(setpoint, 0.0, self.tick_stamp))
        self.report_changes()

    def on_control_step(self) -> None:
        """Serial backend: read the board, publish, run the force loop, send the set-point."""
        if self.board is None:
            return
        try:
            self.position, self.force = self.board.read()
            self.joint_pub.publish(
                joint_state(self.position, self.force, self.get_clock().now().to_msg())
            )
            self.board.set_position(self.core.update(self._now(), self.force))
        except BoardError as exc:
            if self.errors.get("board") != str(exc):
                self.get_logger().error(str(exc))
            self.errors["board"] = str(exc)
            return
        if self.errors.pop("board", None) is not None:
            self.get_logger().info(f"{self.port}: servo board answers again")
        self.report_changes()

    def report_changes(self) -> None:
        """Log and publish diagnostics at once when who is in charge of the blade changes."""
        source = self.core.state.source.split(" (")[0]
        if source == self._reported_source:
            return
        self._reported_source = source
        if source.startswith("watchdog"):
            self.get_logger().warning("no behaviour command: blade home")
        self.publish_diagnostics()

    # --- diagnostics ------------------------------------------------------------------------

    def publish_diagnostics(self) -> None:
        """OK while the controller is in charge; WARN for watchdog/override; ERROR on faults."""
        s = self.core.state
        status = DiagnosticStatus(
            name=f"{self.get_namespace().rstrip('/')}/blade_driver",
            hardware_id=self.port if self.board is not None else f"sim{self.get_namespace()}",
        )
        if self.errors:
            status.level = DiagnosticStatus.ERROR
            status.message = "; ".join([*self.errors.values(), f"blade: {s.source}"])
        elif s.source.startswith("controller"):
            status.level, status.message = DiagnosticStatus.OK, s.source
        else:
            status.level, status.message = DiagnosticStatus.WARN, s.source
        status.values = [
            KeyValue(key="backend", value=self.backend_name),
            KeyValue(key="setting", value=BLADE_NAMES[s.setting]),
            KeyValue(key="setpoint", value=f"{s.setpoint:.4f}"),
            KeyValue(key="trim", value=f"{s.trim:.4f}"),
            KeyValue(key="force", value="unknown" if self.force is None else f"{self.force:.3f}"),
            KeyValue(key="commands", value=str(self.commands)),
            KeyValue(key="override_clipped", value=str(s.clipped)),
        ]
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = self.get_clock().now().to_msg()
        self.diag_pub.publish(msg)

    def destroy_node(self) -> None:
        """Close the serial port with the node."""
        if self.board is not None:
            self.board.close()
        super().destroy_node()


_PARAM_NAMES = tuple(DriverParams.__dataclass_fields__)


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run blade_driver driver``."""
    try:
        return spin_node(BladeDriverNode, args)
    except DriverConfigError as exc:
        print(f"driver: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
