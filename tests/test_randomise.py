"""Domain randomisation (ant_evolution.randomise), the sensor noise it switches on, and the
combined fitness in units of progress."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from ant_controller.controller import Controller
from ant_controller.layout import U1, Z1, Z_ABOVE, Z_BELOW, Z_LEVEL
from ant_evolution import randomise
from ant_evolution.evaluate import ScenarioSet, evaluate, program_fitness
from blueprint_server.blueprint import resolve_blueprint
from excavation_common.constants import ZONE_DIG
from excavation_sim.cell_soil import X_BLADE_LIMIT, X_MAX_DIFF, X_MOTOR0
from excavation_sim.rules import CHANCE_ONE, DEFAULT_RULES, P_MISREAD, P_U1_DROPOUT
from excavation_sim.world import World, front_cell, sensor_noise

GENOME = "genomes/best.json"


def test_a_scenario_draws_its_world_from_its_own_stream_within_the_ranges():
    draws = [randomise.draw(DEFAULT_RULES, 7, i) for i in range(200)]
    assert draws[3] == randomise.draw(DEFAULT_RULES, 7, 3)  # the same seed, the same world
    assert draws[3] != randomise.draw(DEFAULT_RULES, 8, 3)
    r = randomise.RANGES
    loads = np.array([d.rules.normal_load for d in draws])
    assert loads.min() >= round(12 * r.load_scale[0]) and loads.max() <= round(12 * r.load_scale[1])
    assert len(set(loads)) > 4
    assert all(d.rules.throttle_load >= d.rules.normal_load for d in draws)
    assert all(d.rules.throttle_climb >= d.rules.normal_climb for d in draws)
    assert {d.rules.normal_climb for d in draws} == {1, 2}
    assert 0.3 < np.mean([d.rules.soil_fill for d in draws]) < 0.7
    assert all(r.misread[0] <= d.misread <= r.misread[1] for d in draws)
    assert all(r.push[0] <= d.push <= r.push[1] for d in draws)
    assert {d.epsilon for d in draws} == {True, False}


@pytest.mark.parametrize("soil", ("grid", "physical:dome"))
def test_randomised_scenarios_keep_the_starts_and_change_the_world(soil):
    blueprint = resolve_blueprint("default", 1)
    plain = ScenarioSet.create(blueprint, 4, 6, 40, 5, soil=soil)
    drawn = ScenarioSet.create(blueprint, 4, 6, 40, 5, soil=soil, randomised=True)
    assert np.array_equal(plain.start.robots, drawn.start.robots)
    assert np.array_equal(plain.start.rng, drawn.start.rng)
    assert (plain.start.params == plain.params).all()
    assert len({tuple(row) for row in drawn.start.params}) == 6
    assert (drawn.start.params[:, P_MISREAD] > 0).all()
    if soil != "grid":
        assert (plain.physics == plain.physics[0]).all()
        base = plain.physics[0]
        for row, i in zip(drawn.physics, range(6), strict=True):
            push = randomise.draw(DEFAULT_RULES, 5, i).push
            assert row[X_MOTOR0] == pytest.approx(base[X_MOTOR0] * push)
            assert row[X_BLADE_LIMIT] == pytest.approx(base[X_BLADE_LIMIT] * push)
        assert len(set(drawn.physics[:, X_MAX_DIFF])) > 1  # the repose angles differ
    genome = Controller.from_file(GENOME)
    scores = drawn.score(genome)
    assert not np.array_equal(scores, plain.score(genome))
    assert np.array_equal(scores, drawn.score(genome))
    # the batched kernel and the traced episodes (ant-eval's path) agree scenario by scenario
    traced = evaluate(genome, blueprint, 4, 6, 40, 5, soil=soil, randomised=True)
    assert np.array_equal(traced.scores, scores)


def _facing_goal_world(height: int) -> tuple[World, int, int]:
    """A robot facing a dig cell whose height is ``height`` against a goal of 0."""
    blueprint = resolve_blueprint("default", 1)
    world = World.scenario(blueprint.zones, blueprint.goal, 1, 3)
    rows, cols = np.nonzero(blueprint.zones == ZONE_DIG)
    world.robots[0, :3] = (rows.min(), cols.min(), 1)  # facing east, into the pit
    r, c = front_cell(rows.min(), cols.min(), 1, 0)
    world.heights[r, c] = world.goal[r, c] + height
    return world, r, c


def test_the_sensor_noise_misreads_near_the_goal_and_drops_u1_only_when_switched_on():
    world, _, _ = _facing_goal_world(0)
    codes = world.sense()[0].copy()
    assert codes[Z1 + 1] == Z_LEVEL
    params = world.params.copy()
    rng = world.rng.copy()
    state = (world.heights, world.zones, world.goal, world.robots, 0)
    out = codes.copy()
    assert not sensor_noise(*state, out, rng, params)
    assert np.array_equal(out, codes) and rng[0] == world.rng[0]  # off: nothing drawn
    params[P_MISREAD] = CHANCE_ONE
    seen = set()
    for _ in range(40):
        out = codes.copy()
        assert sensor_noise(*state, out, rng, params)
        seen.add(int(out[Z1 + 1]))
    assert seen == {Z_ABOVE, Z_BELOW}  # a unit either way, evenly drawn
    far, _, _ = _facing_goal_world(3)  # three units above the goal: read as it is
    out = far.sense()[0].copy()
    sensor_noise(far.heights, far.zones, far.goal, far.robots, 0, out, rng, params)
    assert out[Z1 + 1] == Z_ABOVE
    params[P_MISREAD] = 0
    params[P_U1_DROPOUT] = CHANCE_ONE
    out = codes.copy()
    out[U1] = 1
    assert sensor_noise(*state, out, rng, params)
    assert out[U1] == 0


def test_the_progress_fitness_weighs_each_soil_by_the_references_gain():
    from ant_evolution.evolve import EvolveConfig, blueprints_of, scenario_sets

    cfg = EvolveConfig(population=4, generations=1, scenarios=3, robots=2, depths=(1,))
    both = dataclasses.replace(cfg, also_soil="physical:dome", combine="progress", seed=2)
    assert both.run_key() != dataclasses.replace(both, combine="mean").run_key()
    assert dataclasses.replace(cfg, combine="mean").run_key() == cfg.run_key()
    sets = scenario_sets(both, 0, blueprints_of(both))
    hand = Controller.hand_coded("chain")
    assert all(s.reference.size == s.size for s in sets)
    assert all(s.reference.mean() - s.start_fitness.mean() > 0.01 for s in sets)
    assert program_fitness(hand, sets) == pytest.approx(1.0)  # the reference itself: 1
    genome = Controller.from_file(GENOME)
    expected = []
    for s in sets:
        gain = s.score(genome).mean() - s.start_fitness.mean()
        expected.append(gain / max(s.reference.mean() - s.start_fitness.mean(), 0.01))
    assert program_fitness(genome, sets) == pytest.approx(min(expected))
    with pytest.raises(Exception, match="combine"):
        dataclasses.replace(cfg, combine="max")


def test_the_floor_fitness_holds_the_runs_own_soil_plain_and_scores_the_other():
    from ant_evolution.evolve import EvolveConfig, blueprints_of, scenario_sets

    cfg = EvolveConfig(
        population=4, generations=1, scenarios=3, robots=2, depths=(1,), steps=60, seed=4,
        also_soil="physical:dome", combine="floor", randomise=True,
    )  # fmt: skip
    sets = scenario_sets(cfg, 0, blueprints_of(cfg))
    held = [s for s in sets if s.soil == "grid"]
    scored = [s for s in sets if s.soil == "physical:dome"]
    assert held and scored
    assert all(s.floor == 0.9 and not s.randomised for s in held)  # held plain
    assert all(s.floor is None and s.randomised for s in scored)
    genome = Controller.from_file(GENOME)
    grid = np.concatenate([s.score(genome) for s in held]).mean()
    dome = np.concatenate([s.score(genome) for s in scored]).mean()
    kept = [dataclasses.replace(s, floor=grid - 0.01) for s in held]
    assert program_fitness(genome, kept + scored) == pytest.approx(dome)  # floor kept
    lost = [dataclasses.replace(s, floor=grid + 0.05) for s in held]
    assert program_fitness(genome, lost + scored) == pytest.approx(-0.05)  # the shortfall
    assert program_fitness(genome, lost + scored) < 0 <= program_fitness(genome, kept + scored)
    assert cfg.run_key() != dataclasses.replace(cfg, floor=0.8).run_key()
    # the default floor keys nothing: test_paper_profile pins the default config's key
    for bad, field_name in (
        ({"floor": 0.0}, "floor"),
        ({"floor": 1.5}, "floor"),
        ({"combine": "mean", "floor": 0.8}, "floor"),
        ({"also_soil": ""}, "combine"),
    ):
        with pytest.raises(Exception, match=field_name):
            dataclasses.replace(cfg, **bad)


def test_a_randomised_run_resumes_bit_for_bit_on_other_workers_and_writes_its_matrix(
    tmp_path, capsys
):
    from ant_evolution.cli_evolve import main

    args = [
        "--soil", "physical:dome", "--randomise", "--population", "5", "--generations", "4",
        "--scenarios", "2", "--steps", "30", "--robots", "2", "--depths", "1", "--seed", "6",
        "--checkpoint-every", "2", "--quiet", "--transfer-scenarios", "2",
    ]  # fmt: skip
    a, b = tmp_path / "a", tmp_path / "b"
    assert main([*args, "--out", str(a), "--workers", "1"]) == 0
    assert "| `physical:dome` randomised |" in capsys.readouterr().out
    matrix = json.loads((a / "transfer.json").read_text())
    assert [r["randomised"] for r in matrix["rows"]].count(True) == 2
    assert (a / "transfer.md").read_text().startswith(str(a / "best.json"))
    from ant_evolution.evolve import EvolveConfig, load_config, run_evolution

    cfg = load_config(str(a / "config.yaml"))
    assert cfg.randomise and isinstance(cfg, EvolveConfig)
    run_evolution(cfg, b, workers=1, stop_after=2)
    assert not (b / "transfer.json").exists()
    assert main([*args, "--out", str(b), "--workers", "2", "--resume"]) == 0

    def strip(d):
        ck = json.loads((d / "checkpoint.json").read_text())
        for row in ck["history"]:
            row.pop("seconds")
        return ck

    assert strip(b) == strip(a)
    assert json.loads((b / "transfer.json").read_text())["rows"] == matrix["rows"]


def _row(soil, randomised, steps, fitness, progress):
    from ant_evolution.transfer import TransferRow

    return TransferRow(soil, randomised, steps, fitness, 0.0, 0.135, progress, 0.0)


def test_the_goal_checks_grid_fitness_scaled_progress_and_the_hand_coded_rules():
    from ant_evolution.transfer import goal

    def matrix(grid, dome, lunar, dome_long, lunar_long):
        return [
            _row("grid", False, 300, grid, 1.0),
            _row("physical:dome", False, 300, dome, None),
            _row("physical:lunar", False, 300, lunar, None),
            _row("physical:dome", False, 900, 0.0, dome_long),
            _row("physical:lunar", False, 900, 0.0, lunar_long),
        ]

    hand = matrix(0.39, 0.177, 0.135, 0.2, 0.0)
    met = goal(matrix(0.95, 0.2, 0.14, 0.85, 0.9), hand)
    assert [c.met for c in met] == [True] * 5
    missed = goal(matrix(0.89, 0.17, 0.14, 0.5, None), hand)
    assert [c.met for c in missed] == [False, False, False, False, True]
    assert "900 steps" in missed[1].criterion and missed[3].value == 0.0
    with pytest.raises(ValueError, match="differ"):
        goal(matrix(0.9, 0.2, 0.14, 0.8, 0.8)[:4], hand)


def test_ant_eval_checks_a_genome_against_the_hand_coded_matrix(tmp_path, capsys):
    from ant_evolution.cli_eval import main

    args = ["--scenarios", "2", "--steps", "40"]
    hand, mine = tmp_path / "hand.json", tmp_path / "mine.json"
    assert main(["--hand-coded", *args, "--transfer", str(hand)]) == 0
    capsys.readouterr()
    assert main(["--genome", GENOME, *args, "--transfer", str(mine), "--against", str(hand)]) == 0
    assert "the goal, against" in capsys.readouterr().out
    checks = json.loads(mine.read_text())["goal"]
    assert len(checks) == 5 and checks[0]["criterion"] == "grid fitness"
    other = ["--scenarios", "2", "--steps", "30", "--transfer", str(tmp_path / "x.json")]
    assert main(["--genome", GENOME, *other, "--against", str(hand)]) == 2
    assert "--against" in capsys.readouterr().err
