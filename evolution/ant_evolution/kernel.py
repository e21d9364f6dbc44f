"""The one episode kernel: sensing, a decision program and the world step in numba (4.3).

Every controller the project evaluates is a *decision program*: a record of plain arrays
that maps a sensor vector to a behaviour bit mask.

* :class:`ant_controller.tissue.TissueRecord`: an ANT tissue (with or without coarse
  coding), :func:`ant_controller.tissue.decide_into`;
* :class:`ant_controller.hand_coded.HandCodedRules`: the appendix's hand-coded controller,
  :func:`ant_controller.hand_coded.hand_coded_program` (either reading of the rules);
* :class:`ant_evolution.baselines.network.NetworkRecord`: a fixed-topology or NEAT network,
  :func:`ant_evolution.baselines.network.program_decide_into`.

:func:`decide_program` and :func:`program_scratch` dispatch on the record's type when
numba compiles the kernel (``numba.extending.overload``), so each kind gets its own
machine code with no run-time branch; in plain Python (``NUMBA_DISABLE_JIT=1``, the
benchmark's reference) the same names dispatch with ``isinstance``. A program's answer
depends on the sensor vector alone, so the kernel keeps a direct-mapped cache of earlier
answers per program (:func:`decide_cached`; the hand-coded rules are cheaper than a
lookup and skip it).

:func:`run_episode` steps one world (:class:`excavation_sim.world.WorldArrays`) and
:func:`run_scenarios` scores one program on every scenario of a set
(the same :class:`~excavation_sim.world.WorldArrays`, stacked); both run the same per-step
loop, one timestep being

1. every active robot senses the same snapshot (:func:`excavation_sim.world.sense_robot`;
   a switched-off robot, such as those beyond a genome's N gene, is skipped);
2. each active robot's program decides its behaviour mask;
3. robots act in index order (:func:`excavation_sim.world.step_robots`, on an occupancy
   grid the kernel keeps for the episode).

A timestep that changes nothing ends the episode early with the same result (a fixed
point; :func:`_run_steps` says why that is exact).
"""

from __future__ import annotations

from typing import NamedTuple, Protocol

import numba as nb
import numpy as np
from numba.extending import overload

from ant_controller.hand_coded import HandCodedRules, hand_coded_program
from ant_controller.layout import N_BEHAVIOURS, N_SENSORS, SENSOR_STATES
from ant_controller.tissue import TissueRecord, decide_into, new_scratch
from ant_evolution.baselines.network import NetworkRecord, program_decide_into, program_scratch
from excavation_sim import cell_soil
from excavation_sim.world import (
    WorldArrays,
    fitness,
    occupancy,
    sense_robot,
    sensor_noise,
    step_robots,
)


class DecisionProgram(Protocol):
    """What the evaluator scores: an ANT or hand-coded ``Controller``, a ``NetworkProgram``."""

    @property
    def robots(self) -> int | None:
        """The N gene (robots to use), or None for each scenario's own count."""

    def record(self) -> TissueRecord | HandCodedRules | NetworkRecord:
        """The program as the kernels take it."""


# --- decision programs ---------------------------------------------------------------------


def _kind(program_type) -> type | None:
    """The record class of a numba type (None for anything that is not a record)."""
    return getattr(program_type, "instance_class", None)


def decide_program(codes, program, scratch):
    """Behaviour mask of ``program`` for one sensor vector (``scratch``: its work buffers)."""
    if isinstance(program, TissueRecord):
        return decide_into(codes, program, scratch)
    if isinstance(program, NetworkRecord):
        return program_decide_into(codes, program, scratch)
    if isinstance(program, HandCodedRules):
        return hand_coded_program(codes, program)
    raise TypeError(f"not a decision program: {type(program).__name__}")


