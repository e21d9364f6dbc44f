"""Physical soil's switches, specs and fixes (docs/world-model.md, "Departures from the grid").

Each departure of ``soil: physical`` from the grid has a switch (the attribution study turns
them one at a time); the artifacts are fixed: refusals of an engaged blade, one rounding rule
for the offline and ROS paths, capacities from the world's profile.
"""

from __future__ import annotations

import numpy as np
import pytest

from ant_controller.layout import BLADE_ABOVE, BLADE_LEVEL
from ant_controller.sensing import blade_volume
from blueprint_server.blueprint import default_blueprint
from excavation_common.messages import heights_to_units
from excavation_sim.dynamics import Dynamics, DynamicsParams
from excavation_sim.rules import WORLD_PROFILES
from excavation_sim.soil import (
    PRESETS,
    Site,
    Soil,
    SoilError,
    SoilParams,
    calibrate,
    check_soil,
    parse_soil,
)
from excavation_sim.world import BLADE, COL, HEADING, ROW, STUCK, World

CELL, UNIT = 0.25, 0.05


def world_of(robots: int = 1, profile: str = "v1") -> World:
    bp = default_blueprint(1)
    return World.scenario(bp.zones, bp.goal, robots, 0, 0, rules=WORLD_PROFILES[profile])


def dynamics(world: World, spec: str = "physical") -> Dynamics:
    return Dynamics(
        world, DynamicsParams.exact(), CELL, np.random.default_rng(0), soil=SoilParams(soil=spec)
    )


# --- specs ---------------------------------------------------------------------------------


def test_specs_name_a_preset_and_override_parameters():
    assert parse_soil("grid") == ("grid", "", [])
    assert parse_soil("physical") == ("physical", "grid", [])
    p = SoilParams(soil="physical,fill=false,load=volume,repose_angle=30").resolved()
    assert (p.fill, p.load, p.repose_angle, p.soil) == (False, "volume", 30.0, p.soil)
    assert p.resolved() == p
    assert set(PRESETS) >= {"grid"}


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("clay", "'clay' is not one of grid, physical"),
        ("physical:moon", "unknown preset 'moon'"),
        ("grid:dome", "takes no preset"),
        ("physical,fill=maybe", "fill = 'maybe' is not a bool"),
        ("physical,mass", "'mass' is not KEY=VALUE"),
        ("physical,soil=grid", "'soil=grid' is not KEY=VALUE"),
        ("physical,repose_angle=200", "repose_angle = 200.0: must be <= 80.0"),
        ("physical,load=weight", "load = 'weight': must be one of force, volume"),
    ],
)
def test_a_bad_spec_is_named(spec, message):
    with pytest.raises(SoilError, match=message) as e:
        check_soil(spec)
    assert repr(spec) in str(e.value)


def test_deployments_and_sites_check_the_spec():
    from excavation_bringup.deployment import Deployment, DeploymentError

    Deployment("hand-coded", 2, 10, 0, drive="continuous", soil="physical,epsilon=false").check()
    with pytest.raises(DeploymentError, match="unknown preset 'moon'"):
        Deployment("hand-coded", 2, 10, 0, drive="continuous", soil="physical:moon").check()


# --- the fixes -----------------------------------------------------------------------------


@pytest.mark.parametrize("half", [0.5, 1.5, 2.5, -0.5, -1.5, -2.5, 120.5, -299.5])
def test_offline_and_ros_paths_round_half_unit_cells_alike(half):
    """A cell whose sub-cell mean is a half: the world and the height map message agree.

    The world rounds the means (halves up) into the heights the offline controllers sense;
    ``dynamics`` publishes the means in metres as float32 and the controller node converts
    them back with :func:`heights_to_units`: the same whole units.
    """
    site = Site(4, 4, CELL, UNIT)
    soil = Soil(np.zeros((4, 4), dtype=np.int64), site, SoilParams(soil="physical"))
    per_cell = soil.s * soil.s * soil.q
    target = int(round(half * per_cell))
    soil.fine[:4, :4] = 0
    soil.fine[0, 0] = target  # cell (0, 0) holds ``half`` units in one sub-cell
    soil.fine[4, 4] = target - 1  # cell (1, 1): one quantum less than the half
    offline = np.zeros((4, 4), dtype=np.int32)
    soil.cell_heights(offline)
    published = (soil.cell_means() * UNIT).astype(np.float32)  # dynamics' height map
    through_ros = heights_to_units(published.astype(np.float64), UNIT)
    assert np.array_equal(offline, through_ros)
    assert offline[0, 0] == int(np.floor(half + 0.5))
    assert offline[1, 1] == int(np.floor(half + 0.5)) - 1


def test_np_round_would_have_disagreed():
    """The old conversion (numpy's round: halves to even) reads 0.5 units as 0."""
    assert np.round(0.5) == 0 and heights_to_units(np.array([0.025]), UNIT)[0] == 1


