"""``ros2 run dome_emulator base``: one robot's differential-drive base, emulated.

Stands in for a dome robot's base running Jazzy's ros2_control ``diff_drive_controller``
(the rules and where they come from: :mod:`dome_emulator.base`), and drives the simulated
world in its place. Run one per robot in the robot's namespace, its world topics remapped
onto the simulator's (here with the simulator's IMU moved to ``/sim``)::

    ros2 run dome_emulator base --ros-args -r __ns:=/robot_0 -r cmd_vel:=base/cmd_vel
      -r world/cmd_vel:=/robot_0/cmd_vel -r world/imu:=/sim/robot_0/imu

Subscribes ``cmd_vel`` (geometry_msgs/TwistStamped, or Twist with ``drive_type: twist``:
the drive executor's output, the site's ``drive_topic``) and, with ``publish_imu``,
``world/imu`` (sensor_msgs/Imu: the simulated world's IMU of this robot, ``dynamics``'
``/robot_k/imu``).

Publishes, every update (``update_rate``, node clock): ``world/cmd_vel`` (TwistStamped,
the limited command stamped with the node clock: the command input of the simulated world,
``dynamics``' ``/robot_k/cmd_vel``, which takes any command stamped at or after its
current step as that step's answer); at ``publish_rate`` ``odom`` (nav_msgs/Odometry, the
wheels' odometry, frames ``<prefix>odom`` -> ``<prefix>base_link``); with
``publish_limited_velocity`` ``cmd_vel_out`` (TwistStamped); with ``publish_imu`` ``imu``
(the world's reading, stamped with the node clock and framed ``<prefix>base_link``); and
``/diagnostics`` (OK while commands come, WARN while braking for a timed-out command or
after ignoring stale ones; values: commands, ignored, timeouts, the limited command, the
odometry pose).
"""

from __future__ import annotations

import math
import sys

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.time import Time
from sensor_msgs.msg import Imu

from dome_emulator.base import (
    STAMPED,
    Accepted,
    BaseParams,
    Braking,
    DiffDriveCore,
    Forward,
    Ignored,
    PublishLimited,
    PublishOdometry,
)
from excavation_common.ros import declare_params, diagnostics, spin_node


def frame_prefix(params: BaseParams, namespace: str) -> str:
    """The frames' prefix as the controller forms it: ``robot_0/`` in ``/robot_0``."""
    if not params.tf_frame_prefix_enable:
        return ""
    prefix = params.tf_frame_prefix or namespace
    prefix = prefix.lstrip("/")
    if prefix and not prefix.endswith("/"):
        prefix += "/"
    return prefix


