"""A differential-drive base as Jazzy's ros2_control ``diff_drive_controller`` runs it (pure).

:class:`DiffDriveCore` is the controller's logic without ``rclpy``: the node
(:mod:`dome_emulator.base_node`) hands it every ``cmd_vel`` and calls :meth:`update` at the
controller manager's ``update_rate``; it returns what to send as small frozen dataclasses.
The rules, as ros2_controllers' ``diff_drive_controller`` (branch ``jazzy``) implements them
in ``diff_drive_controller/src/diff_drive_controller.cpp``:

* **Input.** Jazzy takes ``geometry_msgs/TwistStamped`` only on ``~/cmd_vel``
  (``doc/release_notes.rst``: "The twist message on ``~/cmd_vel`` is now required to be of
  stamped type", PR 812; the Humble parameter ``use_stamped_vel`` is gone). A base whose
  vendor driver takes ``geometry_msgs/Twist`` is emulated with ``drive_type: twist``: such a
  command is stamped with the node clock when it arrives, as Humble's
  ``~/cmd_vel_unstamped`` subscription did.
* **Stamps on arrival.** A TwistStamped with a zero stamp is stamped with the node clock
  ("Received TwistStamped with zero timestamp, setting it to current time"); one whose
  stamp is ``cmd_vel_timeout`` or more older than the node clock is ignored ("Ignoring the
  received message ... because it is older than the current time by ... seconds, which
  exceeds the allowed timeout"). A ``cmd_vel_timeout`` of 0 disables both age checks.
* **Stamps at each update** (``update_reference_from_subscribers``). The latest command
  whose age (now minus its stamp) exceeds ``cmd_vel_timeout`` is replaced by zero ("Velocity
  command timed out. Braking."); a command with a NaN or infinite component leaves the
  reference at its previous value. The emulator warns only when a command asking for
  motion lapses: the start-up zero twist lapsing is said once at INFO, a zero twist (a
  driver that stopped between goals) only at DEBUG.
* **Limits** (``update_and_write_commands``). The reference then goes through one
  ``SpeedLimiter`` per axis, control_toolbox's ``RateLimiter`` (``rate_limiter.hpp``):
  first the jerk (not emulated here), then the acceleration with the previous command as
  ``v0`` (forward ``[max_deceleration, max_acceleration] dt`` while ``v0 > 0``; reverse
  ``[max_acceleration_reverse, max_deceleration_reverse] dt`` while ``v0 < 0``; from
  standstill ``[max_acceleration_reverse, max_acceleration] dt``; an unset ``*_reverse`` or
  ``max_deceleration`` takes RateLimiter's default), then the velocity clamp
  ``[min_velocity, max_velocity]``. So a timed-out command brakes at the deceleration limit.
* **Odometry.** ``Odometry::integrateExact`` (second-order Runge-Kutta for an angle below
  1e-6 rad) over each update's period, published at ``publish_rate`` by the controller's own
  rule (``previous_publish_timestamp + publish_period < time``). The emulated wheels follow
  their command exactly, so the odometry integrates the command the wheels ran during the
  period (what wheel encoders would give), not the simulated world's slip: it drifts from
  the world's truth as a real base's does.

``cmd_vel_timeout`` defaults to the dome's 0.25 s (docs/field.md, "Connecting a real robot
base"), not the controller's 0.5 s. Limits are finite parameters (``excavation_common.params``
refuses NaN): where the real controller leaves a limit unset (``.NAN``), give a large value.
``max_deceleration``, ``max_acceleration_reverse`` and ``max_deceleration_reverse`` of 0 mean
unset.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from excavation_common.params import param

STAMPED = "twist_stamped"
UNSTAMPED = "twist"


@dataclass(frozen=True)
class BaseParams:
    """The emulated base's parameters (``diff_drive_controller``'s names in descriptions)."""

    drive_type: str = param(
        STAMPED,
        "cmd_vel's type: twist_stamped (geometry_msgs/TwistStamped, Jazzy's "
        "diff_drive_controller) or twist (geometry_msgs/Twist, stamped on arrival)",
        choices=(UNSTAMPED, STAMPED),
    )
    update_rate: float = param(
        50.0, "controller update rate, Hz (the controller manager's)", low=1.0, high=1000.0
    )
    publish_rate: float = param(50.0, "odometry publishing rate, Hz", low=0.1, high=1000.0)
    cmd_vel_timeout: float = param(
        0.25,
        "s: a cmd_vel this much older than the node clock is ignored, and zeroed once it ages "
        "past it (0: never; the dome's 0.25 s, diff_drive_controller's default is 0.5 s)",
        low=0.0,
        high=60.0,
    )
    linear_max_velocity: float = param(
        0.3, "linear.x.max_velocity, m/s (the simulated wheels' limit)", low=0.0, high=100.0
    )
    linear_min_velocity: float = param(-0.3, "linear.x.min_velocity, m/s", low=-100.0, high=0.0)
    linear_max_acceleration: float = param(
        1.0, "linear.x.max_acceleration, m/s^2", low=1e-6, high=1e6
    )
    linear_max_deceleration: float = param(
        0.0,
        "linear.x.max_deceleration, m/s^2, negative (0: unset, -max_acceleration)",
        low=-1e6,
        high=0.0,
    )
    linear_max_acceleration_reverse: float = param(
        0.0,
        "linear.x.max_acceleration_reverse, m/s^2, negative (0: unset, -max_acceleration)",
        low=-1e6,
        high=0.0,
    )
    linear_max_deceleration_reverse: float = param(
        0.0,
        "linear.x.max_deceleration_reverse, m/s^2, positive (0: unset, max_acceleration)",
        low=0.0,
        high=1e6,
    )
    angular_max_velocity: float = param(
        3.0, "angular.z.max_velocity, rad/s (0.3 m/s wheels on a 0.2 m track)", low=0.0, high=1e3
    )
    angular_min_velocity: float = param(-3.0, "angular.z.min_velocity, rad/s", low=-1e3, high=0.0)
    angular_max_acceleration: float = param(
        6.0, "angular.z.max_acceleration, rad/s^2", low=1e-6, high=1e6
    )
    angular_max_deceleration: float = param(
        0.0,
        "angular.z.max_deceleration, rad/s^2, negative (0: unset, -max_acceleration)",
        low=-1e6,
        high=0.0,
    )
    angular_max_acceleration_reverse: float = param(
        0.0,
        "angular.z.max_acceleration_reverse, rad/s^2, negative (0: unset, -max_acceleration)",
        low=-1e6,
        high=0.0,
    )
    angular_max_deceleration_reverse: float = param(
        0.0,
        "angular.z.max_deceleration_reverse, rad/s^2, positive (0: unset, max_acceleration)",
        low=0.0,
        high=1e6,
    )
    odom_frame_id: str = param("odom", "odometry frame (after the prefix)")
    base_frame_id: str = param("base_link", "the robot's base frame (after the prefix)")
    tf_frame_prefix_enable: bool = param(True, "prefix odom_frame_id and base_frame_id")
    tf_frame_prefix: str = param("", "the frames' prefix; empty: the node's namespace")
    pose_covariance_diagonal: tuple[float, ...] = param(
        (0.001, 0.001, 0.001, 0.001, 0.001, 0.01), "odometry pose covariance (x y z rx ry rz)"
    )
    twist_covariance_diagonal: tuple[float, ...] = param(
        (0.001, 0.001, 0.001, 0.001, 0.001, 0.01), "odometry twist covariance (x y z rx ry rz)"
    )
    publish_limited_velocity: bool = param(False, "publish the limited command on cmd_vel_out")
    publish_imu: bool = param(
        True, "relay the world's IMU (world/imu) as imu, stamped and framed by the base"
    )
    diagnostics_period: float = param(1.0, "s between diagnostics", low=0.05, high=3600.0)

    def check(self) -> None:
        """Six covariance values each; the velocity limits leave room to stand still."""
        for name in ("pose_covariance_diagonal", "twist_covariance_diagonal"):
            values = getattr(self, name)
            if len(values) != 6 or not all(math.isfinite(v) and v >= 0 for v in values):
                raise ValueError(f"{name} needs six finite values >= 0, got {list(values)}")


@dataclass(frozen=True)
class AxisLimits:
    """One axis of control_toolbox's ``RateLimiter`` (velocity and acceleration parts).

    Attributes:
        min_velocity: Lowest velocity (``min_value``).
        max_velocity: Highest velocity (``max_value``).
        max_acceleration: ``max_first_derivative_pos``: speeding up forwards, per second.
        max_deceleration: ``min_first_derivative_pos`` (negative): slowing down forwards.
        max_acceleration_reverse: ``min_first_derivative_neg`` (negative): speeding up
            backwards.
        max_deceleration_reverse: ``max_first_derivative_neg`` (positive): slowing down
            backwards.
    """

    min_velocity: float
    max_velocity: float
    max_acceleration: float
    max_deceleration: float
    max_acceleration_reverse: float
    max_deceleration_reverse: float

    @classmethod
    def from_params(
        cls,
        min_velocity: float,
        max_velocity: float,
        max_acceleration: float,
        max_deceleration: float = 0.0,
        max_acceleration_reverse: float = 0.0,
        max_deceleration_reverse: float = 0.0,
    ) -> AxisLimits:
        """The limits with RateLimiter's defaults for those given as 0 (unset).

        ``set_params``: an unset ``min_first_derivative_neg`` is ``-max_first_derivative_pos``;
        an unset ``max_first_derivative_neg`` is ``max_first_derivative_pos``; an unset
        ``min_first_derivative_pos`` is ``min_first_derivative_neg``.
        """
        accel_reverse = max_acceleration_reverse or -max_acceleration
        decel_reverse = max_deceleration_reverse or max_acceleration
        decel = max_deceleration or accel_reverse
        return cls(
            min_velocity, max_velocity, max_acceleration, decel, accel_reverse, decel_reverse
        )

    def limit(self, v: float, v0: float, dt: float) -> float:
        """``v`` limited in acceleration from ``v0`` over ``dt`` s, then in velocity."""
        if v0 > 0.0:
            low, high = self.max_deceleration, self.max_acceleration
        elif v0 < 0.0:
            low, high = self.max_acceleration_reverse, self.max_deceleration_reverse
        else:
            low, high = self.max_acceleration_reverse, self.max_acceleration
        v = v0 + min(max(v - v0, low * dt), high * dt)
        return min(max(v, self.min_velocity), self.max_velocity)


def limits_of(params: BaseParams) -> tuple[AxisLimits, AxisLimits]:
    """``(linear, angular)`` limits of the base's parameters."""
    p = params
    linear = AxisLimits.from_params(
        p.linear_min_velocity,
        p.linear_max_velocity,
        p.linear_max_acceleration,
        p.linear_max_deceleration,
        p.linear_max_acceleration_reverse,
        p.linear_max_deceleration_reverse,
    )
    angular = AxisLimits.from_params(
        p.angular_min_velocity,
        p.angular_max_velocity,
        p.angular_max_acceleration,
        p.angular_max_deceleration,
        p.angular_max_acceleration_reverse,
        p.angular_max_deceleration_reverse,
    )
    return linear, angular


