"""The simulated worksite: soil heights, bulldozer robots and the blade model (paper, 4.1-4.2).

The world is a grid of integer soil heights (ground level 0). Each robot covers 2 x 2
cells and carries a blade across the two cells in front of it. One timestep:

1. every robot senses the same snapshot of the world (``sense_all``);
2. each controller turns its sensor vector into a behaviour bit mask;
3. robots apply their masks one after another in index order (robot 0 first), each
   running its selected behaviours in Table 2 order (``apply_behaviours``).

Soil moves only through ``try_forward`` and only between two cells, so the total is
conserved exactly. The readings of the paper the model can take (soil fill, push
capacity, climbing, H1's frame, where robots start) are the switches of
:class:`excavation_sim.rules.WorldRules`, packed into the ``params`` array the kernels
take. ``docs/world-model.md`` states every rule and the choices taken where the paper is
silent.

State lives in plain arrays so that numba kernels (and later the batched evaluator) can
run whole episodes without Python in the loop:

* ``heights``: ``int32 [rows, cols]`` soil height in soil units.
* ``robots``: ``int64 [n, ROBOT_FIELDS]`` per-robot state (columns ``ROW`` .. ``STUCK``).
* ``active``: ``bool [n]`` robots taking part (a disabled robot is invisible and idle).
* ``rng``: ``uint64 [1]`` xorshift64* state for the random turn.
* ``params``: ``int64 [N_PACKED]`` the packed :class:`~excavation_sim.rules.WorldRules`.
* ``occupancy``: ``int16 [rows, cols]`` which active robot stands on each cell (``k + 1``,
  0 free), derived from ``robots`` and ``active`` (:func:`occupancy`). The moves read it
  instead of scanning every robot and keep it up to date; :func:`apply_all` builds it per
  call, the episode kernel keeps one for a whole episode (:func:`step_robots`).
"""

from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np

from ant_controller.layout import (
    BLADE_ABOVE,
    BLADE_ABOVE_CMD,
    BLADE_BELOW,
    BLADE_BELOW_CMD,
    BLADE_HOME,
    BLADE_HOME_CMD,
    BLADE_LEVEL,
    BLADE_LEVEL_CMD,
    MOVE_BACKWARD,
    MOVE_FORWARD,
    N_SENSORS,
    RANDOM_TURN,
    THROTTLE_UP,
    TURN_LEFT,
    TURN_RIGHT,
    U1,
    Z1,
)
from ant_controller.memory import next_memory
from ant_controller.sensing import (
    FORWARD,
    blade_offset,
    blade_volume,
    front_cell,
    front_wheel,
    in_grid,
    is_tilted_down,
    rear_wheel,
    sense,
    zone_code,
)
from excavation_common.constants import ZONE_DIG, ZONE_DUMP
from excavation_sim.rules import (
    DEFAULT_RULES,
    P_H1,
    P_MISREAD,
    P_NORMAL_CLIMB,
    P_NORMAL_LOAD,
    P_SOIL_FILL,
    P_THROTTLE_CLIMB,
    P_THROTTLE_LOAD,
    P_U1_DROPOUT,
    WorldRules,
)

# Robot state columns. The first three are the pose (row, col, heading).
ROW, COL, HEADING, BLADE, MEMORY, STUCK = range(6)
ROBOT_FIELDS = 6

# --- random numbers ------------------------------------------------------------------------


@nb.njit(cache=True)
def next_random(rng):
    """Advance a xorshift64* generator held in ``rng[0]``; returns 64 random bits."""
    x = rng[0]
    x ^= x >> np.uint64(12)
    x ^= x << np.uint64(25)
    x ^= x >> np.uint64(27)
    rng[0] = x
    return x * np.uint64(0x2545F4914F6CDD1D)


def seed_state(seed_bits: int) -> np.ndarray:
    """A non-zero xorshift state from 64 seed bits."""
    return np.array([(seed_bits & 0xFFFFFFFFFFFFFFFF) or 0x9E3779B97F4A7C15], dtype=np.uint64)


