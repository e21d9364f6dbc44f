"""Parity: a trial through the ROS nodes equals the offline evaluator, exactly."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import next_domain

from ant_controller.controller import Controller
from ant_evolution.evaluate import ScenarioSet
from blueprint_server.blueprint import default_blueprint
from excavation_bringup.trial import run_trial


def offline(spec, robots, steps, seed):
    """Final heights and fitness of the same scenario in the offline evaluator."""
    from ant_evolution.evaluate import advance

    ctl = Controller.hand_coded() if spec == "hand-coded" else Controller.from_file(spec)
    batch = ScenarioSet.create(default_blueprint(1), robots, 1, steps, seed)
    world = batch.world(0)
    advance(world, ctl, steps)
    assert batch.score(ctl)[0] == world.fitness()
    return world.heights, world.fitness()


@pytest.mark.parametrize("spec", ["hand-coded", "genomes/best.json"])
@pytest.mark.parametrize("robots", [1, 4])
def test_trial_through_nodes_equals_offline(spec, robots):
    """The full default trial length, with a blade driver per robot."""
    steps, seed = 300, 3
    result = run_trial(
        spec, robots, steps, seed, "default:1", domain=next_domain(), command_timeout=30.0
    )
    heights, fitness = offline(spec, robots, steps, seed)
    assert sum(result.missed.values()) == 0
    assert np.array_equal(result.heights, heights)
    assert result.fitness == fitness
    assert len(result.trace) == steps + 1


@pytest.mark.parametrize(
    ("blade_driver", "processes"),
    [
        pytest.param(False, False, id="no-driver"),
        pytest.param(True, True, id="processes", marks=pytest.mark.system),  # make test-system
    ],
)
def test_trial_modes_equal_offline(blade_driver, processes):
    """Without blade drivers (the simulator reports the blade), and one process per node."""
    steps, seed, robots = 40, 5, 2
    result = run_trial(
        "genomes/best.json",
        robots,
        steps,
        seed,
        "default:1",
        domain=next_domain(),
        command_timeout=30.0,
        blade_driver=blade_driver,
        processes=processes,
        timeout=300.0,
    )
    heights, fitness = offline("genomes/best.json", robots, steps, seed)
    assert sum(result.missed.values()) == 0
    assert np.array_equal(result.heights, heights)
    assert result.fitness == fitness
