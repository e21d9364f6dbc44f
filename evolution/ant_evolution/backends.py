"""The one evaluator: a population scored in this process, a local process pool, or Ray.

Every backend computes the same pure function per individual: compile it into a decision
program (``compile_fn``: an ANT genome into its tissue, a fixed network or a NEAT genome
into a network program; in the workers, in parallel), score it on every scenario set
(:func:`ant_evolution.evaluate.program_fitness`) and average. So fitness is identical for
any worker count and either backend; only the wall time differs. Individuals travel to
workers pickled and come back as floats.

* ``workers <= 1`` and no Ray address: in this process.
* ``workers > 1``: a ``ProcessPoolExecutor`` (spawned processes, each loads the numba
  cache once), kept for the whole run. The population is dealt into ``CHUNKS_PER_WORKER x
  workers`` interleaved chunks (individual i into chunk ``i mod chunks``), one task each,
  which idle workers take in turn: individuals cost very different amounts (a tissue
  whose robots come to rest ends its scenarios early, docs/benchmarks.md), and neither
  neighbours in the population nor one chunk per worker would share that out evenly.
* ``ray_address``: ``ray.init(address=...)`` (``"local"`` starts a Ray instance on this
  machine); chunks as above, the cluster's CPU count standing for ``workers``.

A ``compile_fn`` wrapped in :class:`CompileHere` runs in this process instead, and the
programs travel: for NEAT, whose genomes (about 1,600 gene objects each) take longer to
pickle and unpickle than to compile. Each chunk is sent as soon as it is compiled, so the
workers start on the first chunks while this process compiles the rest.
"""

from __future__ import annotations

import copy
import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context

import numpy as np

from ant_controller.controller import Controller
from ant_controller.genome import Genome
from ant_evolution.evaluate import ScenarioSet, program_fitness


def compile_genome(genome: Genome) -> Controller:
    """An ANT genome as a decision program (its compiled tissue and N gene)."""
    return Controller.from_genome(genome)


def genome_fitness(genome: Genome, sets: Sequence[ScenarioSet]) -> float:
    """Mean final fitness of one genome over every scenario of every set."""
    return program_fitness(compile_genome(genome), sets)


CHUNKS_PER_WORKER = 4
"""Tasks per worker and generation (see the module docstring)."""


class CompileHere:
    """A ``compile_fn`` to run in the evaluating process; the workers get the programs.

    Args:
        fn: The compile function (individual -> decision program).
    """

    def __init__(self, fn: Callable) -> None:
        self.fn = fn

    def __call__(self, item):
        """The decision program of ``item``."""
        return self.fn(item)


def _evaluate_parts(items: list, sets: Sequence[ScenarioSet], compile_fn) -> list[float]:
    if compile_fn is None:
        return [program_fitness(p, sets) for p in items]
    return [program_fitness(compile_fn(x), sets) for x in items]


def _chunks(items: list, n: int) -> list[list]:
    """``items`` dealt into ``n`` interleaved chunks (item i into chunk ``i mod n``)."""
    n = max(1, min(n, len(items)))
    return [items[i::n] for i in range(n)]


def _unchunk(results: list[list[float]]) -> np.ndarray:
    """Fitness in the items' order from the results of :func:`_chunks`' chunks."""
    n = len(results)
    out = np.empty(sum(len(r) for r in results))
    for i, r in enumerate(results):
        out[i::n] = r
    return out


def _writable_items(task: Callable, items, *args):
    """``task(items, *args)`` on a writable copy of ``items`` (a Ray worker's task).

    Ray hands a task the numpy arrays of its arguments read-only (zero-copy from its object
    store), and numba types a read-only array apart from a writable one: every kernel taking
    a program that came that way compiled once more in each Ray worker, for minutes on a
    cold cache, although the cache held the same kernel for writable arrays (the NEAT
    programs of ``CompileHere``). Only the individuals are copied (microseconds): the
    scenario sets' arrays are read-only by design, wherever they are.
    """
    return task(copy.deepcopy(items), *args)


def start_workers(workers: int, ray_address: str | None, task) -> tuple:
    """Start the workers of a backend: ``(pool, ray, remote task, worker count)``.

    ``ray_address``: a Ray instance (``"local"`` starts one here) with ``task`` as its remote
    function, one worker per cluster CPU; otherwise a spawned process pool when
    ``workers > 1``; otherwise nothing (evaluate in this process).
    """
    if ray_address:
        import ray

        if not ray.is_initialized():
            if ray_address == "local":
                ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
            else:
                ray.init(address=ray_address, log_to_driver=False)

        def on_ray(items, *args):
            return _writable_items(task, items, *args)

        remote = ray.remote(on_ray)
        return None, ray, remote, max(1, int(ray.cluster_resources().get("CPU", 1)))
    if workers > 1:
        return ProcessPoolExecutor(workers, mp_context=get_context("spawn")), None, None, workers
    return None, None, None, workers


class Evaluator:
    """Scores populations on fixed scenario sets with the chosen backend (every method's).

    Args:
        workers: Local processes (``None``: all cores; 1: this process).
        ray_address: Ray cluster address, ``"local"`` for a local Ray, or ``None``.
    """

    def __init__(self, workers: int | None = None, ray_address: str | None = None) -> None:
        self.workers = workers if workers and workers > 0 else (os.cpu_count() or 1)
        self.ray_address = ray_address
        self._pool, self._ray, self._remote, self.workers = start_workers(
            self.workers, ray_address, _evaluate_parts
        )

    @property
    def backend(self) -> str:
        """``"ray"``, ``"process-pool"`` or ``"in-process"``."""
        if self._ray is not None:
            return "ray"
        return "process-pool" if self._pool is not None else "in-process"

    def evaluate(
        self,
        items: Sequence,
        sets: Sequence[ScenarioSet],
        compile_fn: Callable | None = compile_genome,
    ) -> np.ndarray:
        """Fitness of every individual (same order).

        Args:
            items: The population: ANT genomes by default, or anything ``compile_fn`` turns
                into a decision program.
            sets: The scenario sets.
            compile_fn: Picklable function run in the workers on every item (in this
                process when it is a :class:`CompileHere`); ``None``: the items are
                decision programs already.
        """
        if self._ray is None and self._pool is None:
            return np.array(_evaluate_parts(list(items), sets, compile_fn))
        chunks = _chunks(list(items), self.workers * CHUNKS_PER_WORKER)
        here = isinstance(compile_fn, CompileHere)

        def payload(chunk: list) -> tuple[list, Callable | None]:
            # compiled here chunk by chunk: the workers start on the first chunks meanwhile
            return ([compile_fn(x) for x in chunk], None) if here else (chunk, compile_fn)

        if self._ray is not None:
            sets_ref = self._ray.put(list(sets))
            refs = []
            for c in chunks:
                part, fn = payload(c)
                refs.append(self._remote.remote(part, sets_ref, fn))
            results = self._ray.get(refs)
        else:
            futures = []
            for c in chunks:
                part, fn = payload(c)
                futures.append(self._pool.submit(_evaluate_parts, part, sets, fn))
            results = [f.result() for f in futures]
        return _unchunk(results)

    def close(self) -> None:
        """Stop the worker processes (Ray is left to its owner)."""
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

    def __enter__(self) -> Evaluator:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
