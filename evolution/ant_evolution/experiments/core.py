"""Shared machinery of the section-5 experiments: scales, training runs, scoring, outputs.

A *training run* is one evolution (ANT, ANT without coarse coding, fixed network or NEAT)
with one robot setting and one seed, in ``OUT/runs/<scale>/<method>-<setting>-r<k>/``.
Runs are resumed from their checkpoints and shared between experiments that pass the same
``--out`` (``compare`` reuses the 4-robot ANT runs of ``training``). Run k of every method
uses seed ``1000 + k``, so the methods see the same scenarios generation by generation.
Evaluations of evolved controllers use seeds from 10,000 on, which training never used.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ant_controller.controller import Controller
from ant_controller.genome_io import load_genome
from ant_evolution.baseline_runs import load_program, run_fixed, run_neat
from ant_evolution.baselines.network import NetworkProgram
from ant_evolution.evaluate import ScenarioSet
from ant_evolution.evolve import EvolveConfig, run_evolution
from ant_evolution.profiles import profile_switches, world_rules_of
from blueprint_server.blueprint import Blueprint, pit_blueprint
from excavation_common.progress import tqdm
from excavation_sim.rules import DEFAULT_RULES, WorldRules

METHODS = ("ant", "ant-nocc", "fixed", "neat")
METHOD_LABELS = {
    "ant": "ANT",
    "ant-nocc": "ANT without coarse coding",
    "fixed": "fixed network",
    "neat": "NEAT",
    "hand-coded": "hand-coded",
}
EVAL_SEED = 10_000
SOLVED = 0.9
"""The fitness the paper counts as a solution."""


@dataclass(frozen=True)
class Scale:
    """How big an experiment is.

    Attributes:
        name: ``quick``, ``medium``, ``tested`` or ``paper``.
        population: P of every training run.
        generations: Generations of every training run.
        scenarios: Scenarios per generation (split over goal depths 1-3).
        steps: Timesteps per training scenario.
        runs: Repetitions per setting (``--runs`` overrides).
        train_robots: Robot counts trained for (the paper: 1 to 5).
        eval_robots: Robot counts evolved controllers are applied to (paper: 1 to 10).
        eval_scenarios: Scenarios per evaluated setting.
        long_steps: Timesteps of the ``depth`` and ``area`` experiments (paper: 10,000).
        areas: Square pit sizes of ``antagonism`` (paper: 6, 8, 10).
        area_sizes: Square pit sizes of ``area``.
        depths: Goal depths (training mixes them; ``depth`` sweeps them).
        robots_range: Bounds of the N gene in ``evolve-robots``.
        checkpoint_every: Generations between checkpoints.
    """

    name: str
    population: int
    generations: int
    scenarios: int
    steps: int
    runs: int
    train_robots: tuple[int, ...]
    eval_robots: tuple[int, ...]
    eval_scenarios: int
    long_steps: int
    areas: tuple[int, ...]
    area_sizes: tuple[int, ...]
    depths: tuple[int, ...] = (1, 2, 3)
    robots_range: tuple[int, int] = (1, 8)
    checkpoint_every: int = 10


_FULL_SWEEPS = dict(
    train_robots=(1, 2, 3, 4, 5),
    eval_robots=tuple(range(1, 11)),
    areas=(6, 8, 10),
    area_sizes=(4, 6, 8, 10, 12),
    depths=(1, 2, 3),
    robots_range=(1, 8),
)
"""The settings every scale but ``quick`` sweeps (the paper's figures)."""

SCALES = {
    "quick": Scale(
        "quick",
        population=8,
        generations=3,
        scenarios=3,
        steps=40,
        runs=2,
        eval_scenarios=3,
        long_steps=60,
        checkpoint_every=2,
        train_robots=(1, 2),
        eval_robots=(1, 2, 3),
        areas=(6, 8),
        area_sizes=(6, 8),
        depths=(1, 2),
        robots_range=(1, 3),
    ),
    "medium": Scale(
        "medium",
        population=40,
        generations=100,
        scenarios=12,
        steps=300,
        runs=2,
        eval_scenarios=30,
        long_steps=3000,
        checkpoint_every=10,
        **_FULL_SWEEPS,
    ),
    # The campaign of the reproduction (docs/experiments.md, "The tested scale"): 10 runs
    # per setting; 1,500 generations of P 100 x S 30 = 4.5 million scenario evaluations per
    # run, what the v1 paper-scale run needed to reach 0.9 (4.3 million, generation 433).
    "tested": Scale(
        "tested",
        population=100,
        generations=1500,
        scenarios=30,
        steps=300,
        runs=10,
        eval_scenarios=100,
        long_steps=10000,
        checkpoint_every=25,
        **_FULL_SWEEPS,
    ),
    "paper": Scale(
        "paper",
        population=100,
        generations=5000,
        scenarios=100,
        steps=300,
        runs=30,
        eval_scenarios=100,
        long_steps=10000,
        checkpoint_every=25,
        **_FULL_SWEEPS,
    ),
}


@dataclass(frozen=True)
class Context:
    """Where and how an experiment runs.

    Attributes:
        out: Root output directory (shared training runs live in ``out/runs``).
        scale: The scale.
        runs: Repetitions per setting.
        workers: Local worker processes per evaluation.
        ray_address: Ray address or ``None``.
        genome: The 4-robot ANT controller of ``antagonism``, ``depth``, ``area`` and
            ``behaviours`` (``None``: the best 4-robot genome of this scale's training).
        replay: ``behaviours``: the ANT run directory to replay (``None``: this scale's
            4-robot run r0).
        generations: ``behaviours``: replay only this many generations.
        profile: The readings of the paper (``v1`` or ``paper``,
            :mod:`ant_evolution.profiles`); training runs of another profile than ``v1``
            live under ``runs/SCALE-PROFILE``, its results under ``NAME-PROFILE``.
        switches: Every switch (the profile's, with ``--set`` applied); ``None``: the
            profile's.
        only_methods: Train only these methods (``--method``); ``None``: every one.
        only_runs: Train only these run indices (``--run``); ``None``: every one.
        only_settings: Train only these robot settings, by label (``--setting``: ``n4``,
            ``mix1+4``, ``evoN``); ``None``: every one. With any of the three set, a
            training experiment trains that part of its runs and stops before its summary
            (:class:`PartialTraining`), so that several processes or machines can share one
            campaign directory, each training its own runs.
        finished_only: ``--finished``: a training experiment trains nothing and summarises
            the runs that are finished (a campaign in part; every table says how many runs
            each setting has).
        soil: The soil every run trains on and every controller is scored on (``grid``, or a
            physical soil: ``--soil``); its runs and results live under names with the
            soil appended (:attr:`suffix`).
        randomise: Every scenario draws its world (``--randomise``,
            :mod:`ant_evolution.randomise`); names get ``-randomised``.
        cluster: A Ray cluster's address (``--cluster``; ``local``: a Ray instance here)
            the missing runs train on, one run per task
            (:mod:`ant_evolution.experiments.cluster`); ``None``: here, one after another.
    """

    out: Path
    scale: Scale
    runs: int
    workers: int = 1
    ray_address: str | None = None
    genome: Path | None = None
    replay: Path | None = None
    generations: int | None = None
    profile: str = "v1"
    switches: dict | None = None
    only_methods: tuple[str, ...] | None = None
    only_runs: tuple[int, ...] | None = None
    only_settings: tuple[str, ...] | None = None
    finished_only: bool = False
    soil: str = "grid"
    randomise: bool = False
    cluster: str | None = None

    @property
    def suffix(self) -> str:
        """The name ending of this context's runs and results (empty: ``v1`` on the grid).

        The profile (but ``v1``), the soil (but ``grid``; its punctuation as ``-``), and
        ``randomised``.
        """
        parts = [] if self.profile == "v1" else [self.profile]
        if self.soil != "grid":
            parts.append(re.sub(r"[^A-Za-z0-9.]+", "-", self.soil).strip("-"))
        if self.randomise:
            parts.append("randomised")
        return "".join(f"-{p}" for p in parts)

    @property
    def partial(self) -> bool:
        """Whether only part of the runs is to be trained (--method, --run, --setting)."""
        chosen = (self.only_methods, self.only_runs, self.only_settings)
        return any(c is not None for c in chosen)

    @property
    def readings(self) -> dict:
        """Every switch of this context."""
        return dict(self.switches) if self.switches is not None else profile_switches(self.profile)

    @property
    def rules(self) -> WorldRules:
        """The world's switches."""
        return world_rules_of(self.readings)

    def dir(self, name: str) -> Path:
        """Output directory of experiment ``name`` (``NAME`` and the :attr:`suffix`)."""
        d = self.out / f"{name}{self.suffix}"
        d.mkdir(parents=True, exist_ok=True)
        return d


def compare_robots(scale: Scale) -> int:
    """The team size of ``compare`` and of the mixed setting: 4, or the scale's largest."""
    return 4 if 4 in scale.train_robots else scale.train_robots[-1]


TRAINING_EXPERIMENTS = ("compare", "training", "coarse-coding", "scaleup", "evolve-robots")
"""The experiments that train runs, cheapest headline first (the campaign's order)."""


def training_jobs(name: str, scale: Scale) -> list[tuple[str, object]]:
    """The ``(method, robots)`` settings that training experiment ``name`` trains.

    Raises:
        ValueError: ``name`` is not a training experiment.
    """
    n = compare_robots(scale)
    robots = scale.train_robots
    if name == "compare":  # cheapest first: a cut-short campaign keeps the most
        return [(m, n) for m in ("ant", "fixed", "neat")]
    if name == "training":
        return [("ant", k) for k in robots]
    if name == "coarse-coding":
        return [(m, k) for m in ("ant", "ant-nocc") for k in robots]
    if name == "scaleup":
        return [("ant", k) for k in robots] + [("ant", (1, n))] + [("fixed", k) for k in robots]
    if name == "evolve-robots":
        return [("ant", "evolve")]
    raise ValueError(f"{name!r} is not a training experiment ({', '.join(TRAINING_EXPERIMENTS)})")


def setting_label(robots: int | tuple[int, ...] | str) -> str:
    """Directory-safe name of a robot setting: ``n4``, ``mix1+4`` or ``evoN``."""
    if robots == "evolve":
        return "evoN"
    if isinstance(robots, tuple):
        return "mix" + "+".join(str(n) for n in robots)
    return f"n{robots}"


def train_config(ctx: Context, method: str, robots, run: int) -> EvolveConfig:
    """The :class:`EvolveConfig` of one training run."""
    s = ctx.scale
    kw: dict = {
        "population": s.population,
        "generations": s.generations,
        "scenarios": s.scenarios,
        "steps": s.steps,
        "depths": s.depths,
        "seed": 1000 + run,
        "checkpoint_every": s.checkpoint_every,
        "coarse_coding": method != "ant-nocc",
    }
    if robots == "evolve":
        kw.update(evolve_robots=True, robots_range=s.robots_range)
    elif isinstance(robots, tuple):
        kw.update(robots=robots[0], robots_mix=robots)
    else:
        kw["robots"] = int(robots)
    return EvolveConfig(
        profile=ctx.profile, **ctx.readings, soil=ctx.soil, randomise=ctx.randomise, **kw
    )


def run_dir(ctx: Context, method: str, robots, run: int) -> Path:
    """Directory of one training run (``runs/SCALE`` and the context's :attr:`~Context.suffix`)."""
    scale = f"{ctx.scale.name}{ctx.suffix}"
    return ctx.out / "runs" / scale / f"{method}-{setting_label(robots)}-r{run}"


def _finished(d: Path) -> bool:
    hist = d / "history.csv"
    return hist.exists() and _history_length(hist) > 0 and (d / "best.json").exists()


def _history_length(path: Path) -> int:
    with open(path, newline="") as f:
        return sum(1 for _ in csv.DictReader(f))


def train(ctx: Context, method: str, robots, run: int, bar: tqdm | None = None) -> list[dict]:
    """Run (or resume, or just read) one training run; returns its history rows."""
    config = train_config(ctx, method, robots, run)
    d = run_dir(ctx, method, robots, run)
    hist = d / "history.csv"
    if _trained(ctx, method, robots, run):
        return read_history(hist)
    resume = (d / "checkpoint.json").exists() or (d / "neat-checkpoint.gz").exists()

    def progress(row: dict) -> None:
        if bar is not None:
            bar.set_postfix(run=d.name, gen=row["generation"], best=f"{row['best']:.3f}")

    kw = {
        "workers": ctx.workers,
        "ray_address": ctx.ray_address,
        "resume": resume,
        "progress": progress,
    }
    if method in ("ant", "ant-nocc"):
        run_evolution(config, d, **kw)
    elif method == "fixed":
        run_fixed(config, d, **kw)
    elif method == "neat":
        run_neat(config, d, **kw)
    else:
        raise ValueError(f"unknown method {method!r} (known: {', '.join(METHODS)})")
    return read_history(hist)


class PartialTraining(Exception):
    """Raised after a ``--method``/``--run``/``--setting`` subset of the runs was trained.

    Not an error: the experiment's summary needs every run, so it stops there.
    """

    def __init__(self, trained: list[str]) -> None:
        self.trained = trained
        super().__init__(
            f"trained {len(trained)} run(s) ({', '.join(trained) or 'none selected'}); "
            "run the command without --method/--run/--setting to write the summary"
        )


def train_all(ctx: Context, jobs: Sequence[tuple[str, object]], desc: str) -> dict:
    """Every run of every ``(method, robots)`` job: ``{(method, robots): [history, ...]}``.

    With ``ctx.finished_only`` nothing is trained: each job's list holds the histories of
    its finished runs only (possibly none).

    Raises:
        PartialTraining: After training the subset that ``ctx.partial`` selects.
    """
    if ctx.finished_only:
        return {
            (m, r): [read_history(p.parent / "history.csv") for _, p in finished_runs(ctx, m, r)]
            for m, r in jobs
        }
    todo = [(m, r, k) for m, r in jobs for k in range(ctx.runs)]
    if ctx.partial:
        todo = [
            (m, r, k)
            for m, r, k in todo
            if (ctx.only_methods is None or m in ctx.only_methods)
            and (ctx.only_runs is None or k in ctx.only_runs)
            and (ctx.only_settings is None or setting_label(r) in ctx.only_settings)
        ]
    out: dict = {}
    # Runs finished before count from the start (tqdm's rate and ETA leave them out); the
    # count is kept by hand: tqdm's iterator writes it back only when it redraws.
    done = {job for job in todo if _trained(ctx, *job)}
    if ctx.cluster is not None and len(done) < len(todo):
        from ant_evolution.experiments.cluster import train_on_cluster

        runs = [
            (run_dir(ctx, *job), job[0], train_config(ctx, *job)) for job in todo if job not in done
        ]
        nodes = train_on_cluster(runs, ctx.cluster, progress=tqdm.write)
        tqdm.write(f"{desc}: chunks per node: {nodes}")
    with tqdm(total=len(todo), initial=len(done), desc=desc, unit="run") as bar:
        for job in todo:
            out.setdefault(job[:2], []).append(train(ctx, *job, bar))
            if job not in done:
                bar.update(1)
    if ctx.partial:
        raise PartialTraining([run_dir(ctx, *job).name for job in todo])
    return out


def _trained(ctx: Context, method: str, robots, run: int) -> bool:
    """Whether that run's history already holds all its generations (read back, not run)."""
    hist = run_dir(ctx, method, robots, run) / "history.csv"
    generations = train_config(ctx, method, robots, run).generations
    return hist.exists() and _history_length(hist) >= generations


def read_history(path: Path) -> list[dict]:
    """Rows of a ``history.csv`` with numbers parsed."""
    rows = []
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            row = dict(r)
            for k in ("generation", "evaluations", "neurons_best"):
                row[k] = int(float(row[k]))
            for k in ("best", "mean", "std", "best_ever", "neurons_mean", "seconds"):
                row[k] = float(row[k])
            rows.append(row)
    return rows


def history_columns(histories: list[list[dict]], key: str) -> np.ndarray:
    """``[runs, generations]`` of one history column (runs cut to the shortest)."""
    g = min(len(h) for h in histories)
    return np.array([[r[key] for r in h[:g]] for h in histories])


# --- evolved controllers -------------------------------------------------------------------


def training_fitness(path: Path) -> float:
    """The training fitness a run recorded in its ``best.json`` (ANT genome or program)."""
    return float(json.loads(Path(path).read_text())["metadata"]["fitness"])


def best_of_runs(ctx: Context, method: str, robots) -> tuple[Path, float]:
    """The fittest finished run's ``best.json`` of a setting (by its training fitness)."""
    best: tuple[Path, float] | None = None
    for _, path in finished_runs(ctx, method, robots):
        fit = training_fitness(path)
        if best is None or fit > best[1]:
            best = (path, fit)
    if best is None:
        raise FileNotFoundError(
            f"no finished {method} run for {setting_label(robots)} in {ctx.out}"
        )
    return best


def finished_runs(ctx: Context, method: str, robots) -> list[tuple[int, Path]]:
    """``(k, best.json)`` of every finished run of a setting (all its generations trained)."""
    return [
        (k, run_dir(ctx, method, robots, k) / "best.json")
        for k in range(ctx.runs)
        if _trained(ctx, method, robots, k)
        and (run_dir(ctx, method, robots, k) / "best.json").is_file()
    ]


def load_controller(path: Path) -> Controller | NetworkProgram:
    """An ANT genome file as a :class:`Controller`, a network-program file as a program."""
    data = json.loads(Path(path).read_text())
    if data.get("format") == "network-program/1":
        return load_program(path)
    return Controller.from_genome(load_genome(path), name=str(path))


def four_robot_genome(ctx: Context) -> Path:
    """The 4-robot ANT controller: ``--genome``, else this scale's best 4-robot training run.

    (At the quick scale, which trains 1 and 2 robots, the 2-robot run stands in.)
    """
    if ctx.genome is not None:
        return ctx.genome
    n = compare_robots(ctx.scale)
    return best_of_runs(ctx, "ant", n)[0]


def score(
    controller,
    blueprint: Blueprint,
    robots: int,
    scenarios: int,
    steps: int,
    seed: int,
    rules: WorldRules = DEFAULT_RULES,
    soil: str = "grid",
    randomise: bool = False,
):
    """Final fitness of a controller (ANT, hand-coded or network program) per scenario."""
    batch = ScenarioSet.create(blueprint, robots, scenarios, steps, seed, rules, soil, randomise)
    return batch.score(controller)


def depth_split(scale: Scale, robots: int) -> list[tuple[int, int, int]]:
    """``(depth, scenarios, seed)`` of each goal depth: ``eval_scenarios`` split as in training.

    The seeds (from :data:`EVAL_SEED` on, never used in training) depend on the robot count,
    so every cell of a robot-count grid has its own scenarios.
    """
    n = len(scale.depths)
    return [
        (d, scale.eval_scenarios // n + (i < scale.eval_scenarios % n), EVAL_SEED + 97 * i + robots)
        for i, d in enumerate(scale.depths)
    ]


def score_parts(
    controller,
    pit: int,
    parts: Sequence[tuple[int, int, int]],
    robots: int,
    steps: int,
    rules: WorldRules = DEFAULT_RULES,
    soil: str = "grid",
    randomise: bool = False,
) -> np.ndarray:
    """Final fitness per scenario over ``parts`` (``(depth, scenarios, seed)``) of one pit."""
    return np.concatenate([
        score(
            controller, site(pit, d, rules.fitted_site), robots, k, steps, seed, rules, soil,
            randomise,
        )
        for d, k, seed in parts
        if k
    ])  # fmt: skip


def score_depths(controller, ctx: Context, robots: int, steps: int | None = None, size: int = 8):
    """Fitness over ``eval_scenarios`` scenarios split over the goal depths, as in training."""
    parts = depth_split(ctx.scale, robots)
    return score_parts(
        controller, size, parts, robots, steps or ctx.scale.steps, ctx.rules, ctx.soil,
        ctx.randomise,
    )  # fmt: skip


def site(pit: int, depth: int, fitted: bool = False) -> Blueprint:
    """A square pit of ``pit`` cells (dump band 2) centred on a grid of at least 16 x 16.

    ``fitted`` (switch ``site = "fitted"``): the grid is the pit plus its dump band.
    """
    grid = pit + 4 if fitted else max(16, pit + 8)
    return pit_blueprint((grid, grid), (pit, pit), depth, 2, name=f"{pit}x{pit} depth {depth}")


def site_text(fitted: bool) -> str:
    """How :func:`site` sizes the grid around a pit, for the sections' text."""
    if fitted:
        return "dump band 2, the grid the pit and its band: `site = fitted`"
    return "dump band 2, grid at least 16 x 16, pit + 8 cells when larger"


# --- outputs ------------------------------------------------------------------------------


def write_csv(path: Path, rows: list[dict]) -> None:
    """Rows to CSV (columns from the first row)."""
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]), lineterminator="\n")
        w.writeheader()
        w.writerows(rows)


