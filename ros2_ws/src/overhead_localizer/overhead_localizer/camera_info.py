"""``sensor_msgs/CameraInfo`` as the camera's intrinsics (no ``rclpy``; messages duck-typed).

A camera driver publishes its intrinsics (``K``, ``D``, image size) on ``camera_info``.
They describe the lens only: where the camera hangs over the worksite (``rvec``, ``tvec``)
comes from the calibration file (``calibrate`` fits it from marks on the floor). A pose
belongs to the intrinsics it was fitted under, so :func:`choose_model` takes the driver's
K and D only when they agree with the file's (within :data:`TOLERANCE_PX`; a file fitted
with ``calibrate --camera-info`` holds the driver's own) and otherwise keeps the file's
and says why: an uncalibrated driver (K all zero, :data:`ZERO_K`), a CameraInfo that is
not a camera model, or intrinsics other than the ones the pose was fitted with.
:func:`with_camera_info` returns the file's model with the message's intrinsics;
``plumb_bob`` (4 or 5 coefficients) and ``rational_polynomial`` (8) are the distortion
models OpenCV reads directly. :func:`load_camera_info` reads the CameraInfo YAML that
camera drivers write (``camera_calibration_parsers``: ``image_width``, ``camera_matrix``,
``distortion_coefficients``, ...).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import SimpleNamespace

import cv2
import numpy as np

from excavation_common.loaders import load_yaml
from overhead_localizer.camera_model import FROM_CAMERA_INFO, CameraModel
from overhead_localizer.errors import ImageError, LocalizerConfigError

TOLERANCE_PX = 0.5
"""Largest pixel shift between the driver's intrinsics and the file's that counts as equal
(over a grid of the image, corners included); below the calibration's own error."""

KEEP = "using the calibration file's intrinsics"

ZERO_K = f"camera_info K is zero (uncalibrated driver): {KEEP}"
"""The warning for a driver that publishes CameraInfo without a calibration."""

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


def k_is_zero(msg) -> bool:
    """The CameraInfo's K is all zeros: the driver has no calibration."""
    k = np.asarray(msg.k, dtype=np.float64).ravel()
    return k.size == 9 and not k.any()


def difference_px(model: CameraModel, width: int, height: int, k, d) -> float:
    """Largest pixel shift over the image between intrinsics ``(k, d)`` and ``model``'s.

    A pixel's ray under ``(k, d)`` is projected with the model's intrinsics, over a 9 x 9
    grid of the image (corners and edges included, where the distortion differs most).
    Infinite when the image sizes differ.
    """
    if (width, height) != (model.width, model.height):
        return float("inf")
    u, v = np.meshgrid(np.linspace(0, width - 1, 9), np.linspace(0, height - 1, 9))
    px = np.column_stack([u.ravel(), v.ravel()]).reshape(-1, 1, 2)
    norm = cv2.undistortPoints(px, np.asarray(k, np.float64), np.asarray(d, np.float64))
    rays = np.concatenate([norm.reshape(-1, 2), np.ones((len(px), 1))], axis=1)
    back, _ = cv2.projectPoints(
        rays, np.zeros(3), np.zeros(3), model.camera_matrix, model.dist_coeffs
    )
    return float(np.hypot(*(back.reshape(-1, 2) - px.reshape(-1, 2)).T).max())


def choose_model(
    model: CameraModel, msg, topic: str = "/overhead/camera_info"
) -> tuple[CameraModel, str | None]:
    """The model to localize with under a CameraInfo, and a warning (``None``: all well).

    ``model`` is the calibration file's. The message's intrinsics replace its own only
    when they agree within :data:`TOLERANCE_PX`; otherwise the file's are kept (its pose
    was fitted with them) and the warning says why: K zero (:data:`ZERO_K`), a CameraInfo
    that is not a usable camera model, another image size, or other intrinsics.
    """
    if k_is_zero(msg):
        return model, ZERO_K
    try:
        width, height, k, d = intrinsics(msg, topic)
    except ImageError as exc:
        return model, f"camera_info unusable ({exc}): {KEEP}"
    if (width, height) != (model.width, model.height):
        return model, (
            f"camera_info is for {width} x {height} images, the calibration for "
            f"{model.width} x {model.height}: {KEEP}"
        )
    shift = difference_px(model, width, height, k, d)
    if shift <= TOLERANCE_PX:
        return dataclasses.replace(model, camera_matrix=k, dist_coeffs=d), None
    if model.intrinsics == FROM_CAMERA_INFO:
        why = (
            "the driver's calibration changed since `calibrate --camera-info`; "
            "re-run it with the driver's current camera_info YAML"
        )
    else:
        why = (
            "the camera pose was fitted with the file's; to use the driver's, "
            "re-run `calibrate --camera-info` with its camera_info YAML"
        )
    return model, (
        f"camera_info K/D differ from the calibration file's by up to {shift:.2f} px "
        f"(tolerance {TOLERANCE_PX} px): {KEEP} ({why})"
    )


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
    d = np.asarray(model.dist_coeffs, dtype=np.float64).ravel()
    p = np.column_stack([k, np.zeros(3)])
    return {
        "width": int(model.width),
        "height": int(model.height),
        "distortion_model": "rational_polynomial" if len(d) == 8 else "plumb_bob",
        "k": k.ravel().tolist(),
        "d": d.tolist(),
        "r": np.eye(3).ravel().tolist(),
        "p": p.ravel().tolist(),
    }


