"""The ANT genome: cell genes plus a tissue gene (paper, section 3.4).

A genome is the developmental program of a tissue. Each :class:`CellGene` describes one
neuron (motor or decision) at a lattice position given relative to the seed address of
the :class:`TissueGene`; its activation flag (``expressed``) decides whether the cell is
grown at all, and its cell-death flag (``dead``) whether a grown cell stays dormant while
still occupying its lattice site. The tissue gene carries the replication probability,
the decision-to-motor ratio used for new cells, the seed address and, optionally, the
number of robots N when N is evolved (paper, section 5.4).

Genes hold every parameter of both kinds so that gene duplication can copy part of a
parent into a daughter of either kind; the fields a kind does not use are ignored (and are
not written to genome files).

The genotype is kept apart from the runnable network: :mod:`ant_controller.tissue`
develops and compiles it. Everything here is pure and immutable; random genomes take an
explicit ``numpy.random.Generator``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ant_controller.layout import N_BEHAVIOURS, N_SENSORS

MOTOR = "motor"
DECISION = "decision"
KINDS = (MOTOR, DECISION)

N_NOMINAL_INPUTS = 9
"""A motor neuron above layer 1 reads the 3 x 3 neurons centred one layer below."""

MAX_EXTENT = 4
"""Largest half-extent of a decision neuron's field along one axis."""


@dataclass(frozen=True)
class Lattice:
    """The 3-D lattice the tissue grows in.

    Attributes:
        half_width: Positions ``l, m`` run over ``-half_width .. half_width``.
        layers: Motor layers above the sensor layer; layer 1 reads every sensor and layer
            ``n > 1`` reads 3 x 3 neurons of layer ``n - 1``. With the sensor layer this
            gives at most ``layers + 1`` layers in all (the paper's four for 3).
    """

    half_width: int = 8
    layers: int = 3

    def contains(self, pos: tuple[int, int, int]) -> bool:
        """True when an absolute position lies inside the lattice."""
        l, m, n = pos
        return abs(l) <= self.half_width and abs(m) <= self.half_width and 1 <= n <= self.layers


DEFAULT_LATTICE = Lattice()


@dataclass(frozen=True)
class CellGene:
    """One neuron's gene.

    Attributes:
        kind: ``"motor"`` or ``"decision"``.
        expressed: Activation flag; a repressed gene grows no cell.
        dead: Cell-death flag; the cell occupies its site but never fires.
        position: ``(l, m, n)`` relative to the tissue's seed address.
        replication: This cell's replication probability; the parent of a new cell is the
            one with the highest value.
        theta1: First threshold of the modular activation function.
        theta2: Second threshold.
        k1: Selector bit (0 or 1) of the activation function.
        k2: Selector bit (0 or 1) of the activation function.
        sensor_weights: One weight per sensor (decision neurons, layer-1 motor neurons).
        input_weights: Nine weights for the 3 x 3 nominal inputs (motor neurons above
            layer 1), ordered by ``(dl, dm)`` from ``(-1, -1)`` to ``(1, 1)``.
        behaviour: Behaviour (0-based Table 2 index) this neuron votes for when it lies in
            the output layer (motor neurons).
        concentration: Chemical concentration released when firing (decision neurons).
        extent: Half-extents ``(d_l, d_m, d_n)`` of the box-shaped field (decision).
    """

    kind: str
    expressed: bool
    dead: bool
    position: tuple[int, int, int]
    replication: float
    theta1: float
    theta2: float
    k1: int
    k2: int
    sensor_weights: tuple[float, ...]
    input_weights: tuple[float, ...]
    behaviour: int = 0
    concentration: float = 1.0
    extent: tuple[int, int, int] = (1, 1, 1)


@dataclass(frozen=True)
class TissueGene:
    """Parameters of the whole tissue.

    Attributes:
        replication_probability: Probability that mutation inserts a new cell.
        decision_ratio: Probability that a new cell is a decision neuron.
        seed: Absolute lattice address that cell positions are relative to.
        robots: Number of robots N when it is evolved, else ``None``.
    """

    replication_probability: float = 0.05
    decision_ratio: float = 0.2
    seed: tuple[int, int, int] = (0, 0, 1)
    robots: int | None = None


