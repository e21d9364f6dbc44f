"""The world model's readings of the paper, as one frozen record (paper, sections 4.1-4.3).

A first reading of the paper took choices that a careful reader contests
(docs/world-model.md and docs/evolution.md, "Profiles"). Each is a named switch of
:class:`WorldRules`; :data:`WORLD_PROFILES` sets them all at once:

* ``v1``: the first readings (the shipped genome and every recorded result were made
  under them and keep reproducing bit for bit);
* ``paper``: the literal reading.

| switch | ``v1`` | ``paper`` | what it changes |
|---|---|---|---|
| ``soil_fill`` | False | True | the blade equations may raise a cell (fill, backfill) |
| ``normal_load`` | 12 | 24 | push capacity without throttle-up (soil units) |
| ``throttle_load`` | 24 | 24 | push capacity with throttle-up |
| ``normal_climb`` | 1 | 1 | highest step the wheels climb without throttle-up |
| ``throttle_climb`` | 2 | 2 | highest step with throttle-up ("high power mode") |
| ``h1`` | relative | absolute | H1 relative to the heading, or the compass bearing |
| ``placement`` | anywhere | worksite | robots start anywhere on the grid, or in the pit |
| ``site`` | shared | fitted | the default pit on 16 x 16, or on the pit plus its dump band |

``soil_fill``, the loads, the climbs and ``h1`` act inside the kernels: :meth:`as_array`
packs them into the ``int64`` array every world step and sensing kernel takes (indices
``P_*``), so a switch costs one scalar load and no Python in the step. Two more entries, 0
here, carry a randomised training scenario's sensor noise (``P_MISREAD``, ``P_U1_DROPOUT``).
``placement`` acts when a scenario starts (:func:`excavation_sim.world.scenario_start`)
and ``site`` when the default blueprint is made
(:func:`blueprint_server.blueprint.resolve_blueprint`). ``docs/world-model.md`` states
each reading and why.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ant_controller.readings import CONTROLLER_PROFILES, H1_FRAMES, PROFILE_NAMES, ReadingError
from excavation_common.constants import MAX_LOAD

P_NORMAL_LOAD, P_THROTTLE_LOAD, P_NORMAL_CLIMB, P_THROTTLE_CLIMB, P_SOIL_FILL, P_H1 = range(6)
"""Indices of the packed rules (:meth:`WorldRules.as_array`)."""
P_MISREAD, P_U1_DROPOUT = 6, 7
"""Indices of the training noise (0 in every rule set; only a randomised scenario sets them,
:mod:`ant_evolution.randomise`): the chance, in units of 1 / :data:`CHANCE_ONE`, that a Z
sensor misreads a dig cell within a unit of its goal, and that U1 reads 0 when set."""
N_PACKED = 8
CHANCE_ONE = 1 << 20
"""A chance of 1 in the packed noise entries (20-bit fixed point)."""

PLACEMENTS = ("anywhere", "worksite")
SITES = ("shared", "fitted")
MAX_CLIMB = 8
"""Largest climb limit a rule may set (soil units)."""


class RulesError(ReadingError):
    """A world rule out of range or unknown (``path: field = value: reason``)."""


@dataclass(frozen=True)
class WorldRules:
    """The world model's switches (see the module docstring for each one).

    Attributes:
        soil_fill: The blade equations may raise the old blade cell to the cutting level,
            with soil from the cell the blade moves into (down to the cutting level there,
            never below: the blade cannot dig the cell ahead to fill the one behind).
        normal_load: Push capacity without throttle-up, soil units.
        throttle_load: Push capacity with throttle-up, soil units.
        normal_climb: Largest upward step the wheels take without throttle-up.
        throttle_climb: Largest upward step with throttle-up.
        h1: ``"relative"`` or ``"absolute"`` (:mod:`ant_controller.readings`).
        placement: ``"anywhere"`` on the grid, or ``"worksite"``: footprints inside the dig
            area (then the dump band, then anywhere, while the area is full).
        site: ``"shared"`` (the default pit centred on 16 x 16) or ``"fitted"`` (a grid of
            the pit plus its dump band on every side).
    """

    soil_fill: bool = False
    normal_load: int = 12
    throttle_load: int = MAX_LOAD
    normal_climb: int = 1
    throttle_climb: int = 2
    h1: str = "relative"
    placement: str = "anywhere"
    site: str = "shared"

    def __post_init__(self) -> None:
        for name in ("normal_load", "throttle_load"):
            v = getattr(self, name)
            if not isinstance(v, int) or not 0 <= v <= 10 * MAX_LOAD:
                raise RulesError("<rules>", name, v, f"must be an integer in 0..{10 * MAX_LOAD}")
        for name in ("normal_climb", "throttle_climb"):
            v = getattr(self, name)
            if not isinstance(v, int) or not 0 <= v <= MAX_CLIMB:
                raise RulesError("<rules>", name, v, f"must be an integer in 0..{MAX_CLIMB}")
        for name, choices in (("h1", tuple(H1_FRAMES)), ("placement", PLACEMENTS), ("site", SITES)):
            if getattr(self, name) not in choices:
                raise RulesError("<rules>", name, getattr(self, name), f"must be one of {choices}")

    def as_array(self) -> np.ndarray:
        """Pack the kernel switches: ``int64 [N_PACKED]`` at the ``P_*`` indices, read-only.

        Read-only always: numba compiles a kernel once per argument type and a read-only
        array is another type. The batched evaluator hands its kernels read-only arrays
        (``ScenarioSet.arrays``); a stepped world's packed rules were writable, and every
        episode kernel was compiled twice per decision program (docs/benchmarks.md,
        "Compiling the kernels").
        """
        out = np.zeros(N_PACKED, dtype=np.int64)
        out[P_NORMAL_LOAD] = self.normal_load
        out[P_THROTTLE_LOAD] = self.throttle_load
        out[P_NORMAL_CLIMB] = self.normal_climb
        out[P_THROTTLE_CLIMB] = self.throttle_climb
        out[P_SOIL_FILL] = int(self.soil_fill)
        out[P_H1] = H1_FRAMES[self.h1]
        out.setflags(write=False)
        return out

    @property
    def fitted_site(self) -> bool:
        """The default pit sits on a grid of the pit plus its dump band."""
        return self.site == "fitted"

    def to_dict(self) -> dict:
        """Switch name -> value."""
        return dataclasses.asdict(self)


V1_RULES = WorldRules()
PAPER_RULES = WorldRules(
    soil_fill=True,
    normal_load=MAX_LOAD,
    throttle_load=MAX_LOAD,
    h1=CONTROLLER_PROFILES["paper"].h1,
    placement="worksite",
    site="fitted",
)
WORLD_PROFILES = {"v1": V1_RULES, "paper": PAPER_RULES}
DEFAULT_RULES = V1_RULES


def world_rules(profile: str, label: str = "<arguments>") -> WorldRules:
    """The world rules of profile ``profile``.

    Raises:
        RulesError: For an unknown profile name.
    """
    if profile not in WORLD_PROFILES:
        raise RulesError(label, "profile", profile, f"must be one of {list(PROFILE_NAMES)}")
    return WORLD_PROFILES[profile]
