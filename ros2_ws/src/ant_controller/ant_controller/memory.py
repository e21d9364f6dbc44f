"""The memory bit M1 (paper, Tables 1 and 2): the one rule that updates it.

Behaviour 11 (bit set) sets M1 and behaviour 12 (bit clear) clears it; both run in Table 2
order, so when a controller selects both in one timestep the bit ends cleared. The world
model (:func:`excavation_sim.world.apply_behaviours`), the controller core a ROS node runs
(:class:`ant_controller.controller.ControllerCore`) and the bag tools all call
:func:`next_memory`, so the bit a controller sees offline and in the field is the same.
"""

from __future__ import annotations

import numba as nb

from ant_controller.layout import BIT_CLEAR, BIT_SET


@nb.njit(cache=True, inline="always")
def next_memory(memory, mask):
    """M1 after a timestep whose behaviour bit mask is ``mask`` (``memory``: M1 before).

    Args:
        memory: The bit before the timestep (0 or 1).
        mask: The behaviour bit mask (bit i: behaviour i + 1 of Table 2).

    Returns:
        The bit after the timestep (0 or 1).
    """
    if (mask >> BIT_SET) & 1:
        memory = 1
    if (mask >> BIT_CLEAR) & 1:
        memory = 0
    return memory
