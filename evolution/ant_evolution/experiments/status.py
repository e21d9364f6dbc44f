"""Where a campaign stands: every training run of every training experiment, read from disk.

``ant-experiment status --scale tested --out campaign`` prints (or, with ``--write``,
saves) a markdown report: one row per setting (runs finished, runs in progress, runs
reaching 0.9, best fitness ever over the finished runs, the command that trains that
setting's missing runs) and one per started run. It reads only ``history.csv``,
``best.json`` and the checkpoints' presence in each run directory; it trains nothing and
needs no compiled kernel, so it can run beside the campaign it reports on.
"""

from __future__ import annotations

import statistics
from dataclasses import dataclass
from pathlib import Path

from ant_evolution.experiments.core import (
    METHOD_LABELS,
    SOLVED,
    TRAINING_EXPERIMENTS,
    Context,
    read_history,
    run_dir,
    setting_label,
    training_jobs,
)


@dataclass(frozen=True)
class RunStatus:
    """One training run as found on disk.

    Attributes:
        method: ``ant``, ``ant-nocc``, ``fixed`` or ``neat``.
        setting: The robot setting's label (``n4``, ``mix1+4``, ``evoN``).
        run: Run index k (seed ``1000 + k``).
        path: The run directory.
        generations: Generations in its ``history.csv`` (0 when there is none).
        target: Generations the scale asks for.
        checkpoint: Whether a checkpoint is there to resume from.
        best_ever: Highest best-of-generation fitness in the history (``None``: no history).
        first_solved: First generation whose best reached :data:`SOLVED` (``None``: none).
        evaluations_solved: Scenario evaluations up to and including that generation.
        seconds: Sum of the history's generation times (each generation's evaluation).
        node: Where its last chunk ran on a cluster (``cluster.json``: the host and the Ray
            node id's head); empty when it was trained here.
    """

    method: str
    setting: str
    run: int
    path: Path
    generations: int
    target: int
    checkpoint: bool
    best_ever: float | None
    first_solved: int | None
    evaluations_solved: int | None
    seconds: float
    node: str = ""

    @property
    def finished(self) -> bool:
        """All the scale's generations are in the history."""
        return self.generations >= self.target

    @property
    def state(self) -> str:
        """``finished``, ``at generation G`` (resumable or not) or ``not started``."""
        where = f" (last chunk on {self.node})" if self.node else ""
        if self.finished:
            return f"finished{where}"
        if self.generations or self.checkpoint:
            how = "" if self.checkpoint else ", no checkpoint: starts again"
            return f"at generation {self.generations}{how}{where}"
        return "not started"


def run_status(ctx: Context, method: str, robots, run: int) -> RunStatus:
    """The state of one training run of ``ctx``'s scale and profile."""
    d = run_dir(ctx, method, robots, run)
    hist = d / "history.csv"
    rows = read_history(hist) if hist.exists() else []
    first = next((r for r in rows if r["best"] >= SOLVED), None)
    return RunStatus(
        method=method,
        setting=setting_label(robots),
        run=run,
        path=d,
        generations=len(rows),
        target=ctx.scale.generations,
        checkpoint=(d / "checkpoint.json").exists() or (d / "neat-checkpoint.gz").exists(),
        best_ever=max((r["best"] for r in rows), default=None),
        first_solved=None if first is None else first["generation"],
        evaluations_solved=None if first is None else first["evaluations"],
        seconds=sum(r["seconds"] for r in rows),
        node=_last_node(d),
    )


def _last_node(d: Path) -> str:
    """The node of a run's last cluster chunk (``cluster.json``), or empty."""
    import json

    try:
        chunks = json.loads((d / "cluster.json").read_text())["chunks"]
        last = chunks[-1]
        return f"{last['host']} {str(last['node_id'])[:8]}"
    except (OSError, ValueError, KeyError, IndexError, TypeError):
        return ""


def campaign(ctx: Context) -> dict[str, list[tuple[str, object, list[RunStatus]]]]:
    """Every setting of every training experiment: ``{experiment: [(method, robots, runs)]}``.

    A setting shared by several experiments (``compare``'s 4-robot ANT runs are
    ``training``'s) is listed under the first of :data:`TRAINING_EXPERIMENTS` only.
    """
    seen: set = set()
    out: dict = {}
    for name in TRAINING_EXPERIMENTS:
        for method, robots in training_jobs(name, ctx.scale):
            if (method, robots) in seen:
                continue
            seen.add((method, robots))
            runs = [run_status(ctx, method, robots, k) for k in range(ctx.runs)]
            out.setdefault(name, []).append((method, robots, runs))
    return out


