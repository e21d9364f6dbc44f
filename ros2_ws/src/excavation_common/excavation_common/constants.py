"""Grid, zone and blade codes shared by every package (``docs/world-model.md``).

These numbers are the contract between the blueprint server, the simulators, the
controllers, the drivers and the perception nodes; each is defined here once.
"""

from __future__ import annotations

from dataclasses import dataclass

# Zone codes of a blueprint (the values of the /blueprint/zones mono8 image).
ZONE_DONT_CARE, ZONE_DIG, ZONE_DUMP = 0, 1, 2
ZONE_NAMES = {ZONE_DONT_CARE: "dont_care", ZONE_DIG: "dig", ZONE_DUMP: "dump"}

# Grid headings of a robot (yaw pi/2, 0, -pi/2, pi in the map frame).
NORTH, EAST, SOUTH, WEST = 0, 1, 2, 3

HEADING_STEPS = ((1, 0), (0, 1), (-1, 0), (0, -1))
"""``HEADING_STEPS[h]``: the (d_row, d_col) of one grid step ahead at heading ``h``."""

# Blade settings: the B1 sensor code and the blade state of a robot (paper, Table 1).
BLADE_BELOW, BLADE_LEVEL, BLADE_ABOVE, BLADE_HOME = 0, 1, 2, 3
BLADE_NAMES = ("below", "level", "above", "home")

MAX_LOAD = 24
"""Soil units a robot can push at most (paper, section 4.1); L1 rescales 0..24 to 0..4."""

ROBOT_CELLS = 2
"""A robot's footprint is ROBOT_CELLS x ROBOT_CELLS grid cells; its blade covers two."""


SOIL_MODES = ("grid", "physical")
"""The continuous-motion simulator's soil: the world model's rules, or the physical model
(``excavation_sim.soil``)."""


@dataclass(frozen=True)
class BladeGeometry:
    """Joint positions of the four blade settings and the force of a full blade.

    Attributes:
        depth: Blade edge below/above the wheels for "below"/"above", metres.
        home: Blade edge height when retracted, metres.
        max_force: Push force (N) that corresponds to ``MAX_LOAD`` soil units (paper: the
            dome robots push at most 10 N).
        reach: The blade's edge ahead of the robot's centre, metres (the front of the
            2 x 2-cell body at 0.25 m cells; the ``robot_k/blade`` frame's offset).
    """

    depth: float = 0.02
    home: float = 0.10
    max_force: float = 10.0
    reach: float = 0.25

    def position(self, blade: int) -> float:
        """Joint position of a blade code."""
        return {
            BLADE_BELOW: -self.depth,
            BLADE_LEVEL: 0.0,
            BLADE_ABOVE: self.depth,
            BLADE_HOME: self.home,
        }[blade]

    def nearest(self, position: float) -> int:
        """The blade code whose joint position is nearest to ``position``."""
        codes = (BLADE_BELOW, BLADE_LEVEL, BLADE_ABOVE, BLADE_HOME)
        return min(codes, key=lambda c: abs(self.position(c) - position))
