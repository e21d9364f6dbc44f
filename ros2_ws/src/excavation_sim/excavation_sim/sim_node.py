"""``ros2 run excavation_sim sim``: the simulated worksite as a ROS node, in lockstep.

The node owns a :class:`excavation_sim.world.World` (scenario 0 of ``seed``, the same as
``ant-eval --seed K``) and steps it once per tick:

1. publish the state of tick t, stamped with sim time ``t * dt`` (``/clock`` too): every
   robot's ``/robot_k/pose``, ``/robot_k/blade/joint_states``, ``/robot_k/stuck`` and
   ``/robot_k/imu``, the frames ``map`` -> ``robot_k/base_link`` (without ``truth_prefix``)
   and ``robot_k/base_link`` -> ``robot_k/blade`` (without blade drivers) on ``/tf``, then
   ``/worksite/height_map`` (latched), ``/worksite/fitness`` and ``/worksite/markers``;
2. wait for one ``/robot_k/behaviour`` command from every robot (``command_timeout``; a
   robot that does not answer idles this tick, which is reported on ``/diagnostics``);
3. apply the commands in robot order (the offline rule) and go on with tick t + 1.

Tick 0 is published once every robot's controller is on the graph (the node that
publishes ``/robot_k/behaviour``), every writer of the tick has matched each reader the
graph shows and the controller's own readers among them (a message sent before a reader is
matched is lost to it), and ``startup_period`` has passed since, so no controller misses
it; nothing is ever published twice for one tick, which is what lets a controller pair the
unstamped ``stuck`` flag with its tick. After ``steps``
ticks the node publishes the final state and fitness and stops stepping (``finished``).

Parameters: ``blueprint`` (``default``, ``default:D``, ``landing-pad`` or a file),
``profile`` (``v1`` or ``paper``: the world's readings of the paper,
:data:`excavation_sim.rules.WORLD_PROFILES`, as ``ant-eval --profile``), ``robots`` (4),
``steps`` (300), ``seed`` (0), ``scenario`` (0, the index within ``seed``), ``dt`` (1.0 s
of sim time per tick),
``command_timeout`` (1.0 s), ``first_command_timeout`` (30.0 s: tick 0 waits longer, while
controllers load their compiled kernels), ``startup_period`` (0.5 s),
``diagnostics_period`` (1.0 s), ``blade_driver`` (false), ``result_file`` (JSON written at
the end; empty: none). With ``blade_driver: true`` every robot has a
``blade_driver driver`` (sim backend): the node publishes ``/robot_k/blade/servo_state``
instead of ``blade/joint_states``, also waits for each driver's
``/robot_k/blade/servo_command`` of the tick, applies the words without their blade bits and
then sets each blade to the driver's set-point (nearest setting).
``wait_for_ready`` (false): tick 0 also waits for every controller's latched
``/robot_k/ready`` (its inputs connected): with ``truth_prefix`` the poses and the height
map come from the perception nodes, whose connections to the controllers this node cannot
see (``ant-trial --perception full`` sets it).
``wait_for_recorder`` (false): tick 0 also waits until the bag recorder (the node
``bag_recorder``) subscribes ``/clock``, so a bag recorded by a separate process starts at
tick 0 (``startup_period`` then gives it time to find the robots' topics too).
``truth_prefix`` (empty) moves the true poses and height map to ``PREFIX/robot_k/pose`` and
``PREFIX/worksite/height_map``, for the perception nodes to stand in (``--perception full``
of ``ant-trial``: the ``sensors`` node renders camera and laser from them); tick 0 then also
waits for a subscriber of each truth pose.

Oversight (``supervised``, true by default; docs/operator.md): the node
applies a tick only while the team is armed (``/team/heartbeat`` younger than the deadman
and saying ``armed``, no e-stop latched on ``/team/estop``); otherwise it holds the tick,
keeping the words and set-points already in, so a paused trial ends as an unpaused one
does. A robot disabled on ``/robot_k/enabled`` is absent: it is not waited for and idles.
A blade set-point with ``held`` set (sent under a closed gate) does not complete a tick; it
applies only to an absent robot or when the tick times out.
"""

from __future__ import annotations

import json
import math
import sys

