"""``training``: best fitness per generation for each training robot count (mean and spread).

:func:`compute` turns the runs' histories into the rows of ``training.csv``; :func:`run`
trains (or reads back) the runs, then writes the CSV and, from its rows, ``training.png``
and ``section.md``.
"""

from __future__ import annotations

import numpy as np

from ant_evolution.experiments.core import (
    SOLVED,
    Context,
    history_columns,
    train_all,
    training_jobs,
    write_csv,
)
from ant_evolution.experiments.figures import figure
from ant_evolution.experiments.sections import (
    figure_link,
    fmt,
    scale_note,
    section,
    table,
    write_section,
)

NAME = "training"


def curves(rows: list[dict], robots: int, key: str) -> np.ndarray:
    """``[runs, generations]`` of one column of ``robots``' rows (runs cut to the shortest)."""
    per_run: dict[int, list[dict]] = {}
    for r in rows:
        if r["robots"] == robots:
            per_run.setdefault(r["run"], []).append(r)
    return history_columns(list(per_run.values()), key)


def compute(runs: dict, robots: tuple[int, ...]) -> list[dict]:
    """One row per robot count, run and generation.

    Args:
        runs: ``{("ant", n): [history, ...]}`` (``train_all``'s answer).
        robots: The robot counts, in order.
    """
    return [
        {
            "robots": n,
            "run": k,
            "generation": r["generation"],
            "evaluations": r["evaluations"],
            "best": r["best"],
            "best_ever": r["best_ever"],
        }  # fmt: skip
        for n in robots
        for k, h in enumerate(runs[("ant", n)])
        for r in h
    ]


def run(ctx: Context) -> None:
    """Train (or read back) the ANT runs with each robot count; write the summary."""
    s = ctx.scale
    runs = train_all(ctx, training_jobs(NAME, s), NAME)
    if not any(runs.values()):
        raise FileNotFoundError(f"training: no finished run in {ctx.out}")
    rows = compute(runs, s.train_robots)
    out = ctx.dir(NAME)
    write_csv(out / "training.csv", rows)
    # --finished: the settings with a finished run
    have = [n for n in s.train_robots if any(r["robots"] == n for r in rows)]
    with figure(out / "training.png", figsize=(6.5, 4), dpi=100) as (_, ax):
        for n in have:
            best = curves(rows, n, "best")
            gens = np.arange(best.shape[1])
            m, sd = best.mean(0), best.std(0)
            ax.plot(gens, m, label=f"{n} robot{'s' if n > 1 else ''}")
            ax.fill_between(gens, m - sd, m + sd, alpha=0.15)
        ax.axhline(SOLVED, color="gray", ls=":", lw=0.8)
        ax.set(xlabel="generation", ylabel="best fitness of the generation", ylim=(0, 1))
        ax.set_title(f"ANT training, mean +- std over the runs ({s.name} scale)", fontsize=9)
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
    body = []
    for n in have:
        best = curves(rows, n, "best")
        tail = best[:, -max(1, best.shape[1] // 10) :].mean(1)
        ever = curves(rows, n, "best_ever")[:, -1]
        body.append([str(n), f"{fmt(tail.mean())} +- {fmt(tail.std())}", fmt(ever.mean()),
                     f"{int((ever >= SOLVED).sum())} / {len(ever)}"])  # fmt: skip
    head = ["robots", "best of generation, last 10% (mean +- std)", "best ever (mean)",
            f"runs reaching {SOLVED}"]  # fmt: skip
    write_section(
        ctx,
        NAME,
        section(
            "Training with 1 to 5 robots",
            scale_note(ctx, runs),
            table(head, "rrrr", body),
            figure_link(NAME, "training.png", "training"),
        ),
    )
