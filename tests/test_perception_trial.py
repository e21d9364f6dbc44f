"""Closed loop: ant-trial --perception full (camera + localizer, laser + mapper)."""

from __future__ import annotations

import numpy as np
import pytest

import excavation_bringup.trial as trial
from excavation_bringup.trial import main, run_trial


def test_short_trial_with_full_perception_matches_truth(monkeypatch, domains):
    made = []
    original = trial.compose

    def spy(*args, **kwargs):
        nodes = original(*args, **kwargs)
        if "sensors" in nodes:  # the full-perception run, not the truth run after it
            made.extend(nodes[name] for name in ("sensors", "localizer", "mapper"))
        return nodes

    monkeypatch.setattr(trial, "compose", spy)
    steps, seed = 10, 3
    full = run_trial(
        "genomes/best.json",
        2,
        steps,
        seed,
        "default:1",
        domain=domains(),
        command_timeout=30.0,
        perception="full",
    )
    sensors, localizer, mapper = made
    # every tick decided went through the synthetic sensors and the perception nodes (the
    # state after the last tick may or may not be rendered before the trial stops)
    assert sensors.frames >= steps
    assert localizer.frames >= steps
    assert mapper.published >= steps
    assert all(e.status == "seen" for e in localizer.estimates)
    assert sum(full.missed.values()) == 0
    truth = run_trial(
        "genomes/best.json",
        2,
        steps,
        seed,
        "default:1",
        domain=domains(),
        command_timeout=30.0,
    )
    assert np.array_equal(full.heights, truth.heights)
    assert full.trace == truth.trace


def test_perception_modes_are_checked(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["--hand-coded", "--perception", "bogus", "--steps", "1"])
    assert exit_.value.code == 2 and "bogus" in capsys.readouterr().err
    assert main(["--hand-coded", "--drive", "continuous", "--no-blade-driver", "--steps", "1"]) == 2
    assert "blade" in capsys.readouterr().err
