"""Terrain snapshots as PNG images, like the paper's simulation-snapshot figure.

Each image shows soil heights (brown above ground, blue below), the blueprint's dig area
(solid outline) and dump band (dashed outline), and every robot as its 2 x 2 footprint
with a bar for the blade and an arrow for its heading. North is up: grid row 0 is drawn at
the bottom, as in the ``map`` frame.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib import patches  # noqa: E402

from ant_controller.layout import BLADE_HOME  # noqa: E402
from ant_controller.sensing import FORWARD, front_cell  # noqa: E402
from excavation_sim.world import BLADE, COL, HEADING, ROW  # noqa: E402

_COLOURS = (
    "tab:red",
    "tab:orange",
    "tab:purple",
    "tab:cyan",
    "tab:pink",
    "tab:olive",
    "tab:gray",
    "tab:green",
    "black",
    "white",
)


def _outline(ax, mask: np.ndarray, **style) -> None:
    """Draw the edges between cells inside and outside ``mask``."""
    rows, cols = mask.shape
    for r in range(rows):
        for c in range(cols):
            if not mask[r, c]:
                continue
            if r == 0 or not mask[r - 1, c]:
                ax.plot([c, c + 1], [r, r], **style)
            if r == rows - 1 or not mask[r + 1, c]:
                ax.plot([c, c + 1], [r + 1, r + 1], **style)
            if c == 0 or not mask[r, c - 1]:
                ax.plot([c, c], [r, r + 1], **style)
            if c == cols - 1 or not mask[r, c + 1]:
                ax.plot([c + 1, c + 1], [r, r + 1], **style)


def draw_world(ax, heights, zones, robots, active=None, title: str = "", limit: int = 3) -> None:
    """Draw one terrain snapshot on a matplotlib axis (cell (r, c) spans [c, c+1] x [r, r+1])."""
    rows, cols = heights.shape
    vmax = max(limit, int(np.abs(heights).max()))
    im = ax.imshow(
        heights,
        origin="lower",
        extent=(0, cols, 0, rows),
        cmap="BrBG_r",
        vmin=-vmax,
        vmax=vmax,
        interpolation="nearest",
    )
    _outline(ax, zones == 1, color="black", linewidth=1.5)
    _outline(ax, zones == 2, color="darkgreen", linewidth=1.0, linestyle="--")
    for k in range(robots.shape[0]):
        if active is not None and not active[k]:
            continue
        r, c, h = int(robots[k, ROW]), int(robots[k, COL]), int(robots[k, HEADING])
        colour = _COLOURS[k % len(_COLOURS)]
        ax.add_patch(patches.Rectangle((c, r), 2, 2, facecolor=colour, alpha=0.6, edgecolor="k"))
        if robots[k, BLADE] != BLADE_HOME:
            (r0, c0), (r1, c1) = front_cell(r, c, h, 0), front_cell(r, c, h, 1)
            xs = [c0 + 0.5 - 0.45 * FORWARD[h, 1], c1 + 0.5 - 0.45 * FORWARD[h, 1]]
            ys = [r0 + 0.5 - 0.45 * FORWARD[h, 0], r1 + 0.5 - 0.45 * FORWARD[h, 0]]
            ax.plot(xs, ys, color="k", linewidth=3)
        ax.annotate(
            "",
            xy=(c + 1 + 0.9 * FORWARD[h, 1], r + 1 + 0.9 * FORWARD[h, 0]),
            xytext=(c + 1, r + 1),
            arrowprops={"arrowstyle": "->", "color": "k", "lw": 1.5},
        )
        ax.text(c + 0.15, r + 0.15, str(k), fontsize=7)
    ax.set_xlim(0, cols)
    ax.set_ylim(0, rows)
    ax.set_aspect("equal")
    ax.set_title(title, fontsize=9)
    ax.set_xticks([])
    ax.set_yticks([])
    return im


def save_snapshot(path: str | Path, heights, zones, robots, active=None, title: str = "") -> Path:
    """Write one snapshot PNG and return its path."""
    fig, ax = plt.subplots(figsize=(4.2, 4.2), dpi=100)
    im = draw_world(ax, heights, zones, robots, active, title)
    fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04, label="soil height (units)")
    return _save(fig, path)


def save_strip(
    path: str | Path,
    frames: Sequence[tuple[int, np.ndarray, np.ndarray]],
    zones,
    active=None,
    title: str = "",
) -> Path:
    """Write several snapshots side by side; ``frames`` holds ``(step, heights, robots)``."""
    n = len(frames)
    fig, axes = plt.subplots(1, n, figsize=(3.0 * n, 3.4), dpi=100, squeeze=False)
    for ax, (step, heights, robots) in zip(axes[0], frames, strict=True):
        draw_world(ax, heights, zones, robots, active, f"t = {step}")
    if title:
        fig.suptitle(title, fontsize=10)
    return _save(fig, path)


def _save(fig, path: str | Path) -> Path:
    """Lay out, write and close a figure; returns the path."""
    fig.tight_layout()
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(p)
    plt.close(fig)
    return p
