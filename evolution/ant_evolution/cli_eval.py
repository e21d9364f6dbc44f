"""``ant-eval``: score a genome or the hand-coded controller on seeded scenarios.

Examples::

    ant-eval --hand-coded --robots 4 --scenarios 100 --seed 0
    ant-eval --genome genomes/best.json --blueprint my_site.yaml --json
    ant-eval --hand-coded --snapshots out/snapshots --snapshot-steps 0,50,100,300
    ant-eval --hand-coded --profile paper --set hand_coded=chain
    ant-eval --genome genomes/best.json --soil physical:dome
    ant-eval --genome genomes/best.json --transfer transfer.json

``--profile`` picks the readings of the paper (world, hand-coded rules; docs/evolution.md,
"Profiles"); ``--set KEY=VALUE`` overrides one switch. ``--soil physical[:PRESET]`` runs the
scenarios on the physical soil (:mod:`excavation_sim.cell_soil`; docs/world-model.md);
``--transfer FILE`` scores the same scenarios on the grid and on each physical soil and
writes the transfer matrix (:mod:`ant_evolution.transfer`).

Exit codes: 0 success, 2 bad arguments or input file (the message names the file, the
field and the value).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

from ant_controller.controller import Controller
from ant_controller.errors import GenomeFormatError
from ant_evolution.errors import ConfigError
from ant_evolution.evaluate import (
    DEFAULT_ROBOTS,
    DEFAULT_STEPS,
    advance,
    evaluate,
)
from ant_evolution.limits import MAX_DEPTH_UNITS, MAX_STEPS, check_workload, option
from ant_evolution.profiles import add_profile_options, switches_of, world_rules_of
from blueprint_server.blueprint import resolve_blueprint
from blueprint_server.errors import BlueprintError
from excavation_common.limits import int_in
from excavation_sim.rules import DEFAULT_RULES, WorldRules
from excavation_sim.soil import SoilError, soil_arg
from excavation_sim.world import PlacementError

DEFAULT_SNAPSHOT_STEPS = (0, 50, 75, 100, 170)
"""The paper's snapshot figure shows these timesteps; the last step is always added."""


def _steps_list(text: str) -> list[int]:
    try:
        steps = sorted({int(s) for s in text.split(",") if s.strip()})
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a comma-separated list") from None
    if not steps or steps[0] < 0 or steps[-1] > MAX_STEPS:
        raise argparse.ArgumentTypeError(f"{text!r}: steps must lie in 0..{MAX_STEPS} (the limit)")
    return steps


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    p = argparse.ArgumentParser(prog="ant-eval", description=__doc__.split("\n\n")[0])
    who = p.add_mutually_exclusive_group(required=True)
    who.add_argument("--genome", metavar="FILE", help="ant-genome/1 JSON file")
    who.add_argument("--hand-coded", action="store_true", help="the paper's hand-coded rules")
    p.add_argument(
        "--robots",
        type=option("robots"),
        default=None,
        help=f"robots per scenario (default: the genome's N gene, else {DEFAULT_ROBOTS})",
    )
    p.add_argument(
        "--blueprint",
        default="default",
        metavar="FILE|default",
        help="blueprint YAML, or 'default' (8 x 8 pit in 16 x 16)",
    )
    p.add_argument(
        "--depth",
        type=int_in(1, MAX_DEPTH_UNITS),
        default=1,
        help="goal depth of the default blueprint (soil units, default 1)",
    )
    p.add_argument(
        "--scenarios", type=option("scenarios"), default=100, help="scenarios (default 100)"
    )
    p.add_argument(
        "--steps",
        type=option("steps"),
        default=DEFAULT_STEPS,
        help=f"timesteps per scenario (default {DEFAULT_STEPS})",
    )
    p.add_argument("--seed", type=option("seed"), default=0, help="scenario seed (default 0)")
    add_profile_options(p)
    p.add_argument(
        "--soil",
        type=soil_arg,
        default="grid",
        help="grid (the world model's soil rules) or physical[:PRESET][,KEY=VALUE...]: the "
        "physical soil, robots moving cell by cell (presets: grid, dome, lunar)",
    )
    p.add_argument(
        "--randomise",
        action="store_true",
        help="each scenario draws its world over training's randomisation ranges "
        '(docs/evolution.md, "Domain randomisation")',
    )
    p.add_argument(
        "--transfer",
        metavar="FILE",
        help="score on the grid and every physical soil; write the transfer matrix (JSON)",
    )
    p.add_argument(
        "--against",
        metavar="HAND.json",
        help="with --transfer: the hand-coded rules' matrix of the same scenarios; print and "
        'write the goal\'s checks (docs/results.md, "Crossing the reality gap")',
    )
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("--snapshots", metavar="DIR", help="write terrain PNGs of scenario 0 here")
    p.add_argument(
        "--snapshot-steps",
        type=_steps_list,
        default=list(DEFAULT_SNAPSHOT_STEPS),
        metavar="T1,T2,...",
        help="timesteps to snapshot (default 0,50,75,100,170)",
    )
    return p


