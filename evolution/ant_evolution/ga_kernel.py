"""Breeding on arrays: the packed form of a genome's cell genes, and ``v1``'s mutation compiled.

:class:`PackedCells` holds a genome's cell genes as rows of read-only arrays and builds a
``CellGene`` object only when something reads it; :func:`mutate_cells`,
:func:`mutate_by_slots`, :func:`crossover_packed`, :func:`append_cell` and
:func:`with_genes` give :mod:`ant_evolution.ga`'s operators their children on rows, the
same children and draws as the Python operators (the specification, which handles every
genome these do not). :func:`mutate_by_slots` is the ``paper`` profile's mutation (by
slots: per gene or per parameter, redrawn or perturbed), compiled as below.

``v1``'s per-parameter mutation, compiled, draw for draw:

:func:`ant_evolution.ga.mutate_cell` is the specification: every parameter of a cell gene
mutates with probability p, drawing from the GA's ``numpy.random.Generator`` in a fixed
order. Run gene by gene in Python it was most of a generation's breeding (about 40 us per
gene, 8,600 genes per generation at P = 100). :func:`mutate_cells` gives the same genes
from the same generator state, and leaves the generator where the Python loop would have:

* It takes a block of the generator's raw 64-bit outputs (``random_raw``) and turns them
  into draws as numpy's ``Generator`` does for PCG64: a double is the top 53 bits of one
  output; ``uniform(lo, hi)`` is ``lo + (hi - lo)`` times a double; ``integers(0, n)`` is
  Lemire's bounded method on 32-bit draws, which PCG64 serves in halves of one output (the
  low half first, the high half kept for the next 32-bit draw, in the state's
  ``has_uint32`` / ``uinteger``).
* Then it resets the generator to where it was, advances it by the outputs used and sets
  the kept half, so the draws after it (the tissue gene, replication, the next tournament)
  are the ones the Python loop would have made.

Tests (tests/test_ga.py) compare it gene for gene and state for state with
:func:`~ant_evolution.ga.mutate_cell` over random genomes and generator states.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass

import numba as nb
import numpy as np

from ant_controller.genome import DECISION, MOTOR, CellGene

_DOUBLE = 1.0 / 9007199254740992.0  # 2**-53


@nb.njit(cache=True, inline="always")
def _double(raw, pos):
    return (raw[pos] >> np.uint64(11)) * _DOUBLE, pos + 1


@nb.njit(cache=True, inline="always")
def _uint32(raw, pos, cache):
    """PCG64's 32-bit draw: the kept high half, else the low half of a new output."""
    if cache[0] == 1:
        cache[0] = 0
        return np.uint32(cache[1]), pos
    word = raw[pos]
    cache[0] = 1
    cache[1] = np.int64(word >> np.uint64(32))
    return np.uint32(word & np.uint64(0xFFFFFFFF)), pos + 1


@nb.njit(cache=True, inline="always")
def _integer(raw, pos, cache, n):
    """``integers(0, n)`` for 1 < n < 2**32 (Lemire's method, as numpy's Generator)."""
    rng_excl = np.uint64(n)
    u, pos = _uint32(raw, pos, cache)
    m = np.uint64(u) * rng_excl
    leftover = m & np.uint64(0xFFFFFFFF)
    if leftover < rng_excl:
        threshold = (np.uint64(0xFFFFFFFF) - (rng_excl - np.uint64(1))) % rng_excl
        while leftover < threshold:
            if pos >= raw.shape[0] - 1:
                return -1, pos
            u, pos = _uint32(raw, pos, cache)
            m = np.uint64(u) * rng_excl
            leftover = m & np.uint64(0xFFFFFFFF)
    return np.int64(m >> np.uint64(32)), pos


@nb.njit(cache=True, inline="always")
def _vector(raw, pos, p, vec, c):
    """``random(m) < p`` hits; if any, ``uniform(-1, 1, m)`` replaces the hit entries."""
    m = vec.shape[1]
    hit = False
    for j in range(m):
        if (raw[pos + j] >> np.uint64(11)) * _DOUBLE < p:
            hit = True
    if not hit:
        return pos + m, False
    for j in range(m):
        if (raw[pos + j] >> np.uint64(11)) * _DOUBLE < p:
            vec[c, j] = -1.0 + 2.0 * ((raw[pos + m + j] >> np.uint64(11)) * _DOUBLE)
    return pos + 2 * m, True


