"""The paper profile: every reading of the paper is a switch, and every switch is honoured.

Each switch is run on and off on the same input and the outcomes are asserted to differ
in the stated way, so a switch the code ignored would fail here. Blade cases are worked
by hand: robot at (2, 2) facing north, front wheels on row 3, blade cells row 4 (columns
2 and 3), the cells the blade moves into row 5.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json

import numpy as np
import pytest
from helpers.worlds import make_world

from ant_controller import layout
from ant_controller.controller import Controller, ControllerCore
from ant_controller.genome import random_genome
from ant_controller.genome_io import genome_to_dict
from ant_controller.hand_coded import HandCodedRules, hand_coded, hand_coded_program
from ant_controller.layout import (
    BLADE_ABOVE,
    BLADE_BELOW,
    BLADE_HOME,
    BLADE_LEVEL,
    H1,
    LEFT,
    N_SENSORS,
    Z2,
    Z3,
    Z_ABOVE,
    Z_DONT_CARE,
    Z_DUMP,
    Z_LEVEL,
    mask_of,
)
from ant_controller.readings import CONTROLLER_PROFILES, H1_ABSOLUTE, H1_RELATIVE, PROFILE_NAMES
from ant_controller.sensing import sensor_vector
from ant_controller.sensing_reference import sense_reference
from ant_evolution import ga
from ant_evolution.errors import CheckpointError, ConfigError
from ant_evolution.evolve import EvolveConfig, config_from_dict, run_evolution
from ant_evolution.profiles import PROFILES, SWITCHES, assignment, resolve_switches
from blueprint_server.blueprint import default_blueprint, resolve_blueprint
from excavation_common.constants import EAST, NORTH, ZONE_DIG, ZONE_DUMP
from excavation_sim.rules import PAPER_RULES, V1_RULES, WORLD_PROFILES
from excavation_sim.world import (
    ROW,
    STUCK,
    World,
    place_robots,
    scenario_start,
)
from excavation_sim.world_reference import step_reference

FORWARD = mask_of(2)
THROTTLE = mask_of(1)
FILL = dataclasses.replace(V1_RULES, soil_fill=True)


def step_both(w: World, mask: int) -> None:
    """Step the kernel and check the plain-Python reference does the same."""
    ref = step_reference(w.heights, w.robots, w.active, [mask], int(w.rng[0]), w.params)
    w.step([mask])
    assert np.array_equal(w.heights, ref[0]) and np.array_equal(w.robots, ref[1])


# --- 1. soil: fill and backfill by the paper's equations -------------------------------------


@pytest.mark.parametrize(
    ("blade", "blade_row", "next_row", "v1_after", "paper_after"),
    [
        # level blade over a cut (blade cells 1 below the wheels), soil ahead: the paper's
        # equation sets the old blade cells to the wheel level with soil from ahead
        (BLADE_LEVEL, (-1, -1), (2, 2), ((-1, -1), (2, 2)), ((0, 0), (1, 1))),
        # the same with only 1 unit ahead in column 0 and none in column 1: a partial
        # fill where the cell ahead holds less than the deficit, none where it holds none
        (BLADE_LEVEL, (-2, -1), (1, 0), ((-2, -1), (1, 0)), ((-1, -1), (0, 0))),
        # level blade over a pit edge with nothing ahead above the wheels: no fill (the
        # blade never digs the cell ahead to fill the one behind)
        (BLADE_LEVEL, (-1, -1), (-1, -1), ((-1, -1), (-1, -1)), ((-1, -1), (-1, -1))),
        # blade above with soil against column 0 (eps = 1, cutting level 1): column 0
        # leaves 1 unit, column 1 (flat) is raised to 1 from its cell ahead
        (BLADE_ABOVE, (3, 0), (0, 2), ((1, 0), (2, 2)), ((1, 1), (2, 1))),
        # blade below: cutting level one under the wheels; a deeper hole is raised to it
        (BLADE_BELOW, (-3, 0), (2, 0), ((-3, -1), (2, 1)), ((-1, -1), (0, 1))),
    ],
)
def test_fill_and_backfill_hand_worked(blade, blade_row, next_row, v1_after, paper_after):
    for rules, (expect_blade, expect_next) in ((V1_RULES, v1_after), (FILL, paper_after)):
        w = make_world([(2, 2, NORTH, blade)], rules)
        w.heights[4, 2:4] = blade_row
        w.heights[5, 2:4] = next_row
        total = int(w.heights.sum())
        step_both(w, FORWARD | THROTTLE)
        assert w.robots[0, STUCK] == 0 and w.robots[0, ROW] == 3
        assert tuple(w.heights[4, 2:4]) == expect_blade, rules
        assert tuple(w.heights[5, 2:4]) == expect_next, rules
        assert int(w.heights.sum()) == total


def test_backfill_undoes_a_cut():
    """A level blade pushing a pile over another robot's cut fills the cut behind it."""
    heights = np.zeros((8, 8), np.int32)
    heights[4, 2:4] = -1  # a cut
    heights[5, 2:4] = 3  # a pile just beyond it
    outcomes = {}
    for rules in (V1_RULES, FILL):
        w = make_world([(2, 2, NORTH, BLADE_LEVEL)], rules, heights=heights.copy())
        step_both(w, FORWARD)
        outcomes[rules.soil_fill] = w.heights[4, 2:4].tolist()
    assert outcomes == {False: [-1, -1], True: [0, 0]}


