"""Evaluate genomes by trials through the ROS topics (``ant-evolve --evaluator ros``).

The batched evaluator (:mod:`ant_evolution.backends`) steps the world model in a compiled
loop; this one runs each scenario as a trial of the node suite, through the same topics a
field system uses, so a genome can be validated or fine-tuned against any simulator that
speaks those interfaces. Several trials run at once, each in a ROS domain of its own
(``domain_base + slot``), so they cannot hear each other.

A trial is a command (by default ``python -m excavation_bringup.trial``, i.e. ``ant-trial``)
that prints one JSON object with a ``fitness`` key and exits 0. Another simulator plugs in
through ``trial_command``, a template with the fields ``{genome}``, ``{robots}``,
``{steps}``, ``{seed}``, ``{scenario}``, ``{blueprint}`` (a blueprint YAML file) and
``{domain}``. Scenario ``i`` of a set is the set's ``seed`` and index ``i``, as
:meth:`ant_evolution.evaluate.ScenarioSet.create` draws it, so for the same seeds the fitness
equals the batched evaluator's exactly (``tests/test_ros_evaluator.py``).

This module starts processes; it never imports rclpy (the trial runner does).
"""

from __future__ import annotations

import json
import os
import queue
import shlex
import subprocess
import sys
import tempfile
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from ant_controller.genome import Genome
from ant_controller.genome_io import save_genome
from ant_evolution.evaluate import ScenarioSet
from blueprint_server.blueprint import Blueprint

DEFAULT_TRIAL = (
    f"{shlex.quote(sys.executable)} -m excavation_bringup.trial --genome {{genome}} "
    "--robots {robots} --steps {steps} --seed {seed} --scenario {scenario} "
    "--blueprint {blueprint} --domain {domain} --command-timeout 60 --json"
)
"""The default trial: ``ant-trial`` with the suite's own simulator, composed in one process."""


class TrialError(RuntimeError):
    """A trial failed, or cannot stand for the batched evaluation it replaces."""


class RosEvaluator:
    """Scores populations by running trials through the topics.

    Args:
        workers: Trials at once (each in its own ROS domain; ``None``: all cores).
        domain_base: First ROS domain id; slot k uses ``domain_base + k``.
        trial_command: Command template (see the module docstring).
        timeout: Seconds one trial may take.
    """

    backend = "ros"

    def __init__(
        self,
        workers: int | None = None,
        domain_base: int = 50,
        trial_command: str = DEFAULT_TRIAL,
        timeout: float = 900.0,
    ) -> None:
        self.workers = workers if workers and workers > 0 else (os.cpu_count() or 1)
        if not 0 <= domain_base or domain_base + self.workers > 232:
            raise ValueError(
                f"domain_base = {domain_base}: domains {domain_base}..."
                f"{domain_base + self.workers - 1} must lie within 0..232"
            )
        self.trial_command = trial_command
        self.timeout = timeout
        self._domains: queue.Queue[int] = queue.Queue()
        for k in range(self.workers):
            self._domains.put(domain_base + k)
        self._pool = ThreadPoolExecutor(self.workers)

    def _run(self, fields: dict) -> float:
        domain = self._domains.get()
        try:
            cmd = shlex.split(self.trial_command.format(domain=domain, **fields))
            env = dict(
                os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST"
            )
            try:
                done = subprocess.run(
                    cmd, env=env, capture_output=True, text=True, timeout=self.timeout
                )
            except subprocess.TimeoutExpired as exc:
                raise TrialError(f"trial {fields} did not finish in {self.timeout} s") from exc
        finally:
            self._domains.put(domain)
        if done.returncode != 0:
            raise TrialError(
                f"trial {' '.join(cmd)} exited with {done.returncode}: "
                f"{done.stderr.strip()[-2000:]}"
            )
        try:
            result = json.loads(done.stdout.strip().splitlines()[-1])
            fitness = float(result["fitness"])
        except (IndexError, ValueError, KeyError, TypeError) as exc:
            raise TrialError(
                f"trial {' '.join(cmd)} printed no JSON with 'fitness': {done.stdout[-500:]!r}"
            ) from exc
        missed = result.get("missed", {})
        if any(missed.values()):
            raise TrialError(
                f"trial {' '.join(cmd)}: robots missed ticks {missed}; its fitness would not "
                "be the controller's (raise the trial's command timeout)"
            )
        return fitness

    def evaluate(
        self, genomes: list[Genome], sets: list[ScenarioSet], compile_fn: Callable | None = None
    ) -> np.ndarray:
        """Fitness of every genome (same order): the mean over every scenario of every set.

        The same call as :meth:`ant_evolution.backends.Evaluator.evaluate`; the trials run
        the genome files themselves, so ``compile_fn`` (ANT's compiler) is not used.

        Raises:
            TrialError: A trial failed, missed ticks, or the sets cannot be run as trials
                (robot counts that alternate, or a genome with an N gene).
        """
        for s in sets:
            if len(set(s.robot_counts)) != 1 or s.robot_counts[0] != s.start.robots.shape[1]:
                raise TrialError(
                    f"robot_counts = {s.robot_counts}: trials need one robot count per "
                    "scenario set (no --robots-mix or --evolve-robots with --evaluator ros)"
                )
        for g in genomes:
            if g.tissue.robots:
                raise TrialError(
                    f"genome N gene = {g.tissue.robots}: --evaluator ros runs a fixed team"
                )
        with tempfile.TemporaryDirectory(prefix="ant-ros-eval-") as tmp:
            blueprints = []
            for j, s in enumerate(sets):
                path = Path(tmp) / f"blueprint_{j}.yaml"
                path.write_text(
                    Blueprint(zones=s.start.zones, goal=s.start.goal, name=f"set {j}").to_yaml()
                )
                blueprints.append(str(path))
            jobs = []
            for i, g in enumerate(genomes):
                genome_file = Path(tmp) / f"genome_{i}.json"
                save_genome(g, genome_file)
                for j, s in enumerate(sets):
                    for k in range(s.size):
                        fields = dict(
                            genome=shlex.quote(str(genome_file)),
                            robots=s.robot_counts[0],
                            steps=s.steps,
                            seed=s.seed,
                            scenario=k,
                            blueprint=shlex.quote(blueprints[j]),
                        )
                        jobs.append((i, j, self._pool.submit(self._run, fields)))
            scores: dict[tuple[int, int], list[float]] = {}
            for i, j, future in jobs:
                scores.setdefault((i, j), []).append(future.result())
        return np.array(
            [
                float(np.concatenate([np.array(scores[i, j]) for j in range(len(sets))]).mean())
                for i in range(len(genomes))
            ]
        )

    def close(self) -> None:
        """Stop taking trials (running ones finish)."""
        self._pool.shutdown(wait=True)

    def __enter__(self) -> RosEvaluator:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
