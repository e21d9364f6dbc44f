"""A trial's bag as per-tick arrays: terrain, robots, behaviours and what each robot sensed.

The bag is read once in its recorded order (publish time, see the recorder). A **frame**
starts at each ``/worksite/height_map`` message (the simulator publishes one per tick,
first after ``/clock``; the mapper publishes one per map update). A **decision** is a
``/robot_k/behaviour`` message: the sensor vector the controller saw is rebuilt from the
latest inputs before it (every robot's pose, the height map, the blueprint, robot k's blade
joint and stuck flag) with the same ``sensor_vector`` and memory-bit rule the controller
runs (``ant_controller.controller.ControllerCore``). Those pairs feed the Table 3
detectors (:mod:`excavation_sim.detectors`); the heading at robot k's next decision tells
which way a Random Turn went.

Heights and goals travel in metres; soil units are ``height_unit`` metres
(``custom_data.height_unit`` of the bag, 0.05 by default, as the controller node assumes).
A message that does not decode is skipped and listed in :attr:`TrialData.problems`; a
missing topic leaves its arrays empty. Camera frames (``/overhead/image_raw/compressed``
as the recorder stores them, or raw ``/overhead/image_raw`` of older bags) are counted, and
a few evenly spaced ones are decoded with OpenCV (:mod:`excavation_bags.images`) into
:attr:`TrialData.camera_frames` for the report. Pure module: no ``rclpy``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from ant_controller.layout import N_SENSORS
from ant_controller.memory import next_memory
from ant_controller.sensing import is_tilted_down, sensor_vector
from excavation_bags.images import COMPRESSED_TYPE, IMAGE_TYPE, frame_array
from excavation_bags.reader import Bag
from excavation_common.constants import BladeGeometry
from excavation_common.errors import FieldError
from excavation_common.messages import (
    blade_from_joint,
    heights_to_units,
    image_to_grid,
    pose_to_grid,
)

HEIGHTS = "/worksite/height_map"
GOAL = "/blueprint/goal"
ZONES = "/blueprint/zones"
MAP_INFO = "/worksite/map_info"
FITNESS = "/worksite/fitness"
CAMERA_TOPICS = {
    "/overhead/image_raw/compressed": COMPRESSED_TYPE,
    "/overhead/image_raw": IMAGE_TYPE,
}
"""Camera topics the report reads, preferred first, with their types."""
CAMERA_FRAMES = 5
"""Camera frames decoded for the report (evenly spaced over the trial)."""
EXPECTED_TYPES = {
    **CAMERA_TOPICS,
    HEIGHTS: "sensor_msgs/msg/Image",
    GOAL: "sensor_msgs/msg/Image",
    ZONES: "sensor_msgs/msg/Image",
    MAP_INFO: "nav_msgs/msg/MapMetaData",
    FITNESS: "std_msgs/msg/Float32",
    "pose": "geometry_msgs/msg/PoseWithCovarianceStamped",
    "behaviour": "std_msgs/msg/UInt16",
    "stuck": "std_msgs/msg/Bool",
    "blade/joint_states": "sensor_msgs/msg/JointState",
}
_ROBOT_TOPIC = re.compile(r"^/robot_(\d+)/(pose|behaviour|stuck|blade/joint_states)$")
UNKNOWN_UNITS = np.iinfo(np.int32).min


@dataclass
class Decision:
    """One robot's behaviour command with the sensor vector it was chosen from.

    Attributes:
        frame: Index of the frame it belongs to.
        robot: Robot index.
        behaviour: The command mask.
        sensors: Sensor vector (``N_SENSORS`` ints), or ``None`` when an input was missing.
        heading: The robot's heading when it decided (-1 unknown).
    """

    frame: int
    robot: int
    behaviour: int
    sensors: np.ndarray | None
    heading: int


@dataclass
class TrialData:
    """What the report needs from a trial's bag.

    Attributes:
        height_unit: Metres per soil unit.
        cell_size: Metres per cell (``/worksite/map_info``), ``None`` when missing.
        zones: Blueprint zones, ``None`` when missing.
        goal: Goal heights (metres, NaN off the dig area), ``None`` when missing.
        robots: Number of robots (``/robot_k/pose`` topics).
        frame_times: Stamp (s) of each frame's height map.
        heights: Height maps in metres, ``[frames, rows, cols]`` (NaN unknown).
        poses: ``[frames, robots, 4]`` (row, col, heading, blade) at each frame's end, -1
            unknown.
        fitness: Recorded ``/worksite/fitness`` per frame (NaN where none).
        decisions: Every decision in bag order.
        camera_topic: The camera topic read (``None`` when the bag has none).
        camera_times: Stamp (s) of every camera frame.
        camera_frames: ``(index, stamp, BGR or mono array)`` of a few frames, decoded.
        camera_bytes: Stored image bytes of every camera frame (compressed or raw).
        topics: Topic -> message count.
        problems: Messages that could not be used, and topics with unexpected types.
    """

    height_unit: float
    cell_size: float | None = None
    zones: np.ndarray | None = None
    goal: np.ndarray | None = None
    robots: int = 0
    frame_times: list[float] = field(default_factory=list)
    heights: list[np.ndarray] = field(default_factory=list)
    poses: list[np.ndarray] = field(default_factory=list)
    fitness: list[float] = field(default_factory=list)
    decisions: list[Decision] = field(default_factory=list)
    camera_topic: str | None = None
    camera_times: list[float] = field(default_factory=list)
    camera_frames: list[tuple[int, float, np.ndarray]] = field(default_factory=list)
    camera_bytes: list[int] = field(default_factory=list)
    topics: dict[str, int] = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)

    @property
    def goal_units(self) -> np.ndarray | None:
        """Goal heights in soil units (``INT32_MIN`` off the dig area)."""
        return None if self.goal is None else heights_to_units(self.goal, self.height_unit)

    def heights_units(self, i: int) -> np.ndarray:
        """Frame i's heights in soil units (``INT32_MIN`` unknown)."""
        return heights_to_units(self.heights[i], self.height_unit)

    def decision_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The decisions whose sensor vector is known, as arrays for the detectors.

        Returns:
            ``(frames [n], sensors [n, 14], behaviours [n], random_turns [n])``; a random
            turn is +1 right, -1 left, 0 none or unknown.
        """
        from ant_controller.layout import RANDOM_TURN, TURN_LEFT, TURN_RIGHT

        keep = [d for d in self.decisions if d.sensors is not None]
        nxt: dict[int, int] = {}
        turns = np.zeros(len(keep), dtype=np.int8)
        # next decision of the same robot, one frame later, gives the heading after
        for i in range(len(keep) - 1, -1, -1):
            d = keep[i]
            j = nxt.get(d.robot)
            if j is not None and d.behaviour >> RANDOM_TURN & 1:
                e = keep[j]
                if e.frame == d.frame + 1 and d.heading >= 0 and e.heading >= 0:
                    explicit = (d.behaviour >> TURN_RIGHT & 1) - (d.behaviour >> TURN_LEFT & 1)
                    rand = (e.heading - d.heading - explicit) % 4
                    turns[i] = 1 if rand == 1 else (-1 if rand == 3 else 0)
            nxt[d.robot] = i
        return (
            np.array([d.frame for d in keep], dtype=np.int64),
            np.array([d.sensors for d in keep], dtype=np.int64).reshape(-1, N_SENSORS),
            np.array([d.behaviour for d in keep], dtype=np.int64),
            turns,
        )


def _check_types(bag: Bag, data: TrialData) -> set[str]:
    """Topics whose type differs from the suite's; they are skipped (and reported)."""
    bad = set()
    for name, info in bag.topics.items():
        m = _ROBOT_TOPIC.match(name)
        key = m.group(2) if m else name
        want = EXPECTED_TYPES.get(key)
        if want is not None and info.msgtype != want:
            data.problems.append(f"{name}: type = {info.msgtype!r}: expected {want}; skipped")
            bad.add(name)
    return bad


