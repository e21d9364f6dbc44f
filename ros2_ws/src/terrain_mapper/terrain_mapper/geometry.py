"""The overhead laser's pan/tilt mount: scan angles -> beam directions in ``map`` (paper, 6.2).

The line scanner sits on a pan/tilt unit above the worksite (``mount``: its centre in
``map``, metres). Its scan plane at ``pan = tilt = 0`` is the vertical plane through the
east axis: the beam at scan angle ``a`` (``sensor_msgs/LaserScan`` convention, about the
laser frame's z axis) points ``cos a`` down and ``sin a`` east. Tilt turns that plane about
the east axis (positive: towards north), pan then turns everything about the vertical
(positive: counter-clockwise seen from above). A sweep steps the tilt from one end to the
other; each scan travels with the mount's ``laser_pan`` / ``laser_tilt`` joint state.

The laser frame (for RViz or a PoseStamped): x = the beam at ``a = 0``, y = the beam at
``a = +pi/2``, z = x cross y. Shared by the mapper and the simulator's laser.
"""

from __future__ import annotations

import numpy as np

PAN_JOINT = "laser_pan"
TILT_JOINT = "laser_tilt"


def mount_rotation(pan: float, tilt: float) -> np.ndarray:
    """Rotation whose columns are the laser frame's x, y, z axes in ``map``."""
    cp, sp, ct, st = np.cos(pan), np.sin(pan), np.cos(tilt), np.sin(tilt)
    rz = np.array([[cp, -sp, 0.0], [sp, cp, 0.0], [0.0, 0.0, 1.0]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, ct, -st], [0.0, st, ct]])
    base = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [-1.0, 0.0, 0.0]])  # x down, y east
    return rz @ rx @ base


def beam_directions(pan: float, tilt: float, angles: np.ndarray) -> np.ndarray:
    """Unit directions ``[n, 3]`` in ``map`` of the beams at scan ``angles`` (radians)."""
    rot = mount_rotation(pan, tilt)
    a = np.asarray(angles, dtype=np.float64)
    local = np.column_stack([np.cos(a), np.sin(a), np.zeros_like(a)])
    return local @ rot.T


def yaw_of(q) -> float:
    """Yaw (radians, about z) of a ``geometry_msgs/Quaternion``-like ``q`` (x, y, z, w)."""
    return float(np.arctan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z)))
