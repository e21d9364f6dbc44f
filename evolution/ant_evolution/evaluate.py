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

Whole episodes run inside the one episode kernel (:mod:`ant_evolution.kernel`): sensing,
the decision program (an ANT tissue, the hand-coded rules or a network program, through a
per-program decision cache) and the world step, with no Python in the per-step path.
:func:`program_fitness` is the one evaluation function every backend runs.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ant_evolution import randomise
from ant_evolution.kernel import (
    DecisionProgram,
    run_episode,
    run_physical_episode,
    run_physical_scenarios,
    run_scenarios,
)
from blueprint_server.blueprint import Blueprint
from excavation_sim import cell_soil
from excavation_sim.rules import DEFAULT_RULES, WorldRules
from excavation_sim.soil import SoilParams
from excavation_sim.world import World, WorldArrays, placement_zones, scenario_start

DEFAULT_STEPS = 300
"""Timesteps per scenario. Long enough for the hand-coded controller's fitness to level
off on the default blueprint with four robots (see docs/world-model.md)."""
DEFAULT_ROBOTS = 4


@dataclass(frozen=True)
class ScenarioSet:
    """Starting states of ``S`` scenarios on one blueprint, stacked for the kernels.

    Attributes:
        start: The scenarios' starting worlds, stacked
            (:class:`~excavation_sim.world.WorldArrays`: ``heights [S, rows, cols]``, shared
            ``zones`` and ``goal``, ``robots [S, N_max, 6]``, ``active [S, N_max]``, ``rng
            [S]``); its ``params [S, N_PACKED]`` are each scenario's packed rules:
            ``params`` in every row, or each randomised scenario's draw
            (:mod:`ant_evolution.randomise`).
        params: Packed world rules (:meth:`~excavation_sim.rules.WorldRules.as_array`).
        steps: Timesteps per scenario.
        seed: The seed the scenarios were drawn from (scenario i: ``scenario_start(..., seed, i)``).
        robot_counts: The robot counts scenarios alternate between.
        soil: ``grid`` (the world model's soil rules) or a physical soil
            (``physical[:PRESET][,KEY=VALUE...]``, :mod:`excavation_sim.cell_soil`).
        physics: ``float64 [S, N_PHYSICS]`` each scenario's physical soil constants (no
            rows for ``grid``).
        randomised: Each scenario draws its world (:mod:`ant_evolution.randomise`).
        start_fitness, reference: ``float64 [S]``, set by :meth:`with_reference` (else
            empty): each scenario's fitness at the start and a reference program's at the
            end, the units of the combined fitness ``progress``.
        floor: The mean fitness a program must keep on this set's soil (the combined
            fitness ``floor``); ``None``: the soil is scored, not held.
    """

    start: WorldArrays
    params: np.ndarray
    steps: int
    seed: int = 0
    robot_counts: tuple[int, ...] = ()
    soil: str = "grid"
    physics: np.ndarray = field(default_factory=lambda: np.zeros((0, cell_soil.N_PHYSICS)))
    randomised: bool = False
    start_fitness: np.ndarray = field(default_factory=lambda: np.zeros(0))
    reference: np.ndarray = field(default_factory=lambda: np.zeros(0))
    floor: float | None = None

    @classmethod
    def create(
        cls,
        blueprint: Blueprint,
        robots: int | Sequence[int],
        scenarios: int,
        steps: int,
        seed: int,
        rules: WorldRules = DEFAULT_RULES,
        soil: str = "grid",
        randomised: bool = False,
    ) -> ScenarioSet:
        """The scenarios of ``seed``; ``robots`` may list counts to alternate between.

        ``rules``: the world's readings (kernel switches, and where robots start).
        ``soil``: ``grid``, or a physical soil on the blueprint's cell size and height unit
        (its ``grid`` preset calibrated to ``rules``' push capacities).
        ``randomised``: each scenario draws its rules, sensor noise and soil around these
        (:mod:`ant_evolution.randomise`; the starts are the unrandomised ones).

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
        worksite = placement_zones(rules, blueprint.zones)
        for i in range(scenarios):
            all_robots[i], active[i], rng_states[i] = scenario_start(
                shape, n_max, counts[i % len(counts)], seed, i, worksite
            )
        base = physics_of(soil, blueprint, rules)
        no_soil = np.zeros((0, cell_soil.N_PHYSICS))
        if randomised:
            draws = [randomise.draw(rules, seed, i) for i in range(scenarios)]
            scenario_params = np.stack([randomise.packed(d) for d in draws])
            physics = (
                np.stack([_drawn_physics(soil, blueprint, rules, d) for d in draws])
                if base.size
                else no_soil
            )
        else:
            scenario_params = np.tile(rules.as_array(), (scenarios, 1))
            physics = np.tile(base, (scenarios, 1)) if base.size else no_soil
        start = WorldArrays(
            heights=np.zeros((scenarios, *shape), dtype=np.int32),
            zones=blueprint.zones,
            goal=blueprint.goal,
            robots=all_robots,
            active=active,
            rng=rng_states,
            params=scenario_params,
        )
        return cls(
            start=start,
            params=rules.as_array(),
            steps=steps,
            seed=seed,
            robot_counts=tuple(counts),
            soil=soil,
            physics=physics,
            randomised=randomised,
        )

    @property
    def physical(self) -> bool:
        """Whether the scenarios run on the physical soil."""
        return self.physics.shape[0] > 0

    @property
    def size(self) -> int:
        """Number of scenarios."""
        return int(self.start.heights.shape[0])

    def world(self, i: int) -> World:
        """Scenario ``i`` as a :class:`World` ready to step (a copy)."""
        return World(
            heights=self.start.heights[i].copy(),
            zones=self.start.zones,
            goal=self.start.goal,
            robots=self.start.robots[i].copy(),
            active=self.start.active[i].copy(),
            rng=self.start.rng[i : i + 1].copy(),
            params=_read_only(self.start.params[i]),
        )

    def arrays(self) -> WorldArrays:
        """The starting states as the kernel takes them: read-only views, always.

        numba compiles a kernel once per argument type, and a read-only array is another
        type: sets made here, unpickled in a pool worker or read from Ray's object store
        differ in which arrays are writable, and each kind would compile the kernel again
        (about a minute per decision program). The kernel only reads them.
        """
        return WorldArrays(*(_read_only(a) for a in self.start))

    def score(self, program: DecisionProgram, n_robots: int = 0) -> np.ndarray:
        """Final fitness of ``program`` on every scenario (``n_robots``: the N gene, 0: none)."""
        return self.run(program, n_robots)[0]

    def run(self, program: DecisionProgram, n_robots: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """``(scores, counters)``: the final fitness on every scenario, and its counters.

        The counters (``int64 [S, 4]``, :mod:`excavation_sim.cell_soil`): on the physical
        soil each scenario's moves, refusals, stalls and quanta cut; zeros on the grid.
        """
        scores = np.zeros(self.size)
        counters = np.zeros((self.size, cell_soil.N_COUNTERS), dtype=np.int64)
        if self.physical:
            run_physical_scenarios(
                self.arrays(), _read_only(self.physics), self.steps, program.record(),
                n_robots, scores, counters,
            )  # fmt: skip
        else:
            run_scenarios(self.arrays(), self.steps, program.record(), n_robots, scores)
        return scores, counters

    def with_reference(self, program: DecisionProgram) -> ScenarioSet:
        """This set with each scenario's start fitness and ``program``'s final fitness."""
        start = np.zeros(self.size)
        for i in range(self.size):
            world = self.world(i)
            soil = self.soil_of(world, i)
            start[i] = (
                world.fitness()
                if soil is None
                else cell_soil.soil_fitness(soil, world.heights, world.zones, world.goal)
            )
        return dataclasses.replace(
            self, start_fitness=start, reference=self.score(program, program.robots or 0)
        )

    def soil_of(self, world: World, i: int = 0) -> cell_soil.SoilArrays | None:
        """The physical soil of ``world`` (scenario ``i``) as it starts (None on the grid).

        It also rounds ``world.heights`` to the settled soil's cells (as ``dynamics``
        starts); step both with :func:`advance`.
        """
        if not self.physical:
            return None
        soil = cell_soil.new_soil(world.heights.shape, world.n_robots, self.physics[i].copy())
        cell_soil.reset(soil, world.heights, world.robots, world.active)
        return soil


def _drawn_physics(
    soil: str, blueprint: Blueprint, rules: WorldRules, draw: randomise.Draw
) -> np.ndarray:
    """A randomised scenario's physical soil constants (its soil factors and push)."""
    out = physics_of(randomise.soil_spec(soil, draw), blueprint, rules)
    randomise.scale_push(out, draw.push)
    return out


