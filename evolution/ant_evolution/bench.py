"""``ant-bench`` (``make bench``): evaluation throughput in robot-steps per second.

Setting (docs/benchmarks.md): 80-neuron ANT tissues, 4 robots, the 16 x 16 default blueprint,
T = 300. Measured in one run:

* the compiled evaluator in this process (1 worker) and on a 2-process pool, for a
  generation-0 population of random tissues, the shipped evolved genome and the hand-coded
  controller;
* the same kernels as plain Python (a subprocess with ``NUMBA_DISABLE_JIT=1``) on a subset
  of the same genome-scenario pairs, whose scores must equal the compiled ones;
* where the time goes per robot-step (:mod:`ant_evolution.breakdown`: sensing, decision,
  world step), compiled and in plain Python;
* the wall time of whole generations of ANT, NEAT and the fixed network (same P, S, T,
  workers), split into evaluation and breeding (``tell``);
* the shipped evolved genome on the physical soil (:mod:`excavation_sim.cell_soil`, each
  preset) against the grid, on one core in the same run.

It prints the tables with ratios against the plain-Python reference and, with
``--write``, puts them into their section of ``docs/benchmarks.md`` (between
``<!-- evaluation-bench -->`` markers; the other sections are left alone). Timings
exclude start-up (pool spawn, numba compilation), which a run pays once.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ant_controller.controller import Controller
from ant_controller.genome import random_genome
from ant_controller.genome_io import genome_from_dict, genome_to_dict, load_genome
from ant_evolution.backends import Evaluator, genome_fitness
from ant_evolution.breakdown import phase_times
from ant_evolution.evaluate import ScenarioSet
from blueprint_server.blueprint import default_blueprint
from excavation_common.files import replace_marked

ROBOTS = 4
STEPS = 300
PAPER_GENERATION = 100 * 100 * STEPS * ROBOTS
"""Robot-steps of one paper-scale generation (P 100, S 100, T 300, 4 robots)."""
PAPER_GENERATIONS = 5000
MARK = "<!-- evaluation-bench -->"
PHASES = ("sensing", "decision", "world step")
SOILS = ("physical", "physical:dome", "physical:lunar")
"""The physical soils timed against the grid (the ``grid`` preset, the dome, the Moon)."""
PHYSICAL_TARGET = 20.0
"""Most time per robot-step on the physical soil, as a multiple of the grid's (the issue's)."""

NOTES = """## Evaluation throughput (`ant-bench`)

Written by `make bench` (`ant-bench --write docs/benchmarks.md`); every number in this
section comes from the run that wrote it. Throughput is in robot-steps per second: one
robot sensing, deciding and acting for one timestep. Setting: 4 robots on the 16 x 16
default blueprint, T = 300, tissues of 80 neurons (random) or the shipped evolved genome.
"Plain Python" is the same code run with numba's JIT disabled, on 2 genomes x 2 scenarios of
the same set, and its scores are checked equal to the compiled ones. Targets (the project's,
docs/benchmarks.md): 6 million robot-steps per second on both cores; for the reproduction,
1.7e7 with an evolved genome (a 5,000-generation paper-scale run in under an hour) and a
NEAT generation at most 1.5 x an ANT generation of the same size.

{results}

The profiling notes (what the time goes to, and what each change gained) follow this
section; they are kept by hand.

Reproduce: `make bench` (a few minutes; it pauses nothing else, so run it on an idle
machine: on a loaded one the rates below are lower bounds).
"""


def population(n: int, seed: int) -> list:
    """``n`` random tissues of exactly 80 neurons."""
    rng = np.random.default_rng(seed)
    return [random_genome(rng, n_neurons=(80, 80)) for _ in range(n)]


def scenarios(n: int, seed: int) -> list[ScenarioSet]:
    """The benchmark's scenario set (default blueprint, depth 1)."""
    return [ScenarioSet.create(default_blueprint(1), ROBOTS, n, STEPS, seed)]


def throughput(genomes, sets, workers: int, repeats: int = 3) -> tuple[float, np.ndarray]:
    """Best-of-``repeats`` robot-steps per second, and the fitness values."""
    steps = len(genomes) * sum(s.size for s in sets) * STEPS * ROBOTS
    with Evaluator(workers=workers) as ev:
        fit = ev.evaluate(genomes[: max(workers, 1)], sets)  # warm up: spawn and compile
        best = 0.0
        for _ in range(repeats):
            t0 = time.perf_counter()
            fit = ev.evaluate(genomes, sets)
            best = max(best, steps / (time.perf_counter() - t0))
    return best, fit


