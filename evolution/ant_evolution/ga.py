"""The genetic algorithm of the paper (sections 3.4, 3.5 and 4.3) as pure functions.

Every operator takes an explicit ``numpy.random.Generator`` and returns new genomes; nothing
is modified in place. Defaults follow the paper: population 100, tournament size 0.06 P,
crossover probability 0.7, mutation probability 0.025 per gene parameter.

* :func:`mutate`: "manipulation of gene parameters with a uniform random distribution" with
  p_m = 0.025, in one of two readings (``mutation_scope``) and with one of two operators
  (``mutation_operator``):

  - scope ``"parameter"`` (profile ``v1``): every parameter of every gene mutates with
    probability p_m (about 112 changes per offspring for the shipped genome);
  - scope ``"gene"`` (profile ``paper``): every gene (each cell gene, and the tissue gene)
    mutates with probability p_m, and a mutating gene changes one of its parameters,
    chosen uniformly;
  - operator ``"redraw"`` (``v1``): the value is drawn afresh, uniform over its range;
  - operator ``"perturb"`` (``paper``): bounded uniform perturbation, the value plus
    ``U(-w, w)`` times its range (``w = mutation_width``), clipped to the range; an
    integer field half-extent steps by one.

  Under both operators flags and selector bits flip, the behaviour is redrawn (it is a
  category) and the N gene steps by one robot. Then, with the tissue's replication
  probability, a cell divides (:func:`replicate`).
* :func:`replicate`: the parent is a grown cell, either the one with the highest
  replication value (``replication_parent = "max"``, ``v1``) or one drawn with probability
  proportional to its replication value (``"proportional"``, ``paper``); the daughter
  takes a free lattice site next to it (one of six neighbours, chosen at random), is a
  decision neuron with probability ``decision_ratio``, and copies the first m% of the
  parent's parameters (m uniform), the rest drawn at random.
* :func:`crossover`: a plane normal to the l or m axis cuts the tissue; child 1 has
  affinity to parent A and child 2 to parent B. Genes on the origin side of the plane come
  from the affine parent; beyond it a gene is exchanged with the other parent's gene at the
  same lattice site when both are expressed or both repressed (the compatibility criterion);
  otherwise it stays.
* :func:`next_generation`: elitism (a switch: ``v1`` copies the best genome unchanged,
  ``paper`` none, as the paper states none), then tournament selection, crossover and
  mutation. It is the one breeding loop: the fixed-topology baseline passes its own
  ``crossover`` and ``mutate``.

``v1`` reproduces the first runs draw for draw (its code path is the original one).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from ant_controller.genome import (
    DECISION,
    MAX_EXTENT,
    MOTOR,
    N_NOMINAL_INPUTS,
    CellGene,
    Genome,
    random_cell,
)
from ant_controller.layout import N_BEHAVIOURS, N_SENSORS
from ant_evolution.errors import ConfigError
from ant_evolution.ga_kernel import (
    PackedCells,
    append_cell,
    crossover_packed,
    mutate_by_slots,
    mutate_cells,
    with_fields,
    with_genes,
)

MUTATION_SCOPES = ("parameter", "gene")
MUTATION_OPERATORS = ("redraw", "perturb")
REPLICATION_PARENTS = ("max", "proportional")

_NEIGHBOURS = ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1))


@dataclass(frozen=True)
class GAParams:
    """Parameters of the genetic algorithm.

    Attributes:
        population: P.
        tournament_fraction: Tournament size as a fraction of P (at least 2 genomes).
        crossover_prob: Probability that a pair of parents is crossed.
        mutation_prob: Probability that one gene parameter mutates.
        elitism: Best genomes copied unchanged into the next generation.
        robots_range: Bounds of the N gene when it is evolved.
        mutation_scope: ``"parameter"`` or ``"gene"`` (what ``mutation_prob`` is per).
        mutation_operator: ``"redraw"`` or ``"perturb"``.
        mutation_width: Half-width of a perturbation as a fraction of the range.
        replication_parent: ``"max"`` or ``"proportional"``.
    """

    population: int = 100
    tournament_fraction: float = 0.06
    crossover_prob: float = 0.7
    mutation_prob: float = 0.025
    elitism: int = 1
    robots_range: tuple[int, int] = (1, 8)
    mutation_scope: str = "parameter"
    mutation_operator: str = "redraw"
    mutation_width: float = 0.1
    replication_parent: str = "max"

    def __post_init__(self) -> None:
        for name, choices in (
            ("mutation_scope", MUTATION_SCOPES),
            ("mutation_operator", MUTATION_OPERATORS),
            ("replication_parent", REPLICATION_PARENTS),
        ):
            if getattr(self, name) not in choices:
                raise ConfigError("<ga>", name, getattr(self, name), f"must be one of {choices}")
        if not 0.0 < self.mutation_width <= 1.0:
            raise ConfigError("<ga>", "mutation_width", self.mutation_width, "must lie in (0, 1]")

    @property
    def legacy_mutation(self) -> bool:
        """Per-parameter full-range redraws: ``v1``'s operator, drawn exactly as it was."""
        return self.mutation_scope == "parameter" and self.mutation_operator == "redraw"

    @property
    def tournament_size(self) -> int:
        """Genomes per tournament."""
        return max(2, int(round(self.tournament_fraction * self.population)))


