"""Genetic operators: mutation, replication, crossover, selection."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ant_controller.genome import DECISION, MOTOR, Genome, random_genome
from ant_controller.genome_io import genome_from_dict, genome_to_dict
from ant_evolution.ga import (
    GAParams,
    crossover,
    mutate,
    mutate_cell,
    next_generation,
    replicate,
    tournament,
)


def valid(genome: Genome) -> Genome:
    """Round-trip through the file validator: unique sites, lattice bounds, ranges."""
    return genome_from_dict(genome_to_dict(genome))


def test_mutation_rate_zero_changes_nothing_and_one_changes_everything():
    rng = np.random.default_rng(0)
    g = random_genome(rng)
    g = dataclasses.replace(g, tissue=dataclasses.replace(g.tissue, replication_probability=0.0))
    assert mutate(rng, g, GAParams(mutation_prob=0.0)) == g
    cell = g.cells[0]
    m = mutate_cell(rng, cell, 1.0)
    assert m.expressed != cell.expressed and m.dead != cell.dead
    assert m.k1 != cell.k1 and m.k2 != cell.k2
    assert m.theta1 != cell.theta1 and m.replication != cell.replication
    assert all(a != b for a, b in zip(m.sensor_weights, cell.sensor_weights, strict=True))
    assert m.position == cell.position and m.kind == cell.kind


def test_mutation_touches_about_the_configured_share_of_parameters():
    rng = np.random.default_rng(1)
    g = random_genome(rng)
    p = 0.025
    changed = total = 0
    for _ in range(20):
        m = [mutate_cell(rng, c, p) for c in g.cells]
        for a, b in zip(g.cells, m, strict=True):
            changed += sum(x != y for x, y in zip(a.sensor_weights, b.sensor_weights, strict=True))
            total += len(a.sensor_weights)
    assert 0.015 < changed / total < 0.035


@pytest.mark.parametrize(("ratio", "kind"), [(0.0, MOTOR), (1.0, DECISION)])
def test_replication_places_a_daughter_next_to_the_most_replicative_cell(ratio, kind):
    rng = np.random.default_rng(2)
    g = random_genome(rng)
    g = dataclasses.replace(g, tissue=dataclasses.replace(g.tissue, decision_ratio=ratio))
    child = replicate(rng, g)
    assert len(child.cells) == len(g.cells) + 1
    daughter = child.cells[-1]
    grown = [c for c in g.cells if c.expressed and not c.dead]
    parent = max(grown, key=lambda c: c.replication)
    d = np.subtract(child.absolute(daughter), g.absolute(parent))
    assert np.abs(d).sum() == 1  # one of the six face neighbours
    assert daughter.kind == kind
    valid(child)


def test_daughter_copies_a_prefix_of_the_parent():
    rng = np.random.default_rng(3)
    g = random_genome(rng)
    grown = [c for c in g.cells if c.expressed and not c.dead]
    parent = max(grown, key=lambda c: c.replication)
    starts_like_parent = 0
    for _ in range(40):
        daughter = replicate(rng, g).cells[-1]
        starts_like_parent += daughter.replication == parent.replication
    assert 20 < starts_like_parent < 40  # m is uniform: usually, not always, copied


def test_crossover_of_identical_parents_gives_the_parents():
    rng = np.random.default_rng(4)
    g = random_genome(rng)
    a, b = crossover(rng, g, g)
    assert a == g and b == g


def test_crossover_exchanges_only_compatible_genes_beyond_the_plane():
    rng = np.random.default_rng(5)
    a = random_genome(rng)
    # b: the same sites with other parameters, and some genes repressed
    b_cells = []
    for i, c in enumerate(a.cells):
        fresh = random_genome(np.random.default_rng(100 + i), n_neurons=(1, 1)).cells[0]
        b_cells.append(
            dataclasses.replace(fresh, kind=c.kind, position=c.position, expressed=i % 3 != 0)
        )
    b = dataclasses.replace(a, cells=tuple(b_cells))
    exchanged = 0
    for seed in range(30):
        c1, c2 = crossover(np.random.default_rng(seed), a, b)
        for i, (x, y) in enumerate(zip(c1.cells, c2.cells, strict=True)):
            if x == a.cells[i]:
                assert y == b.cells[i]
            else:  # exchanged: only when both expressed or both repressed
                assert x == b.cells[i] and y == a.cells[i]
                assert a.cells[i].expressed == b.cells[i].expressed
                exchanged += 1
        valid(c1)
        valid(c2)
    assert exchanged > 0


def test_tournament_picks_the_best_of_its_sample():
    rng = np.random.default_rng(6)
    fitness = np.arange(100, dtype=float)
    wins = [tournament(rng, fitness, 6) for _ in range(200)]
    assert np.mean(wins) > 80  # best of 6 uniform picks: expected ~85
    assert tournament(rng, np.array([0.5, 0.5]), 2) == 0


def test_next_generation_is_seeded_keeps_the_elite_and_stays_valid():
    rng = np.random.default_rng(7)
    pop = [random_genome(rng) for _ in range(12)]
    fit = np.linspace(0, 1, 12)
    params = GAParams(population=12, elitism=1)
    a = next_generation(np.random.default_rng(9), pop, fit, params)
    b = next_generation(np.random.default_rng(9), pop, fit, params)
    assert a == b and len(a) == 12
    assert a[0] is pop[11]
    for g in a:
        valid(g)
    # Many generations of operators keep every genome loadable.
    for gen in range(15):
        a = next_generation(
            np.random.default_rng(gen),
            a,
            np.random.default_rng(gen).random(12),
            dataclasses.replace(params, mutation_prob=0.2),
        )
    for g in a:
        valid(g)


def test_robots_gene_mutates_within_its_range():
    rng = np.random.default_rng(8)
    g = random_genome(rng, robots=1)
    seen = set()
    for _ in range(200):
        g = mutate(rng, g, GAParams(mutation_prob=0.5, robots_range=(1, 3)))
        seen.add(g.tissue.robots)
    assert seen == {1, 2, 3}


# --- the compiled per-parameter mutation (ant_evolution.ga_kernel) ------------------------


def _twin(rng: np.random.Generator) -> np.random.Generator:
    other = np.random.Generator(np.random.PCG64())
    other.bit_generator.state = rng.bit_generator.state
    return other


@pytest.mark.parametrize("p", [0.0, 0.025, 0.3, 1.0])
def test_compiled_mutation_gives_mutate_cells_genes_and_generator_state(p):
    """Gene for gene and state for state: ``mutate_cells`` is ``mutate_cell`` in a loop, also
    from a state that keeps half a 32-bit draw (``has_uint32``)."""
    from ant_controller.genome import MAX_EXTENT
    from ant_controller.layout import N_BEHAVIOURS
    from ant_evolution.ga_kernel import mutate_cells

    for seed in range(12):
        genome = random_genome(np.random.default_rng(seed))
        python = np.random.Generator(np.random.PCG64(100 + seed))
        if seed % 2:
            python.integers(0, 5)  # leaves the high half of a 64-bit output kept
        compiled = _twin(python)
        expected = tuple(mutate_cell(python, g, p) for g in genome.cells)
        got = mutate_cells(compiled, genome.cells, p, N_BEHAVIOURS, MAX_EXTENT + 1)
        assert got == expected
        assert compiled.bit_generator.state == python.bit_generator.state
        assert compiled.random() == python.random()


def test_compiled_bounded_integers_follow_numpy_through_rejections():
    """Lemire's method with a bound whose rejections are frequent (3e9 of 2**32)."""
    from ant_evolution.ga_kernel import _integer

    rng = np.random.Generator(np.random.PCG64(7))
    expected = [int(rng.integers(0, 3_000_000_000)) for _ in range(200)]
    raw = np.random.Generator(np.random.PCG64(7)).bit_generator.random_raw(1000)
    cache, pos, got = np.zeros(2, dtype=np.int64), 0, []
    for _ in range(200):
        value, pos = _integer(raw, pos, cache, 3_000_000_000)
        got.append(int(value))
    assert got == expected


def test_a_generation_bred_with_the_compiled_mutation_equals_the_python_one(monkeypatch):
    """``next_generation`` under ``v1``: the same children and the same generator state as
    with the Python loop (the fallback), so checkpoints and histories resume unchanged."""
    import ant_evolution.ga as ga

    rng = np.random.default_rng(4)
    population = [random_genome(rng) for _ in range(12)]
    fitness = rng.random(12)
    params = GAParams(population=12)
    fast = np.random.Generator(np.random.PCG64(9))
    slow = _twin(fast)
    children = next_generation(fast, population, fitness, params)
    monkeypatch.setattr(ga, "mutate_cells", lambda *args: None)
    assert next_generation(slow, population, fitness, params) == children
    assert fast.bit_generator.state == slow.bit_generator.state
