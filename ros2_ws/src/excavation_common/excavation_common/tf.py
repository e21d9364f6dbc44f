"""The suite's frame tree on ``/tf`` and ``/tf_static`` (tf2_msgs/TFMessage, REP 105 names).

Each transform is published by the node that knows it (docs/interfaces.md, "The frame
tree"):

* ``map`` -> ``robot_k/base_link`` on ``/tf`` with every pose, by the source of
  ``/robot_k/pose``: the localiser (the dome, full perception), else the simulator;
* ``robot_k/base_link`` -> ``robot_k/blade`` on ``/tf`` with every joint state, by the
  blade driver (:func:`blade_transform`);
* ``map`` -> ``overhead_camera`` on ``/tf_static``, by the localiser from its calibration;
* ``map`` -> ``overhead_laser`` on ``/tf`` with every mount state, by the terrain mapper.

QoS as tf2_ros uses it: ``/tf`` reliable, volatile, depth 100; ``/tf_static`` reliable,
transient local, depth 1, each static broadcaster sending all its transforms in one
message. A tf2 listener, RViz or Foxglove through a ROS bridge read them as they are;
:class:`FrameTree` composes a chain without tf2.

The transform builders and :class:`FrameTree` are pure; :class:`TfBroadcaster` takes a node.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
from geometry_msgs.msg import TransformStamped
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from tf2_msgs.msg import TFMessage

MAP = "map"
CAMERA = "overhead_camera"
LASER = "overhead_laser"

TF_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
"""QoS of ``/tf`` (tf2_ros's ``DynamicBroadcasterQoS``)."""

TF_STATIC_QOS = QoSProfile(
    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)
"""QoS of ``/tf_static`` (tf2_ros's ``StaticBroadcasterQoS``)."""


def base_frame(k: int) -> str:
    """Robot k's body frame, ``robot_k/base_link``."""
    return f"robot_{k}/base_link"


def blade_frame(k: int) -> str:
    """Robot k's blade frame, ``robot_k/blade``: at the blade's edge, axes as the body's."""
    return f"robot_{k}/blade"


def quaternion(rotation: np.ndarray) -> np.ndarray:
    """``(x, y, z, w)`` of a rotation matrix."""
    m = np.asarray(rotation, dtype=np.float64)
    w = math.sqrt(max(0.0, 1.0 + m[0, 0] + m[1, 1] + m[2, 2])) / 2
    x = math.copysign(math.sqrt(max(0.0, 1.0 + m[0, 0] - m[1, 1] - m[2, 2])) / 2, m[2, 1] - m[1, 2])
    y = math.copysign(math.sqrt(max(0.0, 1.0 - m[0, 0] + m[1, 1] - m[2, 2])) / 2, m[0, 2] - m[2, 0])
    z = math.copysign(math.sqrt(max(0.0, 1.0 - m[0, 0] - m[1, 1] + m[2, 2])) / 2, m[1, 0] - m[0, 1])
    return np.array([x, y, z, w])


def rotation(q) -> np.ndarray:
    """The rotation matrix of a quaternion ``(x, y, z, w)`` (normalised first)."""
    x, y, z, w = (float(v) for v in q)
    n = math.sqrt(x * x + y * y + z * z + w * w) or 1.0
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def transform(parent: str, child: str, translation, q, stamp=None) -> TransformStamped:
    """A ``TransformStamped`` of ``child`` in ``parent``: translation (m), quaternion xyzw."""
    t = TransformStamped()
    if stamp is not None:
        t.header.stamp = stamp
    t.header.frame_id = parent
    t.child_frame_id = child
    v = t.transform.translation
    v.x, v.y, v.z = (float(c) for c in translation)
    r = t.transform.rotation
    r.x, r.y, r.z, r.w = (float(c) for c in q)
    return t


def pose_transform(msg, child: str) -> TransformStamped:
    """The transform of a ``PoseWithCovarianceStamped`` (or ``PoseStamped``) as ``child``."""
    pose = msg.pose.pose if hasattr(msg.pose, "pose") else msg.pose
    p, o = pose.position, pose.orientation
    return transform(
        msg.header.frame_id, child, (p.x, p.y, p.z), (o.x, o.y, o.z, o.w), msg.header.stamp
    )


def robot_name(namespace: str) -> str:
    """The frame prefix of a node in a robot's namespace (``/robot_0`` -> ``robot_0``)."""
    return namespace.strip("/") or "robot"


def blade_transform(robot: str, position: float, reach: float, stamp=None) -> TransformStamped:
    """``robot``'s blade in its body: ``reach`` m ahead, at the joint ``position`` (m, up)."""
    return transform(
        f"{robot}/base_link", f"{robot}/blade", (reach, 0.0, position), (0, 0, 0, 1), stamp
    )


class FrameTree:
    """The latest transform of each child frame, composed along chains (no tf2 needed)."""

    def __init__(self) -> None:
        self.edges: dict[str, tuple[str, np.ndarray]] = {}

    def add(self, transforms: Iterable[TransformStamped]) -> None:
        """Keep each transform (a newer one of the same child replaces the older)."""
        for t in transforms:
            m = np.eye(4)
            r = t.transform.rotation
            m[:3, :3] = rotation((r.x, r.y, r.z, r.w))
            v = t.transform.translation
            m[:3, 3] = (v.x, v.y, v.z)
            self.edges[t.child_frame_id] = (t.header.frame_id, m)

    def lookup(self, target: str, source: str) -> np.ndarray | None:
        """The 4 x 4 pose of frame ``source`` in frame ``target``, or ``None`` (no chain).

        Only chains in which ``target`` is an ancestor of ``source`` (as tf2's
        ``lookup_transform(target, source)`` on a tree rooted at ``map``).
        """
        m, frame, seen = np.eye(4), source, set()
        while frame != target:
            if frame not in self.edges or frame in seen:
                return None
            seen.add(frame)
            parent, edge = self.edges[frame]
            m = edge @ m
            frame = parent
        return m


class TfBroadcaster:
    """``/tf`` (and, with ``static``, ``/tf_static``) writers of one node.

    As tf2_ros's two broadcasters; created at once, so a recorder or listener matches them
    before the first transform.
    """

    def __init__(self, node, static: bool = False) -> None:
        self.publisher = node.create_publisher(TFMessage, "/tf", TF_QOS)
        self.static_publisher = (
            node.create_publisher(TFMessage, "/tf_static", TF_STATIC_QOS) if static else None
        )
        self._statics: dict[str, TransformStamped] = {}

    def send(self, transforms: list[TransformStamped]) -> None:
        """Publish ``transforms`` on ``/tf``."""
        self.publisher.publish(TFMessage(transforms=list(transforms)))

    def send_static(self, transforms: list[TransformStamped]) -> None:
        """Publish ``transforms`` on ``/tf_static`` with every static sent before (latched).

        Raises:
            RuntimeError: The broadcaster was made without ``static``.
        """
        if self.static_publisher is None:
            raise RuntimeError("TfBroadcaster(static=False) sends no static transforms")
        for t in transforms:
            self._statics[t.child_frame_id] = t
        self.static_publisher.publish(TFMessage(transforms=list(self._statics.values())))
