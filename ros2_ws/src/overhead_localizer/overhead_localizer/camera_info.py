"""``sensor_msgs/CameraInfo`` as the camera's intrinsics (no ``rclpy``; messages duck-typed).

A camera driver publishes its calibrated intrinsics (``K``, ``D``, image size) on
``camera_info``. They describe the lens only: where the camera hangs over the worksite
(``rvec``, ``tvec``) still comes from the calibration file (``calibrate`` fits it from marks
on the floor). :func:`with_camera_info` returns the file's model with the message's
intrinsics; ``plumb_bob`` (4 or 5 coefficients) and ``rational_polynomial`` (8) are the
distortion models OpenCV reads directly.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from overhead_localizer.camera_model import CameraModel
from overhead_localizer.errors import ImageError

DISTORTION_MODELS = {"plumb_bob": (4, 5), "rational_polynomial": (8,), "": (0, 4, 5)}
"""CameraInfo ``distortion_model`` -> the numbers of coefficients accepted."""


def intrinsics(
    msg, topic: str = "/overhead/camera_info"
) -> tuple[int, int, np.ndarray, np.ndarray]:
    """``(width, height, K [3, 3], D)`` of a CameraInfo message.

    Raises:
        ImageError: A non-positive size or focal length, non-finite numbers, or a
            distortion model OpenCV's pinhole model does not read.
    """
    width, height = int(msg.width), int(msg.height)
    if width <= 0 or height <= 0:
        raise ImageError(topic, "width/height", (width, height), "must be > 0")
    k = np.asarray(msg.k, dtype=np.float64).reshape(3, 3)
    if not np.isfinite(k).all() or k[0, 0] <= 0 or k[1, 1] <= 0 or k[2, 2] != 1.0:
        raise ImageError(topic, "k", k.ravel().tolist(), "expected a camera matrix, fx, fy > 0")
    d = np.asarray(msg.d, dtype=np.float64).ravel()
    model = str(msg.distortion_model)
    sizes = DISTORTION_MODELS.get(model)
    if sizes is None:
        raise ImageError(
            topic,
            "distortion_model",
            model,
            f"expected one of {sorted(m for m in DISTORTION_MODELS if m)}",
        )
    if len(d) not in sizes or not np.isfinite(d).all():
        raise ImageError(
            topic, "d", d.tolist(), f"{model or 'no model'} takes {sizes} finite numbers"
        )
    if len(d) < 5:
        d = np.concatenate([d, np.zeros(5 - len(d))])
    return width, height, k, d


def with_camera_info(model: CameraModel, msg, topic: str = "/overhead/camera_info") -> CameraModel:
    """``model`` (from the calibration file) with the intrinsics of a CameraInfo message.

    Raises:
        ImageError: As :func:`intrinsics`.
    """
    width, height, k, d = intrinsics(msg, topic)
    return dataclasses.replace(model, width=width, height=height, camera_matrix=k, dist_coeffs=d)


def camera_info_fields(model: CameraModel) -> dict:
    """The CameraInfo fields of a model, as a driver calibrated with the same lens sends them.

    Returns ``width``, ``height``, ``distortion_model``, ``k``, ``d``, ``r`` and ``p``.
    """
    k = np.asarray(model.camera_matrix, dtype=np.float64)
    p = np.column_stack([k, np.zeros(3)])
    return {
        "width": int(model.width),
        "height": int(model.height),
        "distortion_model": "plumb_bob",
        "k": k.ravel().tolist(),
        "d": np.asarray(model.dist_coeffs, dtype=np.float64).ravel().tolist(),
        "r": np.eye(3).ravel().tolist(),
        "p": p.ravel().tolist(),
    }
