"""``ros2 run excavation_sim dynamics``: the continuous-motion simulator as a ROS node.

The node owns a :class:`excavation_sim.dynamics.Dynamics` over scenario ``scenario`` of
``seed`` (the world ``ant-eval --seed`` and the lockstep ``sim`` start from) and is the
clock of the trial: every step it integrates each robot's latest ``cmd_vel`` for ``dt``
seconds of sim time and publishes ``/clock`` and every robot's pose. It waits for one
``cmd_vel`` per robot stamped with the current step (the executors answer every pose) or
``command_timeout`` wall seconds, whichever comes first, so a trial runs as fast as the
executors answer: faster than real time, and every node runs on ``use_sim_time``. A robot
that missed that deadline is not waited for again until it sends a ``cmd_vel`` (a dead
executor costs one ``command_timeout``, not one per step until its wheels stop); the
barrier, the time factors' schedule and the lagging robots are the pure
:class:`excavation_sim.step_clock.StepClock`. While
every command is zero (the team waits for its controllers or a camera frame) the clock
runs at most ``idle_time_factor`` times real time, so that waiting costs neither CPU nor
a race of sim time; ``max_time_factor`` caps it while robots move (nodes in separate
processes judge heartbeats on this clock: a cap bounds how much sim time a process's lag is)
and ``time_factor`` caps it always (1: real time, as in the dome, for nodes in other
processes that must keep up with sim time, such as a supervisor's heartbeat), on a fixed
schedule of wall time so that the time each step takes does not add up.

Subscribes, per robot k: ``/robot_k/cmd_vel`` (TwistStamped; none for ``cmd_vel_timeout``
sim seconds stops the robot's wheels, as diff_drive_controller's ``cmd_vel_timeout`` does,
and the steps stop waiting for it until it sends again),
``/robot_k/drive/throttle``
(Bool, latched: high-power mode), ``/robot_k/blade/servo_command`` (BladeCommand, a blade
set-point stamped with its tick, from the ``blade_driver`` sim backend) and
``/robot_k/drive/status`` (excavation_interfaces/DriveStatus): with ``blade_after_motion``
a set-point takes effect once the robot's drive goal of the same tick has ended (Table 2
order: blade behaviours run after the moves). ``/team/snapshot``
(excavation_interfaces/Snapshot): the team tick asks for a perception snapshot of a tick
taken at ``stamp`` or later (published with the first step that reaches it). Each request
(tick and ``stamp``) is taken once: the same request
again (the team tick sends it again while it has no acknowledgement) is only acknowledged
again, so that a late acknowledgement never renders a second frame and sweep of the tick.

Publishes: ``/clock``; ``{pose_prefix}/robot_k/pose`` every step (PoseWithCovarianceStamped,
with ``pose_noise``) and, without ``pose_prefix``, the same as ``map`` ->
``robot_k/base_link`` on ``/tf``; every ``imu_period`` ``/robot_k/imu`` (sensor_msgs/Imu:
yaw, and the pitch :data:`~excavation_sim.sim_node.TILT_PITCH` while the robot stands
tilted nose down by the world model's R1 rule) and ``/robot_k/blade/plant_state`` (JointState: the
simulated servo's position and push force); on each snapshot request every robot's IMU,
then ``{snapshot_prefix}/worksite/height_map`` (latched, 32FC1 metres), the poses again under
``snapshot_prefix`` when it differs from ``pose_prefix`` (the ``sensors`` node renders
exactly those), the blade plant states, ``/worksite/fitness``, ``/worksite/markers`` and
``/team/snapshot_ack`` (Snapshot, latched: the request's tick, stamped with the
snapshot's instant); ``/diagnostics``.

With ``snapshot_period`` (sim seconds) the node takes a snapshot that often unasked and
ignores requests: the world of an emulated dome (``ant-dome rehearse``), where the team
tick stamps its requests on the wall clock and the emulated camera and laser render the
world's latest poses and heights whenever their own clocks say so.

With ``soil: physical`` (:mod:`excavation_sim.soil`, its parameters declared here too) the
soil is a fine height field that the blades cut and push; ``/worksite/height_map`` then
carries the cells' sub-cell means (what the controllers read), or with
``fine_height_map`` the fine field itself (what the synthetic laser of ``sensors``
sees), and the fitness is that of the means.

With ``result_file`` set, every snapshot also rewrites that JSON file (atomically) with the
world as the snapshot shows it: ``fitness``, ``heights`` (soil units), ``snapshots`` (the
fitness of every snapshot by its request label, ``"tick t"``), ``sim_seconds``, ``steps``
and ``late_steps``. ``ant-trial --drive continuous --processes`` and ``ant-dome up --sim``
read it.
"""

