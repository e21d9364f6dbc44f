"""LED beacons in an overhead frame -> robot poses in ``map`` (paper, 6.2).

The pipeline of one frame (:meth:`Localizer.update`):

1. **Detect**: HSV conversion, one threshold (bright *and* saturated: LEDs in a dark
   dome; glare is bright but nearly white), connected components (first on every second
   pixel, then at full resolution around each hit), and per blob an
   intensity-weighted sub-pixel centroid, its spread and its mean hue, which names its
   colour in the beacon table (:class:`Blob`).
2. **Locate**: each blob's pixel ray meets the plane of the LEDs (``beacons.height`` above
   the soil; the soil height comes from the height map when one is given, else ground
   level 0) through the calibrated :class:`CameraModel`.
3. **Pair**: robot k is a front blob of its front colour and a rear blob of its rear colour
   at the LED spacing (``spacing_tolerance``); near its track when it has one (``gate``).
   Each blob goes to one robot; among the assignments that place the most robots, the one
   with the best total fit wins (:func:`assign`). Two equally good pairs for a
   robot without a track make it *ambiguous*; robots sharing a colour pair in the table
   are *duplicates*. Neither is ever reported as a pose.
4. **Track**: a robot seen gives its centre (the LEDs' midpoint), yaw (rear -> front) and
   a covariance from the blobs' centroid spread, the metres per pixel there, the
   calibration error and the unknown soil height; a robot not seen *coasts* on its last
   pose for ``max_coast`` frames and at most ``max_coast_time`` seconds with a growing
   covariance, then is *lost*.

Pure module (numpy, OpenCV), no ``rclpy``; the node ``localizer_node`` wraps it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from excavation_common.params import param
from overhead_localizer.beacons import Beacons
from overhead_localizer.camera_model import CameraModel
from overhead_localizer.errors import ImageError

SEEN, COASTING, LOST, AMBIGUOUS, DUPLICATE = "seen", "coasting", "lost", "ambiguous", "duplicate"
"""Per-robot status of a frame; only ``SEEN`` and ``COASTING`` give a pose."""


@dataclass(frozen=True)
class LocalizerParams:
    """Detection, pairing and tracking settings (``config/localizer.yaml``).

    Attributes:
        min_value: Brightest channel a beacon pixel reaches (0..255).
        min_saturation: Saturation a beacon pixel reaches (0..255).
        min_area: Smallest blob, pixels.
        max_area: Largest blob, pixels (bigger ones are glare or reflections).
        hue_tolerance: Largest hue difference (OpenCV units, 0..180) to a table colour.
        spacing_tolerance: Accepted deviation of the LED distance, fraction of ``spacing``.
        gate: Largest jump (metres) from a track's last pose for a pair to continue it.
        max_coast: Frames a robot keeps its last pose when its LEDs are not seen.
        max_coast_time: ... and seconds (when frames carry stamps): a robot can move a cell
            in about a second, so a pose older than this is not reported.
        coast_sigma: Position standard deviation (metres) added per coasted frame.
        max_sigma: A pose less certain than this (metres, position) is not reported.
        ground_sigma: Standard deviation of the soil height under an LED when no height
            map is given, metres.
        min_pixel_variance: Floor of a centroid's variance, pixels squared.
    """

    min_value: int = param(110, "brightest channel of a beacon pixel (0..255)", low=0, high=255)
    min_saturation: int = param(60, "saturation of a beacon pixel (0..255)", low=0, high=255)
    min_area: int = param(3, "smallest blob, pixels", low=1, high=100000)
    max_area: int = param(500, "largest blob, pixels (bigger: glare)", low=1, high=10000000)
    hue_tolerance: float = param(
        12.0, "hue distance to a table colour (0..180)", low=0.0, high=90.0
    )
    spacing_tolerance: float = param(
        0.12, "LED distance deviation, fraction of the spacing", low=0.0, high=1.0
    )
    gate: float = param(0.6, "largest jump of a track between frames, m", low=0.0, high=100.0)
    max_coast: int = param(3, "frames a robot keeps its last pose unseen", low=0, high=1000)
    max_coast_time: float = param(0.5, "seconds a robot keeps its last pose", low=0.0, high=60.0)
    coast_sigma: float = param(0.02, "position sigma added per coasted frame, m", low=0.0)
    max_sigma: float = param(0.08, "poses less certain than this (m) are not sent", low=0.0)
    ground_sigma: float = param(0.05, "soil height sigma without a height map, m", low=0.0)
    min_pixel_variance: float = param(0.02, "floor of a centroid variance, px^2", low=0.0)

    def check(self) -> None:
        """Blob area limits in order."""
        if self.min_area > self.max_area:
            raise ValueError(f"min_area {self.min_area} > max_area {self.max_area}")


@dataclass(frozen=True)
class Blob:
    """One bright, saturated spot.

    Attributes:
        u: Sub-pixel column of the centroid.
        v: Sub-pixel row of the centroid.
        colour: Index into the table's colour names, or -1 when no colour matches.
        variance: Centroid variance, pixels squared.
        area: Pixels.
    """

    u: float
    v: float
    colour: int
    variance: float
    area: int


@dataclass(frozen=True)
class RobotEstimate:
    """A robot's pose in one frame (``x``, ``y``, ``yaw`` meaningful for seen or coasting).

    Attributes:
        status: ``seen``, ``coasting``, ``lost``, ``ambiguous`` or ``duplicate``.
        x: Centre, metres east.
        y: Centre, metres north.
        yaw: Radians, 0 = east, pi/2 = north.
        covariance: ``3 x 3`` over ``(x, y, yaw)``.
        detail: Why a robot has no pose (for diagnostics).
    """

    status: str
    x: float = math.nan
    y: float = math.nan
    yaw: float = math.nan
    covariance: np.ndarray = field(default_factory=lambda: np.full((3, 3), np.nan))
    detail: str = ""

    @property
    def reportable(self) -> bool:
        """True when the pose may be published."""
        return self.status in (SEEN, COASTING)


@dataclass
class _Track:
    x: float
    y: float
    yaw: float
    covariance: np.ndarray
    stamp: float | None = None
    missed: int = 0


def check_image(image: np.ndarray, model: CameraModel, source: str = "<image>") -> None:
    """Raise :class:`ImageError` unless ``image`` is ``uint8 [height, width, 3]`` of the model."""
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8 or image.ndim != 3:
        shown = getattr(image, "dtype", type(image).__name__)
        raise ImageError(source, "dtype/ndim", str(shown), "expected a uint8 BGR image")
    if image.shape != (model.height, model.width, 3):
        raise ImageError(
            source,
            "height x width x channels",
            image.shape,
            f"the calibration is for {model.height} x {model.width} x 3",
        )


def assign(options: dict[int, list[tuple[float, int, int]]]) -> dict[int, tuple[int, int]]:
    """Robot -> (front blob, rear blob): most robots placed, then the lowest total score.

    Args:
        options: Per robot, candidate pairs ``(score, front blob, rear blob)``, best first
            (only the best three are tried).
    """
    robots = [k for k in sorted(options) if options[k]]
    best: list = [(-1, 0.0), {}]

    def search(idx: int, used: frozenset, placed: dict, score: float) -> None:
        if len(placed) + len(robots) - idx < best[0][0]:
            return
        if idx == len(robots):
            key = (len(placed), -score)
            if key > (best[0][0], -best[0][1]):
                best[0], best[1] = (len(placed), score), dict(placed)
            return
        k = robots[idx]
        for s, i, j in options[k][:3]:
            if i not in used and j not in used:
                placed[k] = (i, j)
                search(idx + 1, used | {i, j}, placed, score + s)
                del placed[k]
        search(idx + 1, used, placed, score)

    search(0, frozenset(), {}, 0.0)
    return best[1]


class Localizer:
    """Frame-by-frame LED localizer with short-dropout tracking (see the module docstring)."""

    def __init__(
        self,
        model: CameraModel,
        beacons: Beacons,
        n_robots: int,
        params: LocalizerParams | None = None,
    ) -> None:
        """Set up for ``n_robots`` robots (the first ``n_robots`` entries of the table)."""
        if n_robots > len(beacons.robots):
            raise ValueError(
                f"{n_robots} robots but the beacon table names only {len(beacons.robots)}"
            )
        self.model = model
        self.beacons = beacons
        self.n = n_robots
        self.params = params or LocalizerParams()
        self.names = list(beacons.colours)
        hues = beacons.hues()
        self.hues = np.array([hues[name] for name in self.names])
        self.duplicated = {k for group in beacons.duplicates(n_robots) for k in group}
        self.tracks: dict[int, _Track] = {}
        self.stride = 2

    # --- 1. detect --------------------------------------------------------------------------

    def detect(self, image: np.ndarray) -> list[Blob]:
        """Beacon blobs in a BGR frame (see the module docstring, step 1).

        Coarse to fine: the threshold and connected components run first on every
        ``stride``-th pixel (an LED's blob is wider than that), then at full resolution only
        in a window around each coarse hit.
        """
        p = self.params
        lo, hi = (0, p.min_saturation, p.min_value), (180, 255, 255)
        step = self.stride
        height, width = image.shape[:2]
        coarse = cv2.resize(image, (width // step, height // step), interpolation=cv2.INTER_NEAREST)
        mask = cv2.inRange(cv2.cvtColor(coarse, cv2.COLOR_BGR2HSV), lo, hi)
        mask = cv2.dilate(mask, np.ones((3, 3), np.uint8))
        count, _, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
        blobs = []
        for i in range(1, count):
            x, y, w, h, _ = (int(v) for v in stats[i])
            if w * h * step * step > 16 * p.max_area:
                continue  # far larger than any LED: glare
            x0, y0 = max(x * step - step, 0), max(y * step - step, 0)
            x1, y1 = min((x + w) * step + step, width), min((y + h) * step + step, height)
            blobs += self._blobs(image[y0:y1, x0:x1], x0, y0)
        return blobs

    def _blobs(self, window: np.ndarray, x0: int, y0: int) -> list[Blob]:
        """Full-resolution blobs of one window whose top-left pixel is ``(x0, y0)``."""
        p = self.params
        hsv = cv2.cvtColor(window, cv2.COLOR_BGR2HSV)
        mask = cv2.inRange(hsv, (0, p.min_saturation, p.min_value), (180, 255, 255))
        count, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
        blobs = []
        for i in range(1, count):
            x, y, w, h, area = (int(v) for v in stats[i])
            if not p.min_area <= area <= p.max_area:
                continue
            roi = (slice(y, y + h), slice(x, x + w))
            own = labels[roi] == i
            weight = np.where(own, hsv[roi][:, :, 2].astype(np.float64) - p.min_value + 1, 0)
            total = weight.sum()
            ys, xs = np.mgrid[y : y + h, x : x + w]
            u = float((weight * xs).sum() / total)
            v = float((weight * ys).sum() / total)
            spread = float((weight * ((xs - u) ** 2 + (ys - v) ** 2)).sum() / total) / 2
            angle = hsv[roi][:, :, 0][own].astype(np.float64) * (math.pi / 90)
            w_own = weight[own]
            hue = math.atan2((w_own * np.sin(angle)).sum(), (w_own * np.cos(angle)).sum())
            hue = (hue * 90 / math.pi) % 180
            diff = np.abs((self.hues - hue + 90) % 180 - 90)
            colour = int(np.argmin(diff)) if diff.min() <= p.hue_tolerance else -1
            variance = max(spread / area, p.min_pixel_variance)
            blobs.append(Blob(u + x0, v + y0, colour, variance, area))
        return blobs

    # --- 2. locate --------------------------------------------------------------------------

    def _ground(self, x: float, y: float, heights: np.ndarray | None, cell_size: float) -> float:
        """Mean known soil height of the footprint centred nearest to ``(x, y)`` (0 if none)."""
        if heights is None:
            return 0.0
        r0, c0 = round(y / cell_size) - 1, round(x / cell_size) - 1
        rows, cols = heights.shape
        cells = heights[max(r0, 0) : max(r0 + 2, 0), max(c0, 0) : max(c0 + 2, 0)]
        known = cells[np.isfinite(cells)] if cells.size else cells
        return float(known.mean()) if known.size else 0.0

    def locate(
        self, blobs: list[Blob], z: float | np.ndarray, ground_sigma: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """``map`` ``(x, y)`` ``[n, 2]`` of blobs on the plane(s) ``z`` and their variance (m^2).

        The variance combines the centroid's spread and the calibration error (pixels, times
        the metres per pixel there) with the parallax of an unknown LED height (
        ``ground_sigma`` times the distance from the camera's foot over its height).
        """
        if not blobs:
            return np.zeros((0, 2)), np.zeros(0)
        px = np.array([(b.u, b.v) for b in blobs])
        z = np.broadcast_to(np.asarray(z, dtype=np.float64), (len(blobs),))
        xy = self.model.to_map(px, z)
        mpp = self.model.metres_per_pixel(px, z)
        pixel_var = np.array([b.variance for b in blobs]) + self.model.rms_px**2
        c = self.model.centre
        lever = np.hypot(xy[:, 0] - c[0], xy[:, 1] - c[1]) / np.maximum(c[2] - z, 1e-6)
        return xy, pixel_var * mpp**2 + (ground_sigma * lever) ** 2

    # --- 3. pair, 4. track ------------------------------------------------------------------

    def update(
        self,
        image: np.ndarray,
        heights: np.ndarray | None = None,
        cell_size: float = 0.25,
        stamp: float | None = None,
    ) -> list[RobotEstimate]:
        """Poses of robots 0 .. n - 1 in one frame (updates the tracks).

        Args:
            image: BGR frame, ``uint8 [height, width, 3]`` of the calibration's size.
            heights: Soil heights in metres per cell (NaN unknown), or ``None``.
            cell_size: Metres per cell of ``heights``.
            stamp: The frame's time in seconds (limits coasting to ``max_coast_time``).

        Raises:
            ImageError: The frame's size or type does not fit the calibration.
        """
        check_image(image, self.model)
        return self.associate(self.detect(image), heights, cell_size, stamp)

    def associate(
        self,
        blobs: list[Blob],
        heights: np.ndarray | None = None,
        cell_size: float = 0.25,
        stamp: float | None = None,
    ) -> list[RobotEstimate]:
        """Locating, pairing and tracking of detected blobs (steps 2 to 4).

        Pairs are formed on the plane at the LED height over ground level; each chosen pair
        is then located again on the plane over the soil of its footprint (from
        ``heights`` when given).
        """
        p, b = self.params, self.beacons
        xy, var = self.locate(blobs, b.height, p.ground_sigma)
        index = {name: i for i, name in enumerate(self.names)}
        colours = np.array([bl.colour for bl in blobs], dtype=int)
        lo, hi = b.spacing * (1 - p.spacing_tolerance), b.spacing * (1 + p.spacing_tolerance)
        per_robot: dict[int, list[tuple[float, int, int]]] = {}
        for k in range(self.n):
            if k in self.duplicated:
                continue
            front, rear = (index[c] for c in b.robots[k])
            fronts = np.flatnonzero(colours == front)
            rears = np.flatnonzero(colours == rear)
            track = self.tracks.get(k)
            options = []
            for i in fronts:
                for j in rears:
                    d = float(np.hypot(*(xy[i] - xy[j])))
                    if not lo <= d <= hi:
                        continue
                    score = abs(d - b.spacing) / b.spacing
                    if track is not None:
                        mid = (xy[i] + xy[j]) / 2
                        jump = float(np.hypot(mid[0] - track.x, mid[1] - track.y))
                        if jump > p.gate:
                            continue
                        score += jump / p.gate
                    options.append((score, int(i), int(j)))
            options.sort()
            per_robot[k] = options
        chosen = assign(per_robot)
        out = []
        for k in range(self.n):
            if k in self.duplicated:
                out.append(
                    RobotEstimate(
                        DUPLICATE, detail=f"robot {k} shares LED colours {b.robots[k]} with another"
                    )
                )
                continue
            options = per_robot.get(k, [])
            if k in chosen and k not in self.tracks:
                i, j = chosen[k]
                rivals = [o for o in options if o[1] not in (i, j) and o[2] not in (i, j)]
                if rivals and rivals[0][0] - options[0][0] < 0.15:
                    chosen.pop(k)
                    out.append(
                        RobotEstimate(
                            AMBIGUOUS,
                            detail=f"robot {k}: {len(options)} LED pairs fit and there is no track",
                        )
                    )
                    continue
            if k in chosen:
                i, j = chosen[k]
                pair = [blobs[i], blobs[j]]
                mid = (xy[i] + xy[j]) / 2
                if heights is not None:
                    ground = self._ground(mid[0], mid[1], heights, cell_size)
                    # the footprint's mean soil height is known to about a fifth of the
                    # LED height (the robot rocks on uneven soil)
                    pxy, pvar = self.locate(pair, ground + b.height, 0.2 * b.height)
                else:
                    pxy, pvar = xy[[i, j]], var[[i, j]]
                out.append(self._seen(k, pxy[0], pxy[1], pvar[0], pvar[1], stamp))
            else:
                out.append(self._coast(k, stamp))
        return out

    def _seen(self, k, front, rear, var_f, var_r, stamp) -> RobotEstimate:
        mid = (front + rear) / 2
        d = front - rear
        yaw = math.atan2(d[1], d[0])
        cov = np.zeros((3, 3))
        cov[0, 0] = cov[1, 1] = (var_f + var_r) / 4
        cov[2, 2] = (var_f + var_r) / float(d @ d)
        self.tracks[k] = _Track(float(mid[0]), float(mid[1]), yaw, cov, stamp)
        if math.sqrt(cov[0, 0]) > self.params.max_sigma:
            return RobotEstimate(
                LOST, detail=f"robot {k}: position uncertainty {math.sqrt(cov[0, 0]):.3f} m"
            )
        return RobotEstimate(SEEN, float(mid[0]), float(mid[1]), yaw, cov)

    def _coast(self, k, stamp) -> RobotEstimate:
        track = self.tracks.get(k)
        if track is None:
            return RobotEstimate(LOST, detail=f"robot {k}: LEDs not seen")
        track.missed += 1
        if track.missed > self.params.max_coast:
            del self.tracks[k]
            return RobotEstimate(LOST, detail=f"robot {k}: LEDs not seen for {track.missed} frames")
        if stamp is not None and track.stamp is not None:
            gap = stamp - track.stamp
            if gap > self.params.max_coast_time:
                # the robot may have moved since: its last pose is no longer its pose (the
                # track stays, to pick the robot up again near where it was)
                return RobotEstimate(LOST, detail=f"robot {k}: LEDs not seen for {gap:.2f} s")
        cov = track.covariance.copy()
        grow = (self.params.coast_sigma * track.missed) ** 2
        cov[0, 0] += grow
        cov[1, 1] += grow
        cov[2, 2] += (0.05 * track.missed) ** 2
        if math.sqrt(cov[0, 0]) > self.params.max_sigma:
            return RobotEstimate(LOST, detail=f"robot {k}: coasting too uncertain")
        return RobotEstimate(COASTING, track.x, track.y, track.yaw, cov, f"coasting {track.missed}")
