"""Development of a genome into a tissue, and the tissue's computation (paper, 3.1-3.3).

``develop`` grows the cells of a genome on the lattice; ``compile_tissue`` flattens the
grown tissue into arrays once (a :class:`TissueRecord`, the form the kernels take, its
fields read by name); ``decide`` (numba) and ``decide_reference`` (plain Python, written
for reading) map a sensor vector to a behaviour bit mask. Tests hold the two to
bit-identical answers. :func:`activation` is the one modular activation function of the
code base (the network baselines and both forms here call it).

The computation of one decision, in order:

1. Sensor codes become input states ``x_i = code_i / (states_i - 1)`` in ``[0, 1]``.
2. Every living decision neuron computes ``sigma = sum(v_i x_i) / sum(x_i)`` (0 when the
   sum of inputs is 0) and its modular activation; a firing neuron releases its
   concentration ``c`` uniformly over its box field ``|dl| <= d_l, |dm| <= d_m,
   |dn| <= d_n``.
3. **Highest-concentration rule.** Each motor neuron's concentration is the sum of the
   fields covering it (added in decision-neuron order). The active motor neurons are those
   whose concentration equals the largest one, provided it is above zero; when no field
   reaches a motor neuron, none is active. With coarse coding off every motor neuron is
   active.
4. Active motor neurons compute, layer by layer, ``sigma = sum(w s) / sum(s)`` over their
   inputs (layer 1: all sensors; layer n > 1: the living neurons among the 3 x 3 sites
   centred below them; dormant neurons have ``s = 0``) and their modular activation.
   Dormant motor neurons have state 0.
5. Output neurons are the living motor neurons of the highest layer that holds any. Each
   votes for its behaviour; behaviour q fires when the mean vote of the *active* output
   neurons connected to q is at least 0.5 (never when none is active).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numba as nb
import numpy as np

from ant_controller.genome import DECISION, MOTOR, Genome
from ant_controller.layout import N_BEHAVIOURS, N_SENSORS, SENSOR_SCALE


@dataclass(frozen=True)
class Cell:
    """A grown cell.

    Attributes:
        gene: Index of its gene in the genome.
        kind: ``"motor"`` or ``"decision"``.
        position: Absolute lattice position ``(l, m, n)``.
        dead: Dormant for good (cell death).
    """

    gene: int
    kind: str
    position: tuple[int, int, int]
    dead: bool


def develop(genome: Genome) -> list[Cell]:
    """Grow the genome's cells: expressed genes only, first gene wins a lattice site.

    Cells outside the lattice are not grown (the loader rejects such files; mutation never
    makes them).
    """
    taken: set[tuple[int, int, int]] = set()
    cells = []
    for i, gene in enumerate(genome.cells):
        if not gene.expressed:
            continue
        pos = genome.absolute(gene)
        if pos in taken or not genome.lattice.contains(pos):
            continue
        taken.add(pos)
        cells.append(Cell(i, gene.kind, pos, gene.dead))
    return cells


class TissueRecord(NamedTuple):
    """A compiled tissue as the numba kernels take it (fields by name, never by position).

    Attributes:
        mn_layer: ``int64 [M]`` layer of each living motor neuron (sorted by layer, l, m).
        mn_func: ``int64 [M]`` activation function ``k1 * 2 + k2``.
        mn_theta: ``float64 [M, 2]`` thresholds.
        mn_sensor_w: ``float64 [M, 14]`` sensor weights (layer 1).
        mn_in_idx: ``int64 [M, 9]`` motor neuron at each of the 3 x 3 sites below, -1: none.
        mn_in_w: ``float64 [M, 9]`` weights of those inputs.
        mn_behaviour: ``int64 [M]`` behaviour an output neuron votes for, -1: not an output.
        dn_func: ``int64 [D]`` decision neurons' activation functions.
        dn_theta: ``float64 [D, 2]`` their thresholds.
        dn_sensor_w: ``float64 [D, 14]`` their sensor weights.
        dn_conc: ``float64 [D]`` their concentration c.
        dn_member: ``bool [D, M]`` motor neuron j lies in decision neuron d's field.
        coarse_coding: False: every motor neuron is always active.
    """

    mn_layer: np.ndarray
    mn_func: np.ndarray
    mn_theta: np.ndarray
    mn_sensor_w: np.ndarray
    mn_in_idx: np.ndarray
    mn_in_w: np.ndarray
    mn_behaviour: np.ndarray
    dn_func: np.ndarray
    dn_theta: np.ndarray
    dn_sensor_w: np.ndarray
    dn_conc: np.ndarray
    dn_member: np.ndarray
    coarse_coding: bool


class TissueScratch(NamedTuple):
    """Work buffers of one decision (:func:`new_scratch`), sized for one tissue."""

    x: np.ndarray
    active: np.ndarray
    conc: np.ndarray
    state: np.ndarray
    votes: np.ndarray
    voters: np.ndarray


@dataclass(frozen=True)
class CompiledTissue:
    """A developed tissue as flat arrays, ready for :func:`decide`.

    Motor neurons are sorted by (layer, l, m) so that one pass computes them in order.
    ``dn_member[d, j]`` says whether motor neuron j lies in decision neuron d's field.
    """

    mn_layer: np.ndarray  # int64 [M]
    mn_func: np.ndarray  # int64 [M]  k1 * 2 + k2
    mn_theta: np.ndarray  # float64 [M, 2]
    mn_sensor_w: np.ndarray  # float64 [M, 14]
    mn_in_idx: np.ndarray  # int64 [M, 9], -1 = no neuron at that site
    mn_in_w: np.ndarray  # float64 [M, 9]
    mn_behaviour: np.ndarray  # int64 [M], -1 = not an output neuron
    dn_func: np.ndarray  # int64 [D]
    dn_theta: np.ndarray  # float64 [D, 2]
    dn_sensor_w: np.ndarray  # float64 [D, 14]
    dn_conc: np.ndarray  # float64 [D]
    dn_member: np.ndarray  # bool [D, M]
    coarse_coding: bool
    motor_genes: tuple[int, ...]
    decision_genes: tuple[int, ...]

    @property
    def n_motor(self) -> int:
        """Living motor neurons."""
        return int(self.mn_layer.shape[0])

    @property
    def n_decision(self) -> int:
        """Living decision neurons."""
        return int(self.dn_conc.shape[0])

    @property
    def n_outputs(self) -> int:
        """Output neurons (living motor neurons of the top occupied layer)."""
        return int(np.count_nonzero(self.mn_behaviour >= 0))

    def record(self) -> TissueRecord:
        """The arrays as a :class:`TissueRecord`, the form the kernels take."""
        return TissueRecord(
            mn_layer=self.mn_layer,
            mn_func=self.mn_func,
            mn_theta=self.mn_theta,
            mn_sensor_w=self.mn_sensor_w,
            mn_in_idx=self.mn_in_idx,
            mn_in_w=self.mn_in_w,
            mn_behaviour=self.mn_behaviour,
            dn_func=self.dn_func,
            dn_theta=self.dn_theta,
            dn_sensor_w=self.dn_sensor_w,
            dn_conc=self.dn_conc,
            dn_member=self.dn_member,
            coarse_coding=bool(self.coarse_coding),
        )


def compile_tissue(genome: Genome, coarse_coding: bool | None = None) -> CompiledTissue:
    """Develop ``genome`` and flatten the living cells into arrays.

    Args:
        genome: The genome.
        coarse_coding: Override the genome's coarse-coding switch.
    """
    cells = [c for c in develop(genome) if not c.dead]
    motor = sorted(
        (c for c in cells if c.kind == MOTOR),
        key=lambda c: (c.position[2], c.position[0], c.position[1]),
    )
    decision = [c for c in cells if c.kind == DECISION]
    index = {c.position: j for j, c in enumerate(motor)}
    top = max((c.position[2] for c in motor), default=0)
    m, d = len(motor), len(decision)
    mn_layer = np.zeros(m, dtype=np.int64)
    mn_func = np.zeros(m, dtype=np.int64)
    mn_theta = np.zeros((m, 2), dtype=np.float64)
    mn_sensor_w = np.zeros((m, N_SENSORS), dtype=np.float64)
    mn_in_idx = np.full((m, 9), -1, dtype=np.int64)
    mn_in_w = np.zeros((m, 9), dtype=np.float64)
    mn_behaviour = np.full(m, -1, dtype=np.int64)
    for j, c in enumerate(motor):
        g = genome.cells[c.gene]
        l, mm, n = c.position
        mn_layer[j] = n
        mn_func[j] = g.k1 * 2 + g.k2
        mn_theta[j] = (g.theta1, g.theta2)
        mn_sensor_w[j] = g.sensor_weights
        mn_in_w[j] = g.input_weights
        if n > 1:
            for a, dl in enumerate((-1, 0, 1)):
                for b, dm in enumerate((-1, 0, 1)):
                    mn_in_idx[j, 3 * a + b] = index.get((l + dl, mm + dm, n - 1), -1)
        if n == top:
            mn_behaviour[j] = g.behaviour
    dn_func = np.zeros(d, dtype=np.int64)
    dn_theta = np.zeros((d, 2), dtype=np.float64)
    dn_sensor_w = np.zeros((d, N_SENSORS), dtype=np.float64)
    dn_conc = np.zeros(d, dtype=np.float64)
    dn_member = np.zeros((d, m), dtype=np.bool_)
    for i, c in enumerate(decision):
        g = genome.cells[c.gene]
        dn_func[i] = g.k1 * 2 + g.k2
        dn_theta[i] = (g.theta1, g.theta2)
        dn_sensor_w[i] = g.sensor_weights
        dn_conc[i] = g.concentration
        for j, mc in enumerate(motor):
            dn_member[i, j] = all(
                abs(mc.position[a] - c.position[a]) <= g.extent[a] for a in range(3)
            )
    return CompiledTissue(
        mn_layer,
        mn_func,
        mn_theta,
        mn_sensor_w,
        mn_in_idx,
        mn_in_w,
        mn_behaviour,
        dn_func,
        dn_theta,
        dn_sensor_w,
        dn_conc,
        dn_member,
        genome.coarse_coding if coarse_coding is None else coarse_coding,
        tuple(c.gene for c in motor),
        tuple(c.gene for c in decision),
    )


# --- the modular activation function ----------------------------------------------------------


@nb.njit(cache=True, inline="always")
def activation(func, theta1, theta2, sigma):
    """The modular activation function psi, ``func = k1 * 2 + k2`` (paper, section 3.3).

    The paper writes it as one sum of the four terms,
    ``psi = (1 - k1)((1 - k2) psi_down + k2 psi_up) + k1((1 - k2) psi_ditch + k2 psi_mound)``;
    exactly one term is selected, so this evaluates only that one:
    0: psi_down (``0 if sigma >= theta1 else 1``), 1: psi_up (``0 if sigma <= theta2``),
    2: psi_ditch (``0 if min <= sigma < max``), 3: psi_mound (``0 if sigma <= min or
    sigma > max``), with ``min, max`` of the two thresholds.
    """
    if func == 0:
        return 0 if sigma >= theta1 else 1
    if func == 1:
        return 0 if sigma <= theta2 else 1
    lo = min(theta1, theta2)
    hi = max(theta1, theta2)
    if func == 2:
        return 0 if lo <= sigma < hi else 1
    return 0 if (sigma <= lo or sigma > hi) else 1


@nb.njit(cache=True)
def new_scratch(tissue):
    """Work buffers for :func:`decide_into`, sized for one :class:`TissueRecord`."""
    m = tissue.mn_layer.shape[0]
    return TissueScratch(
        np.empty(N_SENSORS, dtype=np.float64),
        np.empty(m, dtype=np.bool_),
        np.empty(m, dtype=np.float64),
        np.empty(m, dtype=np.int64),
        np.empty(N_BEHAVIOURS, dtype=np.int64),
        np.empty(N_BEHAVIOURS, dtype=np.int64),
    )


@nb.njit(cache=True)
def decide(codes, tissue):
    """Behaviour bit mask for one sensor vector (numba kernel; see the module docstring).

    Args:
        codes: Integer sensor vector (length 14).
        tissue: A :class:`TissueRecord` (:meth:`CompiledTissue.record`).
    """
    return decide_into(codes, tissue, new_scratch(tissue))


@nb.njit(cache=True, inline="always")
def decide_into(codes, tissue, scratch):
    """:func:`decide` with caller-owned work buffers (:func:`new_scratch`); allocates nothing."""
    mn_layer = tissue.mn_layer
    mn_func = tissue.mn_func
    mn_theta = tissue.mn_theta
    mn_sensor_w = tissue.mn_sensor_w
    mn_in_idx = tissue.mn_in_idx
    mn_in_w = tissue.mn_in_w
    mn_behaviour = tissue.mn_behaviour
    dn_func = tissue.dn_func
    dn_theta = tissue.dn_theta
    dn_sensor_w = tissue.dn_sensor_w
    dn_conc = tissue.dn_conc
    dn_member = tissue.dn_member
    x = scratch.x
    active = scratch.active
    conc = scratch.conc
    state = scratch.state
    votes = scratch.votes
    voters = scratch.voters
    n_s = codes.shape[0]
    sx = 0.0
    for i in range(n_s):
        x[i] = codes[i] * SENSOR_SCALE[i]
        sx += x[i]
    m = mn_layer.shape[0]
    if tissue.coarse_coding:
        conc[:] = 0.0
        for d in range(dn_conc.shape[0]):
            num = 0.0
            for i in range(n_s):
                num += dn_sensor_w[d, i] * x[i]
            sigma = num / sx if sx != 0.0 else 0.0
            if activation(dn_func[d], dn_theta[d, 0], dn_theta[d, 1], sigma) == 1:
                for j in range(m):
                    if dn_member[d, j]:
                        conc[j] += dn_conc[d]
        best = 0.0
        for j in range(m):
            if conc[j] > best:
                best = conc[j]
        for j in range(m):
            active[j] = best > 0.0 and conc[j] == best
    else:
        active[:] = True
    state[:] = 0
    for j in range(m):
        if not active[j]:
            continue
        num = 0.0
        den = 0.0
        if mn_layer[j] == 1:
            for i in range(n_s):
                num += mn_sensor_w[j, i] * x[i]
            den = sx
        else:
            for a in range(9):
                src = mn_in_idx[j, a]
                if src >= 0 and state[src] != 0:
                    num += mn_in_w[j, a] * state[src]
                    den += state[src]
        sigma = num / den if den != 0.0 else 0.0
        state[j] = activation(mn_func[j], mn_theta[j, 0], mn_theta[j, 1], sigma)
    votes[:] = 0
    voters[:] = 0
    for j in range(m):
        q = mn_behaviour[j]
        if q >= 0 and active[j]:
            voters[q] += 1
            votes[q] += state[j]
    mask = 0
    for q in range(N_BEHAVIOURS):
        if voters[q] > 0 and 2 * votes[q] >= voters[q]:
            mask |= 1 << q
    return mask


def decide_tissue(tissue: CompiledTissue, codes: np.ndarray) -> int:
    """:func:`decide` for a compiled tissue and one integer sensor vector."""
    return int(decide(np.asarray(codes, dtype=np.int64), tissue.record()))


# --- plain reference -------------------------------------------------------------------------


def decide_reference(genome: Genome, codes, coarse_coding: bool | None = None) -> int:
    """Behaviour mask computed straight from the developed cells, for reading and testing.

    Slow on purpose: no precomputed arrays, every rule spelled out over lattice positions
    (the activation itself is the one :func:`activation`).
    """
    use_cc = genome.coarse_coding if coarse_coding is None else coarse_coding
    cells = [c for c in develop(genome) if not c.dead]
    x = [float(codes[i]) * float(SENSOR_SCALE[i]) for i in range(N_SENSORS)]
    sx = 0.0
    for v in x:
        sx += v
    motor = sorted(
        (c for c in cells if c.kind == MOTOR),
        key=lambda c: (c.position[2], c.position[0], c.position[1]),
    )
    decision = [c for c in cells if c.kind == DECISION]

    def weighted(weights, states, total):
        num = 0.0
        for w, s in zip(weights, states, strict=True):
            num += w * s
        return num / total if total != 0.0 else 0.0

    concentration = {c.position: 0.0 for c in motor}
    for c in decision:
        g = genome.cells[c.gene]
        if activation(g.k1 * 2 + g.k2, g.theta1, g.theta2, weighted(g.sensor_weights, x, sx)) != 1:
            continue
        for mc in motor:
            if all(abs(mc.position[a] - c.position[a]) <= g.extent[a] for a in range(3)):
                concentration[mc.position] += g.concentration
    if use_cc:
        peak = max(concentration.values(), default=0.0)
        active = {p for p, v in concentration.items() if peak > 0.0 and v == peak}
    else:
        active = set(concentration)
    state: dict[tuple[int, int, int], int] = {}
    for c in motor:
        g = genome.cells[c.gene]
        l, m, n = c.position
        if c.position not in active:
            state[c.position] = 0
            continue
        if n == 1:
            sigma = weighted(g.sensor_weights, x, sx)
        else:
            num = 0.0
            den = 0.0
            for a, dl in enumerate((-1, 0, 1)):
                for b, dm in enumerate((-1, 0, 1)):
                    s = state.get((l + dl, m + dm, n - 1), 0)
                    if s:
                        num += g.input_weights[3 * a + b] * s
                        den += s
            sigma = num / den if den != 0.0 else 0.0
        state[c.position] = int(activation(g.k1 * 2 + g.k2, g.theta1, g.theta2, sigma))
    top = max((c.position[2] for c in motor), default=0)
    mask = 0
    for q in range(N_BEHAVIOURS):
        voters = [
            state[c.position]
            for c in motor
            if c.position[2] == top and c.position in active and genome.cells[c.gene].behaviour == q
        ]
        if voters and sum(voters) / len(voters) >= 0.5:
            mask |= 1 << q
    return mask
