"""The experiments of the paper's section 5, one function each.

Every function takes a :class:`~.core.Context`, trains what it needs (resuming shared
runs), evaluates, and writes into ``OUT/<name>/``: a CSV of the numbers, PNG figures and
``section.md`` (a markdown section: what ran, a table, the figure). ``docs/experiments.md``
describes each one against the paper.
"""

from __future__ import annotations

import json

import numpy as np
from tqdm import tqdm

from ant_controller.controller import Controller
from ant_controller.genome_io import load_genome
from ant_evolution.experiments.core import (
    METHOD_LABELS,
    SOLVED,
    Context,
    best_of_runs,
    compare_robots,
    finished_runs,
    four_robot_genome,
    load_controller,
    pyplot,
    scale_note,
    score_depths,
    setting_label,
    train_all,
    training_fitness,
    training_jobs,
    write_csv,
    write_section,
)


def _curves(histories: list[list[dict]], key: str) -> np.ndarray:
    """``[runs, generations]`` of one history column (runs cut to the shortest)."""
    g = min(len(h) for h in histories)
    return np.array([[r[key] for r in h[:g]] for h in histories])


def _fmt(x: float) -> str:
    return f"{x:.3f}"


# --- training ------------------------------------------------------------------------------


def training(ctx: Context) -> None:
    """Best fitness per generation for each training robot count (mean and spread)."""
    s = ctx.scale
    runs = train_all(ctx, training_jobs("training", s), "training")
    if not any(runs.values()):
        raise FileNotFoundError(f"training: no finished run in {ctx.out}")
    rows, table = [], []
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.5, 4), dpi=100)
    for n in s.train_robots:
        hs = runs[("ant", n)]
        if not hs:  # --finished: none of this setting's runs is finished yet
            continue
        for k, h in enumerate(hs):
            rows += [
                {
                    "robots": n,
                    "run": k,
                    "generation": r["generation"],
                    "evaluations": r["evaluations"],
                    "best": r["best"],
                    "best_ever": r["best_ever"],
                }  # fmt: skip
                for r in h
            ]
        best = _curves(hs, "best")
        gens = np.arange(best.shape[1])
        m, sd = best.mean(0), best.std(0)
        ax.plot(gens, m, label=f"{n} robot{'s' if n > 1 else ''}")
        ax.fill_between(gens, m - sd, m + sd, alpha=0.15)
        tail = best[:, -max(1, best.shape[1] // 10) :].mean(1)
        ever = _curves(hs, "best_ever")[:, -1]
        table.append(
            f"| {n} | {_fmt(tail.mean())} +- {_fmt(tail.std())} | {_fmt(ever.mean())} | "
            f"{int((ever >= SOLVED).sum())} / {len(hs)} |"
        )
    ax.axhline(SOLVED, color="gray", ls=":", lw=0.8)
    ax.set(xlabel="generation", ylabel="best fitness of the generation", ylim=(0, 1))
    ax.set_title(f"ANT training, mean +- std over the runs ({s.name} scale)", fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(ctx.dir("training") / "training.png")
    plt.close(fig)
    write_csv(ctx.dir("training") / "training.csv", rows)
    write_section(
        ctx,
        "training",
        f"""### Training with 1 to 5 robots

{scale_note(ctx, runs)}

| robots | best of generation, last 10% (mean +- std) | best ever (mean) | runs reaching {SOLVED} |
|---:|---:|---:|---:|
{chr(10).join(table)}

![training](figures/training/training.png)
""",
    )


# --- compare -------------------------------------------------------------------------------


def compare(ctx: Context) -> None:
    """ANT against NEAT and the fixed network: mean maximum fitness and P(fitness >= 0.9)."""
    s = ctx.scale
    n = compare_robots(s)
    methods = ("ant", "fixed", "neat")
    runs = train_all(ctx, training_jobs("compare", s), "compare")
    plt = pyplot()
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4), dpi=100)
    rows, final = [], {}
    methods = tuple(m for m in methods if runs[(m, n)])  # --finished: those with a run
    if not methods:
        raise FileNotFoundError(f"compare: no finished run in {ctx.out}")
    for m in methods:
        hs = runs[(m, n)]
        ever = _curves(hs, "best_ever")
        evals = _curves(hs, "evaluations").mean(0)
        mean_max = ever.mean(0)
        p_sol = (ever >= SOLVED).mean(0)
        final[m] = (mean_max[-1], ever[:, -1].std(), p_sol[-1], len(hs))
        a1.plot(evals, mean_max, label=METHOD_LABELS[m])
        a2.plot(evals, p_sol, label=METHOD_LABELS[m])
        rows += [
            {
                "method": m,
                "generation": g,
                "evaluations": int(evals[g]),
                "mean_max_fitness": float(mean_max[g]),
                "p_solution": float(p_sol[g]),
            }  # fmt: skip
            for g in range(len(evals))
        ]
    a1.set(xlabel="scenario evaluations", ylabel="maximum fitness (mean over runs)", ylim=(0, 1))
    a2.set(xlabel="scenario evaluations", ylabel=f"P(fitness >= {SOLVED})", ylim=(-0.02, 1.02))
    for a in (a1, a2):
        a.grid(alpha=0.3)
        a.legend(fontsize=8)
    counts = ", ".join(f"{METHOD_LABELS[m]} {final[m][3]}" for m in methods)
    fig.suptitle(f"{n} robots, runs: {counts} ({s.name} scale)", fontsize=9)
    fig.tight_layout()
    fig.savefig(ctx.dir("compare") / "compare.png")
    plt.close(fig)
    write_csv(ctx.dir("compare") / "compare.csv", rows)
    conventional = [final[m][0] for m in ("neat", "fixed") if m in final]
    best_conv = max(conventional, default=float("nan"))
    gain = final["ant"][0] / best_conv - 1 if "ant" in final and best_conv > 0 else float("nan")
    p_ratio = float("nan")
    if "ant" in final and "neat" in final:
        p_ratio = final["ant"][2] / final["neat"][2] if final["neat"][2] > 0 else float("inf")
    table = "\n".join(
        f"| {METHOD_LABELS[m]} | {final[m][3]} | {_fmt(final[m][0])} +- {_fmt(final[m][1])} | "
        f"{final[m][2]:.2f} |"
        for m in methods
    )
    (ctx.dir("compare") / "summary.json").write_text(
        json.dumps(
            {
                "final": final,
                "ant_gain_over_best_conventional": gain,
                # null where NEAT solved nothing (the ratio is unbounded) or has no run
                "p_solution_ratio_ant_neat": p_ratio if np.isfinite(p_ratio) else None,
            },
            indent=1,
        )  # fmt: skip
    )
    write_section(
        ctx,
        "compare",
        f"""### ANT against NEAT and a fixed-topology network ({n} robots)

{scale_note(ctx, runs)} Same seeds, hence the same scenarios, for every method.

| method | runs | maximum fitness at the end (mean +- std over runs) | P(fitness >= {SOLVED}) |
|---|---:|---:|---:|
{table}

{_compare_sentence(gain, p_ratio, final.get("ant", (0, 0, 0.0))[2])}

![compare](figures/compare/compare.png)
""",
    )


def _compare_sentence(gain: float, p_ratio: float, p_ant: float) -> str:
    """The two headline ratios, each only where both of its methods have runs."""
    parts = []
    if not np.isnan(gain):
        parts.append(f"ANT's mean maximum fitness is {gain * 100:+.0f}% against the best "
                     "conventional network")  # fmt: skip
    if np.isinf(p_ratio):
        parts.append(f"no NEAT run reached {SOLVED}, against {p_ant:.2f} of ANT's runs")
    elif not np.isnan(p_ratio):
        parts.append(f"its probability of a solution is {p_ratio:.2f} times NEAT's")
    return ("; ".join(parts) + ".") if parts else "(ANT or both conventional networks: no run.)"


# --- coarse coding -------------------------------------------------------------------------


def coarse_coding(ctx: Context) -> None:
    """ANT with and without coarse coding for each training robot count."""
    s = ctx.scale
    runs = train_all(ctx, training_jobs("coarse-coding", s), "coarse-coding")
    rows, lines = [], []
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 4), dpi=100)
    for m in ("ant", "ant-nocc"):
        ns, means, sds = [], [], []
        for n in s.train_robots:
            if not runs[(m, n)]:  # --finished: none of this setting's runs is finished yet
                continue
            ever = _curves(runs[(m, n)], "best_ever")[:, -1]
            ns.append(n)
            means.append(ever.mean())
            sds.append(ever.std())
            rows.append({"method": m, "robots": n, "runs": len(ever),
                         "max_fitness_mean": float(ever.mean()),
                         "max_fitness_std": float(ever.std()),
                         "p_solution": float((ever >= SOLVED).mean())})  # fmt: skip
        if ns:
            ax.errorbar(ns, means, yerr=sds, marker="o", capsize=3, label=METHOD_LABELS[m])
    if not rows:
        plt.close(fig)
        raise FileNotFoundError(f"coarse-coding: no finished run in {ctx.out}")
    cell = {(r["method"], r["robots"]): r for r in rows}

    def fmt_cell(r: dict | None) -> str:
        if r is None:
            return "-"
        return f"{_fmt(r['max_fitness_mean'])} +- {_fmt(r['max_fitness_std'])} ({r['runs']})"

    for n in s.train_robots:
        lines.append(
            f"| {n} | {fmt_cell(cell.get(('ant', n)))} | {fmt_cell(cell.get(('ant-nocc', n)))} |"
        )
    ax.set(xlabel="robots in training", ylabel="maximum fitness (mean over runs)", ylim=(0, 1))
    ax.set_xticks(list(s.train_robots))
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(f"coarse coding on and off ({s.name} scale)", fontsize=9)
    fig.tight_layout()
    fig.savefig(ctx.dir("coarse-coding") / "coarse_coding.png")
    plt.close(fig)
    write_csv(ctx.dir("coarse-coding") / "coarse_coding.csv", rows)
    write_section(
        ctx,
        "coarse-coding",
        f"""### ANT with and without coarse coding

{scale_note(ctx, runs)} Each cell: maximum fitness at the end, mean +- std over the runs
(their number).

| robots | with coarse coding | without coarse coding |
|---:|---:|---:|
{chr(10).join(lines)}

![coarse coding](figures/coarse-coding/coarse_coding.png)
""",
    )


