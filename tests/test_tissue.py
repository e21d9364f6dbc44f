"""Tests for development, the modular activation and the tissue's decision (kernel vs reference)."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest

from ant_controller.genome import (
    DECISION,
    MOTOR,
    CellGene,
    Genome,
    Lattice,
    TissueGene,
    random_genome,
)
from ant_controller.layout import (
    MOVE_BACKWARD,
    MOVE_FORWARD,
    N_SENSORS,
    RANDOM_TURN,
    SENSOR_STATES,
    TURN_LEFT,
)
from ant_controller.tissue import (
    activation,
    compile_tissue,
    decide_reference,
    decide_tissue,
    develop,
)

PSI_DOWN, PSI_UP, PSI_DITCH, PSI_MOUND = 0, 1, 2, 3
K_BITS = {PSI_DOWN: (0, 0), PSI_UP: (0, 1), PSI_DITCH: (1, 0), PSI_MOUND: (1, 1)}

ZERO = np.zeros(N_SENSORS, dtype=np.int64)
FULL = SENSOR_STATES - 1


def _random_codes(rng: np.random.Generator, n: int) -> np.ndarray:
    return rng.integers(0, SENSOR_STATES, size=(n, N_SENSORS))


# --- numba kernel == reference ---------------------------------------------------------------


def _with_repressed_and_dead(genome: Genome, rng: np.random.Generator) -> Genome:
    cells = []
    for c in genome.cells:
        u = rng.uniform()
        if u < 0.15:
            c = dataclasses.replace(c, expressed=False)
        elif u < 0.35:
            c = dataclasses.replace(c, dead=True)
        cells.append(c)
    return dataclasses.replace(genome, cells=tuple(cells))


def _with_collisions(genome: Genome, rng: np.random.Generator) -> Genome:
    # Some genes share a site: the first one wins in development.
    cells = list(genome.cells)
    for i in rng.choice(len(cells), size=len(cells) // 5, replace=False):
        j = int(rng.integers(0, len(cells)))
        cells[i] = dataclasses.replace(cells[i], position=cells[j].position)
    return dataclasses.replace(genome, cells=tuple(cells))


def _variants(seed: int) -> list[Genome]:
    rng = np.random.default_rng(1000 + seed)
    g = random_genome(np.random.default_rng(seed))
    return [g, _with_repressed_and_dead(g, rng), _with_collisions(g, rng)]


@pytest.mark.parametrize("coarse_coding", [True, False], ids=["cc", "no-cc"])
@pytest.mark.parametrize("seed", range(30))
def test_kernel_equals_reference(seed, coarse_coding):
    rng = np.random.default_rng(seed)
    codes = np.vstack([ZERO, FULL, _random_codes(rng, 100)])
    for variant, genome in enumerate(_variants(seed)):
        compiled = compile_tissue(genome, coarse_coding=coarse_coding)
        for row in codes:
            expected = decide_reference(genome, row, coarse_coding=coarse_coding)
            got = decide_tissue(compiled, row)
            assert got == expected, (seed, variant, row.tolist())
            assert 0 <= got < 1 << 12


def test_kernel_equals_reference_with_genome_switch():
    # compile_tissue/decide_reference without override follow genome.coarse_coding
    rng = np.random.default_rng(99)
    for seed in range(5):
        for cc in (True, False):
            g = dataclasses.replace(random_genome(np.random.default_rng(seed)), coarse_coding=cc)
            compiled = compile_tissue(g)
            assert compiled.coarse_coding is cc
            for row in _random_codes(rng, 50):
                assert decide_tissue(compiled, row) == decide_reference(g, row)
                assert decide_reference(g, row) == decide_reference(g, row, coarse_coding=cc)


def test_kernel_comparison_is_not_trivial():
    # The equality test above would be vacuous if every decision were 0.
    for cc in (True, False):
        rng = np.random.default_rng(5)
        masks = set()
        for seed in range(10):
            g = random_genome(np.random.default_rng(seed))
            compiled = compile_tissue(g, coarse_coding=cc)
            masks.update(decide_tissue(compiled, row) for row in _random_codes(rng, 50))
        assert len(masks) > 5, (cc, masks)


def test_zero_sensor_vector_on_random_genomes():
    for seed in range(30):
        for g in _variants(seed):
            for cc in (True, False):
                compiled = compile_tissue(g, coarse_coding=cc)
                assert decide_tissue(compiled, ZERO) == decide_reference(g, ZERO, coarse_coding=cc)
                assert decide_tissue(compiled, [0] * N_SENSORS) == decide_reference(
                    g, [0] * N_SENSORS, coarse_coding=cc
                )


# --- the modular activation function -------------------------------------------------------


def paper_psi(k1: int, k2: int, t1: float, t2: float, sigma: float) -> int:
    """The modular activation as the paper writes it (section 3.3), term by term."""
    down = 0 if sigma >= t1 else 1
    up = 0 if sigma <= t2 else 1
    ditch = 0 if min(t1, t2) <= sigma < max(t1, t2) else 1
    mound = 0 if (sigma <= min(t1, t2) or sigma > max(t1, t2)) else 1
    return (1 - k1) * ((1 - k2) * down + k2 * up) + k1 * ((1 - k2) * ditch + k2 * mound)


@pytest.mark.parametrize(
    ("func", "t1", "t2", "sigma", "out"),
    [
        # psi_down: 0 iff sigma >= theta1 (theta2 ignored)
        (PSI_DOWN, 0.2, 0.9, 0.1, 1),
        (PSI_DOWN, 0.2, 0.9, 0.2, 0),
        (PSI_DOWN, 0.2, 0.9, 0.3, 0),
        (PSI_DOWN, 0.2, -0.9, 0.19999, 1),
        (PSI_DOWN, -1.0, 0.0, -1.0, 0),
        # psi_up: 0 iff sigma <= theta2 (theta1 ignored)
        (PSI_UP, 0.9, 0.2, 0.1, 0),
        (PSI_UP, 0.9, 0.2, 0.2, 0),
        (PSI_UP, 0.9, 0.2, 0.3, 1),
        (PSI_UP, -0.9, 0.2, 0.20001, 1),
        (PSI_UP, 0.0, -1.0, 0.0, 1),
        # psi_ditch: 0 iff min <= sigma < max
        (PSI_DITCH, -0.5, 0.5, -0.6, 1),
        (PSI_DITCH, -0.5, 0.5, -0.5, 0),
        (PSI_DITCH, -0.5, 0.5, 0.0, 0),
        (PSI_DITCH, -0.5, 0.5, 0.5, 1),
        (PSI_DITCH, -0.5, 0.5, 0.6, 1),
        (PSI_DITCH, 0.5, -0.5, -0.5, 0),  # thresholds in either order
        (PSI_DITCH, 0.5, -0.5, 0.5, 1),
        (PSI_DITCH, 0.3, 0.3, 0.3, 1),  # empty interval: always fires
        # psi_mound: 0 iff sigma <= min or sigma > max
        (PSI_MOUND, -0.5, 0.5, -0.6, 0),
        (PSI_MOUND, -0.5, 0.5, -0.5, 0),
        (PSI_MOUND, -0.5, 0.5, 0.0, 1),
        (PSI_MOUND, -0.5, 0.5, 0.5, 1),
        (PSI_MOUND, -0.5, 0.5, 0.6, 0),
        (PSI_MOUND, 0.5, -0.5, 0.5, 1),
        (PSI_MOUND, 0.5, -0.5, -0.5, 0),
        (PSI_MOUND, 0.3, 0.3, 0.3, 0),  # empty interval: never fires
    ],
)
def test_activation_hand_picked(func, t1, t2, sigma, out):
    assert activation(func, t1, t2, sigma) == out
    assert paper_psi(*K_BITS[func], t1, t2, sigma) == out


def test_activation_boundary_rules_on_a_grid():
    values = [-1.0, -0.5, -0.25, 0.0, 0.25, 0.5, 1.0]
    for t1, t2, sigma in itertools.product(values, repeat=3):
        lo, hi = min(t1, t2), max(t1, t2)
        assert activation(PSI_DOWN, t1, t2, sigma) == (0 if sigma >= t1 else 1)
        assert activation(PSI_UP, t1, t2, sigma) == (0 if sigma <= t2 else 1)
        assert activation(PSI_DITCH, t1, t2, sigma) == (0 if lo <= sigma < hi else 1)
        assert activation(PSI_MOUND, t1, t2, sigma) == (0 if sigma <= lo or sigma > hi else 1)


def test_activation_matches_psi_on_a_grid():
    values = np.linspace(-1.0, 1.0, 9)
    for k1, k2 in itertools.product((0, 1), repeat=2):
        for t1, t2, sigma in itertools.product(values, repeat=3):
            t1, t2, sigma = float(t1), float(t2), float(sigma)
            got = activation(k1 * 2 + k2, t1, t2, sigma)
            assert got == paper_psi(k1, k2, t1, t2, sigma), (k1, k2, t1, t2, sigma)
            assert got in (0, 1)


# --- hand-built tissues ----------------------------------------------------------------------

ZERO_W14 = (0.0,) * N_SENSORS
ZERO_W9 = (0.0,) * 9


def motor(pos, behaviour=MOVE_FORWARD, fires=True, **kw):
    """A motor gene; ``fires`` picks psi_up with theta2 -1 (fires at sigma 0) or +1 (never)."""
    params = dict(
        kind=MOTOR,
        expressed=True,
        dead=False,
        position=pos,
        replication=0.5,
        theta1=0.0,
        theta2=-1.0 if fires else 1.0,
        k1=0,
        k2=1,
        sensor_weights=ZERO_W14,
        input_weights=ZERO_W9,
        behaviour=behaviour,
    )
    params.update(kw)
    return CellGene(**params)


def decision(pos, extent, concentration=0.5, fires=True, **kw):
    params = dict(
        kind=DECISION,
        expressed=True,
        dead=False,
        position=pos,
        replication=0.5,
        theta1=0.0,
        theta2=-1.0 if fires else 1.0,
        k1=0,
        k2=1,
        sensor_weights=ZERO_W14,
        input_weights=ZERO_W9,
        behaviour=0,
        concentration=concentration,
        extent=extent,
    )
    params.update(kw)
    return CellGene(**params)


def tissue(*cells, coarse_coding=False):
    return Genome(TissueGene(seed=(0, 0, 1)), tuple(cells), Lattice(), coarse_coding)


def bit(q):
    return 1 << q


def decide_both(genome, codes=ZERO, coarse_coding=None):
    """Decision of the kernel and the reference, which must agree."""
    got = decide_tissue(compile_tissue(genome, coarse_coding=coarse_coding), codes)
    ref = decide_reference(genome, codes, coarse_coding=coarse_coding)
    assert got == ref
    return got


@pytest.mark.parametrize("codes", [ZERO, FULL], ids=["zero", "full"])
def test_single_motor_neuron_without_coarse_coding(codes):
    g = tissue(motor((0, 0, 0), MOVE_FORWARD))
    assert decide_both(g, codes) == bit(MOVE_FORWARD) == 0b10
    assert decide_both(g, codes, coarse_coding=False) == bit(MOVE_FORWARD)


def test_single_motor_neuron_not_firing():
    g = tissue(motor((0, 0, 0), MOVE_FORWARD, fires=False))
    assert decide_both(g) == 0


def test_single_motor_neuron_with_coarse_coding_and_no_decision_neuron():
    g = tissue(motor((0, 0, 0), MOVE_FORWARD), coarse_coding=True)
    assert decide_both(g) == 0
    assert decide_both(g, FULL) == 0
    assert decide_both(g, coarse_coding=False) == bit(MOVE_FORWARD)


def test_layer1_sigma_is_weighted_mean_of_sensor_states():
    # sigma = sum(v x) / sum(x); x = code / (states - 1).
    w = np.zeros(N_SENSORS)
    w[0], w[8] = 1.0, -1.0  # Z1 (5 states), S1 (2 states)
    codes = np.zeros(N_SENSORS, dtype=np.int64)
    codes[0], codes[8] = 2, 1  # x = 0.5 and 1.0 -> sigma = (0.5 - 1.0) / 1.5 = -1/3
    for theta2, out in [(-0.34, 1), (-0.33, 0)]:
        g = tissue(motor((0, 0, 0), TURN_LEFT, sensor_weights=tuple(w), theta2=theta2))
        assert decide_both(g, codes) == (bit(TURN_LEFT) if out else 0)


def test_firing_decision_neuron_activates_motor_neuron():
    m = motor((0, 0, 0), MOVE_FORWARD)
    d = decision((0, 1, 0), extent=(1, 1, 1), concentration=0.5)
    assert decide_both(tissue(m, d, coarse_coding=True)) == bit(MOVE_FORWARD)


def test_silent_decision_neuron_activates_nothing():
    m = motor((0, 0, 0), MOVE_FORWARD)
    d = decision((0, 1, 0), extent=(1, 1, 1), fires=False)
    assert decide_both(tissue(m, d, coarse_coding=True)) == 0


def test_decision_field_that_misses_the_motor_neuron():
    m = motor((0, 0, 0), MOVE_FORWARD)
    d = decision((0, 2, 0), extent=(1, 1, 1))  # |dm| = 2 > 1
    assert decide_both(tissue(m, d, coarse_coding=True)) == 0
    d = decision((0, 2, 0), extent=(0, 2, 0))  # box reaches exactly
    assert decide_both(tissue(m, d, coarse_coding=True)) == bit(MOVE_FORWARD)


def test_zero_concentration_activates_nothing():
    m = motor((0, 0, 0), MOVE_FORWARD)
    d = decision((0, 1, 0), extent=(1, 1, 1), concentration=0.0)
    assert decide_both(tissue(m, d, coarse_coding=True)) == 0


def test_highest_concentration_rule():
    a = motor((0, 0, 0), MOVE_FORWARD)
    b = motor((3, 0, 0), MOVE_BACKWARD)
    both = decision((0, 1, 0), extent=(4, 1, 0), concentration=0.5)  # covers A and B
    only_a = decision((0, -1, 0), extent=(1, 1, 0), concentration=0.5)  # covers A only
    g = tissue(a, b, both, only_a, coarse_coding=True)
    compiled = compile_tissue(g)
    assert compiled.dn_member.tolist() == [[True, True], [True, False]]
    assert decide_both(g) == bit(MOVE_FORWARD)
    # without the second field both motor neurons share the peak and both vote
    assert decide_both(tissue(a, b, both, coarse_coding=True)) == bit(MOVE_FORWARD) | bit(
        MOVE_BACKWARD
    )
    # a stronger field over B alone moves the peak to B
    only_b = decision((3, 1, 0), extent=(0, 1, 0), concentration=0.75)
    assert decide_both(tissue(a, b, both, only_a, only_b, coarse_coding=True)) == bit(MOVE_BACKWARD)
    # a silent decision neuron releases nothing
    silent_a = dataclasses.replace(only_a, theta2=1.0)
    assert decide_both(tissue(a, b, both, silent_a, coarse_coding=True)) == bit(MOVE_FORWARD) | bit(
        MOVE_BACKWARD
    )
    # coarse coding off: decision neurons are ignored
    assert decide_both(g, coarse_coding=False) == bit(MOVE_FORWARD) | bit(MOVE_BACKWARD)


@pytest.mark.parametrize(
    ("firing", "out"),
    [
        ((True, True, False), True),
        ((True, False, False), False),
        ((True, False), True),  # mean 0.5 >= 0.5
        ((False, False), False),
        ((False,), False),
        ((True,), True),
        ((True, True, False, False), True),
        ((True, False, False, False), False),
    ],
)
def test_vote_arbitration(firing, out):
    cells = [motor((i, 0, 0), RANDOM_TURN, fires=f) for i, f in enumerate(firing)]
    assert decide_both(tissue(*cells)) == (bit(RANDOM_TURN) if out else 0)


def test_votes_only_count_for_their_own_behaviour():
    cells = [
        motor((0, 0, 0), MOVE_FORWARD, fires=True),
        motor((1, 0, 0), MOVE_BACKWARD, fires=False),
        motor((2, 0, 0), MOVE_BACKWARD, fires=False),
        motor((3, 0, 0), TURN_LEFT, fires=True),
    ]
    assert decide_both(tissue(*cells)) == bit(MOVE_FORWARD) | bit(TURN_LEFT)


def test_inactive_output_neurons_do_not_vote():
    # Two output neurons for one behaviour; only the active one (in the field) votes.
    firing = motor((0, 0, 0), MOVE_FORWARD, fires=True)
    silent = motor((4, 0, 0), MOVE_FORWARD, fires=False)
    d = decision((0, 1, 0), extent=(1, 1, 0))
    assert decide_both(tissue(firing, silent, d, coarse_coding=True)) == bit(MOVE_FORWARD)
    d = decision((4, 1, 0), extent=(1, 1, 0))
    assert decide_both(tissue(firing, silent, d, coarse_coding=True)) == 0


def test_output_layer_is_highest_occupied_layer():
    low = motor((0, 0, 0), TURN_LEFT, fires=True)
    high = motor((0, 0, 1), MOVE_FORWARD, fires=True)
    g = tissue(low, high)
    compiled = compile_tissue(g)
    assert compiled.mn_layer.tolist() == [1, 2]
    assert compiled.mn_behaviour.tolist() == [-1, MOVE_FORWARD]
    assert compiled.n_outputs == 1
    assert decide_both(g) == bit(MOVE_FORWARD)
    # on its own the layer-1 neuron is the output
    compiled = compile_tissue(tissue(low))
    assert compiled.mn_behaviour.tolist() == [TURN_LEFT]
    assert decide_both(tissue(low)) == bit(TURN_LEFT)


def test_output_layer_is_highest_layer_with_a_living_neuron():
    low = motor((0, 0, 0), TURN_LEFT, fires=True)
    high = motor((0, 0, 1), MOVE_FORWARD, fires=True, dead=True)
    g = tissue(low, high)
    compiled = compile_tissue(g)
    assert compiled.mn_behaviour.tolist() == [TURN_LEFT]
    assert decide_both(g) == bit(TURN_LEFT)


def test_layer3_output_over_gap():
    # A layer-3 neuron is the output even when layer 2 is empty (it reads nothing).
    low = motor((0, 0, 0), TURN_LEFT, fires=True)
    top = motor((0, 0, 2), MOVE_FORWARD, fires=True)
    g = tissue(low, top)
    compiled = compile_tissue(g)
    assert compiled.mn_behaviour.tolist() == [-1, MOVE_FORWARD]
    assert compiled.mn_in_idx.tolist()[1] == [-1] * 9
    assert decide_both(g) == bit(MOVE_FORWARD)


def _reader(fires_when_negative: bool, weights=(-0.8,) * 9):
    """Layer-2 neuron at (0, 0, 2); psi_down/psi_up with threshold -0.5 on its 3 x 3 inputs."""
    if fires_when_negative:
        return motor((0, 0, 1), MOVE_FORWARD, k1=0, k2=0, theta1=-0.5, input_weights=weights)
    return motor((0, 0, 1), MOVE_FORWARD, k1=0, k2=1, theta2=-0.5, input_weights=weights)


def test_layer2_sigma_is_zero_without_firing_inputs():
    silent_below = motor((0, 0, 0), TURN_LEFT, fires=False)
    # sigma = 0: psi_down(theta1 = -0.5) silent, psi_up(theta2 = -0.5) fires
    assert decide_both(tissue(silent_below, _reader(True))) == 0
    assert decide_both(tissue(silent_below, _reader(False))) == bit(MOVE_FORWARD)
    # no neuron below at all: also sigma = 0
    assert decide_both(tissue(_reader(True))) == 0
    assert decide_both(tissue(_reader(False))) == bit(MOVE_FORWARD)
    # a firing input gives sigma = -0.8
    firing_below = motor((0, 0, 0), TURN_LEFT, fires=True)
    assert decide_both(tissue(firing_below, _reader(True))) == bit(MOVE_FORWARD)
    assert decide_both(tissue(firing_below, _reader(False))) == 0


@pytest.mark.parametrize(
    ("pos", "reads"),
    [
        ((-1, -1, 0), True),
        ((1, 1, 0), True),
        ((1, -1, 0), True),
        ((0, 1, 0), True),
        ((2, 0, 0), False),
        ((0, -2, 0), False),
        ((2, 2, 0), False),
    ],
)
def test_layer2_reads_the_3x3_sites_below(pos, reads):
    below = motor(pos, TURN_LEFT, fires=True)
    g = tissue(below, _reader(True))
    assert decide_both(g) == (bit(MOVE_FORWARD) if reads else 0)
    compiled = compile_tissue(g)
    idx = compiled.mn_in_idx[1].tolist()
    if reads:
        slot = 3 * (pos[0] + 1) + (pos[1] + 1)  # (dl, dm) from (-1, -1) to (1, 1)
        assert idx == [0 if a == slot else -1 for a in range(9)]
    else:
        assert idx == [-1] * 9


def test_layer2_input_weights_are_ordered_by_dl_then_dm():
    # Only slot 5 = (dl, dm) = (0, 1) has a negative weight.
    weights = tuple(-0.8 if a == 5 else 0.8 for a in range(9))
    reader = _reader(True, weights)
    assert decide_both(tissue(motor((0, 1, 0), TURN_LEFT), reader)) == bit(MOVE_FORWARD)
    assert decide_both(tissue(motor((1, 0, 0), TURN_LEFT), reader)) == 0


def test_layer2_sigma_is_weighted_mean_over_firing_inputs():
    weights = tuple([-0.8, 0.2] + [0.0] * 7)  # slot 0 = (-1, -1), slot 1 = (-1, 0)
    a = motor((-1, -1, 0), TURN_LEFT, fires=True)
    b_fires = motor((-1, 0, 0), TURN_LEFT, fires=True)
    b_silent = motor((-1, 0, 0), TURN_LEFT, fires=False)
    reader = _reader(True, weights)  # fires iff sigma < -0.5
    assert decide_both(tissue(a, b_silent, reader)) == bit(MOVE_FORWARD)  # sigma = -0.8
    assert decide_both(tissue(a, b_fires, reader)) == 0  # sigma = (-0.8 + 0.2) / 2 = -0.3


def test_dead_input_is_silent():
    dead_below = motor((0, 0, 0), TURN_LEFT, fires=True, dead=True)
    assert decide_both(tissue(dead_below, _reader(True))) == 0
    assert decide_both(tissue(dead_below, _reader(False))) == bit(MOVE_FORWARD)


def test_dead_cell_never_votes():
    dead = motor((0, 0, 0), MOVE_FORWARD, fires=True, dead=True)
    assert decide_both(tissue(dead)) == 0
    # a dead "firing" voter does not make 1 of 2
    silent = motor((1, 0, 0), MOVE_FORWARD, fires=False)
    assert decide_both(tissue(dead, silent)) == 0
    # a dead voter does not dilute 1 of 2 into 1 of 3
    firing = motor((2, 0, 0), MOVE_FORWARD, fires=True)
    dead_silent = motor((0, 0, 0), MOVE_FORWARD, fires=False, dead=True)
    assert decide_both(tissue(dead_silent, silent, firing)) == bit(MOVE_FORWARD)
    compiled = compile_tissue(tissue(dead, silent, firing))
    assert compiled.motor_genes == (1, 2)


def test_dead_decision_neuron_releases_nothing():
    m = motor((0, 0, 0), MOVE_FORWARD)
    d = decision((0, 1, 0), extent=(1, 1, 1), dead=True)
    g = tissue(m, d, coarse_coding=True)
    assert compile_tissue(g).n_decision == 0
    assert decide_both(g) == 0


def test_dead_cell_occupies_its_site():
    dead = motor((0, 0, 0), MOVE_FORWARD, dead=True)
    later = motor((0, 0, 0), TURN_LEFT, fires=True)
    g = tissue(dead, later)
    cells = develop(g)
    assert [(c.gene, c.position, c.dead) for c in cells] == [(0, (0, 0, 1), True)]
    assert decide_both(g) == 0


def test_repressed_gene_grows_no_cell():
    repressed = motor((0, 0, 0), MOVE_FORWARD, expressed=False)
    other = motor((1, 0, 0), TURN_LEFT)
    g = tissue(repressed, other)
    cells = develop(g)
    assert [c.gene for c in cells] == [1]
    assert decide_both(g) == bit(TURN_LEFT)
    # its site stays free for a later gene
    later = motor((0, 0, 0), MOVE_BACKWARD)
    cells = develop(tissue(repressed, later))
    assert [(c.gene, c.position) for c in cells] == [(1, (0, 0, 1))]
    assert decide_both(tissue(repressed)) == 0


def test_first_gene_wins_a_site():
    first = motor((0, 0, 0), MOVE_FORWARD)
    second = decision((0, 0, 0), extent=(1, 1, 1))
    third = motor((1, 0, 0), TURN_LEFT)
    g = tissue(first, second, third)
    cells = develop(g)
    assert [(c.gene, c.kind, c.position) for c in cells] == [
        (0, MOTOR, (0, 0, 1)),
        (2, MOTOR, (1, 0, 1)),
    ]
    assert decide_both(g) == bit(MOVE_FORWARD) | bit(TURN_LEFT)
    # the other way round the decision neuron wins
    cells = develop(tissue(second, first, third))
    assert [(c.gene, c.kind) for c in cells] == [(0, DECISION), (2, MOTOR)]


def test_develop_uses_seed_and_skips_cells_outside_lattice():
    g = Genome(
        TissueGene(seed=(2, -3, 2)),
        (motor((0, 0, 0)), motor((1, 1, -1)), motor((7, 0, 0)), motor((0, 0, 2))),
        Lattice(half_width=8, layers=3),
        False,
    )
    cells = develop(g)
    assert [(c.gene, c.position) for c in cells] == [(0, (2, -3, 2)), (1, (3, -2, 1))]


def test_empty_tissue_decides_nothing():
    g = tissue()
    compiled = compile_tissue(g)
    assert compiled.n_motor == compiled.n_decision == compiled.n_outputs == 0
    for cc in (True, False):
        assert decide_both(g, coarse_coding=cc) == 0
        assert decide_both(g, FULL, coarse_coding=cc) == 0


# --- random genomes ------------------------------------------------------------------------------


@pytest.mark.parametrize("seed", range(40))
def test_random_genome_shape(seed):
    g = random_genome(np.random.default_rng(seed))
    assert 40 <= g.n_cells <= 120
    positions = [g.absolute(c) for c in g.cells]
    assert len(set(positions)) == len(positions)
    assert all(g.lattice.contains(p) for p in positions)
    assert all(c.expressed and not c.dead for c in g.cells)
    assert {c.kind for c in g.cells} <= {MOTOR, DECISION}
    assert len(develop(g)) == g.n_cells
    for c in g.cells:
        assert len(c.sensor_weights) == N_SENSORS and len(c.input_weights) == 9
        assert all(-1.0 <= w <= 1.0 for w in c.sensor_weights + c.input_weights)
        assert c.k1 in (0, 1) and c.k2 in (0, 1)
        assert 0 <= c.behaviour < 12
        assert all(0 <= e <= 4 for e in c.extent)


def test_random_genome_neuron_count_covers_range():
    counts = [random_genome(np.random.default_rng(s)).n_cells for s in range(200)]
    assert min(counts) >= 40 and max(counts) <= 120
    assert max(counts) - min(counts) > 40


def test_random_genome_neuron_count_bounds_are_inclusive():
    g = random_genome(np.random.default_rng(0), n_neurons=(50, 50))
    assert g.n_cells == 50


def test_random_genome_small_lattice_stays_inside():
    lattice = Lattice(half_width=3, layers=2)
    for seed in range(20):
        g = random_genome(np.random.default_rng(seed), n_neurons=(40, 98), lattice=lattice)
        positions = [g.absolute(c) for c in g.cells]
        assert len(set(positions)) == len(positions)
        assert all(lattice.contains(p) for p in positions)


def test_random_genome_is_reproducible():
    for seed in range(5):
        a = random_genome(np.random.default_rng(seed))
        b = random_genome(np.random.default_rng(seed))
        assert a == b
    assert random_genome(np.random.default_rng(1)) != random_genome(np.random.default_rng(2))
    others = {random_genome(np.random.default_rng(s)).cells for s in range(10)}
    assert len(others) == 10