@nb.njit(cache=True)
def _mutate(raw, cache, p, n_behaviours, n_extent, scalars, sensors, inputs, changed):
    """Mutate the arrays in place; return the raw outputs used, or -1 when ``raw`` ran short.

    ``scalars`` columns: expressed, dead, k1, k2 (0/1), replication, theta1, theta2,
    concentration (ranges ``[0, 1]``, ``[-1, 1]``, ``[-1, 1]``, ``[0, 1]``), behaviour, and
    the three extents. ``changed`` gets, per gene, a bit per field that changed, bit k for:
    expressed, dead, k1, k2, replication, theta1, theta2, concentration, behaviour,
    sensor_weights, input_weights, extent.
    """
    pos = 0
    n = scalars.shape[0]
    need = 5 + 6 + 8 + 1 + 2 * sensors.shape[1] + 2 * inputs.shape[1] + 4
    lows = (0.0, -1.0, -1.0, 0.0)
    flip = np.zeros(5, dtype=np.bool_)
    for c in range(n):
        if pos + need >= raw.shape[0]:
            return -1
        for j in range(5):
            d, pos = _double(raw, pos)
            flip[j] = d < p
        for j in range(4):
            if flip[j]:
                scalars[c, j] = 1.0 - scalars[c, j]
                changed[c] |= 1 << j
        for j in range(3):
            d, pos = _double(raw, pos)
            if d < p:
                v, pos = _integer(raw, pos, cache, n_extent)
                if v < 0:
                    return -1
                scalars[c, 9 + j] = v
                changed[c] |= 1 << 11
        for j in range(4):
            d, pos = _double(raw, pos)
            if d < p:
                lo = lows[j]
                u, pos = _double(raw, pos)
                scalars[c, 4 + j] = lo + (1.0 - lo) * u
                changed[c] |= 1 << (4 + j)
        if flip[4]:
            v, pos = _integer(raw, pos, cache, n_behaviours)
            if v < 0:
                return -1
            scalars[c, 8] = v
            changed[c] |= 1 << 8
        pos, hit = _vector(raw, pos, p, sensors, c)
        if hit:
            changed[c] |= 1 << 9
        pos, hit = _vector(raw, pos, p, inputs, c)
        if hit:
            changed[c] |= 1 << 10
    return pos


# slot kinds of :func:`_mutate_by_slots` (``ant_evolution.ga._CELL_SLOTS``' kinds)
SLOT_KINDS = ("flag", "bit", "real", "int", "category")
# where a field's values lie: (array, first column); 0 scalars, 1 sensors, 2 inputs
COLUMNS = {
    "expressed": (0, 0), "dead": (0, 1), "k1": (0, 2), "k2": (0, 3), "replication": (0, 4),
    "theta1": (0, 5), "theta2": (0, 6), "concentration": (0, 7), "behaviour": (0, 8),
    "extent": (0, 9), "sensor_weights": (1, 0), "input_weights": (2, 0),
}  # fmt: skip


@nb.njit(cache=True)
def _slot_value(raw, pos, cache, kind, value, lo, hi, perturb, width):
    """``ga._new_value`` on one slot: (new value, position), position -1 when ``raw`` ran short."""
    if kind == 0:  # flag: not value
        return (0.0 if value != 0.0 else 1.0), pos
    if kind == 1:  # bit: 1 - value
        return 1.0 - value, pos
    if kind == 4 or (kind == 3 and not perturb):  # integers(lo, hi) / integers(lo, hi + 1)
        n = int(hi) - int(lo) + (1 if kind == 3 else 0)
        v, pos = _integer(raw, pos, cache, n)
        if v < 0:
            return 0.0, -1
        return float(v + int(lo)), pos
    d, pos = _double(raw, pos)
    if kind == 3:  # an integer steps by one: random() < 0.5 up, else down, clipped
        step = 1 if d < 0.5 else -1
        return float(min(max(int(value) + step, int(lo)), int(hi))), pos
    if not perturb:  # uniform(lo, hi)
        return lo + (hi - lo) * d, pos
    w = width * (hi - lo)
    u = -w + (w - -w) * d  # uniform(-w, w), as numpy computes it
    return min(max(value + u, lo), hi), pos