# --- scale-up ------------------------------------------------------------------------------


def _sweep(ctx: Context, controller, label: str, bar) -> list[dict]:
    out = []
    for n in ctx.scale.eval_robots:
        sc = score_depths(controller, ctx, n)
        out.append({"controller": label, "robots": n, "mean": float(sc.mean()),
                    "std": float(sc.std())})  # fmt: skip
        bar.update()
    return out


def scaleup(ctx: Context) -> None:
    """Controllers evolved with 1-5 robots (and mixed) applied to 1-10 robots on 8 x 8.

    The main table is each setting's fittest genome (by training fitness); a second table
    scores every finished run's genome (mean +- std over each setting's runs), since one
    controller is one sample of what a setting's evolution finds.
    """
    s = ctx.scale
    runs = train_all(ctx, training_jobs("scaleup", s), "scaleup training")
    plan = [(f"{METHOD_LABELS[m]} {setting_label(r)}", m, r) for (m, r), h in runs.items() if h]
    if not plan:
        raise FileNotFoundError(f"scaleup: no finished run in {ctx.out}")
    rows = []
    with tqdm(total=(len(plan) + 1) * len(s.eval_robots), desc="scaleup", unit="setting") as bar:
        for label, m, r in plan:
            path, _ = best_of_runs(ctx, m, r)
            rows += _sweep(ctx, load_controller(path), label, bar)
        rows += _sweep(ctx, Controller.hand_coded(ctx.readings["hand_coded"]), "hand-coded", bar)
    write_csv(ctx.dir("scaleup") / "scaleup.csv", rows)
    labels = [p[0] for p in plan] + ["hand-coded"]
    by = {(r["controller"], r["robots"]): r for r in rows}
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), dpi=100, sharey=True)
    for ax, prefix in zip(axes, ("ANT", "fixed network"), strict=True):
        for lab in labels:
            if lab.startswith(prefix) or lab == "hand-coded":
                ys = [by[(lab, n)]["mean"] for n in s.eval_robots]
                ax.plot(s.eval_robots, ys, marker="o", ms=3, label=lab.replace(prefix + " ", ""),
                        ls="--" if lab == "hand-coded" else "-")  # fmt: skip
        ax.set(xlabel="robots", title=f"{prefix} evolved with n robots", ylim=(0, 1))
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    axes[0].set_ylabel(f"fitness after {s.steps} steps (8 x 8 pit)")
    fig.tight_layout()
    fig.savefig(ctx.dir("scaleup") / "scaleup.png")
    plt.close(fig)
    head = "| controller | " + " | ".join(str(n) for n in s.eval_robots) + " |"
    sep = "|---|" + "---:|" * len(s.eval_robots)
    body = "\n".join(
        f"| {lab} | " + " | ".join(_fmt(by[(lab, n)]["mean"]) for n in s.eval_robots) + " |"
        for lab in labels
    )
    every = _every_run(
        ctx, "scaleup", [(label, finished_runs(ctx, m, r)) for label, m, r in plan], "setting",
        lambda c, _label, n: score_depths(c, ctx, n), f"fitness after {s.steps} steps (8 x 8)",
        "each setting",
    )  # fmt: skip
    write_section(
        ctx,
        "scaleup",
        f"""### Scaling the evolved controllers to 1-10 robots

{scale_note(ctx, runs)} Each row is the fittest genome (by training fitness) of that
setting's runs; columns are robots at evaluation time on the 8 x 8 pit; `n4` = evolved with
4 robots, `mix1+4` = scenarios alternating 1 and 4 robots.

{head}
{sep}
{body}

![scaleup](figures/scaleup/scaleup.png)
{every}""",
    )


