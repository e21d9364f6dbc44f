"""Baselines: network programs (fixed network, NEAT) against plain-Python references."""

from __future__ import annotations

import functools
import json

import numpy as np
import pytest

from ant_controller.layout import N_BEHAVIOURS, SENSOR_SCALE, SENSOR_STATES
from ant_controller.tissue import activation
from ant_evolution.backends import Evaluator
from ant_evolution.baseline_runs import (
    load_program,
    program_from_dict,
    program_to_dict,
    run_fixed,
    run_neat,
)
from ant_evolution.baselines.fixed import (
    FixedTopology,
    compile_fixed,
    crossover,
    mutate,
    random_network,
)
from ant_evolution.baselines.neat_baseline import config_overrides
from ant_evolution.baselines.network import (
    ACT_IDENTITY,
    ACT_SIGMOID,
    AGG_MEAN,
    AGG_SUM,
    GROUP_SEPARATE,
    GROUP_SEPARATE_SUM,
    GROUP_SHARED,
    GROUP_UNION,
    LANES,
    UNION_SLACK,
    NetworkProgram,
    decide_program_reference,
    lane_layout,
    program_decide,
    program_decide_into,
    program_scratch,
    union_rows,
)
from ant_evolution.evaluate import ScenarioSet
from ant_evolution.evolve import EvolveConfig
from ant_evolution.ga import GAParams
from blueprint_server.blueprint import default_blueprint


def _random_codes(rng: np.random.Generator, n: int) -> np.ndarray:
    return np.stack([rng.integers(0, SENSOR_STATES) for _ in range(n)]).astype(np.int64)


def _fixed_program(seed: int):
    rng = np.random.default_rng(seed)
    top = FixedTopology.random(rng)
    return top, compile_fixed(top, random_network(rng, top))


def _neat_programs(
    tmp_path, count: int, hidden: int = 30, seed: int = 7, deep: bool = False, overrides=None
):
    """NEAT programs mutated 5 times; ``deep``: 12 times, each after adding a node on a
    connection (hidden nodes that read hidden nodes). ``overrides``: of the configuration."""
    import neat

    from ant_evolution.baselines.neat_baseline import compile_neat, neat_config

    cfg = neat_config(tmp_path / f"neat-{seed}.ini", count, hidden=hidden, overrides=overrides)
    pop = neat.Population(cfg, seed=seed)
    genomes = list(pop.population.values())[:count]
    # mutate a few times so that topologies differ from the initial full layer
    for g in genomes:
        for _ in range(12 if deep else 5):
            if deep:
                g.mutate_add_node(cfg.genome_config)
            g.mutate(cfg.genome_config)
    return cfg, genomes, [compile_neat(g, cfg) for g in genomes]


@pytest.mark.parametrize("seed", range(4))
def test_fixed_topology_is_within_the_papers_bounds(seed):
    top = FixedTopology.random(np.random.default_rng(seed))
    assert 40 <= top.n_neurons <= 120
    assert 3 <= len(top.layers) + 1 <= 4  # sensor layer + hidden + output layers
    assert top.layers[-1] == N_BEHAVIOURS


@pytest.mark.parametrize("seed", range(3))
def test_fixed_network_kernel_equals_reference(seed):
    _, prog = _fixed_program(seed)
    codes = _random_codes(np.random.default_rng(100 + seed), 300)
    states = set()
    for c in codes:
        ref, values = decide_program_reference(prog, c)
        assert program_decide(c, prog.record()) == ref
        states.add(tuple(values))
    assert len(states) > 1  # the comparison is not between constant networks


def test_fixed_network_reference_is_the_layered_ant_neuron():
    """The reference forward pass recomputed layer by layer with numpy, by hand."""
    rng = np.random.default_rng(3)
    top = FixedTopology((20, 9))
    net = random_network(rng, top)
    prog = compile_fixed(top, net)
    for c in _random_codes(rng, 50):
        s = c * SENSOR_SCALE
        w0 = 0
        n0 = 0
        for size in top.layers:
            fan = s.size
            w = net.weights[w0 : w0 + fan * size].reshape(size, fan)
            den = s.sum()
            sig = (w @ s) / den if den else np.zeros(size)
            s = np.array(
                [
                    activation(int(net.func[n0 + j]), *net.theta[n0 + j], float(sig[j]))
                    for j in range(size)
                ],
                dtype=float,
            )
            w0 += fan * size
            n0 += size
        mask = sum(1 << q for q in range(N_BEHAVIOURS) if s[q] >= 0.5)
        assert decide_program_reference(prog, c)[0] == mask