def test_home_blade_never_fills():
    w = make_world([(2, 2, NORTH, BLADE_HOME)], FILL)
    w.heights[4, 2:4] = -1
    w.heights[5, 2:4] = 3
    step_both(w, FORWARD)
    assert w.heights[4, 2:4].tolist() == [-1, -1] and w.heights[5, 2:4].tolist() == [3, 3]


@pytest.mark.parametrize("profile", PROFILE_NAMES)
@pytest.mark.parametrize("seed", range(6))
def test_soil_is_conserved_over_random_runs_of_every_profile(profile, seed):
    rules = WORLD_PROFILES[profile]
    rng = np.random.default_rng(seed)
    bp = default_blueprint(int(rng.integers(1, 4)), rules.fitted_site)
    w = World.scenario(bp.zones, bp.goal, 6, seed, 0, rules)
    w.heights[:] = rng.integers(-3, 4, w.heights.shape)
    total = int(w.heights.sum())
    for _ in range(300):
        masks = (rng.random((6, 12)) < 0.3) @ (1 << np.arange(12))
        w.step(masks)
    assert int(w.heights.sum()) == total


# --- 2. push capacity and throttle-up ---------------------------------------------------------


def test_push_capacity_is_24_at_all_times_under_the_paper():
    outcomes = {}
    for rules in (V1_RULES, PAPER_RULES):
        w = make_world([(2, 2, NORTH, BLADE_LEVEL)], rules)
        w.heights[4, 2:4] = (10, 10)  # 20 units against the blade: over 12, under 24
        step_both(w, FORWARD)
        outcomes[rules is PAPER_RULES] = int(w.robots[0, STUCK])
    assert outcomes == {False: 1, True: 0}
    w = make_world([(2, 2, NORTH, BLADE_LEVEL)], PAPER_RULES)
    w.heights[4, 2:4] = (13, 12)  # 25 units: over 24 even with throttle-up
    step_both(w, FORWARD | THROTTLE)
    assert w.robots[0, STUCK] == 1


def test_throttle_up_raises_the_climb_limit_under_the_paper():
    for throttle, stuck in ((0, 1), (THROTTLE, 0)):
        w = make_world([(2, 2, NORTH, BLADE_HOME)], PAPER_RULES)
        w.heights[4, 2] = 2  # a 2-unit step
        step_both(w, FORWARD | throttle)
        assert w.robots[0, STUCK] == stuck
    climb = dataclasses.replace(PAPER_RULES, throttle_climb=1)
    w = make_world([(2, 2, NORTH, BLADE_HOME)], climb)
    w.heights[4, 2] = 2
    step_both(w, FORWARD | THROTTLE)
    assert w.robots[0, STUCK] == 1  # the switch is what lets it climb


# --- 3. the worksite --------------------------------------------------------------------------


def _inside(zones, robots, allowed) -> list[bool]:
    return [bool(np.isin(zones[r : r + 2, c : c + 2], allowed).all()) for r, c in robots[:, :2]]