def reference(genomes, n_scenarios: int, seed: int) -> dict:
    """Plain-Python rate and phases (a subprocess with numba's JIT disabled).

    Returns:
        ``rate`` (robot-steps per second of ``genomes``), ``fitness`` (theirs), ``phases``
        (the first genome's :func:`phase_times`) and ``hand`` (the hand-coded
        controller's).
    """
    payload = json.dumps(
        {"genomes": [genome_to_dict(g) for g in genomes], "scenarios": n_scenarios, "seed": seed}
    )
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    out = subprocess.run(
        [sys.executable, "-m", "ant_evolution.bench", "--reference-worker"],
        input=payload,
        capture_output=True,
        text=True,
        env=env,
        check=True,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def _reference_worker() -> None:
    import warnings

    warnings.simplefilter("ignore", RuntimeWarning)  # uint64 wrap-around is intended
    data = json.loads(sys.stdin.read())
    genomes = [genome_from_dict(d) for d in data["genomes"]]
    sets = scenarios(data["scenarios"], data["seed"])
    t0 = time.perf_counter()
    fit = [genome_fitness(g, sets) for g in genomes]
    dt = time.perf_counter() - t0
    steps = len(genomes) * data["scenarios"] * STEPS * ROBOTS
    phases = phase_times(Controller.from_genome(genomes[0]), sets[0], repeats=1)
    hand = phase_times(Controller.hand_coded(), sets[0], repeats=1)
    print(json.dumps({"rate": steps / dt, "fitness": fit, "phases": phases, "hand": hand}))


def generation_costs(
    population_size: int, n_scenarios: int, workers: int, generations: int, seed: int = 1000
) -> dict[str, dict[str, float]]:
    """Wall seconds per generation of ANT, NEAT and the fixed network, side by side.

    The three run generation by generation in turn on one worker pool, on the same
    scenarios (4 robots, T = 300), so machine load falls on all of them alike. Generation
    0 is reported apart (NEAT's and the fixed network's initial populations differ most
    from later ones); ``eval`` and ``tell`` are medians over generations 1 onward.
    """
    from ant_evolution.baseline_runs import FixedStrategy, NeatStrategy
    from ant_evolution.evolve import AntStrategy, EvolveConfig, blueprints_of, scenario_sets
    from ant_evolution.loop import cyclic_gc_paused

    config = EvolveConfig(
        population=population_size,
        generations=generations,
        scenarios=n_scenarios,
        steps=STEPS,
        robots=ROBOTS,
        seed=seed,
    )
    blueprints = blueprints_of(config)
    with tempfile.TemporaryDirectory() as tmp:
        strategies = {
            "ANT": AntStrategy(config),
            "NEAT": NeatStrategy(config, Path(tmp)),
            "fixed network": FixedStrategy(config),
        }
        states = {k: s.init() for k, s in strategies.items()}
        rows: dict[str, list[tuple[float, float]]] = {k: [] for k in strategies}
        with Evaluator(workers=workers) as ev:
            warm = scenario_sets(config, 0, blueprints)
            for k, s in strategies.items():  # spawn and compile outside the timing
                pop, st = s.ask(states[k])
                ev.evaluate(pop[:workers], warm, s.compiler(st))
            for g in range(generations):
                sets = scenario_sets(config, g, blueprints)
                for k, s in strategies.items():
                    t0 = time.perf_counter()
                    pop, st = s.ask(states[k])
                    fit = ev.evaluate(pop, sets, s.compiler(st))
                    t1 = time.perf_counter()
                    with cyclic_gc_paused():  # as the generation loop does
                        states[k] = s.tell(st, fit)
                    rows[k].append((t1 - t0, time.perf_counter() - t1))
    out = {}
    for k, r in rows.items():
        a = np.array(r)
        out[k] = {
            "gen0": float(a[0].sum()),
            "eval": float(np.median(a[1:, 0])),
            "tell": float(np.median(a[1:, 1])),
            "total": float(np.median(a[1:].sum(axis=1))),
        }
    return out


def soil_costs(genome, n_scenarios: int, seed: int, repeats: int = 5) -> list[tuple]:
    """``(soil, rate, mean fitness, stalls per scenario)`` on the grid and each physical soil.

    ``genome`` on ``n_scenarios`` scenarios, one core, best of ``repeats`` after a warm-up.
    The soils take turns within each repeat, so the grid and the physical soils are timed
    side by side (a machine whose speed drifts moves them together, not their ratio).
    """
    controller = Controller.from_genome(genome)
    soils = ("grid", *SOILS)
    batches = {}
    results = {}
    for soil in soils:
        batches[soil] = ScenarioSet.create(
            default_blueprint(1), ROBOTS, n_scenarios, STEPS, seed, soil=soil
        )
        results[soil] = batches[soil].run(controller)
    best = dict.fromkeys(soils, 0.0)
    for _ in range(repeats):
        for soil in soils:
            t0 = time.perf_counter()
            batches[soil].run(controller)
            rate = n_scenarios * STEPS * ROBOTS / (time.perf_counter() - t0)
            best[soil] = max(best[soil], rate)
    out = []
    for soil in soils:
        scores, counters = results[soil]
        out.append((soil, best[soil], float(scores.mean()), float(counters[:, 2].mean())))
    return out


def soil_table(costs: list[tuple], n_scenarios: int) -> list[str]:
    """The physical soil's section: rates and the cost per robot-step against the grid."""
    grid = costs[0][1]
    lines = [
        "",
        "### The physical soil (`ant-eval --soil`)",
        "",
        f"The shipped evolved genome, {n_scenarios} scenarios x {STEPS} steps x {ROBOTS} "
        "robots, one core, best of 5: the offline physical world (robots moving cell by "
        "cell through the physical soil) against the grid in the same run, the soils taking "
        "turns in each repeat. Target: at most "
        f"{PHYSICAL_TARGET:.0f} x the grid's time per robot-step.",
        "",
        "| soil | robot-steps/s | ns per robot-step | / grid | mean fitness | stalls per "
        "scenario |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for soil, rate, fitness, stalls in costs:
        lines.append(
            f"| `{soil}` | {rate:,.0f} | {_ns(1 / rate)} | {grid / rate:,.1f}x | {fitness:.3f} "
            f"| {stalls:.1f} |"
        )
    return lines


def _ns(x: float) -> str:
    return f"{x * 1e9:,.0f}"


def breakdown_table(cases: list[tuple[str, dict, dict]]) -> list[str]:
    """Rows of the per-robot-step breakdown of ``(label, compiled, plain)`` phase times."""
    lines = [
        "| controller | phase | compiled, ns per robot-step | share | plain Python, us | "
        "plain / compiled |",
        "|---|---|---:|---:|---:|---:|",
    ]
    for label, c, p in cases:
        total = sum(c[k] for k in PHASES)
        for k in PHASES:
            lines.append(
                f"| {label} | {k} | {_ns(c[k])} | {c[k] / total:.0%} | {p[k] * 1e6:,.1f} | "
                f"{p[k] / c[k]:,.0f}x |"
            )
        lines.append(
            f"| {label} | **sum** (the whole kernel: {_ns(c['kernel'])}) | {_ns(total)} | | "
            f"{sum(p[k] for k in PHASES) * 1e6:,.1f} | "
            f"{sum(p[k] for k in PHASES) / total:,.0f}x |"
        )
    return lines


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ant-bench``."""
    p = argparse.ArgumentParser(prog="ant-bench", description=__doc__.split("\n\n")[0])
    p.add_argument("--genomes", type=int, default=100, help="population size (default 100)")
    p.add_argument("--scenarios", type=int, default=100, help="scenarios (default 100)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--evolved",
        metavar="FILE",
        default="genomes/best.json",
        help="an evolved genome to time as well (skipped when missing)",
    )
    p.add_argument(
        "--generations",
        type=int,
        default=12,
        help="generations of each method timed side by side (default 12; 0 skips them)",
    )
    p.add_argument("--write", metavar="MD", help="put the section into this file")
    p.add_argument("--reference-worker", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.reference_worker:
        _reference_worker()
        return 0

    sets = scenarios(args.scenarios, args.seed)
    rows = []
    cases = [
        (
            "random 80-neuron tissues (a generation-0 population)",
            population(args.genomes, args.seed),
        )
    ]
    evolved = None
    if Path(args.evolved).exists():
        evolved = load_genome(args.evolved)
        cases.append((f"evolved genome {args.evolved} (x{args.genomes})", [evolved] * args.genomes))
    ref = {}
    for label, genomes in cases:
        r1, fit1 = throughput(genomes, sets, 1)
        r2, fit2 = throughput(genomes, sets, 2)
        if not np.array_equal(fit1, fit2):
            raise SystemExit("ant-bench: 1 and 2 workers disagree; this is a bug")
        ref = reference(genomes[:2], 2, args.seed)
        compiled = [genome_fitness(g, scenarios(2, args.seed)) for g in genomes[:2]]
        if ref["fitness"] != compiled:
            raise SystemExit("ant-bench: the plain-Python reference disagrees; this is a bug")
        rows.append((label, ref["rate"], r1, r2))
    hand = Controller.hand_coded()
    hand_steps = sum(st.size for st in sets) * STEPS * ROBOTS
    hand_rate = 0.0
    for _ in range(3):
        t0 = time.perf_counter()
        for st in sets:
            st.score(hand)
        hand_rate = max(hand_rate, hand_steps / (time.perf_counter() - t0))
    ref_rate = rows[-1][1]

    lines = [
        f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}; load average at the start "
        f"{os.getloadavg()[0]:.1f}. {args.genomes} genomes x {args.scenarios} "
        f"scenarios x {STEPS} steps x {ROBOTS} robots per measurement, best of 3.",
        "",
        "| controllers | plain Python (ref) | compiled, 1 worker | compiled, 2 workers |"
        " 1 worker / ref | 2 workers / ref | 2 / 1 workers (efficiency) |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for label, rate, r1, r2 in rows:
        lines.append(
            f"| {label} | {rate:,.0f} | {r1:,.0f} | {r2:,.0f} | {r1 / rate:,.0f}x | "
            f"{r2 / rate:,.0f}x | {r2 / r1:.2f} ({r2 / r1 / 2:.0%}) |"
        )
    lines += [
        "",
        f"Hand-coded controller, 1 worker: {hand_rate:,.0f} robot-steps/s "
        f"({hand_rate / ref_rate:,.0f}x the reference of the last row).",
        "",
        "Robot-steps per second; the paper-scale generation (1.2e7 robot-steps) takes "
        + ", ".join(
            f"{PAPER_GENERATION / r2:.2f} s ({label.split(' (')[0]})" for label, _, _, r2 in rows
        )
        + " on 2 workers.",
    ]
    if evolved is not None:
        r2 = rows[-1][3]
        hours = PAPER_GENERATIONS * PAPER_GENERATION / r2 / 3600
        lines += [
            f"A {PAPER_GENERATIONS:,}-generation paper-scale run of evolved genomes "
            f"({PAPER_GENERATIONS * PAPER_GENERATION:.1e} robot-steps) at that rate: "
            f"{hours:.2f} h on 2 workers (target: under 1 h, i.e. 1.7e7 robot-steps/s).",
        ]
        batch = sets[0]
        compiled = [
            ("evolved genome", phase_times(Controller.from_genome(evolved), batch), ref["phases"]),
            ("hand-coded", phase_times(hand, batch), ref["hand"]),
        ]
        lines += [
            "",
            "### Where the time goes per robot-step",
            "",
            f"`ant_evolution.breakdown` on {batch.size} scenarios (compiled) and 2 scenarios "
            "(plain Python, the reference's): each phase replayed alone on a recording of "
            "the kernel's own run, checked to reproduce it; one core, best of 3.",
            "",
            *breakdown_table(compiled),
        ]
        n_soil = min(args.scenarios, 20)
        lines += soil_table(soil_costs(evolved, n_soil, args.seed), n_soil)
    if args.generations > 1:
        costs = generation_costs(args.genomes, 20, 2, args.generations)
        ant = costs["ANT"]["total"]
        lines += [
            "",
            "### Generations: ANT, NEAT and the fixed network",
            "",
            f"P {args.genomes}, S 20, T {STEPS}, {ROBOTS} robots, 2 workers; the three "
            f"methods' generations run in turn on one pool ({args.generations} each, seed "
            "1000). Wall seconds: generation 0, then medians over the later generations.",
            "",
            "| method | generation 0 | later generation | evaluation | breeding (tell) | "
            "breeding / evaluation | / ANT |",
            "|---|---:|---:|---:|---:|---:|---:|",
        ]
        for k, c in costs.items():
            lines.append(
                f"| {k} | {c['gen0']:.2f} | {c['total']:.3f} | {c['eval']:.3f} | "
                f"{c['tell']:.3f} | {c['tell'] / c['eval']:.2f}x | {c['total'] / ant:.1f}x |"
            )
        lines += [
            "",
            "Targets: ANT's breeding at most 0.2 x its evaluation; NEAT's generation at most "
            "1.5 x ANT's.",
        ]
    text = "\n".join(lines)
    print(text)
    if args.write:
        replace_marked(args.write, NOTES.replace("{results}", text), MARK)
    return 0


if __name__ == "__main__":
    sys.exit(main())