def _yaml_matrix(path: str, doc: dict, key: str, rows: int | None, cols: int | None) -> np.ndarray:
    """A ``{rows, cols, data}`` matrix of a camera_calibration_parsers YAML."""
    value = doc.get(key)
    if not isinstance(value, dict) or not isinstance(value.get("data"), list):
        raise LocalizerConfigError(path, key, value, "expected {rows, cols, data: [...]}")
    r, c = value.get("rows"), value.get("cols")
    try:
        data = np.array(value["data"], dtype=np.float64)
    except (TypeError, ValueError):
        raise LocalizerConfigError(path, f"{key}.data", value["data"], "expected numbers") from None
    ok = all(isinstance(n, int) and not isinstance(n, bool) and n >= 0 for n in (r, c))
    ok = ok and (rows is None or r == rows) and (cols is None or c == cols)
    if not ok or data.shape != (r * c,) or not np.isfinite(data).all():
        shape = f"{rows or 'n'} x {cols or 'n'}"
        raise LocalizerConfigError(
            path, key, value, f"expected {shape} finite numbers (rows x cols = len(data))"
        )
    return data


def load_camera_info(path: str | Path):
    """A CameraInfo YAML as a camera driver writes it, as a CameraInfo-like object.

    The ``camera_calibration_parsers`` format (``image_width``, ``image_height``,
    ``camera_name``, ``camera_matrix``, ``distortion_model``, ``distortion_coefficients``,
    ``rectification_matrix``, ``projection_matrix``; the last two are not needed here).
    The result has ``width``, ``height``, ``k``, ``d``, ``distortion_model`` and
    ``camera_name``, checked as :func:`intrinsics` checks a message.

    Raises:
        LocalizerConfigError: Missing file, a missing or malformed field, K zero (an
            uncalibrated camera) or not a camera matrix, an unreadable distortion model.
    """
    where = str(path)
    if not Path(path).exists():
        raise LocalizerConfigError(where, "file", None, "does not exist")
    doc = load_yaml(path, LocalizerConfigError)
    if not isinstance(doc, dict):
        raise LocalizerConfigError(where, "<root>", type(doc).__name__, "expected a mapping")
    size = []
    for key in ("image_width", "image_height"):
        value = doc.get(key)
        if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
            raise LocalizerConfigError(where, key, value, "expected a positive integer")
        size.append(value)
    k = _yaml_matrix(where, doc, "camera_matrix", 3, 3)
    d = _yaml_matrix(where, doc, "distortion_coefficients", 1, None)
    model = doc.get("distortion_model", "plumb_bob" if len(d) else "")
    if not isinstance(model, str):
        raise LocalizerConfigError(where, "distortion_model", model, "expected a name")
    info = SimpleNamespace(
        width=size[0],
        height=size[1],
        k=k.tolist(),
        d=d.tolist(),
        distortion_model=model,
        camera_name=str(doc.get("camera_name", "")),
    )
    if k_is_zero(info):
        raise LocalizerConfigError(
            where, "camera_matrix", k.tolist(), "is zero: the camera has no calibration"
        )
    try:
        intrinsics(info, where)
    except ImageError as exc:
        raise LocalizerConfigError(where, exc.field, exc.value, exc.reason) from None
    return info


def camera_info_yaml(model: CameraModel, camera_name: str = "overhead_camera") -> str:
    """The CameraInfo YAML of a model's intrinsics, as ``camera_calibration_parsers`` writes it."""
    f = camera_info_fields(model)
    d = f["d"]
    lines = [
        f"image_width: {f['width']}",
        f"image_height: {f['height']}",
        f"camera_name: {camera_name}",
        "camera_matrix:",
        "  rows: 3",
        "  cols: 3",
        f"  data: [{', '.join(repr(float(v)) for v in f['k'])}]",
        f"distortion_model: {'rational_polynomial' if len(d) == 8 else 'plumb_bob'}",
        "distortion_coefficients:",
        "  rows: 1",
        f"  cols: {len(d)}",
        f"  data: [{', '.join(repr(float(v)) for v in d)}]",
        "rectification_matrix:",
        "  rows: 3",
        "  cols: 3",
        f"  data: [{', '.join(repr(float(v)) for v in f['r'])}]",
        "projection_matrix:",
        "  rows: 3",
        "  cols: 4",
        f"  data: [{', '.join(repr(float(v)) for v in f['p'])}]",
    ]
    return "\n".join(lines) + "\n"
