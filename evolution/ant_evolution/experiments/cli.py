"""``ant-experiment``: run one experiment of the paper's section 5 (see docs/experiments.md).

Example::

    ant-experiment training --scale medium --workers 2 --out runs/exp
    ant-experiment compare --scale medium --workers 2 --out runs/exp   # reuses training's runs
    ant-experiment compare --scale tested --workers 2 --out runs/exp-tested   # the campaign
    ant-experiment compare --scale tested --method neat --run 3 --out runs/exp-tested   # one run
    ant-experiment status --scale tested --out runs/exp-tested   # what is done, what is left
    ant-experiment compare --scale tested --finished --out runs/exp-tested   # summary in part

Every experiment is resumable: run the same command again after an interruption. With
``--method``, ``--run`` or ``--setting`` a training experiment trains only those runs and
stops before its summary, so that processes or machines can share one ``--out``, each with
its own runs. With ``--finished`` it trains nothing and summarises the runs finished so far.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ant_evolution.errors import CheckpointError, ConfigError
from ant_evolution.experiments.core import (
    METHODS,
    SCALES,
    TRAINING_EXPERIMENTS,
    Context,
    PartialTraining,
    scale_dict,
    setting_label,
    training_jobs,
)
from ant_evolution.limits import MAX_WORKERS, option
from ant_evolution.profiles import add_profile_options, switches_of
from excavation_common.limits import int_in
from excavation_sim.soil import soil_arg

NAMES = (
    "training",
    "compare",
    "coarse-coding",
    "scaleup",
    "antagonism",
    "depth",
    "area",
    "evolve-robots",
    "behaviours",
    "status",
)


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ant-experiment``."""
    from excavation_common.signals import interrupt_on_sigint

    interrupt_on_sigint()  # Ctrl-C stops it even when a script started it in the background
    p = argparse.ArgumentParser(prog="ant-experiment", description=__doc__.split("\n\n")[0])
    p.add_argument("name", choices=NAMES)
    p.add_argument("--scale", choices=sorted(SCALES), default="medium")
    p.add_argument("--runs", type=int_in(1, 1000), default=None, help="repetitions per setting")
    p.add_argument(
        "--workers", type=int_in(1, MAX_WORKERS), default=1, help="local worker processes"
    )
    p.add_argument("--ray-address", default=None, help="Ray address ('local' for a local Ray)")
    p.add_argument(
        "--cluster",
        default=None,
        metavar="ADDRESS",
        help="train the missing runs on this Ray cluster, one run per task ('local': a Ray "
        'instance here); docs/experiments.md, "On a Ray cluster"',
    )
    p.add_argument(
        "--chunk",
        type=int_in(1, 100_000),
        default=None,
        metavar="G",
        help="with --cluster: generations per task (default 50: a lost node costs at most "
        "that much of one run)",
    )
    p.add_argument("--genome", type=Path, default=None,
                   help="4-robot ANT genome for antagonism/depth/area/behaviours")  # fmt: skip
    p.add_argument(
        "--replay",
        type=Path,
        default=None,
        help="behaviours: ANT run directory to replay (default: the scale's r0)",
    )
    p.add_argument(
        "--generations",
        type=option("generations"),
        default=None,
        help="behaviours: replay only this many generations",
    )
    add_profile_options(p)
    p.add_argument(
        "--method",
        dest="methods",
        action="append",
        choices=METHODS,
        default=None,
        help="train only this method's runs, then stop before the summary (repeatable)",
    )
    p.add_argument(
        "--run",
        dest="run_indices",
        action="append",
        type=int_in(0, 999),
        default=None,
        metavar="K",
        help="train only run K (seed 1000 + K), then stop before the summary (repeatable)",
    )
    p.add_argument(
        "--setting",
        dest="settings",
        action="append",
        default=None,
        metavar="LABEL",
        help="train only this robot setting's runs (n1..n5, mix1+4, evoN), then stop before "
        "the summary (repeatable)",
    )
    p.add_argument(
        "--finished",
        action="store_true",
        help="train nothing: summarise the runs finished so far (a campaign in part)",
    )
    p.add_argument(
        "--write",
        type=Path,
        default=None,
        help="status: also write the report to this markdown file",
    )
    p.add_argument(
        "--soil",
        type=soil_arg,
        default="grid",
        help="train and score on this soil: grid (default) or physical[:PRESET][,KEY=VALUE...] "
        "(the offline physical world; runs and results get the soil in their names)",
    )
    p.add_argument(
        "--randomise",
        action="store_true",
        help='every scenario draws its world (docs/evolution.md, "Domain randomisation")',
    )
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args(argv)
    if (
        args.methods or args.run_indices or args.settings
    ) and args.name not in TRAINING_EXPERIMENTS:
        p.error(f"--method, --run and --setting select training runs; {args.name} trains none")
    if args.finished and args.name not in TRAINING_EXPERIMENTS:
        p.error(f"--finished summarises training runs; {args.name} trains none")
    if args.finished and (args.methods or args.run_indices or args.settings):
        p.error("--finished trains nothing: leave out --method, --run and --setting")
    scale = SCALES[args.scale]
    runs = args.runs if args.runs is not None else scale.runs
    if runs < 1:
        p.error(f"--runs must be at least 1, got {runs}")
    if args.settings and args.name in TRAINING_EXPERIMENTS:
        known = {setting_label(r) for _, r in training_jobs(args.name, scale)}
        for label in args.settings:
            if label not in known:
                p.error(f"--setting {label}: {args.name} trains {', '.join(sorted(known))}")
    for k in args.run_indices or ():
        if k >= runs:
            p.error(f"--run {k}: this scale has runs 0 to {runs - 1} (--runs {runs})")
    if args.genome is not None and not args.genome.is_file():
        p.error(f"--genome {args.genome}: no such file")
    if args.name == "behaviours" and (args.soil != "grid" or args.randomise):
        p.error("behaviours replays its runs on the grid: leave out --soil and --randomise")
    if args.chunk is not None and args.cluster is None:
        p.error("--chunk is an option of --cluster")
    if args.chunk is not None:
        from ant_evolution.experiments import cluster

        cluster.CHUNK = args.chunk
    if args.write is not None and args.name != "status":
        p.error("--write is an option of status")
    # status needs none of the experiment modules
    from ant_evolution.experiments.suite import experiments as runnable

    experiments = runnable()
    if args.name not in experiments and args.name != "status":
        print(f"ant-experiment: error: {args.name} needs excavation_sim.detectors", file=sys.stderr)
        return 2
    if args.replay is not None and not (args.replay / "config.yaml").is_file():
        p.error(f"--replay {args.replay}: no config.yaml there")
    try:
        switches = switches_of(args)
    except ConfigError as exc:
        print(f"ant-experiment: error: {exc}", file=sys.stderr)
        return 2
    ctx = Context(
        args.out,
        scale,
        runs,
        args.workers,
        args.ray_address,
        args.genome,
        args.replay,
        args.generations,
        args.profile,
        switches,
        tuple(args.methods) if args.methods else None,
        tuple(args.run_indices) if args.run_indices else None,
        tuple(args.settings) if args.settings else None,
        args.finished,
        args.soil,
        args.randomise,
        args.cluster,
    )
    if args.name == "status":
        from ant_evolution.experiments.status import report

        text = report(ctx)
        print(text, end="")
        if args.write is not None:
            args.write.write_text(text, encoding="utf-8")
        return 0
    args.out.mkdir(parents=True, exist_ok=True)
    readings = {} if args.profile == "v1" and not args.assignments else {
        "profile": args.profile, "switches": switches}  # fmt: skip
    if args.soil != "grid":
        readings["soil"] = args.soil
    if args.randomise:
        readings["randomise"] = True
    (ctx.dir(args.name) / "scale.json").write_text(
        json.dumps({**scale_dict(scale), "runs": runs, **readings}, indent=1)
    )
    try:
        experiments[args.name](ctx)
    except PartialTraining as done:
        print(f"ant-experiment: {done}")
        return 0
    except (CheckpointError, ConfigError, FileNotFoundError, ValueError) as exc:
        print(f"ant-experiment: error: {exc}", file=sys.stderr)
        return 2
    print(f"ant-experiment: wrote {ctx.dir(args.name)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