# --- mutation -------------------------------------------------------------------------------


def _redraw(rng: np.random.Generator, value: float, lo: float, hi: float, p: float) -> float:
    return float(rng.uniform(lo, hi)) if rng.random() < p else value


def _redraw_vector(rng: np.random.Generator, values: tuple[float, ...], p: float):
    hits = rng.random(len(values)) < p
    if not hits.any():
        return values
    fresh = rng.uniform(-1.0, 1.0, len(values))
    return tuple(float(f) if h else v for v, f, h in zip(values, fresh, hits, strict=True))


def mutate_cell(rng: np.random.Generator, gene: CellGene, p: float) -> CellGene:
    """Mutate every parameter of one cell gene with probability ``p`` each."""
    flips = rng.random(5) < p
    extent = tuple(
        int(rng.integers(0, MAX_EXTENT + 1)) if rng.random() < p else e for e in gene.extent
    )
    return replace(
        gene,
        expressed=gene.expressed ^ bool(flips[0]),
        dead=gene.dead ^ bool(flips[1]),
        k1=gene.k1 ^ int(flips[2]),
        k2=gene.k2 ^ int(flips[3]),
        replication=_redraw(rng, gene.replication, 0.0, 1.0, p),
        theta1=_redraw(rng, gene.theta1, -1.0, 1.0, p),
        theta2=_redraw(rng, gene.theta2, -1.0, 1.0, p),
        concentration=_redraw(rng, gene.concentration, 0.0, 1.0, p),
        behaviour=int(rng.integers(0, N_BEHAVIOURS)) if flips[4] else gene.behaviour,
        sensor_weights=_redraw_vector(rng, gene.sensor_weights, p),
        input_weights=_redraw_vector(rng, gene.input_weights, p),
        extent=extent,
    )


def mutate(rng: np.random.Generator, genome: Genome, params: GAParams) -> Genome:
    """Mutate a genome's cell genes and tissue gene, then maybe replicate a cell."""
    if params.legacy_mutation:
        child = _mutate_v1(rng, genome, params)
    else:
        child = _mutate_slots(rng, genome, params)
    if rng.random() < child.tissue.replication_probability:
        child = replicate(rng, child, params.replication_parent)
    return child


def _mutate_v1(rng: np.random.Generator, genome: Genome, params: GAParams) -> Genome:
    p = params.mutation_prob
    cells = mutate_cells(rng, genome.cells, p, N_BEHAVIOURS, MAX_EXTENT + 1)
    if cells is None:  # not a PCG64 generator, or genes of several vector lengths
        cells = tuple(mutate_cell(rng, g, p) for g in genome.cells)
    t = genome.tissue
    robots = t.robots
    if robots is not None and rng.random() < p:
        lo, hi = params.robots_range
        robots = int(np.clip(robots + (1 if rng.random() < 0.5 else -1), lo, hi))
    tissue = with_fields(
        t,
        {
            "replication_probability": _redraw(rng, t.replication_probability, 0.0, 0.1, p),
            "decision_ratio": _redraw(rng, t.decision_ratio, 0.0, 1.0, p),
            "robots": robots,
        },
    )
    return with_fields(genome, {"tissue": tissue, "cells": cells})