def write_snapshots(
    controller: Controller,
    blueprint,
    n_robots: int,
    steps: int,
    seed: int,
    out_dir: Path,
    at: list[int],
    rules: WorldRules = DEFAULT_RULES,
    soil: str = "grid",
    randomised: bool = False,
) -> list[Path]:
    """Replay scenario 0 of ``seed`` and write a PNG at each step in ``at`` plus a strip."""
    from ant_evolution.evaluate import ScenarioSet
    from excavation_sim.cell_soil import soil_fitness
    from excavation_sim.snapshots import save_snapshot, save_strip

    batch = ScenarioSet.create(blueprint, n_robots, 1, 1, seed, rules, soil, randomised)
    world = batch.world(0)
    physical = batch.soil_of(world)

    def fitness() -> float:
        if physical is None:
            return world.fitness()
        return soil_fitness(physical, world.heights, world.zones, world.goal)

    wanted = sorted({s for s in at if s <= steps} | {steps})
    frames = []
    paths = []
    done = 0
    for s in wanted:
        advance(world, controller, s - done, soil=physical)
        done = s
        frames.append((s, world.heights.copy(), world.robots.copy()))
        paths.append(
            save_snapshot(
                out_dir / f"step_{s:05d}.png",
                world.heights,
                world.zones,
                world.robots,
                world.active,
                f"{controller.name}: t = {s}, fitness {fitness():.3f}",
            )
        )
    paths.append(
        save_strip(
            out_dir / "strip.png",
            frames,
            world.zones,
            world.active,
            f"{controller.name}, {n_robots} robots, {blueprint.name}",
        )
    )
    return paths


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ant-eval``."""
    args = build_parser().parse_args(argv)
    try:
        switches = switches_of(args)
        rules = world_rules_of(switches)
        controller = (
            Controller.hand_coded(switches["hand_coded"])
            if args.hand_coded
            else Controller.from_file(args.genome)
        )
        blueprint = resolve_blueprint(args.blueprint, args.depth, rules.fitted_site)
        n_robots = args.robots or controller.robots or DEFAULT_ROBOTS
        check_workload("<command line>", blueprint.zones.size, args.scenarios, args.steps)
        if args.transfer:
            return _transfer(args, controller, blueprint, n_robots, rules)
        result = evaluate(
            controller,
            blueprint,
            n_robots,
            args.scenarios,
            args.steps,
            args.seed,
            rules,
            args.soil,
            args.randomise,
        )
        snaps = []
        if args.snapshots:
            snaps = write_snapshots(
                controller,
                blueprint,
                n_robots,
                args.steps,
                args.seed,
                Path(args.snapshots),
                args.snapshot_steps,
                rules,
                args.soil,
                args.randomise,
            )
    except (GenomeFormatError, BlueprintError, PlacementError, ConfigError, SoilError) as exc:
        print(f"ant-eval: error: {exc}", file=sys.stderr)
        return 2
    summary = result.summary()
    if args.json:
        print(
            json.dumps(
                {
                    "controller": controller.name,
                    "blueprint": blueprint.name,
                    "robots": n_robots,
                    "scenarios": args.scenarios,
                    "steps": args.steps,
                    "seed": args.seed,
                    **({"profile": args.profile} if args.profile != "v1" else {}),
                    **({"switches": dict(args.assignments)} if args.assignments else {}),
                    **({"soil": args.soil} if args.soil != "grid" else {}),
                    **({"randomised": True} if args.randomise else {}),
                    **summary,
                    **_counts(result),
                    "scores": [float(v) for v in result.scores],
                    "snapshots": [str(p) for p in snaps],
                },
                indent=1,
            )
        )
    else:
        profile = "" if args.profile == "v1" else f" | profile {args.profile}"
        changed = "".join(f" | {k}={v}" for k, v in args.assignments)
        changed += f" | soil {args.soil}" if args.soil != "grid" else ""
        changed += " | randomised" if args.randomise else ""
        print(
            f"{controller.name} | {blueprint.name} | {n_robots} robots | "
            f"{args.scenarios} scenarios x {args.steps} steps | seed {args.seed}"
            f"{profile}{changed}"
        )
        print(
            "fitness: mean {mean:.4f}  std {std:.4f}  min {min:.4f}  max {max:.4f}".format(
                **summary
            )
        )
        start = float(np.mean(result.curves[:, 0]))
        print(f"(start of each scenario: {start:.4f})")
        if result.counters is not None:
            c = _counts(result)
            print(
                f"per scenario: {c['moves']:.1f} moves, {c['refused']:.1f} refused, "
                f"{c['stalls']:.1f} stalls (the push the robot could not give)"
            )
        if snaps:
            print(f"snapshots: {len(snaps)} PNG files in {args.snapshots}")
    return 0


def _transfer(args, controller, blueprint, n_robots: int, rules) -> int:
    """``--transfer``: the matrix printed and written."""
    from ant_evolution import transfer

    if args.soil != "grid" or args.randomise:
        flag, value = ("--soil", args.soil) if args.soil != "grid" else ("--randomise", True)
        raise ConfigError("<command line>", flag, value, "--transfer scores every soil")
    header = transfer.about(controller, blueprint, n_robots, args.scenarios, args.steps, args.seed)
    hand = None
    if args.against:
        try:
            theirs, hand = transfer.read(Path(args.against))
        except (OSError, ValueError) as exc:
            raise ConfigError("<command line>", "--against", args.against, str(exc)) from None
        for key in ("blueprint", "robots", "scenarios", "steps", "seed"):
            if theirs.get(key) != header[key]:
                raise ConfigError(
                    "<command line>", "--against", args.against,
                    f"scored {key} = {theirs.get(key)!r}, this matrix {header[key]!r}",
                )  # fmt: skip
    rows = transfer.transfer_matrix(
        controller, blueprint, n_robots, args.scenarios, args.steps, args.seed, rules
    )
    extra = {}
    if hand is not None:
        try:
            checks = transfer.goal(rows, hand)
        except ValueError as exc:
            raise ConfigError("<command line>", "--against", args.against, str(exc)) from None
        extra = {"goal": [dataclasses.asdict(c) for c in checks], "against": args.against}
    transfer.write(Path(args.transfer), rows, {**header, **extra})
    print(transfer.title(header))
    print(transfer.table(rows))
    if hand is not None:
        print(f"\nthe goal, against {args.against}:")
        print(transfer.goal_table(checks))
    return 0


def _counts(result) -> dict:
    """Mean moves, refusals and stalls per scenario on the physical soil (empty: grid)."""
    if result.counters is None:
        return {}
    mean = result.counters.mean(axis=0)
    return {"moves": float(mean[0]), "refused": float(mean[1]), "stalls": float(mean[2])}


if __name__ == "__main__":
    sys.exit(main())
