"""``ant-perception-bench``: the dome perception measured against simulator truth (paper, 6.2).

Two measurements, both on scenes that change as a real trial does (episodes of the
hand-coded controller on the default blueprint, depth 3: pits deepen and berms grow):

* **Localizer** (:func:`localizer_accuracy`): every tick (1 s) of every episode is rendered by the
  synthetic overhead camera (1280 x 720, low light, noise, glare, lens distortion, robots'
  bodies off their grid pose by a few centimetres and degrees), and the localizer,
  calibrated from marked points like in the field, tracks the robots through the
  episode with the true height map for its LED planes. Reported: share of robot-frames with
  a pose, position error (p50, p95, max, in cells), share of robot-frames whose cardinal
  heading (the one the controller uses) is right, and frames per second of
  :meth:`Localizer.update` on one core.
* **Mapper** (:func:`mapper_accuracy`): one sweep of the synthetic laser (default noise,
  dropouts, robots in the way) over each of those terrains into a fresh mapper with no
  prior; reported: height RMSE over the measured cells (soil units), share of cells
  measured, and scans per second of the mapper core.

``ant-perception-bench --write docs/benchmarks.md --doc docs/perception.md`` replaces the
section between ``<!-- perception-bench -->`` markers in both files (``make bench`` runs it
after ``ant-bench``). No ``rclpy``: only the pure cores are used.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ant_controller.controller import Controller
from ant_evolution.evaluate import advance
from blueprint_server.blueprint import default_blueprint
from excavation_common.files import replace_marked
from excavation_common.frames import yaw_to_heading
from excavation_common.progress import tqdm
from excavation_sim.camera import (
    CameraParams,
    OverheadCamera,
    calibration_marks,
    default_beacons,
    robot_views,
)
from excavation_sim.laser import LaserParams, OverheadLaser, surface_with_robots
from excavation_sim.world import COL, HEADING, ROW, World
from overhead_localizer.camera_model import calibrate
from overhead_localizer.localize import Localizer
from terrain_mapper.mapper import MapperParams, TerrainMapper

MARK = "<!-- perception-bench -->"


def episodes(n_episodes: int, ticks: int, robots: int, seed: int, every: int = 1):
    """``(episode, world)`` at every ``every``-th tick of hand-coded episodes (depth 3)."""
    bp = default_blueprint(3)
    ctl = Controller.hand_coded()
    for e in range(n_episodes):
        world = World.scenario(bp.zones, bp.goal, robots, seed, index=e)
        for t in range(ticks):
            if t % every == 0:
                yield e, world
            advance(world, ctl, 1)


@dataclass(frozen=True)
class LocalizerFigures:
    """Localizer against truth (see :func:`localizer_accuracy`)."""

    frames: int
    robot_frames: int
    reported: float
    p50_cells: float
    p95_cells: float
    max_cells: float
    heading_right: float
    fps: float


def localizer_accuracy(
    n_episodes: int, ticks: int, robots: int = 4, seed: int = 0, progress: bool = False
) -> LocalizerFigures:
    """Track the robots through rendered episodes and compare with truth."""
    bp = default_blueprint(3)
    rows, cols = bp.shape
    cell, unit = bp.cell_size, bp.height_unit
    params = CameraParams.for_site(cols * cell, rows * cell)
    camera = OverheadCamera(params, default_beacons(), rows, cols, cell, seed)
    rng = np.random.default_rng(seed)
    model = calibrate(*calibration_marks(camera, rng), (params.width, params.height))
    errors, right, robot_frames, frames, seconds = [], 0, 0, 0, 0.0
    localizer = None
    last = -1
    for frame, (e, world) in enumerate(
        tqdm(
            episodes(n_episodes, ticks, robots, seed),
            total=n_episodes * ticks,
            desc="localizer frames",
            disable=not progress,
        )
    ):
        tick = frame % ticks  # one frame per simulator tick, 1 s of sim time apart
        if e != last:
            localizer = Localizer(model, default_beacons(), robots)
            last = e
        heights = world.heights * unit
        views = robot_views(world.robots, world.heights, cell, unit)
        image, _ = camera.render(views, heights, rng)
        started = time.perf_counter()
        estimates = localizer.update(image, heights, cell, stamp=float(tick))
        seconds += time.perf_counter() - started
        frames += 1
        for k, est in enumerate(estimates):
            robot_frames += 1
            if not est.reportable:
                continue
            errors.append(math.hypot(est.x - views[k].x, est.y - views[k].y) / cell)
            right += yaw_to_heading(est.yaw) == int(world.robots[k, HEADING])
    err = np.array(errors) if errors else np.array([np.inf])
    return LocalizerFigures(
        frames,
        robot_frames,
        len(errors) / robot_frames,
        float(np.percentile(err, 50)),
        float(np.percentile(err, 95)),
        float(err.max()),
        right / robot_frames,
        frames / seconds,
    )


@dataclass(frozen=True)
class MapperFigures:
    """Mapper against truth (see :func:`mapper_accuracy`)."""

    sweeps: int
    rmse_units: float
    max_units: float
    measured: float
    scans_per_second: float


def mapper_accuracy(
    n_episodes: int,
    ticks: int,
    every: int,
    robots: int = 4,
    seed: int = 0,
    progress: bool = False,
    laser: LaserParams | None = None,
) -> MapperFigures:
    """One sweep per sampled terrain into a fresh mapper; errors over the measured cells."""
    bp = default_blueprint(3)
    rows, cols = bp.shape
    cell, unit = bp.cell_size, bp.height_unit
    lp = laser or LaserParams.for_site(rows, cols, cell)
    scanner = OverheadLaser(lp, cell)
    rng = np.random.default_rng(seed)
    sq, worst, measured, cells, sweeps, scans, seconds = 0.0, 0.0, 0, 0, 0, 0, 0.0
    mp = MapperParams(
        rows=rows, cols=cols, cell_size=cell, mount_x=lp.mount[0], mount_y=lp.mount[1]
    )
    mp = MapperParams(**{**mp.__dict__, "mount_z": lp.mount[2]})
    total = n_episodes * len(range(0, ticks, every))
    for _, world in tqdm(
        episodes(n_episodes, ticks, robots, seed, every),
        total=total,
        desc="mapper sweeps",
        disable=not progress,
    ):
        heights = world.heights * unit
        anchors = world.robots[:, [ROW, COL]]
        sweep = scanner.sweep(surface_with_robots(heights, anchors, lp.robot_height), rng)
        poses = [(v.x, v.y, v.yaw) for v in robot_views(world.robots, world.heights, cell, unit)]
        mapper = TerrainMapper(mp)
        started = time.perf_counter()
        for pan, tilt, ranges in sweep:
            mapper.add_scan(
                ranges, lp.angle_min, lp.angle_increment, lp.range_min, lp.range_max, pan, tilt
            )
        mapper.finish_sweep(poses)
        seconds += time.perf_counter() - started
        scans += len(sweep)
        est = mapper.height_map()
        known = np.isfinite(est)
        diff = (est[known] - heights[known]) / unit
        sq += float((diff**2).sum())
        worst = max(worst, float(np.abs(diff).max()) if diff.size else 0.0)
        measured += int(known.sum())
        cells += est.size
        sweeps += 1
    return MapperFigures(
        sweeps, math.sqrt(sq / max(measured, 1)), worst, measured / cells, scans / seconds
    )


def report(loc: LocalizerFigures, mapper: MapperFigures) -> str:
    """The Markdown section (between markers)."""
    cpu = platform.processor() or platform.machine()
    return "\n".join(
        [
            "## Perception (`ant-perception-bench`)",
            "",
            f"Measured against simulator truth on this machine ({cpu}, one core, Python "
            f"{platform.python_version()}); scenes are hand-coded episodes on the default "
            "blueprint at depth 3, 4 robots (docs/perception.md says how).",
            "",
            "| localizer (1280 x 720, low light, noise, glare, distortion) | value | target |",
            "|---|---|---|",
            f"| frames (robot-frames) | {loc.frames} ({loc.robot_frames}) | |",
            f"| robot-frames with a pose | {loc.reported:.2%} | |",
            f"| position error p50 / p95 / max | {loc.p50_cells:.3f} / {loc.p95_cells:.3f} / "
            f"{loc.max_cells:.3f} cell | p95 < 0.25 cell |",
            f"| cardinal heading right (of all robot-frames) | {loc.heading_right:.3%} | 99.9% |",
            f"| frames per second, one core | {loc.fps:.1f} | 30 |",
            "",
            "| mapper (one sweep, default noise, fresh map) | value | target |",
            "|---|---|---|",
            f"| sweeps of {LaserParams().sweep_scans} scans x {LaserParams().beams} beams | "
            f"{mapper.sweeps} | |",
            f"| height RMSE over measured cells | {mapper.rmse_units:.3f} soil unit | "
            "< 0.25 unit |",
            f"| worst cell | {mapper.max_units:.3f} soil unit | |",
            f"| cells measured (the rest are under robots) | {mapper.measured:.1%} | |",
            f"| scans per second, one core | {mapper.scans_per_second:.0f} | sweep rate x "
            f"{LaserParams().sweep_scans} |",
        ]
    )


def laser_survey(
    heights: np.ndarray,
    robots: np.ndarray,
    cell: float,
    unit: float,
    rng: np.random.Generator,
) -> np.ndarray:
    """One overhead-laser sweep of a grid world through the terrain mapper.

    Args:
        heights: Soil heights in units, ``[rows, cols]``.
        robots: The world's robot states (their footprints hide the ground below them).
        cell: Cell size, m.
        unit: Soil unit, m.
        rng: The laser's noise generator.

    Returns:
        The mapper's height map in metres (NaN: not seen, such as the cells under a robot).
    """
    rows, cols = heights.shape
    lp = LaserParams.for_site(rows, cols, cell)
    scanner = OverheadLaser(lp, cell)
    mp = MapperParams(
        rows=rows,
        cols=cols,
        cell_size=cell,
        mount_x=lp.mount[0],
        mount_y=lp.mount[1],
        mount_z=lp.mount[2],
    )
    anchors = robots[:, [ROW, COL]]
    views = robot_views(robots, heights, cell, unit)
    mapper = TerrainMapper(mp)
    for pan, tilt, ranges in scanner.sweep(
        surface_with_robots(heights * unit, anchors, lp.robot_height), rng
    ):
        mapper.add_scan(
            ranges, lp.angle_min, lp.angle_increment, lp.range_min, lp.range_max, pan, tilt
        )
    mapper.finish_sweep([(v.x, v.y, v.yaw) for v in views])
    return mapper.height_map().astype(np.float64)


def figures(out: Path, seed: int = 0) -> dict:
    """Pictures for docs/perception.md, written to ``out``.

    * ``overhead_frame.png``: a synthetic frame of the shipped genome's episode at tick 150
      with the localizer's poses drawn on it (circle: centre, line: heading);
    * ``before.npy``, ``after.npy``: the mapper's maps (one sweep each) before and after
      300 ticks of the shipped genome (4 robots, default blueprint, depth 1; cells under a
      robot during a survey are unknown), and
      ``field_metrics.png``, the ``field-metrics`` heat map of their difference.

    Returns:
        The field metrics of that run (as a dict).
    """
    import cv2

    from terrain_mapper.field_metrics import draw_difference
    from terrain_mapper.metrics import field_metrics

    out.mkdir(parents=True, exist_ok=True)
    bp = default_blueprint(1)
    rows, cols = bp.shape
    cell, unit = bp.cell_size, bp.height_unit
    ctl = Controller.from_file(Path(__file__).resolve().parents[2] / "genomes" / "best.json")
    world = World.scenario(bp.zones, bp.goal, 4, seed)
    rng = np.random.default_rng(seed)

    def survey() -> np.ndarray:
        return laser_survey(world.heights, world.robots, bp.cell_size, bp.height_unit, rng)

    before = survey()
    advance(world, ctl, 150)
    params = CameraParams.for_site(cols * cell, rows * cell)
    camera = OverheadCamera(params, default_beacons(), rows, cols, cell, seed)
    model = calibrate(*calibration_marks(camera, rng), (params.width, params.height))
    views = robot_views(world.robots, world.heights, cell, unit)
    image, _ = camera.render(views, world.heights * unit, rng)
    estimates = Localizer(model, default_beacons(), 4).update(image, world.heights * unit, cell)
    shown = image.copy()
    for k, est in enumerate(estimates):
        if not est.reportable:
            continue
        tip = (est.x + 0.3 * math.cos(est.yaw), est.y + 0.3 * math.sin(est.yaw), 0.15)
        (cu, cv), (tu, tv) = camera.project(np.array([(est.x, est.y, 0.15), tip]))
        cv2.circle(shown, (round(cu), round(cv)), 24, (255, 255, 255), 2, cv2.LINE_AA)
        cv2.line(shown, (round(cu), round(cv)), (round(tu), round(tv)), (255, 255, 255), 2)
        cv2.putText(shown, f"robot {k}", (round(cu) + 28, round(cv)), 0, 0.7, (255, 255, 255), 2)
    cv2.imwrite(str(out / "overhead_frame.png"), shown)
    advance(world, ctl, 150)
    after = survey()
    np.save(out / "before.npy", before)
    np.save(out / "after.npy", after)
    metrics = field_metrics(before, after, bp.zones, bp.goal * unit, unit / 4)
    draw_difference(before, after, bp.zones, metrics, str(out / "field_metrics.png"), unit)
    return metrics.as_dict()


def one_core() -> None:
    """Run on one CPU (affinity where the OS allows it) with OpenCV single-threaded."""
    import cv2

    cv2.setNumThreads(1)
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ant-perception-bench``."""
    p = argparse.ArgumentParser(prog="ant-perception-bench", description=__doc__.split("\n\n")[0])
    p.add_argument("--episodes", type=int, default=10, help="episodes (default 10)")
    p.add_argument("--ticks", type=int, default=300, help="ticks per episode (default 300)")
    p.add_argument("--every", type=int, default=10, help="mapper: a sweep every N ticks")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--write", metavar="MD", help="put the section into this file")
    p.add_argument("--doc", metavar="MD", help="and into this one")
    p.add_argument("--figures", metavar="DIR", help="also draw the pictures of the docs here")
    args = p.parse_args(argv)
    one_core()
    if args.figures:
        print(f"field metrics of the shipped genome's run: {figures(Path(args.figures))}")
    loc = localizer_accuracy(args.episodes, args.ticks, seed=args.seed, progress=True)
    mapper = mapper_accuracy(args.episodes, args.ticks, args.every, seed=args.seed, progress=True)
    section = report(loc, mapper)
    print(section)
    for target in (args.write, args.doc):
        if target:
            replace_marked(target, section, MARK)
    return 0


if __name__ == "__main__":
    sys.exit(main())
