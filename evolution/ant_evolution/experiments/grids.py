"""Robot-count grids: controllers scored on every (key, robot count) cell of an experiment.

``scaleup``, ``antagonism``, ``depth`` and ``area`` each score a controller on cells of a
key (a controller, a pit size, a goal depth) by robot count, and then the best genome of
every finished training run on the same cells. The grids (:func:`robot_grid`,
:func:`every_run_grid`, :func:`every_run_summary`) are pure: they score what they are
given and return rows. Reading the controllers from their files (:func:`load_runs`,
:func:`four_robot_controller`) and writing the part on every run (:func:`every_run`) are
for the experiments' run steps.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from ant_controller.controller import Controller
from ant_controller.genome_io import load_genome
from ant_evolution.experiments import figures, sections
from ant_evolution.experiments.core import (
    Context,
    EveryRunGroup,
    GridRow,
    compare_robots,
    finished_runs,
    four_robot_genome,
    load_controller,
    training_fitness,
    write_grid_csv,
)
from excavation_common.progress import tqdm
from excavation_sim.world import PlacementError

Progress = Callable[[], object]
"""Called once per scored cell (a progress bar's ``update``)."""


def _no_progress() -> None:
    return None


def cell_stats(scores: Callable[[], np.ndarray]) -> tuple[float, float]:
    """Mean and std of a cell's per-scenario fitness.

    NaN when the robots do not fit the cell's site (``PlacementError``: 10 robots on the
    paper profile's fitted 8 x 8 site around a 4 x 4 pit, say).
    """
    try:
        sc = scores()
    except PlacementError:
        return float("nan"), float("nan")
    return float(sc.mean()), float(sc.std())


def robot_grid(
    score_cell: Callable[[object, int], np.ndarray],
    keys: Sequence,
    robots: Sequence[int],
    progress: Progress = _no_progress,
) -> list[GridRow]:
    """One row per (key, robot count): mean and std of ``score_cell(key, robots)``.

    Args:
        score_cell: Per-scenario fitness of one cell.
        keys: The keys, in order (rows come key by key).
        robots: The robot counts.
        progress: Called after each cell.
    """
    rows = []
    for key in keys:
        for n in robots:
            mean, std = cell_stats(lambda: score_cell(key, n))  # noqa: B023 (called at once)
            rows.append(GridRow(key, n, mean, std))
            progress()
    return rows


RunGroups = list[tuple[object, list[tuple[int, Path]]]]
"""``[(key, [(run, best.json), ...]), ...]``: the runs scored for each key."""

LoadedGroups = list[tuple[object, list[tuple[int, object, float]]]]
"""``[(key, [(run, controller, training fitness), ...]), ...]``."""


def load_runs(groups: RunGroups) -> LoadedGroups:
    """Each run's controller and training fitness (a file read once, however many keys)."""
    loaded: dict = {}
    out = []
    for key, runs in groups:
        row = []
        for k, path in runs:
            if path not in loaded:
                loaded[path] = (load_controller(path), training_fitness(path))
            row.append((k, *loaded[path]))
        out.append((key, row))
    return out


def every_run_grid(
    groups: LoadedGroups,
    score_cell: Callable[[object, object, int], np.ndarray],
    robots: Sequence[int],
    progress: Progress = _no_progress,
) -> list[GridRow]:
    """The grid for every run's controller, group by group (``NAME_runs.csv``'s rows).

    Args:
        groups: :func:`load_runs`'s answer.
        score_cell: ``score_cell(controller, key, robots)``: per-scenario fitness of a cell.
        robots: The robot counts.
        progress: Called after each cell.
    """
    rows = []
    for key, runs in groups:
        for k, ctl, fit in runs:
            for n in robots:
                mean, std = cell_stats(lambda: score_cell(ctl, key, n))  # noqa: B023
                rows.append(GridRow(key, n, mean, std, run=k, training_fitness=fit))
                progress()
    return rows


def every_run_wanted(groups: Sequence[tuple[object, Sequence]]) -> bool:
    """Whether a group has two runs or more (with fewer the part says nothing new)."""
    return max((len(runs) for _, runs in groups), default=0) >= 2


def every_run_summary(
    rows: Sequence[GridRow], groups: Sequence[tuple[object, Sequence]], robots
) -> list[EveryRunGroup]:
    """:func:`every_run_grid`'s rows per group (groups without a run are left out).

    Args:
        rows: :func:`every_run_grid`'s rows.
        groups: ``[(key, [(run, ...), ...]), ...]``: which runs each key has.
        robots: The robot counts.
    """
    robots = list(robots)
    grid = {(r.run, r.key, r.robots): r.mean for r in rows}
    out = []
    for key, runs in groups:
        if not runs:
            continue
        per_run = np.array([[grid[(run[0], key, n)] for n in robots] for run in runs])
        peaks = [robots[sections.peak_index(row)] for row in per_run]
        out.append(EveryRunGroup(key, len(runs), per_run.mean(0), per_run.std(0), peaks,
                                 float(np.median(peaks))))  # fmt: skip
    return out


def four_robot_controller(ctx: Context) -> tuple[Controller, str]:
    """The 4-robot controller (:func:`~.core.four_robot_genome`) and a note for the text."""
    path = four_robot_genome(ctx)
    g = load_genome(path)
    fit = g.metadata.get("fitness") if isinstance(g.metadata, dict) else None
    shown = f"{fit:.3f}" if isinstance(fit, float) else fit
    return Controller.from_genome(g, name=str(path)), f"`{path}` (training fitness {shown})"


def four_robot_runs(ctx: Context, keys) -> RunGroups:
    """The groups of every 4-robot ANT run, the same runs for every key.

    None when ``--genome`` names the controller.
    """
    runs = [] if ctx.genome is not None else finished_runs(ctx, "ant", compare_robots(ctx.scale))
    return [(key, runs) for key in keys]


def every_run(
    ctx: Context,
    name: str,
    groups: RunGroups,
    key_label: str,
    score_cell: Callable[[object, object, int], np.ndarray],
    ylabel: str,
    what: str,
) -> str:
    """An experiment's grid for the best genome of every finished run, group by group.

    One controller is one sample of what evolution finds; the numbers of every run's own
    controller show how much a result depends on the run. Writes ``NAME_runs.csv`` and
    ``NAME_runs.png`` into the experiment's directory.

    Args:
        ctx: The context.
        name: The experiment.
        groups: The runs scored for each key.
        key_label: The key's column name (``pit``, ``depth``, ``setting``).
        score_cell: ``score_cell(controller, key, robots)``: per-scenario fitness of a cell.
        ylabel: The figure's y label.
        what: Which runs these are, for the text (``the 4-robot ANT runs``).

    Returns:
        The section's part on them; "" when no group has two finished runs.
    """
    if not every_run_wanted(groups):
        return ""
    s = ctx.scale
    loaded = load_runs(groups)
    total = sum(len(runs) for _, runs in groups) * len(s.eval_robots)
    with tqdm(total=total, desc=f"{name}, every run", unit="setting") as bar:
        rows = every_run_grid(loaded, score_cell, s.eval_robots, bar.update)
    stem = name.replace("-", "_")
    write_grid_csv(ctx.dir(name) / f"{stem}_runs.csv", rows, key_label)
    summary = every_run_summary(rows, groups, s.eval_robots)
    title = f"best genome of every finished run of {what} ({s.name} scale)"
    figures.every_run_figure(ctx.dir(name) / f"{stem}_runs.png", summary, key_label,
                             s.eval_robots, ylabel, title)  # fmt: skip
    return sections.every_run_part(summary, key_label, s.eval_robots, name, what)


def write_grid(
    ctx: Context,
    name: str,
    rows: list[GridRow],
    keys: Sequence,
    key_label: str,
    score_cell: Callable[[object, object, int], np.ndarray],
    ylabel: str,
    title: str,
    what_ran: str,
) -> None:
    """The outputs of a 4-robot controller's grid (``antagonism``, ``depth``, ``area``).

    ``NAME.csv`` (``rows``: :func:`robot_grid`'s), ``NAME.png``, the part on every 4-robot
    ANT run (:func:`every_run`, the same cells scored by ``score_cell``) and
    ``section.md``: ``title``, the paragraph ``what_ran``, the table of peaks, the figure.
    """
    out = ctx.dir(name)
    write_grid_csv(out / f"{name}.csv", rows, key_label)
    figures.robot_grid_figure(out / f"{name}.png", rows, keys, key_label, ylabel)
    every = every_run(ctx, name, four_robot_runs(ctx, keys), key_label, score_cell, ylabel,
                      "the 4-robot ANT runs")  # fmt: skip
    sections.write_section(
        ctx,
        name,
        sections.section(
            title,
            what_ran,
            sections.peak_table(rows, keys, key_label, ctx.scale.eval_robots),
            sections.figure_link(name, f"{name}.png", name),
            every,
        ),
    )
