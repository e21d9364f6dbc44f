"""An ANT evolution run: its configuration and its strategy on the one loop (paper, 4.3).

A run is fully described by an :class:`EvolveConfig` (the baselines take the same one).
:class:`AntStrategy` is ANT behind the ask / tell seam of :mod:`ant_evolution.loop`: its
state is the population and the GA generator's state, ``tell`` breeds with
:func:`ant_evolution.ga.next_generation`. Randomness comes from two places, both derived
from ``config.seed``: the GA's generator (whose state is checkpointed), and the scenarios
of generation g, seeded by ``SeedSequence([seed, g])`` and shared by every genome of that
generation (common random numbers; :func:`scenario_sets`). So a run resumed from a
checkpoint ends bit-identical to an uninterrupted one, whatever the worker count or
backend.

Outputs in the run directory:

* ``config.yaml``: the resolved configuration (loading it back gives the same run);
* ``history.csv``: one row per generation (best, mean, std, neuron counts, N histogram);
* ``best.json``: the best genome seen so far (``ant-genome/1`` with training metadata);
* ``fitness.png``: best and mean fitness against generations;
* ``checkpoint.json``: everything needed to resume, written atomically every
  ``checkpoint_every`` generations and at the end.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ant_controller.controller import Controller
from ant_controller.errors import GenomeFormatError
from ant_controller.genome import Genome, random_genome
from ant_controller.genome_io import genome_from_dict, genome_to_dict, load_genome
from ant_evolution.backends import Evaluator, compile_genome
from ant_evolution.errors import ConfigError
from ant_evolution.evaluate import DEFAULT_STEPS, ScenarioSet
from ant_evolution.ga import GAParams, mutate, next_generation
from ant_evolution.ga_kernel import PackedCells
from ant_evolution.limits import MAX_CONFIG_BYTES, check_config_value
from ant_evolution.loop import RunState, run_strategy
from ant_evolution.profiles import (
    CHOICES,
    PROFILES,
    SWITCHES,
    profile_switches,
    world_rules_of,
)
from blueprint_server.blueprint import Blueprint, resolve_blueprint
from excavation_common.loaders import load_yaml
from excavation_sim.rules import WorldRules
from excavation_sim.soil import SoilError, check_soil

CHECKPOINT_FORMAT = "ant-checkpoint/1"
COMBINES = ("mean", "progress", "floor")
"""How a run's soils combine into one fitness (``EvolveConfig.combine``)."""


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
        elitism: Best genomes copied unchanged (0 disables; a profile switch).
        seed: Seed of everything random in the run.
        checkpoint_every: Generations between checkpoints.
        profile: The profile the switches below started from (``v1`` or ``paper``,
            :mod:`ant_evolution.profiles`); a key given in the same file overrides one.
        soil_fill, normal_load, throttle_load, normal_climb, throttle_climb, h1,
            placement, site: The world's switches (:class:`excavation_sim.rules.WorldRules`).
        hand_coded: The hand-coded rules' reading (experiments that score them).
        mutation_scope, mutation_operator, mutation_width, replication_parent: The GA's
            switches (:class:`ant_evolution.ga.GAParams`).
        neat_activation, neat_budget: The NEAT baseline's switches.
        soil: ``grid`` (the world model's soil rules) or a physical soil the scenarios run
            on (``physical[:PRESET][,KEY=VALUE...]``, :mod:`excavation_sim.cell_soil`).
        also_soil: A second soil every genome is also scored on, on the same scenarios
            (empty: none); the fitness is then the lower of the two soils' means (the
            combined fitness, :func:`ant_evolution.evaluate.program_fitness`).
        start: A genome file the run starts from (fine-tuning: generation 0 is that genome
            and ``population - 1`` mutants of it); empty: random tissues.
        randomise: Each scenario draws its world (rules, sensor noise, soil) over the
            documented ranges (:mod:`ant_evolution.randomise`).
        combine: How the soils of a run with ``also_soil`` combine: ``mean`` (the lowest
            soil's mean fitness), ``progress`` (the lowest soil's gain over the start in
            units of the hand-coded rules' gain on the same scenarios) or ``floor`` (the
            ``also_soil`` mean while the run's own soil, never randomised, keeps a mean of
            at least ``floor``; below it the shortfall, a negative fitness;
            :func:`ant_evolution.evaluate.program_fitness`).
        floor: The run's own soil's mean fitness a genome must keep (``combine: floor``).
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
    profile: str = "v1"
    soil_fill: bool = False
    normal_load: int = 12
    throttle_load: int = 24
    normal_climb: int = 1
    throttle_climb: int = 2
    h1: str = "relative"
    placement: str = "anywhere"
    site: str = "shared"
    hand_coded: str = "chain"
    mutation_scope: str = "parameter"
    mutation_operator: str = "redraw"
    mutation_width: float = 0.1
    replication_parent: str = "max"
    neat_activation: str = "sigmoid"
    neat_budget: str = "library"
    soil: str = "grid"
    also_soil: str = ""
    start: str = ""
    randomise: bool = False
    combine: str = "mean"
    floor: float = 0.9
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
            "floor": 0.0 < self.floor <= 1.0,
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
        for key in ("soil", "also_soil"):
            value = getattr(self, key)
            try:
                if value or key == "soil":
                    check_soil(value)
            except SoilError as exc:
                raise ConfigError("<config>", key, value, str(exc)) from None
        if self.combine not in COMBINES:
            raise ConfigError("<config>", "combine", self.combine, f"must be one of {COMBINES}")
        if self.combine != "mean" and not self.also_soil:
            raise ConfigError("<config>", "combine", self.combine, "needs also_soil")
        if self.floor != 0.9 and self.combine != "floor":
            raise ConfigError("<config>", "floor", self.floor, "applies only with combine: floor")
        if self.also_soil == self.soil:
            raise ConfigError("<config>", "also_soil", self.also_soil, "is the run's soil")
        profile_switches(self.profile, "<config>")  # a known profile name
        world_rules_of(self.to_dict())
        for name, allowed in CHOICES.items():
            if getattr(self, name) not in allowed:
                raise ConfigError(
                    "<config>", name, getattr(self, name), f"must be one of {allowed}"
                )
        try:
            self.ga  # noqa: B018 (validates the GA switches)
        except ConfigError as exc:
            raise ConfigError("<config>", exc.field, exc.value, exc.reason) from None

    def with_profile(self, name: str) -> EvolveConfig:
        """This config with every switch set to profile ``name``'s values.

        Raises:
            ConfigError: For an unknown profile.
        """
        return dataclasses.replace(self, profile=name, **profile_switches(name, "<config>"))

    def switches(self) -> dict:
        """Switch name -> value (:data:`ant_evolution.profiles.SWITCHES`)."""
        return {k: getattr(self, k) for k in SWITCHES}

    @property
    def world_rules(self) -> WorldRules:
        """The world's switches, as the kernels and scenarios take them."""
        return world_rules_of(self.to_dict())

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
            mutation_scope=self.mutation_scope,
            mutation_operator=self.mutation_operator,
            mutation_width=self.mutation_width,
            replication_parent=self.replication_parent,
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
        """Hash of everything that changes results (not ``generations``).

        The profile and the switches added with it count only where they differ from
        ``v1``, so a ``v1`` run keeps the key its checkpoints were written with.
        """
        d = self.to_dict()
        d.pop("generations")
        d.pop("checkpoint_every")
        v1 = {"profile": "v1", **PROFILES["v1"]}
        for key in _KEYED_SINCE_PROFILES:
            if d[key] == v1[key]:
                d.pop(key)
        for key, default in _KEYED_WHERE_SET.items():
            if d[key] == default:  # keyed only where set, as the switches
                d.pop(key)
        return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:16]