class BaseNode(Node):
    """Thin ROS plumbing around :class:`DiffDriveCore`."""

    def __init__(self, **kwargs) -> None:
        super().__init__("base", **kwargs)
        self.params = p = declare_params(self, BaseParams)
        self.core = DiffDriveCore(p, self.now_ns())
        prefix = frame_prefix(p, self.get_namespace())
        self.odom_frame = prefix + p.odom_frame_id
        self.base_frame = prefix + p.base_frame_id
        self.problem = ""
        self.last_ignored_age = 0.0
        self.ignored_reported = 0  # ignored commands already in a diagnostics message
        if p.drive_type == STAMPED:
            self.create_subscription(TwistStamped, "cmd_vel", self.on_stamped, 10)
        else:
            self.create_subscription(Twist, "cmd_vel", self.on_twist, 10)
        self.world_pub = self.create_publisher(TwistStamped, "world/cmd_vel", 10)
        self.odom_pub = self.create_publisher(Odometry, "odom", 10)
        self.limited_pub = (
            self.create_publisher(TwistStamped, "cmd_vel_out", 10)
            if p.publish_limited_velocity
            else None
        )
        self.imu_pub = None
        if p.publish_imu:
            self.imu_pub = self.create_publisher(Imu, "imu", 10)
            self.create_subscription(Imu, "world/imu", self.on_world_imu, 10)
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.create_timer(1.0 / p.update_rate, self.update)
        self.create_timer(p.diagnostics_period, self.publish_diagnostics)

    def now_ns(self) -> int:
        """The node clock, nanoseconds."""
        return self.get_clock().now().nanoseconds

    def on_stamped(self, msg: TwistStamped) -> None:
        """A TwistStamped: its stamp is the command's age (Jazzy)."""
        stamp = Time.from_msg(msg.header.stamp).nanoseconds
        self.take(msg.twist, stamp)

    def on_twist(self, msg: Twist) -> None:
        """A Twist: stamped on arrival."""
        self.take(msg, None)

    def take(self, twist: Twist, stamp_ns: int | None) -> None:
        """Hand a command to the core; say so when it is ignored for its age."""
        match self.core.receive(twist.linear.x, twist.angular.z, stamp_ns, self.now_ns()):
            case Ignored(age):
                self.last_ignored_age = age
                self.get_logger().warning(
                    f"ignoring a cmd_vel {age:.3f} s older than the node clock (cmd_vel_timeout "
                    f"{self.params.cmd_vel_timeout} s)",
                    throttle_duration_sec=1.0,
                )
            case Accepted():
                pass

    def update(self) -> None:
        """One controller update: send what the core decides, in its order."""
        now = self.get_clock().now()
        stamp = now.to_msg()
        for action in self.core.update(now.nanoseconds):
            match action:
                case Forward(linear, angular):
                    self.world_pub.publish(self.twist(linear, angular, stamp))
                case PublishOdometry():
                    self.odom_pub.publish(self.odometry(action, stamp))
                case PublishLimited(linear, angular):
                    self.limited_pub.publish(self.twist(linear, angular, stamp))
                case Braking(received=False):
                    self.get_logger().info("no velocity command yet: wheels held still")
                case Braking(age, moving=False):
                    self.get_logger().debug(f"zero twist {age:.3f} s old: wheels held still")
                case Braking(age):
                    self.get_logger().warning(
                        f"velocity command timed out ({age:.3f} s old): braking"
                    )

    def twist(self, linear: float, angular: float, stamp) -> TwistStamped:
        """A TwistStamped in the base frame."""
        msg = TwistStamped()
        msg.header.stamp = stamp
        msg.header.frame_id = self.base_frame
        msg.twist.linear.x = float(linear)
        msg.twist.angular.z = float(angular)
        return msg

    def odometry(self, o: PublishOdometry, stamp) -> Odometry:
        """The odometry message of the core's pose and velocity."""
        msg = Odometry()
        msg.header.stamp = stamp
        msg.header.frame_id = self.odom_frame
        msg.child_frame_id = self.base_frame
        msg.pose.pose.position.x = o.x
        msg.pose.pose.position.y = o.y
        msg.pose.pose.orientation.z = math.sin(o.yaw / 2)
        msg.pose.pose.orientation.w = math.cos(o.yaw / 2)
        msg.twist.twist.linear.x = o.linear
        msg.twist.twist.angular.z = o.angular
        pose_cov, twist_cov = [0.0] * 36, [0.0] * 36
        for i in range(6):
            pose_cov[7 * i] = self.params.pose_covariance_diagonal[i]
            twist_cov[7 * i] = self.params.twist_covariance_diagonal[i]
        msg.pose.covariance = pose_cov
        msg.twist.covariance = twist_cov
        return msg

    def on_world_imu(self, msg: Imu) -> None:
        """The world's IMU of this robot, as the base's IMU reports it."""
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = self.base_frame
        self.imu_pub.publish(msg)

    def publish_diagnostics(self) -> None:
        """OK while driving or idle; WARN while braking or after ignoring stale commands.

        An ignored command is reported once, in the next diagnostics message.
        """
        c = self.core
        parts = []
        if c.braking:
            parts.append("cmd_vel timed out: braking")
        if c.ignored > self.ignored_reported:
            parts.append(
                f"ignored {c.ignored - self.ignored_reported} stale cmd_vel (the last "
                f"{self.last_ignored_age:.3f} s older than the node clock)"
            )
        level = DiagnosticStatus.WARN if parts else DiagnosticStatus.OK
        if not parts:
            parts.append("driving" if c.received else "no cmd_vel yet")
        message = "; ".join(parts)
        o = c.odometry
        values = {
            "drive_type": self.params.drive_type,
            "commands": c.received,
            "ignored": c.ignored,
            "not_finite": c.not_finite,
            "timeouts": c.timeouts,
            "linear": f"{c.previous[0]:.4f}",
            "angular": f"{c.previous[1]:.4f}",
            "odom": f"{o.x:.3f} {o.y:.3f} {o.yaw:.3f}",
        }
        self.ignored_reported = c.ignored
        self.diag_pub.publish(diagnostics(self, level, message, values, hardware_id="base"))


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run dome_emulator base``."""
    return spin_node(BaseNode, args)


if __name__ == "__main__":
    sys.exit(main())
