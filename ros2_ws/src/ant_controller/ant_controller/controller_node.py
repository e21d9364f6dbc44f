"""``ros2 run ant_controller controller --genome best.json``: one robot's ANT controller.

Run one per robot in its namespace (add ``-p robot_id:=K`` for robot K)::

    ros2 run ant_controller controller --genome best.json --ros-args -r __ns:=/robot_0 -p robots:=4

Inputs (relative names resolve in the robot's namespace): ``pose``
(PoseWithCovarianceStamped) and the other robots' ``/robot_j/pose``,
``/worksite/height_map`` (Image 32FC1), ``/blueprint/goal``, ``/blueprint/zones``,
``/worksite/map_info`` (latched), ``blade/joint_states`` (JointState), ``stuck``
(std_msgs/Bool), with ``tilt_source: imu`` ``imu`` (sensor_msgs/Imu: R1 is its nose-down
pitch above ``tilt_threshold``; stale after ``imu_timeout``, in lockstep mode when none has
come since the last tick), and every robot's ``/robot_j/enabled`` (std_msgs/Bool,
latched, from the team supervisor): a disabled robot is absent to this controller (the
core's ``active`` mask) and its pose is not waited for, so a robot the localiser loses
does not freeze the team; this robot disabled, the controller holds still. Output:
``behaviour`` (std_msgs/UInt16, bit i = behaviour i + 1 of Table 2), ``/diagnostics``, and
with ``lockstep: true`` ``ready`` (std_msgs/Bool, latched): true once every input above
(but the optional ``enabled`` flags) has a connected publisher, so that a message sent from
then on reaches the node; the lockstep simulator waits for it before tick 0 when the poses
come from the perception nodes (``wait_for_ready``).

With ``lockstep: true`` (used with ``excavation_sim sim``) the node decides exactly once per
simulator tick, when all of that tick's inputs have arrived (same stamp), and never
publishes in between. Otherwise, every ``1 / rate`` seconds the node checks its inputs:
when all are present and fresh (poses within ``pose_timeout``, height map within
``map_timeout``, joint state and stuck flag within ``joint_timeout``, the IMU within
``imu_timeout`` when it is the tilt source; the blueprint is
latched and never stale) it decides with :class:`ant_controller.controller.ControllerCore`
and publishes the mask; otherwise it publishes 0, which moves nothing, and says which
input is missing or stale on ``/diagnostics`` (level WARN). Malformed messages are dropped
and reported (ERROR). The freshness rule and the lockstep barrier are
:class:`ant_controller.input_gate.InputGate`; the parameters are
:class:`ant_controller.input_gate.ControllerParams` (``config/controller.yaml``; a bad value
at start is one line and exit code 2).

A missing or malformed genome file ends the program before ROS starts, with the loader's
message (file, field, value) and exit code 2.
"""

from __future__ import annotations

import argparse
import sys

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseWithCovarianceStamped
from nav_msgs.msg import MapMetaData
from rclpy.node import Node
from rclpy.utilities import remove_ros_args
from sensor_msgs.msg import Image, Imu, JointState
from std_msgs.msg import Bool, UInt16

from ant_controller.controller import KIND_HAND_CODED, Controller, ControllerCore
from ant_controller.errors import GenomeFormatError
from ant_controller.input_gate import TILT_IMU, ControllerParams, InputGate
from ant_controller.readings import controller_readings
from excavation_common.constants import BladeGeometry
from excavation_common.messages import (
    MessageError,
    blade_from_joint,
    heights_to_units,
    image_to_grid,
    imu_pitch,
    pose_to_grid,
)
from excavation_common.ros import LATCHED, declare_params, diagnostics, spin_node
from excavation_common.safety import ENABLED_TOPIC


def _stamp(msg) -> tuple[int, int]:
    return (msg.header.stamp.sec, msg.header.stamp.nanosec)