# --- occupancy --------------------------------------------------------------------------------


@nb.njit(cache=True)
def occupancy(robots, active, occ):
    """Fill ``occ`` (``int16 [rows, cols]``): ``k + 1`` under active robot k, 0 elsewhere."""
    occ[:] = 0
    for k in range(robots.shape[0]):
        if active[k]:
            stamp_footprint(occ, robots[k, ROW], robots[k, COL], k + 1)


@nb.njit(cache=True, inline="always")
def stamp_footprint(occ, row, col, value):
    """Write ``value`` into the 2 x 2 footprint anchored at ``(row, col)``."""
    occ[row, col] = value
    occ[row, col + 1] = value
    occ[row + 1, col] = value
    occ[row + 1, col + 1] = value


@nb.njit(cache=True, inline="always")
def occupied(occ, k, r, c):
    """True when on-grid cell ``(r, c)`` is under an active robot other than k.

    The occupancy-grid form of :func:`ant_controller.sensing.occupied_by_other`.
    """
    v = occ[r, c]
    return v != 0 and v != k + 1


# --- moves ----------------------------------------------------------------------------------


@nb.njit(cache=True, inline="always")
def fill_amount(deficit, spare):
    """Soil that fills a blade cell ``deficit`` units below the cutting level (``soil_fill``).

    ``spare``: soil of the cell ahead above the cutting level (may be negative). The fill
    is what the paper's equation asks for, bounded by what lies above the cutting level
    ahead: the blade never digs that cell below its edge to fill the one behind.
    """
    if spare <= 0:
        return 0
    return deficit if deficit < spare else spare


@nb.njit(cache=True, inline="always")
def try_forward(heights, robots, occ, k, throttle, params):
    """Move robot k one cell forward, pushing or cutting soil with the blade.

    The blade equations of the paper, per blade column i with front wheel cell W_i, old
    blade cell B~_i and new blade cell B_i = B~_i + forward:

    * cutting level ``t_i = h(W_i) + b_h * eps`` where ``eps = 0`` when the blade holds no
      soil and ``b_h >= 0``, else 1;
    * soil above the cutting level in B~_i moves into B_i; B~_i is left at ``t_i``;
    * a B~_i below ``t_i``: left alone (rule ``soil_fill`` off, ``v1``), or raised toward
      ``t_i`` with soil from B_i above ``t_i`` (``soil_fill`` on, ``paper``: the paper's
      equation, bounded so that B_i never drops below the cutting level);
    * the front wheels then stand on the old blade cells.

    The move is refused (robot stuck, nothing changes) when the new footprint leaves the
    grid or meets another robot, when an engaged blade would push soil off the grid or into
    another robot, when the soil then held against the blade exceeds the push capacity, or
    when the wheels would climb a step higher than the climb limit. Only a move that is
    made changes the soil (the episode kernel relies on it), and it moves robot k's
    footprint in ``occ`` (:func:`occupancy`).

    Returns:
        True when the robot moved.
    """
    row = robots[k, ROW]
    col = robots[k, COL]
    h = robots[k, HEADING]
    rows = heights.shape[0]
    cols = heights.shape[1]
    fr = FORWARD[h, 0]
    fc = FORWARD[h, 1]
    capacity = params[P_THROTTLE_LOAD] if throttle else params[P_NORMAL_LOAD]
    climb = params[P_THROTTLE_CLIMB] if throttle else params[P_NORMAL_CLIMB]
    fill = params[P_SOIL_FILL] != 0
    blade = robots[k, BLADE]
    engaged = blade != BLADE_HOME
    # New footprint cells are the old blade cells.
    for i in range(2):
        br, bc = front_cell(row, col, h, i)
        if not in_grid(rows, cols, br, bc) or occupied(occ, k, br, bc):
            return False
        if engaged:
            nr = br + fr
            nc = bc + fc
            if not in_grid(rows, cols, nr, nc) or occupied(occ, k, nr, nc):
                return False
    bh = blade_offset(blade)
    moved0 = 0
    moved1 = 0
    new_load = 0
    if engaged:
        eps = 0 if (blade_volume(heights, row, col, h, blade) == 0 and bh >= 0) else 1
        for i in range(2):
            br, bc = front_cell(row, col, h, i)
            wr, wc = front_wheel(row, col, h, i)
            target = heights[wr, wc] + bh * eps
            moved = heights[br, bc] - target
            if moved < 0:
                moved = -fill_amount(-moved, heights[br + fr, bc + fc] - target) if fill else 0
            # Soil against the blade after the move, above the new cutting level.
            pile = heights[br + fr, bc + fc] + moved - (heights[br, bc] - moved) - bh
            if pile > 0:
                new_load += pile
            if heights[br, bc] - moved - heights[wr, wc] > climb:
                return False
            if i == 0:
                moved0 = moved
            else:
                moved1 = moved
        if new_load > capacity:
            return False
    else:
        for i in range(2):
            br, bc = front_cell(row, col, h, i)
            wr, wc = front_wheel(row, col, h, i)
            if heights[br, bc] - heights[wr, wc] > climb:
                return False
    if engaged:
        for i in range(2):
            moved = moved0 if i == 0 else moved1
            br, bc = front_cell(row, col, h, i)
            heights[br, bc] -= moved
            heights[br + fr, bc + fc] += moved
    stamp_footprint(occ, row, col, 0)
    stamp_footprint(occ, row + fr, col + fc, k + 1)
    robots[k, ROW] = row + fr
    robots[k, COL] = col + fc
    return True


