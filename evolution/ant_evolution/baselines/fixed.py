"""The fixed-topology network baseline (paper, section 5): layers fixed, parameters evolved.

Topology: the 14 sensors, one or two fully connected hidden layers and 12 output neurons
(one per behaviour of Table 2), so at most four layers counting the sensor and output
layers, as for ANT. Every neuron is the ANT neuron: ``sigma = sum(w s) / sum(s)`` over its
inputs and the modular activation function with its own ``theta1, theta2, k1, k2``
(section 3.3); behaviour q fires when output neuron q is 1. The neuron count (hidden plus
output) is drawn once per run from 40 to 120, like ANT's initial tissues; the split
between the two hidden layers is drawn too (a second hidden layer of 0 means 3 layers).

The genome is a flat parameter vector per neuron. The GA uses ANT's settings (tournament
of 0.06 P, crossover 0.7, mutation 0.025, elitism, and ANT's mutation switches with a
neuron as the gene); crossover cuts the neuron list at one random point and swaps the
tails, mutation redraws (or perturbs) a weight or a threshold in ``[-1, 1]`` and flips a
selector bit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ant_controller.layout import N_BEHAVIOURS, N_SENSORS
from ant_evolution.baselines.network import AGG_MEAN, NetworkProgram
from ant_evolution.ga import GAParams


@dataclass(frozen=True)
class FixedTopology:
    """Layer sizes of a fixed network (sensors, hidden 1, hidden 2, outputs).

    Attributes:
        hidden: Sizes of the hidden layers (one or two; a 0 second layer is dropped).
    """

    hidden: tuple[int, ...]

    def __post_init__(self) -> None:
        if not 1 <= len(self.hidden) <= 2 or min(self.hidden) < 1:
            raise ValueError(
                f"fixed network: hidden layers {self.hidden} must be 1 or 2 sizes >= 1"
            )

    @classmethod
    def random(
        cls, rng: np.random.Generator, neurons: tuple[int, int] = (40, 120)
    ) -> FixedTopology:
        """Draw a neuron count in ``neurons`` (hidden + outputs) and split it in 1-2 layers."""
        total = int(rng.integers(neurons[0], neurons[1] + 1)) - N_BEHAVIOURS
        total = max(1, total)
        first = int(rng.integers(1, total + 1))
        second = total - first
        return cls((first, second) if second > 0 else (first,))

    @property
    def layers(self) -> tuple[int, ...]:
        """Non-input layer sizes, outputs last."""
        return (*self.hidden, N_BEHAVIOURS)

    @property
    def n_neurons(self) -> int:
        """Hidden plus output neurons."""
        return sum(self.layers)

    @property
    def fan_in(self) -> tuple[int, ...]:
        """Inputs of a neuron of each non-input layer."""
        return (N_SENSORS, *self.layers[:-1])

    @property
    def n_weights(self) -> int:
        """Connections."""
        return sum(a * b for a, b in zip(self.fan_in, self.layers, strict=True))


@dataclass(frozen=True)
class FixedNetwork:
    """The evolved parameters of a fixed network.

    Attributes:
        weights: ``float64 [E]`` connection weights, neuron after neuron, inputs in order.
        theta: ``float64 [N, 2]`` thresholds.
        func: ``int64 [N]`` ``k1 * 2 + k2``.
    """

    weights: np.ndarray
    theta: np.ndarray
    func: np.ndarray

    def to_dict(self) -> dict:
        """Plain lists (checkpoints)."""
        return {
            "weights": self.weights.tolist(),
            "theta": self.theta.tolist(),
            "func": self.func.tolist(),
        }

    @classmethod
    def from_dict(cls, data: dict) -> FixedNetwork:
        """Inverse of :meth:`to_dict`."""
        return cls(
            np.asarray(data["weights"], dtype=np.float64),
            np.asarray(data["theta"], dtype=np.float64).reshape(-1, 2),
            np.asarray(data["func"], dtype=np.int64),
        )


def random_network(rng: np.random.Generator, topology: FixedTopology) -> FixedNetwork:
    """Uniform random parameters (weights and thresholds in [-1, 1], random functions)."""
    n = topology.n_neurons
    return FixedNetwork(
        rng.uniform(-1.0, 1.0, topology.n_weights),
        rng.uniform(-1.0, 1.0, (n, 2)),
        rng.integers(0, 4, n).astype(np.int64),
    )


def compile_fixed(topology: FixedTopology, net: FixedNetwork) -> NetworkProgram:
    """The network program of a fixed network (fully connected layers)."""
    n = topology.n_neurons
    srcs: list[np.ndarray] = []
    first, width, node_base = 0, N_SENSORS, N_SENSORS  # value index of the layer below
    for size in topology.layers:
        srcs.extend([np.arange(first, first + width, dtype=np.int64)] * size)
        first, width = node_base, size
        node_base += size
    starts = np.concatenate(([0], np.cumsum([s.size for s in srcs]))).astype(np.int64)
    out_node = np.arange(n - N_BEHAVIOURS, n, dtype=np.int64)
    return NetworkProgram(
        node_act=net.func.astype(np.int64),
        node_agg=np.full(n, AGG_MEAN, dtype=np.int64),
        node_bias=np.zeros(n),
        node_resp=np.ones(n),
        node_theta=net.theta.astype(np.float64),
        edge_start=starts,
        edge_src=np.concatenate(srcs),
        edge_w=net.weights.astype(np.float64),
        out_node=out_node,
    )


def _neuron_bounds(topology: FixedTopology) -> np.ndarray:
    """Weight index where each neuron's inputs start (length N + 1)."""
    fans = np.repeat(topology.fan_in, topology.layers)
    return np.concatenate(([0], np.cumsum(fans)))


