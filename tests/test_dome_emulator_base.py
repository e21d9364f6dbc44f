"""The emulated base: diff_drive_controller's stamp, timeout and limit rules, its odometry,
and the node between a drive executor's cmd_vel and the simulated world."""

from __future__ import annotations

import dataclasses
import math

import pytest
from dome_emulator.base import (
    Accepted,
    AxisLimits,
    BaseParams,
    Braking,
    DiffDriveCore,
    Forward,
    Ignored,
    PublishLimited,
    PublishOdometry,
)
from helpers.diagnostics import DiagnosticsProbe

from excavation_common.params import ParameterError, validate

S = 1_000_000_000  # ns per second
T0 = 1_700_000_000 * S  # a wall-clock instant


def forwards(actions) -> list[Forward]:
    return [a for a in actions if isinstance(a, Forward)]


def run(core: DiffDriveCore, start_ns: int, seconds: float, rate: float = 50.0):
    """Update at ``rate`` for ``seconds``; every update's actions, and the last instant."""
    period = int(S / rate)
    out, now = [], start_ns
    for _ in range(int(round(seconds * rate))):
        now += period
        out.append(core.update(now))
    return out, now


def loose(**changes) -> BaseParams:
    """Parameters whose limits never bind (the rules under test are the stamps')."""
    return dataclasses.replace(
        BaseParams(),
        linear_max_velocity=100.0,
        linear_min_velocity=-100.0,
        linear_max_acceleration=1e6,
        angular_max_velocity=100.0,
        angular_min_velocity=-100.0,
        angular_max_acceleration=1e6,
        **{"cmd_vel_timeout": 0.5, **changes},
    )


