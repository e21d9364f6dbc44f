"""Topic names that the node graph and the bag tools share (no ``rclpy`` here).

A continuous run's controllers read the team tick's snapshot, republished under
:data:`TICK_PREFIX`, instead of the live poses, height map and U1; in the dome their blade
state is the blade driver's tick-stamped one (:data:`DOME_BLADE_OUT`). The trial graph
(``excavation_bringup.nodes.controller_remaps``) and the tick replay of a bag
(``excavation_bags.tick_replay``) both remap a controller with :func:`tick_remaps`.
"""

from __future__ import annotations

from collections.abc import Iterable

TICK_PREFIX = "/tick"
"""Where the team tick republishes each tick's snapshot."""

DOME_BLADE_OUT = "blade/tick_state"
"""A dome blade driver's tick-stamped state, relative to the robot's namespace."""


def tick_remaps(robots: Iterable[int], k: int, dome_blade: bool) -> list[str]:
    """Robot ``k``'s controller remaps (``from:=to``) onto the tick's snapshot.

    Args:
        robots: Every robot of the team (each one's pose is read from the tick).
        k: The controller's robot.
        dome_blade: The blade state is the dome driver's :data:`DOME_BLADE_OUT`.
    """
    out = [f"/robot_{j}/pose:={TICK_PREFIX}/robot_{j}/pose" for j in robots]
    out.append(f"/worksite/height_map:={TICK_PREFIX}/worksite/height_map")
    out.append(f"/robot_{k}/stuck:={TICK_PREFIX}/robot_{k}/stuck")
    if dome_blade:
        out.append(f"/robot_{k}/blade/joint_states:=/robot_{k}/{DOME_BLADE_OUT}")
    return out
