"""NEAT (neat-python 2.0) on the excavation task, compiled to network programs (paper, 5).

neat-python does the whole NEAT algorithm (genomes, speciation, reproduction); this module
gives it a configuration with the excavation task's 14 sensor inputs and 12 behaviour
outputs, an initial topology of 40 to 120 neurons (hidden plus output, drawn once per run
from the run's seed), and a fitness function that compiles every genome into a
:class:`~.network.NetworkProgram` (:func:`compile_neat`: the network neat-python's
``FeedForwardNetwork.create`` builds, computed with numpy) and scores it on the same
scenarios and the same batched kernel path as the fixed network.

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

:class:`NeatGenome` is neat-python's ``DefaultGenome`` with changes that leave every
result as it was: crossover's check that an inherited connection closes no cycle, which
the library does by rescanning every connection of the child (quadratic: about 0.1 s per
child of 1,600 connections, most of a generation), is answered once per child from the
fitter parent's graph instead, with the same answers; the connection genes' copy and
crossover are written out with the library's random draws, and their mutation runs as one
compiled loop that draws from the ``random`` module's own generator state
(:mod:`.pyrandom`). Children, random draws and runs are unchanged.
"""

from __future__ import annotations

import random
import warnings
import weakref
from itertools import chain
from operator import attrgetter
from pathlib import Path

import neat
import numba as nb
import numpy as np
from neat.genes import DefaultConnectionGene

from ant_controller.layout import N_BEHAVIOURS, N_SENSORS
from ant_evolution.baselines.network import (
    ACT_IDENTITY,
    ACT_SIGMOID,
    AGG_MEAN,
    AGG_SUM,
    NetworkProgram,
)
from ant_evolution.baselines.pyrandom import gauss, put_state, take_state, uniform01

NEAT_CONFIG_TEMPLATE = """\
[NEAT]
fitness_criterion     = max
fitness_threshold     = 1.0
no_fitness_termination = True
pop_size              = {population}
reset_on_extinction   = True

[{genome_section}]
num_inputs              = {inputs}
num_outputs             = {outputs}
num_hidden              = {hidden}
feed_forward            = True
single_structural_mutation = false
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


class NeatConnectionGene(DefaultConnectionGene):
    """neat-python's connection gene with ``copy``, ``crossover`` and ``mutate`` inlined.

    The three are written out for the gene's two attributes (weight, enabled). Each makes
    the library's random draws in the library's order (``neat/genes.py`` and
    ``neat/attributes.py`` of neat-python 2.0.0: ``FloatAttribute`` and ``BoolAttribute``)
    and gives the same gene; only the per-attribute ``getattr`` / ``setattr`` loops are
    gone. NEAT copies and mutates every connection of every child, about 1,600 per
    genome here, so these three are most of a generation's reproduction.
    """

    def copy(self):
        """A copy of this gene."""
        new = NeatConnectionGene.__new__(self.__class__)
        new.key = self.key
        new.innovation = self.innovation
        new.weight = self.weight
        new.enabled = self.enabled
        return new

    def crossover(self, gene2):
        """Each attribute from either parent at random; the NEAT paper's 75 % disable rule."""
        assert self.key == gene2.key and self.innovation == gene2.innovation
        new = NeatConnectionGene.__new__(self.__class__)
        new.key = self.key
        new.innovation = self.innovation
        new.weight = self.weight if random.random() > 0.5 else gene2.weight
        new.enabled = self.enabled if random.random() > 0.5 else gene2.enabled
        if (not self.enabled or not gene2.enabled) and random.random() < 0.75:
            new.enabled = False
        return new

    def mutate(self, config):
        """``FloatAttribute.mutate_value`` of the weight, then ``BoolAttribute``'s of enabled."""
        mutate_connections((self,), config)


