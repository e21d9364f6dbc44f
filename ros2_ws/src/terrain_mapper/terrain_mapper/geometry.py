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

A real mount is never set up perfectly level and square. Its base's orientation errors are
the *mount offsets* ``(pan_offset, tilt_offset, roll_offset)``: a turn of the whole mount
about the vertical (yaw), about the east axis (pitch) and about the north axis (roll),
applied after the joints: ``R = Rz(pan_offset) Ry(roll_offset) Rx(tilt_offset) Rz(pan)
Rx(tilt) base``. ``calibrate_mount`` fits tilt and roll offsets from a sweep of the flat
floor (a yaw error leaves a flat floor flat, so ``pan_offset`` is measured against a
landmark and entered by hand).
"""

from __future__ import annotations

import numpy as np

PAN_JOINT = "laser_pan"
TILT_JOINT = "laser_tilt"


NO_OFFSETS = (0.0, 0.0, 0.0)
"""A perfectly set-up mount: ``(pan_offset, tilt_offset, roll_offset)``, radians."""


def _rz(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _rx(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _ry(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


_BASE = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [-1.0, 0.0, 0.0]])  # x down, y east


def mount_rotation(
    pan: float, tilt: float, offsets: tuple[float, float, float] = NO_OFFSETS
) -> np.ndarray:
    """Rotation whose columns are the laser frame's x, y, z axes in ``map``.

    Args:
        pan: Pan joint angle, radians.
        tilt: Tilt joint angle, radians.
        offsets: The mount's ``(pan_offset, tilt_offset, roll_offset)``, radians.
    """
    rot = _rz(pan) @ _rx(tilt) @ _BASE
    if any(offsets):
        yaw, pitch, roll = offsets
        rot = _rz(yaw) @ _ry(roll) @ _rx(pitch) @ rot
    return rot


def beam_directions(
    pan: float,
    tilt: float,
    angles: np.ndarray,
    offsets: tuple[float, float, float] = NO_OFFSETS,
) -> np.ndarray:
    """Unit directions ``[n, 3]`` in ``map`` of the beams at scan ``angles`` (radians)."""
    rot = mount_rotation(pan, tilt, offsets)
    a = np.asarray(angles, dtype=np.float64)
    local = np.column_stack([np.cos(a), np.sin(a), np.zeros_like(a)])
    return local @ rot.T


def yaw_of(q) -> float:
    """Yaw (radians, about z) of a ``geometry_msgs/Quaternion``-like ``q`` (x, y, z, w)."""
    return float(np.arctan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z)))
