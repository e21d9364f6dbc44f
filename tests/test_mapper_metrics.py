"""Field metrics (the paper's field-trial table) and the field-metrics command."""

from __future__ import annotations

import json

import numpy as np
import pytest

from blueprint_server.blueprint import DIG, DUMP, default_blueprint
from terrain_mapper.field_metrics import load_map, main
from terrain_mapper.metrics import field_metrics


def site():
    bp = default_blueprint(2)
    return bp, bp.zones, bp.goal.astype(float)


def test_untouched_site_is_all_above_goal():
    _, zones, goal = site()
    flat = np.zeros(zones.shape)
    m = field_metrics(flat, flat, zones, goal)
    assert m.above_goal == 1.0 and m.towards_goal == 0.0 and m.indeterminate == 0.0
    assert np.isnan(m.dump_share) and m.removed == 0 and m.deposited == 0


def test_shares_count_each_rule():
    _, zones, goal = site()
    before = np.zeros(zones.shape)
    after = before.copy()
    dig = np.argwhere(zones == DIG)
    dump = np.argwhere(zones == DUMP)
    n = len(dig)
    (r0, c0), (r1, c1), (r2, c2), (r3, c3), (r4, c4) = dig[:5]
    after[r0, c0] = -2  # at goal
    after[r1, c1] = -1  # closer to goal
    after[r2, c2] = -3  # dug below goal
    after[r3, c3] = 1  # soil dumped on a dig cell
    before[r4, c4] = np.nan  # not measured
    # the removed soil: 2 + 1 + 3 = 6 units; 5 of them in dump zones, 1 on a dig cell
    after[tuple(dump[0])] = 5
    m = field_metrics(before, after, zones, goal)
    assert m.towards_goal == pytest.approx(2 / n)
    assert m.below_goal == pytest.approx(1 / n)
    assert m.indeterminate == pytest.approx(1 / n)
    assert m.above_goal == pytest.approx((n - 4) / n)
    assert m.towards_goal + m.above_goal + m.below_goal + m.indeterminate == pytest.approx(1)
    assert m.removed == 6 and m.deposited == 6
    assert m.dump_share == pytest.approx(5 / 6)


def test_noise_within_tolerance_is_not_a_change():
    _, zones, goal = site()
    rng = np.random.default_rng(0)
    before = rng.normal(0, 0.05, zones.shape)
    after = before + rng.normal(0, 0.05, zones.shape)
    m = field_metrics(before, after, zones, goal, tolerance=0.25)
    assert m.deposited == 0 and m.removed == 0 and m.towards_goal == 0


def test_shapes_must_agree():
    _, zones, goal = site()
    with pytest.raises(ValueError, match="one shape"):
        field_metrics(np.zeros((3, 3)), np.zeros(zones.shape), zones, goal)


def test_command_prints_table_and_draws(tmp_path, capsys):
    bp = default_blueprint(1)
    before = np.zeros(bp.shape)
    after = before.copy()
    after[bp.zones == DIG] = -bp.height_unit
    after[bp.zones == DUMP] = bp.height_unit * 64 / int((bp.zones == DUMP).sum())
    np.save(tmp_path / "before.npy", before)
    np.savetxt(tmp_path / "after.csv", after, delimiter=",")
    png = tmp_path / "diff.png"
    args = [str(tmp_path / "before.npy"), str(tmp_path / "after.csv"), "--blueprint", "default:1"]
    assert main([*args, "--png", str(png)]) == 0
    assert "100.0% correctly excavated towards goal depth" in capsys.readouterr().out
    assert png.stat().st_size > 10_000
    assert main([*args, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["towards_goal"] == 1.0 and out["dump_share"] == pytest.approx(1.0)


def test_command_names_bad_file(tmp_path, capsys):
    np.save(tmp_path / "small.npy", np.zeros((4, 4)))
    assert main([str(tmp_path / "small.npy"), str(tmp_path / "small.npy")]) == 2
    assert "small.npy: shape = (4, 4)" in capsys.readouterr().err
    assert main([str(tmp_path / "missing.npy"), str(tmp_path / "small.npy")]) == 2
    assert "missing.npy: file = None: does not exist" in capsys.readouterr().err
    (tmp_path / "bad.csv").write_text("1,2\nx,y\n")
    with pytest.raises(Exception, match="bad.csv: content"):
        load_map(str(tmp_path / "bad.csv"))
