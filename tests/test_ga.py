"""Genetic operators: mutation, replication, crossover, selection."""

from __future__ import annotations

import dataclasses
import json

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


@pytest.mark.parametrize("scope", ["gene", "parameter"])
@pytest.mark.parametrize("operator", ["redraw", "perturb"])
@pytest.mark.parametrize("p", [0.025, 0.3, 1.0])
def test_compiled_slot_mutation_gives_the_python_loops_genes_and_generator_state(
    monkeypatch, scope, operator, p
):
    """``mutate_by_slots`` is ``_mutate_slots``' cell loop, gene for gene and state for
    state, also from a state that keeps half a 32-bit draw and with blocks of raw draws
    that run short (drawn again from the same state)."""
    import ant_evolution.ga as ga
    from ant_evolution import ga_kernel

    params = GAParams(mutation_prob=p, mutation_scope=scope, mutation_operator=operator)
    for seed in range(8):
        if seed >= 6:  # short blocks: every genome runs out at least once
            monkeypatch.setattr(ga_kernel, "_on_raw_outputs", _short_blocks(ga_kernel))
        genome = random_genome(np.random.default_rng(seed))
        python = np.random.Generator(np.random.PCG64(200 + seed))
        if seed % 2:
            python.integers(0, 5)  # leaves the high half of a 64-bit output kept
        compiled = _twin(python)
        changes = {}
        for i, g in enumerate(genome.cells):
            slots = ga._chosen_slots(python, len(ga._CELL_SLOTS), params)
            if slots:
                changes[i] = ga._mutate_gene_slots(python, g, slots, params)
        expected = tuple(changes.get(i, g) for i, g in enumerate(genome.cells))
        got = ga_kernel.mutate_by_slots(
            compiled, genome.cells, p, ga._CELL_SLOTS, scope, operator, params.mutation_width
        )
        assert got == expected
        assert json.dumps([dataclasses.asdict(g) for g in got]) == json.dumps(
            [dataclasses.asdict(g) for g in expected]
        )
        assert compiled.bit_generator.state == python.bit_generator.state
        assert compiled.random() == python.random()
        monkeypatch.undo()


def _short_blocks(ga_kernel):
    real = ga_kernel._on_raw_outputs

    def short(rng, parent, block, kernel, *args):
        return real(rng, parent, 8, kernel, *args)

    return short


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


# --- breeding on packed genes (ant_evolution.ga_kernel.PackedCells) ------------------------


def _python_only(monkeypatch):
    """Breeding without the compiled mutation or the array crossover (the specification)."""
    import ant_evolution.ga as ga

    monkeypatch.setattr(ga, "mutate_cells", lambda *args: None)
    monkeypatch.setattr(ga, "mutate_by_slots", lambda *args: None)
    monkeypatch.setattr(ga, "crossover_packed", lambda *args: None)


def _assert_packed_agrees(genome: Genome) -> None:
    """A packed genome's arrays are its genes' values (packed afresh from plain genes)."""
    from ant_evolution.ga_kernel import PackedCells, packed

    cells = genome.cells
    assert isinstance(cells, PackedCells)
    fresh = packed(tuple(cells))
    for name in ("scalars", "sensors", "inputs"):
        assert np.array_equal(getattr(cells, name), getattr(fresh, name)), name
    for name in ("positions", "keys", "order", "sorted_keys", "low", "high"):
        assert np.array_equal(getattr(cells.sites, name), getattr(fresh.sites, name)), name


@pytest.mark.parametrize("mutation_prob", [0.025, 0.2])
def test_generations_bred_on_packed_genes_equal_the_python_ones(monkeypatch, mutation_prob):
    """Eight ``v1`` generations (crossover, mutation, replication, elitism) with the packed
    fast paths give the children and generator states of the Python operators, and every
    packed child's arrays agree with its genes."""
    rng = np.random.default_rng(11)
    start = [random_genome(rng, n_neurons=(20, 60)) for _ in range(14)]
    # replication often, so that daughters are appended to packed genes too
    start = [
        dataclasses.replace(g, tissue=dataclasses.replace(g.tissue, replication_probability=0.5))
        for g in start
    ]
    params = GAParams(population=14, mutation_prob=mutation_prob)
    fast_rng = np.random.Generator(np.random.PCG64(21))
    slow_rng = _twin(fast_rng)
    fast, fitness_rng = start, np.random.default_rng(5)
    fitnesses = [fitness_rng.random(14) for _ in range(8)]
    for fitness in fitnesses:
        fast = next_generation(fast_rng, fast, fitness, params)
        for g in fast:
            if not any(g is s for s in start):  # an elite of generation 0 stays plain
                _assert_packed_agrees(g)
    _python_only(monkeypatch)
    slow = start
    for fitness in fitnesses:
        slow = next_generation(slow_rng, slow, fitness, params)
    assert fast == slow
    assert fast_rng.bit_generator.state == slow_rng.bit_generator.state
    for a, b in zip(fast, slow, strict=True):  # type for type: the same genome file
        assert json.dumps(genome_to_dict(a)) == json.dumps(genome_to_dict(b))