_FIELD_TYPES = {f.name: f.type for f in dataclasses.fields(EvolveConfig)}
_KEYED_WHERE_SET = {
    "soil": "grid",
    "also_soil": "",
    "start": "",
    "randomise": False,
    "combine": "mean",
    "floor": 0.9,
}
"""Keys added after the first runs: keyed in ``run_key`` only where not their default."""
_KEYED_SINCE_PROFILES = ("profile", *(k for k in SWITCHES if k != "elitism"))


def config_from_dict(
    data: object, path: str = "<config>", base: EvolveConfig | None = None
) -> EvolveConfig:
    """Build a config from a mapping; unknown keys and wrong types are errors.

    A ``profile`` key first sets every switch to that profile's values; the other keys
    then override (so ``profile: paper`` with ``elitism: 1`` is the paper profile with
    elitism).

    Raises:
        ConfigError: Naming the file, the key and the value.
    """
    if not isinstance(data, dict):
        raise ConfigError(path, "<root>", type(data).__name__, "must be a mapping")
    base = base or EvolveConfig()
    if "profile" in data:
        name = data["profile"]
        if not isinstance(name, str) or name not in PROFILES:
            raise ConfigError(path, "profile", name, f"must be one of {list(PROFILES)}")
        base = base.with_profile(name)
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


