"""``calibrate``: fit the overhead camera to marked points and write the localizer's YAML.

Usage::

    ros2 run overhead_localizer calibrate marks.yaml --out camera.yaml [--focal F] [--no-distortion]

``marks.yaml`` lists where known points of the worksite appear in one camera image::

    image_width: 1280
    image_height: 720
    points:
      - {pixel: [340.1, 658.7], map: [0.0, 0.0]}          # a ground mark (z = 0)
      - {pixel: [512.3, 402.9], map: [1.0, 2.0, 0.15]}    # a mark at a known height

At least 6 points; ground marks spread over the whole site, plus a few at a known height
(a parked robot's LEDs), pin the camera down best. The command prints the reprojection
error and the camera centre it found. Bad files end with exit code 2 and a message naming
the file, the field and the value.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from excavation_common.loaders import load_yaml
from overhead_localizer.camera_model import calibrate, save_model
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
    args = parser.parse_args(argv)
    try:
        pixels, world, size = load_marks(args.marks)
        model = calibrate(pixels, world, size, args.focal, not args.no_distortion)
    except LocalizerConfigError as exc:
        print(f"calibrate: error: {exc}", file=sys.stderr)
        return 2
    except ValueError as exc:
        print(f"calibrate: error: {args.marks}: {exc}", file=sys.stderr)
        return 2
    save_model(model, args.out)
    c = model.centre
    print(
        f"{len(pixels)} marks: reprojection error {model.rms_px:.3f} px, focal "
        f"{model.camera_matrix[0, 0]:.1f} px, k1 {model.dist_coeffs[0]:+.4f}, camera at "
        f"({c[0]:.3f}, {c[1]:.3f}, {c[2]:.3f}) m; wrote {args.out}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