def test_neat_compiled_equals_neat_python_and_reference(tmp_path):
    import neat

    cfg, genomes, programs = _neat_programs(tmp_path, 6)
    codes = _random_codes(np.random.default_rng(5), 100)
    for g, prog in zip(genomes, programs, strict=True):
        net = neat.nn.FeedForwardNetwork.create(g, cfg)
        for c in codes:
            outs = net.activate([float(c[i]) * float(SENSOR_SCALE[i]) for i in range(len(c))])
            mask = sum(1 << q for q, o in enumerate(outs) if o >= 0.5)
            ref, values = decide_program_reference(prog, c)
            assert ref == mask == program_decide(c, prog.record())
            for q, o in enumerate(prog.out_node):
                if o >= 0:
                    assert values[o] == pytest.approx(outs[q], abs=1e-12)


def _deep_neat_programs(tmp_path, count: int):
    """:func:`_neat_programs` with hidden nodes that read hidden nodes."""
    return _neat_programs(tmp_path, count, hidden=8, seed=11, deep=True)[2]


def _hand_program() -> NetworkProgram:
    """A small program with one group of every kind :func:`lane_layout` makes.

    Nodes 0-2 (sum, sigmoid / identity) read sensors, two of them the same inputs in
    orders that disagree (their merge reads sensor 0 twice): a union group. Nodes 3-4
    read node 2, whose identity activation is unbounded: separate sum nodes. Nodes 5-6
    (mean, modular) read node 4 and different sensors: a separate group; node 7 alone.
    """
    nodes = [  # (aggregation, activation, sources, weights)
        (AGG_SUM, ACT_SIGMOID, [0, 1, 2, 3, 4, 5, 6, 7], [0.5, -1, 2, 0.25, 1, -2, 0.0, 3]),
        (AGG_SUM, ACT_SIGMOID, [1, 0, 2, 3, 4, 5, 6, 7], [1, 1, -1, 0.5, 2, 0.1, -3, 1]),
        (AGG_SUM, ACT_IDENTITY, [2, 9, 5], [4.0, -2.0, 1.5]),
        (AGG_SUM, ACT_SIGMOID, [16, 3], [0.7, -0.2]),
        (AGG_SUM, ACT_SIGMOID, [4, 16, 8], [1.1, 0.3, -0.9]),
        (AGG_MEAN, 2, [18, 10, 11], [0.2, 0.9, -0.4]),
        (AGG_MEAN, 1, [12, 18], [0.6, 0.6]),
        (AGG_MEAN, 3, [14, 19, 20, 13], [0.3, -0.8, 0.5, 1.0]),
    ]
    n = len(nodes)
    counts = [len(src) for _, _, src, _ in nodes]
    return NetworkProgram(
        node_act=np.array([act for _, act, _, _ in nodes], dtype=np.int64),
        node_agg=np.array([agg for agg, _, _, _ in nodes], dtype=np.int64),
        node_bias=np.linspace(-0.5, 0.5, n),
        node_resp=np.linspace(1.5, 0.5, n),
        node_theta=np.stack([np.linspace(-0.2, 0.6, n), np.linspace(0.4, 0.1, n)], axis=1),
        edge_start=np.concatenate(([0], np.cumsum(counts))).astype(np.int64),
        edge_src=np.array([x for *_, src, _ in nodes for x in src], dtype=np.int64),
        edge_w=np.array([x for *_, w in nodes for x in w], dtype=np.float64),
        out_node=np.array([0, 1, 2, 3, 4, 5, 6, 7, -1, 7, 3, 0], dtype=np.int64),
    )


def _layout_programs(tmp_path) -> list[NetworkProgram]:
    """Programs whose layouts between them hold every group kind and group size."""
    programs = _neat_programs(tmp_path, 3)[2] + _deep_neat_programs(tmp_path, 3)
    programs += _neat_programs(tmp_path, 3, seed=5, overrides=config_overrides("modular"))[2]
    return programs + [_fixed_program(s)[1] for s in range(2)] + [_hand_program()]


