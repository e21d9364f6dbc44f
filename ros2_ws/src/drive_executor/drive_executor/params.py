"""Parameters of the drive executor (``config/executor.yaml`` mirrors them).

Defaults suit the paper's dome robots (15 kg, non-holonomic, four-wheel drive) on
0.25 m cells: a cell in about three seconds, a quarter turn in about three seconds.
"""

from __future__ import annotations

from dataclasses import dataclass

from excavation_common.params import param


@dataclass(frozen=True)
class ExecutorParams:
    """The executor node's parameters (ROS parameters of the same names)."""

    cell_size: float = param(0.25, "grid cell size, m (the blueprint's)", low=0.01, high=10.0)
    rate: float = param(
        20.0, "safety loop rate on the node clock, Hz (gate, stale pose)", low=1.0, high=1000.0
    )
    max_speed: float = param(0.10, "linear speed limit, m/s", low=0.001, high=5.0)
    throttle_speed: float = param(
        0.15, "linear speed limit with Throttle Up, m/s", low=0.001, high=5.0
    )
    max_accel: float = param(0.25, "linear acceleration limit, m/s^2", low=0.001, high=50.0)
    max_turn_rate: float = param(0.6, "angular speed limit, rad/s", low=0.01, high=20.0)
    throttle_turn_rate: float = param(
        0.9, "angular speed limit with Throttle Up, rad/s", low=0.01, high=20.0
    )
    max_turn_accel: float = param(2.0, "angular acceleration limit, rad/s^2", low=0.01, high=100.0)
    position_tolerance: float = param(
        0.008, "along-track distance from the cell centre that ends a drive, m", low=1e-4, high=1.0
    )
    heading_tolerance: float = param(
        0.03, "heading error that ends a turn, rad", low=1e-4, high=0.5
    )
    heading_gain: float = param(2.0, "heading correction while driving, 1/s", low=0.0, high=50.0)
    cross_track_gain: float = param(
        8.0, "cross-track correction while driving, rad/(m s)", low=0.0, high=500.0
    )
    time_allowance: float = param(
        12.0, "seconds a primitive may take before it aborts", low=0.1, high=600.0
    )
    progress_window: float = param(
        1.0, "seconds over which a primitive must make progress", low=0.05, high=60.0
    )
    min_progress: float = param(
        0.004, "progress a drive must make per window, m (turns: x 10 rad/m)", low=0.0, high=1.0
    )
    pose_timeout: float = param(
        0.3, "a pose older than this (header stamp) stops the robot, s", low=0.01, high=10.0
    )
    future_tolerance: float = param(
        0.05,
        "a pose stamped more than this ahead of the node clock stops the robot too (a clock "
        "offset), s",
        low=0.0,
        high=10.0,
    )
    clock_offset_limit: float = param(
        0.02,
        "poses stamped more than this ahead of the node clock are reported on /diagnostics "
        "(WARN), s",
        low=0.0,
        high=10.0,
    )
    override_timeout: float = param(
        0.5, "a drive override stays in charge this long after it arrives, s", low=0.01, high=10.0
    )
    deadman: float = param(
        0.5, "heartbeat age that stops the robot, s (the team deadman)", low=0.05, high=10.0
    )
    rearm_after_loss: bool = param(
        False,
        "on a robot's own computer: after a lost heartbeat (a dropped link) nothing moves "
        "until a newer arming on /team/armed (the operator re-arms)",
    )
    mode: str = param(
        "tick",
        "tick: run the team tick's goals (the drive action); free: run each word when idle",
        choices=("tick", "free"),
    )
    seed: int = param(0, "seed of the executor's own random-turn generator", low=0, high=2**31 - 1)
    pose_topic: str = param("pose", "the pose the loop closes on (localiser or simulator)")
    drive_type: str = param(
        "twist_stamped",
        "cmd_vel's type: twist_stamped (geometry_msgs/TwistStamped: Jazzy's "
        "diff_drive_controller) or twist (geometry_msgs/Twist)",
        choices=("twist", "twist_stamped"),
    )
    predict_pose: bool = param(
        False,
        "advance each pose by its age along the twist last sent before acting on it (a "
        "camera's latency: the dome), so a drive does not overshoot its cell by the distance "
        "covered while the frame was processed",
    )
    cmd_vel_stamp: str = param(
        "now",
        "now: cmd_vel stamped with the node clock when sent (a base's cmd_vel_timeout counts "
        "from it); pose: with the stamp of the pose it answers (the continuous simulator's "
        "lockstep)",
        choices=("now", "pose"),
    )

    def check(self) -> None:
        """Throttle-up may only raise the limits."""
        if self.throttle_speed < self.max_speed:
            raise ValueError(f"throttle_speed {self.throttle_speed} < max_speed {self.max_speed}")
        if self.throttle_turn_rate < self.max_turn_rate:
            raise ValueError(
                f"throttle_turn_rate {self.throttle_turn_rate} < max_turn_rate {self.max_turn_rate}"
            )