# --- what a command did on arrival --------------------------------------------------------


@dataclass(frozen=True)
class Accepted:
    """The command is the latest; ``stamp_ns`` is the stamp its age counts from."""

    stamp_ns: int


@dataclass(frozen=True)
class Ignored:
    """The command was older than ``cmd_vel_timeout`` on arrival (``age`` seconds)."""

    age: float


Received = Accepted | Ignored


# --- what an update sends ------------------------------------------------------------------


@dataclass(frozen=True)
class Forward:
    """The limited command for the wheels (the simulated world's ``cmd_vel``)."""

    linear: float
    angular: float


@dataclass(frozen=True)
class PublishOdometry:
    """Wheel odometry in the odometry frame: pose and the wheels' velocity."""

    x: float
    y: float
    yaw: float
    linear: float
    angular: float


@dataclass(frozen=True)
class PublishLimited:
    """The limited command (``cmd_vel_out``, with ``publish_limited_velocity``)."""

    linear: float
    angular: float


@dataclass(frozen=True)
class Braking:
    """The latest command timed out at this update (``age`` s): the reference is zero.

    ``received``: whether any ``cmd_vel`` came before (False: the zero twist the base
    starts with lapsed, at start-up, before its driver's first command). ``moving``:
    whether the lapsed command asked for motion (a stream that stopped after a zero twist,
    as a driver stops between goals, is no fault; one that stopped mid-motion is).
    """

    age: float
    received: bool = True
    moving: bool = True