def mutate_connections(genes, config) -> None:
    """:meth:`NeatConnectionGene.mutate` of every gene in turn, as one compiled loop.

    The library's draws in its order (``neat/attributes.py``: ``FloatAttribute.mutate_value``
    of the weight, ``init_value`` when it is replaced, then ``BoolAttribute.mutate_value``
    of ``enabled``), made by :mod:`.pyrandom` from the ``random`` module's state, which
    is then left where the library's own draws would have left it. The genes' weights and
    flags go to arrays and back: the same values as the library's loop, gene for gene.

    Raises:
        RuntimeError: For a weight ``init_type`` neat-python does not know (its message).
    """
    genes = genes if isinstance(genes, list | tuple) else list(genes)
    n = len(genes)
    if n == 0:
        return
    init_type = config.weight_init_type.lower()
    mean, stdev = config.weight_init_mean, config.weight_init_stdev
    high, low = config.weight_max_value, config.weight_min_value
    if "gauss" in init_type or "normal" in init_type:
        init_uniform, init_a, init_b = False, mean, stdev
    elif "uniform" in init_type:  # FloatAttribute.init_value's bounds, as it computes them
        init_uniform, init_a, init_b = True, max(low, mean - 2 * stdev), min(high, mean + 2 * stdev)
    else:
        raise RuntimeError(f"Unknown init_type {config.weight_init_type!r} for weight_init_type")
    weight = np.fromiter(map(_WEIGHT, genes), np.float64, n)
    enabled = np.fromiter(map(_ENABLED, genes), np.bool_, n)
    state = take_state()
    _mutate_genes(
        weight,
        enabled,
        *state,
        config.weight_mutate_rate,
        config.weight_replace_rate + config.weight_mutate_rate,
        config.weight_mutate_power,
        float(high),
        float(low),
        init_uniform,
        float(init_a),
        float(init_b),
        config.enabled_mutate_rate + config.enabled_rate_to_false_add,
        config.enabled_mutate_rate + config.enabled_rate_to_true_add,
    )
    put_state(*state)
    for gene, w, on in zip(genes, weight.tolist(), enabled.tolist(), strict=True):
        gene.weight = w
        gene.enabled = on


@nb.njit(cache=True, inline="always")
def _clamp(w, high, low):
    """Python's ``max(min(w, high), low)``, comparisons in its order."""
    w = high if high < w else w
    return low if low > w else w


@nb.njit(cache=True)
def _mutate_genes(
    weight, enabled, words, position, cached, mutate_rate, replace_below, power, high, low,
    init_uniform, init_a, init_b, rate_enabled, rate_disabled,
):  # fmt: skip
    """The loop of :func:`mutate_connections`, on the genes' arrays and the state's."""
    for i in range(weight.shape[0]):
        r = uniform01(words, position)
        if r < mutate_rate:
            w = weight[i] + gauss(words, position, cached, 0.0, power)
            weight[i] = _clamp(w, high, low)
        elif r < replace_below:
            if init_uniform:  # random.uniform(a, b): within the bounds already
                weight[i] = init_a + (init_b - init_a) * uniform01(words, position)
            else:
                weight[i] = _clamp(gauss(words, position, cached, init_a, init_b), high, low)
        rate = rate_enabled if enabled[i] else rate_disabled
        if rate > 0 and uniform01(words, position) < rate:
            enabled[i] = uniform01(words, position) < 0.5