@dataclass(frozen=True)
class Genome:
    """A complete ANT genome.

    Attributes:
        tissue: The tissue gene.
        cells: Cell genes in development order.
        lattice: Lattice bounds the tissue grows in.
        coarse_coding: When False, every motor neuron is active (decision neurons are
            ignored): the paper's "ANT without coarse coding".
    """

    tissue: TissueGene
    cells: tuple[CellGene, ...]
    lattice: Lattice = DEFAULT_LATTICE
    coarse_coding: bool = True
    metadata: dict = field(default_factory=dict, compare=False, hash=False)

    def absolute(self, gene: CellGene) -> tuple[int, int, int]:
        """Absolute lattice position of a cell gene."""
        s = self.tissue.seed
        p = gene.position
        return (s[0] + p[0], s[1] + p[1], s[2] + p[2])

    @property
    def n_cells(self) -> int:
        """Number of cell genes (expressed or not)."""
        return len(self.cells)


def random_cell(rng: np.random.Generator, kind: str, position: tuple[int, int, int]) -> CellGene:
    """A cell gene with every parameter drawn uniformly from its range.

    Ranges: weights and thresholds in ``[-1, 1]``, replication and concentration in
    ``[0, 1]``, selector bits, behaviour and field half-extents uniform over their values.
    """
    return CellGene(
        kind=kind,
        expressed=True,
        dead=False,
        position=tuple(int(v) for v in position),
        replication=float(rng.uniform(0.0, 1.0)),
        theta1=float(rng.uniform(-1.0, 1.0)),
        theta2=float(rng.uniform(-1.0, 1.0)),
        k1=int(rng.integers(0, 2)),
        k2=int(rng.integers(0, 2)),
        sensor_weights=tuple(float(w) for w in rng.uniform(-1.0, 1.0, N_SENSORS)),
        input_weights=tuple(float(w) for w in rng.uniform(-1.0, 1.0, N_NOMINAL_INPUTS)),
        behaviour=int(rng.integers(0, N_BEHAVIOURS)),
        concentration=float(rng.uniform(0.0, 1.0)),
        extent=tuple(int(v) for v in rng.integers(0, MAX_EXTENT + 1, 3)),
    )


def random_genome(
    rng: np.random.Generator,
    n_neurons: tuple[int, int] = (40, 120),
    lattice: Lattice = DEFAULT_LATTICE,
    coarse_coding: bool = True,
    robots: int | None = None,
) -> Genome:
    """A random tissue as in the paper's initial population (40 to 120 neurons).

    Neurons take distinct sites in a square patch around the seed, spread over every
    layer, so that nominal 3 x 3 inputs overlap; the patch is as small as the neuron count
    allows. The decision-neuron share is drawn from ``[0.1, 0.4]``.

    Args:
        rng: Source of randomness.
        n_neurons: Inclusive range of the neuron count.
        lattice: Lattice bounds.
        coarse_coding: Coarse-coding switch stored in the genome.
        robots: Initial N gene, or ``None`` when N is not evolved.
    """
    n = int(rng.integers(n_neurons[0], n_neurons[1] + 1))
    ratio = float(rng.uniform(0.1, 0.4))
    per_layer = -(-n // lattice.layers)
    half = min(lattice.half_width, int(np.ceil((np.sqrt(per_layer * 1.5) - 1) / 2)))
    side = 2 * half + 1
    if side * side * lattice.layers < n:
        raise ValueError(f"{n} neurons do not fit a lattice of half-width {lattice.half_width}")
    sites = rng.choice(side * side * lattice.layers, size=n, replace=False)
    seed = (0, 0, 1)
    cells = []
    for s in sites:
        layer, rest = divmod(int(s), side * side)
        l, m = divmod(rest, side)
        pos = (l - half - seed[0], m - half - seed[1], layer + 1 - seed[2])
        kind = DECISION if rng.uniform() < ratio else MOTOR
        cells.append(random_cell(rng, kind, pos))
    tissue = TissueGene(
        replication_probability=float(rng.uniform(0.0, 0.1)),
        decision_ratio=ratio,
        seed=seed,
        robots=robots,
    )
    return Genome(tissue, tuple(cells), lattice, coarse_coding)