def load_config(
    path: str | Path, base: EvolveConfig | None = None, profile: str | None = None
) -> EvolveConfig:
    """Read a YAML config file.

    ``profile``: replaces the file's ``profile`` key (``ant-evolve --profile``); the file's
    other keys still override the profile's switches.

    Raises:
        ConfigError: For an unreadable file, bad YAML, unknown keys or bad values.
    """
    label = str(path)
    data = load_yaml(label, ConfigError, max_bytes=MAX_CONFIG_BYTES) or {}
    if profile is not None and isinstance(data, dict):
        data = {**data, "profile": profile}
    return config_from_dict(data, label, base)


# --- the run ---------------------------------------------------------------------------------


def blueprints_of(config: EvolveConfig) -> list[Blueprint]:
    """The blueprints scenarios are spread over (switch ``site`` sizes the default's grid)."""
    fitted = config.world_rules.fitted_site
    if config.blueprint == "default":
        return [resolve_blueprint("default", d, fitted) for d in config.depths]
    return [resolve_blueprint(config.blueprint, fitted=fitted)]


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
    rules = config.world_rules
    soils = [config.soil, *([config.also_soil] if config.also_soil else [])]
    held = config.soil if config.combine == "floor" else None  # scored plain, held at floor
    sets = [
        ScenarioSet.create(
            bp, robots, size, config.steps, seed + i, rules, soil, config.randomise and soil != held
        )
        for soil in soils
        for i, (bp, size) in enumerate(zip(blueprints, sizes, strict=True))
        if size > 0
    ]
    if held is not None:
        sets = [dataclasses.replace(s, floor=config.floor) if s.soil == held else s for s in sets]
    if config.combine == "progress":
        reference = Controller.hand_coded(config.hand_coded)
        sets = [s.with_reference(reference) for s in sets]
    return sets


def initial_population(config: EvolveConfig, rng: np.random.Generator) -> list[Genome]:
    """P random tissues (N gene drawn uniformly from its range when evolved).

    With ``config.start``: that genome and P - 1 mutants of it (the GA's own mutation).

    Raises:
        ConfigError: When the start genome cannot be read or does not fit the run.
    """
    if config.start:
        return start_population(config, rng)
    pop = []
    for _ in range(config.population):
        robots = None
        if config.evolve_robots:
            robots = int(rng.integers(config.robots_range[0], config.robots_range[1] + 1))
        pop.append(
            random_genome(rng, config.neurons, coarse_coding=config.coarse_coding, robots=robots)
        )
    return pop


def start_population(config: EvolveConfig, rng: np.random.Generator) -> list[Genome]:
    """Generation 0 of a fine-tuning run: ``config.start`` and P - 1 mutants of it."""
    try:
        genome = load_genome(config.start)
    except GenomeFormatError as exc:
        raise ConfigError("<config>", "start", config.start, str(exc)) from None
    if genome.coarse_coding != config.coarse_coding:
        raise ConfigError(
            "<config>",
            "start",
            config.start,
            f"coarse_coding is {genome.coarse_coding}, the run's {config.coarse_coding}",
        )
    if config.evolve_robots != (genome.tissue.robots is not None):
        raise ConfigError("<config>", "start", config.start, "the N gene must match evolve_robots")
    genome = dataclasses.replace(genome, metadata={})
    return [genome] + [mutate(rng, genome, config.ga) for _ in range(config.population - 1)]


def generator(state: dict) -> np.random.Generator:
    """A PCG64 generator restored from ``bit_generator.state`` (a strategy state's)."""
    rng = np.random.Generator(np.random.PCG64())
    rng.bit_generator.state = state
    return rng


@dataclass(frozen=True)
class GAState:
    """The state of a GA strategy between generations.

    Attributes:
        population: The individuals of the generation to evaluate next.
        rng_state: The GA generator's ``bit_generator.state``.
    """

    population: list
    rng_state: dict


