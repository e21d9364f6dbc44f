"""Evolution runs of the baselines, with ANT's budget, scenarios, outputs and checkpoints.

:func:`run_fixed` and :func:`run_neat` take the same :class:`~ant_evolution.evolve.EvolveConfig`
as :func:`ant_evolution.evolve.run_evolution` and use the same scenarios per generation
(:func:`~ant_evolution.evolve.scenario_sets`: ``SeedSequence([seed, g])``), so an ANT run, a
fixed-network run and a NEAT run with one seed see identical worksites. Each writes
``config.yaml``, ``history.csv`` (the same columns as ANT's), ``fitness.png``, ``best.json``
(the best network program, ``network-program/1``) and a checkpoint, written atomically
every ``checkpoint_every`` generations and at the end; ``resume=True`` continues exactly.

* Fixed network: the checkpoint is JSON (population, GA generator state, history, best).
* NEAT: neat-python's own checkpoint (its gzip pickle of population, species, innovation
  tracker and ``random`` state: the library's mechanism, read only from the run's own
  directory), renamed into place atomically, plus a JSON side file with our history.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import io
import json
import os
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import yaml

from ant_evolution.baselines.fixed import (
    FixedNetwork,
    FixedTopology,
    compile_fixed,
    next_generation,
    random_network,
)
from ant_evolution.baselines.neat_baseline import compile_neat, neat_config, neat_hidden
from ant_evolution.baselines.network import NetworkProgram, ProgramEvaluator
from ant_evolution.errors import CheckpointError
from ant_evolution.evolve import (
    EvolveConfig,
    _history_csv,
    blueprints_of,
    plot_history,
    scenario_sets,
)
from excavation_common.files import write_text_atomic

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
    arrays["node_theta"] = arrays["node_theta"].reshape(-1, 2)
    try:
        return NetworkProgram(**arrays)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


def load_program(path: str | Path) -> NetworkProgram:
    """Read a ``network-program/1`` file."""
    return program_from_dict(json.loads(Path(path).read_text(encoding="utf-8")), str(path))


def _row(g: int, evaluations: int, fit: np.ndarray, best_ever: float, neurons, t0) -> dict:
    i = int(np.argmax(fit))
    return {
        "generation": g,
        "evaluations": evaluations,
        "best": float(fit[i]),
        "mean": float(fit.mean()),
        "std": float(fit.std()),
        "best_ever": best_ever,
        "neurons_best": int(neurons[i]),
        "neurons_mean": float(np.mean(neurons)),
        "robots_hist": "",
        "seconds": round(time.perf_counter() - t0, 3),
    }


def _write_outputs(out: Path, history: list[dict], title: str) -> None:
    write_text_atomic(out / "history.csv", _history_csv(history))
    plot_history(history, out / "fitness.png", title)


def _start(out: Path, config: EvolveConfig, resume: bool, checkpoint: str) -> None:
    out.mkdir(parents=True, exist_ok=True)
    if not resume and (out / checkpoint).exists():
        raise CheckpointError(
            str(out / checkpoint),
            "exists: pass resume to continue that run, or choose a new output directory",
        )
    write_text_atomic(out / "config.yaml", yaml.safe_dump(config.to_dict(), sort_keys=False))


# --- fixed-topology network ---------------------------------------------------------------


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
    out = Path(out)
    ckpt = out / "checkpoint.json"
    _start(out, config, resume, ckpt.name)
    key = "fixed-" + config.run_key()
    if resume:
        try:
            data = json.loads(ckpt.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise CheckpointError(str(ckpt), "does not exist; nothing to resume") from None
        except ValueError as exc:
            raise CheckpointError(str(ckpt), f"is corrupt ({exc})") from None
        if data.get("run_key") != key:
            raise CheckpointError(str(ckpt), "was written by a run with a different configuration")
        topology = FixedTopology(tuple(data["hidden"]))
        population = [FixedNetwork.from_dict(d) for d in data["population"]]
        rng = np.random.Generator(np.random.PCG64())
        rng.bit_generator.state = data["rng_state"]
        g, history, evaluations = data["generation"], data["history"], data["evaluations"]
        best_fit = data["best_fitness"]
    else:
        rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence([config.seed, 0xF1])))
        topology = FixedTopology.random(rng, config.neurons)
        population = [random_network(rng, topology) for _ in range(config.population)]
        g, history, evaluations, best_fit = 0, [], 0, -1.0
    title = (
        f"fixed network {topology.layers}, P={config.population}, "
        f"S={config.scenarios}, T={config.steps}"
    )
    blueprints = blueprints_of(config)
    done = 0
    with ProgramEvaluator(workers, ray_address) as evaluator:
        while g < config.generations:
            t0 = time.perf_counter()
            programs = [compile_fixed(topology, p) for p in population]
            fit = evaluator.evaluate(programs, scenario_sets(config, g, blueprints))
            evaluations += len(population) * config.scenarios
            i = int(np.argmax(fit))
            if fit[i] > best_fit:
                best_fit = float(fit[i])
                meta = {"kind": "fixed", "fitness": best_fit, "generation": g}
                meta.update(hidden=list(topology.hidden), seed=config.seed)
                write_text_atomic(out / "best.json", json.dumps(program_to_dict(programs[i], meta)))
            neurons = [topology.n_neurons] * len(population)
            history.append(_row(g, evaluations, fit, best_fit, neurons, t0))
            population = next_generation(rng, population, fit, config.ga, topology)
            g += 1
            done += 1
            if progress is not None:
                progress(history[-1])
            stopping = stop_after is not None and done >= stop_after
            if g == config.generations or stopping or g % config.checkpoint_every == 0:
                _write_outputs(out, history, title)
                state = {
                    "format": "fixed-checkpoint/1",
                    "run_key": key,
                    "hidden": list(topology.hidden),
                    "generation": g,
                    "rng_state": rng.bit_generator.state,
                    "evaluations": evaluations,
                    "best_fitness": best_fit,
                    "history": history,
                    "population": [p.to_dict() for p in population],
                }
                write_text_atomic(ckpt, json.dumps(state))
            if stopping:
                break
    return history


# --- NEAT ---------------------------------------------------------------------------------


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

    Population size, generations, scenarios and seed come from ``config``; the GA
    operators are NEAT's own (``neat.ini`` in ``out`` holds them).

    Raises:
        CheckpointError: As :func:`ant_evolution.evolve.run_evolution`.
    """
    import neat

    out = Path(out)
    ckpt = out / "neat-checkpoint.gz"
    side = out / "neat-state.json"
    _start(out, config, resume, ckpt.name)
    key = "neat-" + config.run_key()
    cfg = neat_config(out / "neat.ini", config.population, neat_hidden(config.seed, config.neurons))
    if resume:
        if not ckpt.exists() or not side.exists():
            raise CheckpointError(str(ckpt), "does not exist; nothing to resume")
        data = json.loads(side.read_text(encoding="utf-8"))
        if data.get("run_key") != key:
            raise CheckpointError(str(side), "was written by a run with a different configuration")
        # the pickled config carries neat-python's node indexer: a fresh config would
        # restart it and hand out node keys that genomes already use
        pop = neat.Checkpointer.restore_checkpoint(str(ckpt))
        if pop.generation != data["generation"]:
            raise CheckpointError(str(side), "does not match neat-checkpoint.gz")
        history, evaluations, best_fit = data["history"], data["evaluations"], data["best_fitness"]
    else:
        pop = neat.Population(cfg, seed=config.seed)
        history, evaluations, best_fit = [], 0, -1.0
    title = f"NEAT, P={config.population}, S={config.scenarios}, T={config.steps}"
    blueprints = blueprints_of(config)
    saver = neat.Checkpointer(None, filename_prefix=str(out / ".tmp-neat-"))
    done = 0
    with ProgramEvaluator(workers, ray_address) as evaluator:

        def fitness_function(genomes, neat_cfg) -> None:
            nonlocal evaluations, best_fit
            t0 = time.perf_counter()
            g = pop.generation
            fit = evaluator.evaluate(
                [genome for _, genome in genomes],
                scenario_sets(config, g, blueprints),
                functools.partial(compile_neat, config=neat_cfg),
            )
            for (_, genome), f in zip(genomes, fit, strict=True):
                genome.fitness = float(f)
            evaluations += len(genomes) * config.scenarios
            i = int(np.argmax(fit))
            if fit[i] > best_fit:
                best_fit = float(fit[i])
                meta = {"kind": "neat", "fitness": best_fit, "generation": g, "seed": config.seed}
                best = compile_neat(genomes[i][1], neat_cfg)
                write_text_atomic(out / "best.json", json.dumps(program_to_dict(best, meta)))
            neurons = [len(genome.nodes) for _, genome in genomes]
            history.append(_row(g, evaluations, fit, best_fit, neurons, t0))

        while pop.generation < config.generations:
            pop.run(fitness_function, 1)
            done += 1
            if progress is not None:
                progress(history[-1])
            g = pop.generation
            stopping = stop_after is not None and done >= stop_after
            if g == config.generations or stopping or g % config.checkpoint_every == 0:
                _write_outputs(out, history, title)
                with contextlib.redirect_stdout(io.StringIO()):
                    saver.save_checkpoint(pop.config, pop.population, pop.species, g)
                os.replace(out / f".tmp-neat-{g}", ckpt)
                state = {
                    "run_key": key,
                    "generation": g,
                    "evaluations": evaluations,
                    "best_fitness": best_fit,
                    "history": history,
                }
                write_text_atomic(side, json.dumps(state))
            if stopping:
                break
    return history
