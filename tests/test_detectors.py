"""Table 3 sensor-behaviour detectors: each rule, vectorised shapes, random-turn direction."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from ant_controller.layout import (
    B1,
    BLADE_ABOVE,
    BLADE_BELOW,
    BLADE_HOME,
    BLADE_LEVEL,
    L1,
    N_SENSORS,
    S1,
    U1,
    Z2,
    Z3,
    Z_ABOVE,
    Z_DUMP,
    mask_of,
)
from excavation_sim.detectors import (
    DETECTORS,
    DetectorInputError,
    count,
    detect,
    random_turn_direction,
)

FWD, BACK, RAND, RIGHT, LEFT = 2, 3, 4, 5, 6  # Table 2 behaviour numbers


def vec(**codes) -> np.ndarray:
    v = np.zeros(N_SENSORS, dtype=np.int64)
    names = {"B1": B1, "L1": L1, "S1": S1, "U1": U1, "Z2": Z2, "Z3": Z3}
    for k, value in codes.items():
        v[names[k]] = value
    return v


def reference(v, mask, rand_dir):
    """Table 3 read literally, one case at a time (rand_dir: -1 left, +1 right, None)."""
    bit = {n: bool(mask >> (n - 1) & 1) for n in range(1, 13)}
    mf, mb, rt, tr, tl = bit[FWD], bit[BACK], bit[RAND], bit[RIGHT], bit[LEFT]
    dump = v[Z2] == Z_DUMP and v[Z3] == Z_DUMP and v[L1] > 0
    return {
        "level": v[B1] == BLADE_LEVEL and v[L1] > 0 and mf,
        "collision_avoidance": v[S1] == 1 and not mf and not rt and (tr != tl or mb),
        "stuck_avoidance": v[U1] == 1 and not mf and (mb or rt or tl != tr),
        "cut_dig": v[B1] == BLADE_BELOW and mf,
        "correct_dump": (dump and not rt and mf and tl == tr)
        or (dump and rt and rand_dir == -1 and tr and not tl and mf)
        or (dump and rt and rand_dir == 1 and not tr and tl and mf),
    }


def test_every_mask_and_sensor_case_matches_the_table():
    masks = np.arange(1 << 12)
    cases = [
        vec(**dict(zip(("B1", "L1", "S1", "U1", "Z2", "Z3"), c, strict=True)))
        for c in itertools.product(
            (BLADE_BELOW, BLADE_LEVEL, BLADE_ABOVE, BLADE_HOME),
            (0, 2),
            (0, 1),
            (0, 1),
            (Z_DUMP, Z_ABOVE),
            (Z_DUMP, Z_ABOVE),
        )
    ]
    sensors = np.repeat(np.stack(cases)[:, None, :], len(masks), axis=1)
    behaviours = np.broadcast_to(masks, sensors.shape[:-1])
    rng = np.random.default_rng(0)
    dirs = rng.choice([-1, 1], size=behaviours.shape)
    dirs = np.where((behaviours >> 3) & 1 == 1, dirs, 0)
    hits = detect(sensors, behaviours, dirs)
    hits_unknown = detect(sensors, behaviours)
    seen = dict.fromkeys(DETECTORS, 0)
    for i, v in enumerate(cases):
        for m in range(0, 1 << 12, 7):  # every 7th mask keeps the loop short
            d = int(dirs[i, m])
            ref = reference(v, m, d if d else None)
            ref_unknown = reference(v, m, None)
            for name in DETECTORS:
                assert hits[name][i, m] == ref[name], (name, v, m, d)
                assert hits_unknown[name][i, m] == ref_unknown[name], (name, v, m)
                seen[name] += ref[name]
    assert all(seen[n] > 0 for n in DETECTORS), seen


@pytest.mark.parametrize(
    ("sensors", "mask", "name", "expected"),
    [
        (vec(B1=BLADE_LEVEL, L1=1), mask_of(FWD), "level", True),
        (vec(B1=BLADE_LEVEL, L1=0), mask_of(FWD), "level", False),
        (vec(B1=BLADE_BELOW, L1=1), mask_of(FWD), "level", False),
        (vec(S1=1), mask_of(RIGHT), "collision_avoidance", True),
        (vec(S1=1), mask_of(BACK), "collision_avoidance", True),
        (vec(S1=1), mask_of(RIGHT, LEFT), "collision_avoidance", False),
        (vec(S1=1), mask_of(RIGHT, RAND), "collision_avoidance", False),
        (vec(S1=1), mask_of(BACK, FWD), "collision_avoidance", False),
        (vec(U1=1), mask_of(RAND), "stuck_avoidance", True),
        (vec(U1=1), mask_of(1, 4, 7, 10, 12), "stuck_avoidance", True),  # hand-coded rule 1
        (vec(U1=1), mask_of(FWD, BACK), "stuck_avoidance", False),
        (vec(U1=0), mask_of(BACK), "stuck_avoidance", False),
        (vec(B1=BLADE_BELOW), mask_of(FWD, 8), "cut_dig", True),
        (vec(B1=BLADE_ABOVE), mask_of(FWD), "cut_dig", False),
        (vec(Z2=Z_DUMP, Z3=Z_DUMP, L1=3), mask_of(FWD), "correct_dump", True),
        (vec(Z2=Z_DUMP, Z3=Z_DUMP, L1=3), mask_of(FWD, RIGHT, LEFT), "correct_dump", True),
        (vec(Z2=Z_DUMP, Z3=Z_DUMP, L1=3), mask_of(FWD, RIGHT), "correct_dump", False),
        (vec(Z2=Z_DUMP, Z3=Z_ABOVE, L1=3), mask_of(FWD), "correct_dump", False),
        (vec(Z2=Z_DUMP, Z3=Z_DUMP, L1=0), mask_of(FWD), "correct_dump", False),
    ],
)
def test_single_cases(sensors, mask, name, expected):
    assert bool(detect(sensors, np.int64(mask))[name]) is expected


def test_correct_dump_random_turn_clauses_need_the_direction():
    v = vec(Z2=Z_DUMP, Z3=Z_DUMP, L1=2)
    m = np.int64(mask_of(FWD, RAND, RIGHT))
    assert not detect(v, m)["correct_dump"]  # direction unknown: not counted
    assert detect(v, m, np.int8(-1))["correct_dump"]  # random left undone by right
    assert not detect(v, m, np.int8(1))["correct_dump"]
    m = np.int64(mask_of(FWD, RAND, LEFT))
    assert detect(v, m, np.int8(1))["correct_dump"]
    assert not detect(v, m, np.int8(-1))["correct_dump"]


def test_count_axes():
    sensors = np.zeros((5, 3, N_SENSORS), dtype=np.int64)
    sensors[..., B1] = BLADE_BELOW
    behaviours = np.zeros((5, 3), dtype=np.int64)
    behaviours[:, 0] = mask_of(FWD)
    behaviours[2, :] = mask_of(FWD)
    per_step = count(sensors, behaviours, axis=1)
    assert per_step["cut_dig"].tolist() == [1, 1, 3, 1, 1]
    assert count(sensors, behaviours)["cut_dig"] == 7
    assert count(sensors, behaviours)["level"] == 0


@pytest.mark.parametrize(
    ("sensors", "behaviours", "random_turns", "match"),
    [
        (np.zeros(13, dtype=np.int64), np.int64(0), None, "last axis"),
        (np.zeros((2, 14), dtype=np.int64), np.zeros(3, dtype=np.int64), None, "shape"),
        (np.zeros(14), np.int64(0), None, "integer"),
        (np.zeros(14, dtype=np.int64), np.int64(1 << 12), None, "12-bit"),
        (np.zeros(14, dtype=np.int64), np.int64(-1), None, "12-bit"),
        (np.zeros(14, dtype=np.int64), np.int64(0), np.int8(2), "random_turns"),
    ],
)
def test_bad_input(sensors, behaviours, random_turns, match):
    with pytest.raises(DetectorInputError, match=match):
        detect(sensors, behaviours, random_turns)


def test_random_turn_direction_follows_the_simulator():
    from blueprint_server.blueprint import default_blueprint
    from excavation_sim.world import HEADING, World, next_random

    bp = default_blueprint(1)
    world = World.scenario(bp.zones, bp.goal, 4, seed=5)
    rng = np.random.default_rng(1)
    hits = {-1: 0, 1: 0}
    for _ in range(60):
        masks = rng.choice(
            [mask_of(RAND), mask_of(RAND, RIGHT), mask_of(RAND, LEFT), mask_of(RIGHT), 0],
            size=4,
        )
        before = world.robots[:, HEADING].copy()
        state = world.rng.copy()
        expected = []
        for m in masks:  # the simulator draws one number per random turn, in robot order
            if m >> 3 & 1:
                expected.append(1 if int(next_random(state)) >> 63 else -1)
            else:
                expected.append(0)
        world.step(masks)
        got = random_turn_direction(before, world.robots[:, HEADING], masks)
        assert got.tolist() == expected
        for d in expected:
            if d:
                hits[d] += 1
    assert hits[-1] > 0 and hits[1] > 0


def test_random_turn_direction_rejects_headings_of_another_step():
    with pytest.raises(DetectorInputError, match="quarter turn"):
        random_turn_direction(np.array([0]), np.array([0]), np.array([mask_of(RAND)]))
