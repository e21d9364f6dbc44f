"""``ant-soil-study``: the attribution study's statistics, first differences and resumption."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from excavation_field.soil_study import (
    AS_SHIPPED,
    GENOME,
    SWITCHES,
    first_difference,
    grid_decisions,
    interval,
    main,
    table,
)

from ant_controller.controller import Controller
from excavation_sim.soil import SoilParams


def test_each_switch_is_a_soil_spec_that_changes_one_thing_from_the_soil_as_shipped():
    base = SoilParams(soil=AS_SHIPPED).resolved()
    assert not base.refusals and not base.epsilon
    changed = {}
    for s in SWITCHES:
        p = SoilParams(soil=s.soil).resolved()
        changed[s.key] = {
            f
            for f in ("refusals", "epsilon", "fill", "load", "fitness_heights", "repose")
            if getattr(p, f) != getattr(base, f)
        }
    assert changed["shipped"] == set()
    assert changed["fixed"] == {"refusals", "epsilon"}
    assert changed["grid-rules"] == {
        "refusals",
        "epsilon",
        "fill",
        "load",
        "fitness_heights",
        "repose",
    }
    singles = {k: v for k, v in changed.items() if k not in ("shipped", "fixed", "grid-rules")}
    assert all(len(v) == 1 for v in singles.values())


def test_the_interval_is_students_t():
    mean, half = interval([1.0, 2.0, 3.0])
    assert mean == 2.0 and half == pytest.approx(4.303 * 1.0 / math.sqrt(3))
    assert math.isnan(interval([0.5])[1])


def test_grid_decisions_replay_the_offline_world():
    trace, decisions = grid_decisions(GENOME, 2, 20, 100, 0)
    assert len(trace) == 21 and len(decisions) == 20 and len(decisions[0]) == 2
    ctl = Controller.from_file(GENOME)
    word, codes = decisions[5][1]
    assert ctl.decide(np.array(codes)) == word


def test_the_first_difference_names_the_inputs_that_differ():
    grid = [[(1, [0] * 14)], [(2, [0] * 14)], [(3, [0] * 14)]]
    codes = [0] * 14
    codes[2], codes[12] = 1, 1
    physical = [[(1, [0] * 14), (5, codes), (3, [0] * 14)]]
    fd = first_difference(grid, physical)
    assert (fd["tick"], fd["robot"], fd["inputs_differ"]) == (1, 0, ["Z3", "U1"])
    assert first_difference(grid, [[w for w in row] for row in [[g[0] for g in grid]]]) is None


def test_the_table_counts_scenarios_per_cell():
    rows = [
        dict(switch="shipped", controller=GENOME, robots=2, progress=p, f0=0.1, grid=0.5,
             physical=0.2, slips=3, first_difference={"tick": 4, "inputs_differ": ["L1"]})
        for p in (0.2, 0.4)
    ]  # fmt: skip
    text = table(rows, (2,))
    assert "| 0.30 +- " in text and "(2)" in text
    assert "2 of 2 trials part from the grid, first at tick 4-4" in text and "L1 2" in text


def test_a_tiny_study_runs_records_and_resumes(tmp_path, domains):
    """Two trials through the nodes (1 robot, 3 ticks); a second run does none again."""
    argv = ["--out", str(tmp_path), "--steps", "3", "--robots", "1", "--scenarios", "1"]
    argv += ["--switches", "shipped", "--domain", str(domains())]
    assert main(argv) == 0
    files = sorted((tmp_path / "trials").glob("*.json"))
    assert [f.name for f in files] == ["shipped-genome-n1-s0.json", "shipped-hand-n1-s0.json"]
    row = json.loads(files[0].read_text())
    assert row["soil"] == AS_SHIPPED and row["steps"] == 3 and row["soil_volume"] == 0
    stamp = files[0].stat().st_mtime_ns
    assert main(argv) == 0
    assert files[0].stat().st_mtime_ns == stamp
    assert "| physical soil as shipped" in (tmp_path / "attribution.md").read_text()


def test_the_offline_world_study_scores_as_the_evaluator_and_finds_first_differences(tmp_path):
    """``--world offline``: each physical trial ends where the evaluator's compiled kernel
    ends on the same scenario and soil; the first differing word is found from every trial."""
    from ant_evolution.evaluate import evaluate
    from blueprint_server.blueprint import default_blueprint

    argv = ["--out", str(tmp_path), "--steps", "40", "--robots", "2", "--scenarios", "2"]
    argv += ["--switches", "shipped", "fixed", "--world", "offline", "--seed", "5"]
    assert main(argv) == 0
    rows = [json.loads(f.read_text()) for f in sorted((tmp_path / "trials").glob("*.json"))]
    assert len(rows) == 2 * 2 * 2 and all(r["world"] == "offline" for r in rows)
    for r in rows:
        ctl = (
            Controller.hand_coded()
            if r["controller"] == "hand-coded"
            else Controller.from_file(GENOME)
        )
        batch = evaluate(ctl, default_blueprint(1), 2, 2, 40, 5, soil=r["soil"])
        assert r["physical"] == batch.scores[r["scenario"]]
        assert r["grid"] == evaluate(ctl, default_blueprint(1), 2, 2, 40, 5).scores[r["scenario"]]
    assert any(r["first_difference"] for r in rows)  # the soils differ somewhere
    for fd in filter(None, (r["first_difference"] for r in rows)):
        assert fd["grid_word"] != fd["physical_word"] and fd["inputs_differ"] is not None
    assert "fixed default" in (tmp_path / "attribution.md").read_text()


def test_a_trial_past_its_time_limit_is_left_for_the_next_run(tmp_path, monkeypatch, capsys):
    """A trial that times out writes no row and stops nothing: the others are kept, the run
    says which is left and exits 1, and the next run does only that one."""
    from excavation_field import soil_study

    real = soil_study.run_offline
    calls = []

    def flaky(switch, controller, robots, scenario, args):
        calls.append((switch.key, controller))
        if controller == "hand-coded" and len(calls) <= 2:
            raise TimeoutError("trial did not finish within 900 s (tick 93)")
        return real(switch, controller, robots, scenario, args)

    monkeypatch.setattr(soil_study, "run_offline", flaky)
    argv = ["--out", str(tmp_path), "--steps", "5", "--robots", "1", "--scenarios", "1"]
    argv += ["--switches", "shipped", "--world", "offline"]
    assert main(argv) == 1
    assert "shipped-hand-n1-s0.json" in capsys.readouterr().err
    names = [f.name for f in (tmp_path / "trials").glob("*.json")]
    assert names == ["shipped-genome-n1-s0.json"]
    assert main(argv) == 0
    assert calls[-1] == ("shipped", "hand-coded") and len(calls) == 3
    assert len(list((tmp_path / "trials").glob("*.json"))) == 2


def test_shards_split_the_trials_between_processes(tmp_path, capsys):
    """``--shard 0/2`` and ``1/2`` run disjoint halves; together, every trial once."""
    argv = ["--out", str(tmp_path), "--steps", "3", "--robots", "1", "2", "--scenarios", "1"]
    argv += ["--switches", "shipped", "--world", "offline"]
    assert main([*argv, "--shard", "1/2"]) == 0
    first = {f.name for f in (tmp_path / "trials").glob("*.json")}
    assert len(first) == 2
    assert main([*argv, "--shard", "0/2"]) == 0
    both = {f.name for f in (tmp_path / "trials").glob("*.json")}
    assert len(both) == 4 and first < both
    with pytest.raises(SystemExit):
        main([*argv, "--shard", "2/2"])
    assert "expected 0 <= K < N" in capsys.readouterr().err