import numpy as np
from builtin_interfaces.msg import Time as TimeMsg
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from excavation_interfaces.msg import BladeCommand, TeamState
from geometry_msgs.msg import PoseWithCovarianceStamped
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Image, Imu, JointState
from std_msgs.msg import Bool, Float32, UInt16
from visualization_msgs.msg import Marker, MarkerArray

from ant_controller.layout import (
    BLADE_ABOVE_CMD,
    BLADE_BELOW_CMD,
    BLADE_HOME_CMD,
    BLADE_LEVEL_CMD,
)
from ant_controller.sensing import blade_volume, is_tilted_down
from blueprint_server.blueprint import resolve_blueprint
from excavation_common.constants import MAX_LOAD, BladeGeometry
from excavation_common.files import write_text_atomic
from excavation_common.messages import blade_joint, grid_to_image, pose_message
from excavation_common.ros import (
    LATCHED,
    declare_params,
    diagnostics,
    publishers_of,
    reaches,
    recorder_subscribes,
    spin_node,
)
from excavation_common.safety import (
    ENABLED_TOPIC,
    ESTOP_TOPIC,
    HEARTBEAT_TOPIC,
    MotionGate,
)
from excavation_common.tf import TfBroadcaster, base_frame, blade_transform, pose_transform
from excavation_sim.lockstep import Action, SimParams, TickClock, TickInputs
from excavation_sim.rules import V1_RULES, WORLD_PROFILES, WorldRules
from excavation_sim.world import (
    BLADE,
    COL,
    HEADING,
    ROW,
    STUCK,
    World,
)

BLADE_BITS = sum(
    1 << b for b in (BLADE_ABOVE_CMD, BLADE_BELOW_CMD, BLADE_LEVEL_CMD, BLADE_HOME_CMD)
)
"""The four blade behaviours of a word (Table 2, 7-10)."""

TILT_PITCH = 0.2
"""Pitch (rad, nose down) the simulated IMU reports when R1 holds."""


def scenario_world(
    blueprint_spec: str, robots: int, seed: int, index: int = 0, rules: WorldRules = V1_RULES
):
    """Scenario ``index`` of ``seed`` (index 0: the world ``ant-eval --seed`` starts from).

    ``rules``: the world's readings (``WORLD_PROFILES[profile]``), as ``ant-eval --profile``.
    """
    bp = resolve_blueprint(blueprint_spec, fitted=rules.fitted_site)
    world = World.scenario(bp.zones, bp.goal, robots, seed, index, rules)
    return bp, world


