"""An evolution run: configuration, the generation loop, checkpoints and outputs (paper, 4.3).

A run is fully described by an :class:`EvolveConfig`. Randomness comes from two places,
both derived from ``config.seed``: the GA's generator (whose state is checkpointed), and
the scenarios of generation g, seeded by ``SeedSequence([seed, g])`` and shared by every
genome of that generation (common random numbers). So a run resumed from a checkpoint ends
bit-identical to an uninterrupted one, whatever the worker count or backend.

Outputs in the run directory:

* ``config.yaml``: the resolved configuration (loading it back gives the same run);
* ``history.csv``: one row per generation (best, mean, std, neuron counts, N histogram);
* ``best.json``: the best genome seen so far (``ant-genome/1`` with training metadata);
* ``fitness.png``: best and mean fitness against generations;
* ``checkpoint.json``: everything needed to resume, written atomically every
  ``checkpoint_every`` generations and at the end.
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import io
import json
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from ant_controller.genome import Genome, random_genome
from ant_controller.genome_io import genome_from_dict, genome_to_dict, save_genome
from ant_evolution.backends import Evaluator
from ant_evolution.errors import CheckpointError, ConfigError
from ant_evolution.evaluate import DEFAULT_STEPS, ScenarioSet
from ant_evolution.ga import GAParams, next_generation
from ant_evolution.limits import MAX_CONFIG_BYTES, check_config_value
from blueprint_server.blueprint import Blueprint, resolve_blueprint
from excavation_common.files import write_text_atomic
from excavation_common.loaders import load_yaml

CHECKPOINT_FORMAT = "ant-checkpoint/1"
HISTORY_FIELDS = (
    "generation",
    "evaluations",
    "best",
    "mean",
    "std",
    "best_ever",
    "neurons_best",
    "neurons_mean",
    "robots_hist",
    "seconds",
)


@dataclass(frozen=True)
class EvolveConfig:
    """Everything that defines an evolution run.

    Attributes:
        population: P (paper: 100).
        generations: Generations to run (paper: 5,000).
        scenarios: Scenarios per generation, S (paper: 100), split evenly over ``depths``.
        steps: Timesteps per scenario, T.
        robots: Robots per scenario (fixed N), the first of ``robots_mix`` otherwise.
        robots_mix: Robot counts to alternate between scenarios (e.g. ``[1, 4]``), or empty.
        evolve_robots: N is a gene (paper, section 5.4), bounded by ``robots_range``.
        robots_range: Bounds of the N gene.
        blueprint: ``"default"`` or a blueprint file.
        depths: Goal depths of the default blueprint (ignored for a file).
        coarse_coding: False trains ANT without coarse coding.
        neurons: Inclusive range of neurons in the initial random tissues.
        tournament_fraction: Tournament size as a fraction of P (paper: 0.06).
        crossover_prob: Paper: 0.7.
        mutation_prob: Paper: 0.025.
        elitism: Best genomes copied unchanged (0 disables).
        seed: Seed of everything random in the run.
        checkpoint_every: Generations between checkpoints.
    """

    population: int = 100
    generations: int = 100
    scenarios: int = 100
    steps: int = DEFAULT_STEPS
    robots: int = 4
    robots_mix: tuple[int, ...] = ()
    evolve_robots: bool = False
    robots_range: tuple[int, int] = (1, 8)
    blueprint: str = "default"
    depths: tuple[int, ...] = (1, 2, 3)
    coarse_coding: bool = True
    neurons: tuple[int, int] = (40, 120)
    tournament_fraction: float = 0.06
    crossover_prob: float = 0.7
    mutation_prob: float = 0.025
    elitism: int = 1
    seed: int = 0
    checkpoint_every: int = 10
    extra: dict = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self) -> None:
        checks = {
            "population": self.population >= 2,
            "generations": self.generations >= 1,
            "scenarios": self.scenarios >= 1,
            "steps": self.steps >= 1,
            "robots": self.robots >= 1,
            "robots_mix": all(n >= 1 for n in self.robots_mix),
            "robots_range": 1 <= self.robots_range[0] <= self.robots_range[1],
            "depths": len(self.depths) >= 1 and all(d >= 1 for d in self.depths),
            "neurons": 1 <= self.neurons[0] <= self.neurons[1],
            "tournament_fraction": 0.0 < self.tournament_fraction <= 1.0,
            "crossover_prob": 0.0 <= self.crossover_prob <= 1.0,
            "mutation_prob": 0.0 <= self.mutation_prob <= 1.0,
            "elitism": 0 <= self.elitism < self.population,
            "checkpoint_every": self.checkpoint_every >= 1,
        }
        for name, ok in checks.items():
            if not ok:
                raise ConfigError("<config>", name, getattr(self, name), "is out of range")
        if self.evolve_robots and self.robots_mix:
            raise ConfigError(
                "<config>",
                "robots_mix",
                list(self.robots_mix),
                "cannot be combined with evolve_robots",
            )

    @property
    def ga(self) -> GAParams:
        """The GA's parameters."""
        return GAParams(
            population=self.population,
            tournament_fraction=self.tournament_fraction,
            crossover_prob=self.crossover_prob,
            mutation_prob=self.mutation_prob,
            elitism=self.elitism,
            robots_range=self.robots_range,
        )

    def to_dict(self) -> dict:
        """Plain mapping (lists for tuples), as written to ``config.yaml``."""
        out = {}
        for f in dataclasses.fields(self):
            if f.name == "extra":
                continue
            v = getattr(self, f.name)
            out[f.name] = list(v) if isinstance(v, tuple) else v
        return out

    def run_key(self) -> str:
        """Hash of everything that changes results (not ``generations``)."""
        d = self.to_dict()
        d.pop("generations")
        d.pop("checkpoint_every")
        return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:16]