def program_scratch_for(program):
    """Work buffers of one decision of ``program`` (allocated once per evaluation)."""
    if isinstance(program, TissueRecord):
        return new_scratch(program)
    if isinstance(program, NetworkRecord):
        return program_scratch(program)
    if isinstance(program, HandCodedRules):
        return np.zeros(0)
    raise TypeError(f"not a decision program: {type(program).__name__}")


@overload(decide_program, inline="always")
def _decide_program(codes, program, scratch):
    kind = _kind(program)
    if kind is TissueRecord:
        return lambda codes, program, scratch: decide_into(codes, program, scratch)
    if kind is NetworkRecord:
        return lambda codes, program, scratch: program_decide_into(codes, program, scratch)
    if kind is HandCodedRules:
        return lambda codes, program, scratch: hand_coded_program(codes, program)
    return None


@overload(program_scratch_for)
def _program_scratch_for(program):
    kind = _kind(program)
    if kind is TissueRecord:
        return lambda program: new_scratch(program)
    if kind is NetworkRecord:
        return lambda program: program_scratch(program)
    if kind is HandCodedRules:
        return lambda program: np.zeros(0)
    return None


# --- the decision cache --------------------------------------------------------------------

CACHE_BITS = 16
"""A decision cache holds ``2 ** CACHE_BITS`` entries (direct-mapped)."""

_RADIX = np.cumprod(np.concatenate(([1], SENSOR_STATES[:-1]))).astype(np.int64)
_MASK_BITS = N_BEHAVIOURS
_MASK_FIELD = (1 << _MASK_BITS) - 1
# An entry is ``key << _MASK_BITS | mask`` in one int64, so a lookup reads one word.
assert int(np.prod(SENSOR_STATES)) < 1 << (63 - _MASK_BITS)


def new_cache() -> np.ndarray:
    """An empty decision cache: ``int64 [2 ** CACHE_BITS]`` entries, -1 = empty slot."""
    return np.full(1 << CACHE_BITS, -1, dtype=np.int64)


@nb.njit(cache=True, inline="always")
def sensor_key(codes):
    """A unique integer for a sensor vector (mixed radix over the sensor state counts)."""
    key = 0
    for i in range(codes.shape[0]):
        key += codes[i] * _RADIX[i]
    return key


def decide_cached(codes, program, scratch, cache):
    """:func:`decide_program` through a direct-mapped cache of earlier answers.

    A program's answer depends on the sensor vector alone, so a hit returns exactly what
    :func:`decide_program` would. Use one cache per program (:func:`new_cache`); an entry
    holds the sensor key and the mask in one word (``key << 12 | mask``).
    """
    if isinstance(program, HandCodedRules):
        return hand_coded_program(codes, program)
    return _lookup(codes, program, scratch, cache)


@nb.njit(cache=True, inline="always")
def _lookup(codes, program, scratch, cache):
    key = sensor_key(codes)
    slot = (np.uint64(key) * np.uint64(0x9E3779B97F4A7C15)) >> np.uint64(64 - CACHE_BITS)
    entry = cache[slot]
    if entry >> _MASK_BITS == key:
        return entry & _MASK_FIELD
    mask = decide_program(codes, program, scratch)
    cache[slot] = key << _MASK_BITS | mask
    return mask


@overload(decide_cached, inline="always")
def _decide_cached(codes, program, scratch, cache):
    kind = _kind(program)
    if kind is HandCodedRules:
        return lambda codes, program, scratch, cache: hand_coded_program(codes, program)
    if kind is TissueRecord or kind is NetworkRecord:
        return lambda codes, program, scratch, cache: _lookup(codes, program, scratch, cache)
    return None


# --- the episode kernel ----------------------------------------------------------------------


class Workspace(NamedTuple):
    """Everything one evaluation writes besides the world (allocated once, reused)."""

    scratch: object
    cache: np.ndarray
    codes: np.ndarray
    masks: np.ndarray
    occupancy: np.ndarray