def physics_of(soil: str, blueprint: Blueprint, rules: WorldRules) -> np.ndarray:
    """The physical soil's constants for ``blueprint`` (empty for ``soil: grid``).

    Raises:
        excavation_sim.soil.SoilError: When ``soil`` names no soil or bad parameters.
    """
    params = SoilParams(soil=soil)
    if not params.physical:
        return np.zeros(0)
    return cell_soil.physics_vector(
        params,
        float(blueprint.cell_size),
        float(blueprint.height_unit),
        (int(rules.normal_load), int(rules.throttle_load)),
    )


def _read_only(array: np.ndarray) -> np.ndarray:
    """A read-only view of ``array`` (the array itself is left as it is)."""
    view = array.view()
    view.flags.writeable = False
    return view


MIN_REFERENCE_GAIN = 0.01
"""Smallest reference gain the ``progress`` fitness divides by (a reference that moves no
soil on a soil would otherwise make any gain there infinite)."""


def program_fitness(program: DecisionProgram, sets: Sequence[ScenarioSet]) -> float:
    """A program's fitness: the mean final fitness over every scenario of every set.

    A program with an N gene (``program.robots``) uses that many robots of each scenario.
    Sets on more than one soil (a run with ``also_soil``) give the **combined fitness**: the
    mean over each soil's scenarios, then the lowest of those means. Sets that carry a
    reference (:meth:`ScenarioSet.with_reference`, a run with ``combine: progress``) give
    each soil's **progress** instead, its mean gain over the start in units of the
    reference's mean gain (at least :data:`MIN_REFERENCE_GAIN`), then the lowest: the soils
    weigh alike however much soil each lets a robot move. A soil whose sets carry a
    ``floor`` (a run with ``combine: floor``) is held, not scored: while its mean is at
    least the floor the fitness is the other soils', below it the (negative) shortfall, so
    every program that keeps the floor ranks above every program that does not.
    """
    n_robots = program.robots or 0
    by_soil: dict[str, list[tuple[np.ndarray, ScenarioSet]]] = {}
    for s in sets:
        by_soil.setdefault(s.soil, []).append((s.score(program, n_robots), s))
    values = []
    shortfall = 0.0
    for pairs in by_soil.values():
        mean = float(np.concatenate([scores for scores, _ in pairs]).mean())
        floor = pairs[0][1].floor
        if floor is not None:
            shortfall = min(shortfall, mean - floor)
            continue
        if all(s.reference.size for _, s in pairs):
            start = float(np.concatenate([s.start_fitness for _, s in pairs]).mean())
            ref = float(np.concatenate([s.reference for _, s in pairs]).mean())
            mean = (mean - start) / max(ref - start, MIN_REFERENCE_GAIN)
        values.append(mean)
    return shortfall if shortfall < 0 else min(values)