from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import dataclass

import numpy as np
from builtin_interfaces.msg import Time as TimeMsg
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from excavation_interfaces.msg import BladeCommand, DriveStatus
from excavation_interfaces.msg import Snapshot as SnapshotMsg
from geometry_msgs.msg import PoseWithCovarianceStamped, TwistStamped
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Image, Imu, JointState
from std_msgs.msg import Bool, Float32
from visualization_msgs.msg import Marker, MarkerArray

from excavation_common.constants import BladeGeometry
from excavation_common.files import write_text_atomic
from excavation_common.messages import DRIVE_ENDED, blade_joint, grid_to_image, imu_message
from excavation_common.params import param
from excavation_common.ros import LATCHED, declare_params, diagnostics, spin_node
from excavation_common.tf import TfBroadcaster, base_frame, pose_transform
from excavation_sim.dynamics import Dynamics, DynamicsParams, WorldResult
from excavation_sim.sim_node import TILT_PITCH, scenario_world
from excavation_sim.soil import SoilParams
from excavation_sim.step_clock import Next, StepClock
from excavation_sim.world import BLADE


@dataclass(frozen=True)
class DynamicsNodeParams:
    """The node's own parameters (the physics ones are :class:`DynamicsParams`)."""

    blueprint: str = param("default", "blueprint spec (default, default:D, landing-pad, a file)")
    robots: int = param(4, "number of robots", low=1, high=64)
    seed: int = param(0, "scenario seed (as ant-eval --seed)", low=0)
    scenario: int = param(0, "scenario index of the seed", low=0)
    noise_seed: int = param(0, "seed of slip and noise", low=0)
    command_timeout: float = param(
        0.5, "wall seconds a step waits for every robot's cmd_vel", low=0.001, high=60.0
    )
    cmd_vel_timeout: float = param(
        0.5,
        "sim seconds without a cmd_vel after which a robot's wheels stop "
        "(diff_drive_controller's cmd_vel_timeout)",
        low=0.001,
        high=60.0,
    )
    startup_period: float = param(0.5, "wall seconds the team is present before step 0", low=0.0)
    imu_period: float = param(0.1, "sim seconds between IMU messages", low=0.001, high=10.0)
    idle_time_factor: float = param(
        0.0,
        "while every command is zero, run at most this many times real time (0: no limit)",
        low=0.0,
    )
    time_factor: float = param(
        0.0,
        "run at most this many times real time, moving or not (0: as fast as the team answers)",
        low=0.0,
    )
    max_time_factor: float = param(
        0.0, "while robots move, run at most this many times real time (0: no limit)", low=0.0
    )
    pose_prefix: str = param("", "prefix of the per-step poses (with full perception: /truth)")
    snapshot_prefix: str = param("", "prefix of the snapshot height map and poses")
    blade_after_motion: bool = param(
        True, "a blade set-point waits for the end of its tick's drive goal (Table 2 order)"
    )
    max_force: float = param(10.0, "push force of a full blade, N", low=0.001)
    diagnostics_period: float = param(1.0, "wall seconds between diagnostics", low=0.05)
    result_file: str = param("", "JSON rewritten at every snapshot: the world it shows")
    fine_height_map: bool = param(
        False,
        "soil: physical: the snapshot height map is the fine field (for the sensors node), "
        "not the cell means",
    )
    snapshot_period: float = param(
        0.0,
        "sim seconds between snapshots taken unasked (0: only when the team tick asks; "
        "then requests are ignored: the world of an emulated dome)",
        low=0.0,
        high=3600.0,
    )


