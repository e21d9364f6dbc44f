"""``ant-evolve``: evolve ANT controller genomes on the simulated worksite.

Examples::

    ant-evolve --out runs/r1 --generations 200
    ant-evolve --config runs/r1/config.yaml --out runs/r1 --resume
    ant-evolve --out runs/mix --robots-mix 1,4 --workers 2
    ant-evolve --out runs/n --evolve-robots --ray-address local
    ant-evolve --out runs/check --evaluator ros --population 10 --scenarios 4 --workers 2
    ant-evolve --profile paper --out runs/paper --set elitism=1

``--profile`` sets every switch of docs/evolution.md ("Profiles") to that profile's
reading; keys of ``--config`` and then ``--set KEY=VALUE`` override single switches.

Command-line values override the config file; the resolved configuration is written to
``OUT/config.yaml``. Exit codes: 0 done, 2 bad configuration or checkpoint, 130 interrupted
(the last checkpoint stays valid: resume with ``--resume``).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

from ant_evolution.errors import CheckpointError, ConfigError
from ant_evolution.evolve import (
    COMBINES,
    EvolveConfig,
    blueprints_of,
    load_config,
    run_evolution,
)
from ant_evolution.limits import (
    LIST_RANGES,
    MAX_DOMAIN,
    MAX_WORKERS,
    check_workload,
    int_list,
    option,
)
from ant_evolution.profiles import add_profile_options, apply_assignments
from ant_evolution.ros_evaluator import TrialError
from ant_evolution.transfer import write_for_run
from blueprint_server.errors import BlueprintError
from excavation_common.limits import int_in
from excavation_common.progress import tqdm
from excavation_sim.soil import soil_arg
from excavation_sim.world import PlacementError


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    p = argparse.ArgumentParser(prog="ant-evolve", description=__doc__.split("\n\n")[0])
    p.add_argument("--config", metavar="FILE", help="YAML run configuration")
    add_profile_options(p, default=None)
    p.add_argument("--out", required=True, metavar="DIR", help="run directory")
    p.add_argument("--population", type=option("population"), help="P (default 100)")
    p.add_argument("--generations", type=option("generations"), help="generations (default 100)")
    p.add_argument(
        "--scenarios", type=option("scenarios"), help="scenarios per generation S (default 100)"
    )
    robots = p.add_mutually_exclusive_group()
    robots.add_argument("--robots", type=option("robots"), help="robots per scenario (default 4)")
    robots.add_argument(
        "--robots-mix",
        type=int_list(*LIST_RANGES["robots_mix"]),
        metavar="N1,N2",
        help="alternate robot counts between scenarios, e.g. 1,4",
    )
    robots.add_argument("--evolve-robots", action="store_true", help="N is a gene")
    p.add_argument("--steps", type=option("steps"), help="timesteps per scenario T (default 300)")
    p.add_argument("--blueprint", metavar="FILE", help="blueprint file (default: 8 x 8 pit)")
    p.add_argument(
        "--depths",
        type=int_list(*LIST_RANGES["depths"]),
        metavar="D1,D2",
        help="goal depths of the default blueprint (default 1,2,3)",
    )
    p.add_argument("--no-coarse-coding", action="store_true", help="ANT without coarse coding")
    p.add_argument(
        "--workers",
        type=int_in(1, MAX_WORKERS),
        default=None,
        help="local processes (default: cores)",
    )
    p.add_argument("--ray-address", metavar="ADDR", help="Ray cluster ('local' starts one)")
    p.add_argument(
        "--evaluator",
        choices=("batched", "ros"),
        default="batched",
        help="batched world model (default), or trials through the ROS topics (--workers "
        "at once, each in its own ROS domain)",
    )
    p.add_argument(
        "--trial-command",
        metavar="TEMPLATE",
        help="with --evaluator ros: the trial command, with {genome} {robots} {steps} {seed} "
        "{scenario} {blueprint} {domain}; prints JSON with 'fitness' (default: ant-trial)",
    )
    p.add_argument(
        "--domain-base",
        type=int_in(0, MAX_DOMAIN),
        default=50,
        help="with --evaluator ros: trials use ROS domains from this one on (default 50; keep "
        "the last at most 101, above it the RTPS ports fall in Linux's ephemeral range)",
    )
    p.add_argument("--seed", type=option("seed"), help="run seed (default 0)")
    p.add_argument(
        "--soil",
        type=soil_arg,
        help="grid (default: the world model's soil rules) or physical[:PRESET][,KEY=VALUE...]"
        ": train on the physical soil, robots moving cell by cell (presets: grid, dome, lunar)",
    )
    p.add_argument(
        "--checkpoint-every",
        type=option("checkpoint_every"),
        help="generations between checkpoints",
    )
    p.add_argument(
        "--also-soil",
        type=soil_arg,
        metavar="SOIL",
        help="score every genome on this soil too (same scenarios); the fitness is the lower "
        "of the two soils' means (e.g. --soil grid --also-soil physical:dome)",
    )
    p.add_argument(
        "--start",
        metavar="GENOME",
        help="fine-tune: generation 0 is this genome and P - 1 mutants of it (e.g. a "
        "grid-evolved genome trained on with --soil)",
    )
    p.add_argument(
        "--randomise",
        action="store_true",
        default=None,
        help="each scenario draws its world (push capacities, climbs, fill, sensor noise, "
        "the physical soil's repose, friction, density, push and epsilon rule) over the "
        'documented ranges (docs/evolution.md, "Domain randomisation")',
    )
    p.add_argument(
        "--combine",
        choices=COMBINES,
        help="with --also-soil: mean (default: the lower soil's mean fitness), progress "
        "(the lower soil's gain over the start in units of the hand-coded rules' gain) or "
        "floor (the --also-soil mean while the run's own soil, not randomised, keeps at least "
        "--floor)",
    )
    p.add_argument(
        "--floor",
        type=float,
        help="with --combine floor: the mean fitness a genome must keep on the run's own "
        "soil (default 0.9; below it the fitness is the shortfall)",
    )
    p.add_argument(
        "--transfer-scenarios",
        type=int_in(0, 10_000),
        default=100,
        metavar="S",
        help="a run on physical soil, with --also-soil or --randomise writes OUT/transfer.json "
        "when it finishes: its best genome on S unseen scenarios of each soil (default 100; "
        "0: none)",
    )
    p.add_argument("--resume", action="store_true", help="continue from OUT/checkpoint.json")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def resolve_config(args: argparse.Namespace) -> EvolveConfig:
    """Defaults, then the config file (or OUT/config.yaml when resuming), then the flags."""
    config = EvolveConfig()
    source = args.config
    if source is None and args.resume and (Path(args.out) / "config.yaml").exists():
        source = str(Path(args.out) / "config.yaml")
    if source:
        config = load_config(source, profile=args.profile)
    elif args.profile is not None:
        config = config.with_profile(args.profile)
    overrides = {
        "population": args.population,
        "generations": args.generations,
        "scenarios": args.scenarios,
        "steps": args.steps,
        "seed": args.seed,
        "checkpoint_every": args.checkpoint_every,
        "depths": args.depths,
        "blueprint": args.blueprint,
        "soil": args.soil,
        "also_soil": args.also_soil,
        "start": args.start,
        "randomise": args.randomise,
        "combine": args.combine,
        "floor": args.floor,
    }
    values = {k: v for k, v in overrides.items() if v is not None}
    if args.robots is not None:
        values.update(robots=args.robots, robots_mix=(), evolve_robots=False)
    if args.robots_mix is not None:
        values.update(robots=args.robots_mix[0], robots_mix=args.robots_mix, evolve_robots=False)
    if args.evolve_robots:
        values.update(evolve_robots=True, robots_mix=())
    if args.no_coarse_coding:
        values["coarse_coding"] = False
    if args.assignments:
        values.update(apply_assignments(config.switches(), args.assignments))
    try:
        return dataclasses.replace(config, **values)
    except ConfigError as exc:
        raise ConfigError("<command line>", exc.field, exc.value, exc.reason) from None


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ant-evolve``."""
    from excavation_common.signals import interrupt_on_sigint

    interrupt_on_sigint()  # Ctrl-C stops it even when a script started it in the background
    args = build_parser().parse_args(argv)
    try:
        config = resolve_config(args)
        cells = max(b.zones.size for b in blueprints_of(config))
        check_workload(
            args.config or "<command line>", cells, config.scenarios, None, config.population
        )
        if args.evaluator == "ros" and args.domain_base + (args.workers or 1) > MAX_DOMAIN + 1:
            raise ConfigError(
                "<command line>",
                "--domain-base",
                args.domain_base,
                f"plus --workers passes the highest ROS domain {MAX_DOMAIN}",
            )
    except (ConfigError, BlueprintError) as exc:
        print(f"ant-evolve: error: {exc}", file=sys.stderr)
        return 2
    bar = tqdm(total=config.generations, unit="gen", disable=args.quiet, dynamic_ncols=True)
    started = time.perf_counter()
    evaluated = 0

    def progress(row: dict) -> None:
        nonlocal evaluated
        if bar.n == 0 and row["generation"] > 0:
            bar.update(row["generation"])  # resumed run
        soils = 2 if config.also_soil else 1
        evaluated += config.population * config.scenarios * soils
        rate = evaluated / max(time.perf_counter() - started, 1e-9)
        bar.set_postfix(
            best=f"{row['best']:.3f}", mean=f"{row['mean']:.3f}", evals_s=f"{rate:,.0f}"
        )
        bar.update(1)

    try:
        state = run_evolution(
            config,
            args.out,
            workers=args.workers,
            ray_address=args.ray_address,
            resume=args.resume,
            progress=progress,
            evaluator=args.evaluator,
            trial_command=args.trial_command,
            domain_base=args.domain_base,
        )
    except (ConfigError, CheckpointError, BlueprintError, PlacementError, TrialError) as exc:
        bar.close()
        print(f"ant-evolve: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        bar.close()
        print(f"ant-evolve: interrupted; resume with --resume --out {args.out}", file=sys.stderr)
        return 130
    bar.close()
    print(
        f"best fitness {state.best_fitness:.4f} after {state.generation} generations "
        f"({state.evaluations:,} scenario evaluations); {args.out}/best.json"
    )
    crosses = config.soil != "grid" or config.also_soil or config.randomise
    if crosses and args.transfer_scenarios and state.generation >= config.generations:
        print(f"transfer matrix ({args.out}/transfer.json):")
        print(write_for_run(Path(args.out), config, args.transfer_scenarios))
    return 0


if __name__ == "__main__":
    sys.exit(main())