@nb.njit(cache=True)
def new_workspace(program, n_robots, rows, cols):
    """A :class:`Workspace` for ``program``, ``n_robots`` robots, a ``rows x cols`` grid."""
    return Workspace(
        program_scratch_for(program),
        np.full(1 << CACHE_BITS, -1, dtype=np.int64),
        np.zeros((n_robots, N_SENSORS), dtype=np.int64),
        np.zeros(n_robots, dtype=np.int64),
        np.zeros((rows, cols), dtype=np.int16),
    )


@nb.njit(cache=True, _nrt=False, error_model="numpy")
def _run_steps(world, steps, program, work, trace):
    """The per-step loop, compiled without numba's reference counting (``_nrt=False``).

    It allocates nothing; with reference counting on, every call that passes arrays costs
    tens of nanoseconds in reference-count traffic even when its branch is not taken. The
    numpy error model drops Python's division checks (every division here is guarded).
    Both measured in docs/benchmarks.md. ``trace[t]`` gets the fitness after step t (an
    empty ``trace``: none).

    A timestep that changes nothing (:func:`excavation_sim.world.step_robots` returns
    False: no robot moved, turned, drew a random turn or changed its blade, memory or stuck
    bit) leaves the world in a fixed point: every later timestep starts from the same
    state, senses and decides the same, and changes nothing either. The loop stops there
    (the trace keeps the last fitness), which gives exactly the result of running on. A
    randomised scenario's sensor noise (:func:`excavation_sim.world.sensor_noise`) draws
    from the generator; a timestep that drew is not a fixed point.
    """
    heights = world.heights
    zones = world.zones
    goal = world.goal
    robots = world.robots
    active = world.active
    codes = work.codes
    masks = work.masks
    occ = work.occupancy
    n = robots.shape[0]
    occupancy(robots, active, occ)
    params = world.params
    for t in range(steps):
        drew = False
        for k in range(n):  # every robot senses the snapshot before any acts
            if active[k]:
                sense_robot(heights, zones, goal, robots, active, k, codes[k], params)
                if sensor_noise(heights, zones, goal, robots, k, codes[k], world.rng, params):
                    drew = True
        for k in range(n):
            if not active[k]:
                masks[k] = 0
            else:
                masks[k] = decide_cached(codes[k], program, work.scratch, work.cache)
        changed = step_robots(heights, robots, active, occ, masks, world.rng, params)
        if trace.shape[0] > t:
            trace[t] = fitness(heights, zones, goal)
        if not changed and not drew:
            for u in range(t + 1, min(steps, trace.shape[0])):
                trace[u] = trace[t]
            return


@nb.njit(cache=True)
def run_episode(world, steps, program, trace):
    """Step ``world`` (a :class:`WorldArrays`) in place ``steps`` times under ``program``.

    ``trace[t]`` gets the fitness after step t; ``trace`` may be empty (length 0).
    """
    rows, cols = world.heights.shape
    work = new_workspace(program, world.robots.shape[0], rows, cols)
    _run_steps(world, steps, program, work, trace)


@nb.njit(cache=True, inline="always")
def _start_world(start, s, n_robots, heights, robots, active, rng):
    """Scenario ``s`` of ``start`` in the reused arrays, as a :class:`WorldArrays`.

    ``n_robots`` > 0: only the first ``n_robots`` robots are active (0 keeps the scenario's).
    """
    world = WorldArrays(heights, start.zones, start.goal, robots, active, rng, start.params[s])
    world.heights[:] = start.heights[s]
    world.robots[:] = start.robots[s]
    world.active[:] = start.active[s]
    if n_robots > 0:
        for k in range(robots.shape[0]):
            world.active[k] = k < n_robots
    world.rng[0] = start.rng[s]
    return world