def _stamp(ns: int) -> TimeMsg:
    return TimeMsg(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def _key(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


class DynamicsNode(Node):
    """Continuous-motion simulator node (the trial's clock)."""

    def __init__(self, **kwargs) -> None:
        super().__init__("dynamics", **kwargs)
        self.params = declare_params(self, DynamicsNodeParams)
        self.physics = declare_params(self, DynamicsParams)
        self.soil = declare_params(self, SoilParams)
        p = self.params
        self.n = p.robots
        self.blueprint, world = scenario_world(p.blueprint, p.robots, p.seed, p.scenario)
        self.sim = Dynamics(
            world,
            self.physics,
            self.blueprint.cell_size,
            np.random.default_rng(p.noise_seed),
            soil=self.soil,
            height_unit=self.blueprint.height_unit,
        )
        self.sim.warm()  # before any topic: the team waits for it, not its first move
        self.geometry = BladeGeometry(max_force=p.max_force)
        self.dt_ns = int(round(self.physics.dt * 1e9))
        self.clock = StepClock(
            self.n,
            self.dt_ns,
            p.command_timeout,
            p.cmd_vel_timeout,
            p.startup_period,
            p.time_factor,
            p.max_time_factor,
            p.idle_time_factor,
        )
        self.next_imu_ns = 0
        self.next_snapshot_ns = 0
        self.pending: list[tuple[int, int] | None] = [None] * self.n
        self.done_tick: list[int] = [-1] * self.n
        self.snapshot_request: int | None = None  # the tick of the request standing
        self.snapshot_due: int | None = None
        self.taken: tuple[int, int] | None = None  # (tick, due) of the last request taken
        self.ack: SnapshotMsg | None = None
        self.snapshots: dict[str, float] = {}
        self.wall_started = time.monotonic()

        self.clock_pub = self.create_publisher(Clock, "/clock", 10)
        self.pose_pubs, self.snap_pose_pubs, self.imu_pubs, self.plant_pubs = [], [], [], []
        self.tf = TfBroadcaster(self)
        self.inputs = []
        separate = p.snapshot_prefix.rstrip("/") != p.pose_prefix.rstrip("/")
        for k in range(self.n):
            ns = f"/robot_{k}"
            self.pose_pubs.append(
                self.create_publisher(
                    PoseWithCovarianceStamped, f"{p.pose_prefix.rstrip('/')}{ns}/pose", 10
                )
            )
            if separate:
                self.snap_pose_pubs.append(
                    self.create_publisher(
                        PoseWithCovarianceStamped, f"{p.snapshot_prefix.rstrip('/')}{ns}/pose", 10
                    )
                )
            self.imu_pubs.append(self.create_publisher(Imu, f"{ns}/imu", 10))
            self.plant_pubs.append(self.create_publisher(JointState, f"{ns}/blade/plant_state", 10))
            sub = self.create_subscription
            self.inputs.append(
                sub(TwistStamped, f"{ns}/cmd_vel", lambda m, k=k: self.on_cmd_vel(k, m), 10)
            )
            sub(Bool, f"{ns}/drive/throttle", lambda m, k=k: self.on_throttle(k, m), LATCHED)
            sub(BladeCommand, f"{ns}/blade/servo_command", lambda m, k=k: self.on_blade(k, m), 10)
            sub(DriveStatus, f"{ns}/drive/status", lambda m, k=k: self.on_status(k, m), 10)
        self.create_subscription(SnapshotMsg, "/team/snapshot", self.on_snapshot_request, 10)
        self.ack_pub = self.create_publisher(SnapshotMsg, "/team/snapshot_ack", LATCHED)
        self.heights_pub = self.create_publisher(
            Image, f"{p.snapshot_prefix.rstrip('/')}/worksite/height_map", LATCHED
        )
        self.fitness_pub = self.create_publisher(Float32, "/worksite/fitness", 10)
        self.markers_pub = self.create_publisher(MarkerArray, "/worksite/markers", 10)
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.create_timer(0.001, self.poll)
        self.create_timer(p.diagnostics_period, self.publish_diagnostics)

    # --- inputs -----------------------------------------------------------------------------

    def on_cmd_vel(self, k: int, msg: TwistStamped) -> None:
        """Robot k's command; one stamped with the current step counts as its answer."""
        self.sim.command(k, float(msg.twist.linear.x), float(msg.twist.angular.z))
        again, step = self.clock.on_command(
            k, _key(msg.header.stamp), time.monotonic(), bool(self.sim.commands.any())
        )
        if again:
            self.get_logger().info(f"robot {k}: cmd_vel again")
        if step:
            self.advance()

    def on_throttle(self, k: int, msg: Bool) -> None:
        """Robot k's power mode (Throttle Up)."""
        self.sim.throttle[k] = bool(msg.data)

    def on_blade(self, k: int, msg: BladeCommand) -> None:
        """A blade set-point (nearest setting), applied after its tick's drive."""
        if not math.isfinite(msg.position):
            return
        self.pending[k] = (_key(msg.stamp), self.geometry.nearest(float(msg.position)))
        self.apply_blade(k)

    def on_status(self, k: int, msg: DriveStatus) -> None:
        """Robot k's drive status: a terminal one releases that tick's blade set-point."""
        if msg.status in DRIVE_ENDED:
            self.done_tick[k] = max(self.done_tick[k], _key(msg.goal.stamp))
            self.apply_blade(k)

    def apply_blade(self, k: int) -> None:
        """Apply robot k's pending set-point if its tick's motion has ended."""
        pending = self.pending[k]
        if pending is None:
            return
        if self.params.blade_after_motion and self.done_tick[k] < pending[0]:
            return
        self.sim.set_blade(k, pending[1])
        self.pending[k] = None

    def on_snapshot_request(self, msg: SnapshotMsg) -> None:
        """The team tick wants a perception snapshot taken at ``msg.stamp`` or later.

        Ignored with ``snapshot_period``: in an emulated dome the team tick's requests are
        stamped on the wall clock and the emulated sensors render the world as it is now.
        """
        if self.params.snapshot_period > 0:
            return
        if (int(msg.tick), _key(msg.stamp)) == self.taken:
            self.ack_pub.publish(self.ack)  # taken already: its acknowledgement came late
            return
        self.snapshot_request = int(msg.tick)
        self.snapshot_due = _key(msg.stamp)
        if self.clock.started and self.clock.now_ns >= self.snapshot_due:
            self.publish_snapshot()

    # --- stepping ---------------------------------------------------------------------------

    def team_present(self) -> bool:
        """Every robot's executor publishes cmd_vel and reads its pose."""
        return all(s.get_publisher_count() > 0 for s in self.inputs) and all(
            pub.get_subscription_count() > 0 for pub in self.pose_pubs
        )

    def poll(self) -> None:
        """Start once the team is present; step when due or when a robot is late."""
        clock = self.clock
        present = clock.started or self.team_present()
        match clock.poll(time.monotonic(), present, bool(self.sim.commands.any())):
            case Next.START:
                self.wall_started = time.monotonic()
                self.publish_state()
            case Next.STEP:
                self.advance()
            case Next.WAIT:
                pass

    def stop_silent_robots(self) -> None:
        """Zero the wheels of a robot whose last cmd_vel is older than ``cmd_vel_timeout``.

        The base's own deadman (diff_drive_controller's ``cmd_vel_timeout``): a robot whose
        executor died mid-motion must not drive on with its last command. Until it sends a
        cmd_vel again the steps no longer wait for it (``command_timeout`` each).
        """
        for k in self.clock.silent():
            self.sim.command(k, 0.0, 0.0)
            self.get_logger().warning(
                f"robot {k}: no cmd_vel for {self.params.cmd_vel_timeout} s: wheels stopped"
            )

    def advance(self) -> None:
        """Integrate one step and publish its state."""
        self.stop_silent_robots()
        self.sim.step()
        self.clock.stepped()
        self.publish_state()

    def publish_state(self) -> None:
        """``/clock`` and every pose of the current step (IMU when due)."""
        stamp = _stamp(self.clock.now_ns)
        self.clock.published(time.monotonic())
        self.clock_pub.publish(Clock(clock=stamp))
        imu_due = self.clock.now_ns >= self.next_imu_ns
        if imu_due:
            self.next_imu_ns = self.clock.now_ns + int(round(self.params.imu_period * 1e9))
        frames = []
        for k in range(self.n):
            pose = self.pose(k, stamp)
            self.pose_pubs[k].publish(pose)
            if not self.params.pose_prefix.rstrip("/"):
                frames.append(pose_transform(pose, base_frame(k)))
            if imu_due:
                self.imu_pubs[k].publish(self.imu(k, stamp))
                self.plant_pubs[k].publish(self.plant_state(k, stamp))
        if frames:
            self.tf.send(frames)
        if self.snapshot_due is not None and self.clock.now_ns >= self.snapshot_due:
            self.publish_snapshot()
        elif self.params.snapshot_period > 0 and self.clock.now_ns >= self.next_snapshot_ns:
            period_ns = int(round(self.params.snapshot_period * 1e9))
            self.next_snapshot_ns = self.clock.now_ns + period_ns
            self.publish_snapshot()

    def pose(self, k: int, stamp: TimeMsg) -> PoseWithCovarianceStamped:
        """Robot k's measured pose in ``map``, with its covariance."""
        x, y, yaw = self.sim.measured(k)
        msg = PoseWithCovarianceStamped()
        msg.header.stamp = stamp
        msg.header.frame_id = "map"
        msg.pose.pose.position.x, msg.pose.pose.position.y = x, y
        msg.pose.pose.orientation.z = math.sin(yaw / 2)
        msg.pose.pose.orientation.w = math.cos(yaw / 2)
        cov = np.zeros(36)
        cov[0] = cov[7] = max(self.physics.pose_noise, 1e-4) ** 2
        cov[14] = cov[21] = cov[28] = 1e6
        cov[35] = max(self.physics.yaw_noise, 1e-4) ** 2
        msg.pose.covariance = cov
        return msg

    def imu(self, k: int, stamp: TimeMsg) -> Imu:
        """Robot k's orientation: yaw, and the R1 pitch when tilted nose down."""
        pitch = TILT_PITCH if self.sim.tilted(k) else 0.0
        return imu_message(float(self.sim.bodies[k, 2]), pitch, f"robot_{k}/base_link", stamp)

    def plant_state(self, k: int, stamp: TimeMsg) -> JointState:
        """Robot k's blade servo as measured: position of its setting, push force."""
        blade = int(self.sim.world.robots[k, BLADE])
        force = self.sim.blade_force(k, self.geometry.max_force)
        return blade_joint(blade, force, self.geometry, stamp)

    def publish_snapshot(self) -> None:
        """IMU, height map, snapshot poses, blade plant states, fitness, markers, stamped now."""
        stamp = _stamp(self.clock.now_ns)
        for k in range(self.n):  # the tilt at the snapshot's instant, before its height map
            self.imu_pubs[k].publish(self.imu(k, stamp))
        self.heights_pub.publish(grid_to_image(self.height_map(), "32FC1", stamp=stamp))
        for k in range(self.n):
            if self.snap_pose_pubs:
                self.snap_pose_pubs[k].publish(self.pose(k, stamp))
            self.plant_pubs[k].publish(self.plant_state(k, stamp))
        fitness = self.sim.fitness()
        if self.snapshot_request is not None:
            self.snapshots[f"tick {self.snapshot_request}"] = fitness
            self.taken = (self.snapshot_request, self.snapshot_due)
            self.ack = SnapshotMsg(stamp=stamp, tick=self.snapshot_request)
        self.snapshot_due = None
        self.fitness_pub.publish(Float32(data=float(fitness)))
        self.markers_pub.publish(self.markers(stamp))
        if self.params.result_file:
            write_text_atomic(self.params.result_file, json.dumps(self.result().to_json()))
        if self.ack is not None:
            self.ack_pub.publish(self.ack)

    def height_map(self) -> np.ndarray:
        """The snapshot's height map, metres (``float32``): cells, means or the fine field."""
        soil, unit = self.sim.soil, self.blueprint.height_unit
        if soil is None:
            return (self.sim.world.heights * unit).astype(np.float32)
        if self.params.fine_height_map:
            return soil.fine_metres().astype(np.float32)
        return (soil.cell_means() * unit).astype(np.float32)

    def result(self) -> WorldResult:
        """The world now (:class:`~excavation_sim.dynamics.WorldResult`)."""
        soil = self.sim.soil
        return WorldResult(
            fitness=float(self.sim.fitness()),
            heights=self.sim.world.heights.tolist(),
            snapshots=dict(self.snapshots),
            sim_seconds=self.clock.now_ns * 1e-9,
            steps=self.clock.steps,
            late_steps=self.clock.late,
            mean_heights=None if soil is None else soil.cell_means().round(6).tolist(),
            volume=None if soil is None else soil.volume(),
            slips=0 if soil is None else self.sim.counters.slips,
        )

    def markers(self, stamp: TimeMsg) -> MarkerArray:
        """One cube per robot at its true pose (for RViz or Foxglove)."""
        out = MarkerArray()
        cell = self.blueprint.cell_size
        for k in range(self.n):
            x, y, yaw = self.sim.bodies[k]
            m = Marker()
            m.header.stamp = stamp
            m.header.frame_id = "map"
            m.ns, m.id, m.type, m.action = "robots", k, Marker.CUBE, Marker.ADD
            m.pose.position.x, m.pose.position.y = float(x), float(y)
            m.pose.orientation.z, m.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
            m.scale.x = m.scale.y = 2 * cell
            m.scale.z = cell
            m.color.r, m.color.g, m.color.b, m.color.a = 0.9, 0.5, 0.1, 0.8
            out.markers.append(m)
        return out

    def publish_diagnostics(self) -> None:
        """Sim time, real-time factor, grid events."""
        wall = max(time.monotonic() - self.wall_started, 1e-9)
        c = self.sim.counters
        level = DiagnosticStatus.OK if self.clock.started else DiagnosticStatus.WARN
        message = (
            f"stepping: {self.clock.now_ns * 1e-9:.2f} s of sim time"
            if self.clock.started
            else "waiting for every robot's executor"
        )
        self.diag_pub.publish(
            diagnostics(
                self,
                level,
                message,
                {
                    "sim_time": f"{self.clock.now_ns * 1e-9:.3f}",
                    "real_time_factor": (
                        f"{self.clock.now_ns * 1e-9 / wall:.2f}" if self.clock.started else 0
                    ),
                    "steps": self.clock.steps,
                    "late_steps": self.clock.late,
                    "moves": c.moves,
                    "refused_moves": c.refused,
                    "turns": c.turns,
                    "fitness": f"{self.sim.fitness():.6f}",
                    "slips": c.slips,
                },
                hardware_id="excavation_sim",
            )
        )


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run excavation_sim dynamics``."""
    return spin_node(DynamicsNode, args)


if __name__ == "__main__":
    sys.exit(main())
