"""Sensor and behaviour layout shared by every controller (paper, Tables 1 and 2).

The sensor vector is a row of small integers, one per sensor of Table 1, each in
``0 .. states - 1``. The network sees each sensor as one input neuron whose state is the
integer divided by ``states - 1`` (so every input lies in ``[0, 1]``); the hand-coded
controller reads the integers directly.

The behaviour command is a bit mask: bit ``i`` set means behaviour ``i + 1`` of Table 2
fires this timestep. Behaviours run in table order (bit 0 first).

The numeric codes below are the contract between the simulator, the controllers and the
ROS nodes; ``docs/world-model.md`` lists them with their meaning.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from excavation_common.behaviour import (  # noqa: F401 (the behaviour word of Table 2)
    BEHAVIOURS,
    BIT_CLEAR,
    BIT_SET,
    BLADE_ABOVE_CMD,
    BLADE_BELOW_CMD,
    BLADE_HOME_CMD,
    BLADE_LEVEL_CMD,
    MOVE_BACKWARD,
    MOVE_FORWARD,
    N_BEHAVIOURS,
    RANDOM_TURN,
    THROTTLE_UP,
    TURN_LEFT,
    TURN_RIGHT,
    behaviour_names,
    mask_of,
)
from excavation_common.constants import (  # noqa: F401 (sensor codes of Table 1)
    BLADE_ABOVE,
    BLADE_BELOW,
    BLADE_HOME,
    BLADE_LEVEL,
    EAST,
    NORTH,
    SOUTH,
    WEST,
)

# --- Sensor indices in the sensor vector (Table 1 order) -------------------------------
Z1, Z2, Z3, Z4, E1, E2, B1, L1, S1, D1, H1, R1, U1, M1 = range(14)
N_SENSORS = 14

# --- Sensor state codes ----------------------------------------------------------------
# Z1..Z4: depth relative to the blueprint.
Z_LEVEL, Z_ABOVE, Z_BELOW, Z_DONT_CARE, Z_DUMP = 0, 1, 2, 3, 4
# E1, E2: blade cell soil relative to the front wheel under it.
E_ABOVE, E_BELOW, E_LEVEL = 0, 1, 2
# B1 and the blade state of a robot, and headings: excavation_common.constants (re-exported
# here because they are also sensor codes).
# H1 (bearing of the nearest robot, relative to the robot's own heading).
AHEAD, RIGHT, BEHIND, LEFT = 0, 1, 2, 3


@dataclass(frozen=True)
class SensorSpec:
    """One sensor of Table 1.

    Attributes:
        name: Paper symbol (``"Z1"``, ``"L1"`` ...).
        states: Number of discrete states.
        meaning: State names, index = code.
    """

    name: str
    states: int
    meaning: tuple[str, ...]


SENSORS: tuple[SensorSpec, ...] = (
    *(
        SensorSpec(f"Z{i}", 5, ("level", "above", "below", "dont_care", "dump"))
        for i in range(1, 5)
    ),
    SensorSpec("E1", 3, ("above", "below", "level")),
    SensorSpec("E2", 3, ("above", "below", "level")),
    SensorSpec("B1", 4, ("below", "level", "above", "home")),
    SensorSpec("L1", 5, ("0", "1", "2", "3", "4")),
    SensorSpec("S1", 2, ("clear", "obstacle")),
    SensorSpec("D1", 4, ("0", "1", "2", "3")),
    SensorSpec("H1", 4, ("ahead", "right", "behind", "left")),
    SensorSpec("R1", 2, ("level", "tilted_down")),
    SensorSpec("U1", 2, ("free", "stuck")),
    SensorSpec("M1", 2, ("0", "1")),
)

SENSOR_STATES = np.array([s.states for s in SENSORS], dtype=np.int64)
"""Number of states of each sensor, in sensor-vector order."""

SENSOR_SCALE = 1.0 / (SENSOR_STATES - 1).astype(np.float64)
"""Factor that maps a sensor code to its input-neuron state in ``[0, 1]``."""

INPUT_ENCODING = "scalar"
"""How sensor codes become input-neuron states (recorded in genome files)."""


def layout_dict() -> dict:
    """Return the layout as stored in genome files (``ant-genome/1``)."""
    return {
        "sensors": [{"name": s.name, "states": s.states} for s in SENSORS],
        "behaviours": list(BEHAVIOURS),
        "encoding": INPUT_ENCODING,
    }
