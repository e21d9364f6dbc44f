"""Where an evaluation's time goes per robot-step: sensing, decision, world step (``ant-bench``).

The episode kernel (:func:`ant_evolution.kernel.run_scenarios`) runs the three phases of a
timestep interleaved, with no clock inside. To split its time, :func:`record_scenario`
runs one scenario exactly as the kernel does and keeps the state before every step (soil,
robots, random-turn state) with the sensor vectors and masks of that step; then each phase
is timed alone on those recorded inputs:

* **sensing**: :func:`excavation_sim.world.sense_robot` of each active robot on each
  recorded state;
* **decision**: the program through its decision cache (:func:`ant_evolution.kernel.
  decide_cached`) on the recorded sensor vectors, one cache for the whole scenario set as
  in the kernel, so hits and misses are the kernel's;
* **world step**: :func:`excavation_sim.world.step_robots` from each recorded state,
  less the time to put that state in place (copies and occupancy grid, timed alone).

The replayed phases are checked against the recording (same sensor vectors, masks and
next states), so the breakdown times exactly the work the kernel does. What is left of
the kernel's own time (:func:`phase_times`' ``kernel`` minus the three phases) is the
loop's overhead and the phases' effects on each other's caches.
"""

from __future__ import annotations

import time

import numba as nb
import numpy as np

from ant_controller.layout import N_SENSORS
from ant_evolution.evaluate import ScenarioSet
from ant_evolution.kernel import decide_cached, new_workspace, run_scenarios
from excavation_sim.world import apply_all, occupancy, sense_robot, step_robots


@nb.njit(cache=True)
def record_scenario(
    heights, zones, goal, robots, active, rng, params, steps, program, work, rec_heights,
    rec_robots, rec_rng, rec_codes, rec_masks,
):  # fmt: skip
    """Run one scenario as the kernel does, keeping the inputs of every step.

    ``rec_heights[t]``, ``rec_robots[t]``, ``rec_rng[t]``: the state before step t;
    ``rec_codes[t]``, ``rec_masks[t]``: its sensor vectors and masks. Returns the steps
    run (fewer than ``steps`` when the world reaches a fixed point, as in the kernel).
    """
    n = robots.shape[0]
    occupancy(robots, active, work.occupancy)
    for t in range(steps):
        rec_heights[t] = heights
        rec_robots[t] = robots
        rec_rng[t] = rng[0]
        for k in range(n):
            if active[k]:
                sense_robot(heights, zones, goal, robots, active, k, work.codes[k], params)
        for k in range(n):
            if not active[k]:
                work.masks[k] = 0
            else:
                work.masks[k] = decide_cached(work.codes[k], program, work.scratch, work.cache)
        rec_codes[t] = work.codes
        rec_masks[t] = work.masks
        if not step_robots(heights, robots, active, work.occupancy, work.masks, rng, params):
            return t + 1
    return steps


@nb.njit(cache=True, _nrt=False, error_model="numpy")
def replay_sense(rec_heights, zones, goal, rec_robots, active, params, out):
    """Sensing alone: every recorded state's sensor vectors (active robots) into ``out[t]``."""
    for t in range(rec_heights.shape[0]):
        for k in range(rec_robots.shape[1]):
            if active[k]:
                sense_robot(
                    rec_heights[t], zones, goal, rec_robots[t], active, k, out[t, k], params
                )


@nb.njit(cache=True, _nrt=False, error_model="numpy")
def replay_decide(rec_codes, active, program, work, out):
    """Decisions alone: every recorded sensor vector through the program's cache."""
    for t in range(rec_codes.shape[0]):
        for k in range(rec_codes.shape[1]):
            if not active[k]:
                out[t, k] = 0
            else:
                out[t, k] = decide_cached(rec_codes[t, k], program, work.scratch, work.cache)


@nb.njit(cache=True, _nrt=False, error_model="numpy")
def replay_apply(rec_heights, rec_robots, rec_rng, active, rec_masks, params, state, apply):
    """World steps alone (``apply``) or just putting each recorded state in place.

    ``state``: ``(heights, robots, occupancy, rng)`` buffers to step in.
    """
    heights, robots, occ, rng = state
    for t in range(rec_heights.shape[0]):
        for r in range(heights.shape[0]):  # element loops: a slice copy would allocate
            for c in range(heights.shape[1]):
                heights[r, c] = rec_heights[t, r, c]
        for k in range(robots.shape[0]):
            for f in range(robots.shape[1]):
                robots[k, f] = rec_robots[t, k, f]
        rng[0] = rec_rng[t]
        occupancy(robots, active, occ)
        if apply:
            step_robots(heights, robots, active, occ, rec_masks[t], rng, params)