def test_robots_start_on_the_worksite_under_the_paper():
    bp = default_blueprint(1)
    outside_v1 = 0
    for i in range(30):
        robots, _, _ = scenario_start(bp.shape, 4, 4, 7, i, bp.zones)
        assert all(_inside(bp.zones, robots, [ZONE_DIG]))
        robots, _, _ = scenario_start(bp.shape, 4, 4, 7, i)
        outside_v1 += sum(not x for x in _inside(bp.zones, robots, [ZONE_DIG]))
    assert outside_v1 > 30  # anywhere on 16 x 16: most robots start outside the pit


@pytest.mark.parametrize("seed", range(5))
def test_a_full_worksite_spills_into_the_dump_band(seed):
    zones = np.zeros((16, 16), np.uint8)
    zones[2:14, 2:14] = ZONE_DUMP
    zones[6:10, 6:10] = ZONE_DIG  # a 4 x 4 pit holds four robots at most
    robots = place_robots(zones.shape, 10, np.random.default_rng(seed), worksite=zones)
    in_pit = _inside(zones, robots, [ZONE_DIG])
    assert in_pit[0] and 1 <= sum(in_pit) <= 4
    assert all(_inside(zones, robots, [ZONE_DIG, ZONE_DUMP]))
    first_outside = in_pit.index(False)
    assert not any(in_pit[first_outside:])  # the pit is full before the band is used
    occupied = np.zeros(zones.shape, int)
    for r, c in robots[:, :2]:
        occupied[r : r + 2, c : c + 2] += 1
    assert occupied.max() == 1  # never overlapping


def test_fitted_site_is_the_pit_plus_its_dump_band():
    shared, fitted = default_blueprint(2), default_blueprint(2, fitted=True)
    assert shared.shape == (16, 16) and fitted.shape == (12, 12)
    assert (fitted.zones == ZONE_DIG).sum() == 64
    assert (fitted.zones == ZONE_DUMP).sum() == 144 - 64  # no don't-care cells left
    assert resolve_blueprint("default:3", fitted=True).shape == (12, 12)
    # the spec the blueprint server takes to publish the paper profile's site
    assert resolve_blueprint("fitted:3").name == default_blueprint(3, fitted=True).name
    assert np.array_equal(resolve_blueprint("fitted", 2).goal, fitted.goal)


# --- 7. H1 ------------------------------------------------------------------------------------


def test_h1_absolute_is_the_compass_bearing():
    heights = zones = goal = np.zeros((12, 12), np.int32)
    poses = np.array([[4, 4, EAST], [8, 4, NORTH]], dtype=np.int64)  # robot 1 due north
    kw = dict(blade=BLADE_HOME, load_volume=0, stuck=False, tilted=False, memory=False)
    rel = sensor_vector(heights, zones, goal, poses, 0, **kw, h1_frame=H1_RELATIVE)
    ab = sensor_vector(heights, zones, goal, poses, 0, **kw, h1_frame=H1_ABSOLUTE)
    assert rel[H1] == LEFT and ab[H1] == NORTH
    for frame, code in ((H1_RELATIVE, LEFT), (H1_ABSOLUTE, NORTH)):
        assert sense_reference(heights, zones, goal, poses, np.ones(2, bool), 0,
                               BLADE_HOME, 0, False, False, False, frame)[H1] == code  # fmt: skip
    world = make_world([(4, 4, EAST, BLADE_HOME), (8, 4, NORTH, BLADE_HOME)], PAPER_RULES, 12)
    assert world.sense()[0, H1] == NORTH
    assert make_world([(4, 4, EAST, 0), (8, 4, NORTH, 0)], V1_RULES, 12).sense()[0, H1] == LEFT


def test_controller_core_takes_the_h1_frame():
    heights = zones = goal = np.zeros((12, 12), np.int32)
    poses = np.array([[4, 4, EAST], [8, 4, NORTH]], dtype=np.int64)
    readings = CONTROLLER_PROFILES["paper"]
    core = ControllerCore(Controller.hand_coded(readings.hand_coded), h1_frame=readings.h1_frame)
    core.decide(heights, zones, goal, poses, 0, BLADE_HOME, 0, False)
    assert core.codes[H1] == NORTH
    core = ControllerCore(Controller.hand_coded())
    core.decide(heights, zones, goal, poses, 0, BLADE_HOME, 0, False)
    assert core.codes[H1] == LEFT


# --- 6. the hand-coded rules ------------------------------------------------------------------


