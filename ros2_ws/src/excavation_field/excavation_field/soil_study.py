"""Which departure of the physical soil from the grid costs the controllers their progress.

``ant-soil-study --out DIR``: continuous trials through ``dynamics`` (truth perception, no
slip or noise, 100 ticks) on the physical soil as it was first shipped, and on that soil with
one departure from the grid switched back to the grid's reading at a time
(:class:`excavation_sim.soil.SoilParams`: ``refusals``, ``epsilon``, ``fill``, ``load``,
``fitness_heights``, ``repose``), plus the fixed default (``physical``); every trial beside
the grid trial of its scenario (the offline world, which a continuous grid-soil trial equals
tick for tick). Each cell is 2 or 4 robots x the shipped genome or the hand-coded rules x
``--scenarios`` scenarios of ``--seed``.

A trial's **normalised progress** is ``(f - f0) / (f_grid - f0)``: the share of its grid
trial's progress from the start ``f0`` that the physical trial makes (1: as much as the grid).
A cell reports the mean over its scenarios with a 95 % interval (Student's t). For the soil
as shipped, each physical trial is recorded and its decisions are read back with the sensor
vectors they were made on (:mod:`excavation_bags.trial_data`); beside the grid's decisions
of the same scenario they give the **first differing word**: the first tick at which some
robot chose another behaviour word than on the grid, and which of the 14 inputs differed
there (counted over scenarios: which input parts the controller from the grid).

Every trial is a JSON file under ``DIR/trials`` written atomically when it ends; run the
command again and it goes on with the trials not yet done (the order is scenario-major, so
every cell grows together). ``DIR/attribution.md`` is rewritten after every trial.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from excavation_common.files import write_text_atomic
from excavation_common.limits import int_in

GENOME = "genomes/best.json"
CONTROLLERS = (GENOME, "hand-coded")
AS_SHIPPED = "physical,refusals=false,epsilon=false"
"""The physical soil before this study: engaged-blade refusals lost, no epsilon rule."""


@dataclass(frozen=True)
class Switch:
    """One row of the study: a soil spec and what it changes against the soil as shipped."""

    key: str
    soil: str
    what: str


SWITCHES = (
    Switch("shipped", AS_SHIPPED, "physical soil as shipped (every departure)"),
    Switch("refusals", "physical,epsilon=false", "+ the engaged blade's refusals"),
    Switch("epsilon", "physical,refusals=false", "+ the epsilon rule"),
    Switch("no-fill", AS_SHIPPED + ",fill=false", "- fill by a carrying blade"),
    Switch("load-volume", AS_SHIPPED + ",load=volume", "L1 from the grid's V_blade"),
    Switch("fitness-rounded", AS_SHIPPED + ",fitness_heights=rounded", "fitness of whole units"),
    Switch("no-repose", AS_SHIPPED + ",repose=false", "- repose (no slumping)"),
    Switch("fixed", "physical", "the fixed default (refusals and epsilon on)"),
    Switch(
        "grid-rules",
        "physical,fill=false,load=volume,fitness_heights=rounded,repose=false",
        "every rule back to the grid's (left: the pile's shape and the push)",
    ),
)
T95 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306, 9: 2.262}
"""Student's t, two-sided 95 %, by degrees of freedom (10 or more: 2.228 down to 1.96)."""

SENSOR_NAMES = ("Z1", "Z2", "Z3", "Z4", "E1", "E2", "B1", "L1", "S1", "D1", "H1", "R1", "U1", "M1")


def t95(dof: int) -> float:
    """Two-sided 95 % Student's t quantile for ``dof`` degrees of freedom."""
    if dof in T95:
        return T95[dof]
    table = {10: 2.228, 12: 2.179, 15: 2.131, 20: 2.086, 30: 2.042, 60: 2.0}
    for d in sorted(table, reverse=True):
        if dof >= d:
            return table[d]
    return 1.96


def interval(values: list[float]) -> tuple[float, float]:
    """Mean and the half-width of its 95 % interval (NaN half-width for one value)."""
    a = np.asarray(values, dtype=float)
    if len(a) < 2:
        return float(a.mean()) if len(a) else math.nan, math.nan
    return float(a.mean()), t95(len(a) - 1) * float(a.std(ddof=1)) / math.sqrt(len(a))


def grid_decisions(controller: str, robots: int, steps: int, seed: int, scenario: int):
    """The grid trial of a scenario: fitness per tick and every decision with its inputs.

    Returns:
        ``(trace, decisions)``: ``trace[t]`` the fitness after t ticks; ``decisions[t][k]``
        ``(word, codes)`` of robot k at tick t.
    """
    from ant_controller.controller import Controller
    from ant_evolution.evaluate import ScenarioSet
    from blueprint_server.blueprint import default_blueprint

    ctl = Controller.from_spec(controller)
    world = ScenarioSet.create(default_blueprint(1), robots, scenario + 1, steps, seed).world(
        scenario
    )
    trace, decisions = [world.fitness()], []
    for _ in range(steps):
        codes = world.sense()
        words = np.array([ctl.decide(codes[k]) for k in range(robots)], dtype=np.int64)
        decisions.append([(int(words[k]), codes[k].tolist()) for k in range(robots)])
        world.step(words)
        trace.append(world.fitness())
    return trace, decisions


