"""How closely the offline physical world follows ``dynamics``: the same scenarios in both.

``python -m excavation_field.cell_agreement run --out DIR --soil physical:dome``: continuous
trials through ``dynamics`` (truth perception, no slip or noise, the default blueprint with
goal depth 1) of the shipped genome and the hand-coded rules on ``--scenarios`` scenarios of
``--seed``, each written to ``DIR/trials/*.json`` when it ends (run the command again and it
goes on); then, or with ``report`` alone, the same scenarios in the offline physical world
(:mod:`excavation_sim.cell_soil`, ``ant-eval --soil``) and ``DIR/agreement-SOIL.md``: per
controller the correlation of the final fitness over the scenarios, the mean of each, and
the U1 events (a move refused or stalled: the offline world's refusals plus stalls against
the executors' stuck events in ``dynamics``).

The tolerances (the physical-evaluator issue): fitness correlation at least 0.9 over 20
scenarios, stall counts within a factor of two; :func:`check` says which hold. Each table
gives the correlation's 95 % bootstrap interval over the scenarios.

``python -m excavation_field.cell_agreement sensitivity --out DIR --soil SOIL``: the offline
world against itself, each physical parameter scaled by ``1 +- --nudge`` (default 1 %),
written to ``DIR/sensitivity-SOIL.md``: how much of a low correlation is the controller's
own sensitivity rather than the model's difference.
"""

from __future__ import annotations

import argparse
import json
import math
import os
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from excavation_common.errors import FieldError
from excavation_common.files import replace_marked, write_text_atomic
from excavation_common.limits import float_in, int_in
from excavation_common.loaders import load_json
from excavation_sim.soil import SoilError, soil_arg

CONTROLLERS = ("genomes/best.json", "hand-coded")
BLUEPRINT = "default:1"
MIN_CORRELATION = 0.9
STALL_FACTOR = 2.0
# a trial file's fields and their types (``run_one`` writes them)
FIELDS = {
    "soil": str,
    "controller": str,
    "robots": int,
    "seed": int,
    "scenario": int,
    "steps": int,
    "fitness": float,
    "stuck_events": int,
}


# the integer fields' ranges: what a trial file may hold and what ``run``'s options take
RANGES = {
    "robots": (1, 16),
    "seed": (0, 2**31 - 1),
    "scenario": (0, 999),
    "steps": (1, 100_000),
    "stuck_events": (0, 10**9),
}


class TrialFileError(FieldError):
    """A trial file under ``DIR/trials`` that is not one ``run`` wrote."""


def slug(soil: str) -> str:
    """``soil`` as a file name part."""
    return soil.replace(":", "-").replace(",", "_").replace("=", "-")


def trial_name(soil: str, controller: str, robots: int, scenario: int) -> str:
    """The trial's file name under ``DIR/trials``."""
    ctl = "hand" if controller == "hand-coded" else "genome"
    return f"{slug(soil)}-{ctl}-n{robots}-s{scenario}.json"


def run_one(soil: str, controller: str, robots: int, scenario: int, args) -> dict:
    """One continuous trial through ``dynamics`` (a JSON-ready row)."""
    from excavation_bringup.trial import run_trial

    r = run_trial(
        controller,
        robots,
        args.steps,
        args.seed,
        BLUEPRINT,
        domain=args.domain,
        scenario=scenario,
        command_timeout=30.0,
        timeout=max(900.0, 10.0 * args.steps),
        drive="continuous",
        exact=True,
        soil=soil,
    )
    return {
        "soil": soil,
        "controller": controller,
        "robots": robots,
        "seed": args.seed,
        "scenario": scenario,
        "steps": args.steps,
        "fitness": float(r.fitness),
        "stuck_events": r.stuck_events,
        "slips": r.slips,
        "wall_seconds": r.seconds,
    }


def offline(soil: str, controller: str, robots: int, scenarios: list[int], seed: int, steps: int):
    """``(fitness, u1_events)`` per scenario in the offline physical world."""
    from ant_controller.controller import Controller
    from ant_evolution.evaluate import ScenarioSet
    from blueprint_server.blueprint import resolve_blueprint
    from excavation_sim.cell_soil import C_REFUSED, C_STALLS

    program = Controller.from_spec(controller)
    blueprint = resolve_blueprint("default", 1)
    batch = ScenarioSet.create(blueprint, robots, max(scenarios) + 1, steps, seed, soil=soil)
    scores, counters = batch.run(program)
    pick = np.asarray(scenarios)
    return scores[pick], counters[pick, C_REFUSED] + counters[pick, C_STALLS]


