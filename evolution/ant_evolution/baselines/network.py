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
    group_kind: np.ndarray
    row_start: np.ndarray
    row_src: np.ndarray
    row_w: np.ndarray


LANES = 4
"""Nodes a decision sums side by side (:func:`lane_layout`)."""
GROUP_SEPARATE = 0
"""A lane group whose nodes read their own inputs (:func:`lane_layout`)."""
GROUP_SHARED = 1
"""A lane group whose nodes read the same inputs in the same order."""
GROUP_UNION = 2
"""A lane group of sum nodes reading a merge of their inputs, weight 0 where not read."""
GROUP_SEPARATE_SUM = 3
"""A :data:`GROUP_SEPARATE` group of sum nodes (no sum of inputs kept)."""
UNION_SLACK = 1.5
"""A :data:`GROUP_UNION` merge may be at most this many times its longest input list (one
load per row instead of four: about 1.7 x cheaper a row, measured on NEAT networks)."""


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
        group_start, group_kind, row_start, row_src, row_w = lane_layout(
            self.edge_start, self.edge_src, self.edge_w, self.node_agg, self.node_act
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
            group_kind=group_kind,
            row_start=row_start,
            row_src=row_src,
            row_w=row_w,
        )


def lane_layout(edge_start, edge_src, edge_w, node_agg, node_act):
    """The edges laid out for :data:`LANES` nodes summed side by side.

    Nodes, in evaluation order, are cut into groups of at most ``LANES`` consecutive nodes
    none of which reads another of its group (so their sums are independent: the CPU
    overlaps them instead of waiting on one sum at a time). Group g holds nodes
    ``group_start[g]:group_start[g + 1]`` and rows ``row_start[g]:row_start[g + 1]`` of
    ``row_src`` / ``row_w`` (``[rows, LANES]``); ``group_kind[g]`` says how the kernel sums
    them:

    * :data:`GROUP_SEPARATE` (and :data:`GROUP_SEPARATE_SUM`, every node ``AGG_SUM``, so
      no sum of inputs is kept): row r, lane l is the r-th input of the group's l-th node.
      A lane shorter than its group's longest (or a lane with no node) is padded with
      weight 0 reading the scratch's last value, which stays 0.
    * :data:`GROUP_SHARED`: every node reads the same inputs in the same order and not
      every node is a sum node (a layer of a fixed network, a single mean node; sum nodes
      reading one list make a union group); ``row_src[:, 0]`` lists them and the kernel loads
      each once for all lanes and sums the inputs once.
    * :data:`GROUP_UNION`: every node is ``AGG_SUM`` and ``row_src[:, 0]`` is a merge of
      the nodes' input lists that keeps each node's own order (for a NEAT layer whose
      nodes lost or gained a few connections, little longer than the longest list); a
      node's weight is 0 on the rows it does not read. Used when the merge is at most
      :data:`UNION_SLACK` times the longest list and every input the group reads is
      bounded (a sensor, or a node whose activation is not the identity), so a padded row
      adds exactly 0 (``0 * v`` with v finite).

    In every kind each node's sum adds its own inputs in its own order with only exact
    zeros between them (a sum starts at +0 and never becomes -0), so every value and mask
    is the sequential one's.

    Args:
        edge_start: The program's first edge of each node (:class:`NetworkProgram`).
        edge_src: Its edges' sources.
        edge_w: Its edges' weights.
        node_agg: Its nodes' aggregations.
        node_act: Its nodes' activations.

    Returns:
        ``(group_start, group_kind, row_start, row_src, row_w)``.
    """
    return _lay_out(
        edge_start.astype(np.int64),
        edge_src.astype(np.int64),
        edge_w.astype(np.float64),
        node_agg.astype(np.int64),
        node_act.astype(np.int64),
    )