@pytest.mark.parametrize(
    "readings",
    [
        {"mutation_scope": "gene", "mutation_operator": "perturb"},  # the paper profile
        {"mutation_scope": "gene", "mutation_operator": "redraw"},
        {"mutation_scope": "parameter", "mutation_operator": "perturb"},
    ],
)
@pytest.mark.parametrize("compiled", [True, False])
def test_slot_mutation_on_packed_genes_equals_the_python_one(monkeypatch, readings, compiled):
    """Mutation by parameter slots (``paper``'s readings), compiled or in Python on packed
    genes, packs its children too: eight generations give the Python operators' children,
    draws and genome files."""
    import ant_evolution.ga as ga
    from ant_evolution.ga_kernel import PackedCells

    if not compiled:
        monkeypatch.setattr(ga, "mutate_by_slots", lambda *args: None)

    rng = np.random.default_rng(15)
    start = [random_genome(rng, n_neurons=(20, 60)) for _ in range(14)]
    start = [
        dataclasses.replace(g, tissue=dataclasses.replace(g.tissue, replication_probability=0.5))
        for g in start
    ]
    params = GAParams(
        population=14, mutation_prob=0.2, replication_parent="proportional", **readings
    )
    fast_rng = np.random.Generator(np.random.PCG64(22))
    slow_rng = _twin(fast_rng)
    fitnesses = [np.random.default_rng(6 + k).random(14) for k in range(8)]
    fast = start
    for fitness in fitnesses:
        fast = next_generation(fast_rng, fast, fitness, params)
    assert sum(isinstance(g.cells, PackedCells) for g in fast) >= 10
    for g in fast:
        if isinstance(g.cells, PackedCells):
            _assert_packed_agrees(g)
    _python_only(monkeypatch)
    monkeypatch.setattr(
        ga, "with_genes", lambda cells, ch: tuple(ch.get(i, g) for i, g in enumerate(cells))
    )
    slow = start
    for fitness in fitnesses:
        slow = next_generation(slow_rng, slow, fitness, params)
    assert not any(isinstance(g.cells, PackedCells) for g in slow)
    assert fast == slow
    assert fast_rng.bit_generator.state == slow_rng.bit_generator.state
    for a, b in zip(fast, slow, strict=True):
        assert json.dumps(genome_to_dict(a)) == json.dumps(genome_to_dict(b))


def test_packed_crossover_matches_python_across_seeds_and_repressed_genes(monkeypatch):
    """Parents whose tissue seeds differ and whose genes are partly repressed: the array
    crossover exchanges the genes the Python one does, with the same draws."""
    from ant_evolution.ga_kernel import crossover_packed, packed

    rng = np.random.default_rng(12)
    for trial in range(40):
        a = random_genome(rng, n_neurons=(10, 80))
        b = random_genome(rng, n_neurons=(10, 80))
        b = dataclasses.replace(
            b,
            tissue=dataclasses.replace(b.tissue, seed=(int(trial % 3) - 1, 0, 1)),
            cells=tuple(
                dataclasses.replace(c, expressed=bool(i % 4)) for i, c in enumerate(b.cells)
            ),
        )
        pa = dataclasses.replace(a, cells=packed(a.cells))
        pb = dataclasses.replace(b, cells=packed(b.cells))
        fast_rng = np.random.Generator(np.random.PCG64(trial))
        slow_rng = _twin(fast_rng)
        fast = crossover_packed(fast_rng, pa, pb)
        _python_only(monkeypatch)
        slow = crossover(slow_rng, a, b)
        monkeypatch.undo()
        assert fast == slow
        assert fast_rng.bit_generator.state == slow_rng.bit_generator.state
        for child in fast:
            if child is not pa and child is not pb:
                _assert_packed_agrees(child)


