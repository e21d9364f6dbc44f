"""``ant-sweep``: a controller's fitness over robot counts and goal depths, as a table and a plot.

Example (the hand-coded table of ``docs/results.md``)::

    ant-sweep --hand-coded --robots 1-10 --depths 1,2,3 --scenarios 100 --out docs/figures
    ant-sweep --hand-coded --profile v1 --set soil_fill=true --out docs/figures/paper_profile/x

``--profile`` and ``--set KEY=VALUE`` choose the readings of the paper (docs/evolution.md,
"Profiles").

Writes ``sweep.csv``, ``sweep.md`` (a markdown table of mean +- std) and ``sweep.png``
into ``--out``, showing progress with a bar.
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

from ant_controller.controller import Controller
from ant_controller.errors import GenomeFormatError
from ant_evolution.errors import ConfigError
from ant_evolution.evaluate import DEFAULT_STEPS, evaluate
from ant_evolution.limits import MAX_DEPTH_UNITS, MAX_ROBOTS, check_workload, option
from ant_evolution.profiles import add_profile_options, switches_of, world_rules_of
from excavation_common.progress import tqdm


def _int_list(high: int):
    """An ``argparse`` type: ``'1,2,3'`` or ``'1-10'``, values in ``1..high``."""

    def parse(text: str) -> list[int]:
        out: set[int] = set()
        for part in text.split(","):
            lo, _, hi = part.partition("-")
            try:
                a, b = int(lo), int(hi or lo)
            except ValueError:
                raise argparse.ArgumentTypeError(f"{text!r}: use '1,2,3' or '1-10'") from None
            if a < 1 or b < a:
                raise argparse.ArgumentTypeError(f"{text!r}: values must be positive and ordered")
            if b > high:
                raise argparse.ArgumentTypeError(f"{text!r}: {b} is above the limit of {high}")
            out.update(range(a, b + 1))
        return sorted(out)

    return parse


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ant-sweep``."""
    p = argparse.ArgumentParser(prog="ant-sweep", description=__doc__.split("\n\n")[0])
    who = p.add_mutually_exclusive_group(required=True)
    who.add_argument("--genome", metavar="FILE")
    who.add_argument("--hand-coded", action="store_true")
    p.add_argument("--robots", type=_int_list(MAX_ROBOTS), default=list(range(1, 11)))
    p.add_argument("--depths", type=_int_list(MAX_DEPTH_UNITS), default=[1, 2, 3])
    p.add_argument("--scenarios", type=option("scenarios"), default=100)
    p.add_argument("--steps", type=option("steps"), default=DEFAULT_STEPS)
    p.add_argument("--seed", type=option("seed"), default=0)
    add_profile_options(p)
    p.add_argument("--out", required=True, type=Path)
    args = p.parse_args(argv)
    from blueprint_server.blueprint import default_blueprint

    try:
        switches = switches_of(args)
        rules = world_rules_of(switches)
        check_workload("<command line>", 16 * 16, args.scenarios, args.steps)
        ctl = (
            Controller.hand_coded(switches["hand_coded"])
            if args.hand_coded
            else Controller.from_file(args.genome)
        )
    except (GenomeFormatError, ConfigError) as exc:
        print(f"ant-sweep: error: {exc}", file=sys.stderr)
        return 2
    rows = []
    cells = [(d, n) for d in args.depths for n in args.robots]
    for d, n in tqdm(cells, desc="sweep", unit="setting"):
        bp = default_blueprint(d, rules.fitted_site)
        res = evaluate(ctl, bp, n, args.scenarios, args.steps, args.seed, rules)
        rows.append({"depth": d, "robots": n, **res.summary()})
    site = bp.name.partition(" (")[0]
    args.out.mkdir(parents=True, exist_ok=True)
    with open(args.out / "sweep.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    by = {(r["depth"], r["robots"]): r for r in rows}
    readings = f"profile {args.profile}" + "".join(f", {k}={v}" for k, v in args.assignments)
    lines = [
        f"Fitness of {ctl.name} on the {site} blueprint, mean +- std over {args.scenarios} "
        f"scenarios of {args.steps} steps (seed {args.seed}; {readings}).",
        "",
        "| robots | " + " | ".join(f"depth {d}" for d in args.depths) + " |",
        "|---:|" + "---:|" * len(args.depths),
    ]
    for n in args.robots:
        vals = " | ".join(
            f"{by[(d, n)]['mean']:.3f} +- {by[(d, n)]['std']:.3f}" for d in args.depths
        )
        lines.append(f"| {n} | {vals} |")
    (args.out / "sweep.md").write_text("\n".join(lines) + "\n")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4), dpi=100)
    for d in args.depths:
        means = [by[(d, n)]["mean"] for n in args.robots]
        stds = [by[(d, n)]["std"] for n in args.robots]
        ax.errorbar(args.robots, means, yerr=stds, capsize=3, marker="o", label=f"depth {d}")
    ax.set_xlabel("robots")
    ax.set_ylabel(f"fitness after {args.steps} steps")
    grid = "x".join(str(v) for v in bp.shape)
    ax.set_title(f"{ctl.name}, 8 x 8 pit in {grid}; {readings}", fontsize=8)
    ax.set_ylim(0, 1)
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(args.out / "sweep.png")
    plt.close(fig)
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