@nb.njit(cache=True)
def _mutate_by_slots(
    raw, cache, p, gene_scope, perturb, width, where, column, kind, lo, hi,
    scalars, sensors, inputs, changed,
):  # fmt: skip
    """``ga._mutate_slots``' cell loop on the arrays; the outputs used, or -1 when short.

    Per gene, as ``_chosen_slots`` draws: under the gene scope ``random() < p`` and then
    one slot ``integers(0, n_slots)``; under the parameter scope ``random(n_slots) < p``.
    Each chosen slot in order then draws its new value (:func:`_slot_value`).
    """
    pos = 0
    n = scalars.shape[0]
    n_slots = kind.shape[0]
    need = 6 if gene_scope else 2 * n_slots + 4
    arrays = (scalars, sensors, inputs)
    chosen = np.empty(n_slots, dtype=np.int64)
    for c in range(n):
        if pos + need >= raw.shape[0]:
            return -1
        m = 0
        if gene_scope:
            d, pos = _double(raw, pos)
            if d < p:
                s, pos = _integer(raw, pos, cache, n_slots)
                if s < 0:
                    return -1
                chosen[0] = s
                m = 1
        else:
            for s in range(n_slots):
                d, pos = _double(raw, pos)
                if d < p:
                    chosen[m] = s
                    m += 1
        for k in range(m):
            s = chosen[k]
            if pos + 2 >= raw.shape[0]:
                return -1
            a = arrays[where[s]]
            value, pos = _slot_value(
                raw, pos, cache, kind[s], a[c, column[s]], lo[s], hi[s], perturb, width
            )
            if pos < 0:
                return -1
            a[c, column[s]] = value
            changed[c] = 1
    return pos


_SPAN = 1 << 16
_HALF = 1 << 15


@dataclass(frozen=True)
class Sites:
    """The genes' relative positions, one integer key per site, sorted, and their bounds.

    A key is linear in the position (``((l * S) + m) * S + n`` plus a constant), so the
    key of an absolute site is the relative key plus the seed's: crossover finds the
    other parent's gene at a site by a search in sorted keys. Children whose genes keep
    their sites (mutation, crossover) share their parent's.
    """

    positions: np.ndarray
    keys: np.ndarray
    order: np.ndarray
    sorted_keys: np.ndarray
    low: tuple[int, int, int]
    high: tuple[int, int, int]

    @staticmethod
    def of(positions: np.ndarray) -> Sites | None:
        """The sites of ``positions`` (n x 3); ``None`` when two coincide or one is far out."""
        if positions.size == 0 or int(np.abs(positions).max()) >= _HALF // 2:
            return None
        keys = site_key(positions)
        order = np.argsort(keys, kind="stable")
        sorted_keys = keys[order]
        if np.any(sorted_keys[1:] == sorted_keys[:-1]):
            return None
        for array in (positions, keys, order, sorted_keys):
            array.flags.writeable = False
        low = tuple(int(v) for v in positions.min(axis=0))
        high = tuple(int(v) for v in positions.max(axis=0))
        return Sites(positions, keys, order, sorted_keys, low, high)

    def holds(self, position) -> bool:
        """Whether a gene sits at ``position`` (relative)."""
        key = _key(position)
        at = int(np.searchsorted(self.sorted_keys, key))
        return at < len(self.sorted_keys) and int(self.sorted_keys[at]) == key

    def with_site(self, position) -> Sites | None:
        """These sites and one more at the end (a daughter cell).

        ``None`` when the site is taken or far out.
        """
        p = tuple(int(v) for v in position)
        if max(map(abs, p)) >= _HALF // 2:
            return None
        key = _key(p)
        at = int(np.searchsorted(self.sorted_keys, key))
        if at < len(self.sorted_keys) and int(self.sorted_keys[at]) == key:
            return None
        positions = np.concatenate((self.positions, np.array([p], dtype=np.int64)))
        keys = np.append(self.keys, np.int64(key))
        order = np.insert(self.order, at, len(self.keys))
        sorted_keys = np.insert(self.sorted_keys, at, np.int64(key))
        for array in (positions, keys, order, sorted_keys):
            array.flags.writeable = False
        low = tuple(min(a, b) for a, b in zip(self.low, p, strict=True))
        high = tuple(max(a, b) for a, b in zip(self.high, p, strict=True))
        return Sites(positions, keys, order, sorted_keys, low, high)


