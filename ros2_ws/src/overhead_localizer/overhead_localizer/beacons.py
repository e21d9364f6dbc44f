"""The LED beacon table: which colours each robot carries at its front and rear (paper, 6.2).

Format (YAML, e.g. ``config/beacons.yaml``)::

    height: 0.15    # LED height above the soil, m
    spacing: 0.36   # front to rear LED, m, centred on the robot
    radius: 0.012   # glow radius, m (used by the simulator's renderer)
    colours: {red: [0, 0, 255], green: [0, 255, 0], ...}   # BGR as the camera sees them
    robots:
      - {front: red, rear: green}     # robot 0
      - ...

The simulator's camera renders from the same format (``excavation_sim/config/beacons.yaml``).
Pure module, no ``rclpy``.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from excavation_common.limits import MAX_ROBOTS
from excavation_common.loaders import load_yaml
from overhead_localizer.errors import LocalizerConfigError

CONFIG_DIR = Path(__file__).resolve().parents[1] / "config"


@dataclass(frozen=True)
class Beacons:
    """LED colours and which pair identifies which robot.

    Attributes:
        colours: Colour name -> BGR (0..255) at full power.
        robots: Per robot k, ``(front colour, rear colour)``.
        height: LED height above the soil under the robot, metres.
        spacing: Distance between the front and the rear LED, metres.
        radius: LED glow radius (one standard deviation), metres.
    """

    colours: dict[str, tuple[int, int, int]]
    robots: tuple[tuple[str, str], ...]
    height: float = 0.15
    spacing: float = 0.36
    radius: float = 0.012

    def hues(self) -> dict[str, float]:
        """OpenCV hue (0..180) of every colour."""
        out = {}
        for name, bgr in self.colours.items():
            px = np.array([[bgr]], dtype=np.uint8)
            out[name] = float(cv2.cvtColor(px, cv2.COLOR_BGR2HSV)[0, 0, 0])
        return out

    def duplicates(self, n_robots: int | None = None) -> list[list[int]]:
        """Groups of robots (among the first ``n_robots``) that share a (front, rear) pair."""
        groups: dict[tuple[str, str], list[int]] = defaultdict(list)
        for k, pair in enumerate(self.robots[:n_robots]):
            groups[pair].append(k)
        return [g for g in groups.values() if len(g) > 1]


def load_beacons(path: str | Path) -> Beacons:
    """Read a beacon table.

    Raises:
        LocalizerConfigError: Missing file, unknown colour, malformed entry.
    """
    path = Path(path)
    where = str(path)
    doc = load_yaml(path, LocalizerConfigError)  # size, nesting, duplicate keys
    if not isinstance(doc, dict):
        raise LocalizerConfigError(where, "<root>", type(doc).__name__, "expected a mapping")
    colours = {}
    raw = doc.get("colours")
    if not isinstance(raw, dict) or not raw:
        raise LocalizerConfigError(where, "colours", raw, "expected a mapping name: [B, G, R]")
    for name, bgr in raw.items():
        ok = isinstance(bgr, list) and len(bgr) == 3
        ok = ok and all(isinstance(v, int) and 0 <= v <= 255 for v in bgr)
        if not ok:
            raise LocalizerConfigError(where, f"colours.{name}", bgr, "expected [B, G, R] 0..255")
        colours[str(name)] = tuple(bgr)
    robots = []
    entries = doc.get("robots")
    if not isinstance(entries, list) or not entries:
        raise LocalizerConfigError(where, "robots", entries, "expected a list of {front, rear}")
    if len(entries) > MAX_ROBOTS:
        raise LocalizerConfigError(
            where, "robots", f"{len(entries)} robots", f"exceeds the limit of {MAX_ROBOTS}"
        )
    for k, entry in enumerate(entries):
        if not (isinstance(entry, dict) and {"front", "rear"} <= set(entry)):
            raise LocalizerConfigError(where, f"robots[{k}]", entry, "expected {front, rear}")
        for key in ("front", "rear"):
            if entry[key] not in colours:
                raise LocalizerConfigError(
                    where, f"robots[{k}].{key}", entry[key], f"not one of {sorted(colours)}"
                )
        if entry["front"] == entry["rear"]:
            raise LocalizerConfigError(
                where, f"robots[{k}]", entry, "front and rear need different colours"
            )
        robots.append((entry["front"], entry["rear"]))
    extra = {}
    for key in ("height", "spacing", "radius"):
        if key in doc:
            value = doc[key]
            if isinstance(value, bool) or not (isinstance(value, (int, float)) and value > 0):
                raise LocalizerConfigError(where, key, value, "expected a positive number")
            extra[key] = float(value)
    return Beacons(colours, tuple(robots), **extra)