def test_lane_layout_keeps_every_nodes_inputs_in_order_and_groups_independent(tmp_path):
    n_s = len(SENSOR_SCALE)
    sizes, seen = set(), set()
    for prog in _layout_programs(tmp_path):
        groups, kinds, rows, src, w = lane_layout(
            prog.edge_start, prog.edge_src, prog.edge_w, prog.node_agg, prog.node_act
        )
        pad = n_s + prog.n_nodes
        assert groups[0] == 0 and groups[-1] == prog.n_nodes and np.all(np.diff(groups) >= 1)
        assert src.shape == w.shape == (rows[-1], LANES)
        assert kinds.shape == (len(groups) - 1,)
        for g in range(len(groups) - 1):
            first, last = groups[g], groups[g + 1]
            sizes.add(last - first)
            seen.add(int(kinds[g]))
            ins = [prog.edge_src[prog.edge_start[j] : prog.edge_start[j + 1]]
                   for j in range(first, last)]  # fmt: skip
            ws = [prog.edge_w[prog.edge_start[j] : prog.edge_start[j + 1]]
                  for j in range(first, last)]  # fmt: skip
            g_src, g_w = src[rows[g] : rows[g + 1]], w[rows[g] : rows[g + 1]]
            assert all(x.size == 0 or x.max() < n_s + first for x in ins)  # none in its group
            assert np.all(g_w[:, last - first :] == 0.0)  # lanes without a node add nothing
            same = all(np.array_equal(x, ins[0]) for x in ins)
            sums = bool((prog.node_agg[first:last] == AGG_SUM).all())
            if kinds[g] in (GROUP_SEPARATE, GROUP_SEPARATE_SUM):
                assert kinds[g] == (GROUP_SEPARATE_SUM if sums else GROUP_SEPARATE)
                for lane, (x, wx) in enumerate(zip(ins, ws, strict=True)):
                    assert np.array_equal(g_src[: x.size, lane], x)
                    assert np.array_equal(g_w[: x.size, lane], wx)
                    assert np.all(g_src[x.size :, lane] == pad) and np.all(g_w[x.size :, lane] == 0)
                continue
            assert np.all(g_src == g_src[:, :1])  # one input per row for every lane
            if kinds[g] == GROUP_SHARED:
                assert same and not sums
                for lane, (x, wx) in enumerate(zip(ins, ws, strict=True)):
                    assert np.array_equal(g_src[:, 0], x) and np.array_equal(g_w[:, lane], wx)
                continue
            assert kinds[g] == GROUP_UNION and sums
            assert same or all(s < n_s or prog.node_act[s - n_s] != ACT_IDENTITY
                               for x in ins for s in x)  # fmt: skip
            assert len(g_src) <= UNION_SLACK * max(x.size for x in ins)
            for lane, (x, wx) in enumerate(zip(ins, ws, strict=True)):
                # the node's inputs are the merge's rows in order, its weight 0 elsewhere
                at, k = [], 0
                for r, v in enumerate(g_src[:, 0]):
                    if k < x.size and v == x[k]:
                        at.append(r)
                        k += 1
                assert k == x.size
                assert np.array_equal(g_w[at, lane], wx)
                assert np.all(np.delete(g_w[:, lane], at) == 0.0)
    assert 1 in sizes and LANES in sizes  # deep networks cut groups short, layers fill them
    assert seen == {GROUP_SEPARATE, GROUP_SHARED, GROUP_UNION, GROUP_SEPARATE_SUM}


def test_union_merge_keeps_each_lists_order_when_orders_disagree():
    """Lists cut from one order merge without repeating an input; lists in other orders
    repeat one."""
    w = np.arange(1.0, 12.0)
    merged, weights = union_rows(
        np.array([0, 2, 3, 1, 3, 4, 0, 2, 4, 5, 6]), w, np.array([0, 3, 6, 11]), 20
    )
    assert merged.tolist() == [0, 2, 1, 3, 4, 5, 6]  # [0 2 3], [1 3 4], [0 2 4 5 6]
    assert weights[:, 0].tolist() == [1, 2, 0, 3, 0, 0, 0]
    assert weights[:, 1].tolist() == [0, 0, 4, 5, 6, 0, 0]
    assert weights[:, 2].tolist() == [7, 8, 0, 0, 9, 10, 11] and not weights[:, 3].any()
    merged, weights = union_rows(np.array([0, 1, 2, 1, 0, 2]), w, np.array([0, 3, 6]), 20)
    assert merged.tolist() == [0, 1, 0, 2]
    assert weights[:, 0].tolist() == [1, 2, 0, 3] and weights[:, 1].tolist() == [0, 4, 5, 6]


