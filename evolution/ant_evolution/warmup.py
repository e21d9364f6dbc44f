"""``python -m ant_evolution.warmup``: compile the suite's kernels into numba's on-disk cache.

A fresh checkout (or any change to the kernel packages' sources, which keys the cache:
``ant_controller/__init__.py``) compiles the step kernels on first use: about 35 s for the
hand-coded rules, 40 s for an ANT tissue and 80 s for a network program (NEAT and the fixed
network) in one process here (docs/benchmarks.md, "Compiling the kernels"). Every process
that starts before the cache holds a kernel compiles it again, so a test suite's workers,
an evaluator's pool or a team of controller nodes started together on a cold cache each
pay it. This compiles each kind once, the
three kinds in parallel processes, and returns when the cache holds them; ``make test``
and ``make demo`` run it first. Running it again on a warm cache takes seconds.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path

KINDS = ("network", "ant", "hand-coded")
"""The decision programs the kernels are compiled for, the slowest first."""


def compile_kind(kind: str) -> float:
    """Run every kernel entry point once with a ``kind`` program; returns the seconds taken.

    Entry points: scoring a scenario set (``run_scenarios``), stepping one world
    (``run_episode``), one world's sensing and step (the lockstep simulator's), one
    decision (the controller node's) and, for tissues and the hand-coded rules, the
    per-phase timing of ``ant-bench`` (:func:`ant_evolution.breakdown.phase_times`); for
    tissues, one generation's compiled mutation under each profile; for networks, a NEAT
    genome's layout and one NEAT generation's compiled mutation too; for tissues and the
    hand-coded rules, the physical soil's two episode kernels.
    """
    import numpy as np

    from ant_controller.controller import Controller
    from ant_evolution.baseline_runs import FixedStrategy, NeatStrategy
    from ant_evolution.baselines.network import program_decide
    from ant_evolution.breakdown import phase_times
    from ant_evolution.evaluate import advance, program_fitness
    from ant_evolution.evolve import AntStrategy, EvolveConfig, blueprints_of, scenario_sets

    started = time.perf_counter()
    config = EvolveConfig(population=2, generations=1, scenarios=1, steps=5, robots=2, seed=1)
    blueprints = blueprints_of(config)
    sets = scenario_sets(config, 0, blueprints)
    world = sets[0].world(0)
    codes = world.sense()[0]
    if kind == "hand-coded":
        program = Controller.hand_coded()
    else:
        strategy = (AntStrategy if kind == "ant" else FixedStrategy)(config)
        population, state = strategy.ask(strategy.init())
        program = strategy.compiler(state)(population[0])
    if kind == "network":
        program_decide(codes, program.record())
        with tempfile.TemporaryDirectory() as tmp:  # NEAT's layout and its compiled mutation
            # 4 genomes: NEAT's elitism keeps 2, so a population of 2 breeds (and mutates) none
            neat = NeatStrategy(dataclasses.replace(config, population=4), Path(tmp))
            genomes, neat_state = neat.ask(neat.init())
            program_decide(codes, neat.compiler(neat_state)(genomes[0]).record())
            neat.tell(neat_state, np.zeros(len(genomes)))
    else:
        program.decide(codes)
        phase_times(program, sets[0], repeats=1)
    if kind == "ant":  # breeding's compiled mutations, under both profiles
        for profile in ("v1", "paper"):
            ant = AntStrategy(dataclasses.replace(config, population=4).with_profile(profile))
            genomes, ant_state = ant.ask(ant.init())
            ant.tell(ant_state, np.arange(len(genomes), dtype=np.float64))
    program_fitness(program, sets)
    advance(world, program, 2)
    if kind != "network":  # the physical soil's episode kernels (ant-eval --soil)
        from ant_evolution.evaluate import ScenarioSet

        physical = ScenarioSet.create(blueprints[0], 2, 1, 5, 1, soil="physical")
        physical.run(program)
        start = physical.world(0)
        advance(start, program, 2, soil=physical.soil_of(start))
    world.step(np.zeros(world.n_robots, dtype=np.int64))
    return time.perf_counter() - started


def main(argv: list[str] | None = None) -> int:
    """Compile every kind (in parallel processes unless ``--workers 1``)."""
    parser = argparse.ArgumentParser(prog="python -m ant_evolution.warmup", description=__doc__)
    parser.add_argument("--workers", type=int, default=len(KINDS), help="processes (1: here)")
    args = parser.parse_args(argv)
    if args.workers < 1:
        parser.error(f"--workers: must be at least 1, got {args.workers}")
    started = time.perf_counter()
    print("compiling the kernels into numba's cache (cold: 2-3 min on 2 cores) ...", flush=True)
    if args.workers == 1:
        times = [compile_kind(k) for k in KINDS]
    else:
        with ProcessPoolExecutor(args.workers, mp_context=get_context("spawn")) as pool:
            times = list(pool.map(compile_kind, KINDS))
    report = ", ".join(f"{k} {t:.0f} s" for k, t in zip(KINDS, times, strict=True))
    print(f"kernels ready in {time.perf_counter() - started:.0f} s ({report})", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