@nb.njit(cache=True, inline="always")
def try_backward(heights, robots, occ, k, throttle, params):
    """Move robot k one cell backward; the blade leaves its soil where it is.

    Refused when the cells behind leave the grid, meet another robot, or stand higher
    than the climb limit above the rear wheels. A move made moves k's footprint in ``occ``.
    """
    row = robots[k, ROW]
    col = robots[k, COL]
    h = robots[k, HEADING]
    rows = heights.shape[0]
    cols = heights.shape[1]
    climb = params[P_THROTTLE_CLIMB] if throttle else params[P_NORMAL_CLIMB]
    for i in range(2):
        rr, rc = rear_wheel(row, col, h, i)
        nr = rr - FORWARD[h, 0]
        nc = rc - FORWARD[h, 1]
        if not in_grid(rows, cols, nr, nc) or occupied(occ, k, nr, nc):
            return False
        if heights[nr, nc] - heights[rr, rc] > climb:
            return False
    stamp_footprint(occ, row, col, 0)
    stamp_footprint(occ, row - FORWARD[h, 0], col - FORWARD[h, 1], k + 1)
    robots[k, ROW] = row - FORWARD[h, 0]
    robots[k, COL] = col - FORWARD[h, 1]
    return True


@nb.njit(cache=True, inline="always")
def robot_word(robots, k):
    """Robot k's heading, blade, memory and stuck bit packed into one integer."""
    return (
        robots[k, HEADING]
        | robots[k, BLADE] << 8
        | robots[k, MEMORY] << 16
        | robots[k, STUCK] << 24
    )


@nb.njit(cache=True, inline="always")
def step_robot(heights, robots, active, occ, k, mask, rng, params):
    """Run robot k's selected behaviours (bit mask) in Table 2 order.

    U1 (stuck) becomes 1 when any move attempted this timestep was refused and 0
    otherwise. Blade and memory commands apply in table order, so the last one wins.
    ``occ``: the occupancy grid of ``robots`` and ``active`` (:func:`occupancy`), kept up
    to date.

    Returns:
        False when the world is exactly as before (no move made, robot k's state
        unchanged); True when anything may have changed.
    """
    if not active[k]:
        return False
    throttle = (mask >> THROTTLE_UP) & 1 == 1
    stuck = 0
    changed = (mask >> RANDOM_TURN) & 1 == 1  # the random turn draws from the generator
    before = robot_word(robots, k)
    if (mask >> MOVE_FORWARD) & 1:
        if try_forward(heights, robots, occ, k, throttle, params):
            changed = True
        else:
            stuck = 1
    if (mask >> MOVE_BACKWARD) & 1:
        if try_backward(heights, robots, occ, k, throttle, params):
            changed = True
        else:
            stuck = 1
    turn_and_set(robots, k, mask, rng)
    robots[k, STUCK] = stuck
    return changed or robot_word(robots, k) != before


