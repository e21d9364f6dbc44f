"""The behaviour word: the controller's output interface (paper, Table 2).

A controller answers each tick with a bit mask; bit ``i`` set means behaviour ``i + 1`` of
Table 2 fires this tick, and behaviours run in table order (bit 0 first). The word is the
contract between the controllers that write it and the field nodes that carry it out (the
team tick, the drive executor, the blade driver) and the simulators, so its layout lives
here, in the shared layer; ``docs/world-model.md`` lists the behaviours with their meaning.
"""

from __future__ import annotations

(
    THROTTLE_UP,
    MOVE_FORWARD,
    MOVE_BACKWARD,
    RANDOM_TURN,
    TURN_RIGHT,
    TURN_LEFT,
    BLADE_ABOVE_CMD,
    BLADE_BELOW_CMD,
    BLADE_LEVEL_CMD,
    BLADE_HOME_CMD,
    BIT_SET,
    BIT_CLEAR,
) = range(12)
N_BEHAVIOURS = 12

BEHAVIOURS: tuple[str, ...] = (
    "throttle_up",
    "move_forward",
    "move_backward",
    "random_turn",
    "turn_right",
    "turn_left",
    "blade_above",
    "blade_below",
    "blade_level",
    "blade_home",
    "bit_set",
    "bit_clear",
)
"""Behaviour names, index = bit."""

MOTION_BITS = sum(1 << b for b in (MOVE_FORWARD, MOVE_BACKWARD, RANDOM_TURN, TURN_RIGHT, TURN_LEFT))
"""The bits that move the robot's base."""


def behaviour_names(mask: int) -> list[str]:
    """Names of the behaviours set in a command bit mask, in execution order."""
    return [BEHAVIOURS[i] for i in range(N_BEHAVIOURS) if mask >> i & 1]


def mask_of(*behaviour_numbers: int) -> int:
    """Bit mask from 1-based behaviour numbers of Table 2 (``mask_of(2, 4)``)."""
    mask = 0
    for b in behaviour_numbers:
        if not 1 <= b <= N_BEHAVIOURS:
            raise ValueError(f"behaviour number {b} is not in 1..{N_BEHAVIOURS}")
        mask |= 1 << (b - 1)
    return mask
