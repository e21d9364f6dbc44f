"""Synthetic overhead camera: what the dome's mast camera sees of the worksite (paper, 6.2).

In the field trials an overhead camera tracked LED beacons on the robots in low light (a
crater's shadow). :class:`OverheadCamera` renders that view from the simulator's truth so
that the localizer runs in CI on the pixels a real camera would give:

* a pinhole camera on a mast (:class:`CameraParams`: position, aim point, focal length,
  optional radial distortion ``k1``, ``k2``), so the ground plane maps to the image by a
  homography and everything above it (LEDs) by the same projection at its height;
* a dim sand texture shaded by the soil heights (``light`` scales the ambient level), dark
  robot bodies, and per robot a front and a rear LED whose colours identify it
  (``config/beacons.yaml``, read by :func:`overhead_localizer.beacons.load_beacons`, the
  format the localizer reads too);
* seeded sensor noise, glare blobs (bright, unsaturated spots), LED dropout (a probability
  per LED and frame) and occlusion on demand (named LEDs hidden in a frame).

Everything random comes from the ``numpy.random.Generator`` passed to
:meth:`OverheadCamera.render`; the same generator state gives the same image, bit for bit.
Pure module (numpy, OpenCV), no ``rclpy``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from excavation_common.errors import FieldError
from overhead_localizer.beacons import Beacons, load_beacons

CONFIG_DIR = Path(__file__).resolve().parents[1] / "config"
BEACONS_FILE = CONFIG_DIR / "beacons.yaml"


class CameraConfigError(FieldError):
    """A camera configuration that cannot be used (file, field, value)."""


def default_beacons() -> Beacons:
    """The beacon table shipped in ``excavation_sim/config/beacons.yaml``."""
    return load_beacons(BEACONS_FILE)


@dataclass(frozen=True)
class CameraParams:
    """The mast camera and the scene conditions.

    Attributes:
        width: Image width, pixels.
        height: Image height, pixels.
        position: Camera centre ``(x, y, z)`` in ``map``, metres.
        target: Point on the ground the optical axis goes through, metres.
        focal: Focal length, pixels.
        k1: Radial distortion (OpenCV model), 0 = none.
        k2: Second radial distortion coefficient.
        light: Ambient light, 0..1 of full daylight (the dome tests were dark: 0.25).
        noise: Sensor noise, standard deviation in grey levels.
        glare: Mean number of glare blobs per frame.
        dropout: Probability that an LED is missing from a frame.
        led_power: LED brightness, 0..1 of the colour table's value.
        pose_jitter: ``(metres, radians)`` standard deviations by which each robot's body
            stands off its grid pose (the real robots are never exactly aligned).
    """

    width: int = 1280
    height: int = 720
    position: tuple[float, float, float] = (2.0, 1.7, 7.0)
    target: tuple[float, float, float] = (2.0, 2.0, 0.0)
    focal: float = 1050.0
    k1: float = -0.08
    k2: float = 0.01
    light: float = 0.25
    noise: float = 3.0
    glare: float = 1.5
    dropout: float = 0.0
    led_power: float = 1.0
    pose_jitter: tuple[float, float] = (0.01, 0.03)

    @classmethod
    def for_site(cls, width_m: float, depth_m: float, **kwargs) -> CameraParams:
        """The default camera scaled to a ``width_m`` x ``depth_m`` site (same view angles).

        The defaults are for the 4 m x 4 m default site: the camera 7 m up, 0.3 m south of
        the centre, aimed at the centre.
        """
        s = max(width_m, depth_m)
        return cls(
            position=(width_m / 2, depth_m / 2 - 0.075 * s, 1.75 * s),
            target=(width_m / 2, depth_m / 2, 0.0),
            **kwargs,
        )

    def camera_matrix(self) -> np.ndarray:
        """The 3 x 3 intrinsic matrix (principal point at the image centre)."""
        return np.array(
            [
                [self.focal, 0.0, (self.width - 1) / 2],
                [0.0, self.focal, (self.height - 1) / 2],
                [0.0, 0.0, 1.0],
            ]
        )

    def dist_coeffs(self) -> np.ndarray:
        """OpenCV distortion coefficients ``(k1, k2, p1, p2, k3)``."""
        return np.array([self.k1, self.k2, 0.0, 0.0, 0.0])

    def extrinsics(self) -> tuple[np.ndarray, np.ndarray]:
        """``(rvec, tvec)`` from ``map`` to the camera (image x east-ish, image y south-ish)."""
        c = np.asarray(self.position, dtype=float)
        z = np.asarray(self.target, dtype=float) - c
        z /= np.linalg.norm(z)
        x = np.array([1.0, 0.0, 0.0]) - z[0] * z
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        rot = np.stack([x, y, z])
        rvec, _ = cv2.Rodrigues(rot)
        return rvec.ravel(), -rot @ c


@dataclass(frozen=True)
class RobotView:
    """A robot as the camera sees it: centre ``(x, y)`` in metres, yaw, soil height below."""

    x: float
    y: float
    yaw: float
    ground: float = 0.0


@dataclass
class OverheadCamera:
    """Renders overhead frames of the worksite (see the module docstring).

    Attributes:
        params: Camera and scene conditions.
        beacons: LED table.
        rows: Worksite rows.
        cols: Worksite columns.
        cell_size: Metres per cell.
        seed: Seed of the fixed sand texture.
    """

    params: CameraParams
    beacons: Beacons
    rows: int = 16
    cols: int = 16
    cell_size: float = 0.25
    seed: int = 0
    _maps: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False)
    _texture: np.ndarray | None = field(default=None, repr=False)

    TEXEL = 16
    """Pixels per cell of the top-down texture the background is warped from."""
    MARGIN = 6
    """Cells of dome floor drawn around the worksite."""

    def __post_init__(self) -> None:
        p = self.params
        self.K = p.camera_matrix()
        self.dist = p.dist_coeffs()
        self.rvec, self.tvec = p.extrinsics()
        tex_rng = np.random.default_rng(self.seed)
        span = (
            (self.rows + 2 * self.MARGIN) * self.TEXEL,
            (self.cols + 2 * self.MARGIN) * self.TEXEL,
        )
        grain = tex_rng.normal(0.0, 1.0, (span[0] // 2, span[1] // 2)).astype(np.float32)
        grain = cv2.resize(cv2.GaussianBlur(grain, (0, 0), 1.0), (span[1], span[0]))
        self._grain = grain
        self._build_maps()

    # --- geometry ---------------------------------------------------------------------------

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixel coordinates ``[n, 2]`` of ``map`` points ``[n, 3]`` (with distortion)."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 1, 3)
        px, _ = cv2.projectPoints(pts, self.rvec, self.tvec, self.K, self.dist)
        return px.reshape(-1, 2)

    def _build_maps(self) -> None:
        """Per-pixel lookup into the top-down texture (ground plane, through the distortion)."""
        p = self.params
        u, v = np.meshgrid(np.arange(p.width, dtype=np.float64), np.arange(p.height))
        pix = np.stack([u.ravel(), v.ravel()], axis=1).reshape(-1, 1, 2)
        norm = cv2.undistortPoints(pix, self.K, self.dist).reshape(-1, 2)
        rot, _ = cv2.Rodrigues(self.rvec)
        centre = -rot.T @ self.tvec
        rays = np.column_stack([norm, np.ones(len(norm))]) @ rot  # rows: rot.T @ ray
        s = -centre[2] / rays[:, 2]
        x = centre[0] + s * rays[:, 0]
        y = centre[1] + s * rays[:, 1]
        t = self.TEXEL / self.cell_size
        tex_u = (x / self.cell_size + self.MARGIN) * self.TEXEL
        tex_v = (y / self.cell_size + self.MARGIN) * self.TEXEL
        del t
        self._maps = (
            tex_u.reshape(p.height, p.width).astype(np.float32),
            tex_v.reshape(p.height, p.width).astype(np.float32),
        )

    # --- rendering --------------------------------------------------------------------------

    def _background(self, heights_m: np.ndarray) -> np.ndarray:
        """Top-down sand texture shaded by height, then warped into the camera."""
        p = self.params
        m = self.MARGIN
        shade = np.full((self.rows + 2 * m, self.cols + 2 * m), 0.0, dtype=np.float32)
        shade[m : m + self.rows, m : m + self.cols] = np.clip(
            heights_m / (10 * self.cell_size), -0.5, 0.5
        )
        shade = cv2.resize(
            shade, (self._grain.shape[1], self._grain.shape[0]), interpolation=cv2.INTER_NEAREST
        )
        level = 255.0 * p.light * (0.55 + 0.6 * shade + 0.06 * self._grain)
        tex = np.clip(level, 0, 255).astype(np.uint8)
        tex = cv2.merge([(tex * 0.8).astype(np.uint8), (tex * 0.92).astype(np.uint8), tex])
        return cv2.remap(
            tex, self._maps[0], self._maps[1], cv2.INTER_LINEAR, borderValue=(8, 8, 10)
        )

    def led_points(self, robot: RobotView) -> np.ndarray:
        """``map`` coordinates ``[2, 3]`` of a robot's front and rear LED."""
        b = self.beacons
        half = b.spacing / 2
        c, s = math.cos(robot.yaw), math.sin(robot.yaw)
        z = robot.ground + b.height
        return np.array(
            [
                [robot.x + half * c, robot.y + half * s, z],
                [robot.x - half * c, robot.y - half * s, z],
            ]
        )

    def render(
        self,
        robots: list[RobotView],
        heights_m: np.ndarray,
        rng: np.random.Generator,
        hidden: set[tuple[int, str]] | frozenset = frozenset(),
    ) -> tuple[np.ndarray, np.ndarray]:
        """One BGR frame and the true pixel positions of every LED.

        Args:
            robots: Robot k's view for k = 0 .. n - 1 (``n`` at most the beacon table).
            heights_m: Soil heights in metres, ``[rows, cols]``.
            rng: Source of all randomness of this frame (jitter, glare, dropout, noise).
            hidden: LEDs occluded on demand, as ``(robot, "front" | "rear")``.

        Returns:
            ``(image uint8 [height, width, 3], leds float [n, 2, 3])`` where ``leds[k, i]``
            is ``(u, v, visible)`` of robot k's front (i = 0) and rear (i = 1) LED.

        Raises:
            CameraConfigError: More robots than the beacon table names.
        """
        p, b = self.params, self.beacons
        if len(robots) > len(b.robots):
            raise CameraConfigError(
                "beacons", "robots", len(b.robots), f"{len(robots)} robots need an entry each"
            )
        img = self._background(np.asarray(heights_m, dtype=np.float32))
        leds = np.zeros((len(robots), 2, 3))
        jit_xy, jit_yaw = p.pose_jitter
        bodies = []
        for r in robots:
            dx, dy = rng.normal(0.0, jit_xy, 2)
            r = RobotView(r.x + dx, r.y + dy, r.yaw + rng.normal(0.0, jit_yaw), r.ground)
            bodies.append(r)
            half = self.cell_size * 0.95
            c, s = math.cos(r.yaw), math.sin(r.yaw)
            corners = [
                (r.x + a * half * c - q * half * s, r.y + a * half * s + q * half * c)
                for a, q in ((1, 1), (1, -1), (-1, -1), (-1, 1))
            ]
            top = r.ground + b.height * 0.8
            px = self.project(np.array([(x, y, top) for x, y in corners]))
            cv2.fillConvexPoly(
                img, np.round(px * 16).astype(np.int32), (22, 22, 26), cv2.LINE_AA, 4
            )
        glare_n = rng.poisson(p.glare)
        for _ in range(glare_n):
            u, v = rng.uniform(0, p.width), rng.uniform(0, p.height)
            sigma = rng.uniform(6, 25)
            self._splat(img, u, v, sigma, (235, 240, 245), rng.uniform(0.6, 1.2))
        for k, r in enumerate(bodies):
            px = self.project(self.led_points(r))
            front, rear = b.robots[k]
            depth = self.params.position[2] - (r.ground + b.height)
            sigma = max(b.radius * p.focal / depth, 0.8)
            for i, (name, colour) in enumerate(((0, front), (1, rear))):
                side = "front" if name == 0 else "rear"
                seen = (k, side) not in hidden and rng.random() >= p.dropout
                leds[k, i] = (px[i, 0], px[i, 1], float(seen))
                if seen:
                    self._splat(
                        img, px[i, 0], px[i, 1], sigma, b.colours[colour], p.led_power * 2.5
                    )
        if p.noise > 0:
            noise = np.empty(img.shape, dtype=np.int16)
            cv2.setRNGSeed(int(rng.integers(0, 2**31 - 1)))
            cv2.randn(noise, 0, p.noise)
            img = cv2.add(img, noise, dtype=cv2.CV_8U)
        return img, leds

    @staticmethod
    def _splat(img: np.ndarray, u: float, v: float, sigma: float, bgr, gain: float) -> None:
        """Add a Gaussian spot of colour ``bgr`` (saturating) centred at ``(u, v)``."""
        h, w = img.shape[:2]
        r = int(math.ceil(3 * sigma))
        u0, u1 = max(int(u) - r, 0), min(int(u) + r + 2, w)
        v0, v1 = max(int(v) - r, 0), min(int(v) + r + 2, h)
        if u0 >= u1 or v0 >= v1:
            return
        xs = np.arange(u0, u1) - u
        ys = np.arange(v0, v1) - v
        g = np.exp(-(ys[:, None] ** 2 + xs[None, :] ** 2) / (2 * sigma * sigma)) * gain
        patch = img[v0:v1, u0:u1].astype(np.float32)
        patch += g[:, :, None] * np.asarray(bgr, dtype=np.float32)[None, None, :]
        img[v0:v1, u0:u1] = np.clip(patch, 0, 255).astype(np.uint8)