@nb.njit(cache=True, inline="always")
def turn_and_set(robots, k, mask, rng):
    """What follows the moves in Table 2 order: turns, blade commands and memory.

    Robot k's random turn (drawn from ``rng``), its turns, its blade commands (the last
    wins) and its memory bit.
    """
    if (mask >> RANDOM_TURN) & 1:
        if next_random(rng) >> np.uint64(63):
            robots[k, HEADING] = (robots[k, HEADING] + 1) % 4
        else:
            robots[k, HEADING] = (robots[k, HEADING] + 3) % 4
    if (mask >> TURN_RIGHT) & 1:
        robots[k, HEADING] = (robots[k, HEADING] + 1) % 4
    if (mask >> TURN_LEFT) & 1:
        robots[k, HEADING] = (robots[k, HEADING] + 3) % 4
    if (mask >> BLADE_ABOVE_CMD) & 1:
        robots[k, BLADE] = BLADE_ABOVE
    if (mask >> BLADE_BELOW_CMD) & 1:
        robots[k, BLADE] = BLADE_BELOW
    if (mask >> BLADE_LEVEL_CMD) & 1:
        robots[k, BLADE] = BLADE_LEVEL
    if (mask >> BLADE_HOME_CMD) & 1:
        robots[k, BLADE] = BLADE_HOME
    robots[k, MEMORY] = next_memory(robots[k, MEMORY], mask)


@nb.njit(cache=True)
def apply_behaviours(heights, robots, active, k, mask, rng, params):
    """:func:`step_robot` for one robot, with the occupancy grid built for the call.

    Returns:
        False when nothing changed.
    """
    occ = np.empty(heights.shape, dtype=np.int16)
    occupancy(robots, active, occ)
    return step_robot(heights, robots, active, occ, k, mask, rng, params)


@nb.njit(cache=True, inline="always")
def sense_robot(heights, zones, goal, robots, active, k, out, params):
    """Sensor vector of robot k from the world state (simulator side of ``sense``)."""
    row = robots[k, ROW]
    col = robots[k, COL]
    h = robots[k, HEADING]
    blade = robots[k, BLADE]
    sense(
        heights,
        zones,
        goal,
        robots,
        active,
        k,
        blade,
        blade_volume(heights, row, col, h, blade),
        robots[k, STUCK],
        is_tilted_down(heights, row, col, h),
        robots[k, MEMORY],
        out,
        params[P_H1],
    )


@nb.njit(cache=True, inline="always")
def _chance(rng, chance):
    """True with probability ``chance / CHANCE_ONE`` (one draw from ``rng``)."""
    return np.int64(next_random(rng) >> np.uint64(44)) < chance


@nb.njit(cache=True)
def sensor_noise(heights, zones, goal, robots, k, out, rng, params):
    """A randomised training scenario's sensor noise on robot k's vector ``out``.

    With the chance ``params[P_MISREAD]`` each Z sensor over a dig cell within one unit of
    its goal reads the cell a unit higher or lower (either, evenly); with the chance
    ``params[P_U1_DROPOUT]`` a set U1 reads 0. Both chances are 0 outside randomised runs,
    where nothing is drawn. Returns True when it drew from ``rng`` (the episode kernels'
    fixed-point test counts a draw as a change).
    """
    drew = False
    if params[P_MISREAD] > 0:
        row = robots[k, ROW]
        col = robots[k, COL]
        h = robots[k, HEADING]
        rows, cols = heights.shape
        for j in range(4):
            r, c = front_cell(row, col, h, j - 1)
            if not in_grid(rows, cols, r, c) or zones[r, c] != ZONE_DIG:
                continue
            if abs(heights[r, c] - goal[r, c]) > 1:
                continue
            drew = True
            if _chance(rng, params[P_MISREAD]):
                step = 1 if next_random(rng) >> np.uint64(63) else -1
                out[Z1 + j] = zone_code(zones[r, c], heights[r, c] + step, goal[r, c])
    if params[P_U1_DROPOUT] > 0 and out[U1] == 1:
        drew = True
        if _chance(rng, params[P_U1_DROPOUT]):
            out[U1] = 0
    return drew