def _key(position) -> int:
    """:func:`site_key` of one site, in Python integers."""
    return ((position[0] + _HALF) * _SPAN + (position[1] + _HALF)) * _SPAN + position[2] + _HALF


def site_key(positions) -> np.ndarray:
    """Integer keys of lattice sites (an n x 3 array, or one site as a 1 x 3 one)."""
    p = np.asarray(positions, dtype=np.int64) + _HALF
    return (p[:, 0] * _SPAN + p[:, 1]) * _SPAN + p[:, 2]


class PackedCells(Sequence):
    """A genome's cell genes held as arrays; each ``CellGene`` object is built when first read.

    Breeding's working form. ``kinds`` (0 motor, 1 decision), ``scalars`` (one row per
    gene, the columns of ``_mutate``), ``sensors`` and ``inputs`` hold the genes' values
    and ``sites`` their positions, so that mutation, crossover and replication read and
    write rows instead of gene objects. A child shares the gene objects of its parent's
    genes it did not change and builds the others only when something reads them (the
    development in an evaluating worker, a checkpoint, the best genome's file): in the
    breeding process a generation builds no gene objects at all. The arrays are read-only
    (children copy before changing them, and share what they do not change) and always
    agree with the genes.

    To the rest of the code it is the tuple of its genes: a sequence that compares equal
    to, and hashes as, the plain tuple of the same genes. It pickles as its arrays (a
    worker builds the genes from the rows, beside its evaluation); genome files and
    checkpoints hold the genes, as ever (``genome_to_dict`` reads them).

    Only genes of the canonical types pack (``float`` values, ``int`` bits, extents and
    positions, ``bool`` flags: what ``random_cell``, the operators and ``genome_from_dict``
    make), so a gene built from its row is the gene, type for type, and genome files
    come out byte for byte as from the Python operators.
    """

    __slots__ = ("kinds", "scalars", "sensors", "inputs", "sites", "_genes")

    def __init__(self, kinds, scalars, sensors, inputs, sites: Sites, genes: list) -> None:
        for array in (kinds, scalars, sensors, inputs):
            array.flags.writeable = False
        self.kinds, self.scalars, self.sensors, self.inputs = kinds, scalars, sensors, inputs
        self.sites = sites
        self._genes = genes  # a gene object, or None until first read

    def __len__(self) -> int:
        return len(self._genes)

    def __getitem__(self, index):
        if isinstance(index, slice):
            return self.genes()[index]
        gene = self._genes[index]
        if gene is None:
            self._build([range(len(self._genes))[index]])
            gene = self._genes[index]
        return gene

    def __iter__(self):
        return iter(self.genes())

    def genes(self) -> tuple:
        """The genes as a plain tuple (building those not built yet)."""
        genes = self._genes
        missing = [i for i, g in enumerate(genes) if g is None]
        if missing:
            self._build(missing)
        return tuple(genes)

    def _build(self, index: list[int]) -> None:
        genes = self._genes
        rows = self.scalars[index].tolist()
        sensors = self.sensors[index].tolist()
        inputs = self.inputs[index].tolist()
        positions = self.sites.positions[index].tolist()
        kinds = self.kinds[index].tolist()
        for i, r, s, w, p, k in zip(index, rows, sensors, inputs, positions, kinds, strict=True):
            genes[i] = _with_dict(
                CellGene,
                {
                    "kind": _KINDS[k],
                    "expressed": r[0] != 0.0,
                    "dead": r[1] != 0.0,
                    "position": tuple(p),
                    "replication": r[4],
                    "theta1": r[5],
                    "theta2": r[6],
                    "k1": int(r[2]),
                    "k2": int(r[3]),
                    "sensor_weights": tuple(s),
                    "input_weights": tuple(w),
                    "behaviour": int(r[8]),
                    "concentration": r[7],
                    "extent": (int(r[9]), int(r[10]), int(r[11])),
                },
            )

    def __eq__(self, other) -> bool:
        if isinstance(other, PackedCells):
            other = other.genes()
        elif not isinstance(other, tuple):
            return NotImplemented
        return self.genes() == other

    def __hash__(self) -> int:
        return hash(self.genes())

    def __repr__(self) -> str:
        return repr(self.genes())

    def __reduce__(self):
        return (
            _restore,
            (self.kinds, self.scalars, self.sensors, self.inputs, self.sites.positions),
        )

    def grown(self) -> np.ndarray:
        """Indices of the expressed, living genes (the cells that grow), in gene order."""
        return np.flatnonzero((self.scalars[:, 0] != 0.0) & (self.scalars[:, 1] == 0.0))

    def with_rows(self, scalars, sensors, inputs, changed: list[int]) -> PackedCells:
        """These genes with new values (same kinds and sites): the rows ``changed`` differ."""
        genes = self._genes.copy()
        for i in changed:
            genes[i] = None
        return PackedCells(self.kinds, scalars, sensors, inputs, self.sites, genes)


