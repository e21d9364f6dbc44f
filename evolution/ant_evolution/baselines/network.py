"""Network programs: the flat-array form of a feed-forward network, and its decision kernel.

A :class:`NetworkProgram` lists the network's non-input nodes in evaluation order; node j
reads the inputs ``edge_src[edge_start[j]:edge_start[j + 1]]`` (index ``i < 14``: sensor
i; ``14 + k``: node k, which comes earlier) with weights ``edge_w``. Its value is

* ``AGG_MEAN`` (the ANT neuron of section 3.2, used by the fixed-topology baseline):
  ``sigma = sum(w v) / sum(v)`` (0 when the sum of inputs is 0), then the activation;
* ``AGG_SUM`` (neat-python's ``sum`` aggregation): ``bias + response * sum(w v)``, then the
  activation.

Activations: ``0..3`` the modular activation function (``k1 * 2 + k2``, the one
:func:`ant_controller.tissue.activation`), ``ACT_SIGMOID`` neat-python's sigmoid
(``1 / (1 + exp(-clamp(5 z, -60, 60)))``), ``ACT_IDENTITY``. Behaviour q fires when its
output node's value is at least 0.5 (never when ``out_node[q] == -1``). Sensor inputs are
``code_i / (states_i - 1)``, exactly what an ANT tissue sees.

A program runs in the one episode kernel (:mod:`ant_evolution.kernel`) as a
:class:`NetworkRecord`, beside ANT tissues and the hand-coded rules; scoring and worker
pools are the one evaluator's (:class:`ant_evolution.backends.Evaluator`).
:func:`decide_program_reference` is the plain Python forward pass the tests hold the
kernel to.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numba as nb
import numpy as np

from ant_controller.layout import N_BEHAVIOURS, N_SENSORS, SENSOR_SCALE
from ant_controller.tissue import activation

AGG_MEAN = 0
AGG_SUM = 1
ACT_SIGMOID = 4
ACT_IDENTITY = 5


class NetworkRecord(NamedTuple):
    """A network program as the kernels take it (fields as :class:`NetworkProgram`)."""

    node_act: np.ndarray
    node_agg: np.ndarray
    node_bias: np.ndarray
    node_resp: np.ndarray
    node_theta: np.ndarray
    edge_start: np.ndarray
    edge_src: np.ndarray
    edge_w: np.ndarray
    out_node: np.ndarray
    group_start: np.ndarray
    group_shared: np.ndarray
    row_start: np.ndarray
    row_src: np.ndarray
    row_w: np.ndarray


LANES = 4
"""Nodes a decision sums side by side (:func:`lane_layout`)."""


@dataclass(frozen=True)
class NetworkProgram:
    """A feed-forward network as flat arrays (see the module docstring).

    Attributes:
        node_act: ``int64 [N]`` activation of each node.
        node_agg: ``int64 [N]`` ``AGG_MEAN`` or ``AGG_SUM``.
        node_bias: ``float64 [N]`` bias (``AGG_SUM`` only).
        node_resp: ``float64 [N]`` response (``AGG_SUM`` only).
        node_theta: ``float64 [N, 2]`` thresholds of the modular activation.
        edge_start: ``int64 [N + 1]`` first edge of each node.
        edge_src: ``int64 [E]`` source: sensor index, or ``14 +`` node index.
        edge_w: ``float64 [E]`` weights.
        out_node: ``int64 [12]`` node voting for behaviour q, -1 for none.
    """

    node_act: np.ndarray
    node_agg: np.ndarray
    node_bias: np.ndarray
    node_resp: np.ndarray
    node_theta: np.ndarray
    edge_start: np.ndarray
    edge_src: np.ndarray
    edge_w: np.ndarray
    out_node: np.ndarray

    def __post_init__(self) -> None:
        n = self.node_act.shape[0]
        e = self.edge_src.shape[0]
        if self.edge_start.shape != (n + 1,) or self.out_node.shape != (N_BEHAVIOURS,):
            raise ValueError("network program: edge_start must have N + 1 and out_node 12 entries")
        for name in ("node_agg", "node_bias", "node_resp"):
            if getattr(self, name).shape != (n,):
                raise ValueError(f"network program: {name} must have N = {n} entries")
        if self.node_theta.shape != (n, 2):
            raise ValueError(f"network program: node_theta must be N x 2 = {n} x 2")
        if self.edge_src.ndim != 1 or self.edge_w.shape != (e,):
            raise ValueError("network program: edge_src and edge_w must be lists of one length")
        counts = np.diff(self.edge_start)
        if self.edge_start[0] != 0 or self.edge_start[-1] != e or (counts < 0).any():
            raise ValueError(f"network program: edge_start must rise from 0 to the {e} edges")
        if ((self.node_act < 0) | (self.node_act > ACT_IDENTITY)).any():
            raise ValueError(f"network program: node_act must lie in 0..{ACT_IDENTITY}")
        if ((self.node_agg != AGG_MEAN) & (self.node_agg != AGG_SUM)).any():
            raise ValueError("network program: node_agg must be 0 (mean) or 1 (sum)")
        if ((self.out_node < -1) | (self.out_node >= n)).any():
            raise ValueError(f"network program: out_node must lie in -1..{n - 1}")
        reader = np.repeat(np.arange(n, dtype=np.int64), counts)  # the node each edge feeds
        bad = (self.edge_src < 0) | (self.edge_src >= N_SENSORS + reader)
        if bad.any():
            j = int(reader[np.argmax(bad)])
            raise ValueError(f"network program: node {j} reads a node that comes later")

    @property
    def n_nodes(self) -> int:
        """Non-input nodes."""
        return int(self.node_act.shape[0])

    @property
    def n_edges(self) -> int:
        """Connections."""
        return int(self.edge_w.shape[0])

    @property
    def robots(self) -> None:
        """A network has no N gene: it runs with each scenario's own robot count."""
        return None

    def record(self) -> NetworkRecord:
        """The arrays as a :class:`NetworkRecord`, the form the kernels take."""
        group_start, group_shared, row_start, row_src, row_w = lane_layout(
            self.edge_start, self.edge_src, self.edge_w
        )
        return NetworkRecord(
            node_act=self.node_act,
            node_agg=self.node_agg,
            node_bias=self.node_bias,
            node_resp=self.node_resp,
            node_theta=self.node_theta,
            edge_start=self.edge_start,
            edge_src=self.edge_src,
            edge_w=self.edge_w,
            out_node=self.out_node,
            group_start=group_start,
            group_shared=group_shared,
            row_start=row_start,
            row_src=row_src,
            row_w=row_w,
        )


