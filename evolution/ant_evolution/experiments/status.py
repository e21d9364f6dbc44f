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
        seconds: Sum of the history's generation times (training wall time).
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

    @property
    def finished(self) -> bool:
        """All the scale's generations are in the history."""
        return self.generations >= self.target

    @property
    def state(self) -> str:
        """``finished``, ``at generation G`` (resumable or not) or ``not started``."""
        if self.finished:
            return "finished"
        if self.generations or self.checkpoint:
            how = "" if self.checkpoint else ", no checkpoint: starts again"
            return f"at generation {self.generations}{how}"
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
    )


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


def _f(x: float | None) -> str:
    return "-" if x is None else f"{x:.3f}"


def _command(ctx: Context, name: str, method: str, robots) -> str:
    profile = "" if ctx.profile == "v1" else f" --profile {ctx.profile}"
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
        "(min-max) | first >= 0.9, median | training hours | to finish it |",
        "|---|---|---:|---:|---:|---|---:|---:|---|",
    ]
    detail = ["", "| run | state | best ever | first >= 0.9 | hours |", "|---|---|---:|---:|---:|"]
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
            lines.append(
                f"| {name} | {METHOD_LABELS[method]} {setting_label(robots)} | "
                f"{len(done)} of {len(runs)} | {len(going)} | "
                f"{f'{len(solved)} of {len(done)}' if done else '-'} | {spread} | "
                f"{statistics.median(solved) if solved else '-'} | "
                f"{sum(r.seconds for r in runs) / 3600:.1f} | {todo} |"
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
    return "\n".join(lines + (detail if len(detail) > 3 else [])) + "\n"