@nb.njit(cache=True)
def _lay_out(edge_start, edge_src, edge_w, node_agg, node_act):
    """:func:`lane_layout`, compiled (it runs once per program, in the workers)."""
    n = edge_start.shape[0] - 1
    pad = N_SENSORS + n  # the scratch's last slot: always 0.0
    group_start = np.zeros(n + 1, dtype=np.int64)
    groups = 0
    j = 0
    while j < n:
        first = j
        j += 1
        while j < n and j - first < LANES:
            latest = -1  # the latest value node j reads
            for e in range(edge_start[j], edge_start[j + 1]):
                latest = max(latest, edge_src[e])
            if latest >= N_SENSORS + first:
                break
            j += 1
        groups += 1
        group_start[groups] = j
    group_start = group_start[: groups + 1]
    kinds = np.zeros(groups, dtype=np.int64)
    row_start = np.zeros(groups + 1, dtype=np.int64)
    rows_max = max(edge_src.shape[0], 1)  # no group has more rows than its nodes' edges
    row_src = np.full((rows_max, LANES), pad, dtype=np.int64)
    row_w = np.zeros((rows_max, LANES))
    r = 0
    for g in range(groups):
        a, b = group_start[g], group_start[g + 1]
        first_edge, last_edge = edge_start[a], edge_start[b]
        longest = 0
        same = True
        sums = True
        for k in range(a, b):
            count = edge_start[k + 1] - edge_start[k]
            longest = max(longest, count)
            sums = sums and node_agg[k] == AGG_SUM
            if count != edge_start[a + 1] - first_edge:
                same = False
            else:
                for i in range(count):
                    if edge_src[edge_start[k] + i] != edge_src[first_edge + i]:
                        same = False
                        break
        # a value that is finite whatever the inputs: a sensor, a node squashed or thresholded
        bounded = True
        for e in range(first_edge, last_edge):
            s = edge_src[e]
            if s >= N_SENSORS and node_act[s - N_SENSORS] == ACT_IDENTITY:
                bounded = False
                break
        kind = GROUP_SHARED if same else (GROUP_SEPARATE_SUM if sums else GROUP_SEPARATE)
        if sums and (same or bounded):
            merged, weights = union_rows(
                edge_src[first_edge:last_edge],
                edge_w[first_edge:last_edge],
                edge_start[a : b + 1] - first_edge,
                pad,
            )
            if merged.shape[0] <= UNION_SLACK * longest:
                kinds[g] = GROUP_UNION
                m = merged.shape[0]
                for i in range(m):
                    for lane in range(LANES):
                        row_src[r + i, lane] = merged[i]
                        row_w[r + i, lane] = weights[i, lane]
                r += m
                row_start[g + 1] = r
                continue
        kinds[g] = kind
        for lane in range(b - a):
            k = a + lane
            for i in range(edge_start[k + 1] - edge_start[k]):
                row_src[r + i, lane] = edge_src[edge_start[k] + i]
                row_w[r + i, lane] = edge_w[edge_start[k] + i]
        if kind == GROUP_SHARED:  # one input list for every lane
            for i in range(longest):
                for lane in range(b - a, LANES):
                    row_src[r + i, lane] = row_src[r + i, 0]
        r += longest
        row_start[g + 1] = r
    return group_start, kinds, row_start, row_src[:r].copy(), row_w[:r].copy()


@nb.njit(cache=True)
def union_rows(src, w, starts, n_values):
    """The merge of :data:`GROUP_UNION`: ``(merged sources, weights [rows, LANES])``.

    Lane l's inputs are ``src[starts[l]:starts[l + 1]]`` (no source twice in a lane),
    with weights ``w``. The merge holds each lane's inputs as a subsequence: it takes a
    lane's next input that no lane still needs later (taking it now delays nothing), else
    the first lane's next one, and moves on every lane whose next input it is; lists cut
    from one common order merge into that order. A lane's weight sits on the row where
    it reads the input, 0 elsewhere.
    """
    k = starts.shape[0] - 1
    pos = np.full((k, n_values), -1, dtype=np.int64)  # a source's place in each lane
    for lane in range(k):
        for i in range(starts[lane], starts[lane + 1]):
            pos[lane, src[i]] = i - starts[lane]
    at = np.zeros(k, dtype=np.int64)
    merged = np.empty(src.shape[0], dtype=np.int64)
    weights = np.zeros((src.shape[0], LANES))
    m = 0
    while True:
        first = -1
        pick = -1
        for lane in range(k):
            if starts[lane] + at[lane] < starts[lane + 1]:
                x = src[starts[lane] + at[lane]]
                if first < 0:
                    first = x
                free = True
                for other in range(k):
                    if pos[other, x] > at[other]:
                        free = False
                        break
                if free:
                    pick = x
                    break
        if first < 0:
            return merged[:m], weights[:m]
        if pick < 0:
            pick = first
        merged[m] = pick
        for lane in range(k):
            i = starts[lane] + at[lane]
            if i < starts[lane + 1] and src[i] == pick:
                weights[m, lane] = w[i]
                at[lane] += 1
        m += 1


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

    The nodes are summed four at a time along :func:`lane_layout`'s rows, each group the
    way its kind says; each node's sum is the sequential one's (its inputs in order, with
    only exact zeros between them). Groups that read one input per row load it once for
    all four lanes; groups of sum nodes keep no sum of inputs.
    """
    group_start = program.group_start
    group_kind = program.group_kind
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
        kind = group_kind[g]
        if kind == GROUP_UNION:
            for r in range(row_start[g], row_start[g + 1]):
                v = values[row_src[r, 0]]
                n0 += row_w[r, 0] * v
                n1 += row_w[r, 1] * v
                n2 += row_w[r, 2] * v
                n3 += row_w[r, 3] * v
        elif kind == GROUP_SHARED:
            for r in range(row_start[g], row_start[g + 1]):
                v = values[row_src[r, 0]]
                n0 += row_w[r, 0] * v
                n1 += row_w[r, 1] * v
                n2 += row_w[r, 2] * v
                n3 += row_w[r, 3] * v
                d0 += v
            d1 = d2 = d3 = d0
        elif kind == GROUP_SEPARATE_SUM:
            for r in range(row_start[g], row_start[g + 1]):
                n0 += row_w[r, 0] * values[row_src[r, 0]]
                n1 += row_w[r, 1] * values[row_src[r, 1]]
                n2 += row_w[r, 2] * values[row_src[r, 2]]
                n3 += row_w[r, 3] * values[row_src[r, 3]]
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
