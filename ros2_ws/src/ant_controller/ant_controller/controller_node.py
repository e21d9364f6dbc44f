"""``ros2 run ant_controller controller --genome best.json``: one robot's ANT controller.

Run one per robot in its namespace (add ``-p robot_id:=K`` for robot K)::

    ros2 run ant_controller controller --genome best.json --ros-args -r __ns:=/robot_0 -p robots:=4

Inputs (relative names resolve in the robot's namespace): ``pose``
(PoseWithCovarianceStamped) and the other robots' ``/robot_j/pose``,
``/worksite/height_map`` (Image 32FC1), ``/blueprint/goal``, ``/blueprint/zones``,
``/worksite/map_info`` (latched), ``blade/joint_states`` (JointState), ``stuck``
(std_msgs/Bool). Output: ``behaviour`` (std_msgs/UInt16, bit i = behaviour i + 1 of Table 2)
and ``/diagnostics``.

With ``lockstep: true`` (used with ``excavation_sim sim``) the node decides exactly once per
simulator tick, when all of that tick's inputs have arrived (same stamp), and never
publishes in between. Otherwise, every ``1 / rate`` seconds the node checks its inputs:
when all are present and fresh (poses within ``pose_timeout``, height map within
``map_timeout``, joint state and stuck flag within ``joint_timeout``; the blueprint is
latched and never stale) it decides with :class:`ant_controller.controller.ControllerCore`
and publishes the mask; otherwise it publishes 0, which moves nothing, and says which
input is missing or stale on ``/diagnostics`` (level WARN). Malformed messages are dropped
and reported (ERROR).

A missing or malformed genome file ends the program before ROS starts, with the loader's
message (file, field, value) and exit code 2.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseWithCovarianceStamped
from nav_msgs.msg import MapMetaData
from rclpy.node import Node
from rclpy.time import Time
from rclpy.utilities import remove_ros_args
from sensor_msgs.msg import Image, JointState
from std_msgs.msg import Bool, UInt16

from ant_controller.controller import Controller, ControllerCore
from ant_controller.errors import GenomeFormatError
from excavation_common.constants import BladeGeometry
from excavation_common.messages import (
    MessageError,
    blade_from_joint,
    heights_to_units,
    image_to_grid,
    pose_to_grid,
)
from excavation_common.ros import LATCHED, spin_node

UNKNOWN = np.iinfo(np.int32).min


class ControllerNode(Node):
    """Thin ROS plumbing around :class:`ControllerCore`."""

    def __init__(self, controller: Controller, **kwargs) -> None:
        super().__init__("controller", **kwargs)
        p = self.declare_parameter
        self.robot_id = int(p("robot_id", 0).value)
        self.n_robots = int(p("robots", 1).value)
        self.height_unit = float(p("height_unit", 0.05).value)
        self.pose_timeout = float(p("pose_timeout", 1.0).value)
        self.map_timeout = float(p("map_timeout", 5.0).value)
        self.joint_timeout = float(p("joint_timeout", 1.0).value)
        rate = float(p("rate", 10.0).value)
        self.lockstep = bool(p("lockstep", False).value)
        self.geometry = BladeGeometry(
            depth=float(p("blade_depth", 0.02).value),
            home=float(p("blade_home", 0.10).value),
            max_force=float(p("max_force", 10.0).value),
        )
        self.core = ControllerCore(controller)
        self.poses: dict[int, tuple[Time, tuple[int, int, int]]] = {}
        self.early_poses: dict[int, tuple[str, PoseWithCovarianceStamped]] = {}
        self.heights: tuple[Time, np.ndarray] | None = None
        self.joint: tuple[Time, tuple[int, int]] | None = None
        self.stuck: tuple[Time, bool] | None = None
        self.zones: np.ndarray | None = None
        self.goal: np.ndarray | None = None
        self.cell_size: float | None = None
        self.errors: dict[str, str] = {}
        self.last_reason = "starting"
        self.last_mask = 0
        self.stamps: dict[str, tuple[int, int]] = {}
        self.fresh_stuck = 0
        self.decided_stamp: tuple[int, int] | None = None

        self.behaviour_pub = self.create_publisher(UInt16, "behaviour", 10)
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        for j in range(self.n_robots):
            topic = "pose" if j == self.robot_id else f"/robot_{j}/pose"
            self.create_subscription(
                PoseWithCovarianceStamped, topic, lambda m, j=j, t=topic: self.on_pose(j, t, m), 10
            )
        self.create_subscription(Image, "/worksite/height_map", self.on_heights, LATCHED)
        self.create_subscription(Image, "/blueprint/goal", self.on_goal, LATCHED)
        self.create_subscription(Image, "/blueprint/zones", self.on_zones, LATCHED)
        self.create_subscription(MapMetaData, "/worksite/map_info", self.on_info, LATCHED)
        self.create_subscription(JointState, "blade/joint_states", self.on_joint, 10)
        self.create_subscription(Bool, "stuck", self.on_stuck, 10)
        self.create_timer(1.0 / rate, self.tick)

    # --- inputs -----------------------------------------------------------------------------

    def _now(self) -> Time:
        return self.get_clock().now()

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

    def _stamped(self, key: str, msg) -> None:
        """Record the stamp of a tick input; in lockstep mode maybe decide."""
        self.stamps[key] = (msg.header.stamp.sec, msg.header.stamp.nanosec)
        if self.lockstep:
            self.try_lockstep()

    def on_info(self, msg: MapMetaData) -> None:
        """Cell size of the worksite; poses that came before it are decoded now.

        The latched map info can reach a freshly started controller after the simulator's
        first poses (separate processes): dropping those would miss tick 0.
        """
        self.cell_size = float(msg.resolution) if msg.resolution > 0 else None
        if self.cell_size is not None:
            early, self.early_poses = self.early_poses, {}
            for j, (topic, pose) in early.items():
                self.on_pose(j, topic, pose)
        if self.lockstep:
            self.try_lockstep()

    def on_pose(self, j: int, topic: str, msg: PoseWithCovarianceStamped) -> None:
        """A robot's pose, snapped to the grid."""
        if self.cell_size is None:  # decoded when /worksite/map_info gives the cell size
            self.early_poses[j] = (topic, msg)
            return
        pose = self._decode(topic, lambda: pose_to_grid(msg, self.cell_size, topic))
        if pose is not None:
            self.poses[j] = (self._now(), pose)
            self._stamped(f"pose{j}", msg)

    def on_heights(self, msg: Image) -> None:
        """The height map, in soil units."""
        topic = "/worksite/height_map"
        shape = self.zones.shape if self.zones is not None else None
        grid = self._decode(topic, lambda: image_to_grid(msg, "32FC1", topic, shape))
        if grid is not None:
            self.heights = (self._now(), heights_to_units(grid, self.height_unit))
            self._stamped("heights", msg)

    def on_goal(self, msg: Image) -> None:
        """Goal heights, in soil units."""
        grid = self._decode(
            "/blueprint/goal", lambda: image_to_grid(msg, "32FC1", "/blueprint/goal")
        )
        if grid is not None:
            self.goal = heights_to_units(grid, self.height_unit)
            if self.lockstep:
                self.try_lockstep()

    def on_zones(self, msg: Image) -> None:
        """Blueprint zones."""
        grid = self._decode(
            "/blueprint/zones", lambda: image_to_grid(msg, "mono8", "/blueprint/zones")
        )
        if grid is not None:
            self.zones = grid
            if self.lockstep:
                self.try_lockstep()

    def on_joint(self, msg: JointState) -> None:
        """Blade setting and load."""
        topic = "blade/joint_states"
        blade = self._decode(topic, lambda: blade_from_joint(msg, self.geometry, topic))
        if blade is not None:
            self.joint = (self._now(), blade)
            self._stamped("joint", msg)

    def on_stuck(self, msg: Bool) -> None:
        """U1 as the robot reports it."""
        self.stuck = (self._now(), bool(msg.data))
        self.fresh_stuck += 1
        if self.lockstep:
            self.try_lockstep()

    # --- decision ---------------------------------------------------------------------------

    def _age(self, stamp: Time) -> float:
        """Seconds since an input arrived (0 in lockstep mode).

        In lockstep mode stamps say what is fresh: a loaded machine may take longer than a
        timeout between two simulator ticks.
        """
        if self.lockstep:
            return 0.0
        return (self._now() - stamp).nanoseconds * 1e-9

    def missing_input(self) -> str | None:
        """Why the controller cannot act now, or ``None`` when every input is fresh."""
        if self.cell_size is None:
            return "no /worksite/map_info"
        if self.zones is None or self.goal is None:
            return "no blueprint (/blueprint/zones, /blueprint/goal)"
        if self.goal.shape != self.zones.shape:
            return "blueprint goal and zones differ in size"
        for j in range(self.n_robots):
            name = "own pose" if j == self.robot_id else f"pose of robot {j}"
            if j not in self.poses:
                return f"no {name}"
            if self._age(self.poses[j][0]) > self.pose_timeout:
                return f"{name} is stale ({self._age(self.poses[j][0]):.2f} s)"
        for name, value, limit in (
            ("height map", self.heights, self.map_timeout),
            ("blade joint state", self.joint, self.joint_timeout),
            ("stuck flag", self.stuck, self.joint_timeout),
        ):
            if value is None:
                return f"no {name}"
            if self._age(value[0]) > limit:
                return f"{name} is stale ({self._age(value[0]):.2f} s)"
        if self.heights[1].shape != self.zones.shape:
            return "height map and blueprint differ in size"
        row, col, _ = self.poses[self.robot_id][1]
        rows, cols = self.zones.shape
        if not (0 <= row < rows - 1 and 0 <= col < cols - 1):
            return f"own pose ({row}, {col}) is off the {rows} x {cols} worksite"
        window = self.heights[1][max(row - 2, 0) : row + 4, max(col - 2, 0) : col + 4]
        if (window == UNKNOWN).any():
            return "unknown terrain around the robot"
        return None

    def try_lockstep(self) -> None:
        """Lockstep mode: decide once per simulator tick, when every input of that tick is in.

        A tick's inputs are the poses, height map and joint state stamped with the same
        time, newer than the last tick decided, plus a stuck flag received since then. A
        complete set older than the last tick decided means the simulator's clock went
        back (it was restarted): the controller decides on it, as in a new trial.
        """
        keys = [f"pose{j}" for j in range(self.n_robots)] + ["heights", "joint"]
        stamps = {self.stamps.get(k) for k in keys}
        if len(stamps) != 1 or None in stamps or self.fresh_stuck == 0:
            return
        (stamp,) = stamps
        if self.decided_stamp is not None and stamp <= self.decided_stamp:
            if stamp == self.decided_stamp:
                return
            # Every input went back in time together: the simulator restarted (or its clock
            # jumped back). That is a new trial: start it with a clear memory bit.
            self.get_logger().warning(
                f"tick inputs went back in time ({self.decided_stamp} -> {stamp}): "
                "a new trial, memory cleared"
            )
            self.core.memory = 0
        if self.missing_input() is not None:
            return  # not ready (e.g. no blueprint yet): decided when the blueprint arrives
        self.decided_stamp = stamp
        self.fresh_stuck = 0
        self.tick(lockstep_decision=True)

    def tick(self, lockstep_decision: bool = False) -> None:
        """Decide and publish once (0 when an input is missing or stale).

        In lockstep mode the timer only refreshes diagnostics; commands go out once per
        simulator tick from :meth:`try_lockstep`.
        """
        if self.lockstep and not lockstep_decision:
            self.last_reason = self.missing_input() or self.last_reason
            self.publish_diagnostics()
            return
        reason = self.missing_input()
        mask = 0
        if reason is None:
            poses = np.array([self.poses[j][1] for j in range(self.n_robots)], dtype=np.int64)
            blade, volume = self.joint[1]
            mask = self.core.decide(
                self.heights[1],
                self.zones,
                self.goal,
                poses,
                self.robot_id,
                blade,
                volume,
                self.stuck[1],
            )
        self.last_reason, self.last_mask = reason, mask
        self.behaviour_pub.publish(UInt16(data=mask))
        self.publish_diagnostics()

    def publish_diagnostics(self) -> None:
        """OK when acting, WARN when holding still (with why), ERROR on malformed input."""
        status = DiagnosticStatus(
            name=f"{self.get_namespace().rstrip('/')}/controller",
            hardware_id=f"robot_{self.robot_id}",
        )
        if self.errors:
            status.level = DiagnosticStatus.ERROR
            status.message = "; ".join(self.errors.values())
        elif self.last_reason is not None:
            status.level = DiagnosticStatus.WARN
            status.message = f"holding still: {self.last_reason}"
        else:
            status.level = DiagnosticStatus.OK
            status.message = "acting"
        status.values = [
            KeyValue(key="controller", value=self.core.controller.name),
            KeyValue(key="behaviour", value=str(self.last_mask)),
            KeyValue(key="memory", value=str(self.core.memory)),
        ]
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = self._now().to_msg()
        self.diag_pub.publish(msg)


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
        controller = (
            Controller.hand_coded() if options.hand_coded else Controller.from_file(options.genome)
        )
    except GenomeFormatError as exc:
        print(f"controller: error: {exc}", file=sys.stderr)
        return 2
    return spin_node(lambda: ControllerNode(controller), argv)


if __name__ == "__main__":
    sys.exit(main())
