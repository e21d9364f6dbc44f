"""``depth`` and ``area``: the 4-robot controller after a long run, one sweep of long runs.

Both score the 4-robot controller for the scale's ``long_steps`` (the paper: 10,000) on
cells of a key by robot count (1-10); they differ only in their cells (:data:`SWEEPS`):

* ``depth``: the 8 x 8 pit at each goal depth of the scale, every scenario of a cell at
  that depth (seed ``EVAL_SEED + robots``);
* ``area``: square pits of the scale's ``area_sizes``, each cell's scenarios split over the
  goal depths as in training (:func:`~ant_evolution.experiments.core.depth_split`).

:func:`compute` scores a controller on the cells of one sweep (the rows of ``NAME.csv``);
:func:`run` (the commands :func:`depth` and :func:`area`) loads the 4-robot controller,
scores it and every 4-robot ANT run's controller, and writes the CSVs, the figures and
``section.md``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from ant_evolution.experiments.core import (
    EVAL_SEED,
    Context,
    Scale,
    depth_split,
    score_parts,
    site_text,
)
from ant_evolution.experiments.grids import (
    Progress,
    four_robot_controller,
    robot_grid,
    write_grid,
)
from excavation_common.progress import tqdm

Cell = tuple[int, list[tuple[int, int, int]]]
"""A long run's site: the pit's size and its ``(depth, scenarios, seed)`` parts."""


def _depth_cell(scale: Scale, depth: int, robots: int) -> Cell:
    return 8, [(depth, scale.eval_scenarios, EVAL_SEED + robots)]


def _area_cell(scale: Scale, pit: int, robots: int) -> Cell:
    return pit, depth_split(scale, robots)


def _depth_text(scale: Scale, note: str, fitted: bool) -> str:
    return f"""The 4-robot controller {note} on the 8 x 8 pit ({site_text(fitted)}) at goal depths
{", ".join(map(str, scale.depths))}, {scale.eval_scenarios} unseen scenarios per cell,
{scale.long_steps} steps."""


def _area_text(scale: Scale, note: str, fitted: bool) -> str:
    sizes = ", ".join(map(str, scale.area_sizes))
    return f"""The 4-robot controller {note} on square pits of {sizes}
cells ({site_text(fitted)}), {scale.eval_scenarios} unseen
scenarios per cell split over goal depths {", ".join(map(str, scale.depths))},
{scale.long_steps} steps."""


@dataclass(frozen=True)
class Sweep:
    """The cells of one long-run command.

    Attributes:
        name: The command, its output directory and files.
        key_label: The key's column name.
        keys: The scale's keys.
        cell: ``cell(scale, key, robots)``: the site of a cell.
        title: The section's title.
        text: ``text(scale, note, fitted)``: the section's paragraph on what ran (``fitted``:
            the profile's ``site`` switch).
    """

    name: str
    key_label: str
    keys: Callable[[Scale], tuple[int, ...]]
    cell: Callable[[Scale, int, int], Cell]
    title: str
    text: Callable[[Scale, str, bool], str]


SWEEPS = {
    "depth": Sweep("depth", "depth", lambda s: s.depths, _depth_cell,
                   "Goal depth after a long run", _depth_text),
    "area": Sweep("area", "pit", lambda s: s.area_sizes, _area_cell,
                  "Growing the excavation area", _area_text),
}  # fmt: skip
"""The long-run commands."""


def score_cell(controller, ctx: Context, sweep: Sweep, key: int, robots: int):
    """Per-scenario fitness of one cell after ``long_steps``."""
    pit, parts = sweep.cell(ctx.scale, key, robots)
    return score_parts(
        controller, pit, parts, robots, ctx.scale.long_steps, ctx.rules, ctx.soil, ctx.randomise
    )


def compute(controller, ctx: Context, sweep: Sweep, progress: Progress) -> list[dict]:
    """``controller`` on each cell of ``sweep`` (key by robot count) after the long run.

    Args:
        controller: The controller scored.
        ctx: The context (scale and world switches; nothing is read or written).
        sweep: The cells (one of :data:`SWEEPS`).
        progress: Called after each cell.
    """
    return robot_grid(lambda key, n: score_cell(controller, ctx, sweep, key, n),
                      sweep.keys(ctx.scale), ctx.scale.eval_robots, progress)  # fmt: skip


def run(ctx: Context, name: str) -> None:
    """Score the 4-robot controller (and every 4-robot run's) on sweep ``name``'s cells."""
    s = ctx.scale
    sweep = SWEEPS[name]
    keys = sweep.keys(s)
    ctl, note = four_robot_controller(ctx)
    with tqdm(total=len(keys) * len(s.eval_robots), desc=name, unit="setting") as bar:
        rows = compute(ctl, ctx, sweep, bar.update)
    write_grid(
        ctx, name, rows, keys, sweep.key_label,
        lambda c, key, n: score_cell(c, ctx, sweep, key, n),
        f"fitness after {s.long_steps} steps", sweep.title,
        sweep.text(s, note, ctx.rules.fitted_site),
    )  # fmt: skip


def depth(ctx: Context) -> None:
    """``depth``: the 4-robot controller at goal depths 1-3 after a long run, 1-10 robots."""
    run(ctx, "depth")


def area(ctx: Context) -> None:
    """``area``: the 4-robot controller on growing pits after a long run, 1-10 robots."""
    run(ctx, "area")