def _restore(kinds, scalars, sensors, inputs, positions) -> PackedCells:
    """A pickled :class:`PackedCells` (its genes built when first read)."""
    sites = Sites.of(np.array(positions, dtype=np.int64))
    if sites is None:
        raise ValueError("packed cell genes with coinciding or far-out sites")
    return PackedCells(
        np.array(kinds, dtype=np.int8),
        np.array(scalars, dtype=np.float64),
        np.array(sensors, dtype=np.float64),
        np.array(inputs, dtype=np.float64),
        sites,
        [None] * len(scalars),
    )


_KINDS = (MOTOR, DECISION)
_KIND_CODE = {MOTOR: 0, DECISION: 1}


_TYPES = {
    "expressed": bool, "dead": bool, "k1": int, "k2": int, "behaviour": int,
    "replication": float, "theta1": float, "theta2": float, "concentration": float,
    "position": tuple, "extent": tuple, "sensor_weights": tuple, "input_weights": tuple,
}  # fmt: skip


def _canonical(g) -> bool:
    """Whether a gene's values have the types a gene built from its row has."""
    return (
        type(g) is CellGene
        and g.kind in _KIND_CODE
        and all(type(getattr(g, name)) is t for name, t in _TYPES.items())
        and len(g.position) == 3
        and len(g.extent) == 3
        and all(type(v) is int for v in (*g.position, *g.extent))
        and all(type(v) is float for v in (*g.sensor_weights, *g.input_weights))
    )


def _row(g) -> tuple:
    """A gene's ``scalars`` row."""
    return (g.expressed, g.dead, g.k1, g.k2, g.replication, g.theta1, g.theta2,
            g.concentration, g.behaviour, *g.extent)  # fmt: skip


def _exact(*arrays: np.ndarray) -> bool:
    """Finite values whose integers a float64 holds exactly (rows give the genes back)."""
    return all(bool(np.all(np.abs(a) < _EXACT)) for a in arrays)


_EXACT = float(2**53)


def packed(cells) -> PackedCells | None:
    """``cells`` in the packed form (itself when it is already).

    ``None`` when the genes differ in vector length, two share a site, or a gene is not
    of the canonical types or holds a value a row cannot give back exactly (not a tissue
    the operators make: the Python operators handle it).
    """
    if isinstance(cells, PackedCells):
        return cells
    n = len(cells)
    if n == 0 or not all(map(_canonical, cells)):
        return None
    n_s, n_i = len(cells[0].sensor_weights), len(cells[0].input_weights)
    if any(len(g.sensor_weights) != n_s or len(g.input_weights) != n_i for g in cells):
        return None
    sites = Sites.of(np.array([g.position for g in cells], dtype=np.int64).reshape(n, 3))
    if sites is None:
        return None
    scalars = np.array([_row(g) for g in cells], dtype=np.float64)
    sensors = np.array([g.sensor_weights for g in cells], dtype=np.float64).reshape(n, n_s)
    inputs = np.array([g.input_weights for g in cells], dtype=np.float64).reshape(n, n_i)
    if not _exact(scalars, sensors, inputs):
        return None
    kinds = np.array([_KIND_CODE[g.kind] for g in cells], dtype=np.int8)
    return PackedCells(kinds, scalars, sensors, inputs, sites, list(cells))


