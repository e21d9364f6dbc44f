"""``coarse-coding``: ANT with and without coarse coding for each training robot count.

:func:`compute` turns the runs' histories into the rows of ``coarse_coding.csv`` (one per
method and robot count); :func:`run` trains (or reads back) the runs, then writes the CSV
and, from its rows, ``coarse_coding.png`` and ``section.md``.
"""

from __future__ import annotations

from ant_evolution.experiments.core import (
    METHOD_LABELS,
    SOLVED,
    Context,
    history_columns,
    train_all,
    training_jobs,
    write_csv,
)
from ant_evolution.experiments.figures import figure, finish
from ant_evolution.experiments.sections import (
    figure_link,
    fmt,
    scale_note,
    section,
    table,
    write_section,
)

NAME = "coarse-coding"
METHODS = ("ant", "ant-nocc")


def compute(runs: dict, robots: tuple[int, ...]) -> list[dict]:
    """Maximum fitness at the end of the runs of each method and robot count.

    Args:
        runs: ``{(method, robots): [history, ...]}`` (``train_all``'s answer); settings
            without a run are left out.
        robots: The robot counts, in order.
    """
    rows = []
    for m in METHODS:
        for n in robots:
            if not runs[(m, n)]:  # --finished: none of this setting's runs is finished yet
                continue
            ever = history_columns(runs[(m, n)], "best_ever")[:, -1]
            rows.append({"method": m, "robots": n, "runs": len(ever),
                         "max_fitness_mean": float(ever.mean()),
                         "max_fitness_std": float(ever.std()),
                         "p_solution": float((ever >= SOLVED).mean())})  # fmt: skip
    return rows


def run(ctx: Context) -> None:
    """Train (or read back) ANT's runs with and without coarse coding; write the summary."""
    s = ctx.scale
    runs = train_all(ctx, training_jobs(NAME, s), NAME)
    rows = compute(runs, s.train_robots)
    if not rows:
        raise FileNotFoundError(f"coarse-coding: no finished run in {ctx.out}")
    out = ctx.dir(NAME)
    with figure(out / "coarse_coding.png", figsize=(6, 4), dpi=100) as (_, ax):
        for m in METHODS:
            sel = [r for r in rows if r["method"] == m]
            if sel:
                ax.errorbar([r["robots"] for r in sel], [r["max_fitness_mean"] for r in sel],
                            yerr=[r["max_fitness_std"] for r in sel], marker="o", capsize=3,
                            label=METHOD_LABELS[m])  # fmt: skip
        ax.set(xlabel="robots in training", ylabel="maximum fitness (mean over runs)", ylim=(0, 1))
        ax.set_xticks(list(s.train_robots))
        finish(ax)
        ax.set_title(f"coarse coding on and off ({s.name} scale)", fontsize=9)
    write_csv(out / "coarse_coding.csv", rows)
    cell = {(r["method"], r["robots"]): r for r in rows}

    def fmt_cell(r: dict | None) -> str:
        if r is None:
            return "-"
        return f"{fmt(r['max_fitness_mean'])} +- {fmt(r['max_fitness_std'])} ({r['runs']})"

    body = [[str(n), *(fmt_cell(cell.get((m, n))) for m in METHODS)] for n in s.train_robots]
    write_section(
        ctx,
        NAME,
        section(
            "ANT with and without coarse coding",
            f"{scale_note(ctx, runs)} Each cell: maximum fitness at the end, mean +- std over "
            "the runs\n(their number).",
            table(["robots", "with coarse coding", "without coarse coding"], "rrr", body),
            figure_link(NAME, "coarse_coding.png", "coarse coding"),
        ),
    )
