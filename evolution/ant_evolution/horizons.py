"""How many timesteps a controller needs on each preset to make its grid progress.

The transfer matrix (:mod:`ant_evolution.transfer`) scores the presets at most
:data:`~ant_evolution.transfer.MAX_HORIZON` times the grid's horizon, while the presets'
robots stall at 0.27-0.29 units of a level pile where the grid's push 12
(docs/world-model.md, "Presets"): a ratio near 40. This module measures the whole curve
instead::

    python -m ant_evolution.horizons --out DIR --controller genomes/best.json
        --controller genomes/dome/best.json --controller hand-coded

scores every controller on the same unseen scenarios (the matrix's: seed 1000, the default
blueprint at depth 1, 4 robots) on the grid for ``--base`` steps (300, the matrix's
reference) and on each preset for ``--steps`` (default 12,000: 40 times that), and writes

* ``DIR/horizons.csv``: per controller, soil and step (every ``--every`` steps and the
  last) the mean fitness and the **progress** ``(f - f0) / (f_grid - f0)`` against the
  controller's own grid fitness at ``--base`` steps (empty where it gains nothing there);
* ``DIR/horizons.png``: progress against steps (log scale), a panel per preset;
* ``DIR/horizons.md``: per controller and preset the progress at 1, 3, 10 and 40 times
  the base, its peak and where, and the first step at which it reaches 0.8 (the goal's
  progress).

Deterministic: the scenarios and the controllers' random turns are seeded.
"""

from __future__ import annotations

import argparse
import csv
import io
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ant_evolution.transfer import GOAL_PROGRESS, PRESETS, TRANSFER_SEED
from excavation_common.files import write_text_atomic
from excavation_common.progress import tqdm

MULTIPLES = (1, 3, 10, 40)
"""Horizons the table reads, in multiples of the base."""


@dataclass(frozen=True)
class Curve:
    """One controller on one soil: the mean fitness after every step, over its scenarios."""

    controller: str
    soil: str
    fitness: np.ndarray
    """``float64 [steps + 1]``: the start, then after each step."""
    start: float
    """The grid's mean start (every soil starts from the same heights)."""
    grid: float
    """The controller's mean grid fitness at the base horizon (its progress's 1)."""

    @property
    def progress(self) -> np.ndarray | None:
        """``(f - f0) / (f_grid - f0)`` after every step; None where the grid gains nothing."""
        gain = self.grid - self.start
        if gain <= 0:
            return None
        return (self.fitness - self.start) / gain

    def first_reaching(self, level: float = GOAL_PROGRESS) -> int | None:
        """The first step at which the progress is at least ``level`` (None: never)."""
        p = self.progress
        if p is None:
            return None
        hits = np.flatnonzero(p >= level)
        return int(hits[0]) if hits.size else None


def curves(
    programs: dict, scenarios: int, base: int, steps: int, seed: int, robots: int
) -> list[Curve]:
    """Every controller of ``programs`` (name: decision program) on every preset."""
    from ant_evolution.evaluate import evaluate
    from blueprint_server.blueprint import resolve_blueprint

    blueprint = resolve_blueprint("default", 1)
    out = []
    with tqdm(total=len(programs) * (1 + len(PRESETS)), desc="horizons", unit="soil") as bar:
        for spec, program in programs.items():
            grid = evaluate(program, blueprint, robots, scenarios, base, seed)
            bar.update()
            start = float(grid.curves[:, 0].mean())
            for soil in PRESETS:
                result = evaluate(program, blueprint, robots, scenarios, steps, seed, soil=soil)
                out.append(Curve(spec, soil, result.curves.mean(axis=0), start, grid.mean))
                bar.update()
    return out