_FIELD_TYPES = {f.name: f.type for f in dataclasses.fields(EvolveConfig)}


def config_from_dict(
    data: object, path: str = "<config>", base: EvolveConfig | None = None
) -> EvolveConfig:
    """Build a config from a mapping; unknown keys and wrong types are errors.

    Raises:
        ConfigError: Naming the file, the key and the value.
    """
    if not isinstance(data, dict):
        raise ConfigError(path, "<root>", type(data).__name__, "must be a mapping")
    base = base or EvolveConfig()
    values = {}
    for key, value in data.items():
        if key not in _FIELD_TYPES or key == "extra":
            known = sorted(k for k in _FIELD_TYPES if k != "extra")
            raise ConfigError(path, key, value, f"is not a known key (known: {', '.join(known)})")
        default = getattr(base, key)
        if isinstance(default, bool):
            ok = isinstance(value, bool)
        elif isinstance(default, int):
            ok = isinstance(value, int) and not isinstance(value, bool)
        elif isinstance(default, float):
            ok = isinstance(value, int | float) and not isinstance(value, bool)
            value = float(value) if ok else value
        elif isinstance(default, str):
            ok = isinstance(value, str)
        else:  # tuples of ints
            ok = isinstance(value, list | tuple) and all(
                isinstance(v, int) and not isinstance(v, bool) for v in value
            )
            value = tuple(value) if ok else value
        if not ok:
            raise ConfigError(path, key, value, f"must be like {default!r}")
        check_config_value(path, key, value)
        values[key] = value
    try:
        return dataclasses.replace(base, **values)
    except ConfigError as exc:
        raise ConfigError(path, exc.field, exc.value, exc.reason) from None


def load_config(path: str | Path, base: EvolveConfig | None = None) -> EvolveConfig:
    """Read a YAML config file.

    Raises:
        ConfigError: For an unreadable file, bad YAML, unknown keys or bad values.
    """
    label = str(path)
    data = load_yaml(label, ConfigError, max_bytes=MAX_CONFIG_BYTES)
    return config_from_dict(data or {}, label, base)


# --- the run ---------------------------------------------------------------------------------


def blueprints_of(config: EvolveConfig) -> list[Blueprint]:
    """The blueprints scenarios are spread over."""
    if config.blueprint == "default":
        return [resolve_blueprint("default", d) for d in config.depths]
    return [resolve_blueprint(config.blueprint)]