# Parameter slots of a cell gene, in order: (field, index or -1, kind, low, high).
# Kinds: "flag" flips, "bit" flips a 0/1 int, "real" and "int" are ranged, "category" is
# redrawn over its values.
_CELL_SLOTS: tuple[tuple[str, int, str, float, float], ...] = (
    ("expressed", -1, "flag", 0, 1),
    ("dead", -1, "flag", 0, 1),
    ("k1", -1, "bit", 0, 1),
    ("k2", -1, "bit", 0, 1),
    ("replication", -1, "real", 0.0, 1.0),
    ("theta1", -1, "real", -1.0, 1.0),
    ("theta2", -1, "real", -1.0, 1.0),
    ("concentration", -1, "real", 0.0, 1.0),
    ("behaviour", -1, "category", 0, N_BEHAVIOURS),
    *(("sensor_weights", i, "real", -1.0, 1.0) for i in range(N_SENSORS)),
    *(("input_weights", i, "real", -1.0, 1.0) for i in range(N_NOMINAL_INPUTS)),
    *(("extent", i, "int", 0, MAX_EXTENT) for i in range(3)),
)


def _new_value(rng: np.random.Generator, value, kind: str, lo, hi, params: GAParams):
    """One parameter's mutated value under ``params.mutation_operator``."""
    if kind == "flag":
        return not value
    if kind == "bit":
        return 1 - int(value)
    if kind == "category":
        return int(rng.integers(lo, hi))
    perturb = params.mutation_operator == "perturb"
    if kind == "int":
        if not perturb:
            return int(rng.integers(lo, hi + 1))
        return int(np.clip(int(value) + (1 if rng.random() < 0.5 else -1), lo, hi))
    if not perturb:
        return float(rng.uniform(lo, hi))
    w = params.mutation_width * (hi - lo)
    return float(np.clip(float(value) + rng.uniform(-w, w), lo, hi))


def _mutate_gene_slots(rng, gene: CellGene, slots, params: GAParams) -> CellGene:
    """``gene`` with the parameter slots ``slots`` (indices into ``_CELL_SLOTS``) mutated."""
    changes: dict = {}
    for s in slots:
        name, index, kind, lo, hi = _CELL_SLOTS[s]
        if index < 0:
            current = changes.get(name, getattr(gene, name))
            changes[name] = _new_value(rng, current, kind, lo, hi, params)
        else:
            vec = list(changes.get(name, getattr(gene, name)))
            vec[index] = _new_value(rng, vec[index], kind, lo, hi, params)
            changes[name] = tuple(vec)
    return replace(gene, **changes) if changes else gene


def _chosen_slots(rng: np.random.Generator, n_slots: int, params: GAParams) -> list[int]:
    """Slots that mutate in one gene: each with p (``parameter``), or one with p (``gene``)."""
    p = params.mutation_prob
    if params.mutation_scope == "parameter":
        return [int(i) for i in np.flatnonzero(rng.random(n_slots) < p)]
    if rng.random() < p:
        return [int(rng.integers(0, n_slots))]
    return []