def append_cell(cells, gene) -> tuple | PackedCells:
    """``(*cells, gene)``, packed when ``cells`` is (replication's daughter)."""
    if (
        not isinstance(cells, PackedCells)
        or not _canonical(gene)
        or len(gene.sensor_weights) != cells.sensors.shape[1]
        or len(gene.input_weights) != cells.inputs.shape[1]
    ):
        return (*cells, gene)
    sites = cells.sites.with_site(gene.position)
    row = np.array([_row(gene)], dtype=np.float64)
    sensors = np.array([gene.sensor_weights], dtype=np.float64)
    inputs = np.array([gene.input_weights], dtype=np.float64)
    if sites is None or not _exact(row, sensors, inputs):
        return (*cells, gene)
    return PackedCells(
        np.append(cells.kinds, np.int8(_KIND_CODE[gene.kind])),
        np.concatenate((cells.scalars, row)),
        np.concatenate((cells.sensors, sensors)),
        np.concatenate((cells.inputs, inputs)),
        sites,
        [*cells._genes, gene],
    )


def with_genes(cells, changes: dict[int, CellGene]):
    """``cells`` with the genes at the indices of ``changes`` replaced (same kinds and sites).

    Packed (:func:`packed`) when the genes pack: the new genes' rows are written and the
    others' gene objects shared, as a mutation under ``mutate_cells`` does; otherwise a
    plain tuple. ``cells`` itself when nothing changes.
    """
    if not changes:
        return cells
    parent = packed(cells)
    if parent is not None and all(
        _canonical(g)
        and _KIND_CODE[g.kind] == parent.kinds[i]
        and g.position == tuple(parent.sites.positions[i].tolist())
        and len(g.sensor_weights) == parent.sensors.shape[1]
        and len(g.input_weights) == parent.inputs.shape[1]
        for i, g in changes.items()
    ):
        index = list(changes)
        genes = [changes[i] for i in index]
        rows = np.array([_row(g) for g in genes], dtype=np.float64)
        sensor_rows = np.array([g.sensor_weights for g in genes], dtype=np.float64)
        input_rows = np.array([g.input_weights for g in genes], dtype=np.float64)
        if _exact(rows, sensor_rows, input_rows):
            scalars, sensors, inputs = (
                parent.scalars.copy(),
                parent.sensors.copy(),
                parent.inputs.copy(),
            )
            scalars[index], sensors[index], inputs[index] = rows, sensor_rows, input_rows
            child = parent.with_rows(scalars, sensors, inputs, [])
            for i, g in zip(index, genes, strict=True):
                child._genes[i] = g
            return child
    return tuple(changes.get(i, g) for i, g in enumerate(cells))


def _block_size(n: int, n_s: int, n_i: int) -> int:
    """Raw outputs drawn for one genome's mutation.

    Enough for a usual genome (about ``n_s + n_i + 16`` a gene at p = 0.025, the vectors'
    redraws included) with a margin; a block that runs short is drawn again, twice as large.
    """
    return n * (20 + n_s + n_i) + 2 * (24 + 2 * (n_s + n_i)) + 64


def mutate_cells(
    rng: np.random.Generator, cells: tuple, p: float, n_behaviours: int, n_extent: int
):
    """``tuple(mutate_cell(rng, g, p) for g in cells)``, compiled; ``rng`` left as that leaves it.

    Returns the genes packed (:class:`PackedCells`), or ``None`` (``rng`` untouched) when
    the generator is not PCG64 or the genes cannot be packed: the caller then runs the
    Python loop.

    Args:
        rng: The GA's generator (a PCG64 one).
        cells: The genome's cell genes, in order (packed or not).
        p: The mutation probability per parameter.
        n_behaviours: ``integers(0, n_behaviours)`` draws a behaviour.
        n_extent: ``integers(0, n_extent)`` draws a field half-extent.
    """
    parent = _kernel_parent(rng, cells)
    if not isinstance(parent, PackedCells):
        return parent
    n_s, n_i = parent.sensors.shape[1], parent.inputs.shape[1]
    block = _block_size(len(parent), n_s, n_i)
    return _on_raw_outputs(rng, parent, block, _mutate, p, n_behaviours, n_extent)