def test_kernel_node_values_equal_the_sequential_reference_exactly(tmp_path):
    """Summing four nodes side by side changes no value: the kernel's scratch holds the
    reference's node values bit for bit (not only the same masks)."""
    programs = _layout_programs(tmp_path)
    codes = _random_codes(np.random.default_rng(8), 200)
    n_s = len(SENSOR_SCALE)
    for prog in programs:
        record = prog.record()
        scratch = program_scratch(record)
        for c in codes:
            mask = program_decide_into(c, record, scratch)
            ref, values = decide_program_reference(prog, c)
            assert mask == ref
            assert scratch[n_s : n_s + prog.n_nodes].tolist() == values
            assert scratch[-1] == 0.0


def test_batched_kernel_equals_stepping_with_the_reference():
    """The one kernel with a network program: whole episodes agree with Python decisions."""
    _, prog = _fixed_program(11)
    batch = ScenarioSet.create(default_blueprint(1), 3, 3, 60, seed=2)
    scores = batch.score(prog)
    for i in range(batch.size):
        w = batch.world(i)
        for _ in range(batch.steps):
            codes = w.sense()
            w.step([decide_program_reference(prog, codes[k])[0] if w.active[k] else 0
                    for k in range(w.n_robots)])  # fmt: skip
        assert w.fitness() == scores[i]


def test_program_evaluator_is_the_same_for_any_worker_count(tmp_path):
    progs = [_fixed_program(s)[1] for s in range(3)] + _neat_programs(tmp_path, 2)[2]
    sets = [ScenarioSet.create(default_blueprint(d), 2, 2, 40, seed=d) for d in (1, 2)]
    with Evaluator(1) as one, Evaluator(2) as two:
        a = one.evaluate(progs, sets, compile_fn=None)
        b = two.evaluate(progs, sets, compile_fn=None)
    assert np.array_equal(a, b)


@pytest.mark.xdist_group("ray")  # one local Ray instance at a time (--dist loadgroup)
def test_neat_genomes_compiled_here_score_alike_on_every_backend(tmp_path):
    """NEAT genomes compile in the evaluating process, chunk by chunk as the workers start:
    the same fitness in this process, in a pool and on Ray as their programs directly."""
    from ant_evolution.backends import CompileHere
    from ant_evolution.baselines.neat_baseline import compile_neat

    cfg, genomes, progs = _neat_programs(tmp_path, 9)
    here = CompileHere(functools.partial(compile_neat, config=cfg))
    sets = [ScenarioSet.create(default_blueprint(1), 2, 2, 40, seed=5)]
    with Evaluator(1) as one, Evaluator(2) as two:
        direct = one.evaluate(progs, sets, compile_fn=None)
        in_process = one.evaluate(genomes, sets, compile_fn=here)
        pool = two.evaluate(genomes, sets, compile_fn=here)
    assert len(set(direct.tolist())) > 1  # the genomes differ
    for other in (in_process, pool):
        assert np.array_equal(direct, other)
    ray = pytest.importorskip("ray", reason="ray is the optional cluster backend")
    try:
        with Evaluator(workers=2, ray_address="local") as ev:
            on_ray = ev.evaluate(genomes, sets, compile_fn=here)
    finally:
        ray.shutdown()
    assert np.array_equal(direct, on_ray)


def test_ga_operators_keep_shapes_and_are_seeded():
    top = FixedTopology((30, 10))
    rng = np.random.default_rng(0)
    a, b = random_network(rng, top), random_network(rng, top)
    params = GAParams(mutation_prob=0.5)
    c1, c2 = crossover(np.random.default_rng(1), a, b, top)
    d1, _ = crossover(np.random.default_rng(1), a, b, top)
    assert np.array_equal(c1.weights, d1.weights)
    assert c1.weights.shape == a.weights.shape and c2.theta.shape == b.theta.shape
    m = mutate(np.random.default_rng(2), a, params)
    assert not np.array_equal(m.weights, a.weights)
    assert set(np.unique(m.func)) <= {0, 1, 2, 3}


