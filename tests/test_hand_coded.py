"""The appendix's hand-coded controller, rule by rule."""

from __future__ import annotations

import numpy as np
import pytest

from ant_controller.hand_coded import hand_coded
from ant_controller.layout import (
    L1,
    M1,
    S1,
    U1,
    Z2,
    Z3,
    Z_ABOVE,
    Z_BELOW,
    Z_DONT_CARE,
    Z_DUMP,
    Z_LEVEL,
    behaviour_names,
    mask_of,
)


def codes(z2=Z_ABOVE, z3=Z_ABOVE, load=0, obstacle=0, stuck=0, memory=0):
    v = np.zeros(14, dtype=np.int64)
    v[Z2], v[Z3], v[L1], v[S1], v[U1], v[M1] = z2, z3, load, obstacle, stuck, memory
    return v


@pytest.mark.parametrize(
    ("vector", "expected"),
    [
        (codes(stuck=1, obstacle=1, load=3), (1, 4, 7, 10, 12)),  # rule 1 beats all
        (codes(obstacle=1, z2=Z_DUMP, load=2), (4,)),  # rule 2
        (codes(z2=Z_DUMP, z3=Z_LEVEL, load=1), (2, 3, 4)),  # rule 3
        (codes(z2=Z_DONT_CARE, z3=Z_ABOVE, load=2), (3, 4, 12)),  # rule 4
        (codes(z2=Z_ABOVE, z3=Z_DONT_CARE), (2, 4)),  # rule 5
        (codes(z2=Z_LEVEL, z3=Z_LEVEL), (2, 4)),  # rule 7
        (codes(z2=Z_BELOW, z3=Z_ABOVE), (2, 7, 11)),  # rule 8 before rule 9
        (codes(memory=0), (2, 8, 11)),  # rules 9 + 10: move, lower blade, set bit
        (codes(memory=1), (2, 9)),  # rules 9 + 11: move (cutting), level the blade
        (codes(z2=Z_DUMP, z3=Z_DUMP), (2, 4)),  # no appendix rule: wander
    ],
)
def test_rules(vector, expected):
    mask = hand_coded(vector)
    assert mask == mask_of(*expected), behaviour_names(mask)


def test_rejects_wrong_length():
    with pytest.raises(ValueError, match="14 entries"):
        hand_coded([0] * 13)