# --- antagonism, depth, area ------------------------------------------------------------------


def _genome_note(ctx: Context) -> tuple[Controller, str]:
    path = four_robot_genome(ctx)
    g = load_genome(path)
    fit = g.metadata.get("fitness") if isinstance(g.metadata, dict) else None
    shown = f"{fit:.3f}" if isinstance(fit, float) else fit
    return Controller.from_genome(g, name=str(path)), f"`{path}` (training fitness {shown})"


def _robot_grid(ctx: Context, name: str, keys, key_label: str, scorer, ylab: str) -> list[dict]:
    s = ctx.scale
    rows = []
    with tqdm(total=len(keys) * len(s.eval_robots), desc=name, unit="setting") as bar:
        for key in keys:
            for n in s.eval_robots:
                sc = scorer(key, n)
                rows.append({key_label: key, "robots": n, "mean": float(sc.mean()),
                             "std": float(sc.std())})  # fmt: skip
                bar.update()
    write_csv(ctx.dir(name) / f"{name}.csv", rows)
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 4), dpi=100)
    for key in keys:
        sel = [r for r in rows if r[key_label] == key]
        ax.errorbar([r["robots"] for r in sel], [r["mean"] for r in sel],
                    yerr=[r["std"] for r in sel], marker="o", ms=3, capsize=2,
                    label=f"{key_label} {key}")  # fmt: skip
    ax.set(xlabel="robots", ylabel=ylab, ylim=(0, 1.05))
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(ctx.dir(name) / f"{name}.png")
    plt.close(fig)
    return rows


