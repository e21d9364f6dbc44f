"""The physical soil's presets (``dome``, ``lunar``), robot forces and terramechanics traction."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from ant_controller.layout import BLADE_BELOW, BLADE_LEVEL
from blueprint_server.blueprint import default_blueprint
from excavation_sim.dynamics import Dynamics, DynamicsParams
from excavation_sim.presets import capacity_rows, push_rows, source_rows
from excavation_sim.soil import (
    PRESETS,
    SoilError,
    SoilParams,
    Terrain,
    calibrate,
    stall_capacity,
)
from excavation_sim.world import COL, HEADING, ROW, World

CELL, UNIT = 0.25, 0.05


def preset(name: str, **changes) -> SoilParams:
    return replace(SoilParams(soil=f"physical:{name}").resolved(), **changes)


def test_every_preset_value_has_a_source_and_validates():
    assert set(PRESETS) == {"grid", "dome", "lunar"}
    for name, p in PRESETS.items():
        assert p.title
        for key in p.values:
            assert len(p.sources[key]) > 10, (name, key)
        resolved = SoilParams(soil=f"physical:{name}").resolved()
        assert all(getattr(resolved, k) == v for k, v in p.values.items())
    assert len(source_rows()) == 2 + sum(len(p.values) for p in PRESETS.values())


def test_the_dome_preset_is_the_papers_robot():
    """15 kg, at most 10 N on the blade, L1 full at 10 N (section 6.2)."""
    p = preset("dome")
    physics = calibrate(p, CELL, UNIT)
    assert physics.mass == 15.0 and physics.blade_limit == 10.0 and physics.load_scale() == 10.0
    assert p.force_control and p.traction == "terramechanics"
    # the wheels, not a motor rating, give the full push: traction less rolling resistance
    wheels = physics.wheels
    assert physics.motor[1] == pytest.approx(wheels.thrust(1.0) - wheels.rolling)
    assert physics.motor[0] == pytest.approx(p.normal_fraction * physics.motor[1])


def test_the_grid_preset_still_stalls_at_the_grid_capacities():
    p = preset("grid")
    assert stall_capacity(p, CELL, UNIT, False) == pytest.approx(12.5, abs=0.5)
    assert stall_capacity(p, CELL, UNIT, True) == pytest.approx(24.5, abs=0.5)


def test_the_quarter_scale_lunar_robot_stalls_where_the_full_size_one_does():
    """Similitude: lengths / 4, cohesion / 4, masses and forces / 64 give the same push in
    soil units as the full-size robot (300 W at 0.3 m/s, 819 kg, 1 m cells and units)."""
    quarter = preset("lunar")
    full = replace(
        quarter,
        drive_power=300.0,
        push_speed=0.3,
        robot_mass=quarter.robot_mass * 64,
        cohesion=quarter.cohesion * 4,
        shear_cohesion=quarter.shear_cohesion * 4,
        contact_width=quarter.contact_width * 4,
        contact_length=quarter.contact_length * 4,
        blade_height=quarter.blade_height * 4,
    )
    assert calibrate(full, 1.0, 1.0).motor[1] == pytest.approx(1000.0)
    for throttle in (False, True):
        small = stall_capacity(quarter, 0.25, 0.25, throttle)
        big = stall_capacity(full, 1.0, 1.0, throttle)
        assert small is not None and small == pytest.approx(big, abs=0.02)


def test_the_presets_table_lists_each_with_its_capacities():
    rows = capacity_rows()
    assert len(rows) == 2 + len(PRESETS)
    assert all("| 12 / 24 |" in r for r in rows[2:])


# --- terramechanics ------------------------------------------------------------------------


def test_bekker_sinkage_and_rolling_resistance():
    p = preset("dome")
    t = Terrain.of(p, 15.0)
    b, l, n = p.contact_width, p.contact_length, p.bekker_n
    modulus = p.bekker_kc / b + p.bekker_kphi
    assert modulus * t.sinkage**n == pytest.approx(15.0 * p.gravity / (2 * b * l))
    assert t.rolling == pytest.approx(2 * b * modulus * t.sinkage ** (n + 1) / (n + 1))
    heavier = Terrain.of(p, 30.0)
    assert heavier.sinkage > t.sinkage and heavier.rolling > 2 * t.rolling


def test_janosi_thrust_rises_with_slip_and_slip_for_inverts_it():
    t = Terrain.of(preset("dome"), 15.0)
    slips = np.linspace(0.01, 1.0, 50)
    thrust = [t.thrust(s) for s in slips]
    assert all(a < b for a, b in zip(thrust, thrust[1:], strict=False))
    assert thrust[-1] < t.shear_max
    for s in (0.05, 0.3, 0.9):
        assert t.slip_for(t.thrust(s)) == pytest.approx(s, abs=1e-5)
    assert t.slip_for(t.thrust(1.0) * 1.01) is None
    assert t.slip_for(0.0) == 0.0


def test_a_heavier_push_slips_more_and_stalls_past_the_wheels():
    physics = calibrate(preset("dome", blade_limit=0.0), CELL, UNIT)
    factors = [physics.speed_factor(f, f, True) for f in (1.0, 20.0, 60.0, 90.0)]
    assert factors == sorted(factors, reverse=True) and factors[0] < 1.0
    assert physics.speed_factor(physics.motor[1] * 1.01, 0.0, True) == 0.0
    assert physics.speed_factor(physics.motor[0] * 1.01, 0.0, False) == 0.0


def test_a_robot_with_too_little_weight_for_its_rolling_resistance_is_refused():
    with pytest.raises(SoilError, match="rolling"):
        calibrate(preset("dome", contact_width=0.001, bekker_kc=0.0, bekker_kphi=1.0), CELL, UNIT)


# --- the dome robot's blade force control --------------------------------------------------


def dome_world() -> World:
    bp = default_blueprint(1)
    world = World.scenario(bp.zones, bp.goal, 1, 0, 0)
    world.robots[0, [ROW, COL, HEADING]] = (6, 1, 1)
    return world


@pytest.mark.parametrize("force_control", [True, False])
def test_the_dome_blade_rises_to_its_force_limit_instead_of_stalling(force_control):
    """A blade set below on flat sand meets more than 10 N at once: with the paper's force
    control it rises and the robot skims on; without, the push stalls."""
    soil = SoilParams(soil=f"physical:dome,force_control={str(force_control).lower()}")
    dyn = Dynamics(dome_world(), DynamicsParams.exact(), CELL, np.random.default_rng(0), soil=soil)
    dyn.set_blade(0, BLADE_BELOW)
    dyn.throttle[0] = True
    x0 = dyn.bodies[0, 0]
    for _ in range(40):
        dyn.command(0, 0.15, 0.0)
        dyn.step()
    advanced = dyn.bodies[0, 0] - x0
    if force_control:
        assert advanced > 0.05 and dyn.counters.slips == 0
        assert dyn.blade_force(0, 10.0) <= 10.0 + 1e-9
        assert dyn.soil.volume() == 0  # it still moved soil: conserved, none made
        assert np.abs(dyn.soil.fine).sum() > 0
    else:
        assert advanced == 0.0 and dyn.counters.slips == 40


def test_terramechanics_slows_a_loaded_push():
    """The same push on the dome's wheels: a heavier pile, more slip, less ground covered."""
    travelled = []
    for units in (0.0, 0.2):
        dyn = Dynamics(
            dome_world(),
            DynamicsParams.exact(),
            CELL,
            np.random.default_rng(0),
            soil=SoilParams(soil="physical:dome"),
        )
        dyn.set_blade(0, BLADE_LEVEL)
        dyn.throttle[0] = True
        x, y, yaw = dyn.bodies[0]
        if units:
            dyn.soil.heap(x, y, yaw, units)
        dyn.command(0, 0.15, 0.0)
        dyn.step()
        travelled.append(dyn.bodies[0, 0] - x)
    assert travelled[1] < travelled[0] < 0.15 * 0.05
    assert not math.isclose(travelled[0], travelled[1])


