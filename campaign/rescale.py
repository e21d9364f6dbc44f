"""Rescaling at the tested scale: every finished ANT run's controller on 1-10 robots.

The `scaleup` experiment writes its summary only when all of its settings are trained (ANT
with 1-5 robots and mixed 1 + 4, the fixed network with 1-5). This script compares the
settings that are finished: the best genome of every finished run of each given ANT setting,
on the 8 x 8 pit with 1-10 robots, on the same unseen scenarios as `scaleup` and
`antagonism` (`score_depths`: 100 scenarios split over goal depths 1-3, 300 steps).

    .venv/bin/python campaign/rescale.py --settings n4 mix1+4 --out campaign/rescale

Writes `rescale.csv` (every run and robot count), `rescale.png` (mean +- std over each
setting's controllers) and `section.md`.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np
from tqdm import tqdm

from ant_controller.controller import Controller
from ant_controller.genome_io import load_genome
from ant_evolution.experiments.core import (
    SCALES,
    Context,
    finished_runs,
    pyplot,
    score_depths,
    setting_label,
    training_jobs,
)


def main() -> None:
    """Score every finished run's controller of each setting on 1-10 robots."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--campaign", type=Path, default=Path("campaign"))
    p.add_argument("--scale", default="tested")
    p.add_argument("--settings", nargs="+", default=["n4", "mix1+4"])
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args()
    scale = SCALES[args.scale]
    ctx = Context(args.campaign, scale, scale.runs)
    robots_of = {setting_label(r): r for _, r in training_jobs("scaleup", scale)}
    runs = {s: finished_runs(ctx, "ant", robots_of[s]) for s in args.settings}
    rows = []
    total = sum(len(r) for r in runs.values()) * len(scale.eval_robots)
    with tqdm(total=total, desc="rescale", unit="setting") as bar:
        for label, found in runs.items():
            for k, path in found:
                ctl = Controller.from_genome(load_genome(path), name=str(path))
                for n in scale.eval_robots:
                    sc = score_depths(ctl, ctx, n)
                    rows.append({"setting": label, "run": k, "robots": n,
                                 "mean": float(sc.mean()), "std": float(sc.std())})  # fmt: skip
                    bar.update()
    args.out.mkdir(parents=True, exist_ok=True)
    with open(args.out / "rescale.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]), lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
    robots = list(scale.eval_robots)
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 4), dpi=100)
    lines = [
        "| setting (runs) | " + " | ".join(str(n) for n in robots) + " |",
        "|---|" + "---:|" * len(robots),
    ]
    for label, found in runs.items():
        grid = np.array(
            [[next(r["mean"] for r in rows if r["setting"] == label and r["run"] == k
                   and r["robots"] == n) for n in robots] for k, _ in found]
        )  # fmt: skip
        mean, sd = grid.mean(0), grid.std(0)
        ax.errorbar(robots, mean, yerr=sd, marker="o", ms=3, capsize=2, label=f"ANT {label}")
        lines.append(
            f"| ANT {label} ({len(found)}) | "
            + " | ".join(f"{m:.3f} +- {d:.3f}" for m, d in zip(mean, sd, strict=True))
            + " |"
        )
    ax.set(xlabel="robots", ylabel=f"fitness after {scale.steps} steps, mean over runs",
           ylim=(0, 1.05))  # fmt: skip
    ax.set_title(f"every finished run's controller, 8 x 8 ({scale.name} scale)", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(args.out / "rescale.png")
    plt.close(fig)
    (args.out / "section.md").write_text(
        "Best genome of every finished run of each setting, 8 x 8 pit, "
        f"{scale.eval_scenarios} unseen scenarios per cell (goal depths 1-3), {scale.steps} "
        "steps; fitness mean +- std over the setting's controllers:\n\n" + "\n".join(lines) + "\n",
        encoding="utf-8",
    )
    print("\n".join(lines))


if __name__ == "__main__":
    main()
