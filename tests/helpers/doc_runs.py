"""The documented commands that run for real (docs as tests, tier two: make test-system).

Tier one (:mod:`helpers.doc_commands`) passes every documented command through its parser.
Here a curated set, at least one per documented workflow, runs as the user would type it,
at a reduced size, in a scratch directory holding a copy of what the commands read
(``genomes/``, ``bags/``, the packages' ``config/`` folders and any fixture a run names):

* each :class:`Step` names a command exactly as a doc shows it (its words joined by one
  space, as :func:`helpers.doc_commands.commands_of` splits them); the run fails when the
  doc no longer shows it, so a changed doc cannot leave a stale run behind;
* ``smaller`` gives options a smaller value (the option must be in the command: fewer ticks,
  generations or scenarios), ``replace`` swaps a placeholder word (``dome_runs/DATE``) for
  the real one, ``add`` appends options the doc leaves to their defaults (a ROS domain of
  the test's own, a population small enough for the budget);
* a step the doc ends with ``&`` runs in the background and is waited for (or stopped with
  SIGINT, ``stop``) after the steps that follow it.

The whole set has a budget (:data:`BUDGET_S`, docs/architecture.md "Tests"): each step
has a hard limit so that a hang fails instead of stalling the suite, and a run reports
its time; no test asserts a time.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from helpers.doc_commands import ROOT, blocks_of, commands_of, entry_points
from helpers.view_client import Client

BIN = Path(sys.executable).parent
BUDGET_S = 600
"""The curated set's stated budget, on two workers of this project's 2-core machine."""
STEP_LIMIT_S = 240
"""A hard limit per step: past it the step has hung."""


@dataclass(frozen=True)
class Step:
    """One documented command and how the run shrinks it."""

    command: str
    smaller: dict[str, str] = field(default_factory=dict)
    replace: dict[str, str] = field(default_factory=dict)
    add: tuple[str, ...] = ()
    returncodes: tuple[int, ...] = (0,)
    """Exit codes the doc leads a user to expect (``ant-bag diff``: 1 when the bags differ)."""
    stop: bool = False
    """A background step still running after the others: SIGINT it (as Ctrl-C would)."""
    ready: tuple[str, ...] = ()
    """A background step: a command of ours that succeeds once it is up (the user's cue to
    go on), run before the next step."""


@dataclass(frozen=True)
class DocRun:
    """A workflow from one doc: its steps in order, in one scratch directory."""

    workflow: str
    doc: str
    steps: tuple[Step, ...]
    fixtures: dict[str, str] = field(default_factory=dict)
    """Scratch path -> repository path: a file the doc tells the user to bring."""
    outputs: tuple[str, ...] = ()
    """Paths the run must leave behind."""
    view: tuple[str, ...] = ()
    """Live-view channels a client must receive while a ``--view`` step runs."""


SITES = "ros2_ws/src/excavation_bringup/config"
DOMAIN = ("--domain", "{domain}")
VIEW = ("/view/robots", "/view/height_map", "/view/blueprint", "/view/fitness", "/tf")
RUNS: tuple[DocRun, ...] = (
    DocRun(
        "demo",
        "README.md",
        (
            Step("ant-bag info bags/sample"),
            Step("ant-bag report bags/sample --out sample-report"),
            Step(
                "ant-trial --genome genomes/best.json --robots 4 --blueprint default:1 "
                "--steps 100 --record my_run",
                smaller={"--steps": "6"},
            ),
            Step("ant-bag play my_run --rate 4"),
        ),
        outputs=("sample-report/summary.md", "my_run/metadata.yaml"),
    ),
    DocRun(
        "eval",
        "README.md",
        (
            Step(
                "ant-eval --hand-coded --robots 1 --depth 2 --scenarios 100 --seed 0",
                smaller={"--scenarios": "3"},
            ),
            Step(
                "ant-eval --hand-coded --snapshots out/ --snapshot-steps 0,100,300",
                add=("--scenarios", "1"),
            ),
        ),
        outputs=("out/strip.png",),
    ),
    DocRun(
        "evolve",
        "README.md",
        (
            Step(
                "ant-evolve --out runs/r1 --generations 200",
                smaller={"--generations": "2"},
                add=("--population", "6", "--scenarios", "2", "--workers", "1"),
            ),
            Step(
                "ant-evolve --out runs/r1 --resume --generations 400",
                smaller={"--generations": "3"},
            ),
        ),
        outputs=("runs/r1/best.json", "runs/r1/fitness.png"),
    ),
    DocRun(
        "trial",
        "docs/interfaces.md",
        (Step("ant-trial --hand-coded --robots 2 --processes", add=("--steps", "5")),),
    ),
    DocRun(
        "bag record / play / report",
        "docs/bags.md",
        (
            Step(
                "ant-trial --genome genomes/best.json --robots 4 --blueprint default:1 "
                "--steps 100 --record run1",
                smaller={"--steps": "6"},
            ),
            Step("ant-bag info run1 --sizes"),
            Step("ant-bag report run1 --out run1-report"),
            Step("ant-bag play run1 --rate 2"),
        ),
        outputs=("run1-report/summary.md",),
    ),
    DocRun(
        "dome up --sim, bag replay, re-perception, diff",
        "docs/bags.md",
        (
            Step(
                f"ant-dome up {SITES}/site_sim.yaml --sim --record runs/dome1",
                add=("--ticks", "3", "--run-dir", "dome_runs/run", *DOMAIN),
            ),
            Step("ant-bag play runs/dome1 --clock --rate 4"),
            Step("ant-bag report runs/dome1 --out runs/dome1-report"),
            Step("ant-bag play runs/dome1 --genome genomes/best.json"),
            Step(
                "ant-bag play runs/dome1 --reperceive --run-dir dome_runs/20261205-1230 "
                "--out runs/dome1-again",
                replace={"dome_runs/20261205-1230": "dome_runs/run"},
            ),
            Step(
                "ant-bag diff runs/dome1 runs/dome1-again --topics /robot_*/pose "
                "/worksite/height_map",
                returncodes=(0, 1),  # re-perceived poses may differ by a fraction of a mm
            ),
        ),
        outputs=("runs/dome1-report/summary.md", "dome_runs/run/state.json"),
    ),
    DocRun(
        "dome check, rehearse with the live view",
        "docs/dome.md",
        (
            Step(f"ant-dome check {SITES}/site_rehearsal.yaml --rehearse"),
            Step(
                f"ant-dome rehearse {SITES}/site_rehearsal.yaml --ticks 20 --record bags/rehearsal "
                "--view",
                smaller={"--ticks": "3"},
                add=("--run-dir", "dome_runs/rehearsal", "--view-port", "{port}", *DOMAIN),
            ),
        ),
        outputs=("bags/rehearsal/metadata.yaml", "dome_runs/rehearsal/logs/view.log"),
        view=VIEW + ("/view/camera",),
    ),
    DocRun(
        "dome up --sim with the live view",
        "docs/dome.md",
        (
            Step(
                f"ant-dome up {SITES}/site_sim.yaml --sim --view",
                add=("--ticks", "3", "--run-dir", "dome_runs/up", "--view-port", "{port}", *DOMAIN),
            ),
        ),
        outputs=("dome_runs/up/logs/view.log",),
        view=VIEW,
    ),
    DocRun(
        "dome plan",
        "docs/dome.md",
        (Step(f"ant-dome plan {SITES}/site_rehearsal_hosts.yaml --rehearse"),),
    ),
    DocRun(
        "calibrate",
        "docs/dome.md",
        (Step("ros2 run overhead_localizer calibrate marks.yaml --out camera.yaml"),),
        fixtures={"marks.yaml": "ros2_ws/src/overhead_localizer/config/marks_sim.yaml"},
        outputs=("camera.yaml",),
    ),
    DocRun(
        "operator",
        "docs/operator.md",
        (
            Step(
                "ros2 run team_supervisor supervisor --ros-args -p robots:=4",
                stop=True,
                ready=("ant-operator", "--timeout", "120", "status"),
            ),
            Step(
                "ant-trial --genome genomes/best.json --robots 4 --steps 300 --supervisor external",
                smaller={"--steps": "100000"},  # still running when the operator's turn ends
                stop=True,
            ),
            Step("ant-operator arm"),
            Step("ant-operator pause"),
            Step("ant-operator status"),
            Step("ant-operator resume"),
            Step("ant-operator disable 2"),
            Step("ant-operator enable 2"),
        ),
    ),
    DocRun(
        "operator: a robot hidden from the camera",
        "docs/operator.md",
        (
            Step(
                "ant-trial --genome genomes/best.json --perception full --occlude 2:front,2:rear",
                add=("--steps", "3"),
            ),
        ),
    ),
    DocRun(
        "experiments",
        "docs/experiments.md",
        (
            Step(
                "ant-experiment compare --scale tested --method ant --method fixed --workers 1 "
                "--out campaign",
                smaller={"--scale": "quick"},
            ),
        ),
    ),
    DocRun(
        "field experiments",
        "docs/results.md",
        (
            Step(
                "ant-field-experiment landing-pad --out runs/field",
                add=(
                    "--scale",
                    "quick",
                    "--steps",
                    "4",
                    "--grid-seeds",
                    "1",
                    "--continuous-seeds",
                    "1",
                    *DOMAIN,
                ),
            ),
        ),
    ),
)


def documented(doc: str) -> dict[str, bool]:
    """Every command of ``doc``'s shell blocks (words joined by one space) -> whether the
    doc runs it in the background (a line ending in ``&``)."""
    out: dict[str, bool] = {}
    for block in blocks_of(ROOT / doc):
        for words in commands_of(block.text):
            out.setdefault(" ".join(words), False)
        joined = block.text.replace("\\\n", " ")
        for line in joined.splitlines():
            line = line.split("#")[0].rstrip()
            if line.endswith("&") and not line.endswith("&&"):
                for words in commands_of(line[:-1])[-1:]:
                    out[" ".join(words)] = True
    return out


def argv_of(step: Step, doc: str, values: dict[str, str]) -> tuple[list[str], bool]:
    """The command to run for ``step`` (the doc's words, shrunk) and whether it runs behind.

    Raises:
        AssertionError: When the doc no longer shows the command, or a reduction no longer
            applies (the option or the placeholder is gone).
    """
    shown = documented(doc)
    assert step.command in shown, f"{doc} no longer shows `{step.command}`"
    words = step.command.split(" ")
    for option, value in step.smaller.items():
        assert option in words[:-1], f"`{step.command}` has no {option} to make smaller"
        words[words.index(option) + 1] = value
    for old, new in step.replace.items():
        assert old in words, f"`{step.command}` has no {old} to replace"
        words[words.index(old)] = new
    words += [a.format(**values) for a in step.add]
    eps = entry_points()
    if words[:2] == ["ros2", "run"]:
        words = words[3:]  # ros2 run PACKAGE EXECUTABLE: the executable's console script
    assert words[0] in eps, f"{words[0]}: not a program of this project"
    return [str(BIN / words[0]), *words[1:]], shown[step.command]


def scratch(run: DocRun, where: Path) -> Path:
    """A scratch copy of what the documented commands read, with the run's fixtures."""
    for name in ("genomes", "bags"):
        shutil.copytree(ROOT / name, where / name)
    for config in (ROOT / "ros2_ws/src").glob("*/config"):
        shutil.copytree(config, where / config.relative_to(ROOT))
    for dest, src in run.fixtures.items():
        shutil.copy(ROOT / src, where / dest)
    return where


@dataclass
class Outcome:
    """What one step did."""

    command: list[str]
    returncode: int
    seconds: float
    output: str


def run_doc(run: DocRun, where: Path, domain: int, port: int) -> list[Outcome]:
    """Run every step of ``run`` in ``where``; a failed step raises with its output.

    Raises:
        AssertionError: When a step exits with another code than the doc's, hangs, or the
            run leaves an expected output missing.
    """
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    env["PATH"] = f"{BIN}{os.pathsep}{env.get('PATH', '')}"
    values = {"domain": str(domain), "port": str(port)}
    behind: list[tuple[Step, list[str], subprocess.Popen, float, Path]] = []
    done: list[Outcome] = []
    started: list[subprocess.Popen] = []
    try:
        for i, step in enumerate(run.steps):
            argv, background = argv_of(step, run.doc, values)
            log = where / f".step{i}.log"
            start = time.monotonic()
            with log.open("w") as out:
                proc = subprocess.Popen(
                    argv, cwd=where, env=env, stdout=out, stderr=subprocess.STDOUT,
                    start_new_session=True,
                )  # fmt: skip
            started.append(proc)
            if background:
                behind.append((step, argv, proc, start, log))
                if step.ready:
                    probe = subprocess.run(
                        [str(BIN / step.ready[0]), *step.ready[1:]],
                        cwd=where, env=env, capture_output=True, text=True,
                        timeout=STEP_LIMIT_S,
                    )  # fmt: skip
                    assert probe.returncode == 0, f"{' '.join(argv)} never came up: {probe.stderr}"
                continue
            done.append(_watched(run, step, argv, proc, start, log, port))
        for step, argv, proc, start, log in reversed(behind):  # last started, first stopped
            if step.stop and proc.poll() is None:
                _signal(proc, signal.SIGINT)  # as Ctrl-C: the whole process group
            done.append(_finish(step, argv, proc, start, log, stopped=step.stop))
    finally:  # a failed step leaves nothing running (a background trial would run on)
        for proc in started:
            if proc.poll() is None:
                _signal(proc, signal.SIGKILL)
                proc.wait()
    missing = [p for p in run.outputs if not (where / p).exists()]
    assert not missing, f"{run.workflow}: the run left no {missing}"
    return done


def _watched(run, step, argv, proc, start, log, port) -> Outcome:
    """Finish a foreground step; with ``--view``, a Foxglove client reads the view meanwhile."""
    if not (run.view and "--view" in argv):
        return _finish(step, argv, proc, start, log)
    client = Client(port, list(run.view), connect_within=STEP_LIMIT_S)
    client.start()
    try:
        outcome = _finish(step, argv, proc, start, log)
    finally:
        client.stop.set()
        client.join(10)
    got = set(client.last)
    assert client.error is None and set(run.view) <= got, (
        f"`{' '.join(argv)}`: the view sent {sorted(got)}, not {sorted(run.view)} ({client.error})"
    )
    return outcome


def _signal(proc: subprocess.Popen, sig: int) -> None:
    """Send ``sig`` to ``proc``'s process group (it was started in a session of its own)."""
    try:
        os.killpg(proc.pid, sig)
    except ProcessLookupError:
        pass


def _finish(step, argv, proc, start, log, stopped=False) -> Outcome:
    try:
        proc.wait(timeout=STEP_LIMIT_S)
    except subprocess.TimeoutExpired:
        _signal(proc, signal.SIGKILL)
        proc.wait()
        raise AssertionError(
            f"`{' '.join(argv)}` still running after {STEP_LIMIT_S} s:\n{_tail(log)}"
        ) from None
    outcome = Outcome(argv, proc.returncode, time.monotonic() - start, log.read_text())
    expected = {*step.returncodes, -signal.SIGINT, 130} if stopped else set(step.returncodes)
    assert proc.returncode in expected, (
        f"`{' '.join(argv)}` exited {proc.returncode} (expected {expected}):\n{_tail(log)}"
    )
    return outcome


def _tail(log: Path, chars: int = 4000) -> str:
    return log.read_text()[-chars:]