@pytest.mark.parametrize(("profile", "loads"), [("v1", (12, 24)), ("paper", (24, 24))])
def test_the_calibration_takes_the_profiles_capacities(profile, loads):
    dyn = dynamics(world_of(profile=profile))
    motor = dyn.soil.physics.motor
    assert motor == calibrate(dyn.soil.params, CELL, UNIT, loads).motor
    assert (motor[0] == motor[1]) == (loads[0] == loads[1])


def facing_a_robot(refusals: bool) -> Dynamics:
    """Robot 0 faces east with a level blade; robot 1 stands just beyond its blade cells."""
    world = world_of(robots=2)
    world.robots[0, [ROW, COL, HEADING]] = (6, 3, 1)
    world.robots[1, [ROW, COL, HEADING]] = (6, 6, 1)
    dyn = dynamics(world, f"physical,refusals={str(refusals).lower()}")
    dyn.set_blade(0, BLADE_LEVEL)
    return dyn


@pytest.mark.parametrize("refusals", [True, False])
def test_an_engaged_blade_refuses_to_push_into_another_robot(refusals):
    """The grid refuses the move (the blade's cells ahead are the other robot's); so does
    physical soil with ``refusals``; without, the move was made as with the blade home."""
    dyn = facing_a_robot(refusals)
    for _ in range(30):  # 0.3 m: one committed move (a second would overlap robot 1)
        dyn.command(0, 0.2, 0.0)
        dyn.step()
    moved = int(dyn.world.robots[0, COL]) != 3
    assert moved != refusals
    assert bool(dyn.world.robots[0, STUCK]) == refusals
    assert dyn.counters.refused == (1 if refusals else 0)


@pytest.mark.parametrize("epsilon", [True, False])
def test_an_empty_blade_set_above_cuts_as_level_with_the_epsilon_rule(epsilon):
    world = world_of()
    world.robots[0, [ROW, COL, HEADING]] = (6, 3, 1)
    dyn = dynamics(world, f"physical,epsilon={str(epsilon).lower()}")
    dyn.set_blade(0, BLADE_ABOVE)
    lift = 0 if epsilon else dyn.soil.q
    assert dyn.edge(0) - dyn.ground[0] == lift
    x, y, yaw = dyn.bodies[0]
    dyn.soil.heap(x, y, yaw, 4)  # with soil against it, the blade stays above
    dyn.set_blade(0, BLADE_ABOVE)
    assert dyn.edge(0) - dyn.ground[0] == dyn.soil.q


@pytest.mark.parametrize("fill", [True, False])
def test_a_hollow_under_the_edge_draws_from_the_soil_ahead_only_with_fill(fill):
    """A one-sub-cell trench, a mound beyond it, a level blade that holds nothing.

    With ``fill`` the trench takes the mound's soil above the edge as the edge passes it;
    without, it stays a trench and the mound is pushed on. (Soil that a pushed pile drops
    into a hollow stays there either way: it lies above the edge when the edge comes.)
    """
    world = world_of()
    world.robots[0, [ROW, COL, HEADING]] = (6, 1, 1)
    dyn = dynamics(world, f"physical,fill={str(fill).lower()},repose=false")
    dyn.set_blade(0, BLADE_LEVEL)
    soil = dyn.soil
    rows = slice(6 * 4, 8 * 4)
    trench, mound = 4 * 4 + 1, 4 * 4 + 2  # sub-cell columns ahead of the blade
    soil.fine[rows, trench] -= soil.q
    soil.fine[rows, mound] += soil.q
    total = soil.volume()
    for _ in range(60):
        dyn.command(0, 0.2, 0.0)
        dyn.step()
    assert dyn.bodies[0, 0] + CELL > (mound + 1) * soil.sub  # the edge passed both
    assert soil.volume() == total
    filled = int(soil.fine[rows, trench].sum())
    assert (filled == 0) == fill
    assert (filled == -soil.q * 8) == (not fill)


def test_the_load_and_fitness_switches_read_the_grid():
    world = world_of()
    world.robots[0, [ROW, COL, HEADING]] = (6, 3, 1)
    dyn = dynamics(world, "physical,load=volume,fitness_heights=rounded")
    dyn.set_blade(0, BLADE_LEVEL)
    x, y, yaw = dyn.bodies[0]
    dyn.soil.heap(x, y, yaw, 5)
    dyn.soil.cell_heights(world.heights)
    r = world.robots[0]
    volume = blade_volume(world.heights, int(r[ROW]), int(r[COL]), int(r[HEADING]), BLADE_LEVEL)
    assert volume > 0
    assert dyn.blade_force(0, 24.0) == pytest.approx(float(volume))
    assert dyn.fitness() == world.fitness()
    assert int(world.robots[0, BLADE]) == BLADE_LEVEL


def test_repose_off_keeps_a_heap_standing():
    world = world_of()
    world.robots[0, [ROW, COL, HEADING]] = (6, 3, 1)
    for repose, changes in ((True, True), (False, False)):
        dyn = dynamics(world.copy(), f"physical,repose={str(repose).lower()}")
        x, y, yaw = dyn.bodies[0]
        dyn.soil.heap(x, y, yaw, 12)
        before = dyn.soil.fine.copy()
        dyn.step()
        assert (not np.array_equal(before, dyn.soil.fine)) == changes