def _codes(**values) -> np.ndarray:
    v = np.zeros(N_SENSORS, dtype=np.int64)
    v[[Z2, Z3]] = Z_LEVEL
    for k, x in values.items():
        v[getattr(layout, k)] = x
    return v


@pytest.mark.parametrize(
    ("codes", "chain", "union"),
    [
        # don't care with an empty blade: rules 5 and 6 both match in the union
        (dict(Z2=Z_DONT_CARE, Z3=Z_DONT_CARE), mask_of(2, 4), mask_of(2, 3, 4)),
        # an empty blade facing dump cells: no rule of the appendix, rule 12 in the chain
        (dict(Z2=Z_DUMP, Z3=Z_DUMP), mask_of(2, 4), 0),
        # above goal with M1 = 1: rules 9 and 11 (2, 9)
        (dict(Z2=Z_ABOVE, Z3=Z_ABOVE, M1=1), mask_of(2, 9), mask_of(2, 9)),
        # one blade cell level, the other above, M1 = 0: rule 7 first in the chain; the
        # union adds 9 and 10 (blade below, bit set)
        (dict(Z2=Z_LEVEL, Z3=Z_ABOVE), mask_of(2, 4), mask_of(2, 4, 8, 11)),
        # pushing into dump next to don't care: rules 3, 4 and 5
        (dict(Z2=Z_DUMP, Z3=Z_DONT_CARE, L1=2), mask_of(2, 3, 4), mask_of(2, 3, 4, 12)),
        # rules 1 and 2 decide alone in both readings
        (dict(U1=1, Z2=Z_DUMP, L1=1), mask_of(1, 4, 7, 10, 12), mask_of(1, 4, 7, 10, 12)),
        (dict(S1=1, Z2=Z_ABOVE), mask_of(4), mask_of(4)),
    ],
)
def test_hand_coded_chain_and_union(codes, chain, union):
    v = _codes(**codes)
    assert hand_coded(v) == chain == hand_coded_program(v, HandCodedRules(False))
    assert hand_coded(v, union=True) == union == hand_coded_program(v, HandCodedRules(True))
    assert Controller.hand_coded("union").decide(v) == union
    assert Controller.hand_coded("chain").decide(v) == chain


def test_hand_coded_reading_changes_an_evaluation():
    from ant_evolution.evaluate import evaluate

    bp = default_blueprint(1)
    a = evaluate(Controller.hand_coded("chain"), bp, 4, 4, 60, seed=1)
    b = evaluate(Controller.hand_coded("union"), bp, 4, 4, 60, seed=1)
    assert not np.array_equal(a.curves, b.curves)


# --- 4 and 5. mutation, elitism, replication --------------------------------------------------


def _changed(a, b) -> int:
    n = 0
    for ga_, gb in zip(a.cells, b.cells, strict=True):
        for f in dataclasses.fields(ga_):
            x, y = getattr(ga_, f.name), getattr(gb, f.name)
            if isinstance(x, tuple):
                n += sum(u != v for u, v in zip(x, y, strict=True))
            else:
                n += x != y
    return n


def _no_replication(genome):
    return dataclasses.replace(
        genome, tissue=dataclasses.replace(genome.tissue, replication_probability=0.0)
    )


def test_per_gene_mutation_changes_about_one_parameter_per_mutated_gene():
    rng = np.random.default_rng(0)
    parent = _no_replication(random_genome(rng, (100, 100)))
    per_param = ga.GAParams(mutation_prob=0.025)
    per_gene = dataclasses.replace(per_param, mutation_scope="gene")
    a = np.mean([_changed(parent, ga.mutate(rng, parent, per_param)) for _ in range(20)])
    b = np.mean([_changed(parent, ga.mutate(rng, parent, per_gene)) for _ in range(20)])
    assert 60 < a < 120  # ~35 parameters x 100 genes x 0.025
    assert 0.5 < b < 6  # ~100 genes x 0.025