class SimNode(Node):
    """Lockstep simulator node: thin plumbing around :class:`~excavation_sim.lockstep.TickClock`."""

    def __init__(self, **kwargs) -> None:
        super().__init__("sim", **kwargs)
        self.params = declare_params(self, SimParams)
        p = self.params
        self.n = p.robots
        self.steps = p.steps
        self.dt = p.dt
        self.blade_driver = p.blade_driver
        self.result_file = p.result_file
        self.truth_prefix = p.truth_prefix.rstrip("/")
        self.blueprint, self.world = scenario_world(
            p.blueprint, p.robots, p.seed, p.scenario, WORLD_PROFILES[p.profile]
        )
        self.clock = TickClock.from_params(p)
        self.geometry = BladeGeometry()
        self.missed_servo: dict[int, int] = {k: 0 for k in range(self.n)}
        self.missed: dict[int, int] = {k: 0 for k in range(self.n)}
        self.fitness_trace = [self.world.fitness()]
        self.applied: list[list[int]] = []

        self.pose_pubs, self.joint_pubs, self.stuck_pubs, self.imu_pubs = [], [], [], []
        self.tf = TfBroadcaster(self)
        self.inputs = []  # command subscriptions: behaviour (and blade set-point) per robot
        for k in range(self.n):
            ns = f"/robot_{k}"
            self.pose_pubs.append(
                self.create_publisher(
                    PoseWithCovarianceStamped, f"{self.truth_prefix}{ns}/pose", 10
                )
            )
            blade_topic = "blade/servo_state" if self.blade_driver else "blade/joint_states"
            self.joint_pubs.append(self.create_publisher(JointState, f"{ns}/{blade_topic}", 10))
            if self.blade_driver:
                self.inputs.append(
                    self.create_subscription(
                        BladeCommand,
                        f"{ns}/blade/servo_command",
                        lambda m, k=k: self.on_servo_command(k, m),
                        10,
                    )
                )
            self.stuck_pubs.append(self.create_publisher(Bool, f"{ns}/stuck", 10))
            self.imu_pubs.append(self.create_publisher(Imu, f"{ns}/imu", 10))
            self.inputs.append(
                self.create_subscription(
                    UInt16, f"{ns}/behaviour", lambda m, k=k: self.on_command(k, m), 10
                )
            )
        self.heights_pub = self.create_publisher(
            Image, f"{self.truth_prefix}/worksite/height_map", LATCHED
        )
        self.fitness_pub = self.create_publisher(Float32, "/worksite/fitness", 10)
        self.markers_pub = self.create_publisher(MarkerArray, "/worksite/markers", 10)
        self.clock_pub = self.create_publisher(Clock, "/clock", 10)
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        # The team's gate (the robots' own state is per robot: ``clock.absent``).
        self.team = MotionGate(active=True, enabled=True)
        self.hold_reason: str | None = None
        self.holds = 0
        if p.supervised:
            self.create_subscription(Bool, ESTOP_TOPIC, self.on_estop, LATCHED)
            self.create_subscription(TeamState, HEARTBEAT_TOPIC, self.on_heartbeat, 10)
            for k in range(self.n):
                self.create_subscription(
                    Bool,
                    f"/robot_{k}/{ENABLED_TOPIC}",
                    lambda m, k=k: self.on_enabled(k, m),
                    LATCHED,
                )
        self.ready: set[int] = set()  # robots whose controller said ready (wait_for_ready)
        if p.wait_for_ready:
            for k in range(self.n):
                self.create_subscription(
                    Bool, f"/robot_{k}/ready", lambda m, k=k: self.on_ready(k, m), LATCHED
                )
        self.create_timer(0.001, self.step)
        self.create_timer(p.diagnostics_period, self.report_state)

    def on_ready(self, k: int, msg: Bool) -> None:
        """Robot k's controller has (or has lost) every input connected."""
        if msg.data:
            self.ready.add(k)
        else:
            self.ready.discard(k)

    @property
    def tick(self) -> int:
        """The current tick."""
        return self.clock.tick

    @property
    def finished(self) -> bool:
        """Every tick has been simulated."""
        return self.clock.finished

    def _seconds(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _stamp(self) -> TimeMsg:
        seconds = self.tick * self.dt
        return TimeMsg(sec=int(seconds), nanosec=int(round((seconds % 1) * 1e9)))

    def publish_state(self) -> None:
        """Everything the controllers need for the current tick, stamped with its sim time."""
        stamp = self._stamp()
        self.clock_pub.publish(Clock(clock=stamp))
        w, cell = self.world, self.blueprint.cell_size
        heights = grid_to_image(
            (w.heights * self.blueprint.height_unit).astype(np.float32), "32FC1", stamp=stamp
        )
        self.heights_pub.publish(heights)
        frames = []
        for k in range(self.n):
            r = w.robots[k]
            row, col, h, blade = int(r[ROW]), int(r[COL]), int(r[HEADING]), int(r[BLADE])
            self.stuck_pubs[k].publish(Bool(data=bool(r[STUCK])))
            force = blade_volume(w.heights, row, col, h, blade) * self.geometry.max_force / MAX_LOAD
            self.joint_pubs[k].publish(blade_joint(blade, force, self.geometry, stamp))
            imu = Imu()
            imu.header.stamp = stamp
            imu.header.frame_id = f"robot_{k}/base_link"
            pitch = TILT_PITCH if is_tilted_down(w.heights, row, col, h) else 0.0
            imu.orientation.y = math.sin(pitch / 2)
            imu.orientation.w = math.cos(pitch / 2)
            self.imu_pubs[k].publish(imu)
            pose = pose_message(row, col, h, cell, (0.05 * cell) ** 2, 0.01, stamp)
            self.pose_pubs[k].publish(pose)
            if not self.truth_prefix:
                frames.append(pose_transform(pose, base_frame(k)))
            if not self.blade_driver:
                position = self.geometry.position(blade)
                frames.append(blade_transform(f"robot_{k}", position, self.geometry.reach, stamp))
        if frames:
            self.tf.send(frames)
        self.fitness_pub.publish(Float32(data=float(w.fitness())))
        self.markers_pub.publish(self.markers(stamp))
        self.clock.published(self._seconds())

    def markers(self, stamp) -> MarkerArray:
        """One cube per robot (for RViz or Foxglove)."""
        out = MarkerArray()
        cell = self.blueprint.cell_size
        for k in range(self.n):
            r = self.world.robots[k]
            m = Marker()
            m.header.stamp = stamp
            m.header.frame_id = "map"
            m.ns, m.id, m.type, m.action = "robots", k, Marker.CUBE, Marker.ADD
            m.pose = pose_message(int(r[ROW]), int(r[COL]), int(r[HEADING]), cell, 0, 0).pose.pose
            m.scale.x = m.scale.y = 2 * cell
            m.scale.z = cell
            m.color.r, m.color.g, m.color.b, m.color.a = 0.9, 0.5, 0.1, 0.8
            out.markers.append(m)
        return out

    def controllers_present(self) -> bool:
        """Every robot's controller (and blade driver, and recorder) is on the graph and connected.

        Tick 0 is published once, so every writer of the tick must already deliver to each
        node that needs it (:func:`excavation_common.ros.reaches`: a message sent before the
        middleware has matched a reader is lost to it, and the robot would wait for it until
        tick 1). The controller of robot k is the node that publishes ``/robot_k/behaviour``
        and its blade driver the one that publishes ``/robot_k/blade/servo_command``; with
        ``wait_for_ready`` each controller has also connected every one of its inputs (the
        blade driver's joint states among them).
        """
        if self.params.wait_for_ready and len(self.ready) < self.n:
            return False
        if self.params.wait_for_recorder and not recorder_subscribes(self, ["/clock"]):
            return False
        if not all(s.get_publisher_count() > 0 for s in self.inputs):
            return False
        controllers, drivers = [], []
        for k in range(self.n):
            controller = publishers_of(self, f"/robot_{k}/behaviour")
            driver = publishers_of(self, f"/robot_{k}/blade/servo_command")
            if not controller or (self.blade_driver and not driver):
                return False
            controllers.append(controller)
            drivers.append(driver)
        everyone = set().union(*controllers)
        for k in range(self.n):
            pose_readers = set() if self.truth_prefix else everyone
            joint_readers = drivers[k] if self.blade_driver else controllers[k]
            if not (
                reaches(self, self.pose_pubs[k], pose_readers)
                and reaches(self, self.stuck_pubs[k], controllers[k])
                and reaches(self, self.joint_pubs[k], joint_readers)
                and reaches(self, self.imu_pubs[k])
                and reaches(self, self.tf.publisher)
                and self.count_subscribers(f"{self.truth_prefix}/robot_{k}/pose") > 0
            ):
                return False
        return True

    def on_servo_command(self, k: int, msg: BladeCommand) -> None:
        """A blade driver's set-point for the current tick (stamped with it; others dropped)."""
        stamp = self._stamp()
        if (msg.stamp.sec, msg.stamp.nanosec) != (stamp.sec, stamp.nanosec):
            return
        if math.isfinite(msg.position):
            self.clock.on_setpoint(k, float(msg.position), held=bool(msg.held))

    def on_command(self, k: int, msg: UInt16) -> None:
        """A robot's behaviour mask for the current tick (the first one counts)."""
        self.clock.on_command(k, msg.data)

    def on_estop(self, msg: Bool) -> None:
        """``/team/estop`` changed."""
        self.team.on_estop(msg.data)

    def on_heartbeat(self, msg: TeamState) -> None:
        """A team heartbeat (the team state)."""
        self.team.on_heartbeat(msg.state, self._seconds())

    def on_enabled(self, k: int, msg: Bool) -> None:
        """Robot ``k`` enabled (waited for) or disabled (absent, idles)."""
        if msg.data:
            self.clock.absent.discard(k)
        else:
            self.clock.absent.add(k)
        self.report(f"robot {k} {'enabled' if msg.data else 'disabled: absent, idles'}")

    def apply_team_state(self) -> None:
        """Hold the tick clock while the team is not armed (supervised only)."""
        if not self.params.supervised:
            return
        now = self._seconds()
        reason = self.team.reason(now)
        if MotionGate.kind(reason) != MotionGate.kind(self.hold_reason):  # not a growing age
            self.hold_reason = reason
            if reason is not None:
                self.holds += 1
            self.report(
                f"tick {self.tick} held: {reason}" if reason else f"tick {self.tick}: armed"
            )
        self.clock.hold(reason is not None, now)

    def step(self) -> None:
        """Ask the tick clock what to do (runs every millisecond)."""
        if self.finished:
            return
        self.apply_team_state()
        present = not self.clock.started and self.controllers_present()
        action = self.clock.poll(self._seconds(), present)
        if action is Action.PUBLISH_FIRST:
            self.publish_state()
            return
        if action is not Action.APPLY:
            return
        tick = self.tick
        inputs = self.clock.take()
        for k in inputs.missing:
            self.missed[k] += 1
        if inputs.missing:
            self.report(f"tick {tick}: no command from robots {inputs.missing}; they idle")
        self.applied.append([int(m) for m in inputs.masks])
        if self.blade_driver:
            self.step_with_drivers(inputs, tick)
        else:
            self.world.step(inputs.masks)
        self.fitness_trace.append(self.world.fitness())
        self.publish_state()
        if self.finished:
            self.report(f"finished {self.steps} ticks, fitness {self.world.fitness():.4f}")
            if self.result_file:
                self.write_result(self.result_file)

    def result(self) -> dict:
        """The trial's outcome: fitness, its trace, final heights, commands, missed ticks."""
        return {
            "fitness": float(self.world.fitness()),
            "trace": [float(f) for f in self.fitness_trace],
            "heights": self.world.heights.tolist(),
            "missed": {str(k): v for k, v in self.missed.items()},
            "missed_blade_setpoints": {str(k): v for k, v in self.missed_servo.items()},
            "commands": self.applied,
            "holds": self.holds,
        }

    def write_result(self, path: str) -> None:
        """Write :meth:`result` as JSON, atomically (``ant-trial --processes`` reads it)."""
        write_text_atomic(path, json.dumps(self.result()))

    def step_with_drivers(self, inputs: TickInputs, tick: int) -> None:
        """Apply the words without their blade bits, then each driver's set-point.

        Blade behaviours come after every move in Table 2 order, so setting the blade after
        the step is the same as the words' own blade bits when a driver follows them. A
        driver that sent nothing for this tick leaves its blade where it was.
        """
        self.world.step(inputs.masks & ~BLADE_BITS)
        for k, value in inputs.setpoints.items():
            self.world.robots[k, BLADE] = self.geometry.nearest(value)
        for k in inputs.missing_setpoints:
            self.missed_servo[k] += 1
        if inputs.missing_setpoints:
            self.report(
                f"tick {tick}: no blade set-point from robots {inputs.missing_setpoints}; "
                "blade held"
            )

    def report_state(self) -> None:
        """The periodic status: waiting for the team, stepping, or finished."""
        if self.finished:
            self.report(f"finished {self.steps} ticks, fitness {self.world.fitness():.4f}")
        elif not self.clock.started:
            self.report("waiting for every robot's controller to join")
        elif self.hold_reason is not None:
            self.report(f"tick {self.tick} held: {self.hold_reason}")
        else:
            self.report(f"stepping: tick {self.tick} of {self.steps}")

    def report(self, message: str, level=DiagnosticStatus.OK) -> None:
        """One diagnostics status for the simulator (WARN once a robot has missed a tick)."""
        missed = sum(self.missed.values())
        values = {"tick": self.tick, "fitness": f"{self.world.fitness():.6f}"}
        if self.params.supervised:
            values |= {"team": self.hold_reason or "armed", "absent": sorted(self.clock.absent)}
        values.update({f"robot_{k}_missed": v for k, v in self.missed.items()})
        if self.blade_driver:
            values.update(
                {f"robot_{k}_missed_blade_setpoints": v for k, v in self.missed_servo.items()}
            )
        if missed and level == DiagnosticStatus.OK:
            level = DiagnosticStatus.WARN
        self.diag_pub.publish(diagnostics(self, level, message, values, "excavation_sim"))


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run excavation_sim sim`` (ends after the last tick)."""
    return spin_node(SimNode, args, until=lambda node: node.finished)


if __name__ == "__main__":
    sys.exit(main())