Action = Forward | PublishOdometry | PublishLimited | Braking


@dataclass
class Odometry:
    """``diff_drive_controller::Odometry``'s pose, integrated exactly per update."""

    x: float = 0.0  # metres in the odometry frame
    y: float = 0.0
    yaw: float = 0.0  # radians

    def integrate(self, linear: float, angular: float) -> None:
        """Add ``linear`` metres and ``angular`` radians driven in one period."""
        if abs(angular) < 1e-6:
            direction = self.yaw + angular * 0.5
            self.x += linear * math.cos(direction)
            self.y += linear * math.sin(direction)
            self.yaw += angular
            return
        old = self.yaw
        r = linear / angular
        self.yaw += angular
        self.x += r * (math.sin(self.yaw) - math.sin(old))
        self.y += -r * (math.cos(self.yaw) - math.cos(old))


class DiffDriveCore:
    """The controller's rules (module docstring); all times are node-clock nanoseconds."""

    def __init__(self, params: BaseParams, now_ns: int) -> None:
        """A base standing still at the odometry frame's origin at ``now_ns``."""
        self.params = params
        self.linear_limits, self.angular_limits = limits_of(params)
        self.timeout_ns = int(round(params.cmd_vel_timeout * 1e9))
        self.publish_period_ns = int(round(1e9 / params.publish_rate))
        # The latest command: (linear, angular, stamp); a zero twist stamped now, as the
        # controller's on_activate leaves it, until the first cmd_vel.
        self.command: tuple[float, float, int] = (0.0, 0.0, now_ns)
        self.reference: tuple[float, float] = (0.0, 0.0)
        self.previous: tuple[float, float] = (0.0, 0.0)  # the wheels' command, last update
        self.last_update_ns = now_ns
        self.last_publish_ns = now_ns
        self.odometry = Odometry()
        self.braking = False
        self.received = 0
        self.ignored = 0
        self.not_finite = 0
        self.timeouts = 0

    def receive(self, linear: float, angular: float, stamp_ns: int | None, now_ns: int) -> Received:
        """A ``cmd_vel``: ``stamp_ns`` None for a Twist (stamped now, as on arrival)."""
        if stamp_ns is None or stamp_ns == 0:
            stamp_ns = now_ns
        age_ns = now_ns - stamp_ns
        if self.timeout_ns and age_ns >= self.timeout_ns:
            self.ignored += 1
            return Ignored(age_ns * 1e-9)
        self.received += 1
        if not (math.isfinite(linear) and math.isfinite(angular)):
            self.not_finite += 1
        self.command = (float(linear), float(angular), stamp_ns)
        return Accepted(stamp_ns)

    def update(self, now_ns: int) -> list[Action]:
        """One controller update at ``now_ns``: the reference, the limits, odometry."""
        out: list[Action] = []
        dt = max(now_ns - self.last_update_ns, 0) * 1e-9
        self.last_update_ns = now_ns
        linear, angular, stamp = self.command
        age_ns = now_ns - stamp
        if self.timeout_ns and age_ns > self.timeout_ns:
            self.reference = (0.0, 0.0)
            if not self.braking:
                self.braking = True
                self.timeouts += 1
                moving = bool(linear or angular) or not math.isfinite(linear + angular)
                out.append(Braking(age_ns * 1e-9, self.received > 0, moving))
        else:
            self.braking = False
            if math.isfinite(linear) and math.isfinite(angular):
                self.reference = (linear, angular)
        # The wheels ran the previous command over the period just ended.
        self.odometry.integrate(self.previous[0] * dt, self.previous[1] * dt)
        wheels_linear, wheels_angular = self.previous
        lin = self.linear_limits.limit(self.reference[0], self.previous[0], dt)
        ang = self.angular_limits.limit(self.reference[1], self.previous[1], dt)
        self.previous = (lin, ang)
        if self.last_publish_ns + self.publish_period_ns < now_ns:
            self.last_publish_ns += self.publish_period_ns
            if now_ns - self.last_publish_ns > self.publish_period_ns:  # fell behind: resync
                self.last_publish_ns = now_ns
            o = self.odometry
            out.append(PublishOdometry(o.x, o.y, o.yaw, wheels_linear, wheels_angular))
        if self.params.publish_limited_velocity:
            out.append(PublishLimited(lin, ang))
        out.append(Forward(lin, ang))
        return out