# the presets' physical parameters that ``sensitivity`` nudges (blade_limit where it is set)
NUDGED = (
    "density",
    "friction_angle",
    "blade_friction_angle",
    "repose_angle",
    "robot_mass",
    "blade_limit",
)


def correlation(a: np.ndarray, b: np.ndarray) -> float:
    """Pearson's r of two score vectors: NaN where either is flat, 1 where they are equal."""
    if not np.ptp(a) or not np.ptp(b):
        return math.nan
    if np.array_equal(a, b):
        return 1.0
    return float(np.corrcoef(a, b)[0, 1])


BOOTSTRAP = 2000
"""Resamples of the scenarios for the correlation's interval (seeded: the same table)."""


def correlation_interval(a: np.ndarray, b: np.ndarray, seed: int = 0) -> tuple[float, float]:
    """The 95 % bootstrap interval of :func:`correlation` over paired scenarios.

    Scenarios are drawn with replacement :data:`BOOTSTRAP` times from a seeded generator;
    resamples where either side is flat are left out. With 20 scenarios whose fitness
    spreads by a few thousandths, one or two scenarios can move r a long way: the interval
    says how far.
    """
    rng = np.random.default_rng(seed)
    picks = rng.integers(0, a.size, size=(BOOTSTRAP, a.size))
    values = [correlation(a[p], b[p]) for p in picks]
    values = np.array([v for v in values if not math.isnan(v)])
    if not values.size:
        return math.nan, math.nan
    low, high = np.quantile(values, [0.025, 0.975])
    return float(low), float(high)


def sensitivity(
    soil: str, controller: str, robots: int, scenarios: int, seed: int, steps: int, nudge: float
) -> list[tuple[str, float, float]]:
    """How well the offline world agrees with itself: ``(parameter, factor, r)``.

    Each parameter of :data:`NUDGED` set in ``soil`` is scaled by ``1 + nudge`` and
    ``1 - nudge`` in turn, and the fitness over the scenarios correlated with the unchanged
    world's. Where a nudge of a percent leaves r near 1, a low correlation against
    ``dynamics`` is a systematic difference; where it does not, the tolerance sits near the
    model's own noise floor for that controller.
    """
    from excavation_sim.soil import SoilParams

    params = SoilParams(soil=soil).resolved()
    scen = list(range(scenarios))
    base, _ = offline(soil, controller, robots, scen, seed, steps)
    out = []
    for name in NUDGED:
        value = getattr(params, name)
        if not value:
            continue
        for factor in (1 + nudge, 1 - nudge):
            fit, _ = offline(
                f"{soil},{name}={value * factor!r}", controller, robots, scen, seed, steps
            )
            out.append((name, factor, correlation(base, fit)))
    return out


def sensitivity_report(soil: str, args) -> str:
    """``sensitivity-SOIL.md``: each controller's correlations with itself, nudged."""
    lines = [
        f"# The offline world against itself, each parameter nudged: `{soil}`",
        "",
        f"Written by `python -m excavation_field.cell_agreement sensitivity`: {args.robots} "
        f"robots, {args.steps} steps, scenarios 0-{args.scenarios - 1} of seed {args.seed}; "
        f"the fitness correlation with the unchanged world, each parameter scaled by "
        f"1 +- {args.nudge}.",
        "",
        "| controller | parameter | r, up | r, down |",
        "|---|---|---:|---:|",
    ]
    for controller in args.controllers:
        rows = sensitivity(
            soil, controller, args.robots, args.scenarios, args.seed, args.steps, args.nudge
        )
        for i in range(0, len(rows), 2):
            (name, _, up), (_, _, down) = rows[i], rows[i + 1]
            lines.append(f"| {controller} | `{name}` | {up:.3f} | {down:.3f} |")
    return "\n".join(lines) + "\n"


@dataclass(frozen=True)
class Agreement:
    """One controller's comparison over the scenarios both worlds ran."""

    controller: str
    scenarios: int
    correlation: float
    fitness_dynamics: float
    fitness_offline: float
    u1_dynamics: float
    u1_offline: float
    interval: tuple[float, float] = (math.nan, math.nan)

    @property
    def stall_ratio(self) -> float:
        """Offline U1 events over ``dynamics``' (mean per scenario)."""
        return self.u1_offline / self.u1_dynamics if self.u1_dynamics else math.inf

    def check(self) -> dict[str, bool]:
        """Which tolerance holds."""
        return {
            "correlation": self.correlation >= MIN_CORRELATION,
            "stalls": 1 / STALL_FACTOR <= self.stall_ratio <= STALL_FACTOR,
        }