def bag_decisions(bag_dir: Path, robots: int) -> list[list[tuple[int, list[int] | None]]]:
    """A recorded trial's decisions per robot in order: ``(word, codes or None)``."""
    from excavation_bags.reader import open_bag
    from excavation_bags.trial_data import read_trial

    data = read_trial(open_bag(bag_dir))
    out: list[list] = [[] for _ in range(robots)]
    for d in data.decisions:
        if 0 <= d.robot < robots:
            codes = None if d.sensors is None else [int(c) for c in d.sensors]
            out[d.robot].append((int(d.behaviour), codes))
    return out


def first_difference(grid, physical) -> dict | None:
    """The first tick where a robot's word differs, with the inputs that differ there."""
    robots = len(physical)
    for t, row in enumerate(grid):
        for k in range(robots):
            if t >= len(physical[k]):
                return None
            word, codes = physical[k][t]
            g_word, g_codes = row[k]
            if word != g_word:
                differ = (
                    [SENSOR_NAMES[i] for i in range(14) if codes[i] != g_codes[i]]
                    if codes is not None
                    else None
                )
                return {
                    "tick": t,
                    "robot": k,
                    "grid_word": g_word,
                    "physical_word": word,
                    "grid_codes": g_codes,
                    "physical_codes": codes,
                    "inputs_differ": differ,
                }
    return None


def _row(switch: Switch, controller: str, robots: int, scenario: int, args, trace, f) -> dict:
    """What every trial's row holds: its cell and scenario, its grid and physical fitness.

    ``trace``: the grid trial's fitness per tick (from the start ``f0``); ``f``: the physical
    trial's final fitness.
    """
    f0, f_grid = trace[0], trace[-1]
    return {
        "switch": switch.key,
        "soil": switch.soil,
        "controller": controller,
        "robots": robots,
        "seed": args.seed,
        "scenario": scenario,
        "steps": args.steps,
        "f0": f0,
        "grid": f_grid,
        "physical": f,
        "progress": (f - f0) / (f_grid - f0) if f_grid != f0 else None,
    }


def run_one(switch: Switch, controller: str, robots: int, scenario: int, args) -> dict:
    """One physical trial beside its grid trial (a JSON-ready row)."""
    from excavation_bringup.trial import run_trial

    trace, decisions = grid_decisions(controller, robots, args.steps, args.seed, scenario)
    record = switch.key == "shipped"
    tmp = Path(tempfile.mkdtemp(prefix="soil-study-")) if record else None
    try:
        r = run_trial(
            controller,
            robots,
            args.steps,
            args.seed,
            "default:1",
            domain=args.domain,
            scenario=scenario,
            command_timeout=30.0,
            timeout=max(900.0, 10.0 * args.steps),
            drive="continuous",
            exact=True,
            soil=switch.soil,
            record=str(tmp / "bag") if record else None,
        )
        first = first_difference(decisions, bag_decisions(tmp / "bag", robots)) if record else None
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    return _row(switch, controller, robots, scenario, args, trace, float(r.fitness)) | {
        "slips": r.slips,
        "stuck_events": r.stuck_events,
        "primitives_aborted": r.primitives_aborted,
        "soil_volume": r.soil_volume,
        "wall_seconds": r.seconds,
        "first_difference": first,
    }


def physical_decisions(
    soil: str, controller: str, robots: int, steps: int, seed: int, scenario: int
):
    """The scenario's trial in the offline physical world (:mod:`excavation_sim.cell_soil`).

    The same loop as the evaluator's compiled one (``ant_evolution.kernel``), stepped here
    so that every decision is kept with its inputs.

    Returns:
        ``(trace, decisions, counters)`` as :func:`grid_decisions`, with the soil's
        counters (moves, refusals, stalls, quanta cut) at the end.
    """
    from ant_controller.controller import Controller
    from ant_evolution.evaluate import ScenarioSet
    from blueprint_server.blueprint import default_blueprint
    from excavation_sim import cell_soil
    from excavation_sim.world import occupancy

    ctl = Controller.from_spec(controller)
    batch = ScenarioSet.create(default_blueprint(1), robots, scenario + 1, steps, seed, soil=soil)
    world = batch.world(scenario)
    ground = batch.soil_of(world, scenario)
    occ = np.zeros(world.heights.shape, dtype=np.int16)
    occupancy(world.robots, world.active, occ)
    codes = np.zeros((robots, 14), dtype=np.int64)
    trace = [cell_soil.soil_fitness(ground, world.heights, world.zones, world.goal)]
    decisions = []
    for _ in range(steps):
        for k in range(robots):
            cell_soil.sense_robot(
                world.heights, world.zones, world.goal, world.robots, world.active, k,
                codes[k], world.params, ground,
            )  # fmt: skip
        words = np.array([ctl.decide(codes[k]) for k in range(robots)], dtype=np.int64)
        decisions.append([(int(words[k]), codes[k].tolist()) for k in range(robots)])
        cell_soil.step_robots(
            world.heights, world.robots, world.active, occ, words, world.rng, ground
        )
        trace.append(cell_soil.soil_fitness(ground, world.heights, world.zones, world.goal))
    return trace, decisions, ground.counters.copy()


