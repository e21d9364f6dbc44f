"""``ant-trial --drive continuous``: executors, team tick and ``dynamics`` against the grid.

With slip and noise off the continuous trial must end with the final height map and
fitness of the lockstep grid trial (which tests/test_trial.py proves equal to ``ant-eval``),
for the hand-coded controller and the shipped genome, with 1 and 4 robots.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from helpers.trials import offline_trace

from excavation_bringup.trial import main, run_trial


def continuous(domain, spec, robots, steps, seed, **kw):
    return run_trial(
        spec,
        robots,
        steps,
        seed,
        "default:1",
        domain=domain,
        command_timeout=30.0,
        timeout=900.0,
        drive="continuous",
        **kw,
    )


@pytest.mark.parametrize(
    ("spec", "robots", "steps"),
    [
        ("hand-coded", 1, 100),
        ("genomes/best.json", 1, 100),
        ("genomes/best.json", 4, 60),
        # the longest of the four (about a minute): in make test-system
        pytest.param("hand-coded", 4, 60, marks=pytest.mark.system),
    ],
)
def test_continuous_without_slip_equals_the_grid(spec, robots, steps, domain):
    seed = 3
    result = continuous(domain, spec, robots, steps, seed, exact=True)
    heights, fitness, trace = offline_trace(spec, robots, steps, seed)
    assert sum(result.missed.values()) == 0 and result.robots_late == 0
    assert np.array_equal(result.heights, heights)
    assert result.fitness == fitness
    assert result.trace == trace
    assert len(result.tick_wall) == steps
    assert result.sim_seconds > steps  # seconds of driving per tick, not one step per tick


def test_continuous_and_lockstep_trials_send_the_same_words(domains):
    """Tick by tick the controllers see the same snapshots: every word is the grid trial's."""
    spec, robots, steps, seed = "genomes/best.json", 4, 30, 8
    grid = run_trial(spec, robots, steps, seed, "default:1", domain=domains(), command_timeout=30.0)
    cont = continuous(domains(), spec, robots, steps, seed, exact=True)
    assert cont.commands == grid.commands
    assert np.array_equal(cont.heights, grid.heights) and cont.trace == grid.trace
    assert cont.stuck_events == cont.primitives_aborted > 0  # stalls happen and report U1


def test_default_slip_noise_and_full_perception_run_to_the_end(domain):
    spec, robots, steps, seed = "hand-coded", 2, 12, 1
    result = continuous(domain, spec, robots, steps, seed, perception="full")
    _, fitness, _ = offline_trace(spec, robots, steps, seed)
    assert sum(result.missed.values()) == 0 and result.robots_late == 0
    assert result.fitness >= 0.9 * fitness
    assert len(result.trace) == steps + 1


def test_cli_reports_the_continuous_figures(capfd, domain):
    code = main(
        [
            "--hand-coded",
            "--robots",
            "1",
            "--steps",
            "5",
            "--drive",
            "continuous",
            "--no-slip",
            "--domain",
            str(domain),
            "--json",
        ]
    )
    captured = capfd.readouterr()
    assert code == 0, captured.err
    out = json.loads(captured.out.strip().splitlines()[-1])
    assert len(out["wall_per_tick"]) == 5
    assert {"primitives_aborted", "stuck_events", "sim_seconds", "fitness"} <= set(out)
    assert main(["--hand-coded", "--drive", "continuous", "--no-blade-driver"]) == 2


def test_physical_soil_can_disagree_with_the_grid(domains):
    """``--soil physical``: the same 25 ticks dig (the fitness rises from the start) but
    score differently from the grid's soil; the soil's total stays what it was (0 quanta on
    the flat site).

    The grid's side is the offline trace, which the exact continuous trial equals
    (``test_continuous_without_slip_equals_the_grid``)."""
    spec, robots, steps, seed = "hand-coded", 2, 25, 0
    _, grid_fitness, grid_trace = offline_trace(spec, robots, steps, seed)
    soil = continuous(domains(), spec, robots, steps, seed, exact=True, soil="physical")
    assert sum(soil.missed.values()) == 0 and soil.robots_late == 0
    assert soil.soil_volume == 0
    assert soil.trace[0] == grid_trace[0] < soil.fitness
    assert soil.trace != grid_trace
    assert main(["--hand-coded", "--soil", "physical", "--steps", "1"]) == 2  # needs continuous


@pytest.mark.parametrize("soil", ["physical:dome", "physical:lunar,repose=false"])
def test_the_presets_run_end_to_end(domains, soil):
    """``ant-trial --soil physical:dome`` (and ``:lunar`` with an override) through the
    nodes: every word applied, the soil conserved to the quantum."""
    r = continuous(domains(), "hand-coded", 2, 5, 0, exact=True, soil=soil)
    assert sum(r.missed.values()) == 0 and r.robots_late == 0
    assert r.soil_volume == 0 and len(r.trace) == 6


def test_a_soil_spec_that_names_no_soil_is_refused_first(capsys):
    with pytest.raises(SystemExit):
        main(["--hand-coded", "--drive", "continuous", "--soil", "physical:moon"])
    assert "unknown preset 'moon'" in capsys.readouterr().err