def read_trial(bag: Bag, height_unit: float | None = None) -> TrialData:
    """Read a trial's bag into :class:`TrialData` (never raises for bad messages)."""
    unit = height_unit
    if unit is None:
        try:
            unit = float(bag.custom_data.get("height_unit", 0.05))
        except (TypeError, ValueError):
            unit = 0.05
    data = TrialData(height_unit=unit, topics={t.name: t.count for t in bag.topics.values()})
    skip = _check_types(bag, data)
    robots = sorted(
        {int(m.group(1)) for t in bag.topics if (m := _ROBOT_TOPIC.match(t)) and t not in skip}
    )
    n = (max(robots) + 1) if robots else 0
    data.robots = n
    geometry = BladeGeometry()
    poses = np.full((n, 3), -1, dtype=np.int64)
    blade = [None] * n
    stuck = [None] * n
    memory = [0] * n
    heights_units: np.ndarray | None = None
    pending_poses: list[tuple[int, object]] = []
    problems: dict[str, int] = {}

    def problem(text: str) -> None:
        if text not in problems:
            data.problems.append(text)
        problems[text] = problems.get(text, 0) + 1

    def end_frame() -> None:
        if data.heights:
            blades = np.array([-1 if b is None else b[0] for b in blade], dtype=np.int64)
            data.poses.append(np.concatenate([poses, blades[:, None]], axis=1).copy())

    camera = next((t for t in CAMERA_TOPICS if data.topics.get(t) and t not in skip), None)
    data.camera_topic = camera
    count = data.topics.get(camera, 0)
    picks = {round(j * (count - 1) / max(CAMERA_FRAMES - 1, 1)) for j in range(CAMERA_FRAMES)}
    wanted = [t for t in bag.topics if t not in skip]
    for topic, _ts, raw in bag.messages(wanted):
        m = _ROBOT_TOPIC.match(topic)
        if not (m or topic in (HEIGHTS, GOAL, ZONES, MAP_INFO, FITNESS, camera)):
            continue
        try:
            msg = bag.decode(topic, raw)
        except FieldError as exc:
            problem(str(exc))
            continue
        try:
            if topic == camera:
                index = len(data.camera_times)
                stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
                data.camera_times.append(stamp)
                data.camera_bytes.append(len(msg.data))
                if index in picks:
                    image = frame_array(msg, CAMERA_TOPICS[topic], topic)
                    data.camera_frames.append((index, stamp, image))
            elif topic == MAP_INFO:
                data.cell_size = float(msg.resolution) if msg.resolution > 0 else None
                for k, pmsg in pending_poses:
                    poses[k] = pose_to_grid(pmsg, data.cell_size, f"/robot_{k}/pose")
                pending_poses.clear()
            elif topic == ZONES:
                data.zones = image_to_grid(msg, "mono8", topic)
            elif topic == GOAL:
                data.goal = image_to_grid(msg, "32FC1", topic).astype(np.float64)
            elif topic == HEIGHTS:
                grid = image_to_grid(msg, "32FC1", topic).astype(np.float64)
                end_frame()
                data.heights.append(grid)
                data.frame_times.append(msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9)
                data.fitness.append(float("nan"))
                heights_units = heights_to_units(grid, unit)
            elif topic == FITNESS:
                if data.fitness:
                    data.fitness[-1] = float(msg.data)
            elif m:
                k, kind = int(m.group(1)), m.group(2)
                if kind == "pose":
                    if data.cell_size is None:
                        pending_poses.append((k, msg))
                    else:
                        poses[k] = pose_to_grid(msg, data.cell_size, topic)
                elif kind == "blade/joint_states":
                    blade[k] = blade_from_joint(msg, geometry, topic)
                elif kind == "stuck":
                    stuck[k] = bool(msg.data)
                elif kind == "behaviour":
                    mask = int(msg.data) & 0xFFF
                    codes = _sense(data, heights_units, poses, k, blade[k], stuck[k], memory[k])
                    data.decisions.append(
                        Decision(len(data.heights) - 1, k, mask, codes, int(poses[k, 2]))
                    )
                    memory[k] = int(next_memory(memory[k], mask))
        except FieldError as exc:
            problem(str(exc))
    end_frame()
    for text, times in problems.items():
        if times > 1:
            data.problems[data.problems.index(text)] = f"{text} ({times} messages)"
    return data


def _sense(data, heights_units, poses, k, blade, stuck, memory) -> np.ndarray | None:
    """Robot k's sensor vector from the latest inputs, or None when one is missing."""
    if (
        heights_units is None
        or data.zones is None
        or data.goal is None
        or blade is None
        or stuck is None
        or (poses[:, 0] < 0).any()
        or heights_units.shape != data.zones.shape
        or data.goal.shape != data.zones.shape
    ):
        return None
    row, col, heading = (int(v) for v in poses[k])
    rows, cols = heights_units.shape
    if not (0 <= row < rows - 1 and 0 <= col < cols - 1):
        return None
    window = heights_units[max(row - 2, 0) : row + 4, max(col - 2, 0) : col + 4]
    if (window == UNKNOWN_UNITS).any():
        return None
    return sensor_vector(
        heights_units,
        data.zones,
        data.goal_units,
        poses,
        k,
        blade=blade[0],
        load_volume=blade[1],
        stuck=stuck,
        tilted=bool(is_tilted_down(heights_units, row, col, heading)),
        memory=bool(memory),
    )