def _peak_table(rows: list[dict], keys, key_label: str, robots) -> str:
    lines = [
        f"| {key_label} | " + " | ".join(str(n) for n in robots) + " | peak at |",
        "|---|" + "---:|" * (len(robots) + 1),
    ]
    for key in keys:
        sel = {r["robots"]: r["mean"] for r in rows if r[key_label] == key}
        peak = max(robots, key=lambda n: sel[n])
        lines.append(
            f"| {key} | " + " | ".join(_fmt(sel[n]) for n in robots) + f" | {peak} robots |"
        )
    return "\n".join(lines)


def antagonism(ctx: Context) -> None:
    """The 4-robot controller on 6 x 6, 8 x 8 and 10 x 10 pits with 1-10 robots."""
    s = ctx.scale
    ctl, note = _genome_note(ctx)
    rows = _robot_grid(
        ctx, "antagonism", s.areas, "pit",
        lambda a, n: score_depths(ctl, ctx, n, size=a),
        f"fitness after {s.steps} steps",
    )  # fmt: skip
    every = _every_run(
        ctx, "antagonism", _four_robot_runs(ctx, s.areas), "pit",
        lambda c, a, n: score_depths(c, ctx, n, size=a),
        f"fitness after {s.steps} steps", "the 4-robot ANT runs",
    )  # fmt: skip
    write_section(
        ctx,
        "antagonism",
        f"""### Antagonism: pit size against robots

The 4-robot controller {note} on square pits of {", ".join(map(str, s.areas))} cells
(dump band 2), {s.eval_scenarios} unseen scenarios per cell split over goal depths
{", ".join(map(str, s.depths))}, {s.steps} steps.

{_peak_table(rows, s.areas, "pit", s.eval_robots)}

![antagonism](figures/antagonism/antagonism.png)
{every}""",
    )