@nb.njit(cache=True, _nrt=False)
def sense_all(heights, zones, goal, robots, active, out, params):
    """Sensor vectors of every robot from one snapshot, ``out[n_robots, 14]``."""
    for k in range(robots.shape[0]):
        sense_robot(heights, zones, goal, robots, active, k, out[k], params)


@nb.njit(cache=True, _nrt=False)
def step_robots(heights, robots, active, occ, masks, rng, params):
    """Apply every robot's behaviour mask in index order (robot 0 first).

    ``occ`` is the occupancy grid of ``robots`` and ``active`` (:func:`occupancy`), kept
    up to date. Returns False when nothing changed: then the next timestep, from the same
    state, does exactly the same, and so does every one after it.
    """
    changed = False
    for k in range(robots.shape[0]):
        if step_robot(heights, robots, active, occ, k, masks[k], rng, params):
            changed = True
    return changed


@nb.njit(cache=True)
def apply_all(heights, robots, active, masks, rng, params):
    """Apply every robot's behaviour mask in index order (robot 0 first).

    Returns:
        False when nothing changed (see :func:`step_robots`).
    """
    occ = np.empty(heights.shape, dtype=np.int16)
    occupancy(robots, active, occ)
    return step_robots(heights, robots, active, occ, masks, rng, params)


@nb.njit(cache=True)
def fitness(heights, zones, goal):
    """The paper's excavation fitness: mean of ``exp(-2 |g - z|)`` over the dig cells.

    Returns 0 for a blueprint without dig cells.
    """
    total = 0.0
    count = 0
    for r in range(heights.shape[0]):
        for c in range(heights.shape[1]):
            if zones[r, c] == 1:
                total += np.exp(-2.0 * abs(goal[r, c] - heights[r, c]))
                count += 1
    if count == 0:
        return 0.0
    return total / count


# --- scenarios ------------------------------------------------------------------------------


class PlacementError(ValueError):
    """The requested robots do not fit on the grid."""


def place_robots(
    shape: tuple[int, int],
    n_robots: int,
    rng: np.random.Generator,
    max_tries: int = 10_000,
    worksite: np.ndarray | None = None,
) -> np.ndarray:
    """Random non-overlapping 2 x 2 footprints with random headings.

    Args:
        shape: Grid ``(rows, cols)``.
        n_robots: Number of robots.
        rng: Source of randomness.
        max_tries: Rejection-sampling budget (placement anywhere).
        worksite: Blueprint zones: place on the worksite instead
            (:func:`place_in_worksite`); ``None``: anywhere on the grid (``v1``).

    Returns:
        ``int64 [n_robots, ROBOT_FIELDS]`` robot states: blade home, memory 0, not stuck.

    Raises:
        PlacementError: When the robots cannot be placed.
    """
    rows, cols = shape
    if rows < 2 or cols < 2:
        raise PlacementError(f"grid {rows} x {cols} is smaller than one robot (2 x 2)")
    if worksite is not None:
        return place_in_worksite(worksite, n_robots, rng)
    robots = np.zeros((n_robots, ROBOT_FIELDS), dtype=np.int64)
    taken = np.zeros(shape, dtype=bool)
    for k in range(n_robots):
        for _ in range(max_tries):
            r = int(rng.integers(0, rows - 1))
            c = int(rng.integers(0, cols - 1))
            if not taken[r : r + 2, c : c + 2].any():
                break
        else:
            raise PlacementError(
                f"could not place robot {k + 1} of {n_robots} on a {rows} x {cols} grid"
            )
        taken[r : r + 2, c : c + 2] = True
        robots[k, ROW] = r
        robots[k, COL] = c
        robots[k, HEADING] = int(rng.integers(0, 4))
        robots[k, BLADE] = BLADE_HOME
    return robots