def mutate_by_slots(
    rng: np.random.Generator, cells, p: float, slots, scope: str, operator: str, width: float
):
    """``ga._mutate_slots``' cell loop, compiled; ``rng`` left as that loop leaves it.

    Returns the genes packed, or ``None`` (``rng`` untouched) when the generator is not
    PCG64 or the genes cannot be packed: the caller then runs the Python loop.

    Args:
        rng: The GA's generator (a PCG64 one).
        cells: The genome's cell genes, in order (packed or not).
        p: The mutation probability (per gene or per parameter, as ``scope`` says).
        slots: ``ga._CELL_SLOTS``: (field, index or -1, kind, low, high) per slot.
        scope: ``"gene"`` or ``"parameter"``.
        operator: ``"redraw"`` or ``"perturb"``.
        width: The perturbation's half-width as a fraction of the range.
    """
    parent = _kernel_parent(rng, cells)
    if not isinstance(parent, PackedCells):
        return parent
    where, column, kind, lo, hi = _slot_arrays(tuple(slots))
    widths = (parent.sensors.shape[1], parent.inputs.shape[1])
    if widths != (int(np.sum(where == 1)), int(np.sum(where == 2))):
        return None  # not a slot per weight: the Python loop
    gene_scope = scope == "gene"
    block = len(parent) * (3 if gene_scope else 2 * len(slots) + 2) + 64
    return _on_raw_outputs(
        rng, parent, block, _mutate_by_slots, p, gene_scope, operator == "perturb",
        float(width), where, column, kind, lo, hi,
    )  # fmt: skip


def _kernel_parent(rng: np.random.Generator, cells):
    """``cells`` packed for a kernel.

    ``()`` when there are none; ``None`` when a kernel cannot run (not a PCG64 generator,
    or genes that do not pack).
    """
    if len(cells) == 0:
        return ()
    if not isinstance(rng.bit_generator, np.random.PCG64):
        return None
    return packed(cells)


@functools.lru_cache(maxsize=8)
def _slot_arrays(slots: tuple) -> tuple[np.ndarray, ...]:
    """Per slot: array (0 scalars, 1 sensors, 2 inputs), column, kind, low and high."""
    where = np.array([COLUMNS[f][0] for f, _, _, _, _ in slots], dtype=np.int64)
    column = np.array([COLUMNS[f][1] + max(i, 0) for f, i, _, _, _ in slots], dtype=np.int64)
    kind = np.array([SLOT_KINDS.index(k) for _, _, k, _, _ in slots], dtype=np.int64)
    lo = np.array([s[3] for s in slots], dtype=np.float64)
    hi = np.array([s[4] for s in slots], dtype=np.float64)
    for array in (where, column, kind, lo, hi):
        array.flags.writeable = False
    return where, column, kind, lo, hi


def _on_raw_outputs(rng: np.random.Generator, parent: PackedCells, block: int, kernel, *args):
    """The child of ``kernel(raw, cache, *args, scalars, sensors, inputs, changed)``.

    The kernel mutates copies of the parent's arrays from a block of the generator's raw
    outputs and returns how many it used (-1 when the block ran short: it runs again on
    fresh copies, from the same state, with a block twice as large). The generator is
    then left where the draws would have left it: advanced by the outputs used, with the
    kept half of a 32-bit draw in ``cache``.
    """
    scalars, sensors, inputs = parent.scalars.copy(), parent.sensors.copy(), parent.inputs.copy()
    changed = np.zeros(len(parent), dtype=np.int64)
    bits = rng.bit_generator
    start = bits.state
    cache = np.array([start["has_uint32"], start["uinteger"]], dtype=np.int64)
    while True:
        raw = bits.random_raw(block)
        used = kernel(raw, cache, *args, scalars, sensors, inputs, changed)
        bits.state = start
        if used >= 0:
            break
        block *= 2  # a long rejection run: again, with more outputs
        cache[:] = (start["has_uint32"], start["uinteger"])
        scalars, sensors, inputs = (
            parent.scalars.copy(),
            parent.sensors.copy(),
            parent.inputs.copy(),
        )
        changed[:] = 0
    bits.advance(used)
    end = bits.state
    end["has_uint32"], end["uinteger"] = int(cache[0]), int(cache[1])
    bits.state = end
    index = np.flatnonzero(changed)
    if index.size == 0:
        return parent
    return parent.with_rows(scalars, sensors, inputs, index.tolist())


