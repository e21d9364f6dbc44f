"""Parity: a trial through the ROS nodes equals the offline evaluator, exactly."""

from __future__ import annotations

import numpy as np
import pytest
from helpers.trials import GENOME, offline

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


@pytest.mark.parametrize("drive", ["grid", "continuous"])
def test_a_healthy_trial_logs_no_warning(drive, domain):
    """Start-up waits (no heartbeat yet, no enable state yet) are INFO: a healthy 4-robot
    trial's log holds no WARN or ERROR line (a user reads those as faults)."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    env = dict(os.environ, ROS_DOMAIN_ID=str(domain))
    exe = Path(sys.executable).with_name("ant-trial")
    cmd = [str(exe), "--genome", str(GENOME), "--robots", "4", "--steps", "4"]
    run = subprocess.run(
        [*cmd, "--drive", drive], env=env, capture_output=True, text=True, timeout=300
    )
    assert run.returncode == 0, run.stderr[-2000:]
    log = run.stdout + run.stderr
    assert "[INFO]" in log  # the nodes did log
    noisy = [line for line in log.splitlines() if "[WARN]" in line or "[ERROR]" in line]
    assert noisy == []
