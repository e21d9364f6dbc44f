"""The one generation loop and its ask / tell strategy seam (paper, section 4.3).

Every method the project evolves (ANT, the fixed-topology network, NEAT) is a
:class:`Strategy` in the style of evosax: an explicit strategy state, ``ask(state) ->
(population, state)`` and ``tell(state, fitness) -> state``. The loop owns everything the
methods share, once:

1. the scenarios of generation g (``SeedSequence([seed, g])``, the same for every
   individual of the generation and for every method: common random numbers);
2. ``ask``, then the one evaluator (:class:`ant_evolution.backends.Evaluator`) compiles
   each individual with the strategy's ``compiler`` in the workers and scores it;
3. bookkeeping: evaluations, the best individual so far (the strategy turns it into the
   document ``best.json`` holds), one history row;
4. ``tell``, then every hook with the :class:`Generation` that just ended.

Outputs are hooks (:class:`BestFile`, :class:`HistoryFiles`, :class:`Checkpoint`,
:func:`progress_hook`); so is the behaviours experiment's replay of a training run. A
checkpoint holds the loop's :class:`RunState` and the strategy's state (its own
``state_to_dict``), so a resumed run ends bit-identical to an uninterrupted one whatever
the worker count or backend.
"""

from __future__ import annotations

import contextlib
import csv
import gc
import io
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import yaml

from ant_evolution.errors import CheckpointError
from ant_evolution.profiles import PROFILES
from excavation_common.files import write_text_atomic

HISTORY_FIELDS = (
    "generation",
    "evaluations",
    "best",
    "mean",
    "std",
    "best_ever",
    "neurons_best",
    "neurons_mean",
    "robots_hist",
    "seconds",
)


@contextlib.contextmanager
def cyclic_gc_paused():
    """Python's cyclic garbage collector off for the block, then back as it was.

    ``tell`` allocates many small objects: neat-python's reproduction makes one per gene
    (about 130,000 per generation at P = 100), and every 700 allocations start a collection
    of the young objects, with full collections over everything alive from time to time;
    that was about a fifth of a NEAT generation (docs/benchmarks.md). No strategy depends on
    when reference cycles are collected, so children and random draws are the same; the
    cycles ``tell`` leaves are collected after the block.
    """
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()


class Strategy(Protocol):
    """One evolutionary method behind the ask / tell seam.

    Attributes:
        config: The run's :class:`~ant_evolution.evolve.EvolveConfig`.
        checkpoint_name: File name of the checkpoint in the run directory.
        checkpoint_formats: ``format`` values its checkpoints may carry (the first is
            written; ``None`` accepts a file without one).
        run_key: Hash of everything that changes results (a checkpoint of another run
            key is refused).
    """

    config: Any
    checkpoint_name: str
    checkpoint_formats: tuple[str | None, ...]
    run_key: str

    def init(self) -> Any:
        """The strategy state of generation 0 (drawn from ``config.seed``)."""

    def ask(self, state: Any) -> tuple[list, Any]:
        """The population to evaluate, and the state to tell."""

    def tell(self, state: Any, fitness: np.ndarray) -> Any:
        """The state of the next generation, from this generation's fitness."""

    def compiler(self, state: Any) -> Callable | None:
        """Picklable function from an individual to its decision program (the workers')."""

    def title(self, state: Any) -> str:
        """Title of the fitness plot."""

    def neurons(self, state: Any, individual: Any) -> int:
        """Neurons of one individual (history columns)."""

    def robots(self, individual: Any) -> int | None:
        """The individual's N gene, or None."""

    def best_document(self, state: Any, individual: Any, info: dict) -> dict:
        """The JSON document of a new best individual (``info``: fitness, generation, ...)."""

    def dump_best(self, document: dict) -> str:
        """The text of ``best.json``."""

    def check_best(self, document: dict, label: str) -> None:
        """Validate a checkpointed best document (raises ``ValueError`` when bad)."""

    def state_to_dict(self, state: Any, out: Path) -> dict:
        """The strategy state for a checkpoint (it may write side files into ``out``)."""

    def state_from_dict(self, data: dict, out: Path, label: str) -> Any:
        """Inverse of :meth:`state_to_dict`."""


@dataclass
class RunState:
    """Where a run stands between generations (what a checkpoint holds).

    Attributes:
        generation: Generations done.
        strategy: The strategy's state.
        history: One row per generation done (``HISTORY_FIELDS``).
        best: JSON document of the best individual so far (``best.json``), or None.
        best_fitness: Its fitness (-1 before the first generation).
        evaluations: Scenario evaluations so far.
    """

    generation: int
    strategy: Any
    history: list[dict]
    best: dict | None
    best_fitness: float
    evaluations: int

    @classmethod
    def start(cls, strategy: Strategy) -> RunState:
        """Generation 0 of a fresh run."""
        return cls(0, strategy.init(), [], None, -1.0, 0)