def test_perturbation_stays_within_its_width_and_redraw_does_not():
    rng = np.random.default_rng(1)
    parent = _no_replication(random_genome(rng, (60, 60)))
    width = 0.05
    for operator, bounded in (("perturb", True), ("redraw", False)):
        params = ga.GAParams(mutation_prob=0.2, mutation_operator=operator, mutation_width=width)
        steps = []
        for _ in range(5):
            child = ga.mutate(rng, parent, params)
            for gp, gc in zip(parent.cells, child.cells, strict=True):
                steps += [
                    abs(x - y) for x, y in zip(gp.sensor_weights, gc.sensor_weights, strict=True)
                ]
        moved = [s for s in steps if s > 0]
        assert moved
        assert (max(moved) <= 2 * width + 1e-12) == bounded  # range [-1, 1] is 2 wide


def test_elitism_switch():
    rng = np.random.default_rng(2)
    pop = [random_genome(rng, (5, 8)) for _ in range(10)]
    fit = np.linspace(0, 1, 10)
    for elitism in (0, 1):
        params = ga.GAParams(population=10, elitism=elitism, mutation_prob=0.5)
        out = ga.next_generation(np.random.default_rng(3), pop, fit, params)
        assert (out[0] is pop[9]) == bool(elitism)


def _distance(a, b) -> int:
    return sum(abs(x - y) for x, y in zip(a, b, strict=True))


def test_replication_parent_proportional_spreads_growth():
    rng = np.random.default_rng(4)
    genome = random_genome(rng, (20, 20))
    best = max((g for g in genome.cells if g.expressed and not g.dead), key=lambda g: g.replication)
    parents = {"max": set(), "proportional": set()}
    for rule in parents:
        for i in range(60):
            child = ga.replicate(np.random.default_rng(i), genome, rule)
            if child.n_cells == genome.n_cells:
                continue
            d = child.absolute(child.cells[-1])
            near = [g for g in genome.cells if _distance(genome.absolute(g), d) == 1]
            parents[rule].add(frozenset(genome.absolute(g) for g in near))
    assert all(genome.absolute(best) in s for s in parents["max"])
    assert len(parents["proportional"]) > len(parents["max"])


def test_v1_breeding_is_draw_for_draw_the_original():
    """Two seeded v1 generations hash as they did on main before the profiles existed."""
    rng = np.random.default_rng(11)
    pop = [random_genome(rng, (20, 40), robots=int(rng.integers(1, 8))) for _ in range(8)]
    fit = rng.random(8)
    params = ga.GAParams(population=8, mutation_prob=0.05)
    out = ga.next_generation(np.random.default_rng(12), pop, fit, params)
    out = ga.next_generation(np.random.default_rng(13), out, fit[::-1].copy(), params)
    text = json.dumps([genome_to_dict(g) for g in out], sort_keys=True)
    assert hashlib.sha256(text.encode()).hexdigest()[:16] == "81b65c92ede7c609"
    paper = dataclasses.replace(
        params,
        mutation_scope="gene",
        mutation_operator="perturb",
        replication_parent="proportional",
    )
    other = ga.next_generation(np.random.default_rng(12), pop, fit, paper)
    assert [genome_to_dict(g) for g in other] != [genome_to_dict(g) for g in out]


# --- configuration, profiles and checkpoints ---------------------------------------------------


def test_profiles_set_every_switch_and_keys_override():
    assert set(PROFILES) == set(PROFILE_NAMES)
    for name, values in PROFILES.items():
        assert tuple(values) == SWITCHES
        assert EvolveConfig().with_profile(name).switches() == values
    c = config_from_dict({"profile": "paper", "elitism": 1, "soil_fill": False})
    assert c.profile == "paper" and c.elitism == 1 and not c.soil_fill and c.h1 == "absolute"
    assert c.world_rules == dataclasses.replace(PAPER_RULES, soil_fill=False)
    assert c.ga.mutation_scope == "gene"
    assert EvolveConfig().world_rules == V1_RULES


@pytest.mark.parametrize(
    ("data", "field"),
    [
        ({"profile": "literal"}, "profile"),
        ({"soil_fil": True}, "soil_fil"),
        ({"h1": "compass"}, "h1"),
        ({"mutation_scope": "genome"}, "mutation_scope"),
        ({"normal_load": -1}, "normal_load"),
        ({"neat_activation": "relu"}, "neat_activation"),
        ({"soil_fill": "yes"}, "soil_fill"),
    ],
)
def test_bad_switches_are_named(data, field):
    with pytest.raises(ConfigError, match=field):
        config_from_dict(data, "run.yaml")


