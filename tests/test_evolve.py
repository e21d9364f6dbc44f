"""Evolution runs: backends agree, checkpoints resume exactly, bad inputs fail clearly."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from helpers.figures import assert_figure
from helpers.waits import poll_until

from ant_controller.genome import random_genome
from ant_controller.genome_io import load_genome
from ant_evolution.backends import Evaluator
from ant_evolution.cli_evolve import main as evolve_main
from ant_evolution.errors import CheckpointError, ConfigError
from ant_evolution.evolve import (
    EvolveConfig,
    blueprints_of,
    config_from_dict,
    load_config,
    run_evolution,
    scenario_sets,
)

TINY = EvolveConfig(
    population=8, generations=10, scenarios=4, steps=40, depths=(1, 2), checkpoint_every=1
)


def deterministic(out: Path) -> dict:
    """Everything a run leaves that must not depend on how it was run."""
    ck = json.loads((out / "checkpoint.json").read_text())
    for row in ck["history"]:
        row.pop("seconds")
    best = json.loads((out / "best.json").read_text())
    return {"checkpoint": ck, "best": best}


@pytest.fixture(scope="module")
def straight(tmp_path_factory):
    out = tmp_path_factory.mktemp("straight")
    run_evolution(TINY, out, workers=1)
    return out


def test_run_writes_its_outputs(straight):
    names = {p.name for p in straight.iterdir()}
    assert {"config.yaml", "history.csv", "best.json", "fitness.png", "checkpoint.json"} <= names
    assert_figure(straight / "fitness.png")
    assert load_config(straight / "config.yaml") == TINY
    lines = (straight / "history.csv").read_text().splitlines()
    assert len(lines) == 11 and lines[0].startswith("generation,evaluations,best,mean")
    best = load_genome(straight / "best.json")
    rows = [line.split(",") for line in lines[1:]]
    assert best.metadata["fitness"] == max(float(r[2]) for r in rows)
    assert best.metadata["config"]["population"] == 8


def test_stop_and_resume_equals_a_straight_run(straight, tmp_path):
    run_evolution(TINY, tmp_path, workers=1, stop_after=5)
    ck = json.loads((tmp_path / "checkpoint.json").read_text())
    assert ck["generation"] == 5
    run_evolution(TINY, tmp_path, workers=2, resume=True)  # another worker count, too
    assert deterministic(tmp_path) == deterministic(straight)


def test_kill_9_and_resume_equals_a_straight_run(straight, tmp_path):
    """A real SIGKILL mid-run: the last checkpoint resumes to the same result."""
    cmd = [
        sys.executable,
        "-m",
        "ant_evolution.cli_evolve",
        "--out",
        str(tmp_path),
        "--quiet",
        "--population",
        "8",
        "--generations",
        "10",
        "--scenarios",
        "4",
        "--steps",
        "40",
        "--depths",
        "1,2",
        "--checkpoint-every",
        "1",
        "--workers",
        "1",
    ]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 240
    generation = 0
    while time.monotonic() < deadline and proc.poll() is None:
        try:
            generation = json.loads((tmp_path / "checkpoint.json").read_text())["generation"]
        except (FileNotFoundError, ValueError):
            pass
        if generation >= 3:
            break
        time.sleep(0.05)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    generation = json.loads((tmp_path / "checkpoint.json").read_text())["generation"]
    assert 3 <= generation < 10  # killed part-way
    assert evolve_main(["--out", str(tmp_path), "--resume", "--quiet", "--workers", "1"]) == 0
    assert deterministic(tmp_path) == deterministic(straight)


@pytest.mark.xdist_group("ray")  # one local Ray instance at a time (--dist loadgroup)
def test_backends_give_identical_fitness():
    rng = np.random.default_rng(0)
    genomes = [random_genome(rng) for _ in range(6)]
    sets = scenario_sets(TINY, 3, blueprints_of(TINY))
    with Evaluator(workers=1) as ev:
        one = ev.evaluate(genomes, sets)
    with Evaluator(workers=2) as ev:
        assert ev.backend == "process-pool"
        two = ev.evaluate(genomes, sets)
    assert np.array_equal(one, two)
    ray = pytest.importorskip("ray", reason="ray is the optional cluster backend")
    try:
        with Evaluator(workers=2, ray_address="local") as ev:
            assert ev.backend == "ray"
            on_ray = ev.evaluate(genomes, sets)
    finally:
        ray.shutdown()
    assert np.array_equal(one, on_ray)


def test_checkpoint_problems_are_clear_errors(straight, tmp_path):
    with pytest.raises(CheckpointError, match="exists: pass --resume"):
        run_evolution(TINY, straight, workers=1)
    with pytest.raises(CheckpointError, match="does not exist"):
        run_evolution(TINY, tmp_path, workers=1, resume=True)
    other = dataclasses.replace(TINY, seed=5)
    with pytest.raises(CheckpointError, match="different configuration"):
        run_evolution(other, straight, workers=1, resume=True)
    (tmp_path / "checkpoint.json").write_text('{"format": "ant-checkpoint/1", "popu')
    with pytest.raises(CheckpointError, match="corrupt"):
        run_evolution(TINY, tmp_path, workers=1, resume=True)


def test_config_errors_name_file_key_and_value(tmp_path):
    bad = tmp_path / "c.yaml"
    bad.write_text("population: 10\nmutation_rate: 0.1\n")
    with pytest.raises(ConfigError, match="mutation_rate") as exc:
        load_config(bad)
    assert str(bad) in str(exc.value)
    with pytest.raises(ConfigError, match="population"):
        config_from_dict({"population": "ten"})
    with pytest.raises(ConfigError, match="crossover_prob"):
        config_from_dict({"crossover_prob": 1.5})
    with pytest.raises(ConfigError, match="evolve_robots"):
        config_from_dict({"robots_mix": [1, 4], "evolve_robots": True})


def test_cli_tiny_run_and_bad_config(tmp_path, capsys):
    out = tmp_path / "run"
    code = evolve_main(
        [
            "--out",
            str(out),
            "--population",
            "6",
            "--generations",
            "2",
            "--scenarios",
            "2",
            "--steps",
            "20",
            "--robots-mix",
            "1,4",
            "--workers",
            "1",
            "--quiet",
        ]
    )
    assert code == 0
    assert "best fitness" in capsys.readouterr().out
    assert load_config(out / "config.yaml").robots_mix == (1, 4)
    bad = tmp_path / "bad.yaml"
    bad.write_text("generations: [1\n")
    assert evolve_main(["--config", str(bad), "--out", str(tmp_path / "x")]) == 2
    assert str(bad) in capsys.readouterr().err


def test_evolved_robot_counts_use_the_gene(tmp_path):
    cfg = EvolveConfig(
        population=6,
        generations=2,
        scenarios=2,
        steps=20,
        depths=(1,),
        evolve_robots=True,
        robots_range=(1, 3),
    )
    state = run_evolution(cfg, tmp_path, workers=1)
    hist = state.history[-1]["robots_hist"]
    counts = dict(part.split(":") for part in hist.split(";"))
    assert sum(int(c) for c in counts.values()) == 6
    assert set(counts) <= {"1", "2", "3"}


def test_cli_blueprint_file_and_bad_blueprint(tmp_path, capsys):
    site = tmp_path / "site.yaml"
    site.write_text(
        "format: ant-blueprint/1\nrows:\n  - 'DDDDDDDD'\n  - 'D1111D..'\n"
        "  - 'D1111D..'\n  - 'DDDDDD..'\n  - '........'\n  - '........'\n"
    )
    out = tmp_path / "run"
    args = [
        "--population",
        "4",
        "--generations",
        "1",
        "--scenarios",
        "2",
        "--steps",
        "10",
        "--robots",
        "2",
        "--workers",
        "1",
        "--quiet",
    ]
    assert evolve_main(["--out", str(out), "--blueprint", str(site), *args]) == 0
    assert load_config(out / "config.yaml").blueprint == str(site)
    site.write_text("format: ant-blueprint/1\nrows: [12, 3]\n")
    assert evolve_main(["--out", str(tmp_path / "run2"), "--blueprint", str(site), *args]) == 2
    assert "rows" in capsys.readouterr().err


@pytest.mark.parametrize("method", ["ant", "fixed", "neat"])
def test_every_method_resumes_bit_identically(tmp_path, method):
    """The one loop: stop after 2 generations, resume on 2 workers, equal a straight run."""
    from ant_evolution.baseline_runs import run_fixed, run_neat

    runner = {"ant": run_evolution, "fixed": run_fixed, "neat": run_neat}[method]
    cfg = dataclasses.replace(TINY, generations=5, checkpoint_every=2, seed=4)
    runner(cfg, tmp_path / "a", workers=1)
    runner(cfg, tmp_path / "b", workers=1, stop_after=2)
    runner(cfg, tmp_path / "b", workers=2, resume=True)
    name = "neat-state.json" if method == "neat" else "checkpoint.json"

    def strip(d: Path) -> dict:
        ck = json.loads((d / name).read_text())
        for row in ck["history"]:
            row.pop("seconds")
        return ck

    assert strip(tmp_path / "b") == strip(tmp_path / "a")
    best = [(tmp_path / d / "best.json").read_bytes() for d in "ab"]
    assert best[0] == best[1]


def test_ant_evolve_started_in_the_background_stops_on_sigint(tmp_path):
    """A shell without job control starts background commands with SIGINT ignored; ant-evolve
    still stops on it (exit 130) and says how to resume."""
    import signal
    import subprocess
    import sys

    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "ant_evolution.cli_evolve", "--out", str(out), "--population"]
    cmd += ["6", "--generations", "100000", "--scenarios", "2", "--steps", "30", "--robots", "2"]
    cmd += ["--depths", "1", "--workers", "1", "--quiet"]
    proc = subprocess.Popen(
        cmd,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN),
    )
    try:
        assert poll_until((out / "history.csv").exists, 300)
        proc.send_signal(signal.SIGINT)
        code, err = proc.wait(timeout=120), proc.stderr.read()
        assert code == 130, err[-3000:]  # once -6 (SIGABRT) under load: docs/reliability.md
        assert "resume with --resume" in err
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
