"""Parity: a trial through the ROS nodes equals the offline evaluator, exactly."""

from __future__ import annotations

import numpy as np
import pytest
from helpers.trials import offline

from excavation_bringup.trial import run_trial


@pytest.mark.parametrize("spec", ["hand-coded", "genomes/best.json"])
@pytest.mark.parametrize("robots", [1, 4])
def test_trial_through_nodes_equals_offline(spec, robots, domain):
    """The full default trial length, with a blade driver per robot."""
    steps, seed = 300, 3
    result = run_trial(spec, robots, steps, seed, "default:1", domain=domain, command_timeout=30.0)
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
def test_trial_modes_equal_offline(blade_driver, processes, domain):
    """Without blade drivers (the simulator reports the blade), and one process per node."""
    steps, seed, robots = 40, 5, 2
    result = run_trial(
        "genomes/best.json",
        robots,
        steps,
        seed,
        "default:1",
        domain=domain,
        command_timeout=30.0,
        blade_driver=blade_driver,
        processes=processes,
        timeout=300.0,
    )
    heights, fitness = offline("genomes/best.json", robots, steps, seed)
    assert sum(result.missed.values()) == 0
    assert np.array_equal(result.heights, heights)
    assert result.fitness == fitness