def _apply_differs(rec, active, params) -> bool:
    """True when a replayed world step does not give the next recorded state."""
    heights, robots, rng, _, masks = rec
    for t in range(len(heights) - 1):
        h, r, g = heights[t].copy(), robots[t].copy(), rng[t : t + 1].copy()
        apply_all(h, r, active, masks[t], g, params)
        if (
            not (np.array_equal(h, heights[t + 1]) and np.array_equal(r, robots[t + 1]))
            or g[0] != rng[t + 1]
        ):
            return True
    return False


def phase_times(program, batch: ScenarioSet, repeats: int = 3) -> dict[str, float]:
    """Seconds per robot-step of each phase for ``program`` on ``batch`` (best of ``repeats``).

    Returns:
        ``kernel`` (the episode kernel, whole), ``sensing``, ``decision``, ``world step``
        (copies excluded), each in CPU seconds per robot-step of active robots (all
        ``steps`` of every scenario, as throughput counts them), and ``steps run``: the
        share of those steps the kernel ran before a fixed point ended a scenario.

    Raises:
        RuntimeError: When a replayed phase does not reproduce the recording.
    """
    record = program.record()
    start = batch.start
    n_robots = program.robots or 0
    steps = batch.steps
    s_count = batch.size
    n = start.robots.shape[1]
    shape = start.zones.shape
    recs = []
    work = new_workspace(record, n, *shape)
    for s in range(s_count):
        heights = start.heights[s].copy()
        robots = start.robots[s].copy()
        active = start.active[s].copy()
        if n_robots > 0:
            active[:] = np.arange(n) < n_robots
        rng = start.rng[s : s + 1].copy()
        rec = (
            np.empty((steps, *shape), dtype=np.int32),
            np.empty((steps, n, robots.shape[1]), dtype=np.int64),
            np.empty(steps, dtype=np.uint64),
            np.empty((steps, n, N_SENSORS), dtype=np.int64),
            np.empty((steps, n), dtype=np.int64),
        )
        ran = record_scenario(
            heights, start.zones, start.goal, robots, active, rng, batch.params, steps, record,
            work, *rec,
        )  # fmt: skip
        recs.append((active, tuple(a[:ran] for a in rec)))
    robot_steps = steps * sum(int(a.sum()) for a, _ in recs)
    run_share = sum(len(rec[0]) * int(a.sum()) for a, rec in recs) / robot_steps
    scores = np.zeros(s_count)

    state = (
        np.empty(shape, dtype=np.int32),
        np.empty((n, start.robots.shape[2]), dtype=np.int64),
        np.empty(shape, dtype=np.int16),
        np.empty(1, dtype=np.uint64),
    )
    out_codes = np.empty((steps, n, N_SENSORS), dtype=np.int64)
    out_masks = np.empty((steps, n), dtype=np.int64)

    def best_of(fn, *args) -> float:
        fn(*args)  # warm: code and data in cache, as in the kernel's loop
        best = float("inf")
        for _ in range(repeats):
            t0 = time.perf_counter()
            fn(*args)
            best = min(best, time.perf_counter() - t0)
        return best

    def decision() -> None:
        w = new_workspace(record, n, *shape)
        for active, (_, _, _, codes, _) in recs:
            replay_decide(codes, active, record, w, out_masks)

    sensing = world = copies = 0.0
    params = batch.params
    for active, (h, r, g, _, masks) in recs:  # one scenario at a time (its states fit in L2)
        sensing += best_of(replay_sense, h, start.zones, start.goal, r, active, params, out_codes)
        copies += best_of(replay_apply, h, r, g, active, masks, params, state, False)
        world += best_of(replay_apply, h, r, g, active, masks, params, state, True)
    check = new_workspace(record, n, *shape)
    for active, (h, r, g, codes, masks) in recs:  # the replays reproduce the recording
        replay_sense(h, start.zones, start.goal, r, active, batch.params, out_codes)
        bad = not np.array_equal(out_codes[: len(h)][:, active], codes[:, active])
        replay_decide(codes, active, record, check, out_masks)
        bad = bad or not np.array_equal(out_masks[: len(h)], masks)
        if bad or _apply_differs((h, r, g, codes, masks), active, batch.params):
            raise RuntimeError("breakdown: a replayed phase differs from the recording")
    return {
        "kernel": best_of(run_scenarios, batch.arrays(), steps, record, n_robots, scores)
        / robot_steps,
        "sensing": sensing / robot_steps,
        "decision": best_of(decision) / robot_steps,
        "world step": max(0.0, world - copies) / robot_steps,
        "steps run": run_share,
    }