def pyplot():
    """Matplotlib's pyplot on the Agg backend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def scale_dict(scale: Scale) -> dict:
    """The scale as a mapping (for ``scale.json`` beside the results)."""
    return {k: list(v) if isinstance(v, tuple) else v for k, v in dataclasses.asdict(scale).items()}


@dataclass(frozen=True)
class GridRow:
    """One cell of a robot grid: a key (a pit, a depth, a setting, a controller) and a team.

    Attributes:
        key: The cell's key; the grid's ``key_label`` names its column.
        robots: The team size.
        mean: Mean fitness over the cell's scenarios.
        std: Its standard deviation.
        run: In the grid of every run's controller: the run's index (else ``None``).
        training_fitness: There: the run's best training fitness.
    """

    key: object
    robots: int
    mean: float
    std: float
    run: int | None = None
    training_fitness: float | None = None

    def csv(self, key_label: str) -> dict:
        """The row as ``NAME.csv`` holds it.

        ``run`` and ``training_fitness`` (in the grid of every run's controller only), the
        key under ``key_label``, ``robots``, ``mean``, ``std``.
        """
        head = {}
        if self.run is not None:
            head = {"run": self.run, "training_fitness": self.training_fitness}
        cell = {"robots": self.robots, "mean": self.mean, "std": self.std}
        return head | {key_label: self.key} | cell


def write_grid_csv(path: Path, rows: Sequence[GridRow], key_label: str) -> None:
    """A grid's rows as a CSV file, the key's column named ``key_label``."""
    write_csv(path, [r.csv(key_label) for r in rows])


@dataclass(frozen=True)
class EveryRunGroup:
    """One key's runs in the grid of every run's controller.

    Attributes:
        key: The key.
        runs: How many runs' controllers.
        mean: Mean over the runs' controllers, per robot count.
        std: Their standard deviation, per robot count.
        peaks: The robot count at which each run's controller peaks.
        median_peak: The median of ``peaks``.
    """

    key: object
    runs: int
    mean: np.ndarray
    std: np.ndarray
    peaks: list[int]
    median_peak: float