def test_v1_run_key_is_the_one_before_profiles():
    assert EvolveConfig().run_key() == "93aa0616a6cf0290"  # main before the profiles
    assert EvolveConfig().with_profile("paper").run_key() != EvolveConfig().run_key()


def test_set_assignments():
    assert assignment("soil_fill=true") == ("soil_fill", True)
    values = resolve_switches("v1", [assignment("normal_load=24"), assignment("site=fitted")])
    assert values["normal_load"] == 24 and values["site"] == "fitted"
    with pytest.raises(ConfigError, match="placement"):
        resolve_switches("v1", [("placement", "everywhere")])


def test_checkpoint_records_its_profile_and_refuses_another(tmp_path):
    config = dataclasses.replace(
        EvolveConfig().with_profile("paper"),
        population=4, generations=2, scenarios=2, steps=5, depths=(1,), neurons=(5, 8),
    )  # fmt: skip
    run_evolution(config, tmp_path, workers=1, stop_after=1)
    data = json.loads((tmp_path / "checkpoint.json").read_text())
    assert data["profile"] == "paper" and data["switches"] == PROFILES["paper"]
    v1 = dataclasses.replace(config.with_profile("v1"), elitism=1)
    with pytest.raises(CheckpointError, match="profile 'paper', not 'v1'"):
        run_evolution(v1, tmp_path, workers=1, resume=True)
    other = dataclasses.replace(config, soil_fill=False)
    with pytest.raises(CheckpointError, match="soil_fill: True there, False here"):
        run_evolution(other, tmp_path, workers=1, resume=True)
    state = run_evolution(config, tmp_path, workers=1, resume=True)
    assert state.generation == 2


# --- 8. NEAT like for like -------------------------------------------------------------------


def test_neat_modular_activation_compiles_to_ants_neuron(tmp_path):
    import neat

    from ant_evolution.baselines.neat_baseline import compile_neat, config_overrides, neat_config
    from ant_evolution.baselines.network import AGG_MEAN, AGG_SUM, decide_program_reference

    outputs = {}
    for activation in ("sigmoid", "modular"):
        cfg = neat_config(tmp_path / f"{activation}.ini", 4, 10, config_overrides(activation))
        pop = neat.Population(cfg, seed=3)
        programs = [compile_neat(g, cfg) for g in pop.population.values()]
        outputs[activation] = programs
    for prog in outputs["sigmoid"]:
        assert set(prog.node_agg.tolist()) == {AGG_SUM} and set(prog.node_act.tolist()) == {4}
    modular = outputs["modular"]
    assert all(set(p.node_agg.tolist()) == {AGG_MEAN} for p in modular)
    assert all(set(p.node_act.tolist()) <= {0, 1, 2, 3} for p in modular)
    assert len({a for p in modular for a in p.node_act.tolist()}) > 1  # the four functions
    assert all(np.abs(p.edge_w).max() <= 1.0 and np.abs(p.node_theta).max() <= 1.0 for p in modular)
    codes = np.array([0, 1, 2, 3, 2, 1, 1, 2, 0, 3, 2, 1, 0, 1])
    mask, _ = decide_program_reference(modular[0], codes)
    assert 0 <= mask < 1 << 12


def test_neat_budget_ant_uses_the_runs_rates(tmp_path):
    from ant_evolution.baselines.neat_baseline import config_overrides, neat_config_text

    library = neat_config_text(10, 5, config_overrides("sigmoid", "library"))
    ant = neat_config_text(10, 5, config_overrides("sigmoid", "ant", 0.025, True, 0.1, 0))
    assert "weight_mutate_rate      = 0.8" in library
    assert "weight_mutate_rate      = 0.025" in ant and "node_add_prob           = 0.05" in ant
    assert "\nelitism                 = 0" in ant
    redraw = neat_config_text(10, 5, config_overrides("sigmoid", "ant", 0.025, False))
    assert "weight_replace_rate     = 0.025" in redraw and "weight_mutate_rate      = 0.0" in redraw
    config = EvolveConfig().with_profile("paper")
    assert (config.neat_activation, config.neat_budget) == ("modular", "ant")


