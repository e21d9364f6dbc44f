"""The calibrated overhead camera: pixels <-> ``map`` points (paper, 6.2).

A :class:`CameraModel` is a pinhole camera with radial distortion (OpenCV's model: camera
matrix, ``k1, k2, p1, p2, k3``) and its pose over the worksite (``rvec``, ``tvec`` from
``map`` to the camera). On the ground plane (z = 0) the undistorted image and the map are
related by the homography ``H = K [r1 r2 t]``, which the calibration file also stores; an
LED at height ``z`` is found by intersecting its pixel's ray with the plane at that height,
which is the same homography for the plane ``z`` (``K [r1 r2 z r3 + t]``).

:func:`calibrate` fits the model to marked points (pixels and their ``map`` coordinates,
ground markers at z = 0 and, better, a few at a known height such as a parked robot's LEDs)
and :func:`save_model` / :func:`load_model` write and read the YAML the localizer loads
(``format: overhead-camera/1``). :func:`fit_pose` fits the pose alone, under intrinsics
held fixed (a calibrated camera driver's K and D). The file records which intrinsics its
pose was fitted with (``intrinsics``: :data:`FROM_MARKS` or :data:`FROM_CAMERA_INFO`): a
pose belongs to the intrinsics it was fitted under. Pure module (numpy, OpenCV, PyYAML), no
``rclpy``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import cv2
import numpy as np
import yaml

from excavation_common.files import write_text_atomic
from excavation_common.limits import MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE
from excavation_common.loaders import load_yaml
from overhead_localizer.errors import LocalizerConfigError

FORMAT = "overhead-camera/1"

FROM_MARKS = "marks"
"""``intrinsics`` of a file whose intrinsics were fitted to the marks with the pose."""
FROM_CAMERA_INFO = "camera_info"
"""``intrinsics`` of a file whose pose was fitted under a camera driver's K and D."""
INTRINSICS = (FROM_MARKS, FROM_CAMERA_INFO)

DIST_SIZES = (5, 8)
"""Distortion coefficients a file may hold: plumb_bob (5) or rational_polynomial (8)."""