def _every_run(
    ctx: Context, name: str, groups, key_label: str, scorer, ylab: str, what: str
) -> str:
    """An experiment's grid for the best genome of every finished run, group by group.

    One controller is one sample of what evolution finds; the numbers of every run's own
    controller show how much a result depends on the run.

    Args:
        ctx: The context.
        name: The experiment (``NAME_runs.csv`` and ``NAME_runs.png`` go to its directory).
        groups: ``[(key, [(run, best.json), ...]), ...]``: the runs scored for each key.
        key_label: The key's column name (``pit``, ``depth``, ``setting``).
        scorer: ``scorer(controller, key, robots)``: per-scenario fitness of one cell.
        ylab: The figure's y label.
        what: Which runs these are, for the text (``the 4-robot ANT runs``).

    Returns:
        A markdown part of the section; "" when no group has two finished runs.
    """
    s = ctx.scale
    if max((len(runs) for _, runs in groups), default=0) < 2:
        return ""
    rows = []
    loaded: dict = {}
    total = sum(len(runs) for _, runs in groups) * len(s.eval_robots)
    with tqdm(total=total, desc=f"{name}, every run", unit="setting") as bar:
        for key, runs in groups:
            for k, path in runs:
                if path not in loaded:
                    loaded[path] = (load_controller(path), training_fitness(path))
                ctl, fit = loaded[path]
                for n in s.eval_robots:
                    sc = scorer(ctl, key, n)
                    rows.append({"run": k, "training_fitness": fit, key_label: key, "robots": n,
                                 "mean": float(sc.mean()), "std": float(sc.std())})  # fmt: skip
                    bar.update()
    stem = name.replace("-", "_")
    write_csv(ctx.dir(name) / f"{stem}_runs.csv", rows)
    robots = list(s.eval_robots)
    grid = {(r["run"], r[key_label], r["robots"]): r["mean"] for r in rows}
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 4), dpi=100)
    lines = [
        f"| {key_label} | runs | " + " | ".join(str(n) for n in robots)
        + " | peak of each run's controller |",
        "|---|---:|" + "---:|" * len(robots) + "---|",
    ]  # fmt: skip
    for key, runs in groups:
        if not runs:
            continue
        per_run = np.array([[grid[(k, key, n)] for n in robots] for k, _ in runs])
        mean, sd = per_run.mean(0), per_run.std(0)
        ax.errorbar(robots, mean, yerr=sd, marker="o", ms=3, capsize=2, label=f"{key_label} {key}")
        peaks = [robots[int(np.argmax(row))] for row in per_run]
        counts = ", ".join(f"{n}: {peaks.count(n)}" for n in sorted(set(peaks)))
        lines.append(
            f"| {key} | {len(runs)} | "
            + " | ".join(f"{m:.3f} +- {d:.3f}" for m, d in zip(mean, sd, strict=True))
            + f" | {counts} (median {float(np.median(peaks)):g}) |"
        )
    ax.set(xlabel="robots", ylabel=f"{ylab}, mean over runs", ylim=(0, 1.05))
    ax.set_title(f"best genome of every finished run of {what} ({s.name} scale)", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(ctx.dir(name) / f"{stem}_runs.png")
    plt.close(fig)
    return f"""
The best genome of every finished run of {what} on the same scenarios: fitness mean +- std
over the runs' controllers, and how many runs' controllers peak at each robot count
(`{stem}_runs.csv` has every run).

{chr(10).join(lines)}

![{name}, every run](figures/{name}/{stem}_runs.png)
"""


def _four_robot_runs(ctx: Context, keys) -> list[tuple[object, list[tuple[int, object]]]]:
    """``_every_run``'s groups for the 4-robot ANT runs, the same runs for every key.

    None when ``--genome`` names the controller.
    """
    runs = [] if ctx.genome is not None else finished_runs(ctx, "ant", compare_robots(ctx.scale))
    return [(key, runs) for key in keys]


def depth(ctx: Context) -> None:
    """The 4-robot controller on goal depths 1-3 after a long run, 1-10 robots."""
    from ant_evolution.experiments.core import EVAL_SEED, score, site

    s = ctx.scale
    ctl, note = _genome_note(ctx)

    def scorer(c, d, n):
        return score(c, site(8, d, ctx.rules.fitted_site), n, s.eval_scenarios, s.long_steps,
                     EVAL_SEED + n, ctx.rules)  # fmt: skip

    ylab = f"fitness after {s.long_steps} steps"
    rows = _robot_grid(ctx, "depth", s.depths, "depth", lambda d, n: scorer(ctl, d, n), ylab)
    every = _every_run(ctx, "depth", _four_robot_runs(ctx, s.depths), "depth", scorer, ylab,
                       "the 4-robot ANT runs")  # fmt: skip
    write_section(
        ctx,
        "depth",
        f"""### Goal depth after a long run

The 4-robot controller {note} on the 8 x 8 pit at goal depths
{", ".join(map(str, s.depths))}, {s.eval_scenarios} unseen scenarios per cell,
{s.long_steps} steps.

{_peak_table(rows, s.depths, "depth", s.eval_robots)}

![depth](figures/depth/depth.png)
{every}""",
    )


def area(ctx: Context) -> None:
    """The 4-robot controller on growing pits after a long run, 1-10 robots."""
    s = ctx.scale
    ctl, note = _genome_note(ctx)

    def scorer(c, a, n):
        return score_depths(c, ctx, n, steps=s.long_steps, size=a)

    ylab = f"fitness after {s.long_steps} steps"
    rows = _robot_grid(ctx, "area", s.area_sizes, "pit", lambda a, n: scorer(ctl, a, n), ylab)
    every = _every_run(ctx, "area", _four_robot_runs(ctx, s.area_sizes), "pit", scorer, ylab,
                       "the 4-robot ANT runs")  # fmt: skip
    write_section(
        ctx,
        "area",
        f"""### Growing the excavation area

The 4-robot controller {note} on square pits of {", ".join(map(str, s.area_sizes))}
cells (grid at least 16 x 16, pit + 8 cells when larger), {s.eval_scenarios} unseen
scenarios per cell split over goal depths {", ".join(map(str, s.depths))},
{s.long_steps} steps.

{_peak_table(rows, s.area_sizes, "pit", s.eval_robots)}

![area](figures/area/area.png)
{every}""",
    )


# --- evolve-robots ---------------------------------------------------------------------------


def evolve_robots(ctx: Context) -> None:
    """N as a gene: which N the best genomes settle on."""
    s = ctx.scale
    trained = train_all(ctx, training_jobs("evolve-robots", s), "evolve-robots")
    runs = trained[("ant", "evolve")]
    if not runs:
        raise FileNotFoundError(f"evolve-robots: no finished run in {ctx.out}")
    lo, hi = s.robots_range
    best_n = [
        int(load_genome(path).tissue.robots) for _, path in finished_runs(ctx, "ant", "evolve")
    ]
    pop = np.zeros(hi + 1)
    for h in runs:
        for r in h[len(h) - max(1, len(h) // 5) :]:
            for part in filter(None, str(r["robots_hist"]).split(";")):
                n, c = part.split(":")
                pop[int(n)] += int(c)
    pop = pop / max(1.0, pop.sum())
    ns = list(range(lo, hi + 1))
    best_hist = np.array([best_n.count(n) for n in ns], dtype=float)
    rows = [{"robots": n, "best_genomes": int(best_hist[i]), "population_share": float(pop[n])}
            for i, n in enumerate(ns)]  # fmt: skip
    write_csv(ctx.dir("evolve-robots") / "evolve_robots.csv", rows)
    plt = pyplot()
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.6), dpi=100)
    a1.bar(ns, best_hist)
    a1.set(xlabel="N of each run's best genome", ylabel="runs")
    a2.bar(ns, pop[lo:])
    a2.set(xlabel="N in the population (last 20% of generations)", ylabel="share")
    for a in (a1, a2):
        a.set_xticks(ns)
        a.grid(alpha=0.3, axis="y")
    fig.suptitle(f"evolved number of robots, {len(runs)} runs ({s.name} scale)", fontsize=9)
    fig.tight_layout()
    fig.savefig(ctx.dir("evolve-robots") / "evolve_robots.png")
    plt.close(fig)
    table = "\n".join(
        f"| {r['robots']} | {r['best_genomes']} | {r['population_share']:.2f} |" for r in rows
    )
    write_section(
        ctx,
        "evolve-robots",
        f"""### Evolving the number of robots

{scale_note(ctx, trained)} N is a gene in {lo}..{hi} (every scenario places {hi} robots and a
genome uses its first N).

| N | runs whose best genome has this N | share of the population, last 20% of generations |
|---:|---:|---:|
{table}

![evolve robots](figures/evolve-robots/evolve_robots.png)
""",
    )


EXPERIMENTS = {
    "training": training,
    "compare": compare,
    "coarse-coding": coarse_coding,
    "scaleup": scaleup,
    "antagonism": antagonism,
    "depth": depth,
    "area": area,
    "evolve-robots": evolve_robots,
}
