"""The presets' progress over long horizons (``python -m ant_evolution.horizons``)."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from helpers.figures import assert_figure

from ant_controller.controller import Controller
from ant_evolution.evaluate import evaluate
from ant_evolution.horizons import PRESETS, Curve, main
from blueprint_server.blueprint import resolve_blueprint


def test_progress_is_against_the_controllers_own_grid_gain():
    c = Curve("x", "physical:dome", np.array([0.1, 0.2, 0.5, 0.4]), start=0.1, grid=0.6)
    assert np.allclose(c.progress, [0.0, 0.2, 0.8, 0.6])
    assert c.first_reaching() == 2
    assert c.first_reaching(0.9) is None
    flat = Curve("x", "physical:dome", np.array([0.1, 0.3]), start=0.1, grid=0.1)
    assert flat.progress is None and flat.first_reaching() is None  # no grid gain: no progress


def test_the_curves_are_the_evaluators_on_the_same_scenarios(tmp_path):
    argv = [
        "--controller", "genomes/best.json", "--controller", "hand-coded", "--scenarios", "2",
        "--base", "20", "--steps", "60", "--every", "10", "--seed", "5",
    ]  # fmt: skip
    assert main(["--out", str(tmp_path / "a"), *argv]) == 0
    assert main(["--out", str(tmp_path / "b"), *argv]) == 0
    text = (tmp_path / "a" / "horizons.csv").read_text()
    assert text == (tmp_path / "b" / "horizons.csv").read_text()  # seeded: the same again
    rows = list(csv.DictReader(text.splitlines()))
    assert len(rows) == 2 * len(PRESETS) * 7  # steps 0, 10, ..., 60
    blueprint = resolve_blueprint("default", 1)
    for spec in ("genomes/best.json", "hand-coded"):
        program = Controller.from_spec(spec)
        grid = evaluate(program, blueprint, 4, 2, 20, 5)
        f0, fg = grid.curves[:, 0].mean(), grid.mean
        for soil in PRESETS:
            mine = {
                int(r["step"]): r for r in rows if r["controller"] == spec and r["soil"] == soil
            }
            curve = evaluate(program, blueprint, 4, 2, 60, 5, soil=soil).curves.mean(axis=0)
            for t in (0, 20, 60):
                assert float(mine[t]["fitness"]) == pytest.approx(curve[t], abs=1e-6)
                assert float(mine[t]["progress"]) == pytest.approx(
                    (curve[t] - f0) / (fg - f0), abs=1e-5
                )
    table = (tmp_path / "a" / "horizons.md").read_text()
    assert table.count("| `physical:dome` |") == 2 and "first reaching 0.8" in table
    assert_figure(tmp_path / "a" / "horizons.png")


def test_a_missing_genome_is_named_before_anything_runs(tmp_path, capsys):
    code = main(["--out", str(tmp_path), "--controller", str(tmp_path / "nope.json")])
    assert code == 2 and "nope.json" in capsys.readouterr().err
    assert not (tmp_path / "horizons.csv").exists()
