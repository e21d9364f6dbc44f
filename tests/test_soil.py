"""Physical soil (``soil: physical``): conservation, the calibrated stall, spillage, McKyes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ant_controller.layout import BLADE_ABOVE, BLADE_BELOW, BLADE_HOME, BLADE_LEVEL
from blueprint_server.blueprint import default_blueprint
from excavation_sim.dynamics import Dynamics, DynamicsParams
from excavation_sim.soil import (
    MAX_FINE_CELLS,
    Site,
    Soil,
    SoilError,
    SoilParams,
    _band,
    _local,
    _rect,
    blade_force,
    calibrate,
    cos_sin,
    level_pile_force,
    mckyes_force,
    n_factors,
    relax_local,
    stamp_body,
)
from excavation_sim.world import BLADE, World

CELL, UNIT = 0.25, 0.05
PHYSICAL = SoilParams(soil="physical")
SQUARE = (0.0, math.pi / 2, -math.pi / 2, math.pi)


def flat_world(robots: int = 1, seed: int = 0) -> World:
    bp = default_blueprint(1)
    return World.scenario(bp.zones, bp.goal, robots, seed, 0)


def physical(world: World, **changes) -> Dynamics:
    params = DynamicsParams.exact(**changes)
    return Dynamics(world, params, CELL, np.random.default_rng(0), soil=PHYSICAL)


@pytest.mark.parametrize("phi", [10.0, 30.0, 45.0])
def test_a_smooth_vertical_blade_meets_rankine_passive_pressure(phi):
    """McKyes's N_gamma for a smooth vertical blade is Rankine's K_p / 2 (Coulomb's wedge)."""
    params = SoilParams(friction_angle=phi, blade_friction_angle=0.0, rake_angle=90.0)
    n_gamma, _, n_q, beta = n_factors(params)
    kp = math.tan(math.radians(45 + phi / 2)) ** 2
    assert n_gamma == pytest.approx(kp / 2, rel=2e-3)
    assert n_q == pytest.approx(kp, rel=2e-3)
    assert math.degrees(beta) == pytest.approx(45 - phi / 2, abs=0.2)


def test_the_blade_cuts_firm_ground_and_drags_loose_soil():
    """The force's three parts on a level field of firm ground: a blade set into it cuts
    McKyes's depth; a pile heaped on the ground (loose) against a level blade is dragged,
    its weight times tan(phi); the same pile against a blade set into the ground lies on
    the failure wedge as its surcharge."""
    site = Site(24, 24, CELL, UNIT)
    physics = calibrate(PHYSICAL, CELL, UNIT)
    x, y = 3 * CELL, 6 * CELL
    soil = Soil(np.full((24, 24), 4, dtype=np.int64), site, PHYSICAL, physics)
    ground = soil.ground(x, y, 0.0)
    below = ground - soil.q  # one unit (5 cm) into the firm ground
    cut = soil.load(x, y, 0.0, below)
    assert cut.depth == pytest.approx(UNIT) and cut.over == 0 and cut.beyond == 0
    assert soil.resistance(x, y, 0.0, below) == pytest.approx(
        mckyes_force(UNIT, 0.0, 2 * CELL, 1.0, physics)
    )
    assert soil.resistance(x, y, 0.0, ground) == 0.0  # a level blade on bare ground
    soil.heap(x, y, 0.0, 6.0)
    assert (soil.loose >= 0).all() and soil.loose.sum() == 6 * soil.q * soil.s * soil.s
    drag = soil.load(x, y, 0.0, ground)
    assert drag.depth == 0 and drag.over == 0 and drag.beyond > 0
    weight = physics.gamma * drag.beyond
    assert soil.resistance(x, y, 0.0, ground) == pytest.approx(
        weight * math.tan(math.radians(PHYSICAL.friction_angle))
    )
    loaded = soil.load(x, y, 0.0, below)
    assert loaded.depth == pytest.approx(UNIT) and loaded.over > 0
    assert soil.resistance(x, y, 0.0, below) == pytest.approx(
        blade_force(loaded, 2 * CELL, physics)
    )
    assert soil.resistance(x, y, 0.0, below) > mckyes_force(UNIT, 0.0, 2 * CELL, 1.0, physics)


def test_conservation_over_random_pushes():
    """Random terrain, blades, throttle and commands: the total never changes by a quantum."""
    rng = np.random.default_rng(7)
    cuts = slips = 0
    for trial in range(6):
        world = flat_world(robots=2, seed=trial)
        world.heights[:] = rng.integers(-2, 3, world.heights.shape)
        start = int(world.heights.sum()) * PHYSICAL.quanta * PHYSICAL.subcells**2
        dyn = physical(world, speed_noise=0.01, turn_noise=0.05)
        total = dyn.soil.volume()
        assert total == start
        for step in range(400):
            if step % 40 == 0:
                for k in range(2):
                    dyn.set_blade(k, int(rng.choice([BLADE_BELOW, BLADE_LEVEL, BLADE_ABOVE])))
                    dyn.throttle[k] = bool(rng.integers(0, 2))
                    dyn.command(k, float(rng.uniform(-0.1, 0.3)), float(rng.uniform(-1, 1)))
            dyn.step()
            assert dyn.soil.volume() == total, (trial, step)
        means = dyn.soil.cell_means()
        assert np.array_equal(world.heights, np.floor(means + 0.5).astype(np.int32))
        cuts += int(np.abs(dyn.soil.fine - np.repeat(np.repeat(world.heights, 4, 0), 4, 1)).sum())
        slips += dyn.counters.slips
    assert cuts > 0 and slips > 0  # soil moved and some pushes were too heavy


@pytest.mark.parametrize(("throttle", "capacity"), [(False, 12), (True, 24)])
def test_a_level_push_stalls_at_the_calibrated_capacity(throttle, capacity):
    """A level blade moves a pile of the grid's capacity and stalls on one unit more.

    The first step decides: left alone, a pile held as :meth:`Soil.heap` puts it slumps
    past the blade's ends and gets lighter.
    """
    advanced = {}
    for units in (capacity, capacity + 1):
        world = flat_world()
        world.robots[0, :3] = (6, 3, 1)  # facing +x with open ground ahead
        dyn = physical(world)
        dyn.set_blade(0, BLADE_LEVEL)
        dyn.throttle[0] = throttle
        x, y, yaw = dyn.bodies[0]
        dyn.soil.heap(x, y, yaw, units)
        dyn.command(0, 0.2, 0.0)
        dyn.step()
        advanced[units] = float(dyn.bodies[0, 0] - x)
    assert advanced[capacity] == pytest.approx(0.2 * 0.05)
    assert advanced[capacity + 1] == 0.0


def test_the_calibration_is_the_grid_capacity_and_traction_allows_it():
    physics = calibrate(PHYSICAL, CELL, UNIT)
    f = [level_pile_force(u, PHYSICAL, CELL, UNIT, physics) for u in (11, 12, 13, 24, 25)]
    assert f == sorted(f)
    assert f[1] < physics.motor[0] < f[2] and f[3] < physics.motor[1] < f[4]
    assert physics.available(True) == physics.motor[1]
    assert physics.wheel_friction * physics.mass * physics.gravity > physics.motor[1]


def test_a_full_blade_spills_at_its_ends():
    """Soil pushed by a full blade ends up beside the blade's path, beyond the heap.

    Full: the 12 units the grid's blade holds without throttle-up (throttle on, so that the
    push carries on as the pile's face steepens).
    """
    world = flat_world()
    world.robots[0, :3] = (6, 1, 1)
    dyn = physical(world)
    dyn.set_blade(0, BLADE_LEVEL)
    dyn.throttle[0] = True
    x0, y0, yaw = dyn.bodies[0]
    dyn.soil.heap(x0, y0, yaw, 12)
    soil = dyn.soil
    rows, cols = soil.fine.shape
    ii, jj = np.mgrid[0:rows, 0:cols]
    px, py = (jj + 0.5) * soil.sub, (ii + 0.5) * soil.sub
    beside = np.abs(py - y0) > CELL  # outside the blade's 2-cell path
    far = px > x0 + CELL + 2.5 * CELL  # beyond where the heap lay

    def spilled() -> int:
        return int(soil.fine[beside & far].sum())

    assert spilled() == 0
    total = soil.volume()
    for _ in range(120):
        dyn.command(0, 0.2, 0.0)
        dyn.step()
    assert dyn.bodies[0, 0] - x0 > 2 * CELL  # it pushed on
    assert spilled() > 0.1 * 12 * soil.q * soil.s**2  # over a tenth of the pile
    assert soil.volume() == total


def test_a_lifted_blade_leaves_its_pile_and_backing_off_moves_no_soil():
    world = flat_world()
    world.robots[0, :3] = (6, 3, 1)
    dyn = physical(world)
    dyn.set_blade(0, BLADE_LEVEL)
    x, y, yaw = dyn.bodies[0]
    dyn.soil.heap(x, y, yaw, 6)
    for _ in range(20):
        dyn.command(0, 0.2, 0.0)
        dyn.step()
    assert dyn.blade_force(0, 10.0) > 0
    dyn.set_blade(0, BLADE_HOME)
    assert dyn.blade_force(0, 10.0) == 0.0
    soil = dyn.soil
    line = dyn.bodies[0, 0] + CELL  # the blade's edge when it was lifted
    px = (np.arange(soil.fine.shape[1]) + 0.5) * soil.sub
    ahead = soil.fine[:, px > line].sum()
    for _ in range(30):
        dyn.command(0, -0.2, 0.0)
        dyn.step()
    assert dyn.bodies[0, 0] < line - CELL - 0.1  # it backed off
    # the pile stays ahead of where the blade was (its face slumps into the place the
    # body left: the blade held it as a wall)
    assert soil.fine[:, px > line].sum() > 0.75 * ahead


def test_physical_soil_changes_the_grid_only_through_the_soil():
    """Cell heights are the rounded sub-cell means; the fitness reads the means."""
    world = flat_world(robots=1)
    dyn = physical(world)
    dyn.set_blade(0, BLADE_BELOW)
    dyn.throttle[0] = True
    for _ in range(200):
        dyn.command(0, 0.2, 0.0)
        dyn.step()
    means = dyn.soil.cell_means()
    assert np.array_equal(world.heights, np.floor(means + 0.5))
    expected = np.where(world.zones == 1, np.exp(-2 * np.abs(world.goal - means)), 0)
    assert dyn.fitness() == pytest.approx(expected.sum() / (world.zones == 1).sum())
    assert int(world.robots[0, BLADE]) == BLADE_BELOW


def test_sizes_are_checked_before_allocating():
    with pytest.raises(SoilError, match="subcells = 16"):
        Soil(np.zeros((1000, 1000)), Site(1000, 1000, CELL, UNIT), SoilParams(subcells=16))
    assert 1000 * 1000 * 16 * 16 > MAX_FINE_CELLS


def test_bad_soil_parameters_are_named():
    from excavation_common.params import ParameterError, validate

    with pytest.raises(ParameterError, match="blade_friction_angle = 65"):
        validate(SoilParams, {"blade_friction_angle": 65.0, "friction_angle": 30.0}, "dynamics")
    with pytest.raises(ParameterError, match="soil"):
        validate(SoilParams, {"soil": "clay"}, "dynamics")


def test_end_plates_keep_more_of_a_pushed_pile():
    """A straight blade loses most of a pile to its sides over five cells; end plates keep it."""
    held = {}
    for plates in (0.0, 1.0):
        world = flat_world()
        world.robots[0, :3] = (6, 1, 1)
        params = DynamicsParams.exact()
        soil = SoilParams(soil="physical", end_plates=plates)
        dyn = Dynamics(world, params, CELL, np.random.default_rng(0), soil=soil)
        dyn.set_blade(0, BLADE_LEVEL)
        dyn.throttle[0] = True
        x0, y0, yaw = dyn.bodies[0]
        dyn.soil.heap(x0, y0, yaw, 12)
        for _ in range(120):
            dyn.command(0, 0.2, 0.0)
            dyn.step()
        s, x = dyn.soil, dyn.bodies[0, 0]
        px = (np.arange(s.fine.shape[1]) + 0.5) * s.sub
        py = (np.arange(s.fine.shape[0]) + 0.5) * s.sub
        lane = s.fine[np.abs(py - y0) < CELL]
        held[plates] = lane[:, px > x + CELL].sum() / (s.q * s.s**2)
        assert x - x0 == pytest.approx(1.2)
    assert held[0.0] < 0.4 * 12 < 0.6 * 12 < held[1.0] < 12


@settings(max_examples=300, deadline=None)
@given(
    x=st.floats(-1.5, 7.0),  # the field: 4-6.7 m; a rectangle may lie wholly off it
    y=st.floats(-1.5, 7.0),
    yaw=st.one_of(st.sampled_from([0.0, math.pi / 2, -math.pi / 2, math.pi]), st.floats(-4, 4)),
    u0=st.floats(-0.6, 0.6),
    length=st.floats(0.0, 0.8),
    half_width=st.floats(0.0, 0.4),
    sub=st.sampled_from([0.0625, 0.25 / 3, 0.05]),
)
def test_a_kernels_window_holds_every_sub_cell_its_rectangle_holds(
    x, y, yaw, u0, length, half_width, sub
):
    """The kernels visit only ``_rect``'s window: it must hold every sub-cell whose centre
    lies in the robot's rectangle (tested against all sub-cells of the field), and for a
    robot square to the grid nothing else. It lies on the field (``0 <= i0 <= i1 <=
    rows``), even for a rectangle off it: a negative end would make a slice wrap."""
    rows = cols = 80
    cy, sy = cos_sin(yaw)
    u1 = u0 + length
    i0, i1, j0, j1 = _rect(x, y, cy, sy, u0, u1, -half_width, half_width, sub, rows, cols)
    assert 0 <= i0 <= i1 <= rows and 0 <= j0 <= j1 <= cols
    inside = set()
    for i in range(rows):
        for j in range(cols):
            u, v = _local(i, j, sub, x, y, cy, sy)
            if u0 <= u <= u1 and abs(v) <= half_width:
                inside.add((i, j))
    window = {(i, j) for i in range(i0, i1) for j in range(j0, j1)}
    assert inside <= window
    if yaw in (0.0, math.pi / 2, -math.pi / 2, math.pi):
        margin = 1e-6 * sub + 1e-12
        near = set()
        for i in range(rows):
            for j in range(cols):
                u, v = _local(i, j, sub, x, y, cy, sy)
                if u0 - margin <= u <= u1 + margin and abs(v) <= half_width + margin:
                    near.add((i, j))
        assert window <= near


def test_cos_sin_is_exact_for_a_square_heading_and_maths_own_otherwise():
    for yaw, exact in zip(SQUARE, ((1.0, 0.0), (0.0, 1.0), (0.0, -1.0), (-1.0, 0.0)), strict=True):
        assert cos_sin(yaw) == exact
        assert cos_sin(yaw) == pytest.approx((math.cos(yaw), math.sin(yaw)), abs=1e-15)
    for yaw in (0.3, -2.0, math.pi / 2 + 1e-12, 1e-300):
        assert cos_sin(yaw) == (math.cos(yaw), math.sin(yaw))


def _worklist(fine, loose, blocked, max_diff, i0, i1, j0, j1, touched):
    """``relax_local`` as first written: every window sub-cell pushed, then popped (LIFO)."""
    rows, cols = fine.shape
    stack, queued = [], np.zeros(fine.shape, dtype=bool)

    def push(i, j):
        if not queued[i, j]:
            queued[i, j] = True
            stack.append((i, j))

    for i in range(i0, i1):
        for j in range(j0, j1):
            if not blocked[i, j]:
                push(i, j)
    moved = 0
    while stack:
        i, j = stack.pop()
        queued[i, j] = False
        for ni, nj in ((i + 1, j), (i - 1, j), (i, j + 1), (i, j - 1)):
            if not (0 <= ni < rows and 0 <= nj < cols):
                continue
            diff = fine[i, j] - fine[ni, nj]
            if abs(diff) <= max_diff or blocked[ni, nj]:
                continue
            src, dst = ((i, j), (ni, nj)) if diff > 0 else ((ni, nj), (i, j))
            t = (abs(diff) - max_diff + 1) // 2
            fine[src] -= t
            fine[dst] += t
            loose[src] -= min(t, loose[src])
            loose[dst] += t
            moved += t
            touched[:] = (
                min(touched[0], i, ni), max(touched[1], i, ni),
                min(touched[2], j, nj), max(touched[3], j, nj),
            )  # fmt: skip
            push(i, j)
            push(ni, nj)
    return moved


@settings(max_examples=200, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    rows=st.integers(1, 9),
    cols=st.integers(1, 9),
    spread=st.sampled_from([3, 10, 40]),
    max_diff=st.integers(1, 6),
    blocked_share=st.sampled_from([0.0, 0.2, 0.5]),
)
def test_the_avalanche_settles_as_a_plain_worklist_does(
    seed, rows, cols, spread, max_diff, blocked_share
):
    """``relax_local`` passes over the window's quiet sub-cells instead of queuing them; it
    must leave the field, its loose soil, ``touched`` and the quanta moved exactly as the
    worklist that queues every one of them (slopes that settle in cascades, blocked cells,
    windows at the field's border)."""
    rng = np.random.default_rng(seed)
    fine = rng.integers(0, spread, (rows, cols)).astype(np.int64)
    loose = (fine * rng.random((rows, cols))).astype(np.int64)
    blocked = rng.random((rows, cols)) < blocked_share
    i0, i1 = sorted(rng.integers(0, rows + 1, 2))
    j0, j1 = sorted(rng.integers(0, cols + 1, 2))
    big = rows + cols
    want = [fine.copy(), loose.copy(), np.array([big, -1, big, -1])]
    moved = _worklist(*want[:2], blocked, max_diff, i0, i1, j0, j1, want[2])
    got = [fine.copy(), loose.copy(), np.array([big, -1, big, -1])]
    stack = np.zeros(fine.size, dtype=np.int64)
    queued = np.zeros(fine.shape, dtype=bool)
    assert relax_local(*got[:2], blocked, max_diff, i0, i1, j0, j1, stack, queued, got[2]) == moved
    for a, b in zip(got, want, strict=True):
        np.testing.assert_array_equal(a, b)
    assert not queued.any()


@settings(max_examples=300, deadline=None)
@given(
    x=st.floats(-1.5, 7.0),  # the field: 4-6.7 m; a rectangle may lie wholly off it
    y=st.floats(-1.5, 7.0),
    aligned=st.booleans(),
    yaw=st.sampled_from(SQUARE),
    u0=st.floats(-0.6, 0.6),
    length=st.floats(0.0, 0.8),
    half_width=st.floats(0.0, 0.4),
    sub=st.sampled_from([0.0625, 0.25 / 3, 0.05]),
)
def test_a_square_robots_band_is_the_sub_cells_its_test_selects(
    x, y, aligned, yaw, u0, length, half_width, sub
):
    """For a square heading ``_band`` gives whole rows and columns without testing each
    sub-cell: they must be exactly the sub-cells the per-sub-cell test selects (robots on
    sub-cell corners, as offline, or anywhere, as in ``dynamics``)."""
    if aligned:
        x, y = round(x / sub) * sub, round(y / sub) * sub
    rows = cols = 80
    cy, sy = cos_sin(yaw)
    u1 = u0 + length
    i0, i1, j0, j1, every = _band(x, y, cy, sy, u0, u1, half_width, sub, rows, cols)
    assert every
    selected = set()
    for i in range(rows):
        for j in range(cols):
            u, v = _local(i, j, sub, x, y, cy, sy)
            if u0 <= u < u1 and abs(v) < half_width:
                selected.add((i, j))
    assert {(i, j) for i in range(i0, i1) for j in range(j0, j1)} == selected


@settings(max_examples=200, deadline=None)
@given(
    x=st.floats(-0.3, 3.3),
    y=st.floats(-0.3, 3.3),
    yaw=st.sampled_from(SQUARE),
    wings=st.booleans(),
    wing=st.sampled_from([0.0, 0.05, 0.25]),
)
def test_a_square_bodys_stamp_is_the_sub_cells_under_it(x, y, yaw, wings, wing):
    """``stamp_body`` marks a square body by rows and columns: the same sub-cells as the
    test of each sub-cell's centre against the body and its end plates."""
    sub, half = 0.0625, CELL
    mask = np.zeros((48, 48), dtype=bool)
    stamp_body(mask, x, y, yaw, sub, half, half, wings, wing)
    cy, sy = cos_sin(yaw)
    want = np.zeros_like(mask)
    for i in range(48):
        for j in range(48):
            u, v = _local(i, j, sub, x, y, cy, sy)
            plate = wings and half <= u < half + wing and half <= abs(v) < half + sub
            want[i, j] = (abs(u) < half and abs(v) < half) or plate
    np.testing.assert_array_equal(mask, want)
