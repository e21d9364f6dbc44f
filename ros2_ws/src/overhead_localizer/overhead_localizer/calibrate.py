"""``calibrate``: fit the overhead camera to marked points and write the localizer's YAML.

Usage::

    ros2 run overhead_localizer calibrate marks.yaml --out camera.yaml [--focal F] [--no-distortion]
    ros2 run overhead_localizer calibrate marks.yaml --out camera.yaml --camera-info ost.yaml

``marks.yaml`` lists where known points of the worksite appear in one camera image::

    image_width: 1280
    image_height: 720
    points:
      - {pixel: [340.1, 658.7], map: [0.0, 0.0]}          # a ground mark (z = 0)
      - {pixel: [512.3, 402.9], map: [1.0, 2.0, 0.15]}    # a mark at a known height

At least 6 points; ground marks spread over the whole site, plus a few at a known height
(a parked robot's LEDs), pin the camera down best. Without ``--camera-info`` the focal
length and radial distortion are fitted with the pose. With ``--camera-info FILE`` (the
CameraInfo YAML a calibrated camera driver loads, ``camera_calibration_parsers`` format:
``image_width``, ``image_height``, ``camera_matrix``, ``distortion_model``,
``distortion_coefficients``, ...) the driver's K and D are held fixed and only the pose is
fitted, so the localizer can use the driver's CameraInfo as it is; the file records it
(``intrinsics: camera_info``). The command prints the reprojection error and the camera
centre it found. Bad files end with exit code 2 and a message naming the file, the field
and the value.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from excavation_common.loaders import load_yaml
from overhead_localizer.camera_info import intrinsics, load_camera_info
from overhead_localizer.camera_model import calibrate, fit_pose, save_model
from overhead_localizer.errors import LocalizerConfigError


def load_marks(path: str) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
    """``(pixels [n, 2], map points [n, 3], (width, height))`` from a marks file.

    Raises:
        LocalizerConfigError: Missing file, missing or malformed field.
    """
    doc = load_yaml(path, LocalizerConfigError)  # size, nesting, duplicate keys
    if not isinstance(doc, dict):
        raise LocalizerConfigError(path, "<root>", type(doc).__name__, "expected a mapping")
    size = []
    for key in ("image_width", "image_height"):
        value = doc.get(key)
        if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
            raise LocalizerConfigError(path, key, value, "expected a positive integer")
        size.append(value)
    points = doc.get("points")
    if not isinstance(points, list) or len(points) < 6:
        shown = len(points) if isinstance(points, list) else points
        raise LocalizerConfigError(path, "points", shown, "expected a list of at least 6 marks")
    pixels, world = [], []
    for i, mark in enumerate(points):
        try:
            px = [float(v) for v in mark["pixel"]]
            xyz = [float(v) for v in mark["map"]]
        except (TypeError, KeyError, ValueError):
            raise LocalizerConfigError(
                path, f"points[{i}]", mark, "expected {pixel: [u, v], map: [x, y(, z)]}"
            ) from None
        if len(px) != 2 or len(xyz) not in (2, 3) or not np.isfinite(px + xyz).all():
            raise LocalizerConfigError(path, f"points[{i}]", mark, "expected 2 + 2 or 3 numbers")
        pixels.append(px)
        world.append(xyz + [0.0] * (3 - len(xyz)))
    return np.array(pixels), np.array(world), (size[0], size[1])


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``calibrate``."""
    parser = argparse.ArgumentParser(prog="calibrate", description=__doc__.split("\n\n")[0])
    parser.add_argument("marks", help="YAML file of marked points")
    parser.add_argument("--out", required=True, help="calibration YAML to write")
    parser.add_argument("--focal", type=float, default=None, help="known focal length, pixels")
    parser.add_argument("--no-distortion", action="store_true", help="assume no lens distortion")
    parser.add_argument(
        "--camera-info",
        metavar="FILE",
        default=None,
        help="a calibrated driver's CameraInfo YAML: fit the pose with its K and D held fixed",
    )
    args = parser.parse_args(argv)
    if args.camera_info and (args.focal or args.no_distortion):
        parser.error("--camera-info fixes the intrinsics: no --focal or --no-distortion")
    try:
        pixels, world, size = load_marks(args.marks)
        if args.camera_info:
            model = fit_to_camera_info(pixels, world, size, args.marks, args.camera_info)
        else:
            model = calibrate(pixels, world, size, args.focal, not args.no_distortion)
    except LocalizerConfigError as exc:
        print(f"calibrate: error: {exc}", file=sys.stderr)
        return 2
    except ValueError as exc:
        print(f"calibrate: error: {args.marks}: {exc}", file=sys.stderr)
        return 2
    save_model(model, args.out)
    c = model.centre
    held = f" (the driver's, from {args.camera_info})" if args.camera_info else ""
    print(
        f"{len(pixels)} marks: reprojection error {model.rms_px:.3f} px, focal "
        f"{model.camera_matrix[0, 0]:.1f} px, k1 {model.dist_coeffs[0]:+.4f}{held}, camera at "
        f"({c[0]:.3f}, {c[1]:.3f}, {c[2]:.3f}) m; wrote {args.out}"
    )
    return 0


def fit_to_camera_info(pixels, world, size, marks: str, path: str):
    """The pose fitted under the intrinsics of a CameraInfo YAML (``--camera-info``).

    Raises:
        LocalizerConfigError: A bad CameraInfo file, or one for another image size than
            the marks'.
    """
    info = load_camera_info(path)
    if (info.width, info.height) != size:
        raise LocalizerConfigError(
            path,
            "image_width x image_height",
            [info.width, info.height],
            f"differs from the marks' {size[0]} x {size[1]} ({marks})",
        )
    _, _, k, d = intrinsics(info, path)
    return fit_pose(pixels, world, size, k, d, str(Path(path).resolve()))


if __name__ == "__main__":
    sys.exit(main())
