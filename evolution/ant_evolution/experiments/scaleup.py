"""``scaleup``: controllers evolved with 1-5 robots (and mixed) applied to 1-10 robots on 8 x 8.

The main table is each setting's fittest genome (by training fitness); a second table
scores every finished run's genome (mean +- std over each setting's runs), since one
controller is one sample of what a setting's evolution finds. :func:`compute` scores the
controllers it is given on every robot count (the rows of ``scaleup.csv``); :func:`run`
trains (or reads back) the runs, loads their controllers and writes the CSV, the figures
and ``section.md``.
"""

from __future__ import annotations

from ant_controller.controller import Controller
from ant_evolution.experiments.core import (
    METHOD_LABELS,
    Context,
    GridRow,
    best_of_runs,
    finished_runs,
    load_controller,
    score_depths,
    setting_label,
    train_all,
    training_jobs,
    write_grid_csv,
)
from ant_evolution.experiments.figures import figure, finish
from ant_evolution.experiments.grids import Progress, every_run, robot_grid
from ant_evolution.experiments.sections import (
    figure_link,
    fmt,
    scale_note,
    section,
    table,
    write_section,
)
from excavation_common.progress import tqdm

NAME = "scaleup"
HAND_CODED = "hand-coded"


def compute(
    ctx: Context, controllers: list[tuple[str, object]], progress: Progress
) -> list[GridRow]:
    """Each controller on the scale's robot counts, 8 x 8 pit, scenarios split over depths.

    Args:
        ctx: The context (scale and world switches; nothing is read or written).
        controllers: ``[(label, controller), ...]``, rows in that order.
        progress: Called after each (controller, robot count).
    """
    by_label = dict(controllers)
    labels = [label for label, _ in controllers]
    return robot_grid(lambda label, n: score_depths(by_label[label], ctx, n), labels,
                      ctx.scale.eval_robots, progress)  # fmt: skip


def run(ctx: Context) -> None:
    """Train (or read back) the settings' runs; score their fittest genomes and every run's."""
    s = ctx.scale
    runs = train_all(ctx, training_jobs(NAME, s), "scaleup training")
    plan = [(f"{METHOD_LABELS[m]} {setting_label(r)}", m, r) for (m, r), h in runs.items() if h]
    if not plan:
        raise FileNotFoundError(f"scaleup: no finished run in {ctx.out}")
    controllers = [(label, load_controller(best_of_runs(ctx, m, r)[0])) for label, m, r in plan]
    controllers.append((HAND_CODED, Controller.hand_coded(ctx.readings["hand_coded"])))
    with tqdm(total=len(controllers) * len(s.eval_robots), desc=NAME, unit="setting") as bar:
        rows = compute(ctx, controllers, bar.update)
    out = ctx.dir(NAME)
    write_grid_csv(out / "scaleup.csv", rows, "controller")
    labels = [label for label, _ in controllers]
    by = {(r.key, r.robots): r for r in rows}
    with figure(out / "scaleup.png", 1, 2, figsize=(11, 4), dpi=100, sharey=True) as (_, axes):
        for ax, prefix in zip(axes, ("ANT", "fixed network"), strict=True):
            for lab in labels:
                if lab.startswith(prefix) or lab == HAND_CODED:
                    ys = [by[(lab, n)].mean for n in s.eval_robots]
                    ax.plot(s.eval_robots, ys, marker="o", ms=3,
                            label=lab.replace(prefix + " ", ""),
                            ls="--" if lab == HAND_CODED else "-")  # fmt: skip
            ax.set(xlabel="robots", title=f"{prefix} evolved with n robots", ylim=(0, 1))
            finish(ax, legend=7)
        axes[0].set_ylabel(f"fitness after {s.steps} steps (8 x 8 pit)")
    head = ["controller", *(str(n) for n in s.eval_robots)]
    body = [[lab, *(fmt(by[(lab, n)].mean) for n in s.eval_robots)] for lab in labels]
    every = every_run(
        ctx, NAME, [(label, finished_runs(ctx, m, r)) for label, m, r in plan], "setting",
        lambda c, _label, n: score_depths(c, ctx, n), f"fitness after {s.steps} steps (8 x 8)",
        "each setting",
    )  # fmt: skip
    write_section(
        ctx,
        NAME,
        section(
            "Scaling the evolved controllers to 1-10 robots",
            f"""{scale_note(ctx, runs)} Each row is the fittest genome (by training fitness) of that
setting's runs; columns are robots at evaluation time on the 8 x 8 pit; `n4` = evolved with
4 robots, `mix1+4` = scenarios alternating 1 and 4 robots.""",
            table(head, "l" + "r" * len(s.eval_robots), body),
            figure_link(NAME, "scaleup.png", "scaleup"),
            every,
        ),
    )
