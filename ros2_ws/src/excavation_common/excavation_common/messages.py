"""Conversions between the suite's ROS messages and the arrays of the pure core.

Only message types (common_interfaces) are imported here, never ``rclpy``, so every
function is testable by building messages in memory. Conventions (``docs/interfaces.md``):

* **Grid images** (``/worksite/height_map`` 32FC1, ``/blueprint/goal`` 32FC1,
  ``/blueprint/zones`` mono8): one pixel per cell, pixel row ``v`` = grid row (``v = 0`` is
  the *southern* edge, like ``nav_msgs/OccupancyGrid``), pixel column ``u`` = grid column.
  Heights and goals are metres; NaN = unknown.
* **Poses** (``PoseWithCovarianceStamped`` in ``map``): the robot's centre (the shared corner
  of its 2 x 2 footprint) and its yaw; :func:`pose_to_grid` snaps them to the footprint
  anchor and the nearest cardinal heading.
* **Blade** (``JointState``, joint ``blade``): position = blade edge height relative to the
  wheels in metres (below ``-depth``, level 0, above ``+depth``, home ``+home``), effort =
  push force in newtons; :func:`blade_from_joint` maps them to the B1 code and the soil
  volume that gives L1.
* **IMU** (``sensor_msgs/Imu`` in ``robot_k/base_link``): the orientation quaternion of
  the body (x forward, y left, z up, REP-103) in the world; :func:`imu_message` builds it
  from yaw and pitch, :func:`imu_pitch` returns the nose-down pitch that gives R1.
"""

from __future__ import annotations

import math

import numpy as np
from excavation_interfaces.msg import DriveStatus
from geometry_msgs.msg import PoseWithCovarianceStamped
from nav_msgs.msg import MapMetaData
from sensor_msgs.msg import Image, Imu, JointState

from excavation_common.constants import MAX_LOAD, BladeGeometry
from excavation_common.errors import FieldError
from excavation_common.frames import heading_to_yaw, robot_anchor, robot_center, yaw_to_heading
from excavation_common.limits import MAX_GRID_CELLS, MAX_GRID_SIDE

DRIVE_ENDED = (
    DriveStatus.STATUS_SUCCEEDED,
    DriveStatus.STATUS_ABORTED,
    DriveStatus.STATUS_CANCELED,
)
"""``DriveStatus`` codes of a drive goal that has ended (``action_msgs/GoalStatus``'s terminal
states): the executor reports one per goal, the team tick, ``dynamics`` and the field report
read it."""

_ENCODINGS = {"32FC1": (np.float32, 4), "mono8": (np.uint8, 1)}


class MessageError(FieldError):
    """A message cannot be used (wrong encoding, size, frame ...): ``topic: field = value``."""


def grid_to_image(grid: np.ndarray, encoding: str, frame_id: str = "map", stamp=None) -> Image:
    """A 2-D grid as an ``Image`` (``32FC1`` or ``mono8``), row 0 first (south)."""
    dtype, size = _ENCODINGS[encoding]
    arr = np.ascontiguousarray(grid, dtype=dtype)
    msg = Image()
    if stamp is not None:
        msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.height, msg.width = arr.shape
    msg.encoding = encoding
    msg.is_bigendian = 0
    msg.step = arr.shape[1] * size
    msg.data = arr.tobytes()
    return msg


