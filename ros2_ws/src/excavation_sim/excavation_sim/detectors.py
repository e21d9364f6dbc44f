"""The paper's sensor-behaviour detectors (Table 3) over sensor vectors and behaviour masks.

The paper tracks how an ANT controller solves excavation by counting five combinations of
what a robot senses and what it does in the same timestep (section 5, "Evolution of
Behaviors through Task Decomposition", and Table 3 of the appendix):

=====================  ========================================================================
name                   holds when
=====================  ========================================================================
``level``              B1 = level, L1 > 0 and Move Forward
``collision_avoidance``  S1 = 1, no Move Forward, no Random Turn, and (Turn Right != Turn Left
                       or Move Backward)
``stuck_avoidance``    U1 = 1, no Move Forward, and (Move Backward or Random Turn or
                       Turn Left != Turn Right)
``cut_dig``            B1 = below and Move Forward
``correct_dump``       Z2 = Z3 = dump, L1 > 0, Move Forward, and the turns of the timestep
                       cancel: no Random Turn and Turn Left = Turn Right, or a Random Turn to
                       the left undone by Turn Right alone, or one to the right undone by
                       Turn Left alone
=====================  ========================================================================

B1, L1, S1, U1, Z2 and Z3 are the sensor values the controller saw when it chose the
behaviours (``ant_controller.layout``); behaviours are the bit masks of Table 2 (bit ``i``
= behaviour ``i + 1``).

The last two clauses of ``correct_dump`` depend on which way a Random Turn went, which the
mask does not say. Pass ``random_turns`` (``+1`` right, ``-1`` left, ``0`` none) to count
them; :func:`random_turn_direction` recovers the direction from the heading before and
after the step. Without it those two clauses count as not detected, so ``correct_dump`` is
then a lower bound (the plain clause is always counted).

This module is pure numpy (no ``rclpy``): the offline evaluator, the experiments and the bag
report (``ant-bag report``) share it. Example::

    hits = detect(sensors, behaviours)           # sensors [..., 14], behaviours [...]
    for name in DETECTORS:
        print(DETECTOR_TITLES[name], int(hits[name].sum()))
"""

from __future__ import annotations

import numpy as np

from ant_controller.layout import (
    B1,
    BLADE_BELOW,
    BLADE_LEVEL,
    L1,
    MOVE_BACKWARD,
    MOVE_FORWARD,
    N_BEHAVIOURS,
    N_SENSORS,
    RANDOM_TURN,
    S1,
    TURN_LEFT,
    TURN_RIGHT,
    U1,
    Z2,
    Z3,
    Z_DUMP,
)

DETECTORS: tuple[str, ...] = (
    "level",
    "collision_avoidance",
    "stuck_avoidance",
    "cut_dig",
    "correct_dump",
)
"""Detector names in Table 3 order (detector 1 .. 5)."""

DETECTOR_TITLES: dict[str, str] = {
    "level": "Level",
    "collision_avoidance": "Collision avoidance",
    "stuck_avoidance": "Stuck avoidance",
    "cut_dig": "Cut dig",
    "correct_dump": "Correct dump",
}
"""Human-readable names for plots and reports."""


class DetectorInputError(ValueError):
    """Sensor vectors and behaviour masks that do not fit together (shape or value)."""


def _bit(behaviours: np.ndarray, index: int) -> np.ndarray:
    return (behaviours >> index) & 1 == 1


