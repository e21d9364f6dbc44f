"""``antagonism``: the 4-robot controller on 6 x 6, 8 x 8 and 10 x 10 pits with 1-10 robots.

:func:`compute` scores a controller on every (pit size, robot count) cell (the rows of
``antagonism.csv``); :func:`run` loads the 4-robot controller, scores it and every 4-robot
ANT run's controller, and writes the CSVs, the figures and ``section.md``.
"""

from __future__ import annotations

from ant_evolution.experiments.core import Context, score_depths, site_text
from ant_evolution.experiments.grids import (
    Progress,
    four_robot_controller,
    robot_grid,
    write_grid,
)
from excavation_common.progress import tqdm

NAME = "antagonism"


def score_cell(controller, ctx: Context, pit: int, robots: int):
    """Per-scenario fitness on a ``pit`` x ``pit`` pit, scenarios split over the depths."""
    return score_depths(controller, ctx, robots, size=pit)


def compute(controller, ctx: Context, progress: Progress) -> list[dict]:
    """``controller`` on each of the scale's pit sizes (``areas``) and robot counts.

    Args:
        controller: The controller scored.
        ctx: The context (scale and world switches; nothing is read or written).
        progress: Called after each cell.
    """
    return robot_grid(lambda a, n: score_cell(controller, ctx, a, n), ctx.scale.areas,
                      ctx.scale.eval_robots, progress)  # fmt: skip


def run(ctx: Context) -> None:
    """Score the 4-robot controller (and every 4-robot run's) on the pit sizes; write them."""
    s = ctx.scale
    ctl, note = four_robot_controller(ctx)
    with tqdm(total=len(s.areas) * len(s.eval_robots), desc=NAME, unit="setting") as bar:
        rows = compute(ctl, ctx, bar.update)
    write_grid(
        ctx, NAME, rows, s.areas, "pit", lambda c, a, n: score_cell(c, ctx, a, n),
        f"fitness after {s.steps} steps", "Antagonism: pit size against robots",
        f"""The 4-robot controller {note} on square pits of {", ".join(map(str, s.areas))} cells
({site_text(ctx.rules.fitted_site)}), {s.eval_scenarios} unseen scenarios per cell
split over goal depths {", ".join(map(str, s.depths))}, {s.steps} steps.""",
    )  # fmt: skip