def robot_views(
    robots: np.ndarray, heights_units: np.ndarray, cell_size: float, height_unit: float
) -> list[RobotView]:
    """Camera views of the simulator's robots (``int64 [n, ROBOT_FIELDS]``) on its terrain."""
    from excavation_common.frames import heading_to_yaw, robot_center
    from excavation_sim.world import COL, HEADING, ROW

    out = []
    for r in robots:
        row, col = int(r[ROW]), int(r[COL])
        x, y = robot_center(row, col, cell_size)
        ground = float(heights_units[row : row + 2, col : col + 2].mean()) * height_unit
        out.append(RobotView(x, y, heading_to_yaw(int(r[HEADING])), ground))
    return out


def calibration_marks(
    camera: OverheadCamera, rng: np.random.Generator, pixel_noise: float = 0.3
) -> tuple[np.ndarray, np.ndarray]:
    """Marks a surveyor would give ``calibrate``: ``(pixels [n, 2], map points [n, 3])``.

    A 5 x 5 grid of ground marks over the worksite, six marks at LED height (a robot parked
    at three places) and four on a 0.6 m survey pole, each pixel clicked with
    ``pixel_noise`` (standard deviation). The raised marks fix the camera's height, which
    ground marks alone barely constrain when the camera looks nearly straight down.
    """
    w, h = camera.cols * camera.cell_size, camera.rows * camera.cell_size
    ground = [(x, y, 0.0) for x in np.linspace(0, w, 5) for y in np.linspace(0, h, 5)]
    z = camera.beacons.height
    raised = [(x, y, z) for x in (0.25 * w, 0.5 * w, 0.75 * w) for y in (0.25 * h, 0.75 * h)]
    pole = [(x, y, 0.6) for x in (0.2 * w, 0.8 * w) for y in (0.2 * h, 0.8 * h)]
    points = np.array(ground + raised + pole)
    pixels = camera.project(points) + rng.normal(0.0, pixel_noise, (len(points), 2))
    return pixels, points


