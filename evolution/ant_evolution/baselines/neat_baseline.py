"""NEAT (neat-python 2.0) on the excavation task, compiled to network programs (paper, 5).

neat-python does the whole NEAT algorithm (genomes, speciation, reproduction); this module
gives it a configuration with the excavation task's 14 sensor inputs and 12 behaviour
outputs, an initial topology of 40 to 120 neurons (hidden plus output, drawn once per run
from the run's seed), and a fitness function that compiles every genome with neat-python's
own ``FeedForwardNetwork.create`` into a :class:`~.network.NetworkProgram` and scores it
on the same scenarios and the same batched kernel path as the fixed network.

Two switches of the run's profile (:mod:`ant_evolution.profiles`) make the comparison like
for like:

* ``neat_activation``: ``"sigmoid"`` (``v1``): neat-python's ``sum`` aggregation and
  ``sigmoid`` activation, behaviour q fires when output q is at least 0.5 (the sigmoid's
  midpoint). ``"modular"`` (``paper``): the neuron of ANT and of the fixed networks, the
  weighted mean of the inputs and the modular activation function (section 3.3, "the
  transfer function used is the modular activation function"): the four functions
  (``k1, k2``) are neat-python activation options that mutate like any other, the node's
  bias is ``theta1`` and its response ``theta2``, and weights, bias and response live in
  ``[-1, 1]`` as ANT's parameters do.
* ``neat_budget``: ``"library"`` (``v1``): neat-python's usual rates (80 % of the weights
  perturbed per offspring, a node added with p = 0.2, a connection with 0.5). ``"ant"``
  (``paper``): ANT's budget: each weight, bias, response and activation mutates with the
  run's ``mutation_prob`` (perturbed when ``mutation_operator`` is ``perturb``, redrawn
  otherwise), structural additions and deletions with p = 0.05 (the mean of ANT's cell
  replication probability, uniform in 0..0.1), and the run's ``elitism``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ant_controller.layout import N_BEHAVIOURS, N_SENSORS
from ant_evolution.baselines.network import (
    ACT_IDENTITY,
    ACT_SIGMOID,
    AGG_MEAN,
    AGG_SUM,
    NetworkProgram,
)

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


def modular_down(z: float) -> float:
    """neat-python activation option ``modular_down`` (k1 = 0, k2 = 0); compiled, never run."""
    return z


def modular_up(z: float) -> float:
    """neat-python activation option ``modular_up`` (k1 = 0, k2 = 1); compiled, never run."""
    return z


def modular_ditch(z: float) -> float:
    """neat-python activation option ``modular_ditch`` (k1 = 1, k2 = 0); compiled, never run."""
    return z


def modular_mound(z: float) -> float:
    """neat-python activation option ``modular_mound`` (k1 = 1, k2 = 1); compiled, never run."""
    return z


MODULAR = (modular_down, modular_up, modular_ditch, modular_mound)
"""The modular activation's four functions, index = ``k1 * 2 + k2`` (the kernel's code)."""
STRUCTURE_PROB = 0.05
"""``neat_budget = "ant"``: probability of each structural mutation per offspring."""


def config_overrides(
    activation: str = "sigmoid",
    budget: str = "library",
    mutation_prob: float = 0.025,
    perturb: bool = False,
    width: float = 0.1,
    elitism: int = 2,
) -> dict[str, str]:
    """Keys of :data:`NEAT_CONFIG_TEMPLATE` that the two switches change (module docstring)."""
    out: dict[str, str] = {}
    if activation == "modular":
        names = " ".join(f.__name__ for f in MODULAR)
        out.update(
            activation_default="random",
            activation_options=names,
            activation_mutate_rate="0.1",
            bias_init_type="uniform",
            bias_init_mean="0.0",
            bias_init_stdev="0.5",
            bias_max_value="1.0",
            bias_min_value="-1.0",
            response_init_type="uniform",
            response_init_mean="0.0",
            response_init_stdev="0.5",
            response_max_value="1.0",
            response_min_value="-1.0",
            response_mutate_power="0.5",
            response_mutate_rate="0.7",
            response_replace_rate="0.1",
            weight_init_type="uniform",
            weight_init_stdev="0.5",
            weight_max_value="1.0",
            weight_min_value="-1.0",
        )
    elif activation != "sigmoid":
        raise ValueError(f"neat_activation {activation!r}: must be sigmoid or modular")
    if budget == "ant":
        p = f"{mutation_prob:g}"
        power = f"{2.0 * width / 1.7320508:g}"  # the stdev of U(-w, w) times the range 2
        mutate, replace = (p, "0.0") if perturb else ("0.0", p)
        for gene in ("bias", "response", "weight"):
            out[f"{gene}_mutate_rate"] = mutate
            out[f"{gene}_replace_rate"] = replace
            out[f"{gene}_mutate_power"] = power
        if activation == "modular":
            out["activation_mutate_rate"] = p
        else:  # the sigmoid's response stays 1, as in the library budget
            out.update(response_mutate_rate="0.0", response_replace_rate="0.0")
        out.update(
            enabled_mutate_rate=p,
            conn_add_prob=f"{STRUCTURE_PROB:g}",
            conn_delete_prob=f"{STRUCTURE_PROB:g}",
            node_add_prob=f"{STRUCTURE_PROB:g}",
            node_delete_prob=f"{STRUCTURE_PROB:g}",
            elitism=str(elitism),
        )
    elif budget != "library":
        raise ValueError(f"neat_budget {budget!r}: must be library or ant")
    return out


def neat_config_text(population: int, hidden: int, overrides: dict[str, str] | None = None) -> str:
    """The run's ``neat.ini``: the template with ``overrides`` (``key = value`` lines)."""
    text = NEAT_CONFIG_TEMPLATE.format(
        population=population, inputs=N_SENSORS, outputs=N_BEHAVIOURS, hidden=hidden
    )
    lines = []
    for line in text.splitlines():
        key = line.split("=", 1)[0].strip()
        if "=" in line and key in (overrides or {}):
            line = f"{key.ljust(23)} = {overrides[key]}"
        lines.append(line)
    return "\n".join(lines) + "\n"


