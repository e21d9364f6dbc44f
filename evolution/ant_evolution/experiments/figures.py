"""Figure writers: the PNGs every experiment writes into ``OUT/<name>/``.

:func:`figure` opens a figure and writes it (laid out, saved, closed) however the drawing
ends; the writers below draw the figures several experiments share: fitness over robot
counts, one line per key, for one controller and for every run's controller.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from ant_evolution.experiments.core import EveryRunGroup, GridRow, pyplot


@contextmanager
def figure(path: Path, *args, **kw) -> Iterator[tuple]:
    """``(fig, axes)`` of ``pyplot.subplots(*args, **kw)``; saved to ``path`` at the end.

    The figure is closed whether or not the drawing raised (then nothing is saved).
    """
    plt = pyplot()
    fig, axes = plt.subplots(*args, **kw)
    try:
        yield fig, axes
        fig.tight_layout()
        fig.savefig(path)
    finally:
        plt.close(fig)


def finish(ax, legend: float = 8) -> None:
    """The axes' light grid and legend (font size ``legend``)."""
    ax.grid(alpha=0.3)
    ax.legend(fontsize=legend)


def robot_grid_figure(
    path: Path, rows: Sequence[GridRow], keys, key_label: str, ylabel: str
) -> None:
    """Fitness (mean +- std over scenarios) by robot count, one line per key."""
    with figure(path, figsize=(6, 4), dpi=100) as (_, ax):
        for key in keys:
            sel = [r for r in rows if r.key == key]
            ax.errorbar([r.robots for r in sel], [r.mean for r in sel],
                        yerr=[r.std for r in sel], marker="o", ms=3, capsize=2,
                        label=f"{key_label} {key}")  # fmt: skip
        ax.set(xlabel="robots", ylabel=ylabel, ylim=(0, 1.05))
        finish(ax)


def every_run_figure(
    path: Path, groups: list[EveryRunGroup], key_label: str, robots, ylabel: str, title: str
) -> None:
    """Fitness by robot count, mean +- std over every run's controller, one line per key."""
    robots = list(robots)
    with figure(path, figsize=(6, 4), dpi=100) as (_, ax):
        for g in groups:
            ax.errorbar(robots, g.mean, yerr=g.std, marker="o", ms=3, capsize=2,
                        label=f"{key_label} {g.key}")  # fmt: skip
        ax.set(xlabel="robots", ylabel=f"{ylabel}, mean over runs", ylim=(0, 1.05))
        ax.set_title(title, fontsize=9)
        finish(ax)
