"""``ant-evolve --evaluator ros``: trials through the topics score like the batched evaluator."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from ant_controller.genome_io import load_genome
from ant_evolution.backends import Evaluator
from ant_evolution.cli_evolve import main as evolve_main
from ant_evolution.evaluate import ScenarioSet
from ant_evolution.ga import GAParams, mutate
from ant_evolution.ros_evaluator import RosEvaluator, TrialError
from blueprint_server.blueprint import default_blueprint


@pytest.mark.system  # a trial process per genome and scenario set
def test_trials_through_the_topics_equal_the_batched_evaluator(domains):
    best = load_genome("genomes/best.json")
    other = mutate(np.random.default_rng(3), best, GAParams())
    genomes = [best, other]
    sets = [
        ScenarioSet.create(default_blueprint(1), 2, 2, 25, seed=11),
        ScenarioSet.create(default_blueprint(2), 2, 1, 25, seed=12),
    ]
    expected = Evaluator(workers=1).evaluate(genomes, sets)
    with RosEvaluator(workers=2, domain_base=domains(2)) as ros:
        got = ros.evaluate(genomes, sets)
    assert expected.max() > 0  # the comparison means something
    assert np.array_equal(got, expected)


def test_what_trials_cannot_stand_for_is_refused(domain):
    best = load_genome("genomes/best.json")
    mixed = ScenarioSet.create(default_blueprint(1), [1, 4], 2, 10, seed=0)
    with RosEvaluator(workers=1, domain_base=domain) as ros:
        with pytest.raises(TrialError, match="one robot count per scenario set"):
            ros.evaluate([best], [mixed])


def test_a_failing_trial_command_is_a_clear_error(domains):
    best = load_genome("genomes/best.json")
    sets = [ScenarioSet.create(default_blueprint(1), 1, 1, 5, seed=0)]
    with RosEvaluator(workers=1, domain_base=domains(), trial_command="false {genome}") as ros:
        with pytest.raises(TrialError, match="exited with 1"):
            ros.evaluate([best], sets)
    with RosEvaluator(workers=1, domain_base=domains(), trial_command="echo {genome}") as ros:
        with pytest.raises(TrialError, match="no JSON with 'fitness'"):
            ros.evaluate([best], sets)


@pytest.mark.system  # a trial process per genome and scenario set
def test_ant_evolve_with_the_ros_evaluator_matches_a_batched_run(tmp_path, domains):
    args = "--population 2 --generations 2 --scenarios 1 --steps 12 --robots 2 --depths 1"
    args += " --seed 4 --quiet --workers 2"
    assert evolve_main([*args.split(), "--out", str(tmp_path / "batched")]) == 0
    ros_args = [*args.split(), "--out", str(tmp_path / "ros"), "--evaluator", "ros"]
    ros_args += ["--domain-base", str(domains(2))]
    assert evolve_main(ros_args) == 0

    def rows(run):
        with open(tmp_path / run / "history.csv") as f:
            return [(r["generation"], r["best"], r["mean"]) for r in csv.DictReader(f)]

    assert rows("ros") == rows("batched")
    assert (tmp_path / "ros" / "best.json").read_text() == (
        tmp_path / "batched" / "best.json"
    ).read_text()