def _free_anchors(allowed: np.ndarray, taken: np.ndarray) -> np.ndarray:
    """Flat indices of the anchors whose 2 x 2 footprint lies in ``allowed`` and is free."""
    ok = allowed & ~taken
    fits = ok[:-1, :-1] & ok[1:, :-1] & ok[:-1, 1:] & ok[1:, 1:]
    return np.flatnonzero(fits)


def place_in_worksite(zones: np.ndarray, n_robots: int, rng: np.random.Generator) -> np.ndarray:
    """Robots "initialized at random positions on the worksite" (paper, 4.3; ``worksite``).

    Each robot in turn takes an anchor drawn uniformly from the free footprints that lie
    wholly inside the dig area; when none is left, inside the dig area and its dump band;
    then anywhere on the grid. Headings are uniform.

    Raises:
        PlacementError: When no free footprint is left on the grid.
    """
    zones = np.asarray(zones)
    rows, cols = zones.shape
    tiers = (
        zones == ZONE_DIG,
        (zones == ZONE_DIG) | (zones == ZONE_DUMP),
        np.ones_like(zones, bool),
    )
    robots = np.zeros((n_robots, ROBOT_FIELDS), dtype=np.int64)
    taken = np.zeros(zones.shape, dtype=bool)
    for k in range(n_robots):
        for allowed in tiers:
            free = _free_anchors(allowed, taken)
            if free.size:
                break
        else:
            raise PlacementError(
                f"could not place robot {k + 1} of {n_robots} on a {rows} x {cols} grid"
            )
        r, c = divmod(int(free[int(rng.integers(0, free.size))]), cols - 1)
        taken[r : r + 2, c : c + 2] = True
        robots[k, ROW] = r
        robots[k, COL] = c
        robots[k, HEADING] = int(rng.integers(0, 4))
        robots[k, BLADE] = BLADE_HOME
    return robots


def scenario_start(
    shape: tuple[int, int],
    n_robots: int,
    active_robots: int,
    seed: int,
    index: int,
    worksite: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, int]:
    """Placements, active flags and random-turn state of scenario ``index`` of ``seed``.

    The one definition of a seeded scenario, shared by the offline evaluator and the
    simulator node: scenario i draws from ``SeedSequence(seed).spawn(...)[i]``, whose
    randomness does not depend on how many scenarios are spawned. ``worksite``: the
    blueprint's zones to place robots on the worksite (rule ``placement = "worksite"``),
    ``None`` to place them anywhere.

    Returns:
        ``(robots [n_robots, ROBOT_FIELDS], active [n_robots], rng_state)``.
    """
    child = np.random.SeedSequence(seed, spawn_key=(index,))
    rng = np.random.default_rng(child)
    robots = place_robots(shape, n_robots, rng, worksite=worksite)
    active = np.zeros(n_robots, dtype=np.bool_)
    active[:active_robots] = True
    return robots, active, int(seed_state(int(rng.integers(0, 2**63)))[0])


def placement_zones(rules: WorldRules, zones: np.ndarray) -> np.ndarray | None:
    """What :func:`scenario_start` takes as ``worksite`` under ``rules``."""
    return zones if rules.placement == "worksite" else None


