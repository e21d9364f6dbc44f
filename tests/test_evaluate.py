"""Seeded evaluation and the ant-eval command."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ant_controller.controller import Controller
from ant_controller.genome import random_genome
from ant_controller.genome_io import save_genome
from ant_evolution.baselines.fixed import FixedTopology, compile_fixed, random_network
from ant_evolution.baselines.network import decide_program_reference
from ant_evolution.cli_eval import main
from ant_evolution.evaluate import ScenarioSet, evaluate, scenario_worlds
from blueprint_server.blueprint import default_blueprint


@pytest.fixture(scope="module")
def genome_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("g") / "g.json"
    save_genome(random_genome(np.random.default_rng(5)), path)
    return path


def _program(kind: str, genome_file):
    """A decision program of each kind, and a Python decision function for it."""
    if kind == "hand":
        ctl = Controller.hand_coded()
    elif kind == "genome":
        ctl = Controller.from_file(genome_file)
    elif kind == "shipped":
        ctl = Controller.from_file("genomes/best.json")
    else:
        top = FixedTopology((24,))
        prog = compile_fixed(top, random_network(np.random.default_rng(8), top))
        return prog, lambda codes: decide_program_reference(prog, codes)[0]
    return ctl, ctl.decide


@pytest.mark.parametrize("kind", ["hand", "genome", "shipped", "network"])
def test_compiled_episode_equals_python_step_loop(kind, genome_file):
    """The one episode kernel and a Python loop over sense/decide/step agree exactly."""
    program, decide = _program(kind, genome_file)
    bp = default_blueprint(2)
    fast = evaluate(program, bp, n_robots=3, scenarios=3, steps=120, seed=11)
    batch = ScenarioSet.create(bp, 3, 3, 120, 11)
    assert np.array_equal(batch.score(program), fast.scores)
    for i, world in enumerate(scenario_worlds(bp, 3, 3, 11)):
        for t in range(120):
            s = world.sense()
            world.step([decide(s[k]) if world.active[k] else 0 for k in range(world.n_robots)])
            assert world.fitness() == fast.curves[i, t + 1]
        assert world.fitness() == fast.scores[i]


def test_same_seed_same_scores_and_seed_matters():
    ctl = Controller.hand_coded()
    bp = default_blueprint(1)
    a = evaluate(ctl, bp, 4, 6, 150, seed=3)
    b = evaluate(ctl, bp, 4, 6, 150, seed=3)
    c = evaluate(ctl, bp, 4, 6, 150, seed=4)
    assert np.array_equal(a.scores, b.scores) and np.array_equal(a.curves, b.curves)
    assert not np.array_equal(a.scores, c.scores)
    assert a.curves[0, 0] == pytest.approx(np.exp(-2.0))


def test_hand_coded_digs():
    result = evaluate(Controller.hand_coded(), default_blueprint(1), 1, 10, 300, seed=0)
    assert result.mean > np.exp(-2.0) + 0.1


def test_cli_json_and_snapshots(tmp_path, capsys):
    snaps = tmp_path / "snaps"
    code = main(
        [
            "--hand-coded",
            "--scenarios",
            "3",
            "--steps",
            "60",
            "--json",
            "--snapshots",
            str(snaps),
            "--snapshot-steps",
            "0,30",
        ]
    )
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert out["scenarios"] == 3 and len(out["scores"]) == 3
    assert out["min"] <= out["mean"] <= out["max"]
    names = sorted(p.name for p in snaps.iterdir())
    assert names == ["step_00000.png", "step_00030.png", "step_00060.png", "strip.png"]
    assert all((snaps / n).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for n in names)


def test_cli_genome_text_output(genome_file, capsys):
    assert main(["--genome", str(genome_file), "--scenarios", "2", "--steps", "20"]) == 0
    assert "fitness: mean" in capsys.readouterr().out


def test_cli_bad_inputs_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "ant-genome/1"')
    assert main(["--genome", str(bad)]) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "not valid JSON" in err
    assert main(["--hand-coded", "--blueprint", str(tmp_path / "none.yaml")]) == 2
    assert "does not exist" in capsys.readouterr().err
    small = tmp_path / "small.yaml"
    small.write_text('format: ant-blueprint/1\nrows: ["1111", "1111", "1111", "1111"]\n')
    assert main(["--hand-coded", "--robots", "64", "--blueprint", str(small)]) == 2
    assert "could not place" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_info:  # beyond the team limit: an argparse error
        main(["--hand-coded", "--robots", "200", "--scenarios", "1"])
    assert exit_info.value.code == 2
    assert "limit" in capsys.readouterr().err
