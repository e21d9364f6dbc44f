"""The baselines as strategies on the one generation loop, and network-program files.

:class:`FixedStrategy` and :class:`NeatStrategy` stand behind the same ask / tell seam as
:class:`ant_evolution.evolve.AntStrategy` (:mod:`ant_evolution.loop`), so :func:`run_fixed`
and :func:`run_neat` take the same :class:`~ant_evolution.evolve.EvolveConfig`, see the same
scenarios per generation (:func:`~ant_evolution.evolve.scenario_sets`:
``SeedSequence([seed, g])``), use the same evaluator and write the same outputs:
``config.yaml``, ``history.csv`` (ANT's columns), ``fitness.png``, ``best.json`` (the best
network program, ``network-program/1``) and a checkpoint, written atomically every
``checkpoint_every`` generations and at the end; ``resume=True`` continues exactly.

* Fixed network: the GA of :mod:`ant_evolution.ga` with the fixed network's operators;
  the checkpoint is JSON (topology, population, GA generator state, history, best).
* NEAT: neat-python does selection, speciation and reproduction; ``tell`` hands it the
  fitness through ``Population.run`` for one generation. Its checkpoint is neat-python's
  own (its gzip pickle of population, species, innovation tracker and ``random`` state:
  the library's mechanism, read only from the run's own directory), renamed into place
  atomically, beside the loop's JSON file.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import io
import json
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ant_evolution.backends import CompileHere, Evaluator
from ant_evolution.baselines import fixed
from ant_evolution.baselines.fixed import FixedNetwork, FixedTopology, compile_fixed
from ant_evolution.baselines.neat_baseline import (
    compile_neat,
    config_overrides,
    neat_config,
    neat_hidden,
)
from ant_evolution.baselines.network import NetworkProgram
from ant_evolution.errors import CheckpointError
from ant_evolution.evolve import (
    EvolveConfig,
    GAState,
    blueprints_of,
    generator,
    scenario_sets,
)
from ant_evolution.ga import next_generation
from ant_evolution.loop import Strategy, run_strategy

PROGRAM_FORMAT = "network-program/1"
_ARRAYS = [f.name for f in dataclasses.fields(NetworkProgram)]
_INT_ARRAYS = {"node_act", "node_agg", "edge_start", "edge_src", "out_node"}


def program_to_dict(program: NetworkProgram, metadata: dict | None = None) -> dict:
    """JSON-ready form of a network program."""
    d = {"format": PROGRAM_FORMAT}
    d.update({name: getattr(program, name).tolist() for name in _ARRAYS})
    d["metadata"] = metadata or {}
    return d


def program_from_dict(data: object, path: str = "<memory>") -> NetworkProgram:
    """Inverse of :func:`program_to_dict`.

    Raises:
        ValueError: Naming the file and the field that is missing or malformed.
    """
    if not isinstance(data, dict) or data.get("format") != PROGRAM_FORMAT:
        raise ValueError(f"{path}: format: not a {PROGRAM_FORMAT} file")
    arrays = {}
    for name in _ARRAYS:
        if name not in data:
            raise ValueError(f"{path}: {name}: missing")
        try:
            dtype = np.int64 if name in _INT_ARRAYS else np.float64
            arrays[name] = np.asarray(data[name], dtype=dtype)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{path}: {name}: {exc}") from None
    if arrays["node_theta"].size % 2:
        raise ValueError(f"{path}: node_theta: {arrays['node_theta'].size} values, not pairs")
    arrays["node_theta"] = arrays["node_theta"].reshape(-1, 2)
    try:
        return NetworkProgram(**arrays)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


def load_program(path: str | Path) -> NetworkProgram:
    """Read a ``network-program/1`` file."""
    return program_from_dict(json.loads(Path(path).read_text(encoding="utf-8")), str(path))


def _run(
    strategy: Strategy,
    out: Path,
    workers: int | None,
    ray_address: str | None,
    resume: bool,
    progress: Callable[[dict], None] | None,
    stop_after: int | None,
) -> list[dict]:
    config = strategy.config
    blueprints = blueprints_of(config)
    with Evaluator(workers, ray_address) as evaluator:
        run = run_strategy(
            strategy,
            out,
            evaluator,
            lambda g: scenario_sets(config, g, blueprints),
            resume=resume,
            progress=progress,
            stop_after=stop_after,
        )
    return run.history


# --- fixed-topology network ---------------------------------------------------------------


@dataclass(frozen=True)
class FixedState(GAState):
    """The GA state of a fixed-network run, with the run's topology.

    Attributes:
        topology: Layer sizes, drawn once per run.
    """

    topology: FixedTopology


class FixedStrategy:
    """The fixed-topology network behind the ask / tell seam (ANT's GA settings)."""

    checkpoint_name = "checkpoint.json"
    checkpoint_formats = ("fixed-checkpoint/1",)

    def __init__(self, config: EvolveConfig) -> None:
        self.config = config
        self.run_key = "fixed-" + config.run_key()

    def init(self) -> FixedState:
        """The topology, then P random networks, from the run's generator."""
        seq = np.random.SeedSequence([self.config.seed, 0xF1])
        rng = np.random.Generator(np.random.PCG64(seq))
        topology = FixedTopology.random(rng, self.config.neurons)
        population = [fixed.random_network(rng, topology) for _ in range(self.config.population)]
        return FixedState(population, rng.bit_generator.state, topology)

    def ask(self, state: FixedState) -> tuple[list[FixedNetwork], FixedState]:
        """The population."""
        return state.population, state

    def tell(self, state: FixedState, fitness: np.ndarray) -> FixedState:
        """Breed with ANT's GA and the fixed network's operators."""
        rng = generator(state.rng_state)
        population = next_generation(
            rng,
            state.population,
            fitness,
            self.config.ga,
            crossover=functools.partial(fixed.crossover, topology=state.topology),
            mutate=functools.partial(fixed.mutate, topology=state.topology),
        )
        return FixedState(population, rng.bit_generator.state, state.topology)

    def compiler(self, state: FixedState) -> Callable:
        """Networks compile into programs in the workers."""
        return functools.partial(compile_fixed, state.topology)

    def title(self, state: FixedState) -> str:
        """Plot title."""
        c = self.config
        return (
            f"fixed network {state.topology.layers}, P={c.population}, S={c.scenarios}, T={c.steps}"
        )

    def neurons(self, state: FixedState, net: FixedNetwork) -> int:
        """Hidden plus output neurons."""
        return state.topology.n_neurons

    def robots(self, net: FixedNetwork) -> None:
        """No N gene."""
        return None

    def best_document(self, state: FixedState, net: FixedNetwork, info: dict) -> dict:
        """The network program with its metadata."""
        meta = {"kind": "fixed", "fitness": info["fitness"], "generation": info["generation"]}
        meta.update(hidden=list(state.topology.hidden), seed=self.config.seed)
        return program_to_dict(compile_fixed(state.topology, net), meta)

    def dump_best(self, document: dict) -> str:
        """Compact JSON."""
        return json.dumps(document)

    def check_best(self, document: dict, label: str) -> None:
        """A valid network program."""
        program_from_dict(document, label)

    def state_to_dict(self, state: FixedState, out: Path) -> dict:
        """Topology, population and generator state."""
        return {
            "hidden": list(state.topology.hidden),
            "rng_state": state.rng_state,
            "population": [p.to_dict() for p in state.population],
        }

    def state_from_dict(self, data: dict, out: Path, label: str) -> FixedState:
        """Inverse of :meth:`state_to_dict`."""
        topology = FixedTopology(tuple(data["hidden"]))
        population = [FixedNetwork.from_dict(d) for d in data["population"]]
        generator(data["rng_state"])
        return FixedState(population, data["rng_state"], topology)


def run_fixed(
    config: EvolveConfig,
    out: str | Path,
    *,
    workers: int | None = 1,
    ray_address: str | None = None,
    resume: bool = False,
    progress: Callable[[dict], None] | None = None,
    stop_after: int | None = None,
) -> list[dict]:
    """Evolve a fixed-topology network (or resume); returns the history rows.

    Raises:
        CheckpointError: As :func:`ant_evolution.evolve.run_evolution`.
    """
    strategy = FixedStrategy(config)
    return _run(strategy, Path(out), workers, ray_address, resume, progress, stop_after)


# --- NEAT ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class NeatState:
    """A NEAT run's state: neat-python's ``Population`` (``tell`` advances it in place).

    Attributes:
        population: The library's population object (genomes, species, reproduction).
    """

    population: Any


class NeatStrategy:
    """NEAT (neat-python) behind the ask / tell seam.

    Population size, generations, scenarios and seed come from ``config``; the GA
    operators are NEAT's own (``neat.ini`` in ``out`` holds them).

    Args:
        config: The run's configuration.
        out: The run directory (``neat.ini`` and neat-python's checkpoint live there).
    """

    checkpoint_name = "neat-state.json"
    checkpoint_formats = ("neat-state/1", None)  # None: side files written before the format

    def __init__(self, config: EvolveConfig, out: Path) -> None:
        self.config = config
        self.run_key = "neat-" + config.run_key()
        self.out = out
        hidden = neat_hidden(config.seed, config.neurons)
        overrides = config_overrides(
            config.neat_activation,
            config.neat_budget,
            config.mutation_prob,
            config.mutation_operator == "perturb",
            config.mutation_width,
            config.elitism,
        )
        self.neat_config = neat_config(out / "neat.ini", config.population, hidden, overrides)

    def init(self) -> NeatState:
        """neat-python's initial population (seeded with ``config.seed``)."""
        import neat

        return NeatState(neat.Population(self.neat_config, seed=self.config.seed))

    def ask(self, state: NeatState) -> tuple[list, NeatState]:
        """The genomes, in neat-python's order."""
        return list(state.population.population.values()), state

    def tell(self, state: NeatState, fitness: np.ndarray) -> NeatState:
        """One generation of neat-python with the given fitness (its own ``run``)."""
        pop = state.population

        def assign(genomes, _config) -> None:
            for (_, genome), f in zip(genomes, fitness, strict=True):
                genome.fitness = float(f)

        pop.run(assign, 1)
        return state

    def compiler(self, state: NeatState) -> Callable:
        """Genomes compile into programs here, with the population's config.

        The programs pickle far faster than the genomes.
        """
        return CompileHere(functools.partial(compile_neat, config=state.population.config))

    def title(self, state: NeatState) -> str:
        """Plot title."""
        c = self.config
        return f"NEAT, P={c.population}, S={c.scenarios}, T={c.steps}"

    def neurons(self, state: NeatState, genome) -> int:
        """Hidden plus output nodes."""
        return len(genome.nodes)

    def robots(self, genome) -> None:
        """No N gene."""
        return None

    def best_document(self, state: NeatState, genome, info: dict) -> dict:
        """The compiled network program with its metadata."""
        meta = {"kind": "neat", "fitness": info["fitness"], "generation": info["generation"]}
        meta["seed"] = self.config.seed
        return program_to_dict(compile_neat(genome, state.population.config), meta)

    def dump_best(self, document: dict) -> str:
        """Compact JSON."""
        return json.dumps(document)

    def check_best(self, document: dict, label: str) -> None:
        """A valid network program."""
        program_from_dict(document, label)

    def state_to_dict(self, state: NeatState, out: Path) -> dict:
        """Write neat-python's checkpoint (atomically); the JSON part holds nothing more."""
        import neat

        pop = state.population
        g = pop.generation
        saver = neat.Checkpointer(None, filename_prefix=str(out / ".tmp-neat-"))
        with contextlib.redirect_stdout(io.StringIO()):
            saver.save_checkpoint(pop.config, pop.population, pop.species, g)
        os.replace(out / f".tmp-neat-{g}", out / "neat-checkpoint.gz")
        return {}

    def state_from_dict(self, data: dict, out: Path, label: str) -> NeatState:
        """neat-python's population from its checkpoint (with its pickled config).

        Raises:
            CheckpointError: The library's checkpoint is missing or from another generation.
        """
        import neat

        ckpt = out / "neat-checkpoint.gz"
        if not ckpt.exists():
            raise CheckpointError(str(ckpt), "does not exist; nothing to resume")
        # the pickled config carries neat-python's node indexer: a fresh config would
        # restart it and hand out node keys that genomes already use
        pop = neat.Checkpointer.restore_checkpoint(str(ckpt))
        if pop.generation != data["generation"]:
            raise CheckpointError(label, "does not match neat-checkpoint.gz")
        return NeatState(pop)


def run_neat(
    config: EvolveConfig,
    out: str | Path,
    *,
    workers: int | None = 1,
    ray_address: str | None = None,
    resume: bool = False,
    progress: Callable[[dict], None] | None = None,
    stop_after: int | None = None,
) -> list[dict]:
    """Evolve NEAT networks with neat-python (or resume); returns the history rows.

    Raises:
        CheckpointError: As :func:`ant_evolution.evolve.run_evolution`.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    strategy = NeatStrategy(config, out)
    return _run(strategy, out, workers, ray_address, resume, progress, stop_after)