def _where(row: dict, soil: str, controller: str) -> str:
    """A trial row's file (its path, or the name ``run`` gives it)."""
    return row.get("path", trial_name(soil, controller, row["robots"], row["scenario"]))


def compare(rows: list[dict], soil: str) -> list[Agreement]:
    """Each controller's agreement over the trials of ``soil`` in ``rows``."""
    out = []
    for controller in CONTROLLERS:
        mine = sorted(
            (r for r in rows if r["soil"] == soil and r["controller"] == controller),
            key=lambda r: r["scenario"],
        )
        if len(mine) < 2:
            continue
        for key in ("robots", "seed", "steps"):
            common, _ = Counter(r[key] for r in mine).most_common(1)[0]
            for r in mine:
                if r[key] != common:
                    raise TrialFileError(
                        _where(r, soil, controller),
                        key,
                        r[key],
                        f"the other trials of {soil} and {controller} have {common} "
                        "(one directory per seed, team and horizon)",
                    )
        first = mine[0]
        scen = [r["scenario"] for r in mine]
        for a, b in zip(mine, mine[1:], strict=False):
            if a["scenario"] == b["scenario"]:
                raise TrialFileError(
                    _where(b, soil, controller),
                    "scenario",
                    b["scenario"],
                    "this scenario has another trial file",
                )
        fit, u1 = offline(soil, controller, first["robots"], scen, first["seed"], first["steps"])
        dyn = np.array([r["fitness"] for r in mine])
        corr = correlation(dyn, fit)
        out.append(
            Agreement(
                controller,
                len(mine),
                corr,
                float(dyn.mean()),
                float(fit.mean()),
                float(np.mean([r["stuck_events"] for r in mine])),
                float(u1.mean()),
                correlation_interval(dyn, fit),
            )
        )
    return out


def report(rows: list[dict], soil: str) -> str:
    """``agreement.md``: the comparison table of ``soil``."""
    lines = [
        f"# The offline physical world against `dynamics`: `{soil}`",
        "",
        "Written by `python -m excavation_field.cell_agreement`. Continuous trials (truth "
        "perception, no slip or noise) against the offline world on the same scenarios.",
        "",
        "| controller | scenarios | fitness correlation (95 % bootstrap) "
        "| mean fitness, dynamics / offline "
        "| U1 events per scenario, dynamics / offline (ratio) | within tolerance |",
        "|---|---:|---:|---|---|---|",
    ]
    for a in compare(rows, soil):
        held = ", ".join(k for k, ok in a.check().items() if ok) or "none"
        lines.append(
            f"| {a.controller} | {a.scenarios} | {a.correlation:.3f} ({a.interval[0]:.2f} to "
            f"{a.interval[1]:.2f}) | "
            f"{a.fitness_dynamics:.3f} / {a.fitness_offline:.3f} | "
            f"{a.u1_dynamics:.1f} / {a.u1_offline:.1f} ({a.stall_ratio:.2f}) | {held} |"
        )
    return "\n".join(lines) + "\n"


MARK = "<!-- cell-agreement -->"
END = "<!-- /cell-agreement -->"


def combined(rows: list[dict]) -> str:
    """One table over every soil in ``rows`` (docs/world-model.md's section)."""
    lines = [
        "| soil | controller | scenarios | fitness correlation (95 % bootstrap) "
        "| mean fitness, dynamics / "
        "offline | U1 events per scenario, dynamics / offline (ratio) | within tolerance |",
        "|---|---|---:|---:|---|---|---|",
    ]
    for soil in sorted({r["soil"] for r in rows}):
        for a in compare(rows, soil):
            held = ", ".join(k for k, ok in a.check().items() if ok) or "none"
            lines.append(
                f"| `{soil}` | {a.controller} | {a.scenarios} | {a.correlation:.3f} "
                f"({a.interval[0]:.2f} to {a.interval[1]:.2f}) | "
                f"{a.fitness_dynamics:.3f} / {a.fitness_offline:.3f} | "
                f"{a.u1_dynamics:.1f} / {a.u1_offline:.1f} ({a.stall_ratio:.2f}) | {held} |"
            )
    return "\n".join(lines)


def write_section(path: Path, table: str) -> None:
    """Put ``table`` between the markers of ``path`` (the rest is left alone)."""
    replace_marked(path, table, MARK, END)


