"""``ant-operator``: the operator's command line for the team (there is no ros2cli here).

::

    ant-operator status                  # team state and every robot's
    ant-operator estop                   # latch the e-stop: every robot stops
    ant-operator reset                   # clear the e-stop (the team is then disarmed)
    ant-operator arm                     # allow motion
    ant-operator pause / resume          # stop every robot / carry on
    ant-operator disable 2 / enable 2    # take robot 2 out of the team / back in
    ant-operator drive 1 0.1 0.0 --for 2 # override robot 1's wheels for 2 s (10 Hz)
    ant-operator blade 1 0.05 --for 1    # override robot 1's blade set-point (m) for 1 s

Every command talks to the supervisor's services (``/supervisor/...``, ``--supervisor``) or
to a robot's override topic, on ``--domain`` (default ``ROS_DOMAIN_ID``) and, unless set
already, ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``. Exit codes: 0 done, 1 the supervisor
refused (its reason is printed), 2 bad arguments, 3 nobody answered within ``--timeout``
(no supervisor, or no node subscribes to the override topic). Behaviour of each command:
docs/operator.md. A ROS-level stop is not a safety function: the dome needs a hardware
e-stop on motor power.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

EXIT_OK, EXIT_REFUSED, EXIT_USAGE, EXIT_NO_ANSWER = 0, 1, 2, 3
OVERRIDE_RATE = 10.0
"""Hz at which ``drive`` and ``blade`` repeat their override."""

TRIGGERS = ("status", "estop", "reset", "arm", "pause", "resume")


class NoAnswer(Exception):
    """Nobody answered within the timeout (no supervisor, no subscriber)."""


class Operator:
    """A short-lived ROS node that sends one operator command.

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


def parser() -> argparse.ArgumentParser:
    """The ``ant-operator`` argument parser."""
    p = argparse.ArgumentParser(prog="ant-operator", description=__doc__.split("\n\n")[0])
    p.add_argument("--domain", type=int, default=None, help="ROS domain (default ROS_DOMAIN_ID)")
    p.add_argument(
        "--site",
        metavar="SITE",
        help="take the domain and discovery range from this site file (as ant-dome up does)",
    )
    p.add_argument("--supervisor", default="/supervisor", help="the supervisor node's name")
    p.add_argument("--timeout", type=float, default=5.0, help="s to wait for an answer")
    sub = p.add_subparsers(dest="command", required=True)
    for name in TRIGGERS:
        sub.add_parser(name, help=f"the supervisor's ~/{name}")
    for name in ("enable", "disable"):
        sub.add_parser(name, help=f"{name} one robot").add_argument("robot", type=int)
    drive = sub.add_parser("drive", help="override one robot's wheels (needs its executor)")
    drive.add_argument("robot", type=int)
    drive.add_argument("vx", type=float, help="forward speed, m/s")
    drive.add_argument("wz", type=float, help="turn rate, rad/s (counter-clockwise)")
    drive.add_argument("--for", dest="seconds", type=float, required=True, help="seconds")
    blade = sub.add_parser("blade", help="override one robot's blade set-point")
    blade.add_argument("robot", type=int)
    blade.add_argument("position", type=float, help="blade set-point, m (home 0.10)")
    blade.add_argument("--for", dest="seconds", type=float, default=1.0, help="seconds (1)")
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ant-operator``."""
    args = parser().parse_args(argv)
    if getattr(args, "seconds", 1.0) <= 0 or args.timeout <= 0:
        print("ant-operator: error: --for and --timeout must be > 0", file=sys.stderr)
        return EXIT_USAGE
    if getattr(args, "robot", 0) < 0:
        print(f"ant-operator: error: robot {args.robot}: must be >= 0", file=sys.stderr)
        return EXIT_USAGE
    if args.site:
        from excavation_common.errors import FieldError
        from excavation_common.network import use_site_network

        try:
            use_site_network(args.site)
        except FieldError as exc:
            print(f"ant-operator: error: {exc}", file=sys.stderr)
            return EXIT_USAGE
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    domain = args.domain if args.domain is not None else int(os.environ.get("ROS_DOMAIN_ID", "0"))
    op = Operator(domain, args.supervisor, args.timeout)
    try:
        if args.command in TRIGGERS:
            ok, message = op.trigger(args.command)
        elif args.command in ("enable", "disable"):
            ok, message = op.enable(args.robot, args.command == "enable")
        elif args.command == "drive":
            n = op.drive(args.robot, args.vx, args.wz, args.seconds)
            ok, message = True, f"robot {args.robot}: {n} drive overrides sent, the last one zero"
        else:
            n = op.blade(args.robot, args.position, args.seconds)
            ok, message = True, f"robot {args.robot}: {n} blade set-points {args.position:g} m sent"
    except NoAnswer as exc:
        print(f"ant-operator: error: {exc}", file=sys.stderr)
        return EXIT_NO_ANSWER
    except KeyboardInterrupt:
        return EXIT_REFUSED
    finally:
        op.close()
    if not ok:
        print(f"ant-operator: refused: {message}", file=sys.stderr)
        return EXIT_REFUSED
    print(message)
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
