"""A controller's transfer matrix: the same scenarios on the grid and on each physical soil.

``ant-eval --genome G --transfer OUT.json`` scores a controller on unseen scenarios of each
soil (the grid's soil rules, then the physical soil's presets, :mod:`excavation_sim.cell_soil`)
and writes one row per soil: the mean final fitness, the mean start, the **progress**
against the grid (``(f - f0) / (f_grid - f0)``: 1 is as much as on the grid) and the stalls
per scenario. What crosses the reality gap reads close to 1 on every row. Two more rows
score the randomised worlds training may use (:mod:`ant_evolution.randomise`), on the grid
and on the dome's soil. A training run on physical soil, with a second soil or randomised
writes its best genome's matrix when it finishes (``ant-evolve``, :func:`write_for_run`).

Where a preset's robot physically moves less soil per push than the grid lets it (its
measured stall capacity, :func:`excavation_sim.soil.stall_capacity`, against the grid's
push capacity without throttle-up), the same controller needs more timesteps for the same
work: the matrix scores each preset again at a horizon scaled by that ratio, at most
:data:`MAX_HORIZON` times (:func:`scaled_horizon`), and its progress there is what
:func:`goal` compares. The goal of the reality-gap work, for a controller's matrix beside
the hand-coded rules' of the same scenarios (:func:`goal`): at least 0.9 on the grid, at
least 0.8 of its grid progress on each preset at the scaled horizon, and above the
hand-coded rules on each preset.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path

from ant_evolution.evaluate import evaluate
from excavation_common.files import write_text_atomic
from excavation_sim.cell_soil import C_STALLS
from excavation_sim.soil import SoilParams, stall_capacity

PRESETS = ("physical:dome", "physical:lunar")
"""The presets of the paper's two real worlds (the goal's soils)."""
SOILS = (
    ("grid", False, 1),
    ("physical", False, 1),
    ("physical:dome", False, 1),
    ("physical:lunar", False, 1),
    ("grid", True, 1),
    ("physical:dome", True, 1),
    ("physical:dome", False, None),
    ("physical:lunar", False, None),
)
"""The rows of a matrix, ``(soil, randomised, horizon)``: the grid, the physical soil
calibrated to it, the dome, the Moon, the grid and the dome randomised, then the two
presets at their scaled horizon (``None``: :func:`scaled_horizon`); ``horizon`` multiplies
the steps."""
MAX_HORIZON = 3
"""Most a preset's horizon is scaled by."""
GOAL_GRID, GOAL_PROGRESS = 0.9, 0.8
"""The goal's grid fitness and progress on each preset at its scaled horizon."""
TRANSFER_SEED = 1000
"""Seed of a run's matrix scenarios (unseen: a run's generations draw theirs from
``SeedSequence([seed, generation])``)."""


@dataclass(frozen=True)
class TransferRow:
    """One soil of a transfer matrix (means over its scenarios)."""

    soil: str
    randomised: bool
    steps: int
    fitness: float
    std: float
    start: float
    progress: float | None
    stalls: float


def transfer_matrix(
    controller, blueprint, n_robots: int, scenarios: int, steps: int, seed: int, rules,
    soils: tuple[tuple[str, bool, int | None], ...] = SOILS,
) -> list[TransferRow]:  # fmt: skip
    """``controller`` on ``scenarios`` scenarios of ``seed`` on each row of ``soils``.

    The first row is the reference of every row's progress (the plain grid in :data:`SOILS`).
    """
    rows = []
    grid_gain = None
    for soil, randomised, horizon in soils:
        if horizon is None:
            horizon = scaled_horizon(soil, blueprint, rules)
        result = evaluate(
            controller, blueprint, n_robots, scenarios, steps * horizon, seed, rules, soil,
            randomised,
        )  # fmt: skip
        start = float(result.curves[:, 0].mean())
        gain = result.mean - start
        if grid_gain is None:
            grid_gain = gain
        stalls = 0.0 if result.counters is None else float(result.counters[:, C_STALLS].mean())
        rows.append(
            TransferRow(
                soil,
                randomised,
                steps * horizon,
                result.mean,
                float(result.scores.std()),
                start,
                gain / grid_gain if grid_gain > 0 else None,  # no grid gain: no progress
                stalls,
            )
        )
    return rows