def _mutate_slots(rng: np.random.Generator, genome: Genome, params: GAParams) -> Genome:
    """Mutation under the ``gene`` scope or the ``perturb`` operator (see the module).

    The cell genes mutate compiled on their rows
    (:func:`ant_evolution.ga_kernel.mutate_by_slots`: the same draws, genes and generator
    state) when they pack; otherwise in Python, where only the genes that mutate are read,
    in gene order, each right after its slots are drawn, and the child is packed when its
    parent's genes pack (:func:`ant_evolution.ga_kernel.with_genes`).
    """
    cells = mutate_by_slots(
        rng,
        genome.cells,
        params.mutation_prob,
        _CELL_SLOTS,
        params.mutation_scope,
        params.mutation_operator,
        params.mutation_width,
    )
    if cells is None:  # not a PCG64 generator, or genes that do not pack
        cells = genome.cells
        n_slots = len(_CELL_SLOTS)
        changes: dict[int, CellGene] = {}
        for i in range(len(cells)):
            slots = _chosen_slots(rng, n_slots, params)
            if slots:
                changes[i] = _mutate_gene_slots(rng, cells[i], slots, params)
        cells = with_genes(cells, changes)
    t = genome.tissue
    n_tissue = 3 if t.robots is not None else 2
    changes: dict = {}
    for s in _chosen_slots(rng, n_tissue, params):
        if s == 0:
            changes["replication_probability"] = _new_value(
                rng, t.replication_probability, "real", 0.0, 0.1, params
            )
        elif s == 1:
            changes["decision_ratio"] = _new_value(rng, t.decision_ratio, "real", 0.0, 1.0, params)
        else:
            lo, hi = params.robots_range
            changes["robots"] = int(np.clip(t.robots + (1 if rng.random() < 0.5 else -1), lo, hi))
    tissue = replace(t, **changes) if changes else t
    return replace(genome, tissue=tissue, cells=cells)


def _param_vector(g: CellGene) -> list[float]:
    return [
        g.replication,
        g.theta1,
        g.theta2,
        float(g.k1),
        float(g.k2),
        *g.sensor_weights,
        *g.input_weights,
        float(g.behaviour),
        g.concentration,
        *map(float, g.extent),
    ]


def _from_vector(base: CellGene, v: list[float]) -> CellGene:
    i = 5 + N_SENSORS
    j = i + N_NOMINAL_INPUTS
    return replace(
        base,
        replication=v[0],
        theta1=v[1],
        theta2=v[2],
        k1=int(v[3]),
        k2=int(v[4]),
        sensor_weights=tuple(v[5:i]),
        input_weights=tuple(v[i:j]),
        behaviour=int(v[j]),
        concentration=v[j + 1],
        extent=tuple(int(e) for e in v[j + 2 : j + 5]),
    )


def replicate(rng: np.random.Generator, genome: Genome, parent_rule: str = "max") -> Genome:
    """Cell division: add one daughter gene next to a grown parent cell.

    ``parent_rule``: ``"max"``, the grown cell with the highest replication value (first
    of equals in gene order); ``"proportional"``, a grown cell drawn with probability
    proportional to its replication value (uniform when all are 0). Returns the genome
    unchanged when no cell is grown or the parent has no free neighbouring site inside
    the lattice.
    """
    cells = genome.cells
    if isinstance(cells, PackedCells):  # flags and replication values from the arrays
        grown = cells.grown().tolist()
        replication = cells.scalars[grown, 4]
    else:
        grown = [i for i, g in enumerate(cells) if g.expressed and not g.dead]
        replication = np.array([cells[i].replication for i in grown], dtype=np.float64)
    if not grown:
        return genome
    if parent_rule == "proportional":
        total = float(replication.sum())
        if total > 0.0:
            i = int(np.searchsorted(np.cumsum(replication), rng.random() * total, side="right"))
            parent = cells[grown[min(i, len(grown) - 1)]]
        else:
            parent = cells[grown[int(rng.integers(0, len(grown)))]]
    else:
        parent = cells[grown[int(np.argmax(replication))]]  # the first of equals, as max()
    seed = genome.tissue.seed
    if isinstance(cells, PackedCells):

        def taken(site) -> bool:
            return cells.sites.holds(tuple(site[a] - seed[a] for a in range(3)))

    else:
        taken = {genome.absolute(g) for g in cells}.__contains__
    base = genome.absolute(parent)
    sites = [
        s
        for s in (tuple(base[a] + d[a] for a in range(3)) for d in _NEIGHBOURS)
        if genome.lattice.contains(s) and not taken(s)
    ]
    if not sites:
        return genome
    site = sites[int(rng.integers(0, len(sites)))]
    kind = DECISION if rng.random() < genome.tissue.decision_ratio else MOTOR
    rel = tuple(site[a] - seed[a] for a in range(3))
    fresh = random_cell(rng, kind, rel)
    pv = _param_vector(parent)
    fv = _param_vector(fresh)
    keep = int(rng.integers(0, len(pv) + 1))  # the first m% of the parent's contents
    daughter = _from_vector(fresh, pv[:keep] + fv[keep:])
    return replace(genome, cells=append_cell(genome.cells, daughter))