def run_offline(switch: Switch, controller: str, robots: int, scenario: int, args) -> dict:
    """:func:`run_one` in the offline physical world (``--world offline``).

    Milliseconds a trial; every trial's decisions are compared with the grid's.
    """
    import time

    from excavation_sim.cell_soil import C_CUT, C_REFUSED, C_STALLS

    began = time.monotonic()
    trace, decisions = grid_decisions(controller, robots, args.steps, args.seed, scenario)
    ptrace, pdecisions, counters = physical_decisions(
        switch.soil, controller, robots, args.steps, args.seed, scenario
    )
    per_robot = [[row[k] for row in pdecisions] for k in range(robots)]
    return _row(switch, controller, robots, scenario, args, trace, float(ptrace[-1])) | {
        "world": "offline",
        "slips": int(counters[C_STALLS]),
        "refused": int(counters[C_REFUSED]),
        "cut": int(counters[C_CUT]),
        "wall_seconds": time.monotonic() - began,
        "first_difference": first_difference(decisions, per_robot),
    }


def trial_name(switch: Switch, controller: str, robots: int, scenario: int) -> str:
    """The trial's file name under ``DIR/trials``."""
    ctl = "hand" if controller == "hand-coded" else "genome"
    return f"{switch.key}-{ctl}-n{robots}-s{scenario}.json"


def load_rows(out: Path) -> list[dict]:
    """Every finished trial's row."""
    return [json.loads(p.read_text()) for p in sorted((out / "trials").glob("*.json"))]


def _cell(rows: list[dict], switch: str, controller: str, robots: int) -> list[dict]:
    """The trials of one cell of the table: a switch, a controller, a team size."""
    return [
        r
        for r in rows
        if r["switch"] == switch and r["controller"] == controller and r["robots"] == robots
    ]


def table(rows: list[dict], robots: tuple[int, ...]) -> str:
    """The attribution table and the first-difference counts (Markdown)."""
    head = "| switch | " + " | ".join(
        f"{'genome' if c == GENOME else 'hand-coded'}, {n} robots"
        for n in robots
        for c in CONTROLLERS
    )
    lines = [
        "Normalised progress `(f - f0) / (f_grid - f0)`, mean +- 95 % interval (scenarios):",
        "",
        head + " |",
        "|---|" + "---|" * (len(robots) * len(CONTROLLERS)),
    ]
    for s in SWITCHES:
        cells = []
        for n in robots:
            for c in CONTROLLERS:
                vals = [
                    r["progress"] for r in _cell(rows, s.key, c, n) if r["progress"] is not None
                ]
                mean, half = interval(vals)
                cells.append(
                    "-"
                    if not vals
                    else f"{mean:.2f} +- {half:.2f} ({len(vals)})"
                    if not math.isnan(half)
                    else f"{mean:.2f} (1)"
                )
        lines.append(f"| {s.what} | " + " | ".join(cells) + " |")
    lines += [
        "",
        "Final fitness, physical / grid (means over the same scenarios; start "
        + (f"{rows[0]['f0']:.3f}" if rows else "-")
        + "), and robot-steps stalled per trial:",
        "",
        head + " |",
        "|---|" + "---|" * (len(robots) * len(CONTROLLERS)),
    ]
    for s in SWITCHES:
        cells = []
        for n in robots:
            for c in CONTROLLERS:
                cell = _cell(rows, s.key, c, n)
                cells.append(
                    "-"
                    if not cell
                    else f"{np.mean([r['physical'] for r in cell]):.3f} / "
                    f"{np.mean([r['grid'] for r in cell]):.3f}; "
                    f"{np.mean([r['slips'] for r in cell]):.0f}"
                )
        lines.append(f"| {s.what} | " + " | ".join(cells) + " |")
    lines += ["", "First differing word, soil as shipped (trials; inputs that differ there):", ""]
    for c in CONTROLLERS:
        firsts = [r for r in rows if r["switch"] == "shipped" and r["controller"] == c]
        counts: dict[str, int] = {}
        ticks = []
        for r in firsts:
            fd = r.get("first_difference")
            if not fd:
                continue
            ticks.append(fd["tick"])
            for name in fd["inputs_differ"] or ["(inputs not recorded)"]:
                counts[name] = counts.get(name, 0) + 1
        ranked = ", ".join(f"{k} {v}" for k, v in sorted(counts.items(), key=lambda kv: -kv[1]))
        name = "genome" if c == GENOME else "hand-coded"
        lines.append(
            f"* {name}: {len(ticks)} of {len(firsts)} trials part from the grid, first at tick "
            f"{min(ticks) if ticks else '-'}-{max(ticks) if ticks else '-'} (median "
            f"{int(np.median(ticks)) if ticks else '-'}); inputs: {ranked or '-'}"
        )
    return "\n".join(lines) + "\n"