def image_to_grid(
    msg: Image, encoding: str, topic: str = "<image>", shape: tuple[int, int] | None = None
) -> np.ndarray:
    """Decode a grid image, checking encoding, byte order, step, size and (optional) shape.

    Raises:
        MessageError: Naming the topic, the field and the value at fault.
    """
    if msg.encoding != encoding:
        raise MessageError(topic, "encoding", msg.encoding, f"expected {encoding}")
    dtype, size = _ENCODINGS[encoding]
    if msg.is_bigendian and size > 1:
        raise MessageError(topic, "is_bigendian", msg.is_bigendian, "big-endian is not supported")
    if msg.step != msg.width * size:
        raise MessageError(topic, "step", msg.step, f"expected width x {size} = {msg.width * size}")
    if len(msg.data) != msg.height * msg.step:
        raise MessageError(
            topic,
            "data",
            f"{len(msg.data)} bytes",
            f"expected height x step = {msg.height * msg.step}",
        )
    if max(msg.height, msg.width) > MAX_GRID_SIDE or msg.height * msg.width > MAX_GRID_CELLS:
        raise MessageError(
            topic,
            "height x width",
            (msg.height, msg.width),
            f"exceeds the grid limits ({MAX_GRID_SIDE} a side, {MAX_GRID_CELLS} cells)",
        )
    if shape is not None and (msg.height, msg.width) != tuple(shape):
        raise MessageError(
            topic,
            "height x width",
            (msg.height, msg.width),
            f"the worksite is {shape[0]} x {shape[1]} cells",
        )
    return np.frombuffer(bytes(msg.data), dtype=dtype).reshape(msg.height, msg.width).copy()


def map_info(rows: int, cols: int, cell_size: float, stamp=None) -> MapMetaData:
    """``MapMetaData`` of the worksite grid (origin at the map origin, no rotation)."""
    msg = MapMetaData()
    if stamp is not None:
        msg.map_load_time = stamp
    msg.resolution = float(cell_size)
    msg.width = int(cols)
    msg.height = int(rows)
    return msg


def pose_message(
    row: int,
    col: int,
    heading: int,
    cell_size: float,
    variance_xy: float,
    variance_yaw: float,
    stamp=None,
) -> PoseWithCovarianceStamped:
    """A robot pose in ``map`` from its footprint anchor and heading, with a covariance."""
    msg = PoseWithCovarianceStamped()
    if stamp is not None:
        msg.header.stamp = stamp
    msg.header.frame_id = "map"
    x, y = robot_center(row, col, cell_size)
    msg.pose.pose.position.x = x
    msg.pose.pose.position.y = y
    yaw = heading_to_yaw(heading)
    msg.pose.pose.orientation.z = math.sin(yaw / 2)
    msg.pose.pose.orientation.w = math.cos(yaw / 2)
    cov = np.zeros(36)
    cov[0] = cov[7] = variance_xy
    cov[14] = cov[21] = cov[28] = 1e6  # z, roll, pitch: not estimated
    cov[35] = variance_yaw
    msg.pose.covariance = cov
    return msg


def pose_to_grid(
    msg: PoseWithCovarianceStamped, cell_size: float, topic: str = "<pose>"
) -> tuple[int, int, int]:
    """``(row, col, heading)`` of a pose message in the ``map`` frame.

    Raises:
        MessageError: Wrong frame or a non-finite position or orientation.
    """
    if msg.header.frame_id != "map":
        raise MessageError(topic, "header.frame_id", msg.header.frame_id, "expected 'map'")
    p = msg.pose.pose.position
    q = msg.pose.pose.orientation
    values = (p.x, p.y, q.x, q.y, q.z, q.w)
    if not all(math.isfinite(v) for v in values):
        raise MessageError(topic, "pose", values, "must be finite")
    yaw = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))
    row, col = robot_anchor(p.x, p.y, cell_size)
    return row, col, yaw_to_heading(yaw)


def blade_joint(blade: int, force: float, geometry: BladeGeometry, stamp=None) -> JointState:
    """The ``blade`` joint state for a blade code and push force."""
    msg = JointState()
    if stamp is not None:
        msg.header.stamp = stamp
    msg.name = ["blade"]
    msg.position = [geometry.position(blade)]
    msg.velocity = []
    msg.effort = [float(force)]
    return msg


