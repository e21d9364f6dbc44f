"""``ant-bag report``: figures and a markdown summary of a recorded trial.

From a bag (:mod:`excavation_bags.trial_data` reads it) the report writes into its
output directory:

* ``fitness.png``: the paper's fitness per frame, as the simulator published it
  (``/worksite/fitness``) and as recomputed from the height map and the blueprint;
* ``snapshots.png``: the terrain and the robots at five moments (``excavation_sim.snapshots``);
* ``trial.gif``: the whole trial, one frame per height map (every ``gif_stride``-th);
* ``detectors.png``: the paper's Table 3 sensor-behaviour detectors
  (:mod:`excavation_sim.detectors`) counted over the trial, cumulative per frame;
* ``field_metrics.png``: the field metrics of ``terrain_mapper.metrics`` between the first
  and the last height map, with the difference heat map;
* ``camera.png`` (only for a bag with camera frames): five overhead camera frames over the
  trial, decoded from ``/overhead/image_raw/compressed`` (or raw ``/overhead/image_raw``);
* ``tracks.png`` and the field figures (only for a continuous or dome run: the robots'
  tracks, drift at each goal's end, lost tracks, stuck events, aborted goals and
  primitives, time per tick; :mod:`excavation_bags.field_report`);
* ``summary.md`` and ``report.json``: the numbers (with the bag's size per minute of
  recording), the bag's topics, and every warning.

A bag that lacks what a section needs still gets every other section; the summary says
what was skipped and why. Nothing here raises for a bad bag: problems become lines of
the summary.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from excavation_bags.reader import Bag  # noqa: E402
from excavation_bags.trial_data import (  # noqa: E402
    FITNESS,
    GOAL,
    HEIGHTS,
    MAP_INFO,
    ZONES,
    TrialData,
    read_trial,
)
from excavation_sim.detectors import DETECTOR_TITLES, DETECTORS, detect  # noqa: E402


@dataclass
class Report:
    """What a report wrote and found.

    Attributes:
        out: Output directory.
        files: Files written (names relative to ``out``).
        skipped: Section -> why it was skipped.
        numbers: JSON-ready figures (fitness, detector counts, field metrics ...).
        warnings: Warnings about the bag and its messages.
    """

    out: Path
    files: list[str] = field(default_factory=list)
    skipped: dict[str, str] = field(default_factory=dict)
    numbers: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)


def _needs(data: TrialData, *topics: str) -> str | None:
    missing = [t for t in topics if not data.topics.get(t)]
    return f"the bag has no {', '.join(missing)}" if missing else None


def recomputed_fitness(data: TrialData) -> np.ndarray:
    """The paper's fitness of each frame's height map (NaN where a dig cell is unknown)."""
    out = np.full(len(data.heights), np.nan)
    if data.zones is None or data.goal is None:
        return out
    dig = data.zones == 1
    goal = data.goal_units
    for i in range(len(data.heights)):
        h = data.heights_units(i)
        if h.shape != dig.shape or (h[dig] == np.iinfo(np.int32).min).any():
            continue
        out[i] = float(np.mean(np.exp(-2.0 * np.abs(goal[dig] - h[dig])))) if dig.any() else 0.0
    return out


def _frame_axis(data: TrialData) -> tuple[np.ndarray, str]:
    t = np.array(data.frame_times, dtype=np.float64)
    if len(t) > 1 and np.all(np.diff(t) > 0):
        return t - t[0], "time since the first height map (s)"
    return np.arange(len(t), dtype=np.float64), "frame"


def plot_fitness(data: TrialData, report: Report) -> None:
    """``fitness.png``: recorded and recomputed fitness per frame."""
    why = _needs(data, HEIGHTS) or (
        _needs(data, ZONES, GOAL) if not data.topics.get(FITNESS) else None
    )
    if not why and not data.heights:
        why = "no usable /worksite/height_map message"
    if why:
        report.skipped["fitness"] = why
        return
    x, label = _frame_axis(data)
    recorded = np.array(data.fitness, dtype=np.float64)
    recomputed = recomputed_fitness(data)
    fig, ax = plt.subplots(figsize=(6, 3.5), dpi=100)
    if np.isfinite(recorded).any():
        ax.plot(x, recorded, label="published (/worksite/fitness)", lw=2)
    if np.isfinite(recomputed).any():
        ax.plot(x, recomputed, "--", label="from height map and blueprint", lw=1.2)
    ax.set_xlabel(label)
    ax.set_ylabel("fitness")
    ax.set_ylim(0, 1)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    ax.set_title("Fitness over the trial")
    _save(fig, report, "fitness.png")
    final = recorded[np.isfinite(recorded)]
    final_re = recomputed[np.isfinite(recomputed)]
    report.numbers["fitness"] = {
        "first": float(final[0]) if len(final) else None,
        "final": float(final[-1]) if len(final) else None,
        "recomputed_final": float(final_re[-1]) if len(final_re) else None,
        "frames": len(data.heights),
    }


def _robots_for(data: TrialData, i: int) -> tuple[np.ndarray, np.ndarray]:
    from excavation_sim.world import ROBOT_FIELDS

    p = data.poses[i]
    robots = np.zeros((p.shape[0], ROBOT_FIELDS), dtype=np.int64)
    robots[:, :4] = np.maximum(p, 0)
    active = (p[:, 0] >= 0) & (p[:, 1] >= 0)
    robots[~active, 3] = 3
    return robots, active


def _display_heights(data: TrialData, i: int) -> np.ndarray:
    h = data.heights_units(i)
    return np.where(h == np.iinfo(np.int32).min, 0, h)


def plot_snapshots(data: TrialData, report: Report, count: int = 5) -> None:
    """``snapshots.png``: terrain and robots at ``count`` evenly spaced frames."""
    from excavation_sim.snapshots import save_strip

    why = _needs(data, HEIGHTS, ZONES) or ("no frames" if not data.heights else None)
    if why:
        report.skipped["snapshots"] = why
        return
    n = len(data.heights)
    picks = sorted({round(j * (n - 1) / max(count - 1, 1)) for j in range(count)})
    frames = []
    for i in picks:
        robots, active = _robots_for(data, i)
        frames.append((i, _display_heights(data, i), robots[active]))
    save_strip(report.out / "snapshots.png", frames, data.zones, title="Terrain (frame index)")
    report.files.append("snapshots.png")


def write_gif(data: TrialData, report: Report, stride: int | None = None, fps: float = 8.0) -> None:
    """``trial.gif``: one image per (``stride``-th) frame; progress on a tqdm bar."""
    from PIL import Image

    from excavation_common.progress import tqdm
    from excavation_sim.snapshots import draw_world

    why = _needs(data, HEIGHTS, ZONES) or ("no frames" if not data.heights else None)
    if why:
        report.skipped["animation"] = why
        return
    n = len(data.heights)
    stride = stride or max(1, math.ceil(n / 120))
    images = []
    fig, ax = plt.subplots(figsize=(3.6, 3.6), dpi=80)
    # The zone outlines are the same in every frame: draw them once (with no robot) and keep
    # those lines; each frame then draws heights and robots over an outline-free zone map.
    no_robots = np.zeros((0, data.poses[0].shape[1]), dtype=np.int64)
    draw_world(ax, _display_heights(data, 0), data.zones, no_robots)
    outlines = set(ax.lines)
    no_zones = np.zeros_like(data.zones)
    for i in tqdm(range(0, n, stride), desc="gif frames", unit="frame", leave=False):
        for artist in [*ax.images, *ax.patches, *ax.texts, *ax.artists]:
            artist.remove()
        for artist in [a for a in ax.lines if a not in outlines]:
            artist.remove()
        for artist in [c for c in ax.get_children() if type(c).__name__ == "Annotation"]:
            artist.remove()
        robots, active = _robots_for(data, i)
        fit = data.fitness[i]
        title = f"frame {i}" + (f"  fitness {fit:.3f}" if math.isfinite(fit) else "")
        draw_world(ax, _display_heights(data, i), no_zones, robots, active, title)
        fig.canvas.draw()
        rgba = np.asarray(fig.canvas.buffer_rgba())
        images.append(Image.fromarray(rgba[..., :3].copy()).quantize(colors=64))
    plt.close(fig)
    images[0].save(
        report.out / "trial.gif",
        save_all=True,
        append_images=images[1:],
        duration=int(1000 / fps),
        loop=0,
    )
    report.files.append("trial.gif")
    report.numbers["animation"] = {"frames": len(images), "stride": stride}


def plot_detectors(data: TrialData, report: Report) -> None:
    """``detectors.png``: Table 3 detector counts, cumulative over frames."""
    frames, sensors, behaviours, turns = data.decision_arrays()
    if not len(sensors):
        decided = sum(1 for _ in data.decisions)
        report.skipped["detectors"] = (
            "no /robot_k/behaviour in the bag"
            if not decided
            else f"none of the {decided} decisions has all its inputs in the bag "
            "(poses, height map, blueprint, blade joint states, stuck flags)"
        )
        return
    hits = detect(sensors, behaviours, turns)
    n = max(len(data.heights), int(frames.max()) + 1)
    x, label = _frame_axis(data) if len(data.heights) == n else (np.arange(n), "frame")
    fig, ax = plt.subplots(figsize=(6, 3.5), dpi=100)
    totals = {}
    for name in DETECTORS:
        per_frame = np.bincount(frames[hits[name]], minlength=n)[:n]
        ax.plot(x, np.cumsum(per_frame), label=DETECTOR_TITLES[name], lw=1.6)
        totals[name] = int(hits[name].sum())
    ax.set_xlabel(label)
    ax.set_ylabel("detections so far (all robots)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    ax.set_title("Table 3 sensor-behaviour detectors")
    _save(fig, report, "detectors.png")
    report.numbers["detectors"] = {
        "decisions": len(sensors),
        "decisions_without_inputs": len(data.decisions) - len(sensors),
        "random_turn_direction_known": int((turns != 0).sum()),
        "counts": totals,
    }


def field_metrics_section(data: TrialData, report: Report) -> None:
    """``field_metrics.png`` and numbers, between the first and the last height map."""
    why = _needs(data, HEIGHTS, ZONES, GOAL)
    if not why and len(data.heights) < 2:
        why = "fewer than two height maps"
    if why:
        report.skipped["field metrics"] = why
        return
    try:
        from terrain_mapper.field_metrics import draw_difference
        from terrain_mapper.metrics import field_metrics
    except ImportError as exc:  # the terrain_mapper package is not installed
        report.skipped["field metrics"] = f"terrain_mapper is not installed ({exc})"
        return
    before, after = data.heights[0], data.heights[-1]
    if before.shape != data.zones.shape or after.shape != data.zones.shape:
        report.skipped["field metrics"] = "height maps and blueprint differ in size"
        return
    m = field_metrics(before, after, data.zones, data.goal, tolerance=0.25 * data.height_unit)
    draw_difference(before, after, data.zones, m, str(report.out / "field_metrics.png"))
    report.files.append("field_metrics.png")
    report.numbers["field_metrics"] = {
        k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in m.as_dict().items()
    }


def field_section(bag: Bag, data: TrialData, report: Report) -> None:
    """``tracks.png`` and the field figures (:mod:`excavation_bags.field_report`).

    Only for a continuous or dome run (poses and drive executors' statuses in the bag).
    """
    from excavation_bags.field_report import field_figures, field_robots, plot_tracks

    if not field_robots(bag):  # a lockstep trial: no drive executors, nothing to measure
        return
    if data.cell_size is None:
        report.skipped["field"] = "no /worksite/map_info: the cell size is unknown"
        return
    tracks: dict = {}
    figures = field_figures(bag, data.cell_size, tracks)
    plot_tracks(figures, tracks, report.out / "tracks.png")
    report.files.append("tracks.png")
    for robot in figures["robots"].values():
        robot.pop("goal_ends")
    report.numbers["field"] = figures


def _save(fig, report: Report, name: str) -> None:
    fig.tight_layout()
    fig.savefig(report.out / name)
    plt.close(fig)
    report.files.append(name)


def _num(v) -> str:
    return "n/a" if v is None else f"{v:.4f}"


def camera_section(data: TrialData, report: Report) -> None:
    """``camera.png``: a few camera frames over the trial (only when the bag has frames)."""
    if data.camera_topic is None:
        return
    sizes = np.array(data.camera_bytes, dtype=np.float64)
    times = np.array(data.camera_times, dtype=np.float64)
    span = float(times[-1] - times[0]) if len(times) > 1 else 0.0
    report.numbers["camera"] = {
        "topic": data.camera_topic,
        "frames": len(times),
        "frames_per_s": (len(times) - 1) / span if span > 0 else None,
        "mean_frame_bytes": float(sizes.mean()) if len(sizes) else None,
    }
    if not data.camera_frames:
        report.skipped["camera"] = f"no frame of {data.camera_topic} decodes"
        return
    fig, axes = plt.subplots(
        1, len(data.camera_frames), figsize=(3.2 * len(data.camera_frames), 2.4), dpi=100
    )
    axes = np.atleast_1d(axes)
    t0 = times[0]
    for ax, (index, stamp, image) in zip(axes, data.camera_frames, strict=True):
        if image.ndim == 2:
            ax.imshow(image, cmap="gray", vmin=0, vmax=255)
        else:
            ax.imshow(image[..., ::-1])
        ax.set_title(f"frame {index} ({stamp - t0:.1f} s)", fontsize=8)
        ax.axis("off")
    fig.suptitle(f"Overhead camera ({data.camera_topic})", fontsize=9)
    _save(fig, report, "camera.png")


def _pct(v) -> str:
    return "n/a" if v is None else f"{100 * v:.1f} %"


def summary_markdown(bag: Bag, data: TrialData, report: Report) -> str:
    """The report's ``summary.md``."""
    lines = [f"# Trial report: `{bag.path}`", ""]
    producer = bag.producer or "unknown"
    lines += [
        f"- producer: {producer}, ROS distro: {bag.ros_distro or 'unknown'}, "
        f"{bag.message_count} messages on {len(bag.topics)} topics"
        + (" (**truncated bag**: read up to the last complete chunk)" if bag.truncated else ""),
        f"- robots: {data.robots}, frames (height maps): {len(data.heights)}, "
        f"cell size: {data.cell_size if data.cell_size is not None else 'unknown'} m, "
        f"soil unit: {data.height_unit} m",
    ]
    size = report.numbers["bag"]
    per_minute = size["bytes_per_minute"]
    lines.append(
        f"- size: {size['bytes'] / 1e6:.2f} MB over {size['duration_s']:.1f} s of recording"
        + (f" ({per_minute / 1e6:.2f} MB per minute)" if per_minute is not None else "")
    )
    cam = report.numbers.get("camera")
    if cam:
        rate = cam["frames_per_s"]
        mean = cam["mean_frame_bytes"]
        lines.append(
            f"- camera: {cam['frames']} frames on `{cam['topic']}`"
            + (f", {rate:.1f} per s of header stamps" if rate else "")
            + (f", {mean / 1e3:.1f} kB per frame" if mean else "")
        )
    fit = report.numbers.get("fitness")
    if fit:
        lines.append(
            f"- fitness: {_num(fit['first'])} at the start, **{_num(fit['final'])}** at the "
            f"end (recomputed from the last height map: {_num(fit['recomputed_final'])})"
        )
    det = report.numbers.get("detectors")
    if det:
        lines += ["", "## Table 3 detectors", "", "| detector | count |", "|---|---|"]
        lines += [f"| {DETECTOR_TITLES[k]} | {v} |" for k, v in det["counts"].items()]
        lines += [
            "",
            f"{det['decisions']} decisions with known inputs "
            f"({det['decisions_without_inputs']} without); {det['random_turn_direction_known']} "
            "Random Turns whose direction the next pose shows (Correct dump needs it).",
        ]
    fm = report.numbers.get("field_metrics")
    if fm:
        lines += [
            "",
            "## Field metrics (first vs last height map)",
            "",
            "| dig area towards goal | above goal | below goal | indeterminate | "
            "dumped soil in dump zones |",
            "|---|---|---|---|---|",
            f"| {_pct(fm['towards_goal'])} | {_pct(fm['above_goal'])} | "
            f"{_pct(fm['below_goal'])} | {_pct(fm['indeterminate'])} | "
            f"{_pct(fm['dump_share'])} |",
        ]
    if report.files:
        lines += ["", "## Figures", ""]
        lines += [
            f"![{f}]({f})" if f.endswith((".png", ".gif")) else f"- {f}" for f in report.files
        ]
    field_run = report.numbers.get("field")
    if field_run:
        lines += [
            "",
            "## Robots in the field (tracks.png)",
            "",
            "| robot | poses | track, m | goals ended | aborted | stuck | primitives "
            "aborted | drift at goal end, cm (mean / max) | heading error, deg (max) | frames "
            "without a pose | longest lost, s |",
            "|---|---|---|---|---|---|---|---|---|---|---|",
        ]

        def n(v, spec: str = "") -> str:
            return "n/a" if v is None else format(v, spec)

        for k, r in field_run["robots"].items():
            lines.append(
                f"| {k} | {r['poses']} | {r['track_m']:.2f} | {r['goals_ended']} | "
                f"{r['goals_aborted']} | {r['stuck_events']} | {n(r['primitives_aborted'])} "
                f"| {n(r['drift_cm_mean'], '.1f')} / {n(r['drift_cm_max'], '.1f')} | "
                f"{n(r['heading_error_deg_max'], '.1f')} | {n(r['frames_without_pose'])} of "
                f"{r['frames']} | {n(r['longest_lost_s'], '.2f')} |"
            )
        t = field_run["ticks"]
        lines += [
            "",
            f"{t['count']} ticks; wall time per tick mean {n(t['wall_mean_s'], '.2f')} s, "
            f"median {n(t['wall_median_s'], '.2f')} s, longest {n(t['wall_max_s'], '.2f')} s.",
        ]
    if report.skipped:
        lines += ["", "## Skipped", ""]
        lines += [f"- {k}: {v}" for k, v in report.skipped.items()]
    if report.warnings:
        lines += ["", "## Warnings", ""]
        lines += [f"- {w}" for w in report.warnings]
    lines += ["", "## Topics", "", "| topic | type | messages |", "|---|---|---|"]
    lines += [f"| `{t.name}` | {t.msgtype} | {t.count} |" for t in bag.topics.values()]
    return "\n".join(lines) + "\n"


def make_report(
    bag: Bag,
    out: str | Path,
    height_unit: float | None = None,
    gif: bool = True,
    gif_stride: int | None = None,
) -> Report:
    """Write every section the bag allows into ``out``; see the module docstring."""
    from excavation_common.files import write_text_atomic

    report = Report(Path(out))
    report.out.mkdir(parents=True, exist_ok=True)
    data = read_trial(bag, height_unit)
    report.warnings = list(bag.warnings) + data.problems
    report.numbers["bag"] = {
        "bytes": bag.size_bytes,
        "duration_s": bag.duration_s,
        "bytes_per_minute": bag.bytes_per_minute,
    }
    if not data.topics.get(MAP_INFO):
        report.warnings.append("the bag has no /worksite/map_info: robot poses are unknown")
    plot_fitness(data, report)
    plot_snapshots(data, report)
    if gif:
        write_gif(data, report, gif_stride)
    else:
        report.skipped["animation"] = "not asked for (--no-gif)"
    plot_detectors(data, report)
    field_metrics_section(data, report)
    camera_section(data, report)
    field_section(bag, data, report)
    report.files.append("summary.md")
    report.files.append("report.json")
    write_text_atomic(report.out / "summary.md", summary_markdown(bag, data, report))
    payload = {
        "bag": str(bag.path),
        "producer": bag.producer,
        "truncated": bag.truncated,
        "robots": data.robots,
        "frames": len(data.heights),
        **report.numbers,
        "files": report.files,
        "skipped": report.skipped,
        "warnings": report.warnings,
    }
    write_text_atomic(report.out / "report.json", json.dumps(payload, indent=2) + "\n")
    return report
