"""``ant-field-experiment``: the landing-pad and field experiments at the quick scale.

Each runs grid and continuous-motion trials (ROS nodes on a test-unique domain, loopback
only), so the tests keep to a few ticks; they check the outputs' structure, that the same
command gives the same CSVs, and that a second run reuses the finished trials.
"""

from __future__ import annotations

import csv

import numpy as np
import pytest
from excavation_field.field_experiment import (
    PLANS,
    Setup,
    _physical_text,
    correlation,
    grid_heights_at,
    grid_trial,
    landing_pad_site,
    main,
    part_tick,
)
from helpers.trials import GENOME

from ant_controller.controller import Controller


def test_landing_pad_site_is_the_pad_on_training_sized_cells():
    bp = landing_pad_site()
    assert bp.shape == (17, 14)
    assert bp.dig_cells == 9 * 10 + 4 * 5
    assert sorted(set(bp.goal[bp.zones == 1].tolist())) == [-2, -1]
    assert int((bp.goal == -2).sum()) == 90 and int((bp.goal == -1).sum()) == 20
    assert bp.cell_size == 0.25 and bp.height_unit == 0.25


def test_grid_trial_trace_starts_at_the_start_and_ends_at_the_heights():
    ctl = Controller.from_file(GENOME)
    bp = landing_pad_site()
    t = grid_trial(ctl, bp, 3, 40, 1)
    assert len(t["trace"]) == 41
    heights = np.array(t["heights"])
    from excavation_sim.world import fitness

    assert t["trace"][-1] == pytest.approx(fitness(heights, bp.zones, bp.goal))
    assert np.array_equal(grid_heights_at(ctl, bp, 3, 40, 1), heights)
    assert t["trace"][0] == pytest.approx(fitness(np.zeros_like(heights), bp.zones, bp.goal))
    assert t["trace"] != [t["trace"][0]] * 41  # three robots change the pad in 40 steps


def _read(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.mark.parametrize("name", ["landing-pad", "field"])
def test_quick_experiment_writes_the_same_csvs_twice_and_resumes(tmp_path, name, domains):
    plan = PLANS[name, "quick"]
    stem = name.replace("-", "_")
    outs = [tmp_path / "a", tmp_path / "b"]
    for out in outs:
        argv = [name, "--scale", "quick", "--domain", str(domains()), "--no-progress"]
        assert main([*argv, "--out", str(out)]) == 0
    a, b = (out / name for out in outs)
    for f in (f"{stem}.csv", f"{stem}_summary.csv", "section.md", "scale.json", f"{stem}.png"):
        assert (a / f).is_file(), f
    assert (a / f"{stem}.csv").read_text() == (b / f"{stem}.csv").read_text()
    assert (a / f"{stem}_summary.csv").read_text() == (b / f"{stem}_summary.csv").read_text()
    rows = _read(a / f"{stem}.csv")
    per_trial = plan.steps // plan.every + 1
    trials = len(plan.robots) * (plan.grid_seeds + plan.continuous_seeds)
    assert len(rows) == trials * per_trial
    assert {r["simulator"] for r in rows} == {"grid", "continuous"}
    assert {int(r["robots"]) for r in rows} == set(plan.robots)
    assert all(0.0 <= float(r["fitness"]) <= 1.0 for r in rows)
    summary = _read(a / f"{stem}_summary.csv")
    assert [r["simulator"] for r in summary] == ["grid", "grid (paired)", "continuous"] * len(
        plan.robots
    )
    section = (a / "section.md").read_text()
    assert f"figures/{name}/{stem}.png" in section
    if name == "field":
        assert "72 %" in section and "full perception" in section
    # A second run in the same directory reads every trial back instead of running it.
    stored = {p.name: p.stat().st_mtime_ns for p in (a / "trials").iterdir()}
    assert len(stored) == trials
    argv = [name, "--scale", "quick", "--domain", str(domains()), "--no-progress"]
    assert main([*argv, "--out", str(outs[0])]) == 0
    assert {p.name: p.stat().st_mtime_ns for p in (a / "trials").iterdir()} == stored


def test_more_continuous_than_grid_seeds_is_refused(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["field", "--grid-seeds", "1", "--continuous-seeds", "2", "--out", str(tmp_path)])
    assert exc.value.code == 2
    assert "--continuous-seeds" in capsys.readouterr().err


def test_laser_survey_sees_the_ground_but_not_under_the_robots():
    from ant_evolution.evaluate import ScenarioSet
    from ant_evolution.perception_bench import laser_survey
    from blueprint_server.blueprint import default_blueprint
    from excavation_sim.world import COL, ROW

    bp = default_blueprint(2)
    world = ScenarioSet.create(bp, 2, 1, 10, 4).world(0)
    world.heights[3, 3] = -2
    cell, unit = bp.cell_size, bp.height_unit
    surveyed = laser_survey(world.heights, world.robots, cell, unit, np.random.default_rng(0))
    assert surveyed.shape == bp.shape
    seen = np.isfinite(surveyed)
    for r, c in world.robots[:, [ROW, COL]]:
        assert not seen[r : r + 2, c : c + 2].any()  # a robot's footprint hides the ground
    assert seen.mean() > 0.8
    assert np.allclose(surveyed[seen], (world.heights * unit)[seen], atol=unit / 4)


def test_physical_soil_runs_apart_and_reports_each_trial_against_its_grid(tmp_path):
    assert part_tick([0.1, 0.2, 0.3], [0.1, 0.2, 0.36]) == 2
    assert part_tick([0.1, 0.2], [0.1, 0.24]) is None
    assert correlation([0, 1, 2], [0, 2, 4]) == pytest.approx(1.0)
    assert np.isnan(correlation([1, 1], [0, 1]))
    trials = {
        ("grid", 2, 0): {"trace": [0.1, 0.3, 0.5]},
        ("continuous", 2, 0): {"trace": [0.1, 0.2, 0.2], "slips": 7, "soil_volume": 0},
    }
    text = "### Pad: grid against continuous motion\n\nContinuous trials:\n\n* 2 robots\n"
    out = _physical_text(text, trials)
    assert "grid against continuous motion on physical soil" in out
    assert "| 2 | 0 | 0.87 | 1 | 0.200 / 0.500 | 7 | 0 |" in out
    setup = Setup("field", "quick", PLANS["field", "quick"], GENOME, tmp_path, 0, "physical")
    assert setup.dir == tmp_path / "field-physical"


def test_a_preset_and_the_hand_coded_rules_get_folders_and_text_of_their_own(tmp_path):
    from excavation_field.field_experiment import HAND_CODED, _controller, _options

    plan = PLANS["field", "quick"]
    setup = Setup("field", "quick", plan, HAND_CODED, tmp_path, 0, "physical:dome,repose=false")
    assert setup.dir == tmp_path / "field-physical-dome-repose-false-hand-coded"
    assert _controller(setup).startswith("The hand-coded rules")
    assert _options(setup) == " --hand-coded --soil physical:dome,repose=false"
    genome = Setup("field", "quick", plan, GENOME, tmp_path, 0, "physical:lunar")
    assert genome.dir == tmp_path / "field-physical-lunar"
    assert GENOME in _controller(genome)


def test_the_hand_coded_field_experiment_runs(tmp_path, domains):
    argv = ["field", "--scale", "quick", "--hand-coded", "--domain", str(domains())]
    assert main([*argv, "--no-progress", "--out", str(tmp_path)]) == 0
    section = (tmp_path / "field-hand-coded" / "section.md").read_text()
    assert "The hand-coded rules" in section and "--hand-coded" in section