class NeatGenome(neat.DefaultGenome):
    """neat-python's ``DefaultGenome``, faster, with the library's children and draws.

    :meth:`configure_crossover` is the library's (neat-python 2.0.0,
    ``neat/genome.py``, BSD-3-Clause) line for line, except for its check, per inherited
    connection, that the connection closes no cycle (``creates_cycle(list(
    self.connections), key)``, a rescan of every connection so far). Every inherited
    connection is one of the fitter parent's, so when that parent's connections form no
    cycle (one topological sort) no check can fail and none is made; otherwise each check
    walks the child's successor lists kept as genes are added. Either way every check has
    the library's answer, so the child and the random draws are the same (whether a
    parent's connections form a cycle is worked out once per parent). The connection
    genes' copy, crossover and mutation are written out in :meth:`configure_crossover` and
    :func:`mutate_connections`, and their distance in :meth:`distance`, all with the
    library's operations in its order. Connection genes are :class:`NeatConnectionGene`.
    """

    @classmethod
    def parse_config(cls, param_dict):
        """The library's genome configuration, with :class:`NeatConnectionGene`."""
        config = super().parse_config(param_dict)
        config.connection_gene_type = NeatConnectionGene
        return config

    def mutate(self, config):
        """The library's ``DefaultGenome.mutate`` with its connection loop as one call.

        The same structural mutations, then :func:`mutate_connections` over the connection
        genes, then each node gene's own ``mutate``: the library's draws in its order.
        """
        if config.single_structural_mutation:  # not in this project's configurations
            super().mutate(config)
            return
        if random.random() < config.node_add_prob:
            self.mutate_add_node(config)
        if random.random() < config.node_delete_prob:
            self.mutate_delete_node(config)
        if random.random() < config.conn_add_prob:
            self.mutate_add_connection(config)
        if random.random() < config.conn_delete_prob:
            self.mutate_delete_connection()
        mutate_connections(self.connections.values(), config)
        for ng in self.nodes.values():
            ng.mutate(config)

    def distance(self, other, config):
        """The library's ``DefaultGenome.distance`` with the connection part written out.

        ``DefaultConnectionGene.distance`` of each homologous pair inline, summed in the
        library's order: the same value.
        """
        node_distance = 0.0
        if self.nodes or other.nodes:
            disjoint_nodes = 0
            for k2 in other.nodes:
                if k2 not in self.nodes:
                    disjoint_nodes += 1
            for k1, n1 in self.nodes.items():
                n2 = other.nodes.get(k1)
                if n2 is None:
                    disjoint_nodes += 1
                else:
                    node_distance += n1.distance(n2, config)
            max_nodes = max(len(self.nodes), len(other.nodes))
            node_distance = (
                node_distance + (config.compatibility_disjoint_coefficient * disjoint_nodes)
            ) / max_nodes
        connection_distance = 0.0
        mine, theirs = self.connections, other.connections
        if mine or theirs:
            disjoint_connections = 0
            for k2 in theirs:
                if k2 not in mine:
                    disjoint_connections += 1
            coefficient = config.compatibility_weight_coefficient
            get = theirs.get
            for k1, c1 in mine.items():
                c2 = get(k1)
                if c2 is None:
                    disjoint_connections += 1
                else:
                    d = abs(c1.weight - c2.weight)
                    if c1.enabled != c2.enabled:
                        d += 1.0
                    connection_distance += d * coefficient
            max_conn = max(len(mine), len(theirs))
            connection_distance = (
                connection_distance
                + (config.compatibility_disjoint_coefficient * disjoint_connections)
            ) / max_conn
        return node_distance + connection_distance

    def configure_crossover(self, genome1, genome2, config):
        """Configure a new genome by crossover from two parent genomes (NEAT, p. 108)."""
        if genome1.fitness > genome2.fitness:
            parent1, parent2 = genome1, genome2
        else:
            parent1, parent2 = genome2, genome1
        parent1_innovations = _innovations(parent1)
        parent2_innovations = _innovations(parent2)
        all_innovations = set(parent1_innovations.keys()) | set(parent2_innovations.keys())
        # Every gene added below has a key of parent1's. When the child starts empty and
        # parent1's connections form no cycle, no subset of them does: no check can fail.
        check = config.feed_forward and (bool(self.connections) or _has_cycle(parent1))
        successors: dict[int, list[int]] = {}
        if check:
            for a, b in self.connections:
                successors.setdefault(a, []).append(b)
        new = object.__new__
        gene_type = NeatConnectionGene
        rnd = random.random
        connections = self.connections
        for innovation_num in all_innovations:
            cg1 = parent1_innovations.get(innovation_num)
            if cg1 is None:
                continue  # genes only in the less fit parent are not inherited
            cg2 = parent2_innovations.get(innovation_num)
            # NeatConnectionGene.copy / .crossover, written out (the same draws)
            gene = new(gene_type)
            gene.key = cg1.key
            gene.innovation = cg1.innovation
            if cg2 is not None and cg1.key != cg2.key:
                warnings.warn(
                    f"Innovation number collision: innovation {innovation_num} assigned to "
                    f"both {cg1.key} and {cg2.key}. Treating as disjoint genes.",
                    RuntimeWarning,
                    stacklevel=2,
                )
                cg2 = None
            if cg2 is None:
                gene.weight = cg1.weight
                gene.enabled = cg1.enabled
            else:
                gene.weight = cg1.weight if rnd() > 0.5 else cg2.weight
                gene.enabled = cg1.enabled if rnd() > 0.5 else cg2.enabled
                if (not cg1.enabled or not cg2.enabled) and rnd() < 0.75:
                    gene.enabled = False
            if check:
                if _closes_cycle(successors, gene.key):
                    continue
                successors.setdefault(gene.key[0], []).append(gene.key[1])
            connections[gene.key] = gene
        for key, ng1 in parent1.nodes.items():
            ng2 = parent2.nodes.get(key)
            assert key not in self.nodes
            self.nodes[key] = ng1.copy() if ng2 is None else ng1.crossover(ng2)