def test_a_short_block_of_draws_is_drawn_again_from_the_same_state(monkeypatch):
    """When the raw outputs run short the mutation starts over from the parent's genes with
    a larger block (nothing of the short attempt stays in the child)."""
    from ant_controller.genome import MAX_EXTENT
    from ant_controller.layout import N_BEHAVIOURS
    from ant_evolution import ga_kernel

    monkeypatch.setattr(ga_kernel, "_block_size", lambda n, n_s, n_i: 40)
    for seed in range(6):
        genome = random_genome(np.random.default_rng(seed))
        python = np.random.Generator(np.random.PCG64(300 + seed))
        compiled = _twin(python)
        expected = tuple(mutate_cell(python, g, 0.3) for g in genome.cells)
        got = ga_kernel.mutate_cells(compiled, genome.cells, 0.3, N_BEHAVIOURS, MAX_EXTENT + 1)
        assert got == expected
        assert compiled.bit_generator.state == python.bit_generator.state


def test_packed_genes_read_compare_and_pickle_as_the_plain_tuple():
    """A packed genome is its genes to every reader: equal and hashing as the plain tuple,
    indexed, sliced and iterated alike, the same genome file; it pickles as its arrays and
    a worker builds the same genes from them."""
    import pickle

    from ant_evolution.ga_kernel import PackedCells, packed

    g = random_genome(np.random.default_rng(13))
    p = dataclasses.replace(g, cells=packed(g.cells))
    assert isinstance(p.cells, PackedCells) and p == g and g == p
    assert hash(p) == hash(g) and hash(p.cells) == hash(g.cells)
    assert p.cells[-1] is g.cells[-1] and p.cells[2:5] == g.cells[2:5]
    assert list(p.cells) == list(g.cells) and len(p.cells) == len(g.cells)
    back = pickle.loads(pickle.dumps(p))
    assert isinstance(back.cells, PackedCells)
    assert all(x is None for x in back.cells._genes)  # built when first read
    assert back.cells[3] == g.cells[3] and back.cells._genes[3] is not None
    assert back == g
    assert json.dumps(genome_to_dict(back)) == json.dumps(genome_to_dict(g))  # types too
    assert not back.cells.scalars.flags.writeable  # children copy; parents never change
    with pytest.raises(IndexError):
        p.cells[len(g.cells)]
    # genes that share a site, differ in vector length or are not of the canonical
    # types stay plain (the Python operators handle them)
    twin = dataclasses.replace(g.cells[1], position=g.cells[0].position)
    assert packed((g.cells[0], twin)) is None
    short = dataclasses.replace(g.cells[1], sensor_weights=g.cells[1].sensor_weights[:3])
    assert packed((g.cells[0], short)) is None
    for odd in ({"theta1": 1}, {"k1": True}, {"sensor_weights": (np.float64(0.5),) * 14}):
        assert packed((g.cells[0], dataclasses.replace(g.cells[1], **odd))) is None
    assert packed((g.cells[0], dataclasses.replace(g.cells[1], theta1=float("inf")))) is None


def test_a_generation_bred_on_packed_genes_builds_no_gene_objects():
    """Mutation and crossover write rows: the changed genes are built only when read."""
    rng = np.random.default_rng(14)
    population = [random_genome(rng) for _ in range(10)]
    params = GAParams(population=10)
    gen_rng = np.random.Generator(np.random.PCG64(3))
    for _ in range(2):
        population = next_generation(gen_rng, population, rng.random(10), params)
    unbuilt = sum(x is None for g in population for x in getattr(g.cells, "_genes", ()))
    assert unbuilt > 0.3 * sum(len(g.cells) for g in population)


def test_tournament_reads_lists_and_arrays_alike_with_numpy_ties_and_nan():
    fitness = np.array([0.5, 0.9, 0.9, np.nan, 0.1, 0.9])
    for seed in range(50):
        a = tournament(np.random.default_rng(seed), fitness, 3)
        b = tournament(np.random.default_rng(seed), fitness.tolist(), 3)
        picks = np.sort(np.random.default_rng(seed).choice(6, size=3, replace=False))
        assert a == b == int(picks[np.argmax(fitness[picks])])