def test_program_file_round_trip_and_errors(tmp_path):
    _, prog = _fixed_program(1)
    path = tmp_path / "p.json"
    path.write_text(json.dumps(program_to_dict(prog, {"fitness": 0.5})))
    back = load_program(path)
    assert all(np.array_equal(x, y) for x, y in zip(prog.record(), back.record(), strict=True))
    bad = program_to_dict(prog)
    del bad["edge_w"]
    with pytest.raises(ValueError, match="edge_w: missing"):
        program_from_dict(bad, "bad.json")
    bad = program_to_dict(prog)
    bad["edge_src"][0] = 10_000
    with pytest.raises(ValueError, match="bad.json: .*node 0 reads a node that comes later"):
        program_from_dict(bad, "bad.json")
    bad = program_to_dict(prog)
    bad["node_theta"] = [[0.1, 0.2, 0.3]]
    with pytest.raises(ValueError, match="bad.json: node_theta: 3 values, not pairs"):
        program_from_dict(bad, "bad.json")


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("node_agg", lambda v: v[:-1], "node_agg must have N"),
        ("node_bias", lambda v: v + [0.0], "node_bias must have N"),
        ("node_theta", lambda v: v[:-2], "node_theta must be N x 2"),
        ("edge_w", lambda v: v[:-1], "edge_src and edge_w must be lists of one length"),
        ("edge_start", lambda v: [v[0] + 1, *v[1:]], "edge_start must rise from 0"),
        ("edge_start", lambda v: [0, v[2], v[1], *v[3:]], "edge_start must rise from 0"),
        ("node_act", lambda v: [9, *v[1:]], "node_act must lie in 0..5"),
        ("node_agg", lambda v: [2, *v[1:]], "node_agg must be 0"),
        ("out_node", lambda v: [len(v) * 1000, *v[1:]], "out_node must lie in -1.."),
        ("edge_src", lambda v: [-3, *v[1:]], "node 0 reads a node that comes later"),
    ],
)
def test_hostile_program_files_are_refused_before_the_kernel(field, value, message):
    """Every array the kernel indexes is checked (it runs without bounds checks)."""
    _, prog = _fixed_program(1)
    bad = program_to_dict(prog)
    bad[field] = value(bad[field])
    with pytest.raises(ValueError, match=f"bad.json: network program: {message}"):
        program_from_dict(bad, "bad.json")


@pytest.mark.parametrize("runner", [run_fixed, run_neat], ids=["fixed", "neat"])
def test_baseline_runs_resume_exactly(tmp_path, runner):
    cfg = EvolveConfig(population=10, generations=4, scenarios=2, steps=30, seed=3,
                       checkpoint_every=2)  # fmt: skip
    whole = runner(cfg, tmp_path / "a")
    runner(cfg, tmp_path / "b", stop_after=1)
    resumed = runner(cfg, tmp_path / "b", resume=True)
    key = [(r["best"], r["mean"], r["evaluations"]) for r in whole]
    assert [(r["best"], r["mean"], r["evaluations"]) for r in resumed] == key
    assert (tmp_path / "b" / "best.json").read_text() == (tmp_path / "a" / "best.json").read_text()


def test_neat_resume_keeps_the_node_indexer(tmp_path):
    """Restored with its pickled config, new node keys never collide with existing ones."""
    import copy

    import neat

    cfg = EvolveConfig(population=12, generations=3, scenarios=1, steps=10, seed=2)
    run_neat(cfg, tmp_path, stop_after=2)
    pop = neat.Checkpointer.restore_checkpoint(str(tmp_path / "neat-checkpoint.gz"))
    genome_config = pop.config.genome_config
    used = {key for genome in pop.population.values() for key in genome.nodes}
    added = []
    # lowest keys first: a restarted indexer would begin inside the next genome's keys
    for genome in sorted(pop.population.values(), key=lambda g: max(g.nodes)):
        assert genome.connections  # mutate_add_node splits one: it adds a node
        child = copy.deepcopy(genome)
        child.mutate_add_node(genome_config)
        new = set(child.nodes) - set(genome.nodes)
        assert len(new) == 1 and set(genome.nodes) <= set(child.nodes), (genome.key, new)
        added += new
    assert not used & set(added), sorted(used & set(added))  # no key of any genome reused
    assert len(set(added)) == len(added)  # nor one given twice


# --- NEAT: the numpy compile and the linear-time crossover give neat-python's results ---------


def _evolved_neat_genomes(
    tmp_path, genome_type, generations: int = 3, count: int = 12, overrides: dict | None = None
):
    """A small NEAT population after a few generations of a made-up fitness (varied
    topologies: added and deleted nodes and connections, disabled connections);
    ``overrides``: :func:`config_overrides`' arguments."""
    import neat

    from ant_evolution.baselines.neat_baseline import config_overrides, neat_config

    tmp_path.mkdir(parents=True, exist_ok=True)
    keys = config_overrides(**overrides) if overrides else None
    cfg = neat_config(tmp_path / "neat.ini", count, hidden=20, overrides=keys)
    cfg.genome_type = genome_type
    if genome_type is neat.DefaultGenome:  # the library's genes too: a reference of its own
        cfg.genome_config.connection_gene_type = neat.genes.DefaultConnectionGene
    cfg.genome_config.node_add_prob = 0.6
    cfg.genome_config.conn_delete_prob = 0.6
    pop = neat.Population(cfg, seed=11)

    def fitness(genomes, _config) -> None:
        for key, g in genomes:
            g.fitness = float((key * 7919) % 101) + 0.01 * len(g.connections)

    pop.run(fitness, generations)
    return cfg, list(pop.population.values())