def test_sim_node_runs_a_profile():
    from excavation_common.params import validate
    from excavation_sim.lockstep import SimParams
    from excavation_sim.sim_node import scenario_world

    assert SimParams().profile == "v1"
    with pytest.raises(ValueError, match="profile"):
        validate(SimParams, {"profile": "literal"}, "sim")
    assert validate(SimParams, {"profile": "paper"}, "sim").profile == "paper"
    bp, world = scenario_world("default", 4, 0, 0, WORLD_PROFILES["paper"])
    assert bp.shape == (12, 12) and np.array_equal(world.params, PAPER_RULES.as_array())
    assert all(_inside(bp.zones, world.robots, [ZONE_DIG]))
    bp, world = scenario_world("default", 4, 0, 0)
    assert bp.shape == (16, 16) and np.array_equal(world.params, V1_RULES.as_array())


def test_ant_evolve_profile_and_set_resolve(tmp_path):
    from ant_evolution.cli_evolve import build_parser, resolve_config

    args = build_parser().parse_args(
        ["--out", str(tmp_path), "--profile", "paper", "--set", "elitism=1"]
    )
    config = resolve_config(args)
    assert config.profile == "paper" and config.elitism == 1 and config.soil_fill
    cfg = tmp_path / "run.yaml"
    cfg.write_text("profile: v1\nsoil_fill: true\npopulation: 10\n")
    args = build_parser().parse_args(["--out", str(tmp_path), "--config", str(cfg)])
    config = resolve_config(args)
    assert (config.profile, config.soil_fill, config.h1) == ("v1", True, "relative")
    args = build_parser().parse_args(
        ["--out", str(tmp_path), "--config", str(cfg), "--profile", "paper"]
    )
    config = resolve_config(args)  # the flag replaces the file's profile; its keys still apply
    assert (config.profile, config.soil_fill, config.h1, config.population) == (
        "paper",
        True,
        "absolute",
        10,
    )
    with pytest.raises(SystemExit):
        build_parser().parse_args(["--out", str(tmp_path), "--set", "soil_fil=true"])


def test_ant_eval_and_sweep_take_a_profile(tmp_path, capsys):
    from ant_evolution.cli_eval import main as ant_eval
    from ant_evolution.sweep import main as ant_sweep

    common = ["--hand-coded", "--scenarios", "3", "--steps", "40", "--json"]
    assert ant_eval(common + ["--profile", "paper"]) == 0
    paper = json.loads(capsys.readouterr().out)
    assert ant_eval(common) == 0
    v1 = json.loads(capsys.readouterr().out)
    assert paper["profile"] == "paper" and "profile" not in v1
    assert (
        paper["blueprint"] == "default 12x12 (depth 1)" and v1["blueprint"] == "default (depth 1)"
    )
    assert paper["scores"] != v1["scores"]
    assert ant_eval(common + ["--set", "hand_coded=bogus"]) == 2
    out = tmp_path / "sweep"
    argv = ["--hand-coded", "--robots", "2", "--depths", "1", "--scenarios", "2", "--steps", "20"]
    assert ant_sweep(argv + ["--profile", "paper", "--out", str(out)]) == 0
    assert "profile paper" in (out / "sweep.md").read_text()


def test_load_and_climb_switches_each_act():
    pile = dataclasses.replace(PAPER_RULES, throttle_load=30)
    w = make_world([(2, 2, NORTH, BLADE_LEVEL)], pile)
    w.heights[4, 2:4] = (13, 12)  # 25 units: over 24, within 30 with throttle-up
    step_both(w, FORWARD | THROTTLE)
    assert w.robots[0, STUCK] == 0
    climber = dataclasses.replace(V1_RULES, normal_climb=2)
    w = make_world([(2, 2, NORTH, BLADE_HOME)], climber)
    w.heights[4, 2] = 2
    step_both(w, FORWARD)  # no throttle-up: climbs only because normal_climb is 2
    assert w.robots[0, STUCK] == 0


def test_neat_strategy_writes_the_profiles_neat_config(tmp_path):
    from ant_evolution.baseline_runs import NeatStrategy

    NeatStrategy(EvolveConfig().with_profile("paper"), tmp_path)
    text = (tmp_path / "neat.ini").read_text()
    assert "modular_down" in text and "weight_mutate_rate      = 0.025" in text
    NeatStrategy(EvolveConfig(), tmp_path)
    text = (tmp_path / "neat.ini").read_text()
    assert "activation_options      = sigmoid" in text and "weight_mutate_rate      = 0.8" in text
