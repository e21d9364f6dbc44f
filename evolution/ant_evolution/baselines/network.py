"""Network programs: the flat-array form of a feed-forward network, and its batched runner.

A :class:`NetworkProgram` lists the network's non-input nodes in evaluation order; node j
reads the inputs ``edge_src[edge_start[j]:edge_start[j + 1]]`` (index ``i < 14``: sensor
i; ``14 + k``: node k, which comes earlier) with weights ``edge_w``. Its value is

* ``AGG_MEAN`` (the ANT neuron of section 3.2, used by the fixed-topology baseline):
  ``sigma = sum(w v) / sum(v)`` (0 when the sum of inputs is 0), then the activation;
* ``AGG_SUM`` (neat-python's ``sum`` aggregation): ``bias + response * sum(w v)``, then the
  activation.

Activations: ``0..3`` the modular activation function (``k1 * 2 + k2``, as
:func:`ant_controller.tissue.activation`), ``ACT_SIGMOID`` neat-python's sigmoid
(``1 / (1 + exp(-clamp(5 z, -60, 60)))``), ``ACT_IDENTITY``. Behaviour q fires when its
output node's value is at least 0.5 (never when ``out_node[q] == -1``). Sensor inputs are
``code_i / (states_i - 1)``, exactly what an ANT tissue sees.

:func:`run_program_scenarios` is the evaluator's second kernel path: the same world step
(:func:`excavation_sim.world.sense_all` / ``apply_all``), the same scenario sets and the same
per-network decision cache as :func:`ant_evolution.evaluate.run_scenarios`, with the
network program in place of the tissue. :func:`decide_program_reference` is the plain
Python forward pass the tests hold the kernel to.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numba as nb
import numpy as np

from ant_controller.layout import N_BEHAVIOURS, N_SENSORS, SENSOR_SCALE
from ant_controller.tissue import CACHE_BITS, activation, sensor_key
from ant_evolution.backends import _chunks, start_workers
from ant_evolution.evaluate import ScenarioSet
from excavation_sim.world import apply_all, fitness, sense_all

AGG_MEAN = 0
AGG_SUM = 1
ACT_SIGMOID = 4
ACT_IDENTITY = 5


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
        if self.edge_start.shape != (n + 1,) or self.out_node.shape != (N_BEHAVIOURS,):
            raise ValueError("network program: edge_start must have N + 1 and out_node 12 entries")
        for j in range(n):
            src = self.edge_src[self.edge_start[j] : self.edge_start[j + 1]]
            if src.size and (src.min() < 0 or src.max() >= N_SENSORS + j):
                raise ValueError(f"network program: node {j} reads a node that comes later")

    @property
    def n_nodes(self) -> int:
        """Non-input nodes."""
        return int(self.node_act.shape[0])

    @property
    def n_edges(self) -> int:
        """Connections."""
        return int(self.edge_w.shape[0])

    def arrays(self) -> tuple:
        """The arrays as one tuple, the form the kernels take."""
        return (
            self.node_act,
            self.node_agg,
            self.node_bias,
            self.node_resp,
            self.node_theta,
            self.edge_start,
            self.edge_src,
            self.edge_w,
            self.out_node,
        )


@nb.njit(cache=True, inline="always")
def _node_activation(act, theta1, theta2, z):
    if act < 4:
        return float(activation(act, theta1, theta2, z))
    if act == ACT_SIGMOID:
        z = max(-60.0, min(60.0, 5.0 * z))
        return 1.0 / (1.0 + math.exp(-z))
    return z


@nb.njit(cache=True, inline="always")
def program_decide_into(codes, program, values):
    """Behaviour mask of one sensor vector; ``values`` (length 14 + N) is scratch."""
    (
        node_act,
        node_agg,
        node_bias,
        node_resp,
        node_theta,
        edge_start,
        edge_src,
        edge_w,
        out_node,
    ) = program
    n_s = codes.shape[0]
    for i in range(n_s):
        values[i] = codes[i] * SENSOR_SCALE[i]
    for j in range(node_act.shape[0]):
        num = 0.0
        den = 0.0
        for e in range(edge_start[j], edge_start[j + 1]):
            v = values[edge_src[e]]
            num += edge_w[e] * v
            den += v
        if node_agg[j] == AGG_MEAN:
            z = num / den if den != 0.0 else 0.0
        else:
            z = node_bias[j] + node_resp[j] * num
        values[n_s + j] = _node_activation(node_act[j], node_theta[j, 0], node_theta[j, 1], z)
    mask = 0
    for q in range(out_node.shape[0]):
        o = out_node[q]
        if o >= 0 and values[n_s + o] >= 0.5:
            mask |= 1 << q
    return mask


@nb.njit(cache=True)
def program_decide(codes, program):
    """:func:`program_decide_into` with its own scratch (for single calls and tests)."""
    values = np.zeros(N_SENSORS + program[0].shape[0])
    return program_decide_into(codes, program, values)


@nb.njit(cache=True, _nrt=False, error_model="numpy")
def _run_program_steps(
    heights, zones, goal, robots, active, rng, params, steps, program, keys, masks_cache,
    values, codes, masks,
):  # fmt: skip
    """The per-step loop of a network program (no reference counting, no allocation)."""
    n = robots.shape[0]
    for _t in range(steps):
        sense_all(heights, zones, goal, robots, active, codes)
        for k in range(n):
            if not active[k]:
                masks[k] = 0
                continue
            key = sensor_key(codes[k])
            slot = (np.uint64(key) * np.uint64(0x9E3779B97F4A7C15)) >> np.uint64(64 - CACHE_BITS)
            if keys[slot] == key:
                masks[k] = masks_cache[slot]
            else:
                m = program_decide_into(codes[k], program, values)
                keys[slot] = key
                masks_cache[slot] = m
                masks[k] = m
        apply_all(heights, robots, active, masks, rng, params)


@nb.njit(cache=True)
def run_program_scenarios(
    heights0, zones, goal, robots0, active0, rng0, params, steps, program, n_robots, scores
):
    """Score one network program on every scenario of a set (as ``run_scenarios``)."""
    keys = np.full(1 << CACHE_BITS, -1, dtype=np.int64)
    masks_cache = np.zeros(1 << CACHE_BITS, dtype=np.int64)
    values = np.zeros(N_SENSORS + program[0].shape[0])
    n = robots0.shape[1]
    codes = np.zeros((n, N_SENSORS), dtype=np.int64)
    masks = np.zeros(n, dtype=np.int64)
    heights = np.empty_like(heights0[0])
    robots = np.empty_like(robots0[0])
    active = np.empty_like(active0[0])
    rng = np.empty(1, dtype=np.uint64)
    for s in range(heights0.shape[0]):
        heights[:] = heights0[s]
        robots[:] = robots0[s]
        active[:] = active0[s]
        if n_robots > 0:
            for k in range(n):
                active[k] = k < n_robots
        rng[0] = rng0[s]
        _run_program_steps(
            heights, zones, goal, robots, active, rng, params, steps, program, keys,
            masks_cache, values, codes, masks,
        )  # fmt: skip
        scores[s] = fitness(heights, zones, goal)


def score_program(program: NetworkProgram, scenarios: ScenarioSet, n_robots: int = 0) -> np.ndarray:
    """Final fitness of ``program`` on every scenario of a set (``n_robots``: 0 = the set's)."""
    scores = np.zeros(scenarios.size)
    run_program_scenarios(
        scenarios.heights,
        scenarios.zones,
        scenarios.goal,
        scenarios.robots,
        scenarios.active,
        scenarios.rng,
        scenarios.params,
        scenarios.steps,
        program.arrays(),
        n_robots,
        scores,
    )
    return scores


def program_fitness(program: NetworkProgram, sets: list[ScenarioSet]) -> float:
    """Mean final fitness over every scenario of every set."""
    return float(np.concatenate([score_program(program, s) for s in sets]).mean())


def _fitness_chunk(payload: tuple) -> list[float]:
    items, sets, compile_fn = payload
    programs = items if compile_fn is None else [compile_fn(x) for x in items]
    return [program_fitness(p, sets) for p in programs]


class ProgramEvaluator:
    """Scores lists of network programs: in this process, a process pool, or Ray.

    The same chunking as :class:`ant_evolution.backends.Evaluator`; fitness is a pure
    function of (program, scenarios), so every backend and worker count gives the same
    numbers.

    Args:
        workers: Local processes (``None`` or 1: this process).
        ray_address: Ray address (``"local"`` for a private local Ray), or ``None``.
    """

    def __init__(self, workers: int | None = 1, ray_address: str | None = None) -> None:
        self.workers = max(1, workers or 1)
        self._pool, self._ray, self._remote, self.workers = start_workers(
            self.workers, ray_address, _fitness_chunk
        )

    def evaluate(
        self, items: list, sets: list[ScenarioSet], compile_fn: Callable | None = None
    ) -> np.ndarray:
        """Fitness of every program (same order).

        Args:
            items: Network programs, or anything ``compile_fn`` turns into one.
            sets: The scenario sets.
            compile_fn: Picklable function run in the workers on every item (NEAT genomes
                compile there, in parallel, instead of in this process).
        """
        if self._ray is None and self._pool is None:
            return np.array(_fitness_chunk((items, sets, compile_fn)))
        chunks = _chunks(list(items), self.workers)
        if self._ray is not None:
            ref = self._ray.put(sets)
            results = self._ray.get([self._remote.remote((c, ref, compile_fn)) for c in chunks])
        else:
            payloads = [(c, sets, compile_fn) for c in chunks]
            results = list(self._pool.map(_fitness_chunk, payloads))
        return np.array([f for chunk in results for f in chunk])

    def close(self) -> None:
        """Stop the worker processes."""
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

    def __enter__(self) -> ProgramEvaluator:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


# --- plain reference -------------------------------------------------------------------------


def _psi(func: int, t1: float, t2: float, sigma: float) -> int:
    k1, k2 = divmod(func, 2)
    down = 0 if sigma >= t1 else 1
    up = 0 if sigma <= t2 else 1
    ditch = 0 if min(t1, t2) <= sigma < max(t1, t2) else 1
    mound = 0 if (sigma <= min(t1, t2) or sigma > max(t1, t2)) else 1
    return (1 - k1) * ((1 - k2) * down + k2 * up) + k1 * ((1 - k2) * ditch + k2 * mound)


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
            nodes.append(float(_psi(act, t1, t2, z)))
        elif act == ACT_SIGMOID:
            nodes.append(1.0 / (1.0 + math.exp(-max(-60.0, min(60.0, 5.0 * z)))))
        else:
            nodes.append(z)
    mask = 0
    for q, o in enumerate(program.out_node):
        if o >= 0 and nodes[o] >= 0.5:
            mask |= 1 << q
    return mask, nodes
