"""Readings of the paper the controller side can take: H1's frame and the hand-coded rules.

Two places where the paper's words allow more than one reading change what a controller
computes, so they are switches here (the world model's switches are
:class:`excavation_sim.rules.WorldRules`, which takes its H1 value from this module):

* ``h1``: Table 1 lists the nearest robot's heading as North / East / West / South.
  ``"relative"`` (profile ``v1``) reports where the nearest robot lies relative to the
  robot's own heading (ahead, right, behind, left); ``"absolute"`` (profile ``paper``)
  reports the compass bearing (north, east, south, west, the heading codes 0..3).
* ``hand_coded``: the appendix's controller. ``"chain"`` (``v1``) is a first-match chain
  with an added rule 12; ``"union"`` (``paper``) runs rule 1, else rule 2, else every one
  of rules 3-11 that matches ("the remaining if statements are executed"; "all selected
  behaviours are executed sequentially"), with no rule 12. See
  :mod:`ant_controller.hand_coded`.

:data:`CONTROLLER_PROFILES` gives both per profile name; a controller node takes a
``profile`` parameter and passes :attr:`ControllerReadings.h1_frame` to
:class:`ant_controller.controller.ControllerCore` and :attr:`ControllerReadings.hand_coded`
to :meth:`ant_controller.controller.Controller.hand_coded`.
"""

from __future__ import annotations

from dataclasses import dataclass

from excavation_common.errors import FieldError

H1_RELATIVE = 0
"""H1 codes are 0 ahead, 1 right, 2 behind, 3 left (``layout.AHEAD`` ...)."""
H1_ABSOLUTE = 1
"""H1 codes are the compass bearing 0 north, 1 east, 2 south, 3 west (``constants.NORTH`` ...)."""
H1_FRAMES = {"relative": H1_RELATIVE, "absolute": H1_ABSOLUTE}
HAND_CODED_READINGS = ("chain", "union")
PROFILE_NAMES = ("v1", "paper")
"""The profiles every part of the suite knows (``v1``: the first readings; ``paper``: literal)."""


class ReadingError(FieldError):
    """An unknown profile or reading (``path: field = value: reason``)."""


@dataclass(frozen=True)
class ControllerReadings:
    """The controller side's readings of the paper.

    Attributes:
        h1: ``"relative"`` or ``"absolute"`` (see the module docstring).
        hand_coded: ``"chain"`` or ``"union"``.
    """

    h1: str = "relative"
    hand_coded: str = "chain"

    def __post_init__(self) -> None:
        if self.h1 not in H1_FRAMES:
            raise ReadingError("<readings>", "h1", self.h1, f"must be one of {sorted(H1_FRAMES)}")
        if self.hand_coded not in HAND_CODED_READINGS:
            raise ReadingError(
                "<readings>", "hand_coded", self.hand_coded, f"must be one of {HAND_CODED_READINGS}"
            )

    @property
    def h1_frame(self) -> int:
        """``H1_RELATIVE`` or ``H1_ABSOLUTE``, as the sensing kernels take it."""
        return H1_FRAMES[self.h1]


CONTROLLER_PROFILES = {
    "v1": ControllerReadings(),
    "paper": ControllerReadings(h1="absolute", hand_coded="union"),
}


def controller_readings(profile: str, label: str = "<arguments>") -> ControllerReadings:
    """The readings of profile ``profile``.

    Raises:
        ReadingError: For an unknown profile name.
    """
    if profile not in CONTROLLER_PROFILES:
        raise ReadingError(label, "profile", profile, f"must be one of {list(PROFILE_NAMES)}")
    return CONTROLLER_PROFILES[profile]
