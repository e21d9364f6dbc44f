"""NEAT (neat-python 2.0) on the excavation task, compiled to network programs (paper, 5).

neat-python does the whole NEAT algorithm (genomes, speciation, reproduction); this module
gives it a configuration with the excavation task's 14 sensor inputs and 12 behaviour
outputs, an initial topology of 40 to 120 neurons (hidden plus output, drawn once per run
from the run's seed), and a fitness function that compiles every genome with neat-python's
own ``FeedForwardNetwork.create`` into a :class:`~.network.NetworkProgram` and scores it
on the same scenarios and the same batched kernel path as the fixed network.

Nodes use neat-python's ``sum`` aggregation and ``sigmoid`` activation; behaviour q fires
when output q is at least 0.5 (the sigmoid's midpoint).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ant_controller.layout import N_BEHAVIOURS, N_SENSORS
from ant_evolution.baselines.network import ACT_IDENTITY, ACT_SIGMOID, AGG_SUM, NetworkProgram

NEAT_CONFIG_TEMPLATE = """\
[NEAT]
fitness_criterion     = max
fitness_threshold     = 1.0
no_fitness_termination = True
pop_size              = {population}
reset_on_extinction   = True

[DefaultGenome]
num_inputs              = {inputs}
num_outputs             = {outputs}
num_hidden              = {hidden}
feed_forward            = True
initial_connection      = full_nodirect
activation_default      = sigmoid
activation_mutate_rate  = 0.0
activation_options      = sigmoid
aggregation_default     = sum
aggregation_mutate_rate = 0.0
aggregation_options     = sum
bias_init_mean          = 0.0
bias_init_stdev         = 1.0
bias_init_type          = gaussian
bias_max_value          = 30.0
bias_min_value          = -30.0
bias_mutate_power       = 0.5
bias_mutate_rate        = 0.7
bias_replace_rate       = 0.1
compatibility_disjoint_coefficient = 1.0
compatibility_weight_coefficient   = 0.5
conn_add_prob           = 0.5
conn_delete_prob        = 0.5
enabled_default         = True
enabled_mutate_rate     = 0.01
node_add_prob           = 0.2
node_delete_prob        = 0.2
response_init_mean      = 1.0
response_init_stdev     = 0.0
response_init_type      = gaussian
response_max_value      = 30.0
response_min_value      = -30.0
response_mutate_power   = 0.0
response_mutate_rate    = 0.0
response_replace_rate   = 0.0
weight_init_mean        = 0.0
weight_init_stdev       = 1.0
weight_init_type        = gaussian
weight_max_value        = 30
weight_min_value        = -30
weight_mutate_power     = 0.5
weight_mutate_rate      = 0.8
weight_replace_rate     = 0.1

[DefaultSpeciesSet]
compatibility_threshold = 4.0

[DefaultStagnation]
species_fitness_func = max
max_stagnation       = 20
species_elitism      = 2

[DefaultReproduction]
elitism            = 2
survival_threshold = 0.2
min_species_size   = 1
"""


def neat_hidden(seed: int, neurons: tuple[int, int]) -> int:
    """Initial hidden nodes of a run: neurons (hidden + outputs) uniform in ``neurons``."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0x4EA7]))
    return max(0, int(rng.integers(neurons[0], neurons[1] + 1)) - N_BEHAVIOURS)


def neat_config(path: Path, population: int, hidden: int):
    """Write the run's neat-python configuration to ``path`` and load it."""
    import neat

    path.write_text(
        NEAT_CONFIG_TEMPLATE.format(
            population=population, inputs=N_SENSORS, outputs=N_BEHAVIOURS, hidden=hidden
        ),
        encoding="utf-8",
    )
    return neat.Config(
        neat.DefaultGenome,
        neat.DefaultReproduction,
        neat.DefaultSpeciesSet,
        neat.DefaultStagnation,
        str(path),
    )


def compile_neat(genome, config) -> NetworkProgram:
    """The network program of a neat-python genome (via ``FeedForwardNetwork.create``).

    Input key ``-1 - i`` is sensor i; output key q is behaviour q. Nodes keep the order
    neat-python evaluates them in; outputs neat-python never evaluates stay 0 (never fire).
    """
    import neat
    from neat.activations import identity_activation, sigmoid_activation
    from neat.aggregations import sum_aggregation

    net = neat.nn.FeedForwardNetwork.create(genome, config)
    index: dict[int, int] = {}
    act, bias, resp, starts, srcs, ws = [], [], [], [0], [], []
    for node, act_f, agg_f, b, r, links in net.node_evals:
        if agg_f is not sum_aggregation:
            raise ValueError(f"NEAT node {node}: only the sum aggregation compiles")
        if act_f is sigmoid_activation:
            act.append(ACT_SIGMOID)
        elif act_f is identity_activation:
            act.append(ACT_IDENTITY)
        else:
            raise ValueError(f"NEAT node {node}: only sigmoid and identity activations compile")
        for i, w in links:
            srcs.append(-1 - i if i < 0 else N_SENSORS + index[i])
            ws.append(w)
        starts.append(len(srcs))
        bias.append(b)
        resp.append(r)
        index[node] = len(act) - 1
    n = len(act)
    out = np.array([index.get(q, -1) for q in config.genome_config.output_keys], dtype=np.int64)
    return NetworkProgram(
        node_act=np.asarray(act, dtype=np.int64),
        node_agg=np.full(n, AGG_SUM, dtype=np.int64),
        node_bias=np.asarray(bias, dtype=np.float64),
        node_resp=np.asarray(resp, dtype=np.float64),
        node_theta=np.zeros((n, 2)),
        edge_start=np.asarray(starts, dtype=np.int64),
        edge_src=np.asarray(srcs, dtype=np.int64),
        edge_w=np.asarray(ws, dtype=np.float64),
        out_node=out,
    )