def test_a_stamp_older_than_the_timeout_is_ignored_on_arrival():
    core = DiffDriveCore(loose(), T0)
    assert core.receive(0.1, 0.0, T0 - S // 2, T0) == Ignored(pytest.approx(0.5))  # at it
    assert core.receive(0.1, 0.0, T0 - 2 * S, T0) == Ignored(pytest.approx(2.0))
    assert core.ignored == 2 and core.received == 0
    assert core.receive(0.1, 0.2, T0 - S // 4, T0) == Accepted(T0 - S // 4)
    assert forwards(core.update(T0 + S // 50)) == [Forward(0.1, 0.2)]


def test_zero_stamps_and_twists_count_from_their_arrival():
    core = DiffDriveCore(loose(), T0)
    assert core.receive(0.1, 0.0, 0, T0) == Accepted(T0)  # Jazzy: a zero stamp is "now"
    assert core.receive(0.1, 0.0, None, T0 + S) == Accepted(T0 + S)  # a Twist
    core = DiffDriveCore(loose(cmd_vel_timeout=0.0), T0)  # 0 disables the age checks
    assert core.receive(0.1, 0.0, T0 - 3600 * S, T0) == Accepted(T0 - 3600 * S)
    actions, _ = run(core, T0, 2.0)
    assert all(f == Forward(0.1, 0.0) for a in actions for f in forwards(a))


def test_the_start_up_zero_twist_lapsing_is_marked_as_no_command_yet():
    core = DiffDriveCore(loose(), T0)
    actions, _ = run(core, T0, 1.0)
    braking = [x for a in actions for x in a if isinstance(x, Braking)]
    assert len(braking) == 1 and not braking[0].received  # the node says so at INFO
    core.receive(0.0, 0.0, T0 + S, T0 + S)  # a driver's last word: stop
    actions, _ = run(core, T0 + S, 1.0)
    braking = [x for a in actions for x in a if isinstance(x, Braking)]
    assert len(braking) == 1 and braking[0].received and not braking[0].moving  # no WARN


def test_a_command_that_ages_past_the_timeout_stops_the_wheels():
    core = DiffDriveCore(loose(), T0)
    core.receive(0.2, 0.5, T0, T0)
    actions, now = run(core, T0, 0.5)  # age 0.5 s at the last update: not yet past it
    assert forwards(actions[-1]) == [Forward(0.2, 0.5)]
    assert not any(isinstance(x, Braking) for a in actions for x in a)
    late = core.update(now + S // 50)
    assert isinstance(late[0], Braking) and late[0].age == pytest.approx(0.52)
    assert late[0].received and late[0].moving  # a lapse mid-motion: the node warns
    assert forwards(late) == [Forward(0.0, 0.0)]
    assert core.braking and core.timeouts == 1
    again = core.update(now + 2 * S // 50)  # reported once
    assert not any(isinstance(x, Braking) for x in again)
    core.receive(0.1, 0.0, now + 2 * S // 50, now + 2 * S // 50)  # a fresh one drives again
    assert forwards(core.update(now + 3 * S // 50)) == [Forward(0.1, 0.0)]
    assert not core.braking


def test_a_timed_out_command_brakes_at_the_deceleration_limit():
    params = dataclasses.replace(
        BaseParams(),
        linear_max_acceleration=1.0,
        linear_max_deceleration=-0.5,
        cmd_vel_timeout=0.5,
    )
    core = DiffDriveCore(params, T0)
    core.receive(0.3, 0.0, T0, T0)
    actions, now = run(core, T0, 0.4)  # 20 updates of 0.02 s at 1 m/s^2: 0.3 m/s by 0.3 s
    assert forwards(actions[-1])[0].linear == pytest.approx(0.3)
    assert forwards(actions[14])[0].linear == pytest.approx(0.3)
    assert forwards(actions[13])[0].linear == pytest.approx(0.28)
    actions, _ = run(core, now, 1.0)  # times out at 0.5 s, then 0.01 m/s less per update
    speeds = [forwards(a)[0].linear for a in actions]
    first = next(i for i, a in enumerate(actions) if any(isinstance(x, Braking) for x in a))
    assert speeds[first] == pytest.approx(0.29)
    assert speeds[first + 1] == pytest.approx(0.28)
    assert speeds[first + 28] == pytest.approx(0.01)
    assert all(v == pytest.approx(0.0, abs=1e-12) for v in speeds[first + 29 :])


def test_velocity_limits_clamp_both_axes():
    core = DiffDriveCore(dataclasses.replace(BaseParams(), cmd_vel_timeout=0.0), T0)
    core.receive(5.0, -50.0, T0, T0)
    actions, _ = run(core, T0, 0.5)  # 6 rad/s^2 reaches 3 rad/s in 0.5 s
    (last,) = forwards(actions[-1])
    assert (last.linear, last.angular) == (pytest.approx(0.3), pytest.approx(-3.0))
    assert max(abs(f.angular) for a in actions for f in forwards(a)) <= 3.0


@pytest.mark.parametrize(
    ("v0", "v", "dt", "want"),
    [
        (0.0, 1.0, 0.1, 0.2),  # from standstill: max_acceleration
        (0.0, -1.0, 0.1, -0.3),  # from standstill backwards: max_acceleration_reverse
        (0.5, 0.0, 0.1, 0.4),  # slowing forwards: max_deceleration
        (0.5, 1.0, 0.1, 0.7),  # speeding up forwards: max_acceleration
        (-0.5, -1.0, 0.1, -0.8),  # speeding up backwards: max_acceleration_reverse
        (-0.5, 0.0, 0.1, -0.1),  # slowing backwards: max_deceleration_reverse
        (0.5, -1.0, 0.1, 0.4),  # reversing from forwards: slows first
        (0.95, 2.0, 0.1, 1.0),  # then the velocity clamp
    ],
)
def test_rate_limiter_picks_the_limit_by_the_previous_velocity(v0, v, dt, want):
    limits = AxisLimits(-1.0, 1.0, 2.0, -1.0, -3.0, 4.0)
    assert limits.limit(v, v0, dt) == pytest.approx(want)


def test_unset_limits_take_rate_limiters_defaults():
    limits = AxisLimits.from_params(-1.0, 1.0, 2.0)
    # min_first_derivative_neg = -max_pos; max_first_derivative_neg = max_pos;
    # min_first_derivative_pos = min_first_derivative_neg
    assert limits == AxisLimits(-1.0, 1.0, 2.0, -2.0, -2.0, 2.0)
    assert AxisLimits.from_params(-1.0, 1.0, 2.0, -0.5) == AxisLimits(
        -1.0, 1.0, 2.0, -0.5, -2.0, 2.0
    )
    assert AxisLimits.from_params(-1.0, 1.0, 2.0, 0.0, -3.0) == AxisLimits(
        -1.0, 1.0, 2.0, -3.0, -3.0, 2.0
    )


def test_a_command_with_nan_keeps_the_reference():
    core = DiffDriveCore(loose(), T0)
    core.receive(0.1, 0.0, T0, T0)
    core.update(T0 + S // 50)
    assert isinstance(core.receive(math.nan, 0.0, T0 + S // 50, T0 + S // 50), Accepted)
    assert forwards(core.update(T0 + 2 * S // 50)) == [Forward(0.1, 0.0)]
    assert core.not_finite == 1


def test_odometry_integrates_the_wheels_exactly_on_an_arc():
    core = DiffDriveCore(loose(), T0)
    v, w = 0.2, 0.5
    now = T0
    for _ in range(200):  # 4 s, a command every update
        core.receive(v, w, now, now)
        now += S // 50
        core.update(now)
    o = core.odometry
    t = 4.0 - 0.02  # the first update's period ran the standstill command
    assert o.yaw == pytest.approx(w * t)
    assert o.x == pytest.approx(v / w * math.sin(w * t))
    assert o.y == pytest.approx(v / w * (1 - math.cos(w * t)))


def test_odometry_goes_out_at_its_rate_and_reports_the_wheels():
    params = loose(publish_rate=10.0, publish_limited_velocity=True, cmd_vel_timeout=0.0)
    core = DiffDriveCore(params, T0)
    core.receive(0.1, 0.0, T0, T0)
    actions, _ = run(core, T0, 1.0)  # 50 updates
    odom = [x for a in actions for x in a if isinstance(x, PublishOdometry)]
    assert 9 <= len(odom) <= 10
    assert odom[-1].linear == pytest.approx(0.1) and odom[-1].x == pytest.approx(0.09)
    limited = [x for a in actions for x in a if isinstance(x, PublishLimited)]
    assert len(limited) == 50 and limited[-1] == PublishLimited(0.1, 0.0)


def test_actions_are_frozen_and_parameters_checked():
    with pytest.raises(dataclasses.FrozenInstanceError):
        Forward(0.0, 0.0).linear = 1.0
    validate(BaseParams, {})
    with pytest.raises(ParameterError, match="pose_covariance_diagonal needs six"):
        validate(BaseParams, {"pose_covariance_diagonal": [0.1, 0.1]})
    with pytest.raises(ParameterError, match="drive_type"):
        validate(BaseParams, {"drive_type": "twist_unstamped"})


def test_base_node_between_an_executor_and_the_world(ros):
    from dome_emulator.base_node import BaseNode
    from geometry_msgs.msg import TwistStamped
    from nav_msgs.msg import Odometry
    from rclpy.duration import Duration
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import Imu

    from excavation_common.messages import imu_message

    base = ros.add(
        BaseNode(
            context=ros.context,
            namespace="/robot_0",
            parameter_overrides=[Parameter("diagnostics_period", value=0.1)],
        )
    )
    probe = ros.add(Node("probe", context=ros.context))
    world, odom, imu = [], [], []
    probe.create_subscription(TwistStamped, "/robot_0/world/cmd_vel", world.append, 10)
    probe.create_subscription(Odometry, "/robot_0/odom", odom.append, 10)
    probe.create_subscription(Imu, "/robot_0/imu", imu.append, 10)
    diags = DiagnosticsProbe(probe).named("/robot_0/base")
    cmd = probe.create_publisher(TwistStamped, "/robot_0/cmd_vel", 10)
    world_imu = probe.create_publisher(Imu, "/robot_0/world/imu", 10)

    def command(linear, angular, age=0.0):
        msg = TwistStamped()
        msg.header.stamp = (probe.get_clock().now() - Duration(seconds=age)).to_msg()
        msg.twist.linear.x, msg.twist.angular.z = linear, angular
        cmd.publish(msg)

    def driving():
        command(0.5, 1.0)
        return bool(world) and world[-1].twist.linear.x == pytest.approx(0.3)

    assert ros.spin_until(driving, 20.0)  # accelerated, clamped at 0.3 m/s
    assert world[-1].twist.angular.z == pytest.approx(1.0)
    assert world[-1].header.frame_id == "robot_0/base_link"
    assert ros.spin_until(lambda: bool(odom) and odom[-1].pose.pose.position.x > 0.0)
    assert odom[-1].header.frame_id == "robot_0/odom"
    assert odom[-1].child_frame_id == "robot_0/base_link"

    def relayed():
        world_imu.publish(imu_message(0.3, 0.2, "robot_0/base_link"))
        return bool(imu)

    assert ros.spin_until(relayed)
    assert imu[-1].header.frame_id == "robot_0/base_link" and imu[-1].header.stamp.sec > 0
    assert imu[-1].orientation.y != 0.0  # the world's nose-down pitch

    # A command stamped 2 s ago is ignored, and said so.
    seen = len(diags)

    def ignored():
        command(-0.2, 0.0, age=2.0)
        return [s for s in diags[seen:] if "ignored" in s.message]

    assert ros.spin_until(ignored)
    assert ignored()[0].level == b"\x01"  # WARN
    assert all(m.twist.linear.x >= 0.0 for m in world)  # never took the stale reverse
    # Silence: the last command ages past cmd_vel_timeout and the wheels stop.
    assert ros.spin_until(lambda: any("braking" in s.message for s in diags), 20.0)
    assert ros.spin_until(lambda: world[-1].twist.linear.x == 0.0, 20.0)
    assert world[-1].twist.angular.z == 0.0
    assert base.core.timeouts == 1
