"""Seeded evaluation of a controller on excavation scenarios (paper, section 4.3).

A *scenario* is one episode: the blueprint, a flat terrain, ``n_robots`` placed at random
and ``steps`` timesteps. Its score is the paper's fitness of the terrain at the end. A
controller's fitness is the mean over scenarios. Scenario ``i`` of seed ``K`` draws all
its randomness (placements, random turns) from ``SeedSequence(K).spawn(S)[i]``, so the
same seed gives the same result bit for bit.

The whole episode (sensing, controller, world step) runs inside one numba kernel,
:func:`run_episode`; Python only sets scenarios up.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numba as nb
import numpy as np

from ant_controller.genome import Genome, TissueGene
from ant_controller.genome_io import load_genome
from ant_controller.hand_coded import hand_coded_decide
from ant_controller.layout import N_SENSORS
from ant_controller.tissue import CompiledTissue, compile_tissue, decide
from blueprint_server.blueprint import Blueprint
from excavation_sim.world import DEFAULT_PARAMS, World, WorldParams, apply_all, fitness, sense_all

KIND_ANT = 0
KIND_HAND_CODED = 1

DEFAULT_STEPS = 300
"""Timesteps per scenario. Long enough for the hand-coded controller's fitness to level
off on the default blueprint with four robots (see docs/world-model.md)."""
DEFAULT_ROBOTS = 4


@dataclass(frozen=True)
class Controller:
    """What decides a robot's behaviours: a compiled ANT tissue or the hand-coded rules.

    Attributes:
        kind: ``KIND_ANT`` or ``KIND_HAND_CODED``.
        tissue: The compiled tissue (an empty one for the hand-coded controller).
        name: Label for reports.
        robots: The genome's N gene, if it has one.
    """

    kind: int
    tissue: CompiledTissue
    name: str
    robots: int | None = None

    @classmethod
    def from_genome(cls, genome: Genome, name: str = "genome") -> Controller:
        """Compile a genome once into a controller."""
        return cls(KIND_ANT, compile_tissue(genome), name, genome.tissue.robots)

    @classmethod
    def from_file(cls, path: str | Path) -> Controller:
        """Load, validate and compile a genome file."""
        return cls.from_genome(load_genome(path), name=str(path))

    @classmethod
    def hand_coded(cls) -> Controller:
        """The appendix's hand-coded controller."""
        return cls(KIND_HAND_CODED, _EMPTY_TISSUE, "hand-coded")

    def decide(self, codes: np.ndarray) -> int:
        """Behaviour mask for one sensor vector."""
        c = np.asarray(codes, dtype=np.int64)
        if self.kind == KIND_HAND_CODED:
            return int(hand_coded_decide(c))
        return int(decide(c, self.tissue.arrays()))


_EMPTY_TISSUE = compile_tissue(Genome(tissue=TissueGene(), cells=()))


@nb.njit(cache=True)
def run_episode(
    heights,
    zones,
    goal,
    robots,
    active,
    rng,
    params,
    steps,
    kind,
    tissue,
    trace,
):
    """Run ``steps`` timesteps in place; ``trace[t]`` gets the fitness after step t.

    ``trace`` may be empty (length 0) when the curve is not wanted.
    """
    n = robots.shape[0]
    codes = np.zeros((n, N_SENSORS), dtype=np.int64)
    masks = np.zeros(n, dtype=np.int64)
    for t in range(steps):
        sense_all(heights, zones, goal, robots, active, codes)
        for k in range(n):
            if not active[k]:
                masks[k] = 0
            elif kind == KIND_HAND_CODED:
                masks[k] = hand_coded_decide(codes[k])
            else:
                masks[k] = decide(codes[k], tissue)
        apply_all(heights, robots, active, masks, rng, params)
        if trace.shape[0] > t:
            trace[t] = fitness(heights, zones, goal)


def advance(world: World, controller: Controller, steps: int, trace: np.ndarray | None = None):
    """Step ``world`` in place ``steps`` times under ``controller``."""
    run_episode(
        world.heights,
        world.zones,
        world.goal,
        world.robots,
        world.active,
        world.rng,
        world.params,
        steps,
        controller.kind,
        controller.tissue.arrays(),
        np.zeros(0) if trace is None else trace,
    )


def scenario_worlds(
    blueprint: Blueprint,
    n_robots: int,
    scenarios: int,
    seed: int,
    params: WorldParams = DEFAULT_PARAMS,
) -> list[World]:
    """The ``scenarios`` starting worlds of a seed (same seed, same worlds)."""
    children = np.random.SeedSequence(seed).spawn(scenarios)
    return [
        World.create(blueprint.zones, blueprint.goal, n_robots, np.random.default_rng(s), params)
        for s in children
    ]


@dataclass(frozen=True)
class Evaluation:
    """Scores of one controller over a set of scenarios.

    Attributes:
        scores: Final fitness per scenario.
        curves: ``[scenarios, steps + 1]`` fitness after each step (column 0: start).
    """

    scores: np.ndarray
    curves: np.ndarray

    @property
    def mean(self) -> float:
        """Mean fitness (the controller's fitness)."""
        return float(self.scores.mean())

    def summary(self) -> dict:
        """Mean, std, min and max over scenarios."""
        s = self.scores
        return {
            "mean": float(s.mean()),
            "std": float(s.std()),
            "min": float(s.min()),
            "max": float(s.max()),
        }


def evaluate(
    controller: Controller,
    blueprint: Blueprint,
    n_robots: int = DEFAULT_ROBOTS,
    scenarios: int = 100,
    steps: int = DEFAULT_STEPS,
    seed: int = 0,
    params: WorldParams = DEFAULT_PARAMS,
) -> Evaluation:
    """Run ``controller`` on ``scenarios`` seeded scenarios and collect fitness.

    Raises:
        ValueError: When a count is not positive.
        excavation_sim.world.PlacementError: When the robots do not fit the grid.
    """
    for name, v in (("n_robots", n_robots), ("scenarios", scenarios), ("steps", steps)):
        if v < 1:
            raise ValueError(f"{name} must be at least 1, got {v}")
    worlds = scenario_worlds(blueprint, n_robots, scenarios, seed, params)
    curves = np.zeros((scenarios, steps + 1))
    for i, w in enumerate(worlds):
        curves[i, 0] = w.fitness()
        advance(w, controller, steps, curves[i, 1:])
    return Evaluation(curves[:, -1].copy(), curves)