def test_the_docs_tables_are_the_presets():
    """docs/world-model.md shows what ``python -m excavation_sim.presets`` prints."""
    from pathlib import Path

    text = (Path(__file__).parent.parent / "docs" / "world-model.md").read_text()
    tables = (("capacities", capacity_rows()), ("push", push_rows()), ("sources", source_rows()))
    for tag, rows in tables:
        start = text.index(f"<!-- presets:{tag} -->\n") + len(f"<!-- presets:{tag} -->\n")
        end = text.index(f"<!-- /presets:{tag} -->")
        assert text[start:end].strip() == "\n".join(rows), (
            f"rerun python -m excavation_sim.presets ({tag})"
        )


def test_wheels_that_spin_in_place_dig_the_robot_in():
    """The dome robot without its blade limit stalls in a 5 cm cut once its heap has grown;
    its slipping wheels carry soil back from under its rear half, so the rear sinks and the
    nose rises; soil is conserved. With coulomb wheels nothing is dug."""
    for traction, digs in (("terramechanics", True), ("coulomb", False)):
        soil = SoilParams(soil=f"physical:dome,blade_limit=0,traction={traction}")
        dyn = Dynamics(dome_world(), DynamicsParams.exact(), CELL, np.random.default_rng(0), soil)
        dyn.set_blade(0, BLADE_BELOW)
        dyn.throttle[0] = True
        total = dyn.soil.volume()
        for _ in range(100):  # into the cut until its heap stalls it
            dyn.command(0, 0.15, 0.0)
            dyn.step()
        x, y, yaw = dyn.bodies[0]
        pitch, slips = dyn.soil.pitch(x, y, yaw), dyn.counters.slips
        assert slips > 0
        for _ in range(300):
            dyn.command(0, 0.15, 0.0)
            dyn.step()
        assert dyn.counters.slips == slips + 300  # stuck in the cut from then on
        assert tuple(dyn.bodies[0]) == (x, y, yaw)
        assert dyn.soil.volume() == total
        assert (dyn.soil.pitch(x, y, yaw) > pitch + 1e-3) == digs


