"""The camera frame with what the localizer saw drawn on it (no ``rclpy``).

:func:`annotate` marks every detected LED blob (a ring in its table colour, grey when no
colour matched) and every robot with a pose (its id and an arrow along its heading, drawn
by projecting the pose through the calibrated camera). The localizer publishes it as
``/overhead/image_annotated`` for ``ant-view`` and RViz.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from overhead_localizer.localize import Blob, Localizer, RobotEstimate


def annotate(
    frame: np.ndarray, blobs: list[Blob], estimates: list[RobotEstimate], localizer: Localizer
) -> np.ndarray:
    """A copy of the BGR ``frame`` with blobs and robot poses drawn."""
    out = frame.copy()
    colours = localizer.beacons.colours
    for b in blobs:
        bgr = colours[localizer.names[b.colour]] if b.colour >= 0 else (160, 160, 160)
        centre = (int(round(b.u)), int(round(b.v)))
        radius = max(4, int(math.sqrt(b.area)) + 3)
        cv2.circle(out, centre, radius, tuple(int(c) for c in bgr), 1, cv2.LINE_AA)
    z = localizer.beacons.height
    for k, e in enumerate(estimates):
        if not e.reportable:
            continue
        tip = (e.x + 0.2 * math.cos(e.yaw), e.y + 0.2 * math.sin(e.yaw))
        (u0, v0), (u1, v1) = localizer.model.project(np.array([[e.x, e.y, z], [*tip, z]]))
        p0, p1 = (int(round(u0)), int(round(v0))), (int(round(u1)), int(round(v1)))
        cv2.arrowedLine(out, p0, p1, (255, 255, 255), 2, cv2.LINE_AA, tipLength=0.3)
        label = f"{k}" if e.status == "seen" else f"{k}?"
        cv2.putText(
            out, label, (p0[0] + 8, p0[1] - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 255), 2
        )
    return out
