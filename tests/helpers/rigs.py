"""Node rigs shared by tests: a lockstep controller node, and the mapper rig.

:func:`controller_node` adds robot k's controller (lockstep, as in every trial) to the
``ros`` fixture's executor (``tests/conftest.py``). :class:`MapperRig` is a mapper node and
a probe that feeds it laser scans and mount states, shared by the mapper node's tests and
the mount synchronisation's tests.
"""

from __future__ import annotations

from typing import Any

from excavation_sim.laser import LaserParams

LASER = LaserParams(sweep_scans=16)
"""The rig's laser: the default one, sweeps of 16 scans."""

EPOCH_S = 100
"""Sim second that :meth:`MapperRig.mount` and :meth:`MapperRig.scan` count from."""


def controller_node(ros, k: int, robots: int, controller=None, **params: Any):
    """Robot ``k``'s controller node of a team of ``robots``, lockstep, added to ``ros``.

    ``controller``: an ``ant_controller.controller.Controller`` (default: the hand-coded
    rules); ``params``: further node parameters.
    """
    from rclpy.parameter import Parameter

    from ant_controller.controller import Controller
    from ant_controller.controller_node import ControllerNode

    values = {"robot_id": k, "robots": robots, "lockstep": True} | params
    return ros.add(
        ControllerNode(
            controller if controller is not None else Controller.hand_coded(),
            context=ros.context,
            namespace=f"/robot_{k}",
            parameter_overrides=[Parameter(n, value=v) for n, v in values.items()],
        )
    )


class MapperRig:
    """A mapper node (sweeps of 16 scans, no robots, reliable QoS, diagnostics every
    0.1 s) and a probe node publishing scans and mount states to it.

    Attributes:
        mapper: The :class:`~terrain_mapper.mapper_node.MapperNode`.
        node: The probe node.
        maps: Height maps the mapper published (``/worksite/height_map``), in order.
        status: The mapper's latest ``/diagnostics`` status (None before the first).
    """

    def __init__(self, ros, mount_wait: float | None = None, wait: float = 10.0, **params):
        """Start both nodes; wait (up to ``wait`` s) until the mapper subscribes to both
        of the probe's topics.

        Args:
            ros: The ``ros`` fixture.
            mount_wait: The mapper's ``mount_wait`` (its own default unless given).
            wait: Longest wait for the subscriptions, seconds (not asserted on).
            params: Further mapper parameters (they win over the rig's).
        """
        from rclpy.node import Node
        from rclpy.parameter import Parameter
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import Image, JointState, LaserScan

        from excavation_common.ros import LATCHED
        from helpers.diagnostics import DiagnosticsProbe
        from terrain_mapper.mapper_node import MOUNT_TOPIC, SCAN_TOPIC, MapperNode

        settings = dict(
            robots=0, sweep_scans=LASER.sweep_scans, reliable=True, diagnostics_period=0.1
        )
        if mount_wait is not None:
            settings["mount_wait"] = mount_wait
        settings.update(params)
        overrides = [Parameter(k, value=v) for k, v in settings.items()]
        self.ros = ros
        self.mapper = ros.add(MapperNode(context=ros.context, parameter_overrides=overrides))
        node = self.node = ros.add(Node("probe", context=ros.context))
        qos = QoSProfile(depth=200, reliability=ReliabilityPolicy.RELIABLE)
        self.scan_pub = node.create_publisher(LaserScan, SCAN_TOPIC, qos)
        self.mount_pub = node.create_publisher(JointState, MOUNT_TOPIC, qos)
        self.maps: list[Image] = []
        node.create_subscription(Image, "/worksite/height_map", self.maps.append, LATCHED)
        self.diagnostics = DiagnosticsProbe(node)
        ros.spin_until(
            lambda: (
                self.scan_pub.get_subscription_count() > 0
                and self.mount_pub.get_subscription_count() > 0
            ),
            wait,
        )

    @property
    def status(self):
        """The mapper's latest status."""
        return self.diagnostics.latest.get("/mapper")

    @staticmethod
    def _mount_msg(stamp, tilt: float, joints=None):
        from sensor_msgs.msg import JointState

        from terrain_mapper.geometry import PAN_JOINT, TILT_JOINT

        joints = (PAN_JOINT, TILT_JOINT) if joints is None else joints
        msg = JointState(name=list(joints), position=[0.0, tilt][: len(joints)])
        msg.header.stamp = stamp
        return msg

    @staticmethod
    def _scan_msg(stamp, ranges, n: int | None = None):
        from sensor_msgs.msg import LaserScan

        msg = LaserScan()
        msg.header.stamp = stamp
        msg.angle_min, msg.angle_max = LASER.angle_min, LASER.angle_max
        msg.angle_increment = LASER.angle_increment
        msg.range_min, msg.range_max = LASER.range_min, LASER.range_max
        msg.ranges = [float(r) for r in ranges][:n]
        return msg

    def send(self, sec: int, ranges, tilt: float, joints=None, n: int | None = None) -> None:
        """Publish a mount state (pan 0, ``tilt``) and a scan, both stamped ``sec``.

        Args:
            sec: The stamp, whole seconds.
            ranges: The scan's ranges.
            tilt: The mount's tilt (rad).
            joints: The mount state's joint names (pan and tilt unless given; with one
                name, only the pan is sent).
            n: Send only the first ``n`` ranges (a malformed scan).
        """
        from builtin_interfaces.msg import Time

        stamp = Time(sec=sec, nanosec=0)
        self.mount_pub.publish(self._mount_msg(stamp, tilt, joints))
        self.scan_pub.publish(self._scan_msg(stamp, ranges, n))

    def sweep(self, sec0: int, heights, rng) -> None:
        """Scan ``heights`` (metres) with the rig's laser: scan ``i`` stamped ``sec0 + i``."""
        from excavation_sim.laser import OverheadLaser

        laser = OverheadLaser(LASER, 0.25)
        for i, (_, tilt, ranges) in enumerate(laser.sweep(heights, rng)):
            self.send(sec0 + i, ranges, tilt)

    @staticmethod
    def stamp(t_ns: int):
        """The stamp ``t_ns`` nanoseconds after :data:`EPOCH_S`."""
        from builtin_interfaces.msg import Time

        return Time(sec=EPOCH_S + t_ns // 10**9, nanosec=t_ns % 10**9)

    def mount(self, t_ns: int, tilt: float) -> None:
        """Publish a mount state (pan 0, ``tilt``) stamped :meth:`stamp` (``t_ns``)."""
        self.mount_pub.publish(self._mount_msg(self.stamp(t_ns), tilt))

    def scan(self, t_ns: int, ranges) -> None:
        """Publish a scan stamped :meth:`stamp` (``t_ns``)."""
        self.scan_pub.publish(self._scan_msg(self.stamp(t_ns), ranges))

    def reported(self, level, text: str):
        """A condition: the mapper's latest status is at ``level`` and says ``text``."""
        return lambda: (
            self.status is not None and self.status.level == level and (text in self.status.message)
        )
