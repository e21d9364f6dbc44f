"""``ant-view``: a live view of the dome in Foxglove (foxglove-sdk WebSocket server).

Subscribes to the suite's topics and serves, on ``ws://127.0.0.1:8765`` by default (open it
in Foxglove: *Open connection* -> *Foxglove WebSocket*; the layout is
``config/foxglove_layout.json``):

==========================  ===============================  =================================
channel                     schema                           from
==========================  ===============================  =================================
``/view/robots``            foxglove.SceneUpdate             ``/robot_k/pose``: a box, an arrow
                                                             along the heading and the id
``/view/height_map``        foxglove.Grid (``height``, m)    ``/worksite/height_map``
``/view/blueprint``         foxglove.Grid (``goal``, m)      ``/blueprint/goal``
``/view/height_error``      foxglove.Grid (``error``, m)     height - goal over the dig cells
``/view/camera``            foxglove.CompressedImage         ``/overhead/image_annotated``
                                                             (the localizer's detected LEDs)
``/view/fitness``           JSON ``{fitness, mapped, ...}``  ``/worksite/fitness`` (simulator)
                                                             and the fitness of the mapped
                                                             heights against the blueprint
``/view/diagnostics``       foxglove.Log                     ``/diagnostics`` (changes only)
``/view/team``              JSON ``{team, robots: [...]}``   the team's state and, per robot,
                                                             enabled, driven by the operator,
                                                             stuck, its last word's behaviours
``/tf``                     foxglove.FrameTransforms         ``/tf`` and ``/tf_static``
                                                             (tf2_msgs/TFMessage): the
                                                             suite's frame tree as the nodes
                                                             publish it (:mod:`excavation_
                                                             common.tf`)
==========================  ===============================  =================================

The view is also a console (:mod:`excavation_bringup.view_control`): Foxglove's Call
Service panels reach the supervisor (``/operator/estop``, ``reset``, ``arm``, ``pause``,
``resume``, ``/operator/robot_K/enable``) and its Teleop panel drives a robot
(``/robot_K/drive/override``); off loopback only an e-stop is accepted without the
operator's token (``--operator-token``).

The latest robots, grids and transforms are sent again every ``--period`` seconds, so a
client that connects late sees the site at once (transforms only then: ``/tf`` comes in
bursts). ``--site`` gives the robots and the soil
unit. The server binds 127.0.0.1 unless ``--host`` says otherwise. ``ant-dome up --view``
starts it.

The message builders (:func:`robot_entities`, :func:`grid`, :func:`frame_transform`,
:func:`mapped_fitness`) are pure; :class:`ViewNode` is the ROS plumbing.
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from excavation_interfaces.msg import TeamState

from excavation_common.errors import FieldError

DIG = 1


def _stamp(sec: int, nanosec: int):
    from foxglove.messages import Timestamp

    return Timestamp(sec=int(sec), nsec=int(nanosec))


def _quat_z(yaw: float):
    from foxglove.messages import Quaternion

    return Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))


def robot_entities(poses: dict[int, tuple[float, float, float, int, int]], cell_size: float):
    """A ``SceneUpdate``: per robot ``k`` (``x, y, yaw, sec, nanosec``) a box, arrow and id."""
    from foxglove.messages import (
        ArrowPrimitive,
        Color,
        CubePrimitive,
        Pose,
        SceneEntity,
        SceneUpdate,
        TextPrimitive,
        Vector3,
    )

    entities = []
    for k, (x, y, yaw, sec, nanosec) in sorted(poses.items()):
        hue = (k * 0.27) % 1.0
        colour = Color(r=0.9, g=0.4 + 0.5 * hue, b=0.1 + 0.6 * (1 - hue), a=0.85)
        size = 2 * cell_size
        body = Pose(position=Vector3(x=x, y=y, z=0.5 * cell_size), orientation=_quat_z(yaw))
        tail = Pose(position=Vector3(x=x, y=y, z=1.05 * cell_size), orientation=_quat_z(yaw))
        label = Pose(position=Vector3(x=x, y=y, z=1.6 * cell_size), orientation=_quat_z(0.0))
        entities.append(
            SceneEntity(
                timestamp=_stamp(sec, nanosec),
                frame_id="map",
                id=f"robot_{k}",
                cubes=[
                    CubePrimitive(
                        pose=body, size=Vector3(x=size, y=size, z=cell_size), color=colour
                    )
                ],
                arrows=[
                    ArrowPrimitive(
                        pose=tail,
                        shaft_length=0.8 * cell_size,
                        shaft_diameter=0.12 * cell_size,
                        head_length=0.4 * cell_size,
                        head_diameter=0.3 * cell_size,
                        color=Color(r=1.0, g=1.0, b=1.0, a=1.0),
                    )
                ],
                texts=[
                    TextPrimitive(
                        pose=label,
                        billboard=True,
                        font_size=14.0,
                        scale_invariant=True,
                        color=Color(r=1.0, g=1.0, b=1.0, a=1.0),
                        text=f"robot_{k}",
                    )
                ],
            )
        )
    return SceneUpdate(entities=entities)


def grid(values: np.ndarray, cell_size: float, field: str, stamp=(0, 0)):
    """A ``Grid`` in ``map`` (row r at y = r * cell_size, column c at x) of float32 ``field``."""
    from foxglove.messages import (
        Grid,
        PackedElementField,
        PackedElementFieldNumericType,
        Pose,
        Quaternion,
        Vector2,
        Vector3,
    )

    arr = np.ascontiguousarray(values, dtype="<f4")
    rows, cols = arr.shape
    return Grid(
        timestamp=_stamp(*stamp),
        frame_id="map",
        pose=Pose(
            position=Vector3(x=0.0, y=0.0, z=0.0), orientation=Quaternion(x=0, y=0, z=0, w=1)
        ),
        column_count=cols,
        cell_size=Vector2(x=cell_size, y=cell_size),
        row_stride=cols * 4,
        cell_stride=4,
        fields=[
            PackedElementField(name=field, offset=0, type=PackedElementFieldNumericType.Float32)
        ],
        data=arr.tobytes(),
    )


def frame_transform(t):
    """A foxglove ``FrameTransform`` of a ``geometry_msgs/TransformStamped``."""
    from foxglove.messages import FrameTransform, Quaternion, Vector3

    v, r = t.transform.translation, t.transform.rotation
    return FrameTransform(
        timestamp=_stamp(t.header.stamp.sec, t.header.stamp.nanosec),
        parent_frame_id=t.header.frame_id,
        child_frame_id=t.child_frame_id,
        translation=Vector3(x=float(v.x), y=float(v.y), z=float(v.z)),
        rotation=Quaternion(x=float(r.x), y=float(r.y), z=float(r.z), w=float(r.w)),
    )


def mapped_fitness(heights_m: np.ndarray, goal_m: np.ndarray, height_unit: float) -> float | None:
    """The paper's fitness of mapped heights: mean ``exp(-2 |g - z|)`` over known dig cells.

    Heights and goal in metres, compared in whole soil units; ``None`` when no dig cell's
    height is known.
    """
    dig = np.isfinite(goal_m) & np.isfinite(heights_m)
    if not dig.any():
        return None
    diff = np.abs(goal_m[dig] - heights_m[dig]) / height_unit
    return float(np.mean(np.exp(-2.0 * np.round(diff))))


class ViewNode:
    """The ROS side of ``ant-view``: subscriptions in, foxglove channels out."""

    def __init__(self, robots: int, height_unit: float, period: float = 0.5, **kwargs) -> None:
        """Create the node (``kwargs`` go to ``rclpy.node.Node``) and the channels."""
        import foxglove.channels as ch
        from diagnostic_msgs.msg import DiagnosticArray
        from foxglove import Channel
        from geometry_msgs.msg import PoseWithCovarianceStamped
        from nav_msgs.msg import MapMetaData
        from rclpy.node import Node
        from sensor_msgs.msg import CompressedImage, Image
        from std_msgs.msg import Bool, Float32, UInt16
        from tf2_msgs.msg import TFMessage

        from excavation_common.ros import LATCHED, LATEST_FRAME
        from excavation_common.tf import TF_QOS, TF_STATIC_QOS

        self.node = node = Node("ant_view", **kwargs)
        self.n = robots
        self.transforms: dict = {}  # child frame -> its newest TransformStamped
        self.height_unit = height_unit
        self.cell_size = 0.25
        self.poses: dict[int, tuple[float, float, float, int, int]] = {}
        self.heights: np.ndarray | None = None
        self.goal: np.ndarray | None = None
        self.sim_fitness: float | None = None
        self.statuses: dict[str, tuple[int, str]] = {}
        self.sent = 0
        self.control = None  # the console's side (view_control.ViewControl), when served
        self.robots_ch = ch.SceneUpdateChannel("/view/robots")
        self.height_ch = ch.GridChannel("/view/height_map")
        self.goal_ch = ch.GridChannel("/view/blueprint")
        self.error_ch = ch.GridChannel("/view/height_error")
        self.camera_ch = ch.CompressedImageChannel("/view/camera")
        self.diag_ch = ch.LogChannel("/view/diagnostics")
        self.tf_ch = ch.FrameTransformsChannel("/tf")
        self.fitness_ch = Channel("/view/fitness", schema=FITNESS_SCHEMA)
        self.team_ch = Channel("/view/team", schema=TEAM_SCHEMA)
        self.team_state: str | None = None
        self.robot_state = [RobotState() for _ in range(robots)]
        for k in range(robots):
            state = self.robot_state[k]
            ns = f"/robot_{k}"
            node.create_subscription(
                Bool, f"{ns}/enabled", lambda m, s=state: setattr(s, "enabled", m.data), LATCHED
            )
            node.create_subscription(
                Bool, f"{ns}/drive/operator", lambda m, s=state: setattr(s, "operator", m.data),
                LATCHED,
            )  # fmt: skip
            node.create_subscription(
                Bool, f"{ns}/stuck", lambda m, s=state: setattr(s, "stuck", m.data), 10
            )
            node.create_subscription(
                UInt16, f"{ns}/behaviour", lambda m, s=state: setattr(s, "word", m.data), 10
            )
        node.create_subscription(TeamState, "/team/heartbeat", self.on_heartbeat, 10)
        for k in range(robots):
            node.create_subscription(
                PoseWithCovarianceStamped, f"/robot_{k}/pose", lambda m, k=k: self.on_pose(k, m), 10
            )
        node.create_subscription(Image, "/worksite/height_map", self.on_heights, LATCHED)
        node.create_subscription(Image, "/blueprint/goal", self.on_goal, LATCHED)
        node.create_subscription(MapMetaData, "/worksite/map_info", self.on_info, LATCHED)
        node.create_subscription(Float32, "/worksite/fitness", self.on_fitness, 10)
        node.create_subscription(
            CompressedImage, "/overhead/image_annotated", self.on_camera, LATEST_FRAME
        )
        node.create_subscription(DiagnosticArray, "/diagnostics", self.on_diagnostics, 50)
        node.create_subscription(TFMessage, "/tf", self.on_tf, TF_QOS)
        node.create_subscription(TFMessage, "/tf_static", self.on_tf, TF_STATIC_QOS)
        self.diag_pub = node.create_publisher(DiagnosticArray, "/diagnostics", 10)
        node.create_timer(period, self.republish)
        node.create_timer(1.0, self.publish_diagnostics)

    # --- inputs -----------------------------------------------------------------------------

    def on_pose(self, k: int, msg) -> None:
        """A robot's pose: the scene and its frame."""
        from terrain_mapper.geometry import yaw_of

        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        self.poses[k] = (p.x, p.y, yaw_of(q), msg.header.stamp.sec, msg.header.stamp.nanosec)
        self.publish_robots()

    def on_heartbeat(self, msg) -> None:
        """The team's state (the supervisor's heartbeat)."""
        self.team_state = msg.state

    def on_tf(self, msg) -> None:
        """Transforms from ``/tf`` or ``/tf_static``: the newest of each frame, kept.

        They go out with every ``--period`` (:meth:`republish`), not with each message: the
        mapper sends one per mount state and a sweep comes in bursts.
        """
        for t in msg.transforms:
            self.transforms[t.child_frame_id] = t

    def on_info(self, msg) -> None:
        """The cell size."""
        if msg.resolution > 0:
            self.cell_size = float(msg.resolution)

    def _grid(self, msg, what: str) -> np.ndarray | None:
        from excavation_common.messages import MessageError, image_to_grid

        try:
            return image_to_grid(msg, "32FC1", what)
        except MessageError as exc:
            self.node.get_logger().warning(str(exc), throttle_duration_sec=5.0)
            return None

    def on_heights(self, msg) -> None:
        """The height map: grid, error against the blueprint, mapped fitness."""
        self.heights = self._grid(msg, "/worksite/height_map")
        self.publish_grids()

    def on_goal(self, msg) -> None:
        """The blueprint's goal heights."""
        self.goal = self._grid(msg, "/blueprint/goal")
        self.publish_grids()

    def on_fitness(self, msg) -> None:
        """The simulator's fitness."""
        self.sim_fitness = float(msg.data)
        self.publish_fitness()

    def on_camera(self, msg) -> None:
        """The annotated camera frame, passed through."""
        from foxglove.messages import CompressedImage

        fmt = "png" if "png" in msg.format else "jpeg"
        stamp = _stamp(msg.header.stamp.sec, msg.header.stamp.nanosec)
        self.camera_ch.log(
            CompressedImage(
                timestamp=stamp, frame_id="overhead_camera", data=bytes(msg.data), format=fmt
            )
        )

    def on_diagnostics(self, msg) -> None:
        """Each status whose level or message changed, as a log line."""
        from foxglove.messages import Log, LogLevel

        levels = [LogLevel.Info, LogLevel.Warning, LogLevel.Error, LogLevel.Fatal]
        for s in msg.status:
            level = s.level[0] if isinstance(s.level, bytes) else int(s.level)
            if self.statuses.get(s.name) == (level, s.message):
                continue
            self.statuses[s.name] = (level, s.message)
            self.diag_ch.log(
                Log(
                    timestamp=_stamp(msg.header.stamp.sec, msg.header.stamp.nanosec),
                    level=levels[min(level, 3)],
                    message=s.message,
                    name=s.name,
                )
            )

    # --- outputs ----------------------------------------------------------------------------

    def publish_robots(self) -> None:
        """The robots' scene."""
        self.robots_ch.log(robot_entities(self.poses, self.cell_size))
        self.sent += 1

    def publish_frames(self) -> None:
        """Every frame the view has heard of (the newest transform of each)."""
        from foxglove.messages import FrameTransforms

        if self.transforms:
            frames = [frame_transform(t) for t in self.transforms.values()]
            self.tf_ch.log(FrameTransforms(transforms=frames))

    def publish_grids(self) -> None:
        """Height map, blueprint, their difference; the mapped fitness."""
        if self.heights is not None:
            self.height_ch.log(grid(self.heights, self.cell_size, "height"))
        if self.goal is not None:
            self.goal_ch.log(grid(self.goal, self.cell_size, "goal"))
        if (
            self.heights is not None
            and self.goal is not None
            and self.heights.shape == self.goal.shape
        ):
            self.error_ch.log(grid(self.heights - self.goal, self.cell_size, "error"))
        self.publish_fitness()

    def publish_fitness(self) -> None:
        """``{"fitness": simulator or null, "mapped": from the height map or null}``."""
        mapped = None
        if (
            self.heights is not None
            and self.goal is not None
            and self.heights.shape == self.goal.shape
        ):
            mapped = mapped_fitness(self.heights, self.goal, self.height_unit)
        self.fitness_ch.log({"fitness": self.sim_fitness, "mapped": mapped})

    def publish_team(self) -> None:
        """The team's state and each robot's (``/view/team``)."""
        self.team_ch.log(team_message(self.team_state, self.robot_state))

    def republish(self) -> None:
        """The latest state again, for clients that joined since."""
        self.publish_robots()
        self.publish_team()
        self.publish_frames()
        self.publish_grids()

    def publish_diagnostics(self) -> None:
        """The view's own status."""
        from diagnostic_msgs.msg import DiagnosticStatus

        from excavation_common.ros import diagnostics

        message = f"serving {len(self.poses)} robots" + (
            ", height map" if self.heights is not None else ""
        )
        values = {"updates": self.sent}
        if self.control is not None:
            values |= self.control.diagnostic_values()
        self.diag_pub.publish(diagnostics(self.node, DiagnosticStatus.OK, message, values))


