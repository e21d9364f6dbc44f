"""Parity: a trial through the ROS nodes equals the offline evaluator, exactly."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import next_domain

from ant_controller.controller import Controller
from ant_evolution.evaluate import ScenarioSet
from blueprint_server.blueprint import default_blueprint
from excavation_sim.trial import run_trial


@pytest.mark.parametrize("spec", ["hand-coded", "genomes/best.json"])
@pytest.mark.parametrize("robots", [1, 4])
def test_trial_through_nodes_equals_offline(spec, robots):
    steps, seed = 60, 3
    result = run_trial(
        spec, robots, steps, seed, "default:1", domain=next_domain(), command_timeout=30.0
    )
    ctl = Controller.hand_coded() if spec == "hand-coded" else Controller.from_file(spec)
    batch = ScenarioSet.create(default_blueprint(1), robots, 1, steps, seed)
    world = batch.world(0)
    from ant_evolution.evaluate import advance

    advance(world, ctl, steps)
    assert sum(result.missed.values()) == 0
    assert np.array_equal(result.heights, world.heights)
    assert result.fitness == batch.score(ctl)[0] == world.fitness()
    assert len(result.trace) == steps + 1
