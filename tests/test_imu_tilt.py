"""R1 from ``/robot_k/imu``: the IMU's nose-down pitch against the height map's grid rule.

In continuous trials and the dome the controller takes R1 (tilted nose down) from the
robot's IMU (``tilt_source: imu``); in lockstep trials from the height map. These tests
hold the two to the same answer on a ramp and on flat ground in a ``dynamics`` run, and
show that a stale IMU reading stops decisions as any stale input does.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from excavation_interfaces.msg import Snapshot
from geometry_msgs.msg import PoseWithCovarianceStamped, TwistStamped
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import Image, Imu

from ant_controller.input_gate import TILT_IMU, TILT_THRESHOLD, ControllerParams, InputGate
from ant_controller.sensing import is_tilted_down
from blueprint_server.blueprint import default_blueprint
from excavation_common.frames import heading_to_yaw, robot_center
from excavation_common.messages import (
    MessageError,
    heights_to_units,
    image_to_grid,
    imu_message,
    imu_pitch,
    pose_to_grid,
)
from excavation_common.ros import LATCHED
from excavation_sim.dynamics import DynamicsParams
from excavation_sim.dynamics_node import DynamicsNode
from excavation_sim.sim_node import TILT_PITCH
from excavation_sim.world import COL, HEADING, ROW


@pytest.mark.parametrize("yaw", [0.0, math.pi / 2, math.pi, -math.pi / 2, 0.3])
@pytest.mark.parametrize("pitch", [0.0, 0.2, -0.2, 0.05])
def test_pitch_round_trip_does_not_depend_on_yaw(yaw, pitch):
    assert imu_pitch(imu_message(yaw, pitch, "robot_0/base_link")) == pytest.approx(pitch)


def test_a_roll_is_not_a_nose_down_tilt_and_bad_orientations_are_named():
    roll = Imu()
    roll.orientation.x, roll.orientation.w = math.sin(0.15), math.cos(0.15)  # 0.3 rad roll
    assert imu_pitch(roll) == pytest.approx(0.0)
    unknown = imu_message(0.0, 0.2, "robot_0/base_link")
    unknown.orientation_covariance[0] = -1.0
    with pytest.raises(MessageError, match="no orientation estimate"):
        imu_pitch(unknown, "/robot_0/imu")
    zero = Imu()
    zero.orientation.w = 0.0
    with pytest.raises(MessageError, match="/robot_0/imu: orientation.*unit quaternion"):
        imu_pitch(zero, "/robot_0/imu")


def test_the_threshold_reproduces_the_grid_rule_on_the_simulators_imus():
    """Flat reads 0, tilted TILT_PITCH; the threshold lies between, below the smallest
    physical grid-rule tilt (half a soil unit over one cell) on the default worksite."""
    bp = default_blueprint(1)
    smallest = math.atan(0.5 * bp.height_unit / bp.cell_size)
    assert 0.0 < TILT_THRESHOLD < smallest < TILT_PITCH
    assert ControllerParams().tilt_threshold == TILT_THRESHOLD


def imu_gate(lockstep):
    g = InputGate(0, 1, lockstep=lockstep, tilt_source=TILT_IMU, imu_timeout=0.5)
    bp = default_blueprint(1)
    g.zones, g.goal, g.cell_size = bp.zones, bp.goal, 0.25
    g.on_pose(0, 0.0, (2, 2, 0), (0, 0))
    g.on_heights(0.0, np.zeros((16, 16), dtype=np.int32), (0, 0))
    g.on_joint(0.0, (3, 0), (0, 0))
    g.on_stuck(0.0, False)
    return g


def test_gate_without_or_with_a_stale_imu_reading_does_not_decide():
    g = imu_gate(lockstep=False)
    assert g.missing(0.1) == "no IMU reading (imu)"
    g.on_imu(0.0, 0.2)
    assert g.missing(0.1) is None and g.tilted() is True
    g.on_pose(0, 0.6, (2, 2, 0), (0, 0))
    g.on_heights(0.6, np.zeros((16, 16), dtype=np.int32), (0, 0))
    g.on_joint(0.6, (3, 0), (0, 0))
    g.on_stuck(0.6, False)
    assert g.missing(0.6) == "IMU reading is stale (0.60 s)"
    g.on_imu(0.6, 0.0)
    assert g.missing(0.6) is None and g.tilted() is False


def test_lockstep_tick_waits_for_an_imu_reading_since_the_last_tick():
    """Paired by arrival (as U1), not by age: the tick's snapshot may come late."""
    g = imu_gate(lockstep=True)
    g.on_imu(0.0, 0.0)
    assert g.lockstep_ready(30.0) and g.tilted() is False  # ages do not count in lockstep
    g.on_pose(0, 31.0, (2, 2, 0), (1, 0))
    g.on_heights(31.0, np.zeros((16, 16), dtype=np.int32), (1, 0))
    g.on_joint(31.0, (3, 0), (1, 0))
    g.on_stuck(31.0, False)
    assert not g.lockstep_ready(31.0)  # tick 1 is in, the IMU fell silent: no decision
    assert g.lockstep_waiting() == "no IMU reading since the last tick"
    g.on_imu(31.5, 0.2)  # a reading arrives: the tick is decided with it
    assert g.lockstep_waiting() is None
    assert g.lockstep_ready(31.5) and g.tilted() is True
    height_map = InputGate(0, 1)
    assert height_map.tilted() is None  # the core's grid rule on the height map


