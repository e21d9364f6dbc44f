"""The operator's connection to the team: one ROS node that calls and streams.

It calls the supervisor's services and each robot's ``enable`` service and streams drive
and blade overrides; ``ant-operator``'s commands, its console and ``ant-dome`` use it.
"""

from __future__ import annotations

import os
import time

OVERRIDE_RATE = 10.0
"""Hz at which ``drive`` and ``blade`` repeat their override."""


class NoAnswer(Exception):
    """Nobody answered within the timeout (no supervisor, no subscriber)."""


class Operator:
    """A ROS node that sends operator commands (one per ``ant-operator`` run; the console's).

    Args:
        domain: ROS domain id.
        supervisor: Fully qualified name of the supervisor node.
        timeout: Seconds to wait for a service or a subscriber.
    """

    def __init__(self, domain: int, supervisor: str = "/supervisor", timeout: float = 5.0):
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor

        self.supervisor = "/" + supervisor.strip("/")
        self.timeout = timeout
        self.context = Context()
        from excavation_common.ros import init_rclpy

        init_rclpy(context=self.context, domain_id=domain)
        self.node = rclpy.create_node(f"ant_operator_{os.getpid()}", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)

    def close(self) -> None:
        """Destroy the node and shut the context down."""
        import rclpy

        self.executor.remove_node(self.node)
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)

    def announce(self, action: str, wait: float = 0.5) -> None:
        """Name ``action`` on ``/diagnostics`` (``last_control``): ``ant-dome``'s events log.

        Waits up to ``wait`` s for a reader (a short-lived process: nobody may be
        listening, which is not an error).
        """
        from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
        from rclpy.duration import Duration

        from excavation_common.ros import diagnostics

        pub = self.node.create_publisher(DiagnosticArray, "/diagnostics", 10)
        deadline = time.monotonic() + wait
        while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)
        values = {"controls": 1, "last_control": action}
        pub.publish(diagnostics(self.node, DiagnosticStatus.OK, action, values))
        pub.wait_for_all_acked(Duration(seconds=wait))

    def _call(self, kind, name: str, request):
        client = self.node.create_client(kind, name)
        try:
            if not client.wait_for_service(timeout_sec=self.timeout):
                raise NoAnswer(
                    f"no supervisor answers {name} within {self.timeout:g} s "
                    f"(ROS_DOMAIN_ID={self.context.get_domain_id()}; is the supervisor running?)"
                )
            future = client.call_async(request)
            self.executor.spin_until_future_complete(future, timeout_sec=self.timeout)
            if not future.done():
                raise NoAnswer(f"{name} did not answer within {self.timeout:g} s")
            return future.result()
        finally:
            self.node.destroy_client(client)

    def trigger(self, name: str) -> tuple[bool, str]:
        """Call ``SUPERVISOR/NAME`` (std_srvs/Trigger): ``(success, message)``."""
        from std_srvs.srv import Trigger

        reply = self._call(Trigger, f"{self.supervisor}/{name}", Trigger.Request())
        return bool(reply.success), str(reply.message)

    def enable(self, robot: int, on: bool) -> tuple[bool, str]:
        """Call ``/robot_K/enable`` (std_srvs/SetBool)."""
        from std_srvs.srv import SetBool

        reply = self._call(SetBool, f"/robot_{robot}/enable", SetBool.Request(data=on))
        return bool(reply.success), str(reply.message)

    def _stream(self, kind, topic: str, make, seconds: float, last=None) -> int:
        """Publish ``make()`` at :data:`OVERRIDE_RATE` for ``seconds``; returns messages sent."""
        pub = self.node.create_publisher(kind, topic, 10)
        deadline = time.monotonic() + self.timeout
        while pub.get_subscription_count() == 0:
            if time.monotonic() > deadline:
                raise NoAnswer(f"no node subscribes to {topic} within {self.timeout:g} s")
            self.executor.spin_once(timeout_sec=0.05)
        sent, end = 0, time.monotonic() + seconds
        while True:
            pub.publish(make())
            sent += 1
            if time.monotonic() + 1.0 / OVERRIDE_RATE > end:
                break
            time.sleep(1.0 / OVERRIDE_RATE)
        if last is not None:
            pub.publish(last())
            sent += 1
        # Every subscriber has the stream (reliable QoS) before the node goes: a fixed pause
        # here lost the last (zero) twist when this process was descheduled.
        from rclpy.duration import Duration

        pub.wait_for_all_acked(Duration(seconds=self.timeout))
        return sent

    def drive(self, robot: int, vx: float, wz: float, seconds: float) -> int:
        """``/robot_K/drive/override`` (TwistStamped) for ``seconds``, then one zero twist."""
        from geometry_msgs.msg import TwistStamped

        def twist(v: float, w: float):
            msg = TwistStamped()
            msg.header.stamp = self.node.get_clock().now().to_msg()
            msg.header.frame_id = f"robot_{robot}/base_link"
            msg.twist.linear.x, msg.twist.angular.z = float(v), float(w)
            return msg

        return self._stream(
            TwistStamped,
            f"/robot_{robot}/drive/override",
            lambda: twist(vx, wz),
            seconds,
            last=lambda: twist(0.0, 0.0),
        )

    def blade(self, robot: int, position: float, seconds: float) -> int:
        """``/robot_K/blade/commands`` (Float64MultiArray, one value) for ``seconds``."""
        from std_msgs.msg import Float64MultiArray

        return self._stream(
            Float64MultiArray,
            f"/robot_{robot}/blade/commands",
            lambda: Float64MultiArray(data=[float(position)]),
            seconds,
        )