def test_neat_compile_gives_neat_pythons_network_exactly(tmp_path):
    """Every node value of the compiled program equals neat-python's ``activate`` output
    bit for bit, on random inputs, for genomes with grown and pruned topologies."""
    import neat

    from ant_evolution.baselines.neat_baseline import NeatGenome, compile_neat

    cfg, genomes = _evolved_neat_genomes(tmp_path / "evolved", NeatGenome)
    assert any(not cg.enabled for g in genomes for cg in g.connections.values())
    initial_cfg, initial, _ = _neat_programs(tmp_path, 3)  # the full initial topology too
    codes = _random_codes(np.random.default_rng(9), 60)
    for cfg, g in [(cfg, g) for g in genomes] + [(initial_cfg, g) for g in initial]:
        prog = compile_neat(g, cfg)
        net = neat.nn.FeedForwardNetwork.create(g, cfg)
        assert prog.n_nodes == len(net.node_evals)
        assert prog.n_edges == sum(len(links) for *_, links in net.node_evals)
        for c in codes:
            outs = net.activate([float(c[i]) * float(SENSOR_SCALE[i]) for i in range(len(c))])
            mask, values = decide_program_reference(prog, c)
            assert [values[o] for o in prog.out_node] == outs  # exactly, not approximately
            assert program_decide(c, prog.record()) == mask


@pytest.mark.parametrize(
    "overrides",
    [
        {},
        {"activation": "modular", "budget": "ant", "perturb": True},
        {"activation": "modular", "budget": "ant", "perturb": False, "mutation_prob": 0.3},
    ],
    ids=["v1", "paper", "paper-redraw"],
)
def test_neat_genome_crossover_equals_neat_pythons(tmp_path, overrides):
    """NeatGenome's reproduction (crossover, mutation, distance) gives neat-python's
    children: same genes, same draws, under both profiles' configurations (v1 redraws a
    weight from a normal distribution, ``paper-redraw`` from a uniform one)."""
    import neat

    from ant_evolution.baselines.neat_baseline import NeatGenome

    def genes(genomes):
        return [
            (
                sorted((k, c.weight, c.enabled, c.innovation) for k, c in g.connections.items()),
                sorted((k, n.bias, n.response) for k, n in g.nodes.items()),
            )
            for g in genomes
        ]

    _, ours = _evolved_neat_genomes(tmp_path / "a", NeatGenome, 4, overrides=overrides)
    _, theirs = _evolved_neat_genomes(tmp_path / "b", neat.DefaultGenome, 4, overrides=overrides)
    assert genes(ours) == genes(theirs)


def test_compiled_random_draws_are_the_random_modules_own():
    """pyrandom's random() and gauss() from the module's state: the module's values, and
    the state it leaves (a cached gauss value included) is the module's own."""
    import random

    from ant_evolution.baselines.pyrandom import draws, put_state, take_state

    random.seed(2024)
    kinds = np.random.default_rng(4).integers(0, 2, 3001)  # odd: ends with gauss cached
    for _ in range(2):  # 3,001 draws run the generator's 624-word refill several times
        state = take_state()
        ours = draws(*state, kinds)
        theirs = [random.random() if k == 0 else random.gauss(0.5, 2.0) for k in kinds]
        assert ours.tolist() == theirs
        after = random.getstate()
        put_state(*state)
        assert random.getstate() == after


def test_neat_config_reads_single_structural_mutation_as_false(tmp_path):
    """neat-python 2.0.0 returns an unset boolean option as its default string 'false'
    (true in an ``if``): the run's neat.ini sets it, so each structural mutation is drawn
    on its own with its configured rate."""
    from ant_evolution.baselines.neat_baseline import config_overrides, neat_config

    for overrides in (None, config_overrides("modular", "ant")):
        cfg = neat_config(tmp_path / "neat.ini", 10, hidden=5, overrides=overrides)
        assert cfg.genome_config.single_structural_mutation is False
