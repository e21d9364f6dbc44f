"""A controller's transfer matrix: the same scenarios on the grid and on each physical soil.

``ant-eval --genome G --transfer OUT.json`` scores a controller on unseen scenarios of each
soil (the grid's soil rules, then the physical soil's presets, :mod:`excavation_sim.cell_soil`)
and writes one row per soil: the mean final fitness, the mean start, the **progress**
against the grid (``(f - f0) / (f_grid - f0)``: 1 is as much as on the grid) and the stalls
per scenario. What crosses the reality gap reads close to 1 on every row. Two more rows
score the randomised worlds training may use (:mod:`ant_evolution.randomise`), on the grid
and on the dome's soil. A training run on physical soil, with a second soil or randomised
writes its best genome's matrix when it finishes (``ant-evolve``, :func:`write_for_run`).
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path

from ant_evolution.evaluate import evaluate
from excavation_common.files import write_text_atomic
from excavation_sim.cell_soil import C_STALLS

SOILS = (
    ("grid", False),
    ("physical", False),
    ("physical:dome", False),
    ("physical:lunar", False),
    ("grid", True),
    ("physical:dome", True),
)
"""The rows of a matrix, ``(soil, randomised)``: the grid, the physical soil calibrated to
it, the dome, the Moon, then the grid and the dome randomised."""
TRANSFER_SEED = 1000
"""Seed of a run's matrix scenarios (unseen: a run's generations draw theirs from
``SeedSequence([seed, generation])``)."""


@dataclass(frozen=True)
class TransferRow:
    """One soil of a transfer matrix (means over its scenarios)."""

    soil: str
    randomised: bool
    fitness: float
    std: float
    start: float
    progress: float | None
    stalls: float


def transfer_matrix(
    controller, blueprint, n_robots: int, scenarios: int, steps: int, seed: int, rules,
    soils: tuple[tuple[str, bool], ...] = SOILS,
) -> list[TransferRow]:  # fmt: skip
    """``controller`` on ``scenarios`` scenarios of ``seed`` on each ``(soil, randomised)``.

    The first row is the reference of every row's progress (the plain grid in :data:`SOILS`).
    """
    rows = []
    grid_gain = None
    for soil, randomised in soils:
        result = evaluate(
            controller, blueprint, n_robots, scenarios, steps, seed, rules, soil, randomised
        )
        start = float(result.curves[:, 0].mean())
        gain = result.mean - start
        if grid_gain is None:
            grid_gain = gain
        stalls = 0.0 if result.counters is None else float(result.counters[:, C_STALLS].mean())
        rows.append(
            TransferRow(
                soil,
                randomised,
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
        name = f"`{r.soil}`" + (" randomised" if r.randomised else "")
        lines.append(
            f"| {name} | {r.fitness:.3f} ({r.std:.3f}) | {r.start:.3f} | {progress} | "
            f"{r.stalls:.1f} |"
        )
    return "\n".join(lines)


def write(path: Path, rows: list[TransferRow], about: dict) -> None:
    """``path``: the matrix as JSON (``about``: what was scored, on what)."""
    data = {"format": "ant-transfer/1", **about, "rows": [asdict(r) for r in rows]}
    write_text_atomic(Path(path), json.dumps(data, indent=1, allow_nan=False) + "\n")


def about(controller, blueprint, n_robots: int, scenarios: int, steps: int, seed: int) -> dict:
    """What a matrix scored, on what (its JSON's header and its table's title)."""
    return {
        "controller": controller.name,
        "blueprint": blueprint.name,
        "robots": n_robots,
        "scenarios": scenarios,
        "steps": steps,
        "seed": seed,
    }


def title(header: dict) -> str:
    """The one-line title of a matrix (:func:`about`'s header)."""
    return (
        f"{header['controller']} | {header['blueprint']} | {header['robots']} robots | "
        f"{header['scenarios']} scenarios x {header['steps']} steps | seed {header['seed']}"
    )


def write_for_run(run_dir: Path, config, scenarios: int) -> str:
    """The matrix of a finished run's best genome: ``RUN/transfer.json`` and ``transfer.md``.

    Scored as ``ant-eval --transfer`` scores it: the default blueprint at depth 1, the
    run's robot count and steps, ``scenarios`` scenarios of :data:`TRANSFER_SEED`, under
    the run's rules. Returns the table.
    """
    from ant_controller.controller import Controller
    from blueprint_server.blueprint import resolve_blueprint

    run_dir = Path(run_dir)
    controller = Controller.from_file(str(run_dir / "best.json"))
    rules = config.world_rules
    blueprint = resolve_blueprint("default", 1, rules.fitted_site)
    n_robots = controller.robots or config.robots
    rows = transfer_matrix(
        controller, blueprint, n_robots, scenarios, config.steps, TRANSFER_SEED, rules
    )
    header = about(controller, blueprint, n_robots, scenarios, config.steps, TRANSFER_SEED)
    write(run_dir / "transfer.json", rows, header)
    text = f"{title(header)}\n\n{table(rows)}\n"
    write_text_atomic(run_dir / "transfer.md", text)
    return text