@dataclass
class RobotState:
    """What the view last heard of one robot (``None``: nothing yet)."""

    enabled: bool | None = None
    operator: bool | None = None
    stuck: bool | None = None
    word: int | None = None


def team_message(team: str | None, robots: list[RobotState]) -> dict:
    """``/view/team``: the team's state and one row per robot."""
    from excavation_common.behaviour import behaviour_names

    return {
        "team": team or "no heartbeat",
        "robots": [
            {
                "robot": k,
                "enabled": r.enabled,
                "operator": r.operator,
                "stuck": r.stuck,
                "word": None if r.word is None else " + ".join(behaviour_names(r.word)) or "idle",
            }
            for k, r in enumerate(robots)
        ],
    }


TEAM_SCHEMA = {
    "type": "object",
    "properties": {
        "team": {"type": "string", "description": "the supervisor's team state"},
        "robots": {"type": "array", "items": {"type": "object"}},
    },
}
"""JSON schema of ``/view/team``."""

FITNESS_SCHEMA = {
    "type": "object",
    "properties": {
        "fitness": {"type": ["number", "null"], "description": "the simulator's fitness"},
        "mapped": {"type": ["number", "null"], "description": "mapped heights vs the blueprint"},
    },
}
"""JSON schema of ``/view/fitness``."""


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ant-view``."""
    import foxglove
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.utilities import remove_ros_args

    argv = sys.argv[1:] if argv is None else argv
    p = argparse.ArgumentParser(prog="ant-view", description=__doc__.split("\n\n")[0])
    p.add_argument("--site", metavar="SITE", help="site file: robots and soil unit")
    p.add_argument("--robots", type=int, default=None, help="default: the site's, else 4")
    p.add_argument("--host", default="127.0.0.1", help="address to serve on (default loopback)")
    p.add_argument("--port", type=int, default=8765)
    p.add_argument("--period", type=float, default=0.5, help="s between repeats of the state")
    p.add_argument(
        "--operator-token",
        default=None,
        help='served off loopback: the token a client gives ("token" in the request) to '
        "call any service but the e-stop",
    )
    p.add_argument("--supervisor", default="/supervisor", help="the supervisor node's name")
    p.add_argument(
        "--hardware",
        choices=("sim", "dome", "emulated"),
        default=None,
        help="what runs the site: ant-dome up --sim (sim), the dome (dome) or a rehearsal's "
        "emulated drivers (emulated); default: sim when the site's camera is the simulator's",
    )
    args = p.parse_args(remove_ros_args(["ant-view", *argv])[1:])
    site = None
    try:
        if args.site:
            site = view_site(args.site, args.hardware)
    except FieldError as exc:
        print(f"ant-view: error: {exc}", file=sys.stderr)
        return 2
    robots = args.robots or (site.n_robots if site is not None else 4)
    unit = site.worksite.soil_unit if site is not None else 0.05
    from excavation_bringup.view_control import ControlPolicy, ViewControl
    from excavation_common.ros import init_rclpy

    init_rclpy(args=["ant-view", *argv])
    view = ViewNode(robots, unit, args.period)
    view.control = ViewControl(
        view.node, robots, ControlPolicy(args.host, args.operator_token), args.supervisor
    )
    server = foxglove.start_server(
        name="ant-view",
        host=args.host,
        port=args.port,
        capabilities=[foxglove.Capability.Services, foxglove.Capability.ClientPublish],
        supported_encodings=["json"],
        server_listener=view.control.listener(),
        services=view.control.services(),
    )
    print(
        f"ant-view: serving ws://{args.host}:{server.port} (Foxglove: open connection)", flush=True
    )
    try:
        rclpy.spin(view.node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        view.node.destroy_node()
        rclpy.try_shutdown()
        server.stop()
    return 0


def view_site(path: str, hardware: str | None):
    """The site the view shows, checked for what runs it (``hardware``, else guessed).

    A rehearsal (``emulated``) keeps the dome's camera (a compressed stream, say), which a
    ``--sim`` check would refuse; ``ant-dome`` always says which it runs.

    Raises:
        excavation_bringup.site.SiteError: The first problem the check finds.
    """
    from excavation_bringup.site import load_site

    if hardware is None:
        hardware = "sim" if _simulated(path) else "dome"
    return load_site(path, sim=hardware == "sim", emulated=hardware == "emulated")


def _simulated(path: str) -> bool:
    """True when the site's camera is the simulator's (its calibration is written at bring-up)."""
    from excavation_bringup.site import SIMULATED, parse_site

    site, _ = parse_site(Path(path).read_text(encoding="utf-8"), path)
    return site is not None and site.camera.calibration == SIMULATED


if __name__ == "__main__":
    sys.exit(main())
