"""Plain-Python reference of the world step (paper, sections 4.1-4.2), written for reading.

:func:`step_reference` does what :func:`excavation_sim.world.apply_all` does to a copy of
the state, the slow way: Python integers, the heading tables, every blade equation spelled
out once per blade column (with and without the ``soil_fill`` switch of
:class:`excavation_sim.rules.WorldRules`), the random turn's xorshift64* in Python
arithmetic. The
tests hold the numba kernels to it on random states and whole random episodes
(``tests/test_world_reference.py``), as :func:`ant_controller.tissue.decide_reference`
does for the network. :func:`sense_all_reference` is the simulator's side of
:func:`ant_controller.sensing_reference.sense_reference`.

Robots act in index order (robot 0 first), each running its selected behaviours in
Table 2 order: throttle-up, forward, backward, random turn, right, left, the four blade
commands, bit set, bit clear.
"""

from __future__ import annotations

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
    RANDOM_TURN,
    THROTTLE_UP,
    TURN_LEFT,
    TURN_RIGHT,
)
from ant_controller.memory import next_memory
from ant_controller.sensing import FORWARD
from ant_controller.sensing_reference import (
    blade_height_offset,
    blade_volume_reference,
    front_row_cell,
    front_wheel_cell,
    on_grid,
    rear_wheel_cell,
    sense_reference,
    tilted_down_reference,
    under_other_robot,
)
from excavation_sim.rules import (
    P_H1,
    P_NORMAL_CLIMB,
    P_NORMAL_LOAD,
    P_SOIL_FILL,
    P_THROTTLE_CLIMB,
    P_THROTTLE_LOAD,
)
from excavation_sim.world import BLADE, HEADING, MEMORY, STUCK

_MASK64 = (1 << 64) - 1


def xorshift_reference(state: int) -> tuple[int, int]:
    """One xorshift64* draw: ``(new state, 64 random bits)``."""
    x = state
    x ^= x >> 12
    x = (x ^ (x << 25)) & _MASK64
    x ^= x >> 27
    return x, (x * 0x2545F4914F6CDD1D) & _MASK64


def _forward(heights, robots, active, k: int, capacity: int, climb: int, fill: bool) -> bool:
    pose = robots[k]
    h = int(pose[HEADING])
    step = (int(FORWARD[h, 0]), int(FORWARD[h, 1]))
    blade = int(pose[BLADE])
    engaged = blade != BLADE_HOME
    blade_cells = [front_row_cell(pose, i) for i in range(2)]
    wheels = [front_wheel_cell(pose, i) for i in range(2)]
    beyond = [(b[0] + step[0], b[1] + step[1]) for b in blade_cells]
    # The new footprint (the old blade cells), and where an engaged blade pushes, must be
    # on the grid and free of other robots.
    for b, n in zip(blade_cells, beyond, strict=True):
        if not on_grid(heights, b) or under_other_robot(robots, active, k, b):
            return False
        if engaged and (not on_grid(heights, n) or under_other_robot(robots, active, k, n)):
            return False
    moved = [0, 0]
    if engaged:
        bh = blade_height_offset(blade)
        eps = 0 if (blade_volume_reference(heights, pose, blade) == 0 and bh >= 0) else 1
        load = 0
        for i in range(2):
            b, w, n = blade_cells[i], wheels[i], beyond[i]
            cut = int(heights[w]) + bh * eps  # the cutting level t_i
            moved[i] = int(heights[b]) - cut  # the paper's equation: B~_i is left at t_i
            if moved[i] < 0 and not fill:
                moved[i] = 0  # v1: a cell below the cutting level is left alone
            elif moved[i] < 0:
                # soil_fill: B~_i is raised toward t_i with soil from B_i, but only with
                # soil that lies above the cutting level there
                spare = max(0, int(heights[n]) - cut)
                moved[i] = -min(-moved[i], spare)
            left = int(heights[b]) - moved[i]
            load += max(0, int(heights[n]) + moved[i] - left - bh)
            if left - int(heights[w]) > climb:
                return False
        if load > capacity:
            return False
    else:
        for b, w in zip(blade_cells, wheels, strict=True):
            if int(heights[b]) - int(heights[w]) > climb:
                return False
    if engaged:  # soil moves from each old blade cell into the cell beyond it (or back)
        for i in range(2):
            heights[blade_cells[i]] -= moved[i]
            heights[beyond[i]] += moved[i]
    robots[k, 0] += step[0]
    robots[k, 1] += step[1]
    return True


