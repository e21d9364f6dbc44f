"""``evolve-robots``: N as a gene, and which N the best genomes settle on.

:func:`compute` turns the runs' histories and the N of each run's best genome into the
rows of ``evolve_robots.csv`` (one per N); :func:`run` trains (or reads back) the runs,
then writes the CSV and, from its rows, ``evolve_robots.png`` and ``section.md``.
"""

from __future__ import annotations

import numpy as np

from ant_controller.genome_io import load_genome
from ant_evolution.experiments.core import (
    Context,
    finished_runs,
    train_all,
    training_jobs,
    write_csv,
)
from ant_evolution.experiments.figures import figure
from ant_evolution.experiments.sections import (
    figure_link,
    scale_note,
    section,
    table,
    write_section,
)

NAME = "evolve-robots"


def compute(histories: list[list[dict]], best_n: list[int], robots_range: tuple[int, int]):
    """Runs whose best genome has each N, and each N's share of the late populations.

    Args:
        histories: The runs' histories (their ``robots_hist`` column: ``N:count;...``).
        best_n: The N gene of each run's best genome.
        robots_range: The N gene's bounds.

    Returns:
        One row per N: ``robots``, ``best_genomes``, ``population_share`` (over the last
        20% of each run's generations).
    """
    lo, hi = robots_range
    pop = np.zeros(hi + 1)
    for h in histories:
        for r in h[len(h) - max(1, len(h) // 5) :]:
            for part in filter(None, str(r["robots_hist"]).split(";")):
                n, c = part.split(":")
                pop[int(n)] += int(c)
    pop = pop / max(1.0, pop.sum())
    ns = list(range(lo, hi + 1))
    return [{"robots": n, "best_genomes": best_n.count(n), "population_share": float(pop[n])}
            for n in ns]  # fmt: skip


def run(ctx: Context) -> None:
    """Train (or read back) the runs with N a gene; write the histograms."""
    s = ctx.scale
    trained = train_all(ctx, training_jobs(NAME, s), NAME)
    runs = trained[("ant", "evolve")]
    if not runs:
        raise FileNotFoundError(f"evolve-robots: no finished run in {ctx.out}")
    best_n = [
        int(load_genome(path).tissue.robots) for _, path in finished_runs(ctx, "ant", "evolve")
    ]
    rows = compute(runs, best_n, s.robots_range)
    out = ctx.dir(NAME)
    write_csv(out / "evolve_robots.csv", rows)
    ns = [r["robots"] for r in rows]
    with figure(out / "evolve_robots.png", 1, 2, figsize=(10, 3.6), dpi=100) as (fig, (a1, a2)):
        a1.bar(ns, np.array([r["best_genomes"] for r in rows], dtype=float))
        a1.set(xlabel="N of each run's best genome", ylabel="runs")
        a2.bar(ns, np.array([r["population_share"] for r in rows]))
        a2.set(xlabel="N in the population (last 20% of generations)", ylabel="share")
        for a in (a1, a2):
            a.set_xticks(ns)
            a.grid(alpha=0.3, axis="y")
        fig.suptitle(f"evolved number of robots, {len(runs)} runs ({s.name} scale)", fontsize=9)
    lo, hi = s.robots_range
    body = [[str(r["robots"]), str(r["best_genomes"]), f"{r['population_share']:.2f}"]
            for r in rows]  # fmt: skip
    head = ["N", "runs whose best genome has this N",
            "share of the population, last 20% of generations"]  # fmt: skip
    write_section(
        ctx,
        NAME,
        section(
            "Evolving the number of robots",
            f"{scale_note(ctx, trained)} N is a gene in {lo}..{hi} (every scenario places {hi} "
            "robots and a\ngenome uses its first N).",
            table(head, "rrr", body),
            figure_link(NAME, "evolve_robots.png", "evolve robots"),
        ),
    )