def neurons(genome: Genome) -> int:
    """Grown, living neurons (expressed genes without the cell-death flag)."""
    cells = genome.cells
    if isinstance(cells, PackedCells):  # from the arrays: the genes need not be built
        return len(cells.grown())
    return sum(g.expressed and not g.dead for g in cells)


class AntStrategy:
    """ANT behind the ask / tell seam (:class:`ant_evolution.loop.Strategy`).

    Args:
        config: The run's configuration.
    """

    checkpoint_name = "checkpoint.json"
    checkpoint_formats = (CHECKPOINT_FORMAT,)

    def __init__(self, config: EvolveConfig) -> None:
        self.config = config
        self.run_key = config.run_key()

    def init(self) -> GAState:
        """P random tissues from the run's GA generator."""
        rng = np.random.Generator(
            np.random.PCG64(np.random.SeedSequence([self.config.seed, 0xA17]))
        )
        return GAState(initial_population(self.config, rng), rng.bit_generator.state)

    def ask(self, state: GAState) -> tuple[list[Genome], GAState]:
        """The population (ANT draws nothing at ask time)."""
        return state.population, state

    def tell(self, state: GAState, fitness: np.ndarray) -> GAState:
        """Breed the next generation."""
        rng = generator(state.rng_state)
        population = next_generation(rng, state.population, fitness, self.config.ga)
        return GAState(population, rng.bit_generator.state)

    def compiler(self, state: GAState) -> Callable:
        """Genomes compile into tissues in the workers."""
        return compile_genome

    def title(self, state: GAState) -> str:
        """Plot title."""
        c = self.config
        return (
            f"ANT{'' if c.coarse_coding else ' without coarse coding'}, "
            f"P={c.population}, S={c.scenarios}, T={c.steps}"
        )

    def neurons(self, state: GAState, genome: Genome) -> int:
        """Grown, living neurons."""
        return neurons(genome)

    def robots(self, genome: Genome) -> int | None:
        """The N gene."""
        return genome.tissue.robots

    def best_document(self, state: GAState, genome: Genome, info: dict) -> dict:
        """The genome file with training metadata (``ant-genome/1``)."""
        metadata = {
            "fitness": info["fitness"],
            "generation": info["generation"],
            "seed": self.config.seed,
            "evaluations": info["evaluations"],
            "config": self.config.to_dict(),
        }
        return genome_to_dict(dataclasses.replace(genome, metadata=metadata))

    def dump_best(self, document: dict) -> str:
        """As :func:`ant_controller.genome_io.save_genome` writes it."""
        return json.dumps(document, indent=1, allow_nan=False) + "\n"

    def check_best(self, document: dict, label: str) -> None:
        """A valid genome file (``GenomeFormatError``, a ``ValueError``, when not)."""
        genome_from_dict(document, label)

    def state_to_dict(self, state: GAState, out: Path) -> dict:
        """Population and generator state."""
        return {
            "rng_state": state.rng_state,
            "population": [genome_to_dict(g) for g in state.population],
        }

    def state_from_dict(self, data: dict, out: Path, label: str) -> GAState:
        """Inverse of :meth:`state_to_dict` (every genome validated)."""
        population = [genome_from_dict(d, f"{label}:population") for d in data["population"]]
        generator(data["rng_state"])  # a bad state fails here, not a generation later
        return GAState(population, data["rng_state"])


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
    domain_base: int = 50,
) -> RunState:
    """Run (or resume) an ANT evolution, writing outputs into ``out``.

    Outputs: ``config.yaml`` (the resolved configuration), ``history.csv`` (one row per
    generation), ``best.json`` (the best genome so far with training metadata),
    ``fitness.png`` and ``checkpoint.json`` (every ``checkpoint_every`` generations and at
    the end, atomically).

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
    if evaluator == "ros":
        from ant_evolution.ros_evaluator import DEFAULT_TRIAL, RosEvaluator

        scorer = RosEvaluator(workers, domain_base, trial_command or DEFAULT_TRIAL)
    elif evaluator == "batched":
        scorer = Evaluator(workers, ray_address)
    else:
        raise ConfigError("<arguments>", "evaluator", evaluator, "must be 'batched' or 'ros'")
    blueprints = blueprints_of(config)
    with scorer:
        return run_strategy(
            AntStrategy(config),
            out,
            scorer,
            lambda g: scenario_sets(config, g, blueprints),
            resume=resume,
            progress=progress,
            stop_after=stop_after,
        )