@nb.njit(cache=True)
def run_scenarios(start, steps, program, n_robots, scores):
    """Score one program on every scenario of ``start``; ``scores[s]`` gets the final fitness.

    ``n_robots`` > 0 switches off robots ``n_robots ..`` in every scenario (the N gene);
    0 keeps each scenario's own robot count. One decision cache serves all scenarios.
    """
    n = start.robots.shape[1]
    work = new_workspace(program, n, start.zones.shape[0], start.zones.shape[1])
    heights = np.empty_like(start.heights[0])
    robots = np.empty_like(start.robots[0])
    active = np.empty_like(start.active[0])
    rng = np.empty(1, dtype=np.uint64)
    no_trace = np.zeros(0)
    for s in range(start.heights.shape[0]):
        world = _start_world(start, s, n_robots, heights, robots, active, rng)
        _run_steps(world, steps, program, work, no_trace)
        scores[s] = fitness(world.heights, world.zones, world.goal)


# --- the physical soil (excavation_sim.cell_soil) ----------------------------------------------


@nb.njit(cache=True, _nrt=False, error_model="numpy")
def _run_physical_steps(world, soil, steps, program, work, trace):
    """:func:`_run_steps` on the physical soil (:mod:`excavation_sim.cell_soil`).

    The same loop, sensing and acting through the physical soil; a fixed point ends it
    early the same way.
    """
    heights = world.heights
    robots = world.robots
    active = world.active
    codes = work.codes
    masks = work.masks
    occ = work.occupancy
    n = robots.shape[0]
    occupancy(robots, active, occ)
    zones = world.zones
    goal = world.goal
    params = world.params
    for t in range(steps):
        drew = False
        for k in range(n):
            if active[k]:
                cell_soil.sense_robot(
                    heights, zones, goal, robots, active, k, codes[k], params, soil
                )
                if sensor_noise(heights, zones, goal, robots, k, codes[k], world.rng, params):
                    drew = True
        for k in range(n):
            if not active[k]:
                masks[k] = 0
            else:
                masks[k] = decide_cached(codes[k], program, work.scratch, work.cache)
        changed = cell_soil.step_robots(heights, robots, active, occ, masks, world.rng, soil)
        if trace.shape[0] > t:
            trace[t] = cell_soil.soil_fitness(soil, heights, zones, goal)
        if not changed and not drew:
            for u in range(t + 1, min(steps, trace.shape[0])):
                trace[u] = trace[t]
            return


@nb.njit(cache=True)
def run_physical_episode(world, soil, steps, program, trace):
    """Step ``world`` and its physical ``soil`` in place ``steps`` times under ``program``.

    ``soil`` starts as :func:`excavation_sim.cell_soil.reset` left it, or where an earlier
    call stopped. ``trace[t]`` gets the fitness after step t; ``trace`` may be empty.
    """
    rows, cols = world.heights.shape
    work = new_workspace(program, world.robots.shape[0], rows, cols)
    _run_physical_steps(world, soil, steps, program, work, trace)


@nb.njit(cache=True)
def run_physical_scenarios(start, physics, steps, program, n_robots, scores, counters):
    """:func:`run_scenarios` on the physical soil of ``physics``.

    ``physics``: ``float64 [S, N_PHYSICS]``, each scenario's
    :func:`excavation_sim.cell_soil.physics_vector`; ``counters[s]`` gets scenario s's moves,
    refusals, stalls and quanta cut.
    """
    n = start.robots.shape[1]
    rows, cols = start.zones.shape
    work = new_workspace(program, n, rows, cols)
    heights = np.empty_like(start.heights[0])
    robots = np.empty_like(start.robots[0])
    active = np.empty_like(start.active[0])
    rng = np.empty(1, dtype=np.uint64)
    soil = cell_soil.new_soil((rows, cols), n, physics[0].copy())
    no_trace = np.zeros(0)
    for s in range(start.heights.shape[0]):
        world = _start_world(start, s, n_robots, heights, robots, active, rng)
        soil.physics[:] = physics[s]
        cell_soil.reset(soil, world.heights, world.robots, world.active)
        _run_physical_steps(world, soil, steps, program, work, no_trace)
        scores[s] = cell_soil.soil_fitness(soil, world.heights, world.zones, world.goal)
        counters[s, :] = soil.counters
