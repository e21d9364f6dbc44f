"""A stand-in for the team supervisor in ``ant-trial``, until ``team_supervisor`` is wired in.

:func:`always_armed_team_state` is the one place that does it: it latches "no e-stop" on
``/team/estop`` and "enabled" on every ``/robot_k/enabled``, and sends an ``armed``
heartbeat at 10 Hz on the node clock (sim time in a trial), so the executors' gates open.
It has no e-stop, pause or per-robot control: a trial that needs those starts the
supervisor instead.
"""

from __future__ import annotations

from rclpy.node import Node
from std_msgs.msg import Bool, Header

from excavation_common.ros import LATCHED
from excavation_common.safety import ARMED, ENABLED_TOPIC, ESTOP_TOPIC, HEARTBEAT_TOPIC

HEARTBEAT_PERIOD = 0.1
"""Seconds between heartbeats (the supervisor's 10 Hz)."""


def always_armed_team_state(robots: int, **node_kwargs) -> Node:
    """A node that keeps the whole team armed and enabled (no supervisor in the trial).

    Args:
        robots: Number of robots (``/robot_0/enabled`` .. ``/robot_{n-1}/enabled``).
        node_kwargs: Passed to ``Node`` (``context``, ``parameter_overrides`` such as
            ``use_sim_time``).
    """
    node = Node("always_armed_team_state", **node_kwargs)
    estop = node.create_publisher(Bool, ESTOP_TOPIC, LATCHED)
    estop.publish(Bool(data=False))
    node._enabled = []  # keep the latched publishers alive with the node
    for k in range(robots):
        pub = node.create_publisher(Bool, f"/robot_{k}/{ENABLED_TOPIC}", LATCHED)
        pub.publish(Bool(data=True))
        node._enabled.append(pub)
    heartbeat = node.create_publisher(Header, HEARTBEAT_TOPIC, 10)

    def beat() -> None:
        heartbeat.publish(Header(stamp=node.get_clock().now().to_msg(), frame_id=ARMED))

    node.create_timer(HEARTBEAT_PERIOD, beat)
    return node
