"""A controller's transfer matrix: the same scenarios on the grid and on each physical soil.

``ant-eval --genome G --transfer OUT.json`` scores a controller on unseen scenarios of each
soil (the grid's soil rules, then the physical soil's presets, :mod:`excavation_sim.cell_soil`)
and writes one row per soil: the mean final fitness, the mean start, the **progress**
against the grid (``(f - f0) / (f_grid - f0)``: 1 is as much as on the grid) and the stalls
per scenario. What crosses the reality gap reads close to 1 on every row.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path

from ant_evolution.evaluate import evaluate
from excavation_common.files import write_text_atomic
from excavation_sim.cell_soil import C_STALLS

SOILS = ("grid", "physical", "physical:dome", "physical:lunar")
"""The soils of a matrix: the grid, the physical soil calibrated to it, the dome, the Moon."""


@dataclass(frozen=True)
class TransferRow:
    """One soil of a transfer matrix (means over its scenarios)."""

    soil: str
    fitness: float
    std: float
    start: float
    progress: float | None
    stalls: float


def transfer_matrix(
    controller, blueprint, n_robots: int, scenarios: int, steps: int, seed: int, rules,
    soils: tuple[str, ...] = SOILS,
) -> list[TransferRow]:  # fmt: skip
    """``controller`` on ``scenarios`` scenarios of ``seed`` on each soil (the first: grid)."""
    rows = []
    grid_gain = None
    for soil in soils:
        result = evaluate(controller, blueprint, n_robots, scenarios, steps, seed, rules, soil)
        start = float(result.curves[:, 0].mean())
        gain = result.mean - start
        if grid_gain is None:
            grid_gain = gain
        stalls = 0.0 if result.counters is None else float(result.counters[:, C_STALLS].mean())
        rows.append(
            TransferRow(
                soil,
                result.mean,
                float(result.scores.std()),
                start,
                gain / grid_gain if grid_gain else None,
                stalls,
            )
        )
    return rows


def table(rows: list[TransferRow]) -> str:
    """The matrix as a Markdown table."""
    lines = [
        "| soil | fitness (mean, std) | start | progress against the grid | stalls per scenario |",
        "|---|---|---:|---:|---:|",
    ]
    for r in rows:
        progress = "n/a" if r.progress is None else f"{r.progress:.2f}"
        lines.append(
            f"| `{r.soil}` | {r.fitness:.3f} ({r.std:.3f}) | {r.start:.3f} | {progress} | "
            f"{r.stalls:.1f} |"
        )
    return "\n".join(lines)


def write(path: Path, rows: list[TransferRow], about: dict) -> None:
    """``path``: the matrix as JSON (``about``: what was scored, on what)."""
    data = {"format": "ant-transfer/1", **about, "rows": [asdict(r) for r in rows]}
    write_text_atomic(Path(path), json.dumps(data, indent=1, allow_nan=False) + "\n")