class Team(Node):
    """Stands in for the executors: answers every pose, turns robot 0 in place."""

    def __init__(self, context, n, turn_rate):
        super().__init__("team", context=context)
        self.n, self.turn_rate = n, turn_rate
        self.cmd = [
            self.create_publisher(TwistStamped, f"/robot_{k}/cmd_vel", 10) for k in range(n)
        ]
        self.poses = {k: {} for k in range(n)}
        self.imus = {k: {} for k in range(n)}
        self.heights = None
        for k in range(n):
            sub = self.create_subscription
            sub(
                PoseWithCovarianceStamped, f"/robot_{k}/pose", lambda m, k=k: self.on_pose(k, m), 50
            )
            sub(Imu, f"/robot_{k}/imu", lambda m, k=k: self.on_imu(k, m), 50)
        self.create_subscription(Image, "/worksite/height_map", self.on_heights, LATCHED)
        self.snapshot = self.create_publisher(Snapshot, "/team/snapshot", 10)

    @staticmethod
    def key(msg):
        return (msg.header.stamp.sec, msg.header.stamp.nanosec)

    def on_pose(self, k, msg):
        self.poses[k][self.key(msg)] = msg
        twist = TwistStamped()
        twist.header.stamp = msg.header.stamp
        twist.twist.angular.z = self.turn_rate if k == 0 else 0.0
        self.cmd[k].publish(twist)

    def on_imu(self, k, msg):
        self.imus[k][self.key(msg)] = msg

    def on_heights(self, msg):
        self.heights = msg


def test_imu_r1_equals_height_map_r1_on_a_ramp_and_flat_ground_in_a_dynamics_run(ros):
    """Robot 0 turns on a ramp (nose down, sideways, nose up), robot 1 stands on flat
    ground, robot 2 sideways on the ramp (a roll), robot 3 faces down the ramp."""
    physics = DynamicsParams.exact()
    sim = ros.add(
        DynamicsNode(
            context=ros.context,
            parameter_overrides=[
                Parameter("blueprint", value="default:1"),
                Parameter("robots", value=4),
                Parameter("startup_period", value=0.0),
            ]
            + [Parameter(name, value=value) for name, value in vars(physics).items()],
        )
    )
    w = sim.sim.world
    w.heights[:, :8] = np.arange(w.heights.shape[0])[:, None] - 8  # rises to the north
    w.heights[:, 8:] = 0
    for k, (row, col, heading) in enumerate([(4, 3, 0), (4, 11, 2), (10, 3, 3), (10, 6, 2)]):
        w.robots[k, ROW], w.robots[k, COL], w.robots[k, HEADING] = row, col, heading
        x, y = robot_center(row, col, sim.sim.cell)
        sim.sim.bodies[k] = (x, y, heading_to_yaw(heading))
    team = ros.add(Team(ros.context, 4, turn_rate=0.6))
    assert ros.spin_until(lambda: sim.clock.started, timeout=20.0)
    team.snapshot.publish(Snapshot(tick=1))
    assert ros.spin_until(lambda: sim.sim.counters.turns >= 4, timeout=60.0)
    assert ros.spin_until(lambda: team.heights is not None)
    bp = sim.blueprint
    units = heights_to_units(image_to_grid(team.heights, "32FC1"), bp.height_unit)
    assert np.array_equal(units, w.heights)  # the ramp did not change: turns move no soil
    r1 = {k: set() for k in range(4)}
    compared = 0
    for k in range(4):
        for stamp in sorted(set(team.poses[k]) & set(team.imus[k])):
            row, col, heading = pose_to_grid(team.poses[k][stamp], bp.cell_size)
            from_map = bool(is_tilted_down(units, row, col, heading))
            from_imu = imu_pitch(team.imus[k][stamp]) > TILT_THRESHOLD
            assert from_imu == from_map, (k, stamp, row, col, heading)
            r1[k].add(from_imu)
            compared += 1
    assert compared > 4 * 50
    assert r1 == {0: {True, False}, 1: {False}, 2: {False}, 3: {True}}
