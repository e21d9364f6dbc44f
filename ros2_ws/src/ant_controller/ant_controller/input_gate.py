"""What a controller node may act on: input freshness and the lockstep decision (no rclpy).

:class:`InputGate` holds the latest decoded inputs of one robot's controller (poses, height
map, blade joint state, stuck flag, the IMU's nose-down pitch, blueprint, cell size) with
the time each arrived and the stamp it carried, plus which robots the supervisor has
enabled (``/robot_j/enabled``).
It answers two questions for the node:

* :meth:`InputGate.missing`: why the controller cannot act now (a missing or stale input,
  an own pose off the worksite, unknown terrain around the robot), or ``None``;
* :meth:`InputGate.lockstep_ready`: in lockstep mode (``ant-trial``), whether every input of
  one simulator tick is in (same stamp, newer than the last tick decided, plus a stuck flag
  received since), so that the node decides exactly once per tick.

R1 (tilted nose down) has two sources (``tilt_source``): ``height_map``, the world model's
rule on the tick's height map under the footprint (lockstep and grid trials, where no robot
carries an IMU), and ``imu``, the pitch of ``/robot_k/imu`` above ``tilt_threshold``
(continuous trials and the dome). Outside lockstep an IMU reading is stale after
``imu_timeout``. In lockstep mode the IMU is the robot's own sensor, not part of the tick's
snapshot (whose stamps are the tick's, reached through slow perception), so it pairs with
the tick by arrival, as the unstamped stuck flag does: a tick is decided only with an IMU
reading received since the last tick decided, and with the latest one.

Disabled robots are absent (docs/operator.md): their poses are neither needed
nor fresh-checked, and :meth:`InputGate.active` leaves them out of the sensor vector (the
core's ``active`` mask), so one robot the localiser loses does not freeze the team. A
robot never heard of on ``enabled`` counts as enabled (a team without a supervisor).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ant_controller.readings import PROFILE_NAMES
from excavation_common.params import param

UNKNOWN = np.iinfo(np.int32).min
"""Height-map value of a cell with no measurement (NaN in the message)."""

Stamp = tuple[int, int]

TILT_HEIGHT_MAP = "height_map"
"""R1 from the height map under the footprint (the world model's rule)."""
TILT_IMU = "imu"
"""R1 from the IMU's nose-down pitch."""
TILT_SOURCES = (TILT_HEIGHT_MAP, TILT_IMU)

TILT_THRESHOLD = 0.05
"""Default nose-down pitch (rad) above which R1 holds with ``tilt_source: imu``.

The grid rule calls a robot tilted when its front wheels stand at least one soil unit
lower than its rear wheels, summed over both sides: the smallest such tilt on the default
worksite (0.05 m units, 0.25 m cells) is half a unit over one cell, atan(0.025 / 0.25) =
0.0997 rad. Half of that leaves room for IMU noise on both sides, and the simulators'
IMUs (0 flat, ``excavation_sim.sim_node.TILT_PITCH`` = 0.2 rad tilted) read exactly as the
grid rule with it (tests/test_imu_tilt.py)."""


@dataclass(frozen=True)
class ControllerParams:
    """Parameters of the controller node (``config/controller.yaml``)."""

    robot_id: int = param(0, "this robot's index in the team", low=0, high=63)
    robots: int = param(1, "team size: poses of /robot_0 .. /robot_{robots-1}", low=1, high=64)
    height_unit: float = param(0.05, "m per soil unit (the blueprint's)", low=1e-6, high=100.0)
    pose_timeout: float = param(1.0, "s: older poses are stale (hold still)", low=1e-3, high=3600.0)
    map_timeout: float = param(5.0, "s: older height map is stale", low=1e-3, high=3600.0)
    joint_timeout: float = param(1.0, "s: blade joint state and stuck flag", low=1e-3, high=3600.0)
    rate: float = param(10.0, "Hz decisions (fresh-input mode)", low=0.1, high=1000.0)
    lockstep: bool = param(False, "one decision per simulator tick (ant-trial)")
    blade_depth: float = param(0.02, "m, must match the blade driver", low=1e-6, high=10.0)
    blade_home: float = param(0.10, "m, must match the blade driver", low=1e-6, high=10.0)
    max_force: float = param(10.0, "N of a full blade", low=1e-6, high=1e6)
    tilt_source: str = param(
        TILT_HEIGHT_MAP,
        "R1 from: height_map (grid rule; lockstep trials) or imu (/robot_k/imu; field)",
        choices=TILT_SOURCES,
    )
    tilt_threshold: float = param(
        TILT_THRESHOLD, "rad of nose-down IMU pitch above which R1 holds", low=0.0, high=1.5
    )
    imu_timeout: float = param(
        0.5, "s: older IMU reading is stale (imu; lockstep: one since the last tick)", low=1e-3
    )
    profile: str = param(
        "v1",
        "readings of the paper (H1 frame, hand-coded rules): v1 or paper, as the simulator's",
        choices=PROFILE_NAMES,
    )

    def check(self) -> None:
        """Rules across fields: the robot is one of the team; home above depth."""
        if self.robot_id >= self.robots:
            raise ValueError(
                f"robot_id = {self.robot_id} is outside the team of {self.robots} "
                f"(0..{self.robots - 1})"
            )
        if self.blade_home <= self.blade_depth:
            raise ValueError(f"blade_home = {self.blade_home}: must be above blade_depth")


@dataclass
class InputGate:
    """The freshness gate and lockstep barrier of one robot's controller.

    Times (``now``) are seconds on the node's clock; stamps are ``(sec, nanosec)`` of the
    messages' headers.

    Attributes:
        robot_id: This robot.
        robots: Team size.
        pose_timeout: Seconds after which a pose is stale.
        map_timeout: Seconds after which the height map is stale.
        joint_timeout: Seconds after which the joint state and the stuck flag are stale.
        lockstep: Stamps, not ages, say what is fresh (one decision per tick).
        tilt_source: ``TILT_HEIGHT_MAP`` or ``TILT_IMU`` (where R1 comes from).
        tilt_threshold: Nose-down pitch (rad) above which the IMU says R1.
        imu_timeout: Seconds after which an IMU reading is stale (outside lockstep; in
            lockstep mode a reading must have come since the last tick decided).
    """

    robot_id: int
    robots: int
    pose_timeout: float = 1.0
    map_timeout: float = 5.0
    joint_timeout: float = 1.0
    lockstep: bool = False
    tilt_source: str = TILT_HEIGHT_MAP
    tilt_threshold: float = TILT_THRESHOLD
    imu_timeout: float = 0.5
    poses: dict[int, tuple[float, tuple[int, int, int]]] = field(default_factory=dict)
    heights: tuple[float, np.ndarray] | None = None
    joint: tuple[float, tuple[int, int]] | None = None
    stuck: tuple[float, bool] | None = None
    imu: tuple[float, float] | None = None
    zones: np.ndarray | None = None
    goal: np.ndarray | None = None
    cell_size: float | None = None
    enabled: dict[int, bool] = field(default_factory=dict)
    stamps: dict[str, Stamp] = field(default_factory=dict)
    fresh_stuck: int = 0
    fresh_imu: int = 0
    decided_stamp: Stamp | None = None
    went_back: bool = False

    @classmethod
    def from_params(cls, p: ControllerParams) -> InputGate:
        """The gate of a node with parameters ``p``."""
        return cls(
            p.robot_id,
            p.robots,
            p.pose_timeout,
            p.map_timeout,
            p.joint_timeout,
            p.lockstep,
            p.tilt_source,
            p.tilt_threshold,
            p.imu_timeout,
        )

    # --- inputs -----------------------------------------------------------------------------

    def on_pose(self, j: int, now: float, pose: tuple[int, int, int], stamp: Stamp) -> None:
        """Robot ``j``'s pose on the grid ``(row, col, heading)``."""
        self.poses[j] = (now, tuple(int(v) for v in pose))
        self.stamps[f"pose{j}"] = stamp

    def on_heights(self, now: float, heights: np.ndarray, stamp: Stamp) -> None:
        """The height map in soil units (:data:`UNKNOWN` where unmeasured)."""
        self.heights = (now, heights)
        self.stamps["heights"] = stamp

    def on_joint(self, now: float, blade: tuple[int, int], stamp: Stamp) -> None:
        """The blade's ``(B1 code, load volume)``."""
        self.joint = (now, blade)
        self.stamps["joint"] = stamp

    def on_stuck(self, now: float, stuck: bool) -> None:
        """U1 as the robot reports it (unstamped: paired with the tick by arrival)."""
        self.stuck = (now, bool(stuck))
        self.fresh_stuck += 1

    def on_imu(self, now: float, pitch: float) -> None:
        """The IMU's nose-down pitch (rad), arrived at ``now``."""
        self.imu = (now, float(pitch))
        self.fresh_imu += 1

    def on_enabled(self, j: int, enabled: bool) -> None:
        """Robot ``j`` enabled or disabled by the supervisor."""
        self.enabled[j] = bool(enabled)

    # --- questions --------------------------------------------------------------------------

    def is_enabled(self, j: int) -> bool:
        """Robot ``j`` takes part (never heard of: yes)."""
        return self.enabled.get(j, True)

    def active(self) -> np.ndarray:
        """The ``active`` mask of the controller core: enabled robots."""
        return np.array([self.is_enabled(j) for j in range(self.robots)], dtype=np.bool_)

    def tilted(self) -> bool | None:
        """R1 from the IMU (``tilt_source: imu``), or ``None``: the core uses the height map."""
        if self.tilt_source != TILT_IMU or self.imu is None:
            return None
        return self.imu[1] > self.tilt_threshold

    def _age(self, arrived: float, now: float) -> float:
        return 0.0 if self.lockstep else now - arrived

    def missing(self, now: float) -> str | None:
        """Why the controller cannot act at ``now``, or ``None`` when every input is fresh."""
        if self.cell_size is None:
            return "no /worksite/map_info"
        if self.zones is None or self.goal is None:
            return "no blueprint (/blueprint/zones, /blueprint/goal)"
        if self.goal.shape != self.zones.shape:
            return "blueprint goal and zones differ in size"
        if not self.is_enabled(self.robot_id):
            return "this robot is disabled (supervisor)"
        for j in range(self.robots):
            if not self.is_enabled(j):
                continue
            name = "own pose" if j == self.robot_id else f"pose of robot {j}"
            if j not in self.poses:
                return f"no {name}"
            age = self._age(self.poses[j][0], now)
            if age > self.pose_timeout:
                return f"{name} is stale ({age:.2f} s)"
        for name, value, limit in (
            ("height map", self.heights, self.map_timeout),
            ("blade joint state", self.joint, self.joint_timeout),
            ("stuck flag", self.stuck, self.joint_timeout),
        ):
            if value is None:
                return f"no {name}"
            age = self._age(value[0], now)
            if age > limit:
                return f"{name} is stale ({age:.2f} s)"
        if self.tilt_source == TILT_IMU:
            if self.imu is None:
                return "no IMU reading (imu)"
            age = self._age(self.imu[0], now)  # lockstep: paired by arrival (lockstep_ready)
            if age > self.imu_timeout:
                return f"IMU reading is stale ({age:.2f} s)"
        if self.heights[1].shape != self.zones.shape:
            return "height map and blueprint differ in size"
        row, col, _ = self.poses[self.robot_id][1]
        rows, cols = self.zones.shape
        if not (0 <= row < rows - 1 and 0 <= col < cols - 1):
            return f"own pose ({row}, {col}) is off the {rows} x {cols} worksite"
        window = self.heights[1][max(row - 2, 0) : row + 4, max(col - 2, 0) : col + 4]
        if (window == UNKNOWN).any():
            return "unknown terrain around the robot"
        return None

    def _new_tick(self) -> Stamp | None:
        """The stamp of a complete set of stamped tick inputs not yet decided, or ``None``."""
        keys = [f"pose{j}" for j in range(self.robots) if self.is_enabled(j)]
        stamps = {self.stamps.get(k) for k in keys + ["heights", "joint"]}
        if len(stamps) != 1 or None in stamps:
            return None
        (stamp,) = stamps
        if self.decided_stamp is not None and stamp == self.decided_stamp:
            return None
        return stamp

    def _imu_unpaired(self) -> bool:
        """``tilt_source: imu`` and no IMU reading since the last tick decided."""
        return self.tilt_source == TILT_IMU and self.fresh_imu == 0

    def lockstep_waiting(self) -> str | None:
        """Lockstep mode: the IMU reading a tick whose stamped inputs are in waits for."""
        if self._imu_unpaired() and self._new_tick() is not None:
            return "no IMU reading since the last tick"
        return None

    def lockstep_ready(self, now: float) -> bool:
        """Every input of a new tick is in: decide it now (the tick is then marked decided).

        A tick's inputs are the poses of every enabled robot, the height map and the joint
        state stamped with the same time, newer than the last tick decided, plus a stuck
        flag received since then (and, with ``tilt_source: imu``, an IMU reading received
        since then: the robot's own sensor, paired with the tick by arrival as U1 is). A
        complete set OLDER than the last tick decided means the simulator's clock went back
        (it was restarted): that is decided too, as the first tick of a new trial, and
        :attr:`went_back` says so (the node clears M1).
        """
        self.went_back = False
        stamp = self._new_tick()
        if stamp is None or self.fresh_stuck == 0 or self._imu_unpaired():
            return False
        went_back = self.decided_stamp is not None and stamp < self.decided_stamp
        if self.missing(now) is not None:
            return False  # not ready (e.g. no blueprint yet): decided when it arrives
        self.went_back = went_back
        self.decided_stamp = stamp
        self.fresh_stuck = 0
        self.fresh_imu = 0
        return True

    def pose_array(self) -> np.ndarray:
        """``[robots, 3]`` poses; an absent robot without a pose is ``(0, 0, 0)``."""
        out = np.zeros((self.robots, 3), dtype=np.int64)
        for j, (_, pose) in self.poses.items():
            if 0 <= j < self.robots:
                out[j] = pose
        return out