@dataclass(frozen=True)
class Generation:
    """What hooks see after a generation: the run after ``tell``, and that generation.

    Attributes:
        index: The generation that ended (the run is now at ``index + 1``).
        run: The run state after ``tell``.
        population: The individuals evaluated.
        fitness: Their fitness.
        row: Its history row.
        improved: The best individual so far is new.
        final: The last generation of this call (the run's last, or ``stop_after``).
        checkpoint_due: Outputs and checkpoint are due (every ``checkpoint_every``
            generations and at ``final``).
    """

    index: int
    run: RunState
    population: list
    fitness: np.ndarray
    row: dict
    improved: bool
    final: bool
    checkpoint_due: bool


Hook = Callable[[Generation], None]


def run_generations(
    strategy: Strategy,
    run: RunState,
    evaluator,
    scenario_sets: Callable[[int], Sequence],
    hooks: Sequence[Hook] = (),
    stop_after: int | None = None,
) -> RunState:
    """Run generations until ``config.generations`` (or ``stop_after`` in this call).

    Args:
        strategy: The method.
        run: Where the run stands (:meth:`RunState.start` or :func:`load_checkpoint`);
            updated in place and returned.
        evaluator: ``evaluate(population, sets, compile_fn) -> fitness``.
        scenario_sets: The scenario sets of generation g.
        hooks: Called in order after every generation.
        stop_after: Stop after this many generations (tests use it to interrupt a run).
    """
    config = strategy.config
    done = 0
    while run.generation < config.generations:
        t0 = time.perf_counter()
        g = run.generation
        population, state = strategy.ask(run.strategy)
        sets = scenario_sets(g)
        fit = evaluator.evaluate(population, sets, strategy.compiler(state))
        run.evaluations += len(population) * sum(s.size for s in sets)
        i = int(np.argmax(fit))
        improved = bool(fit[i] > run.best_fitness)
        if improved:
            run.best_fitness = float(fit[i])
            info = {"fitness": run.best_fitness, "generation": g, "evaluations": run.evaluations}
            run.best = strategy.best_document(state, population[i], info)
        neurons = [strategy.neurons(state, p) for p in population]
        genes = [strategy.robots(p) for p in population]
        hist = ""
        if config.evolve_robots and None not in genes:
            counts = np.bincount(genes)
            hist = ";".join(f"{n}:{c}" for n, c in enumerate(counts) if c)
        row = {
            "generation": g,
            "evaluations": run.evaluations,
            "best": float(fit[i]),
            "mean": float(fit.mean()),
            "std": float(fit.std()),
            "best_ever": run.best_fitness,
            "neurons_best": int(neurons[i]),
            "neurons_mean": float(np.mean(neurons)),
            "robots_hist": hist,
            "seconds": round(time.perf_counter() - t0, 3),
        }
        run.history.append(row)
        with cyclic_gc_paused():
            run.strategy = strategy.tell(state, fit)
        run.generation = g + 1
        done += 1
        stopping = stop_after is not None and done >= stop_after
        final = stopping or run.generation == config.generations
        due = final or run.generation % config.checkpoint_every == 0
        event = Generation(g, run, population, fit, row, improved, final, due)
        for hook in hooks:
            hook(event)
        if stopping:
            break
    return run


# --- checkpoints -----------------------------------------------------------------------------


def save_checkpoint(out: Path, strategy: Strategy, run: RunState) -> None:
    """Write the strategy's checkpoint file in ``out`` atomically."""
    data = {
        "format": strategy.checkpoint_formats[0],
        "run_key": strategy.run_key,
        **_profile_record(strategy.config),
        "generation": run.generation,
        "evaluations": run.evaluations,
        "best_fitness": run.best_fitness,
        "best": run.best,
        "history": run.history,
        **strategy.state_to_dict(run.strategy, out),
    }
    write_text_atomic(out / strategy.checkpoint_name, json.dumps(data, allow_nan=False))