def _check(
    sensors: np.ndarray, behaviours: np.ndarray, random_turns: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    s = np.asarray(sensors)
    b = np.asarray(behaviours)
    if s.ndim < 1 or s.shape[-1] != N_SENSORS:
        raise DetectorInputError(
            f"sensors: shape {s.shape}: the last axis must hold the {N_SENSORS} sensors"
        )
    if not (np.issubdtype(s.dtype, np.integer) and np.issubdtype(b.dtype, np.integer)):
        raise DetectorInputError(
            f"sensors ({s.dtype}) and behaviours ({b.dtype}) must be integer codes and masks"
        )
    if b.shape != s.shape[:-1]:
        raise DetectorInputError(
            f"behaviours: shape {b.shape} does not match the sensors' {s.shape[:-1]}"
        )
    if b.size and (b.min() < 0 or b.max() >= 1 << N_BEHAVIOURS):
        raise DetectorInputError(
            f"behaviours: value {int(b.min() if b.min() < 0 else b.max())} is not a "
            f"{N_BEHAVIOURS}-bit mask"
        )
    r = None
    if random_turns is not None:
        r = np.asarray(random_turns)
        if r.shape != b.shape:
            raise DetectorInputError(
                f"random_turns: shape {r.shape} does not match the behaviours' {b.shape}"
            )
        if r.size and not np.isin(r, (-1, 0, 1)).all():
            raise DetectorInputError("random_turns: values must be -1 (left), 0 or +1 (right)")
    return s.astype(np.int64, copy=False), b.astype(np.int64, copy=False), r


def detect(
    sensors: np.ndarray,
    behaviours: np.ndarray,
    random_turns: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """Evaluate every Table 3 detector for each (sensor vector, behaviour mask) pair.

    Args:
        sensors: Integer sensor vectors, ``[..., 14]`` in Table 1 order (what the robot
            sensed before acting).
        behaviours: Behaviour bit masks chosen from those sensors, shape ``[...]``.
        random_turns: Optional direction each Random Turn took (``+1`` right, ``-1`` left,
            ``0`` none), shape ``[...]``; needed for the last two ``correct_dump`` clauses.

    Returns:
        ``{name: bool array of shape [...]}`` for every name in :data:`DETECTORS`.

    Raises:
        DetectorInputError: When shapes or values do not fit.
    """
    s, b, r = _check(sensors, behaviours, random_turns)
    forward = _bit(b, MOVE_FORWARD)
    backward = _bit(b, MOVE_BACKWARD)
    random_turn = _bit(b, RANDOM_TURN)
    right = _bit(b, TURN_RIGHT)
    left = _bit(b, TURN_LEFT)
    loaded = s[..., L1] > 0
    one_turn = right != left

    dump_ahead = (s[..., Z2] == Z_DUMP) & (s[..., Z3] == Z_DUMP) & loaded & forward
    straight = ~random_turn & (left == right)
    if r is not None:
        undone_left = random_turn & (r == -1) & right & ~left
        undone_right = random_turn & (r == 1) & left & ~right
        straight = straight | undone_left | undone_right
    return {
        "level": (s[..., B1] == BLADE_LEVEL) & loaded & forward,
        "collision_avoidance": (s[..., S1] == 1) & ~forward & ~random_turn & (one_turn | backward),
        "stuck_avoidance": (s[..., U1] == 1) & ~forward & (backward | random_turn | one_turn),
        "cut_dig": (s[..., B1] == BLADE_BELOW) & forward,
        "correct_dump": dump_ahead & straight,
    }


def count(
    sensors: np.ndarray,
    behaviours: np.ndarray,
    random_turns: np.ndarray | None = None,
    axis: int | tuple[int, ...] | None = None,
) -> dict[str, np.ndarray | int]:
    """How often each detector fires, summed over ``axis`` (all axes by default).

    Example: with sensors ``[steps, robots, 14]``, ``axis=1`` gives counts per step.
    """
    hits = detect(sensors, behaviours, random_turns)
    out: dict[str, np.ndarray | int] = {}
    for name, v in hits.items():
        total = v.sum(axis=axis)
        out[name] = int(total) if axis is None else total
    return out


def random_turn_direction(
    heading_before: np.ndarray, heading_after: np.ndarray, behaviours: np.ndarray
) -> np.ndarray:
    """Which way each Random Turn went, from the headings around one timestep.

    Moves never change the heading, so the net turn of a step is the random turn plus
    Turn Right minus Turn Left (headings 0 N, 1 E, 2 S, 3 W; right = +1).

    Args:
        heading_before: Heading when the robot sensed, ``[...]``.
        heading_after: Heading after its behaviours ran, ``[...]``.
        behaviours: The masks run in between, ``[...]``.

    Returns:
        ``int8 [...]``: ``+1`` right, ``-1`` left, ``0`` where no Random Turn ran.

    Raises:
        DetectorInputError: A random turn whose net effect is not a quarter turn (the
            headings do not belong to this step).
    """
    hb = np.asarray(heading_before, dtype=np.int64)
    ha = np.asarray(heading_after, dtype=np.int64)
    b = np.asarray(behaviours, dtype=np.int64)
    if not hb.shape == ha.shape == b.shape:
        raise DetectorInputError(
            f"headings {hb.shape}, {ha.shape} and behaviours {b.shape} differ in shape"
        )
    explicit = _bit(b, TURN_RIGHT).astype(np.int64) - _bit(b, TURN_LEFT).astype(np.int64)
    rand = (ha - hb - explicit) % 4
    turned = _bit(b, RANDOM_TURN)
    if (turned & ((rand == 0) | (rand == 2))).any():
        raise DetectorInputError(
            "heading_after: a Random Turn that is not a quarter turn; the headings do not "
            "belong to the behaviours' timestep"
        )
    out = np.zeros(b.shape, dtype=np.int8)
    out[turned & (rand == 1)] = 1
    out[turned & (rand == 3)] = -1
    return out
