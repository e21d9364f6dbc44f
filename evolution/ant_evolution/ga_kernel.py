"""``v1``'s per-parameter mutation of a genome's cell genes, compiled, draw for draw.

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

import numba as nb
import numpy as np

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

    ``scalars`` columns are :data:`FIELDS`' scalars (extent's three last): expressed, dead,
    k1, k2 (0/1), replication, theta1, theta2, concentration (ranges ``[0, 1]``,
    ``[-1, 1]``, ``[-1, 1]``, ``[0, 1]``), behaviour, extent. ``changed`` gets, per gene, a
    bit per field that changed (:data:`FIELDS` order).
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


FIELDS = (
    "expressed",
    "dead",
    "k1",
    "k2",
    "replication",
    "theta1",
    "theta2",
    "concentration",
    "behaviour",
    "sensor_weights",
    "input_weights",
    "extent",
)
"""A cell gene's mutable fields, in the order of ``_mutate``'s change bits."""


def mutate_cells(
    rng: np.random.Generator, cells: tuple, p: float, n_behaviours: int, n_extent: int
):
    """``tuple(mutate_cell(rng, g, p) for g in cells)``, compiled; ``rng`` left as that leaves it.

    ``None`` (``rng`` untouched) when the generator is not PCG64 or the genes' vectors
    differ in length: the caller then runs the Python loop.

    Args:
        rng: The GA's generator (a PCG64 one).
        cells: The genome's cell genes, in order.
        p: The mutation probability per parameter.
        n_behaviours: ``integers(0, n_behaviours)`` draws a behaviour.
        n_extent: ``integers(0, n_extent)`` draws a field half-extent.
    """
    n = len(cells)
    if n == 0:
        return ()
    if not isinstance(rng.bit_generator, np.random.PCG64):
        return None
    n_s, n_i = len(cells[0].sensor_weights), len(cells[0].input_weights)
    if any(len(g.sensor_weights) != n_s or len(g.input_weights) != n_i for g in cells):
        return None
    scalars = np.array(
        [
            (g.expressed, g.dead, g.k1, g.k2, g.replication, g.theta1, g.theta2,
             g.concentration, g.behaviour, *g.extent)
            for g in cells
        ],
        dtype=np.float64,
    )  # fmt: skip
    sensors = np.array([g.sensor_weights for g in cells], dtype=np.float64).reshape(n, n_s)
    inputs = np.array([g.input_weights for g in cells], dtype=np.float64).reshape(n, n_i)
    changed = np.zeros(n, dtype=np.int64)
    bits = rng.bit_generator
    start = bits.state
    cache = np.array([start["has_uint32"], start["uinteger"]], dtype=np.int64)
    block = n * (24 + 2 * (n_s + n_i)) + 64
    while True:
        raw = bits.random_raw(block)
        used = _mutate(raw, cache, p, n_behaviours, n_extent, scalars, sensors, inputs, changed)
        bits.state = start
        if used >= 0:
            break
        block *= 2  # a long rejection run: again, with more outputs
        cache[:] = (start["has_uint32"], start["uinteger"])
    bits.advance(used)
    end = bits.state
    end["has_uint32"], end["uinteger"] = int(cache[0]), int(cache[1])
    bits.state = end
    rows, sens, ins = scalars.tolist(), sensors.tolist(), inputs.tolist()
    out = []
    for c, (g, bits_c) in enumerate(zip(cells, changed.tolist(), strict=True)):
        if not bits_c:
            out.append(g)
            continue
        row, fields = rows[c], {}
        while bits_c:
            k = (bits_c & -bits_c).bit_length() - 1
            bits_c &= bits_c - 1
            if k < 2:
                fields[FIELDS[k]] = bool(row[k])
            elif k < 4 or k == 8:
                fields[FIELDS[k]] = int(row[k])
            elif k < 8:
                fields[FIELDS[k]] = row[k]
            elif k == 9:
                fields["sensor_weights"] = tuple(sens[c])
            elif k == 10:
                fields["input_weights"] = tuple(ins[c])
            else:
                fields["extent"] = (int(row[9]), int(row[10]), int(row[11]))
        out.append(with_fields(g, fields))
    return tuple(out)


def with_fields(gene, fields: dict):
    """``dataclasses.replace(gene, **fields)`` at a tenth of the cost.

    For a frozen dataclass without ``__post_init__`` (``CellGene``): a new instance whose
    fields are ``gene``'s with ``fields`` changed, without running ``__init__`` again
    (``replace`` took 11 us a gene, most of a generation's breeding after the kernel).
    """
    new = object.__new__(type(gene))
    new.__dict__.update(gene.__dict__)
    new.__dict__.update(fields)
    return new