def crossover_packed(rng: np.random.Generator, a, b):
    """:func:`ant_evolution.ga.crossover` on packed genes: the same children and draws.

    The children's genes are packed too; ``None`` (``rng`` untouched) unless both
    parents' genes are packed.
    """
    ca, cb = a.cells, b.cells
    if not (isinstance(ca, PackedCells) and isinstance(cb, PackedCells)):
        return None
    if ca.sensors.shape[1:] != cb.sensors.shape[1:] or ca.inputs.shape[1:] != cb.inputs.shape[1:]:
        return None
    seed_a, seed_b = a.tissue.seed, b.tissue.seed
    if max(map(abs, (*seed_a, *seed_b))) >= _HALF // 2:
        return None
    axis = int(rng.integers(0, 2))
    sa, sb = ca.sites, cb.sites
    lo = min(sa.low[axis] + seed_a[axis], sb.low[axis] + seed_b[axis])
    hi = max(sa.high[axis] + seed_a[axis], sb.high[axis] + seed_b[axis])
    cut = int(rng.integers(lo, hi + 1)) - seed_a[axis]
    col_a = sa.positions[:, axis]
    i = np.flatnonzero(col_a > cut if cut + seed_a[axis] >= 0 else col_a <= cut)
    # a's gene i and b's gene j share a site when a's key plus a's seed is b's plus b's
    wanted = sa.keys[i] + (_key(seed_a) - _key(seed_b))  # keys are linear in the site
    at = np.minimum(np.searchsorted(sb.sorted_keys, wanted), len(sb.sorted_keys) - 1)
    hit = sb.sorted_keys[at] == wanted
    i, j = i[hit], sb.order[at[hit]]
    same = ca.scalars[i, 0] == cb.scalars[j, 0]  # the compatibility criterion: expressed
    i, j = i[same], j[same]
    if i.size == 0:
        return a, b
    a_genes, b_genes = ca._genes.copy(), cb._genes.copy()
    i_list, j_list = i.tolist(), j.tolist()
    if seed_a == seed_b:  # the usual case: a moved gene keeps its position, so moves itself
        for x, y in zip(i_list, j_list, strict=True):
            a_genes[x], b_genes[y] = cb._genes[y], ca._genes[x]
    else:  # at another position: built from its row when first read
        for x in i_list:
            a_genes[x] = None
        for y in j_list:
            b_genes[y] = None
    arrays_a, arrays_b = [], []
    for k in ("kinds", "scalars", "sensors", "inputs"):
        va, vb = getattr(ca, k).copy(), getattr(cb, k).copy()
        va[i], vb[j] = getattr(cb, k)[j], getattr(ca, k)[i]
        arrays_a.append(va)
        arrays_b.append(vb)
    child_a = PackedCells(*arrays_a, sa, a_genes)
    child_b = PackedCells(*arrays_b, sb, b_genes)
    return with_fields(a, {"cells": child_a}), with_fields(b, {"cells": child_b})


def with_fields(gene, fields: dict):
    """``dataclasses.replace(gene, **fields)`` at a tenth of the cost.

    For a frozen dataclass without ``__post_init__`` (``CellGene``, ``TissueGene``,
    ``Genome``): a new instance whose fields are ``gene``'s with ``fields`` changed (the
    others shared, as ``replace`` shares them), without running ``__init__`` again
    (``replace`` took 11 us a gene, most of a generation's breeding after the kernel).
    """
    d = gene.__dict__.copy()
    d.update(fields)
    return _with_dict(type(gene), d)


_new_object = object.__new__
_set_attribute = object.__setattr__


def _with_dict(cls, d: dict):
    """An instance of the frozen dataclass ``cls`` whose attributes are ``d`` (not copied)."""
    new = _new_object(cls)
    _set_attribute(new, "__dict__", d)
    return new