def blade_from_joint(
    msg: JointState, geometry: BladeGeometry, topic: str = "<joint_states>"
) -> tuple[int, int]:
    """``(B1 code, soil volume for L1)`` from a joint state holding the ``blade`` joint.

    The code is the setting nearest to the joint position; the volume is the force
    rescaled so that ``max_force`` gives ``MAX_LOAD`` units (negative forces count as 0).

    Raises:
        MessageError: No ``blade`` joint, or a non-finite position or effort.
    """
    if "blade" not in msg.name:
        raise MessageError(topic, "name", list(msg.name), "has no 'blade' joint")
    i = list(msg.name).index("blade")
    if i >= len(msg.position) or i >= len(msg.effort):
        raise MessageError(
            topic,
            "position/effort",
            (len(msg.position), len(msg.effort)),
            "missing the blade's entry",
        )
    pos, force = float(msg.position[i]), float(msg.effort[i])
    if not (math.isfinite(pos) and math.isfinite(force)):
        raise MessageError(topic, "blade", (pos, force), "position and effort must be finite")
    blade = geometry.nearest(pos)
    volume = int(round(max(force, 0.0) / geometry.max_force * MAX_LOAD))
    return blade, volume


HALF_SLACK = 3e-5
"""Units: a height this close below a half counts as the half (metres carry float error)."""


def heights_to_units(heights_m: np.ndarray, height_unit: float) -> np.ndarray:
    """Metres to whole soil units, halves up; NaN stays unknown as ``INT32_MIN``.

    Halves round up, as the simulator rounds the physical soil's cell means
    (``excavation_sim.soil.round_heights``), so a controller reading a height map through
    this conversion senses what the offline world senses (``np.round`` would take halves
    to even: 0.5 -> 0 where the world says 1). ``HALF_SLACK`` absorbs the float error of
    a half that went through metres (a float32 height map holds about 7 digits: at 300
    units a half may come back 2e-5 low; the physical soil's cell means step by
    1 / (16 x 1000) = 6e-5 units, so no other value moves).
    """
    units = np.full(heights_m.shape, np.iinfo(np.int32).min, dtype=np.int32)
    known = np.isfinite(heights_m)
    units[known] = np.floor(heights_m[known] / height_unit + 0.5 + HALF_SLACK).astype(np.int32)
    return units


def imu_message(yaw: float, pitch: float, frame_id: str, stamp=None) -> Imu:
    """An IMU orientation: ``yaw`` about z (counter-clockwise from east), then ``pitch``.

    ``pitch`` turns about the body's y axis (left), so a positive pitch is nose down. Only
    the orientation is filled in (rates and accelerations unknown: covariance ``-1``).
    """
    msg = Imu()
    if stamp is not None:
        msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    msg.orientation.w, msg.orientation.x = cy * cp, -sy * sp
    msg.orientation.y, msg.orientation.z = cy * sp, sy * cp
    msg.angular_velocity_covariance[0] = -1.0
    msg.linear_acceleration_covariance[0] = -1.0
    return msg


def imu_pitch(msg: Imu, topic: str = "<imu>") -> float:
    """Nose-down pitch (rad) of an IMU orientation: how far the body's x axis points down.

    ``asin`` of minus the world z component of the body's forward axis, so it does not
    depend on yaw, and a pure roll (one side lower) gives 0, whatever order of rotations
    the IMU's driver composes.

    Raises:
        MessageError: Orientation marked unknown (``orientation_covariance[0] == -1``, the
            message's convention), non-finite, or not a rotation (norm far from 1).
    """
    if msg.orientation_covariance[0] == -1.0:
        raise MessageError(topic, "orientation_covariance[0]", -1.0, "no orientation estimate")
    q = msg.orientation
    values = (q.w, q.x, q.y, q.z)
    if not all(math.isfinite(v) for v in values):
        raise MessageError(topic, "orientation", values, "must be finite")
    norm = math.sqrt(sum(v * v for v in values))
    if abs(norm - 1.0) > 0.1:
        raise MessageError(topic, "orientation", values, "is not a unit quaternion")
    w, x, y, z = (v / norm for v in values)
    return math.asin(max(-1.0, min(1.0, 2.0 * (w * y - x * z))))
