"""The numba sensing and world-step kernels equal their plain-Python references.

Random states from seeded generators: rough terrain (so blades cut, fill and climb),
random zones and goals, robots with random poses, blades, memory and stuck bits, some of
them switched off, and random behaviour masks; then whole random episodes step by step.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers.worlds import random_masks, random_state

from ant_controller.layout import N_BEHAVIOURS, N_SENSORS
from ant_controller.memory import next_memory
from ant_controller.sensing import sense
from ant_controller.sensing_reference import sense_reference
from excavation_sim.world import (
    apply_all,
    blade_volume,
    is_tilted_down,
    seed_state,
    sense_all,
)
from excavation_sim.world_reference import (
    blade_volume_reference,
    sense_all_reference,
    step_reference,
    tilted_down_reference,
    xorshift_reference,
)


@pytest.mark.parametrize("seed", range(60))
def test_sense_kernel_equals_reference(seed):
    rng = np.random.default_rng(seed)
    heights, zones, goal, robots, active, params = random_state(rng)
    for k in range(len(robots)):
        blade, volume = int(rng.integers(0, 4)), int(rng.integers(0, 30))
        stuck, tilted, memory = (bool(b) for b in rng.integers(0, 2, 3))
        h1_frame = int(rng.integers(0, 2))
        out = np.zeros(N_SENSORS, dtype=np.int64)
        poses = robots[:, :3].copy()
        sense(
            heights, zones, goal, poses, active, k, blade, volume, stuck, tilted, memory, out,
            h1_frame,
        )  # fmt: skip
        ref = sense_reference(
            heights, zones, goal, poses, active, k, blade, volume, stuck, tilted, memory, h1_frame
        )
        assert out.tolist() == ref
    assert np.array_equal(
        sense_all_reference(heights, zones, goal, robots, active, params),
        _sense_all(heights, zones, goal, robots, active, params),
    )


@pytest.mark.parametrize("seed", range(30))
def test_blade_volume_and_tilt_equal_reference(seed):
    rng = np.random.default_rng(1000 + seed)
    heights, _, _, robots, _, _ = random_state(rng)
    for row, col, h, blade, *_ in robots:
        assert blade_volume(heights, row, col, h, blade) == blade_volume_reference(
            heights, (row, col, h), blade
        )
        assert bool(is_tilted_down(heights, row, col, h)) == tilted_down_reference(
            heights, (row, col, h)
        )


@pytest.mark.parametrize("seed", range(60))
def test_world_step_equals_reference(seed):
    rng = np.random.default_rng(2000 + seed)
    heights, _, _, robots, active, params = random_state(rng)
    masks = random_masks(rng, len(robots))
    state = seed_state(int(rng.integers(0, 2**63)))
    ref_heights, ref_robots, ref_state = step_reference(
        heights, robots, active, masks, int(state[0]), params
    )
    apply_all(heights, robots, active, masks, state, params)
    assert np.array_equal(heights, ref_heights)
    assert np.array_equal(robots, ref_robots)
    assert int(state[0]) == ref_state


@pytest.mark.parametrize("seed", range(8))
def test_random_episodes_equal_reference_step_by_step(seed):
    """200 steps of random masks: kernel and reference agree on every sensor and state."""
    rng = np.random.default_rng(3000 + seed)
    heights, zones, goal, robots, active, params = random_state(rng, (12, 12), 5)
    state = seed_state(int(rng.integers(0, 2**63)))
    ref = (heights.copy(), robots.copy(), int(state[0]))
    total = int(heights.sum())
    for _ in range(200):
        codes = _sense_all(heights, zones, goal, robots, active, params)
        assert np.array_equal(
            codes, sense_all_reference(ref[0], zones, goal, ref[1], active, params)
        )
        masks = random_masks(rng, len(robots))
        apply_all(heights, robots, active, masks, state, params)
        ref = step_reference(ref[0], ref[1], active, masks, ref[2], params)
        assert np.array_equal(heights, ref[0]) and np.array_equal(robots, ref[1])
        assert int(state[0]) == ref[2]
    assert int(heights.sum()) == total  # soil is conserved


def test_xorshift_reference_matches_the_kernels_generator():
    from excavation_sim.world import next_random

    rng = seed_state(12345)
    state = int(rng[0])
    for _ in range(100):
        state, bits = xorshift_reference(state)
        assert int(next_random(rng)) == bits and int(rng[0]) == state


@pytest.mark.parametrize("memory", [0, 1])
@pytest.mark.parametrize("mask", range(0, 1 << N_BEHAVIOURS, 97))
def test_memory_bit_rule(memory, mask):
    """Bit set, then bit clear, in Table 2 order: both at once clear the bit."""
    set_, clear = mask >> 10 & 1, mask >> 11 & 1
    expected = 0 if clear else (1 if set_ else memory)
    assert next_memory(memory, mask) == expected


def _sense_all(heights, zones, goal, robots, active, params) -> np.ndarray:
    out = np.zeros((len(robots), N_SENSORS), dtype=np.int64)
    sense_all(heights, zones, goal, robots, active, out, params)
    return out