@pytest.mark.parametrize("spec", ["physical:dome", "physical:lunar", "physical:dome,blade_limit=0"])
def test_every_preset_conserves_soil_to_the_quantum(spec):
    """Random terrain, blades, throttle and commands on each preset (force control,
    terramechanics slip and dig-in included): the total never changes by a quantum, and the
    loose soil stays a layer on the firm ground."""
    rng = np.random.default_rng(11)
    bp = default_blueprint(1)
    world = World.scenario(bp.zones, bp.goal, 2, 3, 0)
    world.heights[:] = rng.integers(-2, 3, world.heights.shape)
    dyn = Dynamics(world, DynamicsParams(), CELL, np.random.default_rng(0), SoilParams(soil=spec))
    total, blades = dyn.soil.volume(), [BLADE_BELOW, BLADE_LEVEL]
    firm = dyn.soil.fine.copy()
    for step in range(300):
        if step % 30 == 0:
            for k in range(2):
                dyn.set_blade(k, int(rng.choice(blades)))
                dyn.throttle[k] = bool(rng.integers(0, 2))
                dyn.command(k, float(rng.uniform(-0.1, 0.3)), float(rng.uniform(-1, 1)))
        dyn.step()
        assert dyn.soil.volume() == total, step
        # loose soil is never negative; the firm ground under it only ever loses soil
        assert (dyn.soil.loose >= 0).all(), step
        now = dyn.soil.fine - dyn.soil.loose
        assert (now <= firm).all(), step
        firm = now
    assert dyn.soil.loose.sum() > 0