def _shard(text: str) -> tuple[int, int]:
    """``K/N`` (``0 <= K < N``) for ``--shard``."""
    try:
        k, n = (int(v) for v in text.split("/"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected K/N, e.g. 0/2") from None
    if not 0 <= k < n <= 64:
        raise argparse.ArgumentTypeError(f"{text!r}: expected 0 <= K < N <= 64")
    return k, n


def main(argv: list[str] | None = None) -> int:
    """``ant-soil-study``: run (or continue) the attribution study."""
    p = argparse.ArgumentParser(prog="ant-soil-study", description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, required=True, help="study directory (resumed)")
    p.add_argument("--scenarios", type=int_in(1, 1000), default=10)
    p.add_argument("--seed", type=int_in(0, 2**31 - 1), default=100)
    p.add_argument("--steps", type=int_in(1, 100_000), default=100)
    p.add_argument("--robots", type=int_in(1, 16), nargs="+", default=[2, 4])
    p.add_argument(
        "--switches",
        nargs="+",
        choices=[s.key for s in SWITCHES],
        default=[s.key for s in SWITCHES],
    )
    p.add_argument(
        "--world",
        choices=("dynamics", "offline"),
        default="dynamics",
        help="where the physical trials run: dynamics (the node suite, about a minute a "
        "trial) or the offline physical world (the evaluator's, milliseconds a trial)",
    )
    p.add_argument("--domain", type=int_in(0, 101), default=101, help="ROS domain id")
    p.add_argument("--limit", type=int_in(1, 100_000), default=None, help="trials this run")
    p.add_argument(
        "--shard",
        type=_shard,
        default=(0, 1),
        metavar="K/N",
        help="run only the K-th of N shares of the trials (0-based), so that N processes "
        "(each with its own --domain) share one study directory",
    )
    p.add_argument(
        "--report", action="store_true", help="rewrite DIR/attribution.md from its trials only"
    )
    args = p.parse_args(argv)
    from excavation_common.signals import interrupt_on_sigint

    interrupt_on_sigint()  # Ctrl-C stops it even when a script started it in the background
    if args.report:
        text = table(load_rows(args.out), tuple(args.robots))
        write_text_atomic(args.out / "attribution.md", text)
        print(text)
        return 0
    os.environ["ROS_DOMAIN_ID"] = str(args.domain)
    from excavation_common.progress import tqdm

    (args.out / "trials").mkdir(parents=True, exist_ok=True)
    jobs = [
        (s, c, n, i)
        for i in range(args.scenarios)
        for n in args.robots
        for c in CONTROLLERS
        for s in SWITCHES
        if s.key in args.switches
    ]
    k, n = args.shard
    jobs = jobs[k::n]
    todo = [j for j in jobs if not (args.out / "trials" / trial_name(*j)).exists()]
    done = len(jobs) - len(todo)
    if args.limit is not None:
        todo = todo[: args.limit]
    robots = tuple(args.robots)
    trial = run_offline if args.world == "offline" else run_one
    late: list[str] = []
    with tqdm(total=done + len(todo), initial=done, unit="trial") as bar:
        for job in todo:
            try:
                row = trial(*job, args)
            except TimeoutError as exc:
                # a niced study beside other work can pass a trial's wall-clock limit; the
                # trial is left for the next run (no row), the others go on
                late.append(trial_name(*job))
                bar.write(f"ant-soil-study: {trial_name(*job)} left for the next run: {exc}")
                continue
            write_text_atomic(args.out / "trials" / trial_name(*job), json.dumps(row, indent=1))
            write_text_atomic(args.out / "attribution.md", table(load_rows(args.out), robots))
            bar.update(1)
    print(table(load_rows(args.out), robots))
    if late:
        print(
            f"ant-soil-study: {len(late)} trial(s) passed their time limit and are left for "
            f"the next run: {', '.join(late)}",
            file=sys.stderr,
        )
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