def load_trial(path: Path) -> dict:
    """One trial file, its fields checked (:data:`FIELDS`).

    Raises:
        TrialFileError: Naming the file and the field that is missing or of another type.
    """
    row = load_json(path, TrialFileError)
    if not isinstance(row, dict):
        raise TrialFileError(path, "<json>", type(row).__name__, "expected an object")
    for name, kind in FIELDS.items():
        value = row.get(name)
        ok = isinstance(value, kind) and not isinstance(value, bool)
        if kind is float:
            ok = isinstance(value, int | float) and not isinstance(value, bool)
            ok = ok and math.isfinite(value)
        if not ok:
            raise TrialFileError(path, name, value, f"expected {kind.__name__}")
    if row["controller"] not in CONTROLLERS:
        raise TrialFileError(path, "controller", row["controller"], f"not one of {CONTROLLERS}")
    for name, (low, high) in RANGES.items():
        if not low <= row[name] <= high:
            raise TrialFileError(path, name, row[name], f"outside {low}..{high}")
    return {**row, "path": str(path)}


def load_rows(out: Path) -> list[dict]:
    """Every finished trial under ``DIR/trials`` (:func:`load_trial`)."""
    return [load_trial(p) for p in sorted((out / "trials").glob("*.json"))]


def main(argv: list[str] | None = None) -> int:
    """``python -m excavation_field.cell_agreement run|report|sensitivity``.

    ``report`` takes the seed, team and horizon from the trials it finds.
    """
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("what", choices=("run", "report", "sensitivity"))
    p.add_argument("--out", type=Path, required=True, help="directory (resumed)")
    p.add_argument("--soil", type=soil_arg, default="physical:dome")
    p.add_argument("--scenarios", type=int_in(2, RANGES["scenario"][1] + 1), default=20)
    p.add_argument("--seed", type=int_in(*RANGES["seed"]), default=100)
    p.add_argument("--steps", type=int_in(*RANGES["steps"]), default=100)
    p.add_argument("--robots", type=int_in(*RANGES["robots"]), default=2)
    p.add_argument("--controllers", nargs="+", choices=CONTROLLERS, default=list(CONTROLLERS))
    p.add_argument("--domain", type=int_in(0, 101), default=100, help="ROS domain id")
    p.add_argument("--write", type=Path, metavar="MD", help="put every soil's table into MD")
    p.add_argument(
        "--nudge",
        type=float_in(0.0001, 0.5),
        default=0.01,
        help="sensitivity: each parameter scaled by 1 +- this",
    )
    args = p.parse_args(argv)
    from excavation_common.signals import interrupt_on_sigint

    interrupt_on_sigint()
    if args.what == "sensitivity":
        if not args.soil.startswith("physical"):
            p.error(f"sensitivity: --soil {args.soil} has no physical parameters to nudge")
        try:
            text = sensitivity_report(args.soil, args)
        except SoilError as e:
            p.error(f"sensitivity: {e}")
        args.out.mkdir(parents=True, exist_ok=True)
        write_text_atomic(args.out / f"sensitivity-{slug(args.soil)}.md", text)
        print(text)
        return 0
    if args.what == "run":
        try:
            existing = load_rows(args.out)
        except TrialFileError as e:
            p.exit(2, f"{p.prog}: error: {e}\n")
        for r in existing:
            same = r["soil"] == args.soil and r["robots"] == args.robots
            if same and (r["seed"], r["steps"]) != (args.seed, args.steps):
                p.error(
                    f"--out {args.out} holds trials of seed {r['seed']} and {r['steps']} steps "
                    f"({r['path']}): give seed {args.seed} at {args.steps} steps another --out"
                )
        os.environ["ROS_DOMAIN_ID"] = str(args.domain)
        from excavation_common.progress import tqdm

        (args.out / "trials").mkdir(parents=True, exist_ok=True)
        jobs = [(c, i) for i in range(args.scenarios) for c in CONTROLLERS if c in args.controllers]
        todo = [
            j
            for j in jobs
            if not (args.out / "trials" / trial_name(args.soil, j[0], args.robots, j[1])).exists()
        ]
        for controller, i in tqdm(todo, desc="continuous trials", unit="trial"):
            row = run_one(args.soil, controller, args.robots, i, args)
            path = args.out / "trials" / trial_name(args.soil, controller, args.robots, i)
            write_text_atomic(path, json.dumps(row, indent=1) + "\n")
    try:
        rows = load_rows(args.out)
        text = report(rows, args.soil)
        section = combined(rows) if args.write else ""
    except TrialFileError as e:
        p.exit(2, f"{p.prog}: error: {e}\n")
    write_text_atomic(args.out / f"agreement-{slug(args.soil)}.md", text)
    print(text)
    if args.write:
        write_section(args.write, section)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
