"""Tables and a figure comparing the hand-coded sweeps of each reading (docs/results.md).

Run from the repository root after the sweeps (commands in docs/results.md, "Paper profile"):

    .venv/bin/python docs/figures/paper_profile/compare.py
"""

from __future__ import annotations

import csv
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

HERE = Path(__file__).parent
READINGS = (
    ("v1", "v1 (all first readings)"),
    ("soil_fill", "v1 + soil_fill"),
    ("capacity", "v1 + normal_load 24"),
    ("placement", "v1 + placement worksite"),
    ("site", "v1 + site fitted"),
    ("worksite", "v1 + placement and site"),
    ("h1", "v1 + h1 absolute"),
    ("hand_coded", "v1 + hand_coded union"),
    ("paper_chain", "paper, hand_coded chain"),
    ("paper", "paper (all literal readings)"),
)


def load(name: str) -> dict:
    """``(depth, robots) -> mean fitness`` of one sweep."""
    with open(HERE / name / "sweep.csv", newline="") as f:
        return {(int(r["depth"]), int(r["robots"])): float(r["mean"]) for r in csv.DictReader(f)}


def main() -> None:
    """Write ``compare.md`` and ``compare.png`` beside this script."""
    data = {name: load(name) for name, _ in READINGS if (HERE / name / "sweep.csv").exists()}
    robots = sorted({n for d in data.values() for _, n in d})
    lines = []
    for depth in (1, 2, 3):
        lines += [
            f"Depth {depth}:",
            "",
            "| reading | " + " | ".join(str(n) for n in robots) + " | best N |",
            "|---|" + "---:|" * (len(robots) + 1),
        ]
        for name, label in READINGS:
            if name not in data:
                continue
            vals = [data[name][(depth, n)] for n in robots]
            best = robots[max(range(len(robots)), key=vals.__getitem__)]
            lines.append(f"| {label} | " + " | ".join(f"{v:.3f}" for v in vals) + f" | {best} |")
        lines.append("")
    (HERE / "compare.md").write_text("\n".join(lines))
    fig, axes = plt.subplots(1, 3, figsize=(13, 4), dpi=100, sharey=True)
    for ax, depth in zip(axes, (1, 2, 3), strict=True):
        for name, label in READINGS:
            if name in data:
                style = "-" if name in ("v1", "paper") else "--"
                width = 2.0 if name in ("v1", "paper") else 1.0
                ax.plot(robots, [data[name][(depth, n)] for n in robots], style, lw=width,
                        marker="o", ms=3, label=label)  # fmt: skip
        ax.set(title=f"hand-coded, depth {depth}", xlabel="robots", ylim=(0, 1))
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("fitness after 300 steps (100 scenarios)")
    axes[-1].legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    fig.savefig(HERE / "compare.png")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