def lane_layout(edge_start, edge_src, edge_w):
    """The edges laid out for :data:`LANES` nodes summed side by side.

    Nodes, in evaluation order, are cut into groups of at most ``LANES`` consecutive nodes
    none of which reads another of its group (so their sums are independent: the CPU
    overlaps them instead of waiting on one sum at a time). Group g holds nodes
    ``group_start[g]:group_start[g + 1]`` and rows ``row_start[g]:row_start[g + 1]`` of
    ``row_src`` / ``row_w`` (``[rows, LANES]``); row r, lane l is the r-th input of the
    group's l-th node. A lane shorter than its group's longest (or a lane with no node)
    is padded with weight 0 reading the scratch's last value, which stays 0: each node's
    sum adds its inputs in its own order, then only exact zeros, so every value and mask is
    the sequential one's. ``group_shared[g]`` is 1 when every node of group g reads the
    same inputs in the same order (a layer of a fixed network, a single node): the kernel
    then loads each input once for all lanes and sums the inputs once.

    Returns:
        ``(group_start, group_shared, row_start, row_src, row_w)``.
    """
    n = edge_start.shape[0] - 1
    pad = N_SENSORS + n  # the scratch's last slot: always 0.0
    counts = np.diff(edge_start)
    reads = np.full(n, -1, dtype=np.int64)  # the latest value each node reads
    has = counts > 0
    if has.any():
        reads[has] = np.maximum.reduceat(edge_src, edge_start[:-1][has])
    starts = [0]
    j = 0
    while j < n:
        first, j = j, j + 1
        while j < n and j - first < LANES and reads[j] < N_SENSORS + first:
            j += 1
        starts.append(j)
    group_start = np.array(starts, dtype=np.int64)
    rows = np.array(
        [counts[a:b].max(initial=0) for a, b in zip(starts, starts[1:], strict=False)],
        dtype=np.int64,
    )
    row_start = np.concatenate(([0], np.cumsum(rows))).astype(np.int64)
    row_src = np.full((int(row_start[-1]), LANES), pad, dtype=np.int64)
    row_w = np.zeros((int(row_start[-1]), LANES))
    shared = np.zeros(len(starts) - 1, dtype=np.int64)
    for g in range(len(starts) - 1):
        r = row_start[g]
        first = edge_src[edge_start[starts[g]] : edge_start[starts[g] + 1]]
        same = True
        for lane, node in enumerate(range(starts[g], starts[g + 1])):
            a, b = edge_start[node], edge_start[node + 1]
            row_src[r : r + b - a, lane] = edge_src[a:b]
            row_w[r : r + b - a, lane] = edge_w[a:b]
            same = same and b - a == first.size and np.array_equal(edge_src[a:b], first)
        shared[g] = same
    return group_start, shared, row_start, row_src, row_w


@nb.njit(cache=True, inline="always")
def _node_activation(act, theta1, theta2, z):
    if act < 4:
        return float(activation(act, theta1, theta2, z))
    if act == ACT_SIGMOID:
        z = max(-60.0, min(60.0, 5.0 * z))
        return 1.0 / (1.0 + math.exp(-z))
    return z


