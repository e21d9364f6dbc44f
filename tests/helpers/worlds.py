"""World states for the world-model, kernel and paper-profile tests.

* :func:`make_world`: a hand-built :class:`~excavation_sim.world.World` (robots placed by
  hand on a flat or given terrain);
* :func:`random_state`: a random world state from a seeded generator (rough terrain, robots
  in every blade and bit state, some switched off, random rules);
* :func:`random_masks`: random behaviour masks.
"""

from __future__ import annotations

import numpy as np

from ant_controller.layout import N_BEHAVIOURS
from excavation_sim.rules import DEFAULT_RULES, WorldRules
from excavation_sim.world import (
    BLADE,
    COL,
    HEADING,
    MEMORY,
    ROBOT_FIELDS,
    ROW,
    STUCK,
    World,
    place_robots,
    seed_state,
)


def make_world(
    robots,
    rules: WorldRules = DEFAULT_RULES,
    size: int = 8,
    heights: np.ndarray | None = None,
    zones: np.ndarray | None = None,
    goal: np.ndarray | None = None,
) -> World:
    """A hand-built world of ``size`` x ``size`` cells.

    Args:
        robots: One row per robot: (row, col, heading, blade); every robot active.
        rules: The world's rules (the v1 rules unless given).
        size: Side of the square grid.
        heights, zones, goal: The grids (copied; flat, no zones, goal 0 unless given).

    Returns:
        The world, its random state seeded with 12345.
    """
    rs = np.zeros((len(robots), ROBOT_FIELDS), dtype=np.int64)
    for k, (r, c, h, b) in enumerate(robots):
        rs[k, [ROW, COL, HEADING, BLADE]] = (r, c, h, b)
    shape = (size, size)
    return World(
        heights=np.zeros(shape, np.int32) if heights is None else heights.astype(np.int32),
        zones=np.zeros(shape, np.uint8) if zones is None else zones.astype(np.uint8),
        goal=np.zeros(shape, np.int32) if goal is None else goal.astype(np.int32),
        robots=rs,
        active=np.ones(len(robots), dtype=np.bool_),
        rng=seed_state(12345),
        params=rules.as_array(),
    )


def random_state(rng: np.random.Generator, shape=(10, 12), n_robots=4, *, maps: bool = True):
    """A random world state with rough terrain and robots in every blade and bit state.

    Heights -3 .. 3; robots placed at random with random blades, memory and stuck bits,
    each active with probability 0.85; random rules.

    Args:
        rng: The generator every value is drawn from (the same seed, the same state).
        shape: The grid's shape.
        n_robots: How many robots.
        maps: Random zones (0 .. 2) and goal (-3 .. 1) too, and random normal and throttle
            loads, soil fill and H1 reading. Without: zones and goal all 0 (not drawn), and
            only the normal load and soil fill drawn (the kernel tests' state).

    Returns:
        ``(heights, zones, goal, robots, active, params)``.
    """
    heights = rng.integers(-3, 4, shape).astype(np.int32)
    if maps:
        zones = rng.integers(0, 3, shape).astype(np.uint8)
        goal = rng.integers(-3, 2, shape).astype(np.int32)
    else:
        zones, goal = np.zeros(shape, np.uint8), np.zeros(shape, np.int32)
    robots = place_robots(shape, n_robots, rng)
    robots[:, BLADE] = rng.integers(0, 4, n_robots)
    robots[:, MEMORY] = rng.integers(0, 2, n_robots)
    robots[:, STUCK] = rng.integers(0, 2, n_robots)
    active = rng.random(n_robots) < 0.85
    if maps:
        rules = WorldRules(
            normal_load=int(rng.integers(4, 13)),
            throttle_load=int(rng.integers(12, 25)),
            soil_fill=bool(rng.integers(0, 2)),
            h1=("relative", "absolute")[int(rng.integers(0, 2))],
        )
    else:
        rules = WorldRules(normal_load=int(rng.integers(4, 13)), soil_fill=bool(rng.integers(0, 2)))
    return heights, zones, goal, robots, active, rules.as_array()


def random_masks(rng: np.random.Generator, n: int, p: float = 0.3) -> np.ndarray:
    """``n`` behaviour masks, each behaviour firing with probability ``p``."""
    bits = rng.random((n, N_BEHAVIOURS)) < p
    return (bits * (1 << np.arange(N_BEHAVIOURS))).sum(axis=1).astype(np.int64)