def csv_text(found: list[Curve], every: int) -> str:
    """The curves as CSV rows: controller, soil, step, fitness, progress."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["controller", "soil", "step", "fitness", "progress"])
    for c in found:
        p = c.progress
        last = len(c.fitness) - 1
        for t in sorted(set(range(0, last + 1, every)) | {last}):
            w.writerow(
                [c.controller, c.soil, t, f"{c.fitness[t]:.6f}", "" if p is None else f"{p[t]:.6f}"]
            )
    return buf.getvalue()


def table(found: list[Curve], base: int) -> str:
    """Progress at each multiple of the base, the peak, and the first step reaching 0.8."""
    heads = " | ".join(f"{m * base} steps" for m in MULTIPLES)
    lines = [
        f"| controller | grid at {base} steps | soil | {heads} | peak (step) | first reaching "
        f"{GOAL_PROGRESS} |",
        "|---|---:|---|" + "---:|" * len(MULTIPLES) + "---:|---:|",
    ]
    for c in found:
        p = c.progress
        steps = len(c.fitness) - 1
        cells = []
        for m in MULTIPLES:
            t = m * base
            if t > steps:
                cells.append("-")
            elif p is None:
                cells.append(f"{c.fitness[t]:.3f}")
            else:
                cells.append(f"{c.fitness[t]:.3f} ({p[t]:.2f})")
        peak = int(np.argmax(c.fitness))
        peak_text = f"{c.fitness[peak]:.3f}" + ("" if p is None else f" ({p[peak]:.2f})")
        first = c.first_reaching()
        lines.append(
            f"| `{c.controller}` | {c.grid:.3f} | `{c.soil}` | " + " | ".join(cells)
            + f" | {peak_text} at {peak} | {f'not in {steps}' if first is None else first} |"
        )  # fmt: skip
    return "\n".join(lines)


def plot(found: list[Curve], base: int, path: Path) -> None:
    """Progress against steps, a panel per preset (fitness where the grid gains nothing)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(PRESETS), figsize=(11, 4.2), sharey=True)
    for ax, soil in zip(axes, PRESETS, strict=True):
        for c in (c for c in found if c.soil == soil and c.progress is not None):
            steps = np.arange(1, len(c.fitness))
            ax.plot(steps, c.progress[1:], label=c.controller)
        ax.axhline(GOAL_PROGRESS, color="grey", linestyle="--", linewidth=0.8)
        for m in (1, 3):
            ax.axvline(m * base, color="grey", linestyle=":", linewidth=0.8)
        ax.set_xscale("log")
        ax.set_title(soil)
        ax.set_xlabel("timesteps")
    axes[0].set_ylabel("progress against the grid at the base horizon")
    axes[-1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    """``python -m ant_evolution.horizons``: the curves, their table and figure."""
    from ant_controller.controller import Controller
    from ant_controller.errors import GenomeFormatError
    from excavation_common.limits import int_in

    ap = argparse.ArgumentParser(prog="python -m ant_evolution.horizons", description=__doc__)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument(
        "--controller", action="append", required=True, help="a genome file or hand-coded"
    )
    ap.add_argument("--scenarios", type=int_in(1, 10_000), default=100)
    ap.add_argument("--base", type=int_in(1, 100_000), default=300, help="the grid's steps")
    ap.add_argument("--steps", type=int_in(1, 1_000_000), default=12_000, help="on the presets")
    ap.add_argument("--every", type=int_in(1, 1_000_000), default=50, help="CSV row spacing")
    ap.add_argument("--seed", type=int, default=TRANSFER_SEED)
    ap.add_argument("--robots", type=int_in(1, 10), default=4)
    args = ap.parse_args(argv)
    if args.steps < args.base:
        ap.error(f"--steps {args.steps} must be at least --base {args.base}")
    try:  # every genome is read before the long part starts
        programs = {spec: Controller.from_spec(spec) for spec in args.controller}
    except (OSError, GenomeFormatError) as e:
        print(f"horizons: {e}", file=sys.stderr)
        return 2
    found = curves(programs, args.scenarios, args.base, args.steps, args.seed, args.robots)
    args.out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(args.out / "horizons.csv", csv_text(found, args.every))
    text = (
        f"{args.scenarios} scenarios of seed {args.seed}, the default blueprint at depth 1, "
        f"{args.robots} robots; grid {args.base} steps, presets {args.steps} steps. "
        "Fitness (progress).\n\n" + table(found, args.base) + "\n"
    )
    write_text_atomic(args.out / "horizons.md", text)
    plot(found, args.base, args.out / "horizons.png")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
