"""``compare``: ANT against NEAT and the fixed network, mean maximum fitness and P(>= 0.9).

:func:`curves` and :func:`compute` turn the runs' histories into each method's curves
against scenario evaluations and the rows of ``compare.csv``; :func:`finals`,
:func:`ratios` and :func:`summary` give ``summary.json``; :func:`run` trains (or reads
back) the runs and writes the CSV, the JSON, ``compare.png`` and ``section.md``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

from ant_evolution.experiments.core import (
    METHOD_LABELS,
    SOLVED,
    Context,
    compare_robots,
    history_columns,
    train_all,
    training_jobs,
    write_csv,
)
from ant_evolution.experiments.figures import figure, finish
from ant_evolution.experiments.sections import (
    figure_link,
    fmt,
    scale_note,
    section,
    table,
    write_section,
)

NAME = "compare"
METHODS = ("ant", "fixed", "neat")


@dataclass(frozen=True)
class Curve:
    """One method's runs, generation by generation.

    Attributes:
        evaluations: Scenario evaluations so far, mean over the runs.
        mean_max: Maximum fitness so far, mean over the runs.
        p_solution: Share of the runs whose maximum so far reached :data:`SOLVED`.
        final_std: Std over the runs of the maximum fitness at the end.
        runs: How many runs.
    """

    evaluations: np.ndarray
    mean_max: np.ndarray
    p_solution: np.ndarray
    final_std: float
    runs: int


def curves(runs: dict, robots: int) -> dict[str, Curve]:
    """Each method's :class:`Curve` (methods without a run are left out).

    Args:
        runs: ``{(method, robots): [history, ...]}`` (``train_all``'s answer).
        robots: The team size compared.
    """
    out = {}
    for m in METHODS:
        hs = runs[(m, robots)]
        if not hs:  # --finished: none of this method's runs is finished yet
            continue
        ever = history_columns(hs, "best_ever")
        out[m] = Curve(history_columns(hs, "evaluations").mean(0), ever.mean(0),
                       (ever >= SOLVED).mean(0), ever[:, -1].std(), len(hs))  # fmt: skip
    return out


def compute(runs: dict, robots: int) -> list[dict]:
    """The rows of ``compare.csv``: method, generation and the two curves."""
    return [
        {
            "method": m,
            "generation": g,
            "evaluations": int(c.evaluations[g]),
            "mean_max_fitness": float(c.mean_max[g]),
            "p_solution": float(c.p_solution[g]),
        }  # fmt: skip
        for m, c in curves(runs, robots).items()
        for g in range(len(c.evaluations))
    ]


def finals(found: dict[str, Curve]) -> dict[str, tuple]:
    """Each method's end: ``(mean maximum fitness, its std, P(solution), runs)``."""
    return {m: (c.mean_max[-1], c.final_std, c.p_solution[-1], c.runs) for m, c in found.items()}


def ratios(final: dict[str, tuple]) -> tuple[float, float]:
    """ANT's gain over the best conventional network, and its P(solution) over NEAT's.

    NaN where a method of the pair has no run; the second is infinite where NEAT solved
    nothing.
    """
    conventional = [final[m][0] for m in ("neat", "fixed") if m in final]
    best_conv = max(conventional, default=float("nan"))
    gain = final["ant"][0] / best_conv - 1 if "ant" in final and best_conv > 0 else float("nan")
    p_ratio = float("nan")
    if "ant" in final and "neat" in final:
        p_ratio = final["ant"][2] / final["neat"][2] if final["neat"][2] > 0 else float("inf")
    return gain, p_ratio


def summary(final: dict[str, tuple]) -> dict:
    """``summary.json``: each method's end (:func:`finals`) and the two :func:`ratios`."""
    gain, p_ratio = ratios(final)
    return {
        "final": final,
        "ant_gain_over_best_conventional": gain,
        # null where NEAT solved nothing (the ratio is unbounded) or has no run
        "p_solution_ratio_ant_neat": p_ratio if np.isfinite(p_ratio) else None,
    }


def sentence(gain: float, p_ratio: float, p_ant: float) -> str:
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


def run(ctx: Context) -> None:
    """Train (or read back) the three methods' runs; write the comparison."""
    s = ctx.scale
    n = compare_robots(s)
    runs = train_all(ctx, training_jobs(NAME, s), NAME)
    found = curves(runs, n)
    if not found:
        raise FileNotFoundError(f"compare: no finished run in {ctx.out}")
    out = ctx.dir(NAME)
    write_csv(out / "compare.csv", compute(runs, n))
    final = finals(found)
    with figure(out / "compare.png", 1, 2, figsize=(10, 4), dpi=100) as (fig, (a1, a2)):
        for m, c in found.items():
            a1.plot(c.evaluations, c.mean_max, label=METHOD_LABELS[m])
            a2.plot(c.evaluations, c.p_solution, label=METHOD_LABELS[m])
        a1.set(xlabel="scenario evaluations", ylabel="maximum fitness (mean over runs)",
               ylim=(0, 1))  # fmt: skip
        a2.set(xlabel="scenario evaluations", ylabel=f"P(fitness >= {SOLVED})",
               ylim=(-0.02, 1.02))  # fmt: skip
        for a in (a1, a2):
            finish(a)
        counts = ", ".join(f"{METHOD_LABELS[m]} {final[m][3]}" for m in found)
        fig.suptitle(f"{n} robots, runs: {counts} ({s.name} scale)", fontsize=9)
    (out / "summary.json").write_text(json.dumps(summary(final), indent=1))
    gain, p_ratio = ratios(final)
    body = [[METHOD_LABELS[m], str(f[3]), f"{fmt(f[0])} +- {fmt(f[1])}", f"{f[2]:.2f}"]
            for m, f in final.items()]  # fmt: skip
    head = ["method", "runs", "maximum fitness at the end (mean +- std over runs)",
            f"P(fitness >= {SOLVED})"]  # fmt: skip
    write_section(
        ctx,
        NAME,
        section(
            f"ANT against NEAT and a fixed-topology network ({n} robots)",
            f"{scale_note(ctx, runs)} Same seeds, hence the same scenarios, for every method.",
            table(head, "lrrr", body),
            sentence(gain, p_ratio, final.get("ant", (0, 0, 0.0))[2]),
            figure_link(NAME, "compare.png", "compare"),
        ),
    )
