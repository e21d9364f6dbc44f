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

Backends (parameter ``backend``):

* ``serial``: a servo board on ``port`` (:mod:`blade_driver.protocol`). A wall-clock timer at
  ``rate`` Hz reads the board, publishes the joint state, runs the force loop and sends the
  set-point. A port that is absent or fails (unplugged) is closed and reopened with
  back-off (``reopen_initial`` doubling up to ``reopen_max``), reported on ``/diagnostics``.
  Once ``/team/tick`` (std_msgs/Header, the team tick's tick ``t`` stamped ``t`` s) has
  come, the watchdog counts tick time, as the sim backend does: a controller answers once
  per tick, and a dome tick lasts many wall seconds.
* ``sim``: the simulator's blade, through two topics in the style of
  topic_based_ros2_control: the simulator publishes ``blade/servo_state`` (JointState,
  stamped with its tick) and takes ``blade/servo_command`` (JointState, the set-point,
  stamped with the tick it is for). Time is the simulator's: watchdog and override
  timeouts count simulated seconds, so a lockstep trial is deterministic however slow the
  machine is. Each tick gets one set-point: at once when the watchdog or an override is in
  charge, otherwise when the controller's word for that tick arrives. An operator set-point
  counts from the first tick whose set-point is computed after it arrives (for
  ``override_timeout`` of sim time), so every tick of a streamed override gets it. While the
  gate is closed the driver sends home with ``frame_id`` :data:`~excavation_common.safety.HELD`
  instead and leaves its core untouched; when the gate opens it sends the tick's own
  set-point, so a paused lockstep trial ends as an unpaused one does. A tick stamped before
  the last one (the simulator restarted: its time went back) is a new trial: the driver
  drops the old set-point, word and override and its core starts afresh (blade home).

On either backend the core restarts when the time it is given goes back
(:meth:`~blade_driver.core.BladeDriverCore.restart`; ``clock_restarts`` on ``/diagnostics``).

In the field (``blade_after_motion: true``: continuous trials, the dome) a tick's blade bits
wait until the tick's drive has ended, as the world model runs a word's moves before its
blade behaviours (:class:`blade_driver.core.AfterDrive` says why): the driver subscribes
``drive/status`` (action_msgs/GoalStatus from the drive executor, ``goal_info.stamp`` = the
tick) and applies a word's blade bits once a terminal status (succeeded, aborted, canceled)
of its tick or a later one has come. The word's tick is the stamp of ``blade/servo_state``
(sim backend) or of ``/team/tick`` (std_msgs/Header from the team tick; serial backend);
before either is known a word applies at once. The watchdog, the operator's override and
a closed gate do not wait. Lockstep trials, with no executor, leave it off.
"""

from __future__ import annotations

import math
import sys

from action_msgs.msg import GoalStatus
from builtin_interfaces.msg import Time as TimeMsg
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64MultiArray, Header, UInt16

from blade_driver.core import BLADE_NAMES, AfterDrive, BladeDriverCore
from blade_driver.errors import BoardError, DriverConfigError, PortError
from blade_driver.params import JOINT, DriverNodeParams
from excavation_common.constants import BladeGeometry
from excavation_common.ros import LATCHED, declare_params, diagnostics, spin_node
from excavation_common.safety import (
    ARMED_TOPIC,
    ENABLED_TOPIC,
    ESTOP_TOPIC,
    HEARTBEAT_TOPIC,
    HELD,
    MotionGate,
)
from excavation_common.tf import TfBroadcaster, blade_transform, robot_name

SUCCESS = TransitionCallbackReturn.SUCCESS
DRIVE_ENDED = (GoalStatus.STATUS_SUCCEEDED, GoalStatus.STATUS_ABORTED, GoalStatus.STATUS_CANCELED)
TEAM_TICK_TOPIC = "/team/tick"


def joint_state(
    position: float, force: float, stamp: TimeMsg | None = None, frame_id: str = ""
) -> JointState:
    """A ``blade`` joint state (position m, effort N)."""
    msg = JointState()
    if stamp is not None:
        msg.header.stamp = stamp
    msg.header.frame_id = frame_id
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


class BladeDriverNode(LifecycleNode):
    """The blade driver of one robot (run it in the robot's namespace)."""

    def __init__(self, **kwargs) -> None:
        super().__init__("blade_driver", **kwargs)
        self.params = declare_params(self, DriverNodeParams, on_change=self.on_params)
        p = self.params
        self.core = BladeDriverCore(p.driver())
        self.gate = MotionGate(deadman=p.deadman, rearm_after_loss=p.rearm_after_loss)
        self.hold: str | None = self.gate.reason(self._wall())
        self.opened = False  # the gate has opened once: a hold after it is a loss (WARN)
        self.lifecycle = "unconfigured"
        self.errors: dict[str, str] = {}
        self.force: float | None = None
        self.position: float | None = None
        self.board = None
        self.backoff = p.backoff()
        self.reopened = 0
        self.board_timeout = (
            "off"  # the board's own set-point timeout: off, pending, armed, refused
        )
        self.tick_stamp: TimeMsg | None = None
        self.word_tick: tuple[int, int] | None = None
        self.open_setpoint: tuple[tuple[int, int], float] | None = None
        self.pending_override: float | None = None
        self.last_sent: tuple[tuple[int, int], str] | None = None
        self.after = AfterDrive() if p.blade_after_motion else None
        self.team_tick: tuple[int, int] | None = None
        self.commands = 0
        self._reported_source = ""
        self._io: list = []

        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.tf = TfBroadcaster(self)
        self.create_subscription(Bool, ESTOP_TOPIC, self.on_estop, LATCHED)
        self.create_subscription(Header, HEARTBEAT_TOPIC, self.on_heartbeat, 10)
        self.create_subscription(Header, ARMED_TOPIC, self.on_armed, LATCHED)
        self.create_subscription(Bool, ENABLED_TOPIC, self.on_enabled, LATCHED)
        self.create_timer(1.0 / p.safety_rate, self.apply_gate)
        self.create_timer(p.diagnostics_period, self.publish_diagnostics)
        if p.autostart:
            self.trigger_configure()
            self.trigger_activate()

    # --- lifecycle --------------------------------------------------------------------------

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Create the blade's topics (and the serial control loop)."""
        p = self.params
        self._io = [
            self.create_subscription(UInt16, "behaviour", self.on_behaviour, 10),
            self.create_subscription(Float64MultiArray, "blade/commands", self.on_override, 10),
        ]
        sub = self.create_subscription
        if self.after is not None:
            self._io.append(sub(GoalStatus, "drive/status", self.on_drive_status, 10))
        if p.backend != "sim":
            self._io.append(sub(Header, TEAM_TICK_TOPIC, self.on_team_tick, 10))
        self.last_joint: JointState | None = None
        self.joint_pub = self.create_publisher(
            JointState,
            "blade/joint_states",
            10,
            event_callbacks=PublisherEventCallbacks(matched=self.on_joint_reader),
        )
        if p.backend == "sim":
            self.servo_pub = self.create_publisher(JointState, "blade/servo_command", 10)
            self._io.append(
                self.create_subscription(JointState, "blade/servo_state", self.on_servo_state, 10)
            )
        else:
            self.backoff = p.backoff()
            self.open_board()
            self._io.append(self.create_timer(1.0 / p.rate, self.on_control_step))
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
        """Destroy what :meth:`on_configure` created; close the port."""
        for entity in self._io:
            if hasattr(entity, "cancel"):
                self.destroy_timer(entity)
            else:
                self.destroy_subscription(entity)
        self._io = []
        for name in ("joint_pub", "servo_pub"):
            if hasattr(self, name):
                self.destroy_publisher(getattr(self, name))
                delattr(self, name)
        if self.board is not None:
            self.board.close()
            self.board = None

    def on_params(self, params: DriverNodeParams) -> None:
        """A runtime change of the force loop or the timeouts."""
        self.params = params
        self.core.params = params.driver()
        pid = self.core._pid
        pid.kp, pid.ki, pid.kd, pid.limit = params.kp, params.ki, params.kd, params.trim_limit

    # --- time and the team's gate -----------------------------------------------------------

    def _wall(self) -> float:
        """Seconds on the node's clock (what the deadman counts)."""
        return self.get_clock().now().nanoseconds * 1e-9

    def _now(self) -> float:
        """Seconds on the driver's clock: the simulator's ticks, or the node's clock."""
        if self.params.backend == "sim":
            return _seconds(self.tick_stamp) if self.tick_stamp is not None else 0.0
        return self._wall()

    def on_estop(self, msg: Bool) -> None:
        """``/team/estop`` changed."""
        self.gate.on_estop(msg.data)
        self.apply_gate()

    def on_heartbeat(self, msg: Header) -> None:
        """A team heartbeat (``frame_id`` = team state)."""
        self.gate.on_heartbeat(msg.frame_id, self._wall())
        self.apply_gate()

    def on_armed(self, msg: Header) -> None:
        """``/team/armed``: an arming (a re-arm ends a latched link loss)."""
        self.gate.on_armed(msg.stamp.sec, msg.stamp.nanosec, msg.frame_id)
        self.apply_gate()

    def on_enabled(self, msg: Bool) -> None:
        """This robot was enabled or disabled."""
        self.gate.on_enabled(msg.data)
        self.apply_gate()

    def apply_gate(self) -> None:
        """Act at once when the gate closes (blade home) or opens (follow the controller)."""
        reason = self.gate.reason(self._wall())
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
            if self.params.backend == "sim":
                self.send_sim_setpoint()
            else:
                self.on_control_step()
        self.publish_diagnostics()

    # --- inputs -----------------------------------------------------------------------------

    def on_behaviour(self, msg: UInt16) -> None:
        """The controller's word: the blade setting it asks for (after the drive, if so set)."""
        self.commands += 1
        word, tick = int(msg.data), self._word_tick()
        if self.after is None or tick is None:
            self.core.command(word, self._now(), tick=self._tick_time())
        else:
            self.core.command(word, self._now(), blade=False, tick=self._tick_time())
            for released in self.after.word(tick, word):
                self.core.apply_blade(released)
        if self.params.backend == "sim" and self.tick_stamp is not None:
            self.word_tick = (self.tick_stamp.sec, self.tick_stamp.nanosec)
            self.send_sim_setpoint()

    def _word_tick(self) -> tuple[int, int] | None:
        """The tick a word that arrives now belongs to (``None``: not known yet)."""
        stamp = self.tick_stamp if self.params.backend == "sim" else None
        if stamp is not None:
            return (stamp.sec, stamp.nanosec)
        return self.team_tick

    def on_team_tick(self, msg: Header) -> None:
        """Serial backend: the team tick began tick ``msg.stamp`` (its words come next)."""
        self.team_tick = (msg.stamp.sec, msg.stamp.nanosec)

    def _tick_time(self) -> float | None:
        """Serial backend: the team's current tick time (s), which the watchdog counts in.

        ``None`` before the first ``/team/tick`` (no team tick runs: wall seconds). A dome
        tick lasts many wall seconds and a controller answers once per tick, so on the wall
        clock the watchdog would home the blade in every tick (seen in the first rehearsal:
        no blade setting of a word outlived its drive).
        """
        if self.params.backend == "sim" or self.team_tick is None:
            return None
        return self.team_tick[0] + self.team_tick[1] * 1e-9

    def on_drive_status(self, msg: GoalStatus) -> None:
        """The executor's status: a terminal one releases the blade bits of its tick."""
        if msg.status not in DRIVE_ENDED:
            return
        stamp = msg.goal_info.stamp
        released = self.after.drive_ended((stamp.sec, stamp.nanosec))
        for word in released:
            self.core.apply_blade(word)
        if released and self.params.backend == "sim":
            self.send_sim_setpoint()

    def on_override(self, msg: Float64MultiArray) -> None:
        """An operator set-point (forward-command convention: ``data[i]`` for ``joints[i]``)."""
        topic = "blade/commands"
        joints = list(self.params.joints)
        try:
            if len(msg.data) != len(joints):
                raise DriverConfigError(
                    topic, "data", list(msg.data), f"needs one value per joint {joints}"
                )
            value = float(msg.data[joints.index(JOINT)])
            if self.params.backend == "sim":
                if not math.isfinite(value):
                    raise DriverConfigError(topic, "data[0]", value, "must be finite")
                self.pending_override = value  # taken by the next set-point computed
            else:
                self.core.override(value, self._now())
        except (DriverConfigError, ValueError) as exc:
            self.errors[topic] = str(exc)
            self.get_logger().warning(str(exc), throttle_duration_sec=5.0)
            self.publish_diagnostics()
            return
        self.errors.pop(topic, None)
        if self.params.backend == "sim" and self.tick_stamp is not None:
            self.send_sim_setpoint()

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
        if self.tick_stamp is not None and _seconds(msg.header.stamp) < _seconds(self.tick_stamp):
            self.restart(msg.header.stamp)
        self.tick_stamp = msg.header.stamp
        self.last_joint = joint_state(self.position, self.force, msg.header.stamp)
        self.publish_joint(self.last_joint)
        self.send_sim_setpoint()

    def publish_joint(self, msg: JointState) -> None:
        """The blade's joint state, and its frame in the robot's body on ``/tf``."""
        self.joint_pub.publish(msg)
        robot = robot_name(self.get_namespace())
        reach = BladeGeometry().reach
        self.tf.send([blade_transform(robot, msg.position[0], reach, msg.header.stamp)])

    def on_joint_reader(self, info) -> None:
        """Sim backend: a new reader of the joint states gets the current tick's too.

        The sim backend relays each tick's joint state once, and a volatile writer keeps
        nothing for a reader it matches later: a controller matched just after the relay
        would wait for its tick until the next (seen: a robot idled tick 0). The copy is
        stamped with its tick and comes before any newer one from this writer, so a reader
        that has it already changes nothing.
        """
        if info.current_count_change > 0 and self.last_joint is not None:
            self.joint_pub.publish(self.last_joint)

    def restart(self, stamp: TimeMsg) -> None:
        """Sim backend: the simulator's time went back (it restarted): a new trial.

        The set-point, the controller's word and any operator set-point of the old trial are
        dropped (so are blade bits held for the drive) and the core starts afresh (blade
        home, as at start).
        """
        self.get_logger().warning(
            f"sim time went back ({_seconds(self.tick_stamp):.3f} s -> {_seconds(stamp):.3f} s):"
            " a new trial; set-point dropped, blade home"
        )
        self.core.restart()
        self.word_tick = self.open_setpoint = self.pending_override = self.last_sent = None
        if self.after is not None:
            self.after = AfterDrive()  # held blade bits belong to the old trial's ticks

    def send_sim_setpoint(self) -> None:
        """Sim backend: the current tick's set-point, if it is due and not yet sent.

        A closed gate sends home marked :data:`HELD` without touching the core; an open one
        sends the tick's own set-point (computed once per tick, when the controller's word
        is in or the watchdog or an override is in charge).
        """
        if self.tick_stamp is None or not hasattr(self, "servo_pub"):
            return
        tick = (self.tick_stamp.sec, self.tick_stamp.nanosec)
        if self.hold is not None:
            value, kind = self.params.home, HELD
        else:
            if self.open_setpoint is None or self.open_setpoint[0] != tick:
                if self.pending_override is not None:
                    self.core.override(self.pending_override, self._now())
                    self.pending_override = None
                if not self.core.needs_no_controller(self._now()):
                    if self.word_tick != tick:
                        return  # wait for the controller's word of this tick
                    if self.after is not None and self.after.holding():
                        return  # its blade bits wait for the end of its drive
                self.open_setpoint = (tick, self.core.update(self._now(), self.force))
            value, kind = self.open_setpoint[1], ""
        if self.last_sent == (tick, kind):
            return
        self.last_sent = (tick, kind)
        self.servo_pub.publish(joint_state(value, 0.0, self.tick_stamp, kind))
        self.report_changes()

    def open_board(self) -> bool:
        """Serial backend: try to open the port; on failure schedule the next try."""
        from blade_driver.serial_backend import SerialBackend

        p = self.params
        try:
            self.board = SerialBackend(p.port, p.baudrate, p.serial_timeout, p.calibration())
        except PortError as exc:
            delay = self.backoff.failed(self._wall())
            self.fault(f"{exc}; retry in {delay:.1f} s")
            return False
        reopened = self.backoff.failures > 0
        self.backoff.succeeded()
        self.board_timeout = "pending" if p.board_timeout > 0 else "off"
        self.errors.pop("board", None)
        if reopened:
            self.reopened += 1
            self.get_logger().info(f"{p.port}: port open again")
            self.publish_diagnostics()
        return True

    def arm_board_timeout(self) -> None:
        """Arm the board's own set-point timeout (``TIMEOUT``), once per connection.

        A board that refuses it (firmware without one: ``ERR``) is reported and used as it
        is; no answer leaves it pending for the next control step.
        """
        p = self.params
        try:
            self.board.set_timeout(p.board_timeout)
        except BoardError as exc:
            if "board refused" not in str(exc):
                raise
            self.board_timeout = "refused"
            self.get_logger().warning(
                f"{p.port}: the board has no set-point timeout ({exc}): only this driver "
                "homes the blade when its host fails"
            )
            return
        self.board_timeout = "armed"
        self.get_logger().info(f"{p.port}: board set-point timeout {p.board_timeout:g} s")

    def fault(self, message: str) -> None:
        """Record a board fault (logged once per distinct message)."""
        if self.errors.get("board") != message:
            self.get_logger().error(message)
            self.errors["board"] = message
            self.publish_diagnostics()

    def on_control_step(self) -> None:
        """Serial backend: read the board, publish, run the force loop, send the set-point."""
        if self.board is None:
            if not self.backoff.due(self._wall()) or not self.open_board():
                return
        now = self._wall()
        try:
            if self.board_timeout == "pending":
                self.arm_board_timeout()
            self.position, self.force = self.board.read()
            self.publish_joint(
                joint_state(self.position, self.force, self.get_clock().now().to_msg())
            )
            setpoint = self.core.update(now, self.force, self.gate.reason(now), self._tick_time())
            self.board.set_position(setpoint)
        except PortError as exc:
            self.board.close()
            self.board = None
            delay = self.backoff.failed(self._wall())
            self.fault(f"{exc}; port closed, reopening in {delay:.1f} s")
            return
        except BoardError as exc:
            self.fault(str(exc))
            return
        if self.errors.pop("board", None) is not None:
            self.get_logger().info(f"{self.params.port}: servo board answers again")
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
        }
        if p.backend == "serial":
            values |= {
                "port": p.port,
                "port_open": self.board is not None,
                "reopen_failures": self.backoff.failures,
                "reopened": self.reopened,
                "board_timeout": self.board_timeout,
            }
        hardware = p.port if p.backend == "serial" else f"sim{self.get_namespace()}"
        self.diag_pub.publish(diagnostics(self, level, message, values, hardware_id=hardware))

    def destroy_node(self) -> None:
        """Close the serial port with the node."""
        if self.board is not None:
            self.board.close()
            self.board = None
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run blade_driver driver``."""
    return spin_node(BladeDriverNode, args)


if __name__ == "__main__":
    sys.exit(main())
