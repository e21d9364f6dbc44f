"""Node-side helpers shared by the suite's nodes (this module imports rclpy; the core does not)."""

from __future__ import annotations

from collections.abc import Callable

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

LATCHED = QoSProfile(
    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)
"""QoS of latched maps (blueprint, map info, height map): reliable, transient local, depth 1."""


def spin_node(
    make_node: Callable[[], Node],
    args: list[str] | None = None,
    until: Callable[[Node], bool] | None = None,
) -> int:
    """Init rclpy, build the node, spin until shutdown (or ``until(node)``), clean up.

    Ctrl-C and external shutdown end it quietly; returns the exit code 0.
    """
    rclpy.init(args=args)
    node = make_node()
    try:
        if until is None:
            rclpy.spin(node)
        else:
            while rclpy.ok() and not until(node):
                rclpy.spin_once(node, timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


def diagnostics(
    node: Node,
    level: bytes,
    message: str,
    values: dict[str, object] | None = None,
    hardware_id: str = "",
) -> DiagnosticArray:
    """One ``/diagnostics`` array holding a single status named after ``node``.

    Args:
        node: The reporting node (its fully qualified name names the status).
        level: ``DiagnosticStatus.OK``, ``WARN``, ``ERROR`` or ``STALE``.
        message: What the node is doing, or what is wrong.
        values: Key/value details (converted with ``str``).
        hardware_id: The device behind the node, if any.
    """
    status = DiagnosticStatus(
        level=level,
        name=node.get_fully_qualified_name(),
        message=message,
        hardware_id=hardware_id,
        values=[KeyValue(key=k, value=str(v)) for k, v in (values or {}).items()],
    )
    msg = DiagnosticArray(status=[status])
    msg.header.stamp = node.get_clock().now().to_msg()
    return msg
