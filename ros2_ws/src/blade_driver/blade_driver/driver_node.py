r"""``ros2 run blade_driver driver``: one robot's blade, between its controller and its servo.

::

    ros2 run blade_driver driver --ros-args -r __ns:=/robot_0 \\
        -p backend:=serial -p port:=/dev/ttyUSB0
    ros2 run blade_driver driver --ros-args -r __ns:=/robot_0 --params-file config/driver.yaml

A managed (lifecycle) node: with ``autostart`` (the default) it configures and activates
itself at start; with ``autostart:=false`` a lifecycle manager drives it through
``~/change_state``. It moves the blade only while it is *active* and the team's
:class:`~excavation_common.safety.MotionGate` is open: no e-stop latched on ``/team/estop``,
a heartbeat on ``/team/heartbeat`` younger than ``deadman`` that says ``armed``, and this
robot enabled on ``enabled``. Otherwise the blade goes home at once (the gate is checked on
every team-state message and ``safety_rate`` times a second) and stays home until the gate
opens again; the operator's override does not beat a closed gate.

Subscribes ``behaviour`` (std_msgs/UInt16, the controller's word) and ``blade/commands``
(std_msgs/Float64MultiArray, one value per joint in ``joints``: the ros2_control
forward-command convention, for an operator override); publishes ``blade/joint_states``
(position = measured blade position, effort = measured push force), the blade's frame
``robot_k/base_link`` -> ``robot_k/blade`` on ``/tf`` with each, and ``/diagnostics``.
The logic is :class:`blade_driver.core.BladeDriverCore`; this node moves messages.

Backends (parameter ``backend``), each a hardware interface of
:mod:`blade_driver.hardware` behind which the node never branches:

* ``serial``: a servo board on ``port`` (:mod:`blade_driver.protocol`), stepped by a
  wall-clock timer at ``rate`` Hz; a port that is absent or fails (unplugged) is closed and
  reopened with back-off (``reopen_initial`` doubling up to ``reopen_max``), reported on
  ``/diagnostics``. Once ``/team/tick`` (excavation_interfaces/Tick, the team tick's
  tick ``t`` stamped ``t`` s) has come, the watchdog counts tick time: a controller answers once per
  tick, and a dome tick lasts many wall seconds.
* ``sim``: the simulator's blade through ``blade/servo_state`` and
  ``blade/servo_command`` (excavation_interfaces/BladeCommand, stamped with the tick), on
  the simulator's time, so a lockstep trial is deterministic however slow the machine is;
  one set-point per tick (:class:`blade_driver.core.TickSetpoints`); while the gate is
  closed it sends home with ``held`` set and leaves its core untouched.

On either backend the core restarts when the time it is given goes back
(:meth:`~blade_driver.core.BladeDriverCore.restart`; ``clock_restarts`` on ``/diagnostics``).

In the field (``blade_after_motion: true``: continuous trials, the dome) a tick's blade bits
wait until the tick's drive has ended, as the world model runs a word's moves before its
blade behaviours (:class:`blade_driver.core.AfterDrive` says why): the driver subscribes
``drive/status`` (excavation_interfaces/DriveStatus from the drive executor, ``goal.stamp`` = the
tick) and applies a word's blade bits once a terminal status (succeeded, aborted, canceled)
of its tick or a later one has come. The word's tick is the stamp of ``blade/servo_state``
(sim backend) or of ``/team/tick`` (excavation_interfaces/Tick from the team tick; serial backend);
before either is known a word applies at once. The watchdog, the operator's override and
a closed gate do not wait. Lockstep trials, with no executor, leave it off.
"""

from __future__ import annotations

import sys

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from excavation_interfaces.msg import DriveStatus, TeamArmed, TeamState
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64MultiArray, UInt16

from blade_driver.core import BLADE_NAMES, AfterDrive, BladeDriverCore
from blade_driver.errors import DriverConfigError
from blade_driver.hardware import BACKENDS, BladeHardware
from blade_driver.params import JOINT, DriverNodeParams
from excavation_common.constants import BladeGeometry
from excavation_common.ros import LATCHED, declare_params, diagnostics, spin_node
from excavation_common.safety import (
    ARMED_TOPIC,
    ENABLED_TOPIC,
    ESTOP_TOPIC,
    HEARTBEAT_TOPIC,
    MotionGate,
)
from excavation_common.tf import TfBroadcaster, blade_transform, robot_name

SUCCESS = TransitionCallbackReturn.SUCCESS
DRIVE_ENDED = (
    DriveStatus.STATUS_SUCCEEDED,
    DriveStatus.STATUS_ABORTED,
    DriveStatus.STATUS_CANCELED,
)