def _backward(heights, robots, active, k: int, climb: int) -> bool:
    pose = robots[k]
    h = int(pose[HEADING])
    for i in range(2):
        rear = rear_wheel_cell(pose, i)
        new = (rear[0] - int(FORWARD[h, 0]), rear[1] - int(FORWARD[h, 1]))
        if not on_grid(heights, new) or under_other_robot(robots, active, k, new):
            return False
        if int(heights[new]) - int(heights[rear]) > climb:
            return False
    robots[k, 0] -= int(FORWARD[h, 0])
    robots[k, 1] -= int(FORWARD[h, 1])
    return True


def step_reference(heights, robots, active, masks, rng_state: int, params):
    """One timestep applied to copies: ``(heights, robots, rng_state)`` afterwards.

    Args:
        heights: Soil heights ``[rows, cols]``.
        robots: Robot states ``[n, ROBOT_FIELDS]``.
        active: Robots taking part.
        masks: One behaviour mask per robot.
        rng_state: The xorshift64* state (``World.rng[0]``).
        params: Packed world rules (``WorldRules.as_array``).
    """
    heights = np.array(heights, copy=True)
    robots = np.array(robots, copy=True)
    normal_load, throttle_load = int(params[P_NORMAL_LOAD]), int(params[P_THROTTLE_LOAD])
    normal_climb, throttle_climb = int(params[P_NORMAL_CLIMB]), int(params[P_THROTTLE_CLIMB])
    fill = bool(params[P_SOIL_FILL])
    state = int(rng_state)
    for k in range(len(robots)):
        if not active[k]:
            continue
        mask = int(masks[k])
        fires = [bool(mask >> b & 1) for b in range(12)]
        throttle = fires[THROTTLE_UP]
        capacity = throttle_load if throttle else normal_load
        climb = throttle_climb if throttle else normal_climb
        stuck = False
        forward_ok = not fires[MOVE_FORWARD] or _forward(
            heights, robots, active, k, capacity, climb, fill
        )
        if not forward_ok:
            stuck = True
        if fires[MOVE_BACKWARD] and not _backward(heights, robots, active, k, climb):
            stuck = True
        if fires[RANDOM_TURN]:
            state, bits = xorshift_reference(state)
            robots[k, HEADING] = (robots[k, HEADING] + (1 if bits >> 63 else 3)) % 4
        if fires[TURN_RIGHT]:
            robots[k, HEADING] = (robots[k, HEADING] + 1) % 4
        if fires[TURN_LEFT]:
            robots[k, HEADING] = (robots[k, HEADING] + 3) % 4
        for cmd, setting in (
            (BLADE_ABOVE_CMD, BLADE_ABOVE),
            (BLADE_BELOW_CMD, BLADE_BELOW),
            (BLADE_LEVEL_CMD, BLADE_LEVEL),
            (BLADE_HOME_CMD, BLADE_HOME),
        ):
            if fires[cmd]:
                robots[k, BLADE] = setting
        robots[k, MEMORY] = next_memory(int(robots[k, MEMORY]), mask)
        robots[k, STUCK] = int(stuck)
    return heights, robots, state


def sense_all_reference(heights, zones, goal, robots, active, params=None) -> np.ndarray:
    """Every robot's sensor vector from the world state, ``int64 [n, 14]``.

    ``params``: packed world rules (only H1's frame matters here); ``None``: ``v1``'s.
    """
    h1_frame = 0 if params is None else int(params[P_H1])
    rows = []
    for k in range(len(robots)):
        pose = robots[k]
        blade = int(pose[BLADE])
        rows.append(
            sense_reference(
                heights,
                zones,
                goal,
                robots,
                active,
                k,
                blade,
                blade_volume_reference(heights, pose, blade),
                bool(pose[STUCK]),
                tilted_down_reference(heights, pose),
                bool(pose[MEMORY]),
                h1_frame,
            )
        )
    return np.array(rows, dtype=np.int64).reshape(len(robots), -1)