def scaled_horizon(soil: str, blueprint, rules) -> int:
    """How many times the steps a preset is also scored at (1 to :data:`MAX_HORIZON`).

    The grid's push capacity over the preset's measured stall capacity (without
    throttle-up), rounded up.
    """
    params = SoilParams(soil=soil).resolved()
    cell, unit = float(blueprint.cell_size), float(blueprint.height_unit)
    measured = stall_capacity(params, cell, unit, throttle=False)
    if measured is None or measured >= rules.normal_load:
        return 1
    return min(MAX_HORIZON, math.ceil(rules.normal_load / max(measured, 1e-9)))


def table(rows: list[TransferRow]) -> str:
    """The matrix as a Markdown table."""
    lines = [
        "| soil | steps | fitness (mean, std) | start | progress against the grid "
        "| stalls per scenario |",
        "|---|---:|---|---:|---:|---:|",
    ]
    for r in rows:
        progress = "n/a" if r.progress is None else f"{r.progress:.2f}"
        name = f"`{r.soil}`" + (" randomised" if r.randomised else "")
        lines.append(
            f"| {name} | {r.steps} | {r.fitness:.3f} ({r.std:.3f}) | {r.start:.3f} | {progress} | "
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


@dataclass(frozen=True)
class GoalCheck:
    """One criterion of the goal: what was measured against what it must reach."""

    criterion: str
    value: float
    target: float
    met: bool


def goal(rows: list[TransferRow], hand: list[TransferRow]) -> list[GoalCheck]:
    """A controller's matrix against the goal.

    ``hand``: the hand-coded rules' matrix of the same scenarios (:data:`SOILS` rows in both).

    Raises:
        ValueError: When the two matrices do not have the same rows.
    """
    key = [(r.soil, r.randomised, r.steps) for r in rows]
    if key != [(r.soil, r.randomised, r.steps) for r in hand]:
        raise ValueError("the controller's and the hand-coded rules' matrices differ in rows")
    base = rows[0].steps
    checks = [GoalCheck("grid fitness", rows[0].fitness, GOAL_GRID, rows[0].fitness >= GOAL_GRID)]
    for soil in PRESETS:
        plain = [r for r in rows if r.soil == soil and not r.randomised]
        scaled = max(plain, key=lambda r: r.steps)
        progress = scaled.progress if scaled.progress is not None else 0.0
        checks.append(
            GoalCheck(
                f"`{soil}` progress at {scaled.steps} steps",
                progress,
                GOAL_PROGRESS,
                progress >= GOAL_PROGRESS,
            )
        )
        mine = next(r for r in plain if r.steps == base)
        theirs = next(r for r in hand if (r.soil, r.randomised, r.steps) == (soil, False, base))
        checks.append(
            GoalCheck(
                f"`{soil}` fitness above the hand-coded rules' ({theirs.fitness:.3f})",
                mine.fitness,
                theirs.fitness,
                mine.fitness > theirs.fitness,
            )
        )
    return checks


def goal_table(checks: list[GoalCheck]) -> str:
    """The goal's checks as a Markdown table."""
    lines = ["| criterion | value | target | met |", "|---|---:|---:|---|"]
    for c in checks:
        lines.append(
            f"| {c.criterion} | {c.value:.3f} | {c.target:.3f} | {'yes' if c.met else 'no'} |"
        )
    return "\n".join(lines)


def read(path: Path) -> tuple[dict, list[TransferRow]]:
    """A matrix written by :func:`write`: its header and rows.

    Raises:
        ValueError: When the file is not a transfer matrix of this format.
    """
    data = json.loads(Path(path).read_text())
    if not isinstance(data, dict) or data.get("format") != "ant-transfer/1":
        raise ValueError(f"{path}: not an ant-transfer/1 matrix")
    try:
        rows = [TransferRow(**r) for r in data["rows"]]
    except (KeyError, TypeError) as exc:
        raise ValueError(f"{path}: rows: {exc}") from None
    return {k: v for k, v in data.items() if k != "rows"}, rows