class BladeDriverNode(LifecycleNode):
    """The blade driver of one robot (run it in the robot's namespace)."""

    def __init__(self, **kwargs) -> None:
        super().__init__("blade_driver", **kwargs)
        self.params = declare_params(self, DriverNodeParams, on_change=self.on_params)
        p = self.params
        self.core = BladeDriverCore(p.driver())
        self.gate = MotionGate(deadman=p.deadman, rearm_after_loss=p.rearm_after_loss)
        self.hold: str | None = self.gate.reason(self.wall())
        self.opened = False  # the gate has opened once: a hold after it is a loss (WARN)
        self.lifecycle = "unconfigured"
        self.errors: dict[str, str] = {}
        self.force: float | None = None
        self.position: float | None = None
        self.last_joint: JointState | None = None
        self.joint_pub = None
        self.after = AfterDrive() if p.blade_after_motion else None
        self.hw: BladeHardware = BACKENDS[p.backend](self)
        self.commands = 0
        self._reported_source = ""
        self._io: list = []

        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.tf = TfBroadcaster(self)
        self.create_subscription(Bool, ESTOP_TOPIC, self.on_estop, LATCHED)
        self.create_subscription(TeamState, HEARTBEAT_TOPIC, self.on_heartbeat, 10)
        self.create_subscription(TeamArmed, ARMED_TOPIC, self.on_armed, LATCHED)
        self.create_subscription(Bool, ENABLED_TOPIC, self.on_enabled, LATCHED)
        self.create_timer(1.0 / p.safety_rate, self.apply_gate)
        self.create_timer(p.diagnostics_period, self.publish_diagnostics)
        if p.autostart:
            self.trigger_configure()
            self.trigger_activate()

    # --- lifecycle --------------------------------------------------------------------------

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Create the blade's topics and the backend's."""
        self._io = [
            self.create_subscription(UInt16, "behaviour", self.on_behaviour, 10),
            self.create_subscription(Float64MultiArray, "blade/commands", self.on_override, 10),
        ]
        if self.after is not None:
            self._io.append(
                self.create_subscription(DriveStatus, "drive/status", self.on_drive_status, 10)
            )
        self.last_joint = None
        self.joint_pub = self.create_publisher(
            JointState,
            "blade/joint_states",
            10,
            event_callbacks=PublisherEventCallbacks(matched=self.on_joint_reader),
        )
        self.hw.configure()
        self.lifecycle = "inactive"
        self.apply_gate()
        return SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Allow motion (the team's gate still decides)."""
        self.gate.active = True
        self.lifecycle = "active"
        self.apply_gate()
        return SUCCESS

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Blade home at once; nothing moves until activated again."""
        self.gate.active = False
        self.lifecycle = "inactive"
        self.apply_gate()
        return SUCCESS

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Release the topics and the port."""
        self.release()
        self.lifecycle = "unconfigured"
        return SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Blade home, then release everything."""
        self.gate.active = False
        self.apply_gate()
        self.release()
        self.lifecycle = "finalized"
        return SUCCESS

    def release(self) -> None:
        """Destroy what :meth:`on_configure` created; the backend closes its port."""
        for sub in self._io:
            self.destroy_subscription(sub)
        self._io = []
        if self.joint_pub is not None:
            self.destroy_publisher(self.joint_pub)
            self.joint_pub = None
        self.hw.release()

    def on_params(self, params: DriverNodeParams) -> None:
        """A runtime change of the force loop or the timeouts."""
        self.params = params
        self.core.set_params(params.driver())

    # --- time and the team's gate -----------------------------------------------------------

    def wall(self) -> float:
        """Seconds on the node's clock (what the deadman counts)."""
        return self.get_clock().now().nanoseconds * 1e-9

    def on_estop(self, msg: Bool) -> None:
        """``/team/estop`` changed."""
        self.gate.on_estop(msg.data)
        self.apply_gate()

    def on_heartbeat(self, msg: TeamState) -> None:
        """A team heartbeat (the team state)."""
        self.gate.on_heartbeat(msg.state, self.wall())
        self.apply_gate()

    def on_armed(self, msg: TeamArmed) -> None:
        """``/team/armed``: an arming (a re-arm ends a latched link loss)."""
        self.gate.on_armed(msg.stamp.sec, msg.stamp.nanosec, msg.armings)
        self.apply_gate()

    def on_enabled(self, msg: Bool) -> None:
        """This robot was enabled or disabled."""
        self.gate.on_enabled(msg.data)
        self.apply_gate()

    def apply_gate(self) -> None:
        """Act at once when the gate closes (blade home) or opens (follow the controller)."""
        reason = self.gate.reason(self.wall())
        if MotionGate.kind(reason) == MotionGate.kind(self.hold):
            return  # the same state (a lost heartbeat's age grows: not a change)
        self.hold = reason
        if reason is not None and self.opened:
            self.get_logger().warning(f"blade home: {reason}")
        elif reason is not None:  # still coming up: waiting is not a fault
            self.get_logger().info(f"blade home until the team is armed: {reason}")
        else:
            self.opened = True
            self.get_logger().info("team armed: blade follows the controller")
        if self.lifecycle in ("inactive", "active"):
            self.hw.on_gate()
        self.publish_diagnostics()

    # --- inputs -----------------------------------------------------------------------------

    def on_behaviour(self, msg: UInt16) -> None:
        """The controller's word: the blade setting it asks for (after the drive, if so set)."""
        self.commands += 1
        word, tick = int(msg.data), self.hw.word_tick()
        now, tick_time = self.hw.now(), self.hw.tick_time()
        if self.after is None or tick is None:
            self.core.command(word, now, tick=tick_time)
        else:
            self.core.command(word, now, blade=False, tick=tick_time)
            for released in self.after.word(tick, word):
                self.core.apply_blade(released)
        self.hw.on_word()

    def on_drive_status(self, msg: DriveStatus) -> None:
        """The executor's status: a terminal one releases the blade bits of its tick."""
        if msg.status not in DRIVE_ENDED:
            return
        stamp = msg.goal.stamp
        released = self.after.drive_ended((stamp.sec, stamp.nanosec))
        for word in released:
            self.core.apply_blade(word)
        if released:
            self.hw.on_released()

    def on_override(self, msg: Float64MultiArray) -> None:
        """An operator set-point (forward-command convention: ``data[i]`` for ``joints[i]``)."""
        topic = "blade/commands"
        joints = list(self.params.joints)
        try:
            if len(msg.data) != len(joints):
                raise DriverConfigError(
                    topic, "data", list(msg.data), f"needs one value per joint {joints}"
                )
            self.hw.override(float(msg.data[joints.index(JOINT)]))
        except (DriverConfigError, ValueError) as exc:
            self.errors[topic] = str(exc)
            self.get_logger().warning(str(exc), throttle_duration_sec=5.0)
            self.publish_diagnostics()
            return
        self.errors.pop(topic, None)
        self.hw.on_override()

    def publish_joint(self, msg: JointState) -> None:
        """The blade's joint state, and its frame in the robot's body on ``/tf``."""
        self.joint_pub.publish(msg)
        robot = robot_name(self.get_namespace())
        reach = BladeGeometry().reach
        self.tf.send([blade_transform(robot, msg.position[0], reach, msg.header.stamp)])

    def on_joint_reader(self, info) -> None:
        """A new reader of the joint states gets the latest one too.

        The sim backend relays each tick's joint state once, and a volatile writer keeps
        nothing for a reader it matches later: a controller matched just after the relay
        would wait for its tick until the next. The copy is stamped with its tick and comes
        before any newer one from this writer, so a reader that has it already changes
        nothing.
        """
        if info.current_count_change > 0 and self.last_joint is not None:
            self.joint_pub.publish(self.last_joint)

    def fault(self, message: str) -> None:
        """Record a board fault (logged once per distinct message)."""
        if self.errors.get("board") != message:
            self.get_logger().error(message)
            self.errors["board"] = message
            self.publish_diagnostics()

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
        """OK: the controller is in charge; WARN: held, watchdog or override; ERROR: faults."""
        s, p = self.core.state, self.params
        source = f"hold: {self.hold}" if self.hold is not None else s.source
        if self.errors:
            level = DiagnosticStatus.ERROR
            message = "; ".join([*self.errors.values(), f"blade: {source}"])
        elif source.startswith("controller"):
            level, message = DiagnosticStatus.OK, source
        else:
            level, message = DiagnosticStatus.WARN, source
        values = {
            "backend": p.backend,
            "lifecycle": self.lifecycle,
            "gate": self.hold or "open",
            "setting": BLADE_NAMES[s.setting],
            "setpoint": f"{s.setpoint:.4f}",
            "trim": f"{s.trim:.4f}",
            "force": "unknown" if self.force is None else f"{self.force:.3f}",
            "commands": self.commands,
            "override_clipped": s.clipped,
            "blade_waits_for_drive": self.after is not None and self.after.holding(),
            "clock_restarts": self.core.restarts,
            **self.hw.diagnostic_values(),
        }
        self.diag_pub.publish(
            diagnostics(self, level, message, values, hardware_id=self.hw.hardware_id())
        )

    def destroy_node(self) -> None:
        """Release the backend (its port closes) with the node."""
        self.hw.release()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run blade_driver driver``."""
    return spin_node(BladeDriverNode, args)


if __name__ == "__main__":
    sys.exit(main())