def load_checkpoint(out: Path, strategy: Strategy) -> RunState:
    """Read and check the strategy's checkpoint in ``out``.

    Raises:
        CheckpointError: Missing, corrupt, or written by a different configuration.
    """
    path = out / strategy.checkpoint_name
    label = str(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise CheckpointError(label, "does not exist; nothing to resume") from None
    except (OSError, UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise CheckpointError(
            label, f"is corrupt ({exc}); it was not written by a finished checkpoint"
        ) from None
    fmt = strategy.checkpoint_formats[0]
    if not isinstance(data, dict) or data.get("format") not in strategy.checkpoint_formats:
        raise CheckpointError(label, f"is not an {fmt} file")
    _check_profile(label, data, strategy.config)
    if data.get("run_key") != strategy.run_key:
        raise CheckpointError(
            label,
            "was written by a run with a different configuration (compare "
            f"{out / 'config.yaml'}); start a new run directory or restore that config",
        )
    try:
        best = data.get("best")
        if best is not None:
            strategy.check_best(best, f"{label}:best")
        return RunState(
            int(data["generation"]),
            strategy.state_from_dict(data, out, label),
            list(data["history"]),
            best,
            float(data["best_fitness"]),
            int(data["evaluations"]),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise CheckpointError(label, f"is corrupt: {exc!r}") from None


def _profile_record(config) -> dict:
    """The profile and switches a checkpoint records (configs without them: none)."""
    if not hasattr(config, "switches"):
        return {}
    return {"profile": config.profile, "switches": config.switches()}


def _check_profile(label: str, data: dict, config) -> None:
    """Refuse a checkpoint written under another profile or other switches, naming them.

    A checkpoint from before profiles existed was written under ``v1``.
    """
    if not hasattr(config, "switches"):
        return
    profile = data.get("profile", "v1")
    switches = data.get("switches", PROFILES["v1"])
    if profile != config.profile:
        raise CheckpointError(
            label,
            f"was written under profile {profile!r}, not {config.profile!r}; resume with "
            f"--profile {profile}, or start a new run directory",
        )
    if not isinstance(switches, dict):
        raise CheckpointError(label, "is corrupt: its switches are not a mapping")
    ours = config.switches()
    differ = [k for k in ours if k in switches and switches[k] != ours[k]]
    if differ:
        shown = ", ".join(f"{k}: {switches[k]!r} there, {ours[k]!r} here" for k in differ)
        raise CheckpointError(
            label,
            f"was written with other switches of profile {profile!r} ({shown}); restore "
            "them (its config.yaml) or start a new run directory",
        )


# --- hooks -----------------------------------------------------------------------------------


def history_csv(rows: list[dict]) -> str:
    """``history.csv`` text of the rows."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=HISTORY_FIELDS, lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    return buf.getvalue()


def plot_history(rows: list[dict], path: Path, title: str) -> None:
    """Best and mean fitness against generations, with the 0.9 solution line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    gens = [r["generation"] for r in rows]
    fig, ax = plt.subplots(figsize=(6, 4), dpi=100)
    ax.plot(gens, [r["best"] for r in rows], label="best")
    ax.plot(gens, [r["mean"] for r in rows], label="mean")
    ax.plot(gens, [r["best_ever"] for r in rows], "--", label="best so far", alpha=0.7)
    ax.axhline(0.9, color="gray", lw=0.8, ls=":")
    ax.set_xlabel("generation")
    ax.set_ylabel("fitness")
    ax.set_ylim(0, 1)
    ax.set_title(title, fontsize=9)
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


@dataclass(frozen=True)
class BestFile:
    """Hook: write ``best.json`` whenever the best individual so far changes."""

    out: Path
    strategy: Strategy

    def __call__(self, event: Generation) -> None:
        """Write the file when ``event.improved``."""
        if event.improved and event.run.best is not None:
            write_text_atomic(self.out / "best.json", self.strategy.dump_best(event.run.best))


@dataclass(frozen=True)
class HistoryFiles:
    """Hook: ``history.csv`` and ``fitness.png`` whenever a checkpoint is due."""

    out: Path
    strategy: Strategy

    def __call__(self, event: Generation) -> None:
        """Rewrite both files when ``event.checkpoint_due``."""
        if event.checkpoint_due:
            write_text_atomic(self.out / "history.csv", history_csv(event.run.history))
            title = self.strategy.title(event.run.strategy)
            plot_history(event.run.history, self.out / "fitness.png", title)


@dataclass(frozen=True)
class Checkpoint:
    """Hook: the checkpoint, every ``checkpoint_every`` generations and at the end."""

    out: Path
    strategy: Strategy

    def __call__(self, event: Generation) -> None:
        """Save when ``event.checkpoint_due``."""
        if event.checkpoint_due:
            save_checkpoint(self.out, self.strategy, event.run)


def progress_hook(progress: Callable[[dict], None]) -> Hook:
    """Hook: ``progress(row)`` after every generation."""

    def hook(event: Generation) -> None:
        progress(event.row)

    return hook


def run_strategy(
    strategy: Strategy,
    out: str | Path,
    evaluator,
    scenario_sets: Callable[[int], Sequence],
    *,
    resume: bool = False,
    progress: Callable[[dict], None] | None = None,
    stop_after: int | None = None,
) -> RunState:
    """A run with the standard outputs in ``out``: config, best, history, plot, checkpoint.

    Raises:
        CheckpointError: ``resume`` without a usable checkpoint, or a fresh run into a
            directory that already holds one.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    ckpt = out / strategy.checkpoint_name
    if resume:
        run = load_checkpoint(out, strategy)
    elif ckpt.exists():
        raise CheckpointError(
            str(ckpt),
            "exists: pass --resume to continue that run, or choose a new output directory",
        )
    else:
        run = RunState.start(strategy)
    config = strategy.config.to_dict()
    write_text_atomic(out / "config.yaml", yaml.safe_dump(config, sort_keys=False))
    hooks: list[Hook] = [BestFile(out, strategy)]
    if progress is not None:
        hooks.append(progress_hook(progress))
    hooks += [HistoryFiles(out, strategy), Checkpoint(out, strategy)]
    return run_generations(strategy, run, evaluator, scenario_sets, hooks, stop_after)
