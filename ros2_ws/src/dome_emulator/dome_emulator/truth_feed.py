"""The emulated sensors' subscriptions to the world's truth (the ROS side of :mod:`.truth`).

The camera and the laser emulators both render the world as it is now: each keeps a
:class:`~dome_emulator.truth.Truth` up to date from ``dynamics``' topics through a
:class:`TruthFeed`, and reports its :attr:`TruthFeed.problem` on ``/diagnostics``.
"""

from __future__ import annotations

from geometry_msgs.msg import PoseWithCovarianceStamped
from rclpy.node import Node
from sensor_msgs.msg import Image

from dome_emulator.errors import TruthError
from dome_emulator.truth import Truth, yaw_of
from excavation_common.messages import MessageError, image_to_grid
from excavation_common.ros import LATCHED, LATEST_STATE


class TruthFeed:
    """Keeps ``truth`` up to date from the truth topics of ``node``'s graph.

    Subscribes ``{prefix}/robot_k/pose`` (PoseWithCovarianceStamped, k < ``robots``) and
    ``{prefix}/worksite/height_map`` (Image ``32FC1``, metres, latched). A bad message
    changes nothing in ``truth`` and leaves its error in :attr:`problem` (a good height map
    clears it).
    """

    def __init__(self, node: Node, truth: Truth, prefix: str, robots: int) -> None:
        self.node = node
        self.truth = truth
        self.problem = ""
        prefix = prefix.rstrip("/")
        for k in range(robots):
            node.create_subscription(
                PoseWithCovarianceStamped,
                f"{prefix}/robot_{k}/pose",
                lambda m, k=k: self.on_pose(k, m),
                LATEST_STATE,
            )
        self.heights_topic = f"{prefix}/worksite/height_map"
        node.create_subscription(Image, self.heights_topic, self.on_heights, LATCHED)

    def on_pose(self, k: int, msg: PoseWithCovarianceStamped) -> None:
        """Robot k's pose in the world."""
        pos, q = msg.pose.pose.position, msg.pose.pose.orientation
        try:
            self.truth.set_pose(k, pos.x, pos.y, yaw_of(q.x, q.y, q.z, q.w), f"robot_{k}")
        except TruthError as exc:
            self.problem = str(exc)

    def on_heights(self, msg: Image) -> None:
        """The world's height map (metres)."""
        try:
            grid = image_to_grid(msg, "32FC1", self.heights_topic)
            self.truth.set_heights(grid, self.heights_topic)
        except (MessageError, TruthError) as exc:
            self.problem = str(exc)
            self.node.get_logger().warning(self.problem, throttle_duration_sec=5.0)
            return
        self.problem = ""
