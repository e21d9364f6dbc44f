"""Seeded evaluation of a controller on excavation scenarios (paper, section 4.3).

A *scenario* is one episode: the blueprint, a flat terrain, robots placed at random and
``steps`` timesteps. Its score is the paper's fitness of the terrain at the end. A
controller's fitness is the mean over scenarios.

A :class:`ScenarioSet` holds the starting state of every scenario of a seed as stacked
arrays. Scenario ``i`` of seed ``K`` draws all its randomness (placements, random turns)
from ``SeedSequence(K).spawn(S)[i]``, so the same seed gives the same result bit for bit.
Robot counts may differ between scenarios (``robots=[1, 4]`` alternates them); every
scenario places ``max(robots)`` robots and switches off the ones it does not use, so a
genome whose N gene asks for fewer robots uses the first N of the same placements (common
random numbers).

Whole episodes run inside numba (:func:`run_scenarios`): sensing, the controller (through a
per-tissue decision cache) and the world step, with no Python in the per-step path.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numba as nb
import numpy as np

from ant_controller.controller import KIND_HAND_CODED, Controller
from ant_controller.hand_coded import hand_coded_decide
from ant_controller.layout import N_SENSORS
from ant_controller.tissue import CACHE_BITS, decide_cached, new_cache, new_scratch
from blueprint_server.blueprint import Blueprint
from excavation_sim.world import (
    DEFAULT_PARAMS,
    World,
    WorldParams,
    apply_all,
    fitness,
    scenario_start,
    sense_all,
)

DEFAULT_STEPS = 300
"""Timesteps per scenario. Long enough for the hand-coded controller's fitness to level
off on the default blueprint with four robots (see docs/world-model.md)."""
DEFAULT_ROBOTS = 4


@nb.njit(cache=True, _nrt=False, error_model="numpy")
def _run_steps(
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
    cache,
    scratch,
    codes,
    masks,
    trace,
):
    """The per-step loop, compiled without numba's reference counting (``_nrt=False``).

    It allocates nothing; with reference counting on, every call that passes arrays costs
    tens of nanoseconds in reference-count traffic even when its branch is not taken. The
    numpy error model drops Python's division checks (every division here is guarded).
    Both measured in docs/benchmarks.md.
    """
    n = robots.shape[0]
    cache_keys, cache_masks = cache
    for t in range(steps):
        sense_all(heights, zones, goal, robots, active, codes)
        for k in range(n):
            if not active[k]:
                masks[k] = 0
            elif kind == KIND_HAND_CODED:
                masks[k] = hand_coded_decide(codes[k])
            else:
                masks[k] = decide_cached(codes[k], tissue, cache_keys, cache_masks, scratch)
        apply_all(heights, robots, active, masks, rng, params)
        if trace.shape[0] > t:
            trace[t] = fitness(heights, zones, goal)


@nb.njit(cache=True)
def run_episode(
    heights, zones, goal, robots, active, rng, params, steps, kind, tissue, cache, trace
):
    """Run ``steps`` timesteps in place; ``trace[t]`` gets the fitness after step t.

    ``cache`` is a ``(keys, masks)`` decision cache of this tissue (:func:`new_cache`);
    ``trace`` may be empty (length 0) when the curve is not wanted.
    """
    n = robots.shape[0]
    codes = np.zeros((n, N_SENSORS), dtype=np.int64)
    masks = np.zeros(n, dtype=np.int64)
    _run_steps(
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
        cache,
        new_scratch(tissue),
        codes,
        masks,
        trace,
    )


@nb.njit(cache=True)
def run_scenarios(
    heights0, zones, goal, robots0, active0, rng0, params, steps, kind, tissue, n_robots, scores
):
    """Score one controller on every scenario of a set; ``scores[s]`` gets the final fitness.

    ``n_robots`` > 0 switches off robots ``n_robots ..`` in every scenario (the N gene);
    0 keeps each scenario's own robot count. One decision cache serves all scenarios.
    """
    cache = (
        np.full(1 << CACHE_BITS, -1, dtype=np.int64),
        np.zeros(1 << CACHE_BITS, dtype=np.int64),
    )
    scratch = new_scratch(tissue)
    n = robots0.shape[1]
    codes = np.zeros((n, N_SENSORS), dtype=np.int64)
    masks = np.zeros(n, dtype=np.int64)
    no_trace = np.zeros(0)
    heights = np.empty_like(heights0[0])
    robots = np.empty_like(robots0[0])
    active = np.empty_like(active0[0])
    rng = np.empty(1, dtype=np.uint64)
    for s in range(heights0.shape[0]):
        heights[:] = heights0[s]
        robots[:] = robots0[s]
        active[:] = active0[s]
        if n_robots > 0:
            for k in range(n):
                active[k] = k < n_robots
        rng[0] = rng0[s]
        _run_steps(
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
            cache,
            scratch,
            codes,
            masks,
            no_trace,
        )
        scores[s] = fitness(heights, zones, goal)


@dataclass(frozen=True)
class ScenarioSet:
    """Starting states of ``S`` scenarios on one blueprint, stacked for the kernels.

    Attributes:
        heights: ``int32 [S, rows, cols]`` starting terrain.
        zones: ``uint8 [rows, cols]`` blueprint zones.
        goal: ``int32 [rows, cols]`` goal heights.
        robots: ``int64 [S, N_max, 6]`` robot states.
        active: ``bool [S, N_max]`` robots taking part.
        rng: ``uint64 [S]`` random-turn generator states.
        params: Packed world parameters.
        steps: Timesteps per scenario.
        seed: The seed the scenarios were drawn from (scenario i: ``scenario_start(..., seed, i)``).
        robot_counts: The robot counts scenarios alternate between.
    """

    heights: np.ndarray
    zones: np.ndarray
    goal: np.ndarray
    robots: np.ndarray
    active: np.ndarray
    rng: np.ndarray
    params: np.ndarray
    steps: int
    seed: int = 0
    robot_counts: tuple[int, ...] = ()

    @classmethod
    def create(
        cls,
        blueprint: Blueprint,
        robots: int | Sequence[int],
        scenarios: int,
        steps: int,
        seed: int,
        params: WorldParams = DEFAULT_PARAMS,
    ) -> ScenarioSet:
        """The scenarios of ``seed``; ``robots`` may list counts to alternate between.

        Raises:
            ValueError: When a count is not positive.
            excavation_sim.world.PlacementError: When the robots do not fit the grid.
        """
        counts = [robots] if isinstance(robots, int) else list(robots)
        for name, v in (
            ("robots", min(counts, default=0)),
            ("scenarios", scenarios),
            ("steps", steps),
        ):
            if v < 1:
                raise ValueError(f"{name} must be at least 1, got {v}")
        n_max = max(counts)
        shape = blueprint.shape
        all_robots = np.zeros((scenarios, n_max, 6), dtype=np.int64)
        active = np.zeros((scenarios, n_max), dtype=np.bool_)
        rng_states = np.zeros(scenarios, dtype=np.uint64)
        for i in range(scenarios):
            all_robots[i], active[i], rng_states[i] = scenario_start(
                shape, n_max, counts[i % len(counts)], seed, i
            )
        return cls(
            heights=np.zeros((scenarios, *shape), dtype=np.int32),
            zones=blueprint.zones,
            goal=blueprint.goal,
            robots=all_robots,
            active=active,
            rng=rng_states,
            params=params.as_array(),
            steps=steps,
            seed=seed,
            robot_counts=tuple(counts),
        )

    @property
    def size(self) -> int:
        """Number of scenarios."""
        return int(self.heights.shape[0])

    def world(self, i: int) -> World:
        """Scenario ``i`` as a :class:`World` ready to step (a copy)."""
        return World(
            heights=self.heights[i].copy(),
            zones=self.zones,
            goal=self.goal,
            robots=self.robots[i].copy(),
            active=self.active[i].copy(),
            rng=self.rng[i : i + 1].copy(),
            params=self.params,
        )

    def score(self, controller: Controller, n_robots: int = 0) -> np.ndarray:
        """Final fitness of ``controller`` on every scenario (``n_robots``: the N gene)."""
        scores = np.zeros(self.size)
        run_scenarios(
            self.heights,
            self.zones,
            self.goal,
            self.robots,
            self.active,
            self.rng,
            self.params,
            self.steps,
            controller.kind,
            controller.tissue.arrays(),
            n_robots,
            scores,
        )
        return scores


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
        new_cache(),
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
    batch = ScenarioSet.create(blueprint, n_robots, scenarios, 1, seed, params)
    return [batch.world(i) for i in range(scenarios)]


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
    """Run ``controller`` on ``scenarios`` seeded scenarios and collect fitness curves.

    Raises:
        ValueError: When a count is not positive.
        excavation_sim.world.PlacementError: When the robots do not fit the grid.
    """
    batch = ScenarioSet.create(blueprint, n_robots, scenarios, steps, seed, params)
    curves = np.zeros((scenarios, steps + 1))
    for i in range(scenarios):
        w = batch.world(i)
        curves[i, 0] = w.fitness()
        advance(w, controller, steps, curves[i, 1:])
    return Evaluation(curves[:, -1].copy(), curves)
