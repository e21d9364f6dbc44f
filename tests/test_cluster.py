"""A campaign's runs as Ray tasks (``ant-experiment ... --cluster``): chunked, resumed from
the driver's files after a lost node, equal to the same runs trained here."""

from __future__ import annotations

import dataclasses
import json

import pytest

from ant_evolution.experiments import cluster
from ant_evolution.experiments.core import SCALES, Context, run_dir, train_all

SCALE = dataclasses.replace(
    SCALES["quick"], population=6, generations=5, scenarios=2, steps=25, checkpoint_every=1
)


def _run_state(d) -> dict:
    """A run's checkpoint and history without the wall-clock column."""
    ck = json.loads((d / "checkpoint.json").read_text())
    for row in ck["history"]:
        row.pop("seconds")
    history = [line.rsplit(",", 1)[0] for line in (d / "history.csv").read_text().splitlines()]
    return {"checkpoint": ck, "history": history, "best": (d / "best.json").read_text()}


@pytest.mark.xdist_group("ray")  # one local Ray instance at a time (--dist loadgroup)
def test_runs_on_a_cluster_equal_runs_here_after_a_lost_node(tmp_path, monkeypatch):
    ray = pytest.importorskip("ray")
    here = Context(tmp_path / "here", SCALE, runs=2)
    there = Context(tmp_path / "there", SCALE, runs=2, cluster="local")
    monkeypatch.setattr(cluster, "CHUNK", 2)  # 5 generations: chunks of 2, 2 and 1
    lost = run_dir(there, "ant", 2, 1)
    marker = tmp_path / "lost-once"
    monkeypatch.setenv(cluster.FAIL_ONCE, f"{lost.name}={marker}")
    try:
        train_all(here, [("ant", 2)], "here")
        on_cluster = train_all(there, [("ant", 2)], "there")
    finally:
        ray.shutdown()
    assert marker.exists()  # the run's first chunk failed on its node, and was run again
    for k in range(2):
        a, b = run_dir(here, "ant", 2, k), run_dir(there, "ant", 2, k)
        assert _run_state(a) == _run_state(b), k
        chunks = json.loads((b / "cluster.json").read_text())["chunks"]
        assert [c["generations"] for c in chunks] == [2, 4, 5] and chunks[0]["node_id"]
    assert [len(h) for h in on_cluster[("ant", 2)]] == [5, 5]
    from ant_evolution.experiments.status import run_status

    assert "finished (last chunk on " in run_status(there, "ant", 2, 0).state
    assert run_status(here, "ant", 2, 0).state == "finished"