def scenario_sets(
    config: EvolveConfig, generation: int, blueprints: list[Blueprint]
) -> list[ScenarioSet]:
    """The scenarios of one generation, the same for every genome in it."""
    seed = int(np.random.SeedSequence([config.seed, generation]).generate_state(1)[0])
    if config.evolve_robots:
        robots: list[int] | int = config.robots_range[1]
    else:
        robots = list(config.robots_mix) or config.robots
    n = len(blueprints)
    sizes = [config.scenarios // n + (i < config.scenarios % n) for i in range(n)]
    return [
        ScenarioSet.create(bp, robots, size, config.steps, seed + i)
        for i, (bp, size) in enumerate(zip(blueprints, sizes, strict=True))
        if size > 0
    ]


def initial_population(config: EvolveConfig, rng: np.random.Generator) -> list[Genome]:
    """P random tissues (N gene drawn uniformly from its range when evolved)."""
    pop = []
    for _ in range(config.population):
        robots = None
        if config.evolve_robots:
            robots = int(rng.integers(config.robots_range[0], config.robots_range[1] + 1))
        pop.append(
            random_genome(rng, config.neurons, coarse_coding=config.coarse_coding, robots=robots)
        )
    return pop


@dataclass
class RunState:
    """What a checkpoint holds."""

    generation: int
    population: list[Genome]
    rng_state: dict
    history: list[dict]
    best: Genome | None
    best_fitness: float
    evaluations: int


def save_checkpoint(out: Path, config: EvolveConfig, state: RunState) -> None:
    """Write ``checkpoint.json`` atomically."""
    data = {
        "format": CHECKPOINT_FORMAT,
        "run_key": config.run_key(),
        "generation": state.generation,
        "rng_state": state.rng_state,
        "evaluations": state.evaluations,
        "best_fitness": state.best_fitness,
        "best": genome_to_dict(state.best) if state.best is not None else None,
        "history": state.history,
        "population": [genome_to_dict(g) for g in state.population],
    }
    write_text_atomic(out / "checkpoint.json", json.dumps(data, allow_nan=False))


def load_checkpoint(out: Path, config: EvolveConfig) -> RunState:
    """Read and check ``checkpoint.json``.

    Raises:
        CheckpointError: Missing, corrupt, or written by a different configuration.
    """
    path = out / "checkpoint.json"
    label = str(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise CheckpointError(label, "does not exist; nothing to resume") from None
    except (OSError, UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise CheckpointError(
            label, f"is corrupt ({exc}); it was not written by a finished checkpoint"
        ) from None
    if not isinstance(data, dict) or data.get("format") != CHECKPOINT_FORMAT:
        raise CheckpointError(label, f"is not an {CHECKPOINT_FORMAT} file")
    if data.get("run_key") != config.run_key():
        raise CheckpointError(
            label,
            "was written by a run with a different configuration (compare "
            f"{out / 'config.yaml'}); start a new run directory or restore that config",
        )
    try:
        pop = [genome_from_dict(d, f"{label}:population") for d in data["population"]]
        best = genome_from_dict(data["best"], f"{label}:best") if data["best"] else None
        rng = np.random.Generator(np.random.PCG64())
        rng.bit_generator.state = data["rng_state"]
        return RunState(
            int(data["generation"]),
            pop,
            data["rng_state"],
            list(data["history"]),
            best,
            float(data["best_fitness"]),
            int(data["evaluations"]),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise CheckpointError(label, f"is corrupt: {exc!r}") from None


def _history_csv(rows: list[dict]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=HISTORY_FIELDS, lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    return buf.getvalue()


def plot_history(rows: list[dict], path: Path, title: str) -> None:
    """Best and mean fitness against generations, with the 0.9 solution line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    gens = [r["generation"] for r in rows]
    fig, ax = plt.subplots(figsize=(6, 4), dpi=100)
    ax.plot(gens, [r["best"] for r in rows], label="best")
    ax.plot(gens, [r["mean"] for r in rows], label="mean")
    ax.plot(gens, [r["best_ever"] for r in rows], "--", label="best so far", alpha=0.7)
    ax.axhline(0.9, color="gray", lw=0.8, ls=":")
    ax.set_xlabel("generation")
    ax.set_ylabel("fitness")
    ax.set_ylim(0, 1)
    ax.set_title(title, fontsize=9)
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def _neurons(genome: Genome) -> int:
    """Grown, living neurons (expressed genes without the cell-death flag)."""
    return sum(g.expressed and not g.dead for g in genome.cells)


def run_evolution(
    config: EvolveConfig,
    out: str | Path,
    *,
    workers: int | None = None,
    ray_address: str | None = None,
    resume: bool = False,
    progress: Callable[[dict], None] | None = None,
    stop_after: int | None = None,
    evaluator: str = "batched",
    trial_command: str | None = None,
    domain_base: int = 100,
) -> RunState:
    """Run (or resume) an evolution, writing outputs into ``out``.

    Args:
        config: The run's configuration.
        out: Run directory.
        workers: Local worker processes (``None``: all cores).
        ray_address: Evaluate on Ray instead (``"local"`` for a local instance).
        resume: Continue from ``out/checkpoint.json``.
        progress: Called with each generation's history row.
        stop_after: Stop after this many generations in this call (tests use it to
            simulate an interruption); the checkpoint is written at the stop.
        evaluator: ``"batched"`` (the compiled world model; ``workers`` / ``ray_address``)
            or ``"ros"`` (trials through the topics, ``workers`` at once:
            :mod:`ant_evolution.ros_evaluator`).
        trial_command: ``"ros"``: the trial command template (default: ``ant-trial``).
        domain_base: ``"ros"``: trials use ROS domains ``domain_base`` onwards.

    Raises:
        CheckpointError: ``resume`` without a usable checkpoint, or a fresh run into a
            directory that already holds one.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if resume:
        state = load_checkpoint(out, config)
        rng = np.random.Generator(np.random.PCG64())
        rng.bit_generator.state = state.rng_state
    else:
        if (out / "checkpoint.json").exists():
            raise CheckpointError(
                str(out / "checkpoint.json"),
                "exists: pass --resume to continue that run, or choose a new output directory",
            )
        rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence([config.seed, 0xA17])))
        state = RunState(0, initial_population(config, rng), {}, [], None, -1.0, 0)
    write_text_atomic(out / "config.yaml", yaml.safe_dump(config.to_dict(), sort_keys=False))
    blueprints = blueprints_of(config)
    title = (
        f"ANT{'' if config.coarse_coding else ' without coarse coding'}, "
        f"P={config.population}, S={config.scenarios}, T={config.steps}"
    )
    done_here = 0
    if evaluator == "ros":
        from ant_evolution.ros_evaluator import DEFAULT_TRIAL, RosEvaluator

        scorer = RosEvaluator(workers, domain_base, trial_command or DEFAULT_TRIAL)
    elif evaluator == "batched":
        scorer = Evaluator(workers, ray_address)
    else:
        raise ConfigError("<arguments>", "evaluator", evaluator, "must be 'batched' or 'ros'")
    with scorer as evaluator:
        while state.generation < config.generations:
            t0 = time.perf_counter()
            g = state.generation
            sets = scenario_sets(config, g, blueprints)
            fit = evaluator.evaluate(state.population, sets)
            state.evaluations += len(state.population) * config.scenarios
            i_best = int(np.argmax(fit))
            if fit[i_best] > state.best_fitness:
                state.best_fitness = float(fit[i_best])
                best = state.population[i_best]
                state.best = dataclasses.replace(
                    best,
                    metadata={
                        "fitness": state.best_fitness,
                        "generation": g,
                        "seed": config.seed,
                        "evaluations": state.evaluations,
                        "config": config.to_dict(),
                    },
                )
                save_genome(state.best, out / "best.json")
            hist = ""
            if config.evolve_robots:
                counts = np.bincount([p.tissue.robots for p in state.population])
                hist = ";".join(f"{n}:{c}" for n, c in enumerate(counts) if c)
            row = {
                "generation": g,
                "evaluations": state.evaluations,
                "best": float(fit[i_best]),
                "mean": float(fit.mean()),
                "std": float(fit.std()),
                "best_ever": state.best_fitness,
                "neurons_best": _neurons(state.population[i_best]),
                "neurons_mean": float(np.mean([_neurons(p) for p in state.population])),
                "robots_hist": hist,
                "seconds": round(time.perf_counter() - t0, 3),
            }
            state.history.append(row)
            state.population = next_generation(rng, state.population, fit, config.ga)
            state.generation = g + 1
            state.rng_state = rng.bit_generator.state
            done_here += 1
            if progress is not None:
                progress(row)
            last = state.generation == config.generations
            stopping = stop_after is not None and done_here >= stop_after
            if last or stopping or state.generation % config.checkpoint_every == 0:
                write_text_atomic(out / "history.csv", _history_csv(state.history))
                plot_history(state.history, out / "fitness.png", title)
                save_checkpoint(out, config, state)
            if stopping:
                break
    return state