def advance(
    world: World,
    program: DecisionProgram,
    steps: int,
    trace: np.ndarray | None = None,
    soil: cell_soil.SoilArrays | None = None,
) -> None:
    """Step ``world`` in place ``steps`` times under ``program``.

    ``soil``: the world's physical soil (:meth:`ScenarioSet.soil_of`), stepped with it;
    ``None``: the grid's soil rules.
    """
    trace = np.zeros(0) if trace is None else trace
    if soil is None:
        run_episode(world.arrays(), steps, program.record(), trace)
    else:
        run_physical_episode(world.arrays(), soil, steps, program.record(), trace)


def scenario_worlds(
    blueprint: Blueprint,
    n_robots: int,
    scenarios: int,
    seed: int,
    rules: WorldRules = DEFAULT_RULES,
) -> list[World]:
    """The ``scenarios`` starting worlds of a seed (same seed, same worlds)."""
    batch = ScenarioSet.create(blueprint, n_robots, scenarios, 1, seed, rules)
    return [batch.world(i) for i in range(scenarios)]


@dataclass(frozen=True)
class Evaluation:
    """Scores of one controller over a set of scenarios.

    Attributes:
        scores: Final fitness per scenario.
        curves: ``[scenarios, steps + 1]`` fitness after each step (column 0: start).
        counters: On the physical soil, ``int64 [scenarios, 4]``: moves, refusals,
            stalls and quanta cut (:mod:`excavation_sim.cell_soil`); ``None`` on the grid.
    """

    scores: np.ndarray
    curves: np.ndarray
    counters: np.ndarray | None = None

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
    controller: DecisionProgram,
    blueprint: Blueprint,
    n_robots: int = DEFAULT_ROBOTS,
    scenarios: int = 100,
    steps: int = DEFAULT_STEPS,
    seed: int = 0,
    rules: WorldRules = DEFAULT_RULES,
    soil: str = "grid",
    randomised: bool = False,
) -> Evaluation:
    """Run ``controller`` on ``scenarios`` seeded scenarios and collect fitness curves.

    ``soil``: ``grid`` or a physical soil; ``randomised``: each scenario draws its world
    (:meth:`ScenarioSet.create`).

    Raises:
        ValueError: When a count is not positive.
        excavation_sim.world.PlacementError: When the robots do not fit the grid.
    """
    batch = ScenarioSet.create(blueprint, n_robots, scenarios, steps, seed, rules, soil, randomised)
    curves = np.zeros((scenarios, steps + 1))
    counters = np.zeros((scenarios, cell_soil.N_COUNTERS), dtype=np.int64)
    for i in range(scenarios):
        w = batch.world(i)
        soil = batch.soil_of(w, i)
        if soil is None:
            curves[i, 0] = w.fitness()
        else:
            curves[i, 0] = cell_soil.soil_fitness(soil, w.heights, w.zones, w.goal)
        advance(w, controller, steps, curves[i, 1:], soil)
        if soil is not None:
            counters[i] = soil.counters
    return Evaluation(curves[:, -1].copy(), curves, counters if batch.physical else None)