def _per_parent(compute):
    """``compute(genome)`` worked out once per genome object and kept while it lives.

    For what crossover reads from a parent: a parent has many children, and its genes do
    not change once it is a parent (elites are carried over unmutated).
    """
    found: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()

    def cached(genome):
        value = found.get(genome)
        if value is None:
            value = found[genome] = compute(genome)
        return value

    cached.__doc__ = compute.__doc__
    return cached


@_per_parent
def _innovations(genome) -> dict:
    """``{gene.innovation: gene}`` of the genome's connections, in the genome's order."""
    return {cg.innovation: cg for cg in genome.connections.values()}


@_per_parent
def _has_cycle(genome) -> bool:
    """True when the genome's connection keys (enabled or not) contain a directed cycle."""
    indegree: dict[int, int] = {}
    successors: dict[int, list[int]] = {}
    for a, b in genome.connections:
        successors.setdefault(a, []).append(b)
        indegree[b] = indegree.get(b, 0) + 1
        indegree.setdefault(a, 0)
    ready = [v for v, d in indegree.items() if d == 0]
    seen = 0
    while ready:
        v = ready.pop()
        seen += 1
        for b in successors.get(v, ()):
            indegree[b] -= 1
            if indegree[b] == 0:
                ready.append(b)
    return seen < len(indegree)


def _closes_cycle(successors: dict[int, list[int]], key: tuple[int, int]) -> bool:
    """``neat.graphs.creates_cycle`` over the graph whose successor lists are given."""
    i, o = key
    if i == o:
        return True
    seen = {o}
    todo = [o]
    while todo:
        for b in successors.get(todo.pop(), ()):
            if b == i:
                return True
            if b not in seen:
                seen.add(b)
                todo.append(b)
    return False


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
        population=population,
        inputs=N_SENSORS,
        outputs=N_BEHAVIOURS,
        hidden=hidden,
        genome_section=NeatGenome.__name__,
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
    path.write_text(neat_config_text(population, hidden, overrides), encoding="utf-8")
    config = neat.Config(
        NeatGenome,
        neat.DefaultReproduction,
        neat.DefaultSpeciesSet,
        neat.DefaultStagnation,
        str(path),
    )
    for f in MODULAR:
        config.genome_config.add_activation(f.__name__, f)
    return config


_ACTIVATIONS = {"sigmoid": ACT_SIGMOID, "identity": ACT_IDENTITY}
"""neat-python activation names that compile to a sum node, and their network-program codes."""
_MODULAR_CODES = {f.__name__: i for i, f in enumerate(MODULAR)}
_ACTIVATION_CODES = {**_MODULAR_CODES, **_ACTIVATIONS}
"""Every activation that compiles, and its network-program code."""
_ENABLED = attrgetter("enabled")
_BIAS = attrgetter("bias")
_RESPONSE = attrgetter("response")
_WEIGHT = attrgetter("weight")