@dataclass(frozen=True)
class CameraModel:
    """Intrinsics, distortion and pose of the overhead camera.

    Attributes:
        width: Image width, pixels.
        height: Image height, pixels.
        camera_matrix: 3 x 3 intrinsic matrix.
        dist_coeffs: ``(k1, k2, p1, p2, k3)`` (OpenCV's order; 8 with ``k4, k5, k6``).
        rvec: Rotation ``map`` -> camera (Rodrigues vector).
        tvec: Translation ``map`` -> camera, metres.
        rms_px: Reprojection error of the calibration, pixels.
        intrinsics: Which intrinsics the pose was fitted with: :data:`FROM_MARKS` (fitted
            to the marks together with the pose) or :data:`FROM_CAMERA_INFO` (a camera
            driver's K and D, held fixed).
        intrinsics_file: The driver's CameraInfo YAML, for :data:`FROM_CAMERA_INFO`.
    """

    width: int
    height: int
    camera_matrix: np.ndarray
    dist_coeffs: np.ndarray
    rvec: np.ndarray
    tvec: np.ndarray
    rms_px: float = 0.0
    intrinsics: str = FROM_MARKS
    intrinsics_file: str = ""

    @cached_property
    def rotation(self) -> np.ndarray:
        """Rotation matrix ``map`` -> camera."""
        return cv2.Rodrigues(np.asarray(self.rvec, dtype=np.float64))[0]

    @cached_property
    def centre(self) -> np.ndarray:
        """Camera centre in ``map``, metres."""
        return -self.rotation.T @ np.asarray(self.tvec, dtype=np.float64)

    def homography(self, z: float = 0.0) -> np.ndarray:
        """Homography from the plane at height ``z`` (``map`` x, y) to undistorted pixels."""
        r = self.rotation
        h = self.camera_matrix @ np.column_stack([r[:, 0], r[:, 1], z * r[:, 2] + self.tvec])
        return h / h[2, 2]

    def project(self, points: np.ndarray) -> np.ndarray:
        """Distorted pixel coordinates ``[n, 2]`` of ``map`` points ``[n, 3]``."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 1, 3)
        px, _ = cv2.projectPoints(pts, self.rvec, self.tvec, self.camera_matrix, self.dist_coeffs)
        return px.reshape(-1, 2)

    def rays(self, pixels: np.ndarray) -> np.ndarray:
        """Unit-free ray directions ``[n, 3]`` in ``map`` through distorted pixels ``[n, 2]``."""
        px = np.asarray(pixels, dtype=np.float64).reshape(-1, 1, 2)
        norm = cv2.undistortPoints(px, self.camera_matrix, self.dist_coeffs).reshape(-1, 2)
        return np.column_stack([norm, np.ones(len(norm))]) @ self.rotation

    def to_map(self, pixels: np.ndarray, z: np.ndarray | float) -> np.ndarray:
        """``map`` ``(x, y)`` ``[n, 2]`` of pixels seen on the horizontal plane(s) at ``z``."""
        rays = self.rays(pixels)
        c = self.centre
        s = (np.asarray(z, dtype=np.float64) - c[2]) / rays[:, 2]
        return np.column_stack([c[0] + s * rays[:, 0], c[1] + s * rays[:, 1]])

    def metres_per_pixel(self, pixels: np.ndarray, z: np.ndarray | float) -> np.ndarray:
        """Ground distance of a one-pixel step at each pixel (mean of the u and v steps)."""
        px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        base = self.to_map(px, z)
        du = self.to_map(px + [1.0, 0.0], z) - base
        dv = self.to_map(px + [0.0, 1.0], z) - base
        return 0.5 * (np.hypot(du[:, 0], du[:, 1]) + np.hypot(dv[:, 0], dv[:, 1]))


def calibrate(
    image_points: np.ndarray,
    map_points: np.ndarray,
    size: tuple[int, int],
    focal: float | None = None,
    distortion: bool = True,
) -> CameraModel:
    """Fit the camera to marked points.

    Args:
        image_points: Pixels ``[n, 2]`` of the marks (as seen, distorted).
        map_points: Their ``map`` coordinates ``[n, 2]`` (on the ground) or ``[n, 3]``.
        size: ``(width, height)`` of the image.
        focal: Known focal length in pixels (fixed), or ``None`` to estimate it.
        distortion: Estimate radial distortion ``k1, k2`` (else none).

    Returns:
        The fitted model, with its reprojection error.

    Raises:
        ValueError: Fewer than 6 points, or shapes that do not match.
    """
    img, obj = _points(image_points, map_points)
    width, height = size
    guess = float(focal) if focal else float(max(width, height))
    k0 = np.array([[guess, 0, (width - 1) / 2], [0, guess, (height - 1) / 2], [0, 0, 1.0]])
    flags = (
        cv2.CALIB_USE_INTRINSIC_GUESS
        | cv2.CALIB_FIX_PRINCIPAL_POINT
        | cv2.CALIB_FIX_ASPECT_RATIO
        | cv2.CALIB_ZERO_TANGENT_DIST
        | cv2.CALIB_FIX_K3
    )
    if focal:
        flags |= cv2.CALIB_FIX_FOCAL_LENGTH
    if not distortion:
        flags |= cv2.CALIB_FIX_K1 | cv2.CALIB_FIX_K2
    # The pose first (planar PnP on the ground marks), then the joint refinement.
    rms, k, dist, rvecs, tvecs = cv2.calibrateCamera(
        [obj.astype(np.float32)],
        [img.astype(np.float32).reshape(-1, 1, 2)],
        (width, height),
        k0,
        np.zeros(5),
        flags=flags,
        criteria=(cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-12),
    )
    return CameraModel(
        int(width),
        int(height),
        k,
        dist.ravel()[:5],
        rvecs[0].ravel(),
        tvecs[0].ravel(),
        float(rms),
    )


def fit_pose(
    image_points: np.ndarray,
    map_points: np.ndarray,
    size: tuple[int, int],
    camera_matrix: np.ndarray,
    dist_coeffs: np.ndarray,
    intrinsics_file: str = "",
) -> CameraModel:
    """Fit the camera's pose to marked points under fixed intrinsics (a driver's K and D).

    SQPnP for a start, then Levenberg-Marquardt on the reprojection error; the intrinsics
    are not touched, so the model is exact for the driver that publishes them.

    Args:
        image_points: Pixels ``[n, 2]`` of the marks (as seen, distorted).
        map_points: Their ``map`` coordinates ``[n, 2]`` (on the ground) or ``[n, 3]``.
        size: ``(width, height)`` of the image.
        camera_matrix: The fixed 3 x 3 intrinsic matrix.
        dist_coeffs: The fixed distortion coefficients (OpenCV's order, 5 or 8).
        intrinsics_file: Where the intrinsics came from (recorded in the model).

    Returns:
        The model, ``intrinsics`` :data:`FROM_CAMERA_INFO`, with its reprojection error.

    Raises:
        ValueError: Fewer than 6 points, shapes that do not match, no pose found, or a pose
            that does not put the camera above every mark.
    """
    img, obj = _points(image_points, map_points)
    k = np.asarray(camera_matrix, dtype=np.float64).reshape(3, 3)
    d = np.asarray(dist_coeffs, dtype=np.float64).ravel()
    ok, rvec, tvec = cv2.solvePnP(obj, img.reshape(-1, 1, 2), k, d, flags=cv2.SOLVEPNP_SQPNP)
    if not ok:
        raise ValueError("no camera pose fits the marks under these intrinsics")
    rvec, tvec = cv2.solvePnPRefineLM(
        obj,
        img.reshape(-1, 1, 2),
        k,
        d,
        rvec,
        tvec,
        criteria=(cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-12),
    )
    width, height = size
    model = CameraModel(
        int(width),
        int(height),
        k,
        d,
        rvec.ravel(),
        tvec.ravel(),
        intrinsics=FROM_CAMERA_INFO,
        intrinsics_file=str(intrinsics_file),
    )
    depth = (obj @ model.rotation.T + model.tvec)[:, 2]
    if not (depth > 0).all():
        raise ValueError("the fitted pose puts marks behind the camera: check the marks")
    residual = model.project(obj) - img
    rms = float(np.sqrt((residual**2).sum(axis=1).mean()))
    return dataclasses.replace(model, rms_px=rms)


def _points(image_points: np.ndarray, map_points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(pixels [n, 2], map points [n, 3])`` as float64, checked.

    Raises:
        ValueError: Fewer than 6 points, or shapes that do not match.
    """
    img = np.asarray(image_points, dtype=np.float64).reshape(-1, 2)
    obj = np.asarray(map_points, dtype=np.float64)
    if obj.ndim == 2 and obj.shape[1] == 2:
        obj = np.column_stack([obj, np.zeros(len(obj))])
    if obj.shape != (len(img), 3):
        raise ValueError(f"{len(img)} pixels but map points of shape {obj.shape}")
    if len(img) < 6:
        raise ValueError(f"{len(img)} points: at least 6 are needed")
    return img, obj


def save_model(model: CameraModel, path: str | Path) -> None:
    """Write the calibration YAML the localizer loads (atomically)."""
    doc = {
        "format": FORMAT,
        "image_width": model.width,
        "image_height": model.height,
        "camera_matrix": np.asarray(model.camera_matrix).round(6).tolist(),
        "dist_coeffs": np.asarray(model.dist_coeffs).round(8).tolist(),
        "rvec": np.asarray(model.rvec).round(9).tolist(),
        "tvec": np.asarray(model.tvec).round(9).tolist(),
        "ground_homography": model.homography(0.0).round(9).tolist(),
        "camera_centre": model.centre.round(6).tolist(),
        "rms_px": round(float(model.rms_px), 6),
        "intrinsics": model.intrinsics,
    }
    if model.intrinsics_file:
        doc["intrinsics_file"] = model.intrinsics_file
    header = (
        "# Overhead camera calibration (overhead_localizer calibrate). ground_homography maps\n"
        "# map (x, y, 1) on the ground plane to undistorted pixels; camera_centre is in map.\n"
        "# intrinsics: the pose was fitted with intrinsics fitted to the marks (marks) or\n"
        "# with a camera driver's K and D held fixed (camera_info, from intrinsics_file).\n"
    )
    write_text_atomic(Path(path), header + yaml.safe_dump(doc, sort_keys=False))


def _matrix(where: str, doc: dict, key: str, shape: tuple[int, ...]) -> np.ndarray:
    value = doc.get(key)
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise LocalizerConfigError(
            where, key, value, f"expected numbers of shape {shape}"
        ) from None
    if arr.shape != shape or not np.isfinite(arr).all():
        raise LocalizerConfigError(where, key, value, f"expected finite numbers of shape {shape}")
    return arr


def load_model(path: str | Path) -> CameraModel:
    """Read a calibration YAML.

    Raises:
        LocalizerConfigError: Missing file, wrong format, a missing or malformed field.
    """
    where = str(path)
    if not Path(path).exists():
        raise LocalizerConfigError(
            where, "file", None, "does not exist (run `calibrate` to make one)"
        )
    doc = load_yaml(path, LocalizerConfigError)  # size, nesting, duplicate keys
    if not isinstance(doc, dict):
        raise LocalizerConfigError(where, "<root>", type(doc).__name__, "expected a mapping")
    if doc.get("format") != FORMAT:
        raise LocalizerConfigError(where, "format", doc.get("format"), f"expected {FORMAT!r}")
    size = []
    for key in ("image_width", "image_height"):
        value = doc.get(key)
        if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
            raise LocalizerConfigError(where, key, value, "expected a positive integer")
        if value > MAX_IMAGE_SIDE:
            raise LocalizerConfigError(
                where, key, value, f"exceeds the limit of {MAX_IMAGE_SIDE} pixels"
            )
        size.append(value)
    if size[0] * size[1] > MAX_IMAGE_PIXELS:
        raise LocalizerConfigError(
            where,
            "image_width x image_height",
            size,
            f"has more than the limit of {MAX_IMAGE_PIXELS} pixels",
        )
    rms = doc.get("rms_px", 0.0)
    if isinstance(rms, bool) or not isinstance(rms, (int, float)) or not rms >= 0:
        raise LocalizerConfigError(where, "rms_px", rms, "expected a number >= 0")
    k = _matrix(where, doc, "camera_matrix", (3, 3))
    if k[0, 0] <= 0 or k[1, 1] <= 0:
        raise LocalizerConfigError(where, "camera_matrix", k.tolist(), "focal lengths must be > 0")
    dist = doc.get("dist_coeffs")
    count = len(dist) if isinstance(dist, list) and len(dist) in DIST_SIZES else 5
    intrinsics = doc.get("intrinsics", FROM_MARKS)  # files written before it: from marks
    if intrinsics not in INTRINSICS:
        raise LocalizerConfigError(where, "intrinsics", intrinsics, f"expected one of {INTRINSICS}")
    source = doc.get("intrinsics_file", "")
    if not isinstance(source, str):
        raise LocalizerConfigError(where, "intrinsics_file", source, "expected a path")
    return CameraModel(
        size[0],
        size[1],
        k,
        _matrix(where, doc, "dist_coeffs", (count,)),
        _matrix(where, doc, "rvec", (3,)),
        _matrix(where, doc, "tvec", (3,)),
        float(rms),
        intrinsics,
        source,
    )