def neat_config(path: Path, population: int, hidden: int, overrides: dict[str, str] | None = None):
    """Write the run's neat-python configuration to ``path`` and load it."""
    import neat

    path.write_text(neat_config_text(population, hidden, overrides), encoding="utf-8")
    config = neat.Config(
        neat.DefaultGenome,
        neat.DefaultReproduction,
        neat.DefaultSpeciesSet,
        neat.DefaultStagnation,
        str(path),
    )
    for f in MODULAR:
        config.genome_config.add_activation(f.__name__, f)
    return config


def compile_neat(genome, config) -> NetworkProgram:
    """The network program of a neat-python genome (via ``FeedForwardNetwork.create``).

    Input key ``-1 - i`` is sensor i; output key q is behaviour q. Nodes keep the order
    neat-python evaluates them in; outputs neat-python never evaluates stay 0 (never fire).
    A node with one of the :data:`MODULAR` activations becomes ANT's neuron (weighted mean,
    modular activation with ``theta1`` = bias, ``theta2`` = response).
    """
    import neat
    from neat.activations import identity_activation, sigmoid_activation
    from neat.aggregations import sum_aggregation

    net = neat.nn.FeedForwardNetwork.create(genome, config)
    index: dict[int, int] = {}
    act, agg, theta, bias, resp, starts, srcs, ws = [], [], [], [], [], [0], [], []
    for node, act_f, agg_f, b, r, links in net.node_evals:
        if agg_f is not sum_aggregation:
            raise ValueError(f"NEAT node {node}: only the sum aggregation compiles")
        modular = next((i for i, f in enumerate(MODULAR) if f.__name__ == act_f.__name__), -1)
        agg.append(AGG_MEAN if modular >= 0 else AGG_SUM)
        theta.append((b, r) if modular >= 0 else (0.0, 0.0))
        if modular >= 0:
            act.append(modular)
        elif act_f is sigmoid_activation:
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
        node_agg=np.asarray(agg, dtype=np.int64).reshape(n),
        node_bias=np.asarray(bias, dtype=np.float64),
        node_resp=np.asarray(resp, dtype=np.float64),
        node_theta=np.asarray(theta, dtype=np.float64).reshape(n, 2),
        edge_start=np.asarray(starts, dtype=np.int64),
        edge_src=np.asarray(srcs, dtype=np.int64),
        edge_w=np.asarray(ws, dtype=np.float64),
        out_node=out,
    )
