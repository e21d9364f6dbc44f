"""The overhead laser's pan/tilt mount: scan angles -> beam directions in ``map`` (paper, 6.2).

The line scanner sits on a pan/tilt unit above the worksite (``mount``: its centre in
``map``, metres). Its scan plane at ``pan = tilt = 0`` is the vertical plane through the
east axis: the beam at scan angle ``a`` (``sensor_msgs/LaserScan`` convention, about the
laser frame's z axis) points ``cos a`` down and ``sin a`` east. Tilt turns that plane about
the east axis (positive: towards north), pan then turns everything about the vertical
(positive: counter-clockwise seen from above). A sweep steps the tilt from one end to the
other; each scan travels with the mount's pan and tilt joint state (joints ``laser_pan`` /
``laser_tilt`` unless the mapper's ``pan_joint`` / ``tilt_joint`` name others).

The laser frame (for RViz or a PoseStamped): x = the beam at ``a = 0``, y = the beam at
``a = +pi/2``, z = x cross y. Shared by the mapper and the simulator's laser.

A real mount is never set up perfectly level and square. Its base's orientation errors are
the *mount offsets* ``(pan_offset, tilt_offset, roll_offset)``: a turn of the whole mount
about the vertical (yaw), about the east axis (pitch) and about the north axis (roll),
applied after the joints: ``R = Rz(pan_offset) Ry(roll_offset) Rx(tilt_offset) Rz(pan)
Rx(tilt) base``. ``calibrate_mount`` fits tilt and roll offsets from a sweep of the flat
floor (a yaw error leaves a flat floor flat, so ``pan_offset`` is measured against a
landmark and entered by hand).

A real scanner is not mounted exactly as above. Two more settings describe it (both leave
the geometry above unchanged at their defaults):

* **Lever arm** ``lever``: the scanner's optical centre, metres, in the *tilting frame*,
  the frame that turns with the pan and tilt joints (and the mount offsets) and whose axes
  are ``map``'s east, north and up at ``pan = tilt = 0``. Its origin is the pan/tilt centre
  ``mount``; a scanner hanging 8 cm below the tilt axis has ``lever = (0, 0, -0.08)``. The
  beams start there: ``origin = mount + R_joints lever``, with ``R_joints = Rz(pan_offset)
  Ry(roll_offset) Rx(tilt_offset) Rz(pan) Rx(tilt)`` (:func:`tilting_rotation`).
* **Upside down** ``flip``: the scanner turned over about its centre beam (the laser
  frame's x axis). Its driver still reports angles in the scanner's own frame, so the beam
  it calls ``a`` goes where an upright scanner's beam ``-a`` would (the scan mirrored east
  to west; its beams in reversed angular order).

A nodding mount keeps moving while the scanner's mirror turns: beam ``i`` of a scan is
taken ``i * time_increment`` after the scan's stamp, so every beam may have its own pan and
tilt. :func:`beam_rays` takes per-beam angles (arrays) as well as one pair for the scan.
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


NO_LEVER = (0.0, 0.0, 0.0)
"""A scanner whose optical centre is the pan/tilt centre: ``(x, y, z)`` in the tilting frame."""


def tilting_rotation(
    pan: float, tilt: float, offsets: tuple[float, float, float] = NO_OFFSETS
) -> np.ndarray:
    """Rotation from the tilting frame (``map`` axes at ``pan = tilt = 0``) to ``map``."""
    rot = _rz(pan) @ _rx(tilt)
    if any(offsets):
        yaw, pitch, roll = offsets
        rot = _rz(yaw) @ _ry(roll) @ _rx(pitch) @ rot
    return rot


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
    flip: bool = False,
) -> np.ndarray:
    """Unit directions ``[n, 3]`` in ``map`` of the beams at scan ``angles`` (radians).

    With ``flip`` the scanner is upside down: beam ``a`` goes where beam ``-a`` would.
    """
    rot = mount_rotation(pan, tilt, offsets)
    a = np.asarray(angles, dtype=np.float64)
    if flip:
        a = -a
    local = np.column_stack([np.cos(a), np.sin(a), np.zeros_like(a)])
    return local @ rot.T


def _stack_rz(a: np.ndarray) -> np.ndarray:
    c, s, z, o = np.cos(a), np.sin(a), np.zeros_like(a), np.ones_like(a)
    return np.stack(
        [np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2
    )


def _stack_rx(a: np.ndarray) -> np.ndarray:
    c, s, z, o = np.cos(a), np.sin(a), np.zeros_like(a), np.ones_like(a)
    return np.stack(
        [np.stack([o, z, z], -1), np.stack([z, c, -s], -1), np.stack([z, s, c], -1)], -2
    )


def beam_rays(
    pan: float | np.ndarray,
    tilt: float | np.ndarray,
    angles: np.ndarray,
    offsets: tuple[float, float, float] = NO_OFFSETS,
    lever: tuple[float, float, float] = NO_LEVER,
    flip: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """Where the beams start (relative to ``mount``) and their unit directions in ``map``.

    Args:
        pan: Pan joint angle, radians: one for the whole scan, or one per beam (``[n]``).
        tilt: Tilt joint angle, radians: one, or one per beam.
        angles: The beams' scan angles ``[n]``, radians.
        offsets: The mount's ``(pan_offset, tilt_offset, roll_offset)``, radians.
        lever: The optical centre in the tilting frame, metres.
        flip: The scanner is upside down.

    Returns:
        ``(origins, directions)``: origins ``[3]`` (one pair of angles) or ``[n, 3]`` (per
        beam), to be added to ``mount``; directions ``[n, 3]``. One pair of angles, no lever
        and no flip give exactly :func:`beam_directions` and a zero origin.
    """
    a = np.asarray(angles, dtype=np.float64)
    if np.ndim(pan) == 0 and np.ndim(tilt) == 0:
        dirs = beam_directions(float(pan), float(tilt), a, offsets, flip)
        origin = np.zeros(3)
        if any(lever):
            origin = tilting_rotation(float(pan), float(tilt), offsets) @ np.asarray(lever, float)
        return origin, dirs
    pans = np.broadcast_to(np.asarray(pan, dtype=np.float64), a.shape)
    tilts = np.broadcast_to(np.asarray(tilt, dtype=np.float64), a.shape)
    rot = _stack_rz(pans) @ _stack_rx(tilts)  # [n, 3, 3], the tilting frame per beam
    if any(offsets):
        yaw, pitch, roll = offsets
        rot = (_rz(yaw) @ _ry(roll) @ _rx(pitch)) @ rot
    if flip:
        a = -a
    local = np.column_stack([np.cos(a), np.sin(a), np.zeros_like(a)])
    dirs = np.einsum("nij,nj->ni", rot @ _BASE, local)
    origins = rot @ np.asarray(lever, dtype=np.float64)
    return origins, dirs


def laser_pose(
    pan: float,
    tilt: float,
    mount,
    offsets: tuple[float, float, float] = NO_OFFSETS,
    lever: tuple[float, float, float] = NO_LEVER,
    flip: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """``(origin, rotation)`` of the laser frame in ``map`` (the ``overhead_laser`` frame).

    ``origin``: the optical centre (``mount`` plus the lever arm turned by the joints);
    ``rotation``: columns are the laser frame's axes in ``map`` (x the beam at ``a = 0``, y
    the beam at ``a = +pi/2`` in the scanner's own angles, so turned over with ``flip``).
    """
    rot = mount_rotation(pan, tilt, offsets)
    if flip:
        rot = rot @ np.diag([1.0, -1.0, -1.0])
    origin = np.asarray(mount, dtype=np.float64) + tilting_rotation(
        pan, tilt, offsets
    ) @ np.asarray(lever, dtype=np.float64)
    return origin, rot


def yaw_of(q) -> float:
    """Yaw (radians, about z) of a ``geometry_msgs/Quaternion``-like ``q`` (x, y, z, w)."""
    return float(np.arctan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z)))