def hours_left(runs: list[RunStatus]) -> float | None:
    """One core's evaluation hours to finish a setting's runs, at its finished runs' pace.

    The pace is the finished runs' evaluation seconds per generation; a run in progress
    counts its missing generations, one without a checkpoint all of them (it starts
    again). ``None`` when no run of the setting is finished (no pace to go by).
    """
    done = [r for r in runs if r.finished]
    if not done:
        return None
    pace = sum(r.seconds for r in done) / sum(r.generations for r in done)
    missing = sum(r.target - (r.generations if r.checkpoint else 0) for r in runs if not r.finished)
    return missing * pace / 3600


def _f(x: float | None) -> str:
    return "-" if x is None else f"{x:.3f}"


def _command(ctx: Context, name: str, method: str, robots) -> str:
    profile = "" if ctx.profile == "v1" else f" --profile {ctx.profile}"
    profile += "" if ctx.soil == "grid" else f" --soil {ctx.soil}"
    profile += " --randomise" if ctx.randomise else ""
    return (
        f"ant-experiment {name} --scale {ctx.scale.name}{profile} --method {method} "
        f"--setting {setting_label(robots)} --workers 2 --out {ctx.out}"
    )


def report(ctx: Context) -> str:
    """The campaign's state as markdown (module docstring)."""
    s = ctx.scale
    found = campaign(ctx)
    lines = [
        f"Campaign `{ctx.out}`, scale `{s.name}` ({ctx.runs} runs per setting, "
        f"{s.generations} generations of P = {s.population} x S = {s.scenarios}), "
        f"profile `{ctx.profile}`. Runs reaching {SOLVED} and best ever are over finished "
        "runs (std: over the runs, as in the experiments' tables); first >= 0.9 is a "
        "generation (scenario evaluations in millions).",
        "",
        "| experiment | setting | finished | in progress | reaching 0.9 | best ever, mean +- std "
        "(min-max) | first >= 0.9, median | evaluation hours | evaluation hours left, one "
        "core (estimate) | to finish it |",
        "|---|---|---:|---:|---:|---|---:|---:|---:|---|",
    ]
    detail = ["", "| run | state | best ever | first >= 0.9 | hours |", "|---|---|---:|---:|---:|"]
    timed, untimed = 0.0, 0
    for name, settings in found.items():
        for method, robots, runs in settings:
            done = [r for r in runs if r.finished]
            going = [r for r in runs if not r.finished and (r.generations or r.checkpoint)]
            ever = [r.best_ever for r in done]
            spread = (
                "-"
                if not ever
                else f"{statistics.fmean(ever):.3f} +- "
                f"{statistics.pstdev(ever):.3f} "
                f"({min(ever):.3f}-{max(ever):.3f})"
            )
            solved = [r.first_solved for r in done if r.first_solved is not None]
            todo = "" if len(done) == len(runs) else f"`{_command(ctx, name, method, robots)}`"
            left = hours_left(runs)
            if left is None:
                untimed += len(runs) - len(done)
            else:
                timed += left
            lines.append(
                f"| {name} | {METHOD_LABELS[method]} {setting_label(robots)} | "
                f"{len(done)} of {len(runs)} | {len(going)} | "
                f"{f'{len(solved)} of {len(done)}' if done else '-'} | {spread} | "
                f"{statistics.median(solved) if solved else '-'} | "
                f"{sum(r.seconds for r in runs) / 3600:.1f} | "
                f"{'-' if left is None else f'{left:.1f}'} | {todo} |"
            )
            for r in runs:
                if not (r.generations or r.checkpoint):
                    continue
                first = (
                    "-"
                    if r.first_solved is None
                    else f"{r.first_solved} ({r.evaluations_solved / 1e6:.2f})"
                )
                detail.append(
                    f"| `{r.path.name}` | {r.state} | {_f(r.best_ever)} | {first} | "
                    f"{r.seconds / 3600:.2f} |"
                )
    lines += [
        "",
        f"Left: about {timed:.1f} h of one core's evaluation for the settings with a "
        f"finished run (at their pace), and {untimed} runs of settings without one. Hours "
        "are the histories' `seconds`: each generation's evaluation, with any time the run "
        "was paused meanwhile; breeding and checkpoints come on top (little for the fixed "
        "network, most for NEAT: docs/experiments.md).",
    ]
    return "\n".join(lines + (detail if len(detail) > 3 else [])) + "\n"