@nb.njit(cache=True, inline="always")
def _finish_node(program, values, n_s, j, num, den):
    """Node j's value from its weighted sum and its sum of inputs."""
    if program.node_agg[j] == AGG_MEAN:
        z = num / den if den != 0.0 else 0.0
    else:
        z = program.node_bias[j] + program.node_resp[j] * num
    theta = program.node_theta
    values[n_s + j] = _node_activation(program.node_act[j], theta[j, 0], theta[j, 1], z)


@nb.njit(cache=True, inline="always")
def program_decide_into(codes, program, values):
    """Behaviour mask of one sensor vector; ``values`` (length 14 + N + 1) is scratch.

    The nodes are summed four at a time along :func:`lane_layout`'s rows; each node's
    sum is the sequential one's (its inputs in order, then exact zeros). A group whose
    nodes share their inputs loads each input once and sums the inputs once (the same
    numbers added in the same order: the same values).
    """
    group_start = program.group_start
    group_shared = program.group_shared
    row_start = program.row_start
    row_src = program.row_src
    row_w = program.row_w
    out_node = program.out_node
    n_s = codes.shape[0]
    for i in range(n_s):
        values[i] = codes[i] * SENSOR_SCALE[i]
    values[values.shape[0] - 1] = 0.0  # the padding's input
    for g in range(group_start.shape[0] - 1):
        n0 = n1 = n2 = n3 = 0.0
        d0 = d1 = d2 = d3 = 0.0
        if group_shared[g]:
            for r in range(row_start[g], row_start[g + 1]):
                v = values[row_src[r, 0]]
                n0 += row_w[r, 0] * v
                n1 += row_w[r, 1] * v
                n2 += row_w[r, 2] * v
                n3 += row_w[r, 3] * v
                d0 += v
            d1 = d2 = d3 = d0
        else:
            for r in range(row_start[g], row_start[g + 1]):
                v0 = values[row_src[r, 0]]
                v1 = values[row_src[r, 1]]
                v2 = values[row_src[r, 2]]
                v3 = values[row_src[r, 3]]
                n0 += row_w[r, 0] * v0
                n1 += row_w[r, 1] * v1
                n2 += row_w[r, 2] * v2
                n3 += row_w[r, 3] * v3
                d0 += v0
                d1 += v1
                d2 += v2
                d3 += v3
        j = group_start[g]
        m = group_start[g + 1] - j
        _finish_node(program, values, n_s, j, n0, d0)
        if m > 1:
            _finish_node(program, values, n_s, j + 1, n1, d1)
        if m > 2:
            _finish_node(program, values, n_s, j + 2, n2, d2)
        if m > 3:
            _finish_node(program, values, n_s, j + 3, n3, d3)
    mask = 0
    for q in range(out_node.shape[0]):
        o = out_node[q]
        if o >= 0 and values[n_s + o] >= 0.5:
            mask |= 1 << q
    return mask


@nb.njit(cache=True)
def program_scratch(program):
    """Scratch of :func:`program_decide_into` for one :class:`NetworkRecord`."""
    return np.zeros(N_SENSORS + program.node_act.shape[0] + 1)


@nb.njit(cache=True)
def program_decide(codes, program):
    """:func:`program_decide_into` with its own scratch (for single calls and tests)."""
    return program_decide_into(codes, program, program_scratch(program))


# --- plain reference -------------------------------------------------------------------------


def decide_program_reference(program: NetworkProgram, codes) -> tuple[int, list[float]]:
    """Plain-Python forward pass: ``(mask, node values)``, written for reading and tests."""
    inputs = [float(codes[i]) * float(SENSOR_SCALE[i]) for i in range(N_SENSORS)]
    nodes: list[float] = []
    for j in range(program.n_nodes):
        srcs = program.edge_src[program.edge_start[j] : program.edge_start[j + 1]]
        ws = program.edge_w[program.edge_start[j] : program.edge_start[j + 1]]
        vals = [inputs[s] if s < N_SENSORS else nodes[s - N_SENSORS] for s in srcs]
        num = 0.0
        for w, v in zip(ws, vals, strict=True):
            num += float(w) * v
        if program.node_agg[j] == AGG_MEAN:
            den = 0.0
            for v in vals:
                den += v
            z = num / den if den != 0.0 else 0.0
        else:
            z = float(program.node_bias[j]) + float(program.node_resp[j]) * num
        act = int(program.node_act[j])
        if act < 4:
            t1, t2 = (float(t) for t in program.node_theta[j])
            nodes.append(float(activation(act, t1, t2, z)))
        elif act == ACT_SIGMOID:
            nodes.append(1.0 / (1.0 + math.exp(-max(-60.0, min(60.0, 5.0 * z)))))
        else:
            nodes.append(z)
    mask = 0
    for q, o in enumerate(program.out_node):
        if o >= 0 and nodes[o] >= 0.5:
            mask |= 1 << q
    return mask, nodes