class WorldArrays(NamedTuple):
    """The grid world's state, declared once: what every kernel steps, senses and scores.

    One world (:class:`World`, :func:`ant_evolution.kernel.run_episode`):

    Attributes:
        heights: Soil heights, ``int32 [rows, cols]``.
        zones: Blueprint zones, ``uint8 [rows, cols]``.
        goal: Goal heights, ``int32 [rows, cols]``.
        robots: Robot states, ``int64 [n, ROBOT_FIELDS]``.
        active: Robots taking part, ``bool [n]``.
        rng: xorshift64* state, ``uint64 [1]``.
        params: Packed :class:`~excavation_sim.rules.WorldRules`, ``int64 [N_PACKED]``.

    ``S`` scenarios stacked on one blueprint (the evaluator's starting states,
    :class:`ant_evolution.evaluate.ScenarioSet`): ``heights [S, rows, cols]``, ``robots
    [S, n, ROBOT_FIELDS]``, ``active [S, n]``, ``rng [S]`` and ``params [S, N_PACKED]``
    (each scenario's rules) gain a leading scenario axis; ``zones`` and ``goal`` are shared.
    """

    heights: np.ndarray
    zones: np.ndarray
    goal: np.ndarray
    robots: np.ndarray
    active: np.ndarray
    rng: np.ndarray
    params: np.ndarray


class World(WorldArrays):
    """A worksite ready to step: one world's :class:`WorldArrays` and what to do with them.

    The arrays are stepped in place (:meth:`step`); the tuple itself never changes.
    """

    __slots__ = ()

    @classmethod
    def create(
        cls,
        zones: np.ndarray,
        goal: np.ndarray,
        n_robots: int,
        rng: np.random.Generator,
        rules: WorldRules = DEFAULT_RULES,
        heights: np.ndarray | None = None,
    ) -> World:
        """A flat (or given) terrain with robots placed at random by ``rng``."""
        shape = zones.shape
        robots = place_robots(shape, n_robots, rng, worksite=placement_zones(rules, zones))
        return cls(
            heights=(
                np.zeros(shape, dtype=np.int32)
                if heights is None
                else np.array(heights, dtype=np.int32)
            ),
            zones=np.ascontiguousarray(zones, dtype=np.uint8),
            goal=np.ascontiguousarray(goal, dtype=np.int32),
            robots=robots,
            active=np.ones(n_robots, dtype=np.bool_),
            rng=seed_state(int(rng.integers(0, 2**63))),
            params=rules.as_array(),
        )

    @classmethod
    def scenario(
        cls,
        zones: np.ndarray,
        goal: np.ndarray,
        n_robots: int,
        seed: int,
        index: int = 0,
        rules: WorldRules = DEFAULT_RULES,
    ) -> World:
        """Scenario ``index`` of ``seed`` on a flat site (see :func:`scenario_start`)."""
        robots, active, rng_state = scenario_start(
            zones.shape, n_robots, n_robots, seed, index, placement_zones(rules, zones)
        )
        return cls(
            heights=np.zeros(zones.shape, dtype=np.int32),
            zones=np.ascontiguousarray(zones, dtype=np.uint8),
            goal=np.ascontiguousarray(goal, dtype=np.int32),
            robots=robots,
            active=active,
            rng=np.array([rng_state], dtype=np.uint64),
            params=rules.as_array(),
        )

    @property
    def n_robots(self) -> int:
        """Number of robots."""
        return self.robots.shape[0]

    def arrays(self) -> WorldArrays:
        """The arrays themselves (not copies) for a kernel that steps this world in place.

        A plain :class:`WorldArrays`, so that a compiled kernel sees one argument type.
        """
        return WorldArrays(*self)

    def sense(self) -> np.ndarray:
        """Sensor vectors of all robots from the current snapshot, ``int64 [n, 14]``."""
        out = np.zeros((self.n_robots, N_SENSORS), dtype=np.int64)
        sense_all(self.heights, self.zones, self.goal, self.robots, self.active, out, self.params)
        return out

    def step(self, masks: np.ndarray) -> None:
        """Apply one behaviour mask per robot, in robot order."""
        apply_all(
            self.heights,
            self.robots,
            self.active,
            np.asarray(masks, dtype=np.int64),
            self.rng,
            self.params,
        )

    def fitness(self) -> float:
        """The paper's fitness of the current terrain."""
        return float(fitness(self.heights, self.zones, self.goal))

    def copy(self) -> World:
        """A deep copy (arrays included)."""
        return World(*(np.array(a, copy=True) for a in self))
