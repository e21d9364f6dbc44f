"""The documented workflows run for real (docs as tests, tier two).

tests/helpers/doc_runs.py holds the curated set: at least one documented command per
workflow, run as the doc shows it at a reduced size in a scratch directory. The fast tests
(make test) check that every curated command is still in its doc and every workflow has a
run; the runs themselves are system tests (make test-system).
"""

from __future__ import annotations

import os
import subprocess
import time
from pathlib import Path

import pytest
from helpers.doc_runs import BUDGET_S, ROOT, RUNS, Step, argv_of, documented, run_doc, scratch
from helpers.view_client import free_port

WORKFLOWS = (
    "demo", "eval", "evolve", "trial", "bag record", "bag", "replay", "report", "diff",
    "dome check", "up --sim", "rehearse", "plan", "operator", "view", "calibrate", "experiments",
)  # fmt: skip
"""What the docs teach, each of which must have a run (the issue's list of workflows)."""


def test_every_workflow_has_a_run():
    names = (
        " ".join(run.workflow for run in RUNS)
        + " "
        + " ".join(s.command for run in RUNS for s in run.steps)
    )
    missing = [w for w in WORKFLOWS if w not in names]
    assert not missing, f"no documented run for {missing}"


@pytest.mark.parametrize("run", RUNS, ids=[r.workflow for r in RUNS])
def test_every_curated_command_is_still_in_its_doc(run):
    for step in run.steps:
        argv, _ = argv_of(step, run.doc, {"domain": "1", "port": "1"})
        assert Path(argv[0]).is_file(), f"{argv[0]}: not installed"


def test_a_command_the_doc_no_longer_shows_or_a_stale_reduction_fails():
    with pytest.raises(AssertionError, match="no longer shows"):
        argv_of(Step("ant-eval --hand-coded --no-such-flag"), "README.md", {})
    with pytest.raises(AssertionError, match="has no --ticks to make smaller"):
        argv_of(Step("ant-bag info bags/sample", smaller={"--ticks": "3"}), "README.md", {})


def test_a_backgrounded_command_is_seen_as_such():
    shown = documented("docs/operator.md")
    assert shown[
        "ant-trial --genome genomes/best.json --robots 4 --steps 300 --supervisor external"
    ]
    assert not shown["ant-operator arm"]


# Documented runs that wait in make test-pending while their cause is open (docs/reliability.md,
# "Pending"); none now.
PENDING_RUNS: set[str] = set()


@pytest.mark.system
@pytest.mark.parametrize(
    "run",
    [pytest.param(r, marks=pytest.mark.pending) if r.workflow in PENDING_RUNS else r for r in RUNS],
    ids=[r.workflow for r in RUNS],
)
def test_documented_workflow_runs(run, tmp_path, domains):
    start = time.monotonic()
    outcomes = run_doc(run, scratch(run, tmp_path), domains(), free_port())
    spent = time.monotonic() - start
    print(f"{run.workflow}: {len(outcomes)} commands in {spent:.0f} s (all runs: {BUDGET_S} s)")


def test_what_the_documented_runs_write_is_ignored_by_git():
    """A new user who follows the docs finds no new files in ``git status`` (campaign/ is the
    project's own results: an experiment's --out there is meant to be committed)."""
    paths = [p for run in RUNS for p in run.outputs if not p.startswith("campaign/")]
    result = subprocess.run(
        ["git", "check-ignore", "--no-index", *paths], cwd=ROOT, capture_output=True, text=True
    )
    ignored = set(result.stdout.split())
    assert set(paths) <= ignored, f"not ignored by git: {sorted(set(paths) - ignored)}"


@pytest.mark.system
def test_a_failed_step_leaves_no_background_process_running(tmp_path, domains):
    """The supervisor the operator block starts in the background is killed when a later
    step fails (a trial left running would load the machine for the rest of the suite)."""
    from helpers.doc_runs import DocRun

    failing = DocRun(
        "operator, failing",
        "docs/operator.md",
        (
            Step("ros2 run team_supervisor supervisor --ros-args -p robots:=4", stop=True),
            Step("ant-operator status", returncodes=(7,)),  # no exit code of its: fails
        ),
    )
    with pytest.raises(AssertionError, match="ant-operator status` exited"):
        run_doc(failing, scratch(failing, tmp_path), domains(), free_port())
    here = str(tmp_path.resolve())
    alive = []
    for proc in Path("/proc").iterdir():
        try:
            if proc.name.isdigit() and os.readlink(proc / "cwd") == here:
                alive.append(proc.name)
        except OSError:
            continue
    assert not alive, f"still running in the scratch directory: {alive}"
