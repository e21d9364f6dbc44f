"""ant-experiment at a tiny scale: every experiment runs end to end, and resumes."""

from __future__ import annotations

import csv
import dataclasses

import pytest
from helpers.figures import assert_figure

from ant_controller.controller import Controller
from ant_evolution.errors import ConfigError
from ant_evolution.evolve import run_evolution
from ant_evolution.experiments import (
    antagonism,
    behaviours,
    cli,
    coarse_coding,
    compare,
    evolve_robots,
    long_run,
    scaleup,
    training,
)
from ant_evolution.experiments.core import (
    SCALES,
    Context,
    best_of_runs,
    read_history,
    run_dir,
    train_config,
)
from ant_evolution.experiments.grids import four_robot_controller
from ant_evolution.experiments.sections import table
from ant_evolution.experiments.suite import EXPERIMENTS
from ant_evolution.profiles import add_profile_options, switches_of

TINY = dataclasses.replace(
    SCALES["quick"], population=6, generations=2, scenarios=2, steps=25, eval_scenarios=2,
    long_steps=30, eval_robots=(1, 2), areas=(6,), area_sizes=(6,), checkpoint_every=1,
)  # fmt: skip

FILES = {
    "training": ["training.csv", "training.png"],
    "compare": ["compare.csv", "compare.png", "summary.json"],
    "coarse-coding": ["coarse_coding.csv", "coarse_coding.png"],
    "scaleup": ["scaleup.csv", "scaleup.png"],
    "antagonism": ["antagonism.csv", "antagonism.png"],
    "depth": ["depth.csv", "depth.png"],
    "area": ["area.csv", "area.png"],
    "evolve-robots": ["evolve_robots.csv", "evolve_robots.png"],
    "behaviours": ["behaviours.csv", "behaviours.png", "neurons.png"],
}


@pytest.fixture(scope="module")
def done(tmp_path_factory):
    """All experiments at the tiny scale, one shared output directory, one run each."""
    out = tmp_path_factory.mktemp("exp")
    ctx = Context(out, TINY, runs=1)
    # interrupt one shared run after its first generation: the experiment must resume it
    cfg = train_config(ctx, "ant", 2, 0)
    run_evolution(cfg, run_dir(ctx, "ant", 2, 0), workers=1, stop_after=1)
    for name in FILES:
        run = behaviours.run if name == "behaviours" else EXPERIMENTS[name]
        run(ctx)
    return ctx


@pytest.mark.parametrize("name", list(FILES))
def test_experiment_writes_csv_figures_and_section(done, name):
    d = done.out / name
    for f in FILES[name]:
        if f.endswith(".png"):
            assert_figure(d / f)
        else:
            assert (d / f).stat().st_size > 0, f
    section = (d / "section.md").read_text()
    assert section.startswith("### ") and "figures/" in section
    csv_name = next(f for f in FILES[name] if f.endswith(".csv"))
    with open(d / csv_name, newline="") as f:
        rows = list(csv.DictReader(f))
    assert rows
    for r in rows:
        for k in ("mean", "best", "mean_max_fitness", "max_fitness_mean"):
            if k in r:
                assert 0.0 <= float(r[k]) <= 1.0


def test_interrupted_run_was_resumed_to_the_same_result(done, tmp_path):
    resumed = read_history(run_dir(done, "ant", 2, 0) / "history.csv")
    fresh_ctx = Context(tmp_path, TINY, runs=1)
    cfg = train_config(fresh_ctx, "ant", 2, 0)
    run_evolution(cfg, tmp_path / "fresh", workers=1)
    fresh = read_history(tmp_path / "fresh" / "history.csv")
    assert len(resumed) == TINY.generations
    assert [(r["best"], r["mean"]) for r in resumed] == [(r["best"], r["mean"]) for r in fresh]


