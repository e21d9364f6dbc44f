"""The ``behaviours`` experiment: Table 3 detectors over a training run, and neuronal activity.

Two parts (paper, section 5.1 "Evolution of Behaviors through Task Decomposition" and 5.2
"Neuronal Analysis"):

1. **Detectors over training.** The 4-robot ANT training run ``ant-n4-r0`` of the scale is
   replayed generation by generation (the run is deterministic, so the replay *is* that
   run: every generation's best fitness is checked against its ``history.csv`` when it
   exists). Every ``trace_every`` generations the generation's best genome runs on
   ``trace_scenarios`` scenarios, step by step, and each robot-step is classified by the
   Table 3 detectors of :mod:`excavation_sim.detectors`. The replay is the one generation
   loop (:func:`ant_evolution.loop.run_generations`) with ANT's strategy and a hook that
   checks and traces; it checkpoints at every traced generation, so it resumes.
2. **Neuronal activity.** The 4-robot controller (``--genome`` or the best of the run) runs
   one 4-robot scenario; for robot 0 we record, per timestep, every living decision
   neuron's state, how many motor neurons coarse coding selects, and the detectors. The
   table gives, for each decision neuron and detector, the firing rate of the neuron at
   timesteps where the detector holds against where it does not.

:func:`run` replays the run (the rows of ``behaviours.csv``; the replay checkpoints, so it
resumes) and writes both parts; the neuronal part is :func:`activity` (the trace of one
scenario) and :func:`compute` (the rows of ``neurons.csv``), both pure.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np

from ant_controller.controller import Controller
from ant_controller.genome import Genome
from ant_controller.genome_io import load_genome
from ant_controller.layout import N_SENSORS, SENSOR_SCALE
from ant_controller.tissue import CompiledTissue, activation
from ant_evolution.backends import Evaluator
from ant_evolution.evaluate import ScenarioSet
from ant_evolution.evolve import AntStrategy, blueprints_of, load_config, scenario_sets
from ant_evolution.experiments.core import (
    EVAL_SEED,
    Context,
    compare_robots,
    read_history,
    run_dir,
    site,
    train_config,
    write_csv,
)
from ant_evolution.experiments.figures import figure
from ant_evolution.experiments.sections import figure_link, section, table, write_section
from ant_evolution.loop import (
    Generation,
    RunState,
    load_checkpoint,
    run_generations,
    save_checkpoint,
)
from excavation_common.progress import tqdm
from excavation_sim.detectors import DETECTOR_TITLES, DETECTORS, detect, random_turn_direction
from excavation_sim.world import HEADING

NAME = "behaviours"
TRACE_POINTS = 20
"""Generations traced per run (evenly spaced, first and last included)."""


def trace(controller: Controller, batch: ScenarioSet, neurons: bool = False) -> dict:
    """Run every scenario of ``batch`` step by step; detector hits and (optionally) neurons.

    Returns:
        ``{"hits": {name: int}, "robot_steps": int}``, plus for ``neurons=True`` the
        per-step arrays of robot 0 of scenario 0: ``decision`` ``[T, D]`` states,
        ``selected`` ``[T]`` motor neurons selected, ``detected`` ``{name: bool [T]}``.
    """
    hits = dict.fromkeys(DETECTORS, 0)
    steps = 0
    record: dict = {"decision": [], "selected": [], "sensors": [], "masks": [], "turns": []}
    for i in range(batch.size):
        w = batch.world(i)
        for _ in range(batch.steps):
            codes = w.sense()
            masks = np.array(
                [controller.decide(codes[k]) if w.active[k] else 0 for k in range(w.n_robots)],
                dtype=np.int64,
            )
            before = w.robots[:, HEADING].copy()
            w.step(masks)
            turns = random_turn_direction(before, w.robots[:, HEADING], masks)
            act = w.active
            found = detect(codes[act], masks[act], turns[act])
            for name in DETECTORS:
                hits[name] += int(found[name].sum())
            steps += int(act.sum())
            if neurons and i == 0:
                dec, sel = neuron_states(controller.tissue, codes[0])
                record["decision"].append(dec)
                record["selected"].append(sel)
                record["sensors"].append(codes[0])
                record["masks"].append(masks[0])
                record["turns"].append(turns[0])
    out: dict = {"hits": hits, "robot_steps": steps}
    if neurons:
        det = detect(
            np.array(record["sensors"]), np.array(record["masks"]), np.array(record["turns"])
        )
        out.update(
            decision=np.array(record["decision"]).reshape(len(record["selected"]), -1),
            selected=np.array(record["selected"]),
            detected=det,
        )
    return out


def neuron_states(tissue: CompiledTissue, codes: np.ndarray) -> tuple[np.ndarray, int]:
    """Decision neuron states and the number of motor neurons coarse coding selects.

    The same rules as :func:`ant_controller.tissue.decide` (steps 1-3 of its docstring).
    """
    x = codes * SENSOR_SCALE[:N_SENSORS]
    sx = float(x.sum())
    d = tissue.n_decision
    states = np.zeros(d, dtype=np.int64)
    conc = np.zeros(tissue.n_motor)
    for i in range(d):
        sigma = float(tissue.dn_sensor_w[i] @ x) / sx if sx != 0.0 else 0.0
        states[i] = activation(tissue.dn_func[i], *tissue.dn_theta[i], sigma)
        if states[i]:
            conc[tissue.dn_member[i]] += tissue.dn_conc[i]
    if not tissue.coarse_coding:
        return states, tissue.n_motor
    peak = conc.max(initial=0.0)
    return states, int(np.count_nonzero(conc == peak)) if peak > 0 else 0


def _replay(ctx: Context, out) -> tuple[list[dict], object]:
    """Replay the 4-robot training run, tracing detectors; resumable."""
    robots = compare_robots(ctx.scale)
    if ctx.replay is not None:
        config = load_config(ctx.replay / "config.yaml")
        robots = config.robots
        hist_path = ctx.replay / "history.csv"
    else:
        config = train_config(ctx, "ant", robots, 0)
        hist_path = run_dir(ctx, "ant", robots, 0) / "history.csv"
    if ctx.generations is not None:
        config = dataclasses.replace(config, generations=min(config.generations, ctx.generations))
    history = read_history(hist_path) if hist_path.exists() else []
    every = max(1, config.generations // (TRACE_POINTS - 1))
    traced = {g for g in range(0, config.generations, every)} | {config.generations - 1}
    n_trace = max(1, min(ctx.scale.eval_scenarios, 10))
    rows_path = out / "rows.json"
    ckpt_dir = out / "replay"
    ckpt_dir.mkdir(exist_ok=True)
    strategy = AntStrategy(config)
    if (ckpt_dir / strategy.checkpoint_name).exists() and rows_path.exists():
        run = load_checkpoint(ckpt_dir, strategy)
        rows = json.loads(rows_path.read_text())
    else:
        run = RunState.start(strategy)
        rows = []
    blueprints = blueprints_of(config)
    bp = site(8, 1)

    def check_and_trace(event: Generation) -> None:
        g = event.index
        i = int(np.argmax(event.fitness))
        best = float(event.fitness[i])
        if g < len(history) and history[g]["best"] != best:
            raise RuntimeError(f"replay of {hist_path} differs at generation {g}")
        if g in traced:
            batch = ScenarioSet.create(bp, robots, n_trace, config.steps, EVAL_SEED + 7)
            res = trace(Controller.from_genome(event.population[i]), batch)
            rows.append({"generation": g, "best": best, "robot_steps": res["robot_steps"],
                         **res["hits"]})  # fmt: skip
        bar.update()
        if g in traced or event.run.generation == config.generations:
            save_checkpoint(ckpt_dir, strategy, event.run)
            rows_path.write_text(json.dumps(rows))

    with (
        Evaluator(ctx.workers, ctx.ray_address) as ev,
        tqdm(
            total=config.generations, initial=run.generation, desc="behaviours", unit="gen"
        ) as bar,
    ):
        run_generations(
            strategy, run, ev, lambda g: scenario_sets(config, g, blueprints), [check_and_trace]
        )
    return rows, hist_path.parent


def activity(controller: Controller) -> dict:
    """Robot 0's neurons and detectors in one 4-robot scenario (8 x 8, depth 1, 250 steps).

    Returns:
        :func:`trace`'s answer with ``neurons=True``.
    """
    batch = ScenarioSet.create(site(8, 1), 4, 1, 250, EVAL_SEED + 11)
    return trace(controller, batch, neurons=True)


def compute(found: dict, decision_genes) -> list[dict]:
    """Each decision neuron's firing rate when each detector holds and when it does not.

    Args:
        found: :func:`activity`'s answer.
        decision_genes: The gene of each decision neuron.

    Returns:
        The rows of ``neurons.csv``: one per decision neuron and detector (rates are NaN
        where the detector never or always holds).
    """
    dec, det = found["decision"], found["detected"]
    rows = []
    for d in range(dec.shape[1]):
        for name in DETECTORS:
            on = det[name]
            rows.append(
                {
                    "decision_neuron": d,
                    "gene": decision_genes[d],
                    "detector": name,
                    "events": int(on.sum()),
                    "rate_when_detected": float(dec[on, d].mean()) if on.any() else float("nan"),
                    "rate_otherwise": float(dec[~on, d].mean()) if (~on).any() else float("nan"),
                }
            )
    return rows


def run(ctx: Context) -> None:
    """Detector counts over a training run, and the neuronal activity of a 4-robot tissue."""
    out = ctx.dir(NAME)
    rows, replayed = _replay(ctx, out)
    write_csv(out / "behaviours.csv", rows)
    with figure(out / "behaviours.png", 2, 3, figsize=(11, 6), dpi=100, sharex=True) as (
        fig,
        axes,
    ):
        gens = [r["generation"] for r in rows]
        axes[0, 0].plot(gens, [r["best"] for r in rows], marker="o", ms=3)
        axes[0, 0].set(title="best fitness", ylim=(0, 1))
        for ax, name in zip(axes.flat[1:], DETECTORS, strict=True):
            ax.plot(gens, [r[name] / max(1, r["robot_steps"]) for r in rows], marker="o", ms=3)
            ax.set(title=DETECTOR_TITLES[name] + " (per robot-step)")
        for ax in axes.flat:
            ax.grid(alpha=0.3)
        for ax in axes[1]:
            ax.set_xlabel("generation")
        fig.suptitle("Table 3 detectors for the best genome of each generation", fontsize=9)

    robots = compare_robots(ctx.scale)
    # the tissue of the replayed run (its best genome), unless --genome names another
    replayed_best = None if ctx.replay is None else ctx.replay / "best.json"
    if ctx.genome is not None:
        genome_path = ctx.genome
    elif replayed_best is not None and replayed_best.is_file():
        genome_path = replayed_best
    else:
        genome_path = run_dir(ctx, "ant", robots, 0) / "best.json"
    genome: Genome = load_genome(genome_path)
    ctl = Controller.from_genome(genome)
    found = activity(ctl)
    corr_rows = compute(found, ctl.tissue.decision_genes)
    if corr_rows:
        write_csv(out / "neurons.csv", corr_rows)
    dec, det = found["decision"], found["detected"]
    t = np.arange(dec.shape[0])
    with figure(
        out / "neurons.png", 3, 1, figsize=(10, 2 + 0.3 * (dec.shape[1] + len(DETECTORS))),
        dpi=100, sharex=True,
        gridspec_kw={"height_ratios": [max(1, dec.shape[1]), 1, len(DETECTORS)]},
    ) as (_, (a1, a2, a3)):  # fmt: skip
        if dec.shape[1]:
            a1.imshow(dec.T, aspect="auto", interpolation="nearest", cmap="Greys")
        a1.set(ylabel="decision\nneuron", title=f"robot 0, one 4-robot scenario: {genome_path}")
        a2.plot(t, found["selected"], drawstyle="steps-mid")
        a2.set(ylabel="motor\nselected")
        a3.imshow(
            np.array([det[n] for n in DETECTORS], dtype=float), aspect="auto",
            interpolation="nearest", cmap="Blues",
        )  # fmt: skip
        a3.set_yticks(range(len(DETECTORS)), [DETECTOR_TITLES[n] for n in DETECTORS], fontsize=7)
        a3.set_xlabel("timestep")
    counts = ", ".join(f"{DETECTOR_TITLES[n]} {int(det[n].sum())}" for n in DETECTORS)
    first, last = rows[0], rows[-1]
    hits = [
        [DETECTOR_TITLES[n], f"{first[n] / max(1, first['robot_steps']):.3f}",
         f"{last[n] / max(1, last['robot_steps']):.3f}"]
        for n in DETECTORS
    ]  # fmt: skip
    cell = {(r["decision_neuron"], r["detector"]): r for r in corr_rows}
    rates = [
        [f"{d} (gene {ctl.tissue.decision_genes[d]})"]
        + [
            f"{c['rate_when_detected']:.2f} / {c['rate_otherwise']:.2f}" if c["events"] else "-"
            for c in (cell[(d, n)] for n in DETECTORS)
        ]
        for d in range(dec.shape[1])
    ]
    titles = [DETECTOR_TITLES[n] for n in DETECTORS]
    write_section(
        ctx,
        NAME,
        section(
            "Behaviours during training and in the tissue",
            f"""Detectors of Table 3 for the best genome of {len(rows)} generations of the run
`{replayed}` (replayed exactly), each on 8 x 8, depth 1 scenarios;
hits per robot-step at the first and the last traced generation
({first["generation"]}: fitness {first["best"]:.3f}; {last["generation"]}: {last["best"]:.3f}):""",
            table(["detector", "first", "last"], "lrr", hits),
            figure_link(NAME, "behaviours.png", "behaviours"),
            f"Neuronal activity of `{genome_path}` ({ctl.tissue.n_decision} living decision "
            f"""neurons,
{ctl.tissue.n_motor} living motor neurons), robot 0 of one 4-robot scenario, 250 steps.
Detector events of that robot: {counts}. Firing rate of each decision neuron when a
detector holds / when it does not:""",
            table(["decision neuron", *titles], "l" + "r" * len(titles), rates),
            figure_link(NAME, "neurons.png", "neurons"),
        ),
    )