# --- crossover ------------------------------------------------------------------------------


def crossover(rng: np.random.Generator, a: Genome, b: Genome) -> tuple[Genome, Genome]:
    """Plane-cut crossover with the compatibility criterion; returns (child of A, child of B).

    Parents whose genes are packed (children of the compiled mutation) cross on arrays
    (:func:`ant_evolution.ga_kernel.crossover_packed`: the same children and draws).
    """
    fast = crossover_packed(rng, a, b)
    if fast is not None:
        return fast
    axis = int(rng.integers(0, 2))
    coords = [a.absolute(g)[axis] for g in a.cells] + [b.absolute(g)[axis] for g in b.cells]
    if not coords:
        return a, b
    cut = int(rng.integers(min(coords), max(coords) + 1))
    b_at = {b.absolute(g): i for i, g in enumerate(b.cells)}
    a_cells = list(a.cells)
    b_cells = list(b.cells)
    for i, ga in enumerate(a.cells):
        pos = a.absolute(ga)
        if (pos[axis] <= cut) if cut >= 0 else (pos[axis] > cut):
            continue  # origin side of the plane (at cut + 0.5): from the affine parent
        j = b_at.get(pos)
        if j is None or b.cells[j].expressed != ga.expressed:
            continue  # incompatible: no exchange
        gb = b.cells[j]
        a_cells[i] = _relocate(gb, pos, a.tissue.seed)
        b_cells[j] = _relocate(ga, pos, b.tissue.seed)
    return replace(a, cells=tuple(a_cells)), replace(b, cells=tuple(b_cells))


def _relocate(gene: CellGene, absolute, seed) -> CellGene:
    return with_fields(gene, {"position": tuple(absolute[k] - seed[k] for k in range(3))})


# --- selection and generations ----------------------------------------------------------------


def tournament(rng: np.random.Generator, fitness, size: int) -> int:
    """Index of the fittest of ``size`` distinct random genomes (ties: the lowest index).

    ``fitness``: an array or a list (a list is faster to read one by one). A NaN wins, the
    lowest-indexed one, as under ``numpy.argmax``.
    """
    picks = sorted(rng.choice(len(fitness), size=min(size, len(fitness)), replace=False).tolist())
    best, top = picks[0], fitness[picks[0]]
    if top != top:
        return best
    for i in picks[1:]:
        v = fitness[i]
        if v != v:
            return i
        if v > top:
            best, top = i, v
    return best


def next_generation(
    rng: np.random.Generator,
    population: Sequence,
    fitness: np.ndarray,
    params: GAParams,
    crossover: Callable = crossover,
    mutate: Callable = mutate,
) -> list:
    """Breed the next population from the current one and its fitness.

    Elitism, then pairs of tournament winners, crossed with ``crossover_prob`` and each
    mutated. ``crossover(rng, a, b) -> (a', b')`` and ``mutate(rng, x, params) -> x'``
    default to ANT's operators; any genome type with its own operators breeds the same way
    (the same draws in the same order).
    """
    order = np.argsort(-fitness, kind="stable")
    out = [population[i] for i in order[: params.elitism]]
    size = params.tournament_size
    scores = np.asarray(fitness, dtype=np.float64).tolist()
    while len(out) < params.population:
        a = population[tournament(rng, scores, size)]
        b = population[tournament(rng, scores, size)]
        if rng.random() < params.crossover_prob:
            a, b = crossover(rng, a, b)
        out.append(mutate(rng, a, params))
        if len(out) < params.population:
            out.append(mutate(rng, b, params))
    return out