def test_rerun_reuses_finished_runs(done):
    """A second call trains nothing: the histories (wall times included) stay as they were."""
    path = run_dir(done, "fixed", 2, 0) / "history.csv"
    before = path.read_text()
    EXPERIMENTS["compare"](done)
    assert path.read_text() == before


def test_behaviours_replay_matches_the_training_run(done):
    """The replay checks every generation's best against history.csv; its rows agree too."""
    with open(done.out / "behaviours" / "behaviours.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    hist = read_history(run_dir(done, "ant", 2, 0) / "history.csv")
    for r in rows:
        assert float(r["best"]) == hist[int(r["generation"])]["best"]
        assert int(r["robot_steps"]) > 0


def test_cli_rejects_bad_arguments(tmp_path, capsys):
    with pytest.raises(SystemExit):
        cli.main(["nonsense", "--out", str(tmp_path)])
    with pytest.raises(SystemExit):
        cli.main(["depth", "--genome", str(tmp_path / "missing.json"), "--out", str(tmp_path)])
    assert "missing.json: no such file" in capsys.readouterr().err


def test_tested_scale_is_the_campaigns_budget():
    """docs/experiments.md: at least 10 runs per setting and, per run, the 4.3 million
    scenario evaluations the v1 run needed to reach 0.9, over more than its 433 generations."""
    s = SCALES["tested"]
    assert s.runs >= 10
    assert s.population * s.scenarios * s.generations >= 4.3e6
    assert s.generations > 433 and s.scenarios % len(s.depths) == 0


def test_method_and_run_select_part_of_a_campaign(tmp_path, capsys, monkeypatch):
    """--method/--run train exactly those runs, stop before the summary, and the full command
    then reads them back: the same histories as one process training everything."""
    monkeypatch.setitem(cli.SCALES, "quick", TINY)
    base = ["compare", "--scale", "quick", "--runs", "2", "--out", str(tmp_path)]
    assert cli.main([*base, "--method", "fixed", "--run", "1"]) == 0
    assert "trained 1 run(s) (fixed-n2-r1)" in capsys.readouterr().out
    ctx = Context(tmp_path, TINY, runs=2)
    trained = [p.name for p in (tmp_path / "runs" / "quick").iterdir()]
    assert trained == ["fixed-n2-r1"]
    assert not (tmp_path / "compare" / "summary.json").exists()
    part = (run_dir(ctx, "fixed", 2, 1) / "history.csv").read_text()
    capsys.readouterr()
    assert cli.main(["status", *base[1:]]) == 0
    report = capsys.readouterr().out
    assert "| compare | fixed network n2 | 1 of 2 | 0 |" in report
    assert "| compare | ANT n2 | 0 of 2 | 0 | - |" in report
    assert "`ant-experiment compare --scale quick --method ant --setting n2 --workers 2" in report
    assert "| `fixed-n2-r1` | finished |" in report
    assert cli.main(base) == 0
    capsys.readouterr()
    assert cli.main(["status", *base[1:], "--write", str(tmp_path / "status.md")]) == 0
    report = (tmp_path / "status.md").read_text()
    assert report == capsys.readouterr().out
    assert "| compare | NEAT n2 | 2 of 2 | 0 |" in report
    assert "| training | ANT n1 | 0 of 2" in report
    # the evaluation experiments on every finished run's controller: the best run's rows are
    # the main table's
    best = best_of_runs(ctx, "ant", 2)[0].parent.name[-1]
    for name, key, keys in (("antagonism", "pit", TINY.areas), ("depth", "depth", TINY.depths),
                            ("area", "pit", TINY.area_sizes)):  # fmt: skip
        assert cli.main([name, *base[1:]]) == 0
        d = tmp_path / name
        with open(d / f"{name}.csv", newline="") as f:
            main_rows = list(csv.DictReader(f))
        with open(d / f"{name}_runs.csv", newline="") as f:
            every = list(csv.DictReader(f))
        assert len(every) == 2 * len(keys) * len(TINY.eval_robots)
        mine = [r for r in every if r["run"] == best]
        assert [(r[key], r["robots"], r["mean"]) for r in mine] == [
            (r[key], r["robots"], r["mean"]) for r in main_rows
        ]
        assert "peak of each run's controller" in (d / "section.md").read_text()
        assert_figure(d / f"{name}_runs.png")
    assert (tmp_path / "compare" / "summary.json").exists()
    assert (run_dir(ctx, "fixed", 2, 1) / "history.csv").read_text() == part
    whole = tmp_path / "whole"
    assert cli.main([*base[:-1], str(whole)]) == 0
    strip = [{k: v for k, v in r.items() if k != "seconds"} for r in read_history(
        run_dir(ctx, "fixed", 2, 1) / "history.csv")]  # fmt: skip
    other = Context(whole, TINY, runs=2)
    assert strip == [{k: v for k, v in r.items() if k != "seconds"} for r in read_history(
        run_dir(other, "fixed", 2, 1) / "history.csv")]  # fmt: skip


def test_setting_selects_one_robot_setting(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(cli.SCALES, "quick", TINY)
    argv = ["scaleup", "--scale", "quick", "--runs", "1", "--setting", "mix1+2", "--out",
            str(tmp_path)]  # fmt: skip
    assert cli.main(argv) == 0
    assert "trained 1 run(s) (ant-mix1+2-r0)" in capsys.readouterr().out
    assert [p.name for p in (tmp_path / "runs" / "quick").iterdir()] == ["ant-mix1+2-r0"]
    with pytest.raises(SystemExit):
        cli.main(["compare", "--scale", "quick", "--setting", "mix1+2", "--out", str(tmp_path)])
    assert "--setting mix1+2: compare trains n2" in capsys.readouterr().err


def test_method_and_run_are_checked(tmp_path, capsys):
    with pytest.raises(SystemExit):
        cli.main(["antagonism", "--run", "0", "--out", str(tmp_path)])
    assert "antagonism trains none" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.main(["depth", "--setting", "n4", "--out", str(tmp_path)])
    assert "depth trains none" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.main(["compare", "--scale", "quick", "--run", "2", "--out", str(tmp_path)])
    assert "runs 0 to 1" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.main(["compare", "--write", str(tmp_path / "x.md"), "--out", str(tmp_path)])
    assert "--write is an option of status" in capsys.readouterr().err


def test_status_reads_runs_in_progress(tmp_path):
    """A run interrupted after its first generation is reported with its checkpoint."""
    from ant_evolution.experiments.status import report, run_status

    ctx = Context(tmp_path, TINY, runs=1)
    run_evolution(train_config(ctx, "ant", 2, 0), run_dir(ctx, "ant", 2, 0), workers=1,
                  stop_after=1)  # fmt: skip
    st = run_status(ctx, "ant", 2, 0)
    assert (st.generations, st.target, st.checkpoint, st.finished) == (1, 2, True, False)
    assert st.state == "at generation 1" and 0.0 <= st.best_ever <= 1.0
    assert "| compare | ANT n2 | 0 of 1 | 1 | - |" in report(ctx)
    assert run_status(ctx, "neat", 2, 0).state == "not started"


def test_finished_summarises_a_campaign_in_part(tmp_path, capsys, monkeypatch):
    """--finished trains nothing and summarises the finished runs; settings without one are
    left out, every table says how many runs it holds, and scaleup scores every run."""
    monkeypatch.setitem(cli.SCALES, "quick", TINY)
    base = ["--scale", "quick", "--runs", "2", "--out", str(tmp_path)]
    assert cli.main(["compare", *base, "--method", "ant", "--run", "0"]) == 0
    assert cli.main(["compare", *base, "--method", "fixed"]) == 0
    # an unfinished run is not summarised
    ctx = Context(tmp_path, TINY, runs=2)
    run_evolution(train_config(ctx, "ant", 1, 0), run_dir(ctx, "ant", 1, 0), workers=1,
                  stop_after=1)  # fmt: skip
    runs_dir = tmp_path / "runs" / "quick"
    before = {p.name: (p / "history.csv").read_text() for p in runs_dir.iterdir()}
    capsys.readouterr()
    assert cli.main(["compare", *base, "--finished"]) == 0
    section = (tmp_path / "compare" / "section.md").read_text()
    assert "**In part**" in section and "ANT n2 1, fixed network n2 2, NEAT n2 0" in section
    assert "| ANT | 1 |" in section and "| fixed network | 2 |" in section
    assert "| NEAT |" not in section and "times NEAT's" not in section
    assert "against the best conventional network" in section
    assert cli.main(["training", *base, "--finished"]) == 0
    table = (tmp_path / "training" / "section.md").read_text()
    assert "| 2 |" in table and "| 1 |" not in table  # the 1-robot run is at generation 1
    assert cli.main(["coarse-coding", *base, "--finished"]) == 0
    assert "| 2 | " in (tmp_path / "coarse-coding" / "section.md").read_text()
    assert "(1) | - |" in (tmp_path / "coarse-coding" / "section.md").read_text()
    assert cli.main(["scaleup", *base, "--finished"]) == 0
    d = tmp_path / "scaleup"
    with open(d / "scaleup.csv", newline="") as f:
        best_rows = list(csv.DictReader(f))
    with open(d / "scaleup_runs.csv", newline="") as f:
        every = list(csv.DictReader(f))
    assert len(every) == 3 * len(TINY.eval_robots)  # ANT n2: 1 run, fixed n2: 2 runs
    best = best_of_runs(ctx, "fixed", 2)[0].parent.name[-1]
    assert [(r["robots"], r["mean"]) for r in every
            if r["setting"] == "fixed network n2" and r["run"] == best] == [
        (r["robots"], r["mean"]) for r in best_rows if r["controller"] == "fixed network n2"
    ]  # fmt: skip
    assert "| fixed network n2 | 2 |" in (d / "section.md").read_text()
    assert_figure(d / "scaleup_runs.png")
    assert {p.name: (p / "history.csv").read_text() for p in runs_dir.iterdir()} == before
    capsys.readouterr()
    assert cli.main(["evolve-robots", *base, "--finished"]) == 2
    assert "evolve-robots: no finished run" in capsys.readouterr().err
    for argv in (
        ["antagonism", *base, "--finished"],
        ["compare", *base, "--finished", "--run", "0"],
    ):
        with pytest.raises(SystemExit):
            cli.main(argv)
    err = capsys.readouterr().err
    assert "antagonism trains none" in err and "leave out --method, --run and --setting" in err


def test_hours_left_goes_by_the_finished_runs_pace(tmp_path):
    """status's estimate: missing generations at the finished runs' seconds per generation;
    a run without a checkpoint counts in full (it starts again); no finished run, no pace."""
    from ant_evolution.experiments.status import RunStatus, hours_left

    def run(k, generations, seconds, checkpoint):
        return RunStatus("ant", "n4", k, tmp_path / str(k), generations, 10, checkpoint, None,
                         None, None, seconds)  # fmt: skip

    done = run(0, 10, 7200.0, False)  # 720 s a generation
    resumable, restarting = run(1, 4, 100.0, True), run(2, 4, 100.0, False)
    assert hours_left([done, resumable, restarting]) == pytest.approx((6 + 10) * 720 / 3600)
    assert hours_left([done]) == 0.0
    assert hours_left([resumable, restarting]) is None


def test_compare_sentence_says_when_neat_solved_nothing():
    assert compare.sentence(0.04, float("inf"), 0.8) == (
        "ANT's mean maximum fitness is +4% against the best conventional network; "
        "no NEAT run reached 0.9, against 0.80 of ANT's runs."
    )
    assert compare.sentence(float("nan"), 2.0, 0.8) == (
        "its probability of a solution is 2.00 times NEAT's."
    )
    gain, p_ratio = compare.ratios({"ant": (0.8, 0.1, 0.5, 2), "neat": (0.4, 0.1, 0.0, 2)})
    assert gain == pytest.approx(1.0) and p_ratio == float("inf")
    assert compare.summary({"ant": (0.8, 0.1, 0.5, 2)})["p_solution_ratio_ant_neat"] is None


# --- the shared --profile / --set helper ------------------------------------------------------


def test_profile_helper_rejects_a_bad_set_naming_the_switch_and_the_value():
    import argparse

    p = argparse.ArgumentParser()
    add_profile_options(p)
    args = p.parse_args(["--profile", "paper", "--set", "soil_fill=false"])
    assert (args.profile, args.assignments) == ("paper", [("soil_fill", False)])
    switches = switches_of(args)
    assert switches["soil_fill"] is False and switches["placement"] == "worksite"
    with pytest.raises(ConfigError) as bad:
        switches_of(p.parse_args(["--set", "soil_fill=3"]))
    assert str(bad.value) == "<command line>: soil_fill = 3: must be like False"
    with pytest.raises(ConfigError, match="placement = 'nowhere': must be one of"):
        switches_of(p.parse_args(["--set", "placement=nowhere"]))
    with pytest.raises(SystemExit):
        p.parse_args(["--set", "soil_fil=true"])  # not a switch: argparse says which
    without = argparse.ArgumentParser()
    add_profile_options(without, default=None)  # ant-evolve: the config file's profile
    assert without.parse_args([]).profile is None


def test_every_command_with_a_profile_rejects_a_bad_set_alike(tmp_path, capsys):
    """ant-experiment, ant-eval, ant-sweep and ant-evolve share the helper: the same message."""
    from ant_evolution.cli_eval import main as ant_eval
    from ant_evolution.cli_evolve import main as ant_evolve
    from ant_evolution.sweep import main as ant_sweep

    bad = ["--set", "soil_fill=3"]
    commands = {
        "ant-experiment": lambda: cli.main(["depth", "--out", str(tmp_path / "e"), *bad]),
        "ant-eval": lambda: ant_eval(["--hand-coded", *bad]),
        "ant-sweep": lambda: ant_sweep(["--hand-coded", "--out", str(tmp_path / "s"), *bad]),
        "ant-evolve": lambda: ant_evolve(["--out", str(tmp_path / "v"), *bad]),
    }
    for name, run in commands.items():
        capsys.readouterr()
        assert run() == 2, name
        assert capsys.readouterr().err == (
            f"{name}: error: <command line>: soil_fill = 3: must be like False\n"
        )
    assert not any(tmp_path.iterdir())  # refused before writing anything


# --- compute steps: pure (same inputs, same rows; no files, no output) ------------------------


def _history(n: int, best: float, robots_hist: str = "") -> list[dict]:
    return [
        {"generation": g, "evaluations": 12 * (g + 1), "best": best + 0.01 * g,
         "best_ever": best + 0.01 * g, "robots_hist": robots_hist}
        for g in range(n)
    ]  # fmt: skip


def _pure(compute, *args):
    """``compute(*args)`` twice: the same rows, the inputs untouched."""
    before = repr(args)
    rows = compute(*args)
    assert rows and compute(*args) == rows
    assert repr(args) == before
    return rows


def test_history_computes_are_pure(capsys):
    runs = {("ant", 1): [_history(3, 0.2), _history(4, 0.3)], ("ant", 2): [_history(3, 0.5)]}
    rows = _pure(training.compute, runs, (1, 2))
    assert len(rows) == 3 + 4 + 3 and rows[0] == {
        "robots": 1, "run": 0, "generation": 0, "evaluations": 12, "best": 0.2, "best_ever": 0.2
    }  # fmt: skip
    assert training.curves(rows, 1, "best").shape == (2, 3)  # cut to the shortest run
    both = {(m, n): [_history(3, 0.4 + 0.1 * i)] for i, m in enumerate(compare.METHODS)
            for n in (2,)}  # fmt: skip
    rows = _pure(compare.compute, both, 2)
    assert [r["method"] for r in rows] == ["ant"] * 3 + ["fixed"] * 3 + ["neat"] * 3
    cc = {(m, n): [_history(2, 0.3)] for m in coarse_coding.METHODS for n in (1, 2)}
    cc[("ant-nocc", 2)] = []  # --finished: a setting without a finished run is left out
    rows = _pure(coarse_coding.compute, cc, (1, 2))
    assert [(r["method"], r["robots"]) for r in rows] == [("ant", 1), ("ant", 2), ("ant-nocc", 1)]
    hists = [_history(5, 0.1, "1:2;3:6"), _history(5, 0.1, "2:8")]
    rows = _pure(evolve_robots.compute, hists, [3, 3], (1, 3))
    assert [r["best_genomes"] for r in rows] == [0, 0, 2]
    assert sum(r["population_share"] for r in rows) == pytest.approx(1.0)
    assert capsys.readouterr() == ("", "")


def test_scoring_computes_are_pure(tmp_path, capsys):
    """The scoring computes read and write nothing: the context's directory is never made."""
    ctx = Context(tmp_path / "never", TINY, runs=1)
    hand = Controller.hand_coded()
    _pure(antagonism.compute, hand, ctx, lambda: None)
    _pure(scaleup.compute, ctx, [("hand-coded", hand)], lambda: None)
    # depth and area are one sweep of long runs, one compute over either's cells
    assert EXPERIMENTS["depth"] is long_run.depth and EXPERIMENTS["area"] is long_run.area
    for name, sweep in long_run.SWEEPS.items():
        rows = _pure(long_run.compute, hand, ctx, sweep, lambda: None)
        keys = TINY.depths if name == "depth" else TINY.area_sizes
        assert [(r.key, r.robots) for r in rows] == [(k, n) for k in keys for n in TINY.eval_robots]
    assert not (tmp_path / "never").exists()
    assert capsys.readouterr() == ("", "")


def test_long_run_commands_write_their_computes_rows(done):
    """depth.csv and area.csv are long_run.compute's rows for the 4-robot controller."""
    ctl, _ = four_robot_controller(done)
    for name, sweep in long_run.SWEEPS.items():
        rows = long_run.compute(ctl, done, sweep, lambda: None)
        with open(done.out / name / f"{name}.csv", newline="") as f:
            written = list(csv.DictReader(f))
        assert written == [{k: str(v) for k, v in r.csv(sweep.key_label).items()} for r in rows]


def test_behaviours_compute_is_pure(done):
    ctl, _ = four_robot_controller(done)
    found = behaviours.activity(ctl)
    rows = behaviours.compute(found, ctl.tissue.decision_genes)
    assert repr(rows) == repr(behaviours.compute(found, ctl.tissue.decision_genes))  # NaN rates
    assert len(rows) == ctl.tissue.n_decision * len(found["detected"])


def test_section_table():
    assert table(["a", "b"], "lr", [["x", "1"]]) == "| a | b |\n|---|---:|\n| x | 1 |"
    with pytest.raises(ValueError):
        table(["a", "b"], "l", [])


def _profile_ctx(tmp_path, profile):
    from ant_evolution.experiments.core import SCALES, Context

    return Context(out=tmp_path, scale=SCALES["quick"], runs=1, profile=profile)


def test_a_paper_profile_experiment_writes_beside_the_v1_one(tmp_path):
    from ant_evolution.experiments.core import run_dir

    v1, paper = _profile_ctx(tmp_path, "v1"), _profile_ctx(tmp_path, "paper")
    assert v1.dir("compare") == tmp_path / "compare"
    assert paper.dir("compare") == tmp_path / "compare-paper"
    assert run_dir(paper, "ant", 4, 0).parent.name == "quick-paper"
    assert run_dir(v1, "ant", 4, 0).parent.name == "quick"


def test_a_cell_whose_robots_do_not_fit_its_site_is_left_out_not_fatal():
    """Under the paper profile the fitted site of a 4 x 4 pit is 8 x 8, where 10 robots may
    find no free place: that cell reads ``-`` and the rest of the grid is scored."""
    import numpy as np

    from ant_evolution.experiments.core import site
    from ant_evolution.experiments.grids import every_run_summary, robot_grid
    from ant_evolution.experiments.sections import UNPLACED_NOTE, peak_table
    from excavation_sim.world import PlacementError, place_in_worksite

    zones = site(4, 1, fitted=True).zones
    assert zones.shape == (8, 8)
    with pytest.raises(PlacementError):
        for seed in range(50):  # random places fragment the 8 x 8 site long before 16 fit
            place_in_worksite(zones, 16, np.random.default_rng(seed))

    def score(key, n):
        if key == 4 and n == 3:
            raise PlacementError("could not place robot 3 of 3 on a 8 x 8 grid")
        return np.full(5, 0.1 * n + key / 100)

    rows = robot_grid(score, [4, 6], [1, 2, 3])
    lost = [r for r in rows if r.mean != r.mean]
    assert [(r.key, r.robots) for r in lost] == [(4, 3)]
    assert list(lost[0].csv("pit")) == ["pit", "robots", "mean", "std"]
    text = peak_table(rows, [4, 6], "pit", [1, 2, 3])
    assert "| 4 | 0.140 | 0.240 | - | 2 robots |" in text
    assert "| 6 | 0.160 | 0.260 | 0.360 | 3 robots |" in text
    assert text.endswith(UNPLACED_NOTE)
    every = [dataclasses.replace(r, run=k, training_fitness=0.9) for k in (0, 1) for r in rows]
    assert list(every[0].csv("pit"))[:3] == ["run", "training_fitness", "pit"]
    (g4, g6) = every_run_summary(every, [(4, [(0,), (1,)]), (6, [(0,), (1,)])], [1, 2, 3])
    assert g4.peaks == [2, 2] and g6.peaks == [3, 3]
    assert np.isnan(g4.mean[2]) and not np.isnan(g4.mean[1])


def test_an_experiment_on_a_physical_soil_trains_and_scores_there(tmp_path, capsys):
    """``ant-experiment --soil physical:dome --randomise``: its runs train on that soil with
    the randomisation, beside the grid's, and its tables score there."""
    from pathlib import Path

    scale = dataclasses.replace(TINY, steps=150)  # long enough for the genome to dig
    ctx = Context(tmp_path, scale, runs=1, soil="physical:dome", randomise=True)
    assert ctx.dir("training") == tmp_path / "training-physical-dome-randomised"
    assert run_dir(ctx, "ant", 1, 0).parent.name == "quick-physical-dome-randomised"
    cfg = train_config(ctx, "ant", 1, 0)
    assert cfg.soil == "physical:dome" and cfg.randomise
    genome = Path("genomes/best.json")
    EXPERIMENTS["antagonism"](dataclasses.replace(ctx, genome=genome))
    rows = (ctx.dir("antagonism") / "antagonism.csv").read_text()
    grid = Context(tmp_path, scale, runs=1, genome=genome)
    EXPERIMENTS["antagonism"](grid)
    assert rows != (grid.dir("antagonism") / "antagonism.csv").read_text()
    with pytest.raises(SystemExit):
        cli.main(["behaviours", "--soil", "physical:dome", "--out", str(tmp_path)])
    assert "on the grid" in capsys.readouterr().err
