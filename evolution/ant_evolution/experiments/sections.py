"""Section writers: the markdown every experiment writes as ``OUT/<name>/section.md``.

A section is a ``### title`` and blocks (paragraphs, tables, figure links) one blank line
apart (:func:`section`); the pieces several experiments share are here: the scale note,
markdown tables, the table of peaks over robot counts and the part on every run's
controller. Everything but :func:`write_section` only builds text.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from ant_evolution.experiments.core import (
    METHOD_LABELS,
    Context,
    EveryRunGroup,
    GridRow,
    setting_label,
)


def fmt(x: float) -> str:
    """A fitness as the tables print it (three decimals; ``-`` where robots did not fit)."""
    return "-" if x != x else f"{x:.3f}"


def peak_index(means: Sequence[float]) -> int:
    """Index of the highest mean (the first of equals).

    Cells whose robots did not fit (NaN) are left out; 0 when no cell has a mean.
    """
    best = None
    for i, m in enumerate(means):
        if m == m and (best is None or m > means[best]):
            best = i
    return 0 if best is None else best


UNPLACED_NOTE = "`-`: the robots do not fit the cell's site (no free 2 x 2 place was left)."
"""The line under a table with a cell whose robots could not be placed."""


def table(head: Sequence[str], align: str, body: Sequence[Sequence[str]]) -> str:
    """A markdown table: header cells, one alignment letter per column, rows of cells.

    Args:
        head: The header's cells.
        align: ``l`` (left, ``---``) or ``r`` (right, ``---:``) for each column.
        body: The rows, each a sequence of cells (already formatted).
    """
    if len(align) != len(head):
        raise ValueError(f"table: {len(head)} columns, {len(align)} alignments")
    marks = {"l": "---", "r": "---:"}
    lines = [_row(head), "|" + "".join(marks[a] + "|" for a in align)]
    return "\n".join(lines + [_row(cells) for cells in body])


def _row(cells: Sequence[str]) -> str:
    return "| " + " | ".join(str(c) for c in cells) + " |"


def figure_link(name: str, file: str, alt: str) -> str:
    """The markdown of a figure of experiment ``name`` (the report keeps it in ``figures/``)."""
    return f"![{alt}](figures/{name}/{file})"


def section(title: str, *blocks: str) -> str:
    """``### title`` and the non-empty blocks, one blank line apart."""
    parts = [b.strip("\n") for b in blocks]
    return f"### {title}\n\n" + "\n\n".join(p for p in parts if p) + "\n"


def write_section(ctx: Context, name: str, text: str) -> Path:
    """Write ``section.md`` of experiment ``name``."""
    path = ctx.dir(name) / "section.md"
    path.write_text(text.rstrip() + "\n", encoding="utf-8")
    return path


def scale_note(ctx: Context, runs: dict | None = None) -> str:
    """The scale an experiment ran at; with ``--finished``, how many runs each setting has.

    Args:
        ctx: The context.
        runs: ``train_all``'s answer (``{(method, robots): [history, ...]}``), for the
            in-part note.
    """
    s = ctx.scale
    note = (
        f"Scale `{s.name}`: {ctx.runs} runs per setting, P = {s.population}, "
        f"{s.generations} generations, {s.scenarios} scenarios of {s.steps} steps per "
        f"generation (goal depths {', '.join(map(str, s.depths))}); evaluations on "
        f"{s.eval_scenarios} unseen scenarios per setting."
    )
    if ctx.finished_only and runs is not None:
        have = ", ".join(
            f"{METHOD_LABELS[m]} {setting_label(r)} {len(h)}" for (m, r), h in runs.items()
        )
        note += (
            f"\n\n**In part** (`--finished`): only the runs finished so far, of {ctx.runs} per "
            f"setting: {have}. Settings without a finished run are left out."
        )
    return note


def peak_table(rows: Sequence[GridRow], keys, key_label: str, robots) -> str:
    """Mean fitness per key (row) and robot count (column), and the robot count of the peak."""
    body = []
    for key in keys:
        sel = {r.robots: r.mean for r in rows if r.key == key}
        peak = list(robots)[peak_index([sel[n] for n in robots])]
        body.append([str(key), *(fmt(sel[n]) for n in robots), f"{peak} robots"])
    head = [key_label, *(str(n) for n in robots), "peak at"]
    text = table(head, "l" + "r" * (len(robots) + 1), body)
    if any(r.mean != r.mean for r in rows):
        text += "\n\n" + UNPLACED_NOTE
    return text


def every_run_part(
    groups: list[EveryRunGroup], key_label: str, robots, name: str, what: str
) -> str:
    """The part of a section on the best genome of every finished run (group by group).

    Args:
        groups: :func:`~ant_evolution.experiments.grids.every_run_summary`'s answer.
        key_label: The key's column name (``pit``, ``depth``, ``setting``).
        robots: The robot counts (columns).
        name: The experiment (its figure is ``NAME_runs.png``).
        what: Which runs these are (``the 4-robot ANT runs``).
    """
    stem = name.replace("-", "_")
    body = []
    for g in groups:
        counts = ", ".join(f"{n}: {g.peaks.count(n)}" for n in sorted(set(g.peaks)))
        body.append(
            [str(g.key), str(g.runs)]
            + [
                fmt(m) if m != m else f"{m:.3f} +- {d:.3f}"
                for m, d in zip(g.mean, g.std, strict=True)
            ]
            + [f"{counts} (median {float(g.median_peak):g})"]
        )
    head = [key_label, "runs", *(str(n) for n in robots), "peak of each run's controller"]
    rows = table(head, "lr" + "r" * len(robots) + "l", body)
    return f"""The best genome of every finished run of {what} on the same scenarios: \
fitness mean +- std
over the runs' controllers, and how many runs' controllers peak at each robot count
(`{stem}_runs.csv` has every run).

{rows}

{figure_link(name, f"{stem}_runs.png", f"{name}, every run")}"""