def mutate(
    rng: np.random.Generator,
    net: FixedNetwork,
    params: GAParams,
    topology: FixedTopology | None = None,
) -> FixedNetwork:
    """Mutate under ANT's switches (:mod:`ant_evolution.ga`), a neuron being a gene.

    ``v1`` (scope ``parameter``, operator ``redraw``): redraw each weight and threshold with
    probability p, flip each selector bit with p. Otherwise (``topology`` needed) each
    neuron (its input weights, two thresholds, two selector bits) is a gene: scope
    ``gene`` mutates one of its parameters with p, scope ``parameter`` each with p; the
    operator redraws or perturbs a weight or threshold as ANT's does.
    """
    if not params.legacy_mutation:
        if topology is None:
            raise ValueError("fixed network: switched mutation needs the topology")
        return _mutate_switched(rng, net, params, _neuron_bounds(topology))
    p = params.mutation_prob
    w = net.weights.copy()
    hit = rng.random(w.shape) < p
    w[hit] = rng.uniform(-1.0, 1.0, int(hit.sum()))
    th = net.theta.copy()
    hit = rng.random(th.shape) < p
    th[hit] = rng.uniform(-1.0, 1.0, int(hit.sum()))
    flips = (rng.random((net.func.shape[0], 2)) < p).astype(np.int64)
    func = net.func ^ (flips[:, 0] * 2 + flips[:, 1])
    return FixedNetwork(w, th, func)


def _mutate_switched(
    rng: np.random.Generator, net: FixedNetwork, params: GAParams, bounds: np.ndarray
) -> FixedNetwork:
    w, th, func = net.weights.copy(), net.theta.copy(), net.func.copy()
    width = 2.0 * params.mutation_width  # the range [-1, 1] is 2 wide
    for j in range(func.shape[0]):
        fan = int(bounds[j + 1] - bounds[j])
        slots = fan + 4  # input weights, theta1, theta2, k1, k2
        if params.mutation_scope == "parameter":
            chosen = [int(s) for s in np.flatnonzero(rng.random(slots) < params.mutation_prob)]
        elif rng.random() < params.mutation_prob:
            chosen = [int(rng.integers(0, slots))]
        else:
            chosen = []
        for s in chosen:
            if s >= fan + 2:
                func[j] ^= 2 if s == fan + 2 else 1
                continue
            arr, i = (w, int(bounds[j]) + s) if s < fan else (th, (j, s - fan))
            if params.mutation_operator == "perturb":
                arr[i] = float(np.clip(arr[i] + rng.uniform(-width, width), -1.0, 1.0))
            else:
                arr[i] = float(rng.uniform(-1.0, 1.0))
    return FixedNetwork(w, th, func)


def crossover(
    rng: np.random.Generator, a: FixedNetwork, b: FixedNetwork, topology: FixedTopology
) -> tuple[FixedNetwork, FixedNetwork]:
    """Swap every neuron (its inputs' weights and its thresholds) after one random cut.

    Bred by :func:`ant_evolution.ga.next_generation` with ``topology`` bound.
    """
    n = topology.n_neurons
    cut = int(rng.integers(1, n))
    wcut = int(_neuron_bounds(topology)[cut])

    def join(x: FixedNetwork, y: FixedNetwork) -> FixedNetwork:
        return FixedNetwork(
            np.concatenate((x.weights[:wcut], y.weights[wcut:])),
            np.concatenate((x.theta[:cut], y.theta[cut:])),
            np.concatenate((x.func[:cut], y.func[cut:])),
        )

    return join(a, b), join(b, a)
