"""The paper's hand-coded excavation controller (appendix 8.1), as a sensor -> mask kernel.

Rules, with behaviours numbered as in Table 2; "Z2 or Z3 is X" means either blade cell
reads X:

1. stuck (U1): 1, 4, 7, 10, 12
2. obstacle in front (S1): 4
3. Z2 or Z3 dump and pushing soil (L1 > 0): 2, 3, 4
4. Z2 or Z3 don't care and pushing soil: 3, 4, 12
5. Z2 or Z3 don't care: 2, 4
6. Z2 or Z3 don't care and L1 = 0: 3
7. Z2 or Z3 at goal depth: 2, 4
8. Z2 or Z3 below goal depth: 2, 7, 11
9. Z2 or Z3 above goal depth: 2
10. Z2 or Z3 above goal depth with M1 = 0: 8, 11
11. Z2 or Z3 above goal depth with M1 = 1: 2, 9

Two readings (:mod:`ant_controller.readings`, switch ``hand_coded``):

* ``"chain"`` (profile ``v1``, :func:`hand_coded_decide`): the first rule whose condition
  holds decides, except that rules 10 and 11 refine rule 9 and add to it; rule 6 is then
  unreachable (rule 5 catches its case first), and a last rule is added, **12. otherwise:
  2, 4** (wander), so that an empty blade facing dump cells does not wait forever.
* ``"union"`` (profile ``paper``, :func:`hand_coded_union`): rule 1, else rule 2, else
  "the remaining if statements are executed": every one of rules 3-11 whose condition
  holds adds its behaviours, and "all selected behaviours are executed sequentially" in
  Table 2 order. No rule 12: a robot that matches none of them does nothing that step.

Rules 9-11 give the incision cut then level dig of the paper: on first meeting soil above
the goal the robot lowers its blade and sets the bit; the next step it moves forward
cutting and then levels the blade. ``docs/world-model.md`` compares the two readings.
"""

from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np

from ant_controller.layout import (
    L1,
    M1,
    N_SENSORS,
    S1,
    U1,
    Z2,
    Z3,
    Z_ABOVE,
    Z_BELOW,
    Z_DONT_CARE,
    Z_DUMP,
    Z_LEVEL,
    mask_of,
)


class HandCodedRules(NamedTuple):
    """The hand-coded controller as a decision program for the kernels.

    Attributes:
        union: The paper's reading (rules 3-11 as a union, no rule 12); False: the
            first-match chain with rule 12 (``v1``).
    """

    union: bool = False


_STUCK = mask_of(1, 4, 7, 10, 12)
_OBSTACLE = mask_of(4)
_DUMP_PUSHING = mask_of(2, 3, 4)
_DONT_CARE_PUSHING = mask_of(3, 4, 12)
_DONT_CARE = mask_of(2, 4)
_DONT_CARE_EMPTY = mask_of(3)
_AT_GOAL = mask_of(2, 4)
_BELOW_GOAL = mask_of(2, 7, 11)
_ABOVE_GOAL = mask_of(2)
_ABOVE_BIT0 = mask_of(8, 11)
_ABOVE_BIT1 = mask_of(9)
_ABOVE_BIT1_UNION = mask_of(2, 9)
_OTHERWISE = mask_of(2, 4)


@nb.njit(cache=True)
def hand_coded_decide(codes):
    """Behaviour mask of the hand-coded controller for one sensor vector."""
    if codes[U1] == 1:
        return _STUCK
    if codes[S1] == 1:
        return _OBSTACLE
    z2 = codes[Z2]
    z3 = codes[Z3]
    pushing = codes[L1] > 0
    dont_care = z2 == Z_DONT_CARE or z3 == Z_DONT_CARE
    if (z2 == Z_DUMP or z3 == Z_DUMP) and pushing:
        return _DUMP_PUSHING
    if dont_care and pushing:
        return _DONT_CARE_PUSHING
    if dont_care:
        return _DONT_CARE
    if dont_care and not pushing:  # rule 6, kept for completeness
        return _DONT_CARE_EMPTY
    if z2 == Z_LEVEL or z3 == Z_LEVEL:
        return _AT_GOAL
    if z2 == Z_BELOW or z3 == Z_BELOW:
        return _BELOW_GOAL
    if z2 == Z_ABOVE or z3 == Z_ABOVE:
        return _ABOVE_GOAL | (_ABOVE_BIT0 if codes[M1] == 0 else _ABOVE_BIT1)
    return _OTHERWISE


@nb.njit(cache=True)
def hand_coded_union(codes):
    """Behaviour mask of the paper's reading: rule 1, else rule 2, else rules 3-11 united."""
    if codes[U1] == 1:
        return _STUCK
    if codes[S1] == 1:
        return _OBSTACLE
    z2 = codes[Z2]
    z3 = codes[Z3]
    pushing = codes[L1] > 0
    dont_care = z2 == Z_DONT_CARE or z3 == Z_DONT_CARE
    above = z2 == Z_ABOVE or z3 == Z_ABOVE
    mask = 0
    if (z2 == Z_DUMP or z3 == Z_DUMP) and pushing:
        mask |= _DUMP_PUSHING
    if dont_care and pushing:
        mask |= _DONT_CARE_PUSHING
    if dont_care:
        mask |= _DONT_CARE
    if dont_care and not pushing:
        mask |= _DONT_CARE_EMPTY
    if z2 == Z_LEVEL or z3 == Z_LEVEL:
        mask |= _AT_GOAL
    if z2 == Z_BELOW or z3 == Z_BELOW:
        mask |= _BELOW_GOAL
    if above:
        mask |= _ABOVE_GOAL
    if above and codes[M1] == 0:
        mask |= _ABOVE_BIT0
    if above and codes[M1] == 1:
        mask |= _ABOVE_BIT1_UNION
    return mask


@nb.njit(cache=True, inline="always")
def hand_coded_program(codes, rules):
    """Behaviour mask of the hand-coded decision program ``rules`` (a :class:`HandCodedRules`)."""
    if rules.union:
        return hand_coded_union(codes)
    return hand_coded_decide(codes)


def hand_coded(codes, union: bool = False) -> int:
    """Python entry point: mask for one integer sensor vector of length 14.

    Args:
        codes: The sensor vector.
        union: The paper's reading (see the module docstring); False: the chain.
    """
    arr = np.asarray(codes, dtype=np.int64)
    if arr.shape != (N_SENSORS,):
        raise ValueError(f"sensor vector must have {N_SENSORS} entries, got shape {arr.shape}")
    return int(hand_coded_union(arr) if union else hand_coded_decide(arr))