class ControllerNode(Node):
    """Thin ROS plumbing around :class:`InputGate` and :class:`ControllerCore`."""

    def __init__(self, controller: Controller | None = None, **kwargs) -> None:
        """``controller``: a genome's controller; ``None`` = the hand-coded rules.

        The hand-coded rules are built here because the ``profile`` parameter chooses
        their reading (:mod:`ant_controller.readings`).
        """
        super().__init__("controller", **kwargs)
        self.params = declare_params(self, ControllerParams)
        p = self.params
        self.robot_id, self.n_robots, self.lockstep = p.robot_id, p.robots, p.lockstep
        self.geometry = BladeGeometry(depth=p.blade_depth, home=p.blade_home, max_force=p.max_force)
        readings = controller_readings(p.profile, self.get_fully_qualified_name())
        if controller is None or controller.kind == KIND_HAND_CODED:
            controller = Controller.hand_coded(readings.hand_coded)
        self.core = ControllerCore(controller, h1_frame=readings.h1_frame)
        self.gate = InputGate.from_params(p)
        self.errors: dict[str, str] = {}
        self.last_reason: str | None = "starting"
        self.last_mask = 0
        self.pending_poses: dict[int, tuple[str, PoseWithCovarianceStamped]] = {}
        self.inputs: list = []

        self.behaviour_pub = self.create_publisher(UInt16, "behaviour", 10)
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.ready_pub = self.create_publisher(Bool, "ready", LATCHED)
        self.ready = False
        sub = self._input  # an input that must be connected before the node is ready
        for j in range(self.n_robots):
            topic = "pose" if j == self.robot_id else f"/robot_{j}/pose"
            sub(PoseWithCovarianceStamped, topic, lambda m, j=j, t=topic: self.on_pose(j, t, m), 10)
            self.create_subscription(
                Bool, f"/robot_{j}/{ENABLED_TOPIC}", lambda m, j=j: self.on_enabled(j, m), LATCHED
            )
        sub(Image, "/worksite/height_map", self.on_heights, LATCHED)
        sub(Image, "/blueprint/goal", self.on_goal, LATCHED)
        sub(Image, "/blueprint/zones", self.on_zones, LATCHED)
        sub(MapMetaData, "/worksite/map_info", self.on_info, LATCHED)
        sub(JointState, "blade/joint_states", self.on_joint, 10)
        sub(Bool, "stuck", self.on_stuck, 10)
        if p.tilt_source == TILT_IMU:
            sub(Imu, "imu", self.on_imu, 10)
        self.create_timer(1.0 / p.rate, self.tick)

    def _input(self, msg_type, topic: str, callback, qos):
        """Subscribe to a required input (counted by :meth:`update_ready`)."""
        self.inputs.append(self.create_subscription(msg_type, topic, callback, qos))

    def update_ready(self) -> None:
        """Publish ``ready`` when every required input's connection is made (or lost)."""
        ready = all(s.get_publisher_count() > 0 for s in self.inputs)
        if ready != self.ready:
            self.ready = ready
            self.ready_pub.publish(Bool(data=ready))

    # --- inputs -----------------------------------------------------------------------------

    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _decode(self, topic: str, decode):
        """Run ``decode()``; a MessageError is recorded for diagnostics and gives None."""
        try:
            value = decode()
        except MessageError as exc:
            self.errors[topic] = str(exc)
            self.get_logger().warning(str(exc), throttle_duration_sec=5.0)
            return None
        self.errors.pop(topic, None)
        return value

    def _changed(self) -> None:
        """An input changed: in lockstep mode, decide if a whole tick is in."""
        if self.lockstep and self.gate.lockstep_ready(self._now()):
            if self.gate.went_back:
                # Every input went back in time together: the simulator restarted (or its
                # clock jumped back). That is a new trial: start it with a clear memory bit.
                self.get_logger().warning("tick inputs went back in time: a new trial, M1 cleared")
                self.core.memory = 0
            self.tick(lockstep_decision=True)

    def on_info(self, msg: MapMetaData) -> None:
        """Cell size of the worksite (poses that came before it are used now)."""
        self.gate.cell_size = float(msg.resolution) if msg.resolution > 0 else None
        if self.gate.cell_size is not None:
            pending, self.pending_poses = self.pending_poses, {}
            for j, (topic, pose) in pending.items():
                self.on_pose(j, topic, pose)
        self._changed()

    def on_pose(self, j: int, topic: str, msg: PoseWithCovarianceStamped) -> None:
        """A robot's pose, snapped to the grid (kept until the cell size is known)."""
        if self.gate.cell_size is None:
            self.pending_poses[j] = (topic, msg)
            return
        pose = self._decode(topic, lambda: pose_to_grid(msg, self.gate.cell_size, topic))
        if pose is not None:
            self.gate.on_pose(j, self._now(), pose, _stamp(msg))
            self._changed()

    def on_enabled(self, j: int, msg: Bool) -> None:
        """The supervisor enabled or disabled robot ``j`` (disabled: absent)."""
        self.gate.on_enabled(j, msg.data)
        self._changed()

    def on_heights(self, msg: Image) -> None:
        """The height map, in soil units."""
        topic = "/worksite/height_map"
        shape = self.gate.zones.shape if self.gate.zones is not None else None
        grid = self._decode(topic, lambda: image_to_grid(msg, "32FC1", topic, shape))
        if grid is not None:
            units = heights_to_units(grid, self.params.height_unit)
            self.gate.on_heights(self._now(), units, _stamp(msg))
            self._changed()

    def on_goal(self, msg: Image) -> None:
        """Goal heights, in soil units."""
        topic = "/blueprint/goal"
        grid = self._decode(topic, lambda: image_to_grid(msg, "32FC1", topic))
        if grid is not None:
            self.gate.goal = heights_to_units(grid, self.params.height_unit)
            self._changed()

    def on_zones(self, msg: Image) -> None:
        """Blueprint zones."""
        topic = "/blueprint/zones"
        grid = self._decode(topic, lambda: image_to_grid(msg, "mono8", topic))
        if grid is not None:
            self.gate.zones = grid
            self._changed()

    def on_joint(self, msg: JointState) -> None:
        """Blade setting and load."""
        topic = "blade/joint_states"
        blade = self._decode(topic, lambda: blade_from_joint(msg, self.geometry, topic))
        if blade is not None:
            self.gate.on_joint(self._now(), blade, _stamp(msg))
            self._changed()

    def on_stuck(self, msg: Bool) -> None:
        """U1 as the robot reports it."""
        self.gate.on_stuck(self._now(), msg.data)
        self._changed()

    def on_imu(self, msg: Imu) -> None:
        """R1's source in the field: the robot's IMU."""
        pitch = self._decode("imu", lambda: imu_pitch(msg, "imu"))
        if pitch is not None:
            self.gate.on_imu(self._now(), pitch)
            self._changed()

    # --- decision ---------------------------------------------------------------------------

    def missing_input(self) -> str | None:
        """Why the controller cannot act now, or ``None`` when every input is fresh."""
        return self.gate.missing(self._now())

    def tick(self, lockstep_decision: bool = False) -> None:
        """Decide and publish once (0 when an input is missing or stale).

        In lockstep mode the timer only refreshes diagnostics; commands go out once per
        simulator tick, when :meth:`InputGate.lockstep_ready` says the tick is complete.
        """
        if self.lockstep and not lockstep_decision:
            self.update_ready()
            waiting = self.missing_input() or self.gate.lockstep_waiting()
            self.last_reason = waiting or self.last_reason
            self.publish_diagnostics()
            return
        reason = self.missing_input()
        mask = 0
        if reason is None:
            g = self.gate
            blade, volume = g.joint[1]
            mask = self.core.decide(
                g.heights[1],
                g.zones,
                g.goal,
                g.pose_array(),
                self.robot_id,
                blade,
                volume,
                g.stuck[1],
                active=g.active(),
                tilted=g.tilted(),
            )
        self.last_reason, self.last_mask = reason, mask
        self.behaviour_pub.publish(UInt16(data=mask))
        self.publish_diagnostics()

    def publish_diagnostics(self) -> None:
        """OK when acting, WARN when holding still (with why), ERROR on malformed input."""
        if self.errors:
            level, message = DiagnosticStatus.ERROR, "; ".join(self.errors.values())
        elif self.last_reason is not None:
            level, message = DiagnosticStatus.WARN, f"holding still: {self.last_reason}"
        else:
            level, message = DiagnosticStatus.OK, "acting"
        absent = [j for j in range(self.n_robots) if not self.gate.is_enabled(j)]
        values = {
            "controller": self.core.controller.name,
            "behaviour": self.last_mask,
            "memory": self.core.memory,
            "absent_robots": absent,
        }
        self.diag_pub.publish(
            diagnostics(self, level, message, values, hardware_id=f"robot_{self.robot_id}")
        )


def parse_args(argv: list[str]) -> argparse.Namespace:
    """``--genome FILE`` or ``--hand-coded`` (ROS arguments removed first)."""
    parser = argparse.ArgumentParser(prog="controller", description=__doc__.split("\n\n")[0])
    who = parser.add_mutually_exclusive_group(required=True)
    who.add_argument("--genome", metavar="FILE", help="ant-genome/1 file")
    who.add_argument("--hand-coded", action="store_true", help="the paper's hand-coded rules")
    return parser.parse_args(argv)


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run ant_controller controller``."""
    argv = sys.argv if args is None else args
    options = parse_args(remove_ros_args(argv)[1:])
    try:
        controller = None if options.hand_coded else Controller.from_file(options.genome)
    except GenomeFormatError as exc:
        print(f"controller: error: {exc}", file=sys.stderr)
        return 2
    return spin_node(lambda: ControllerNode(controller), argv)


if __name__ == "__main__":
    sys.exit(main())