def marks_yaml(camera: OverheadCamera, pixels: np.ndarray, points: np.ndarray) -> str:
    """The marks as the ``calibrate`` command reads them."""
    import yaml

    doc = {
        "image_width": camera.params.width,
        "image_height": camera.params.height,
        "points": [
            {"pixel": [round(float(u), 3), round(float(v), 3)], "map": [float(c) for c in p]}
            for (u, v), p in zip(pixels, points, strict=True)
        ],
    }
    return yaml.safe_dump(doc, sort_keys=False, default_flow_style=None)


def main(argv: list[str] | None = None) -> int:
    """``python -m excavation_sim.camera``: a sample frame and calibration marks."""
    import argparse

    from blueprint_server.blueprint import resolve_blueprint
    from excavation_sim.world import World

    parser = argparse.ArgumentParser(description="Render a synthetic overhead frame.")
    parser.add_argument("--png", help="write a frame of scenario 0 here")
    parser.add_argument("--marks", help="write calibration marks (YAML) here")
    parser.add_argument("--robots", type=int, default=4)
    parser.add_argument("--blueprint", default="default")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    bp = resolve_blueprint(args.blueprint)
    rows, cols = bp.shape
    cam = OverheadCamera(CameraParams(), default_beacons(), rows, cols, bp.cell_size, args.seed)
    rng = np.random.default_rng(args.seed)
    if args.marks:
        Path(args.marks).write_text(marks_yaml(cam, *calibration_marks(cam, rng)))
        print(f"calibration marks: {args.marks}")
    if args.png:
        world = World.scenario(bp.zones, bp.goal, args.robots, args.seed)
        views = robot_views(world.robots, world.heights, bp.cell_size, bp.height_unit)
        img, _ = cam.render(views, world.heights * bp.height_unit, rng)
        cv2.imwrite(args.png, img)
        print(f"frame: {args.png}")
    return 0


if __name__ == "__main__":
    import sys

    sys.exit(main())