def compile_neat(genome, config) -> NetworkProgram:
    """The network program of a neat-python genome, computed with numpy.

    It is the network neat-python 2.0.0's ``FeedForwardNetwork.create`` builds: the
    enabled connections; the nodes required for the outputs (the outputs and every node
    with a path to one); each required node reads its enabled incoming connections in the
    genome's order. Nodes are laid out by depth (0: no required predecessor), an
    evaluation order as good as the library's layers, since a node's value depends on its
    inputs' values alone. Input key ``-1 - i`` is sensor i; output key q is behaviour q.
    A node with one of the :data:`MODULAR` activations becomes ANT's neuron (weighted mean,
    modular activation with ``theta1`` = bias, ``theta2`` = response).
    """
    gc = config.genome_config
    outputs = list(gc.output_keys)
    node_keys = list(genome.nodes)
    n = len(node_keys)
    genes = genome.connections  # gene key (input, output) -> gene
    links = len(genes)
    pairs = np.fromiter(chain.from_iterable(genes), np.int64, 2 * links).reshape(links, 2)
    enabled = np.fromiter(map(_ENABLED, genes.values()), bool, links)
    src_key, dst_key = pairs[enabled, 0], pairs[enabled, 1]
    weight = np.fromiter(map(_WEIGHT, genes.values()), np.float64, links)[enabled]
    from_node = src_key >= 0  # input keys are negative
    # node key -> position in genome.nodes, for all links at once
    keys = np.fromiter(node_keys, np.int64, n)
    by_key = np.argsort(keys, kind="stable")
    sorted_keys = keys[by_key]

    def index_of(k: np.ndarray) -> np.ndarray:
        if k.size and n == 0:
            raise ValueError(f"NEAT genome: a connection names node {int(k[0])}, not in it")
        at = np.minimum(np.searchsorted(sorted_keys, k), max(n - 1, 0))
        missing = k[sorted_keys[at] != k] if k.size else k
        if missing.size:
            raise ValueError(f"NEAT genome: a connection names node {int(missing[0])}, not in it")
        return by_key[at]

    dst = index_of(dst_key)
    src = np.full(src_key.size, -1, dtype=np.int64)
    src[from_node] = index_of(src_key[from_node])
    index = {key: j for j, key in enumerate(node_keys)}
    # required: the outputs and everything upstream of them
    required = np.zeros(n, dtype=bool)
    required[[index[q] for q in outputs if q in index]] = True
    while True:
        grow = from_node & required[dst] & ~required[np.maximum(src, 0)]
        if not grow.any():
            break
        required[src[grow]] = True
    # depth: longest path from a node without required predecessors
    inner = from_node & required[dst] & required[np.maximum(src, 0)]
    depth = np.zeros(n, dtype=np.int64)
    for _ in range(n + 1):
        nxt = depth.copy()
        np.maximum.at(nxt, dst[inner], depth[src[inner]] + 1)
        if np.array_equal(nxt, depth):
            break
        depth = nxt
    else:
        raise ValueError("NEAT genome: its enabled connections form a cycle")
    order = np.flatnonzero(required)
    order = order[np.argsort(depth[order], kind="stable")]
    position = np.full(n, -1, dtype=np.int64)
    position[order] = np.arange(order.size)
    keep = required[dst]
    e = np.flatnonzero(keep)
    e = e[np.argsort(position[dst[e]], kind="stable")]  # by node, genome order within
    edge_src = np.where(from_node[e], N_SENSORS + position[np.maximum(src[e], 0)], -1 - src_key[e])
    counts = np.bincount(position[dst[e]], minlength=order.size)
    m = order.size
    nodes = [genome.nodes[node_keys[j]] for j in order]
    for ng in nodes:  # only what the kernel computes
        if ng.aggregation != "sum":
            raise ValueError(f"NEAT node {ng.key}: only the sum aggregation compiles")
        if ng.activation not in _ACTIVATION_CODES:
            raise ValueError(f"NEAT node {ng.key}: only sigmoid and identity activations compile")
    act = np.fromiter((_ACTIVATION_CODES[ng.activation] for ng in nodes), np.int64, m)
    bias = np.fromiter(map(_BIAS, nodes), np.float64, m)
    resp = np.fromiter(map(_RESPONSE, nodes), np.float64, m)
    modular = act < ACT_SIGMOID
    theta = np.where(modular[:, None], np.stack((bias, resp), axis=1), 0.0)
    return NetworkProgram(
        node_act=act,
        node_agg=np.where(modular, AGG_MEAN, AGG_SUM).astype(np.int64),
        node_bias=bias,
        node_resp=resp,
        node_theta=theta.reshape(m, 2),
        edge_start=np.concatenate(([0], np.cumsum(counts))).astype(np.int64),
        edge_src=edge_src.astype(np.int64),
        edge_w=weight[e],
        out_node=np.array(
            [position[index[q]] if q in index else -1 for q in outputs], dtype=np.int64
        ),
    )
